"""evolution: a generic ask/tell evolution engine with resumable runs.

A library of its own: it sees only *problems* (genomes in; objectives, measures and fields out) and imports nothing
from ``structgen`` or ``physics``. Optimisers are chosen by name (``ga``, ``cma_es``, ``map_elites``, ``cma_mae``);
evaluation goes through one batch call that runs in this process, in local worker processes or on a Dask cluster;
a run is a folder with an atomic checkpoint, metrics, the best candidate, the archive and plots.

Modules, each using only those listed before it: ``files`` (the gate every file read and written goes through),
``problem`` (what is optimised), ``optimizers`` (the interface, GA, CMA-ES, all settings), ``qd`` (pyribs),
``registry`` (optimisers by name), ``evaluators`` (where evaluation runs), ``runfolder`` (the files of a run),
``plots``, ``run`` (the loop), ``toys`` (two small problems).

The names below load their module on first use, so ``import evolution.files`` costs nothing more than that module.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_HOMES = {
    "DaskEvaluator": "evolution.evaluators",
    "EvaluationError": "evolution.evaluators",
    "Evaluator": "evolution.evaluators",
    "PoolEvaluator": "evolution.evaluators",
    "SerialEvaluator": "evolution.evaluators",
    "make_evaluator": "evolution.evaluators",
    "InputFileError": "evolution.files",
    "atomic_write": "evolution.files",
    "Optimizer": "evolution.optimizers",
    "Evaluation": "evolution.problem",
    "Problem": "evolution.problem",
    "DEFAULT_OPTIMIZER": "evolution.registry",
    "OPTIMIZERS": "evolution.registry",
    "make_optimizer": "evolution.registry",
    "RunSettings": "evolution.run",
    "advance": "evolution.run",
    "graceful_interrupt": "evolution.run",
    "Archive": "evolution.runfolder",
    "Best": "evolution.runfolder",
    "RunFolder": "evolution.runfolder",
    "RunFolderError": "evolution.runfolder",
    "RunState": "evolution.runfolder",
    "library_versions": "evolution.runfolder",
    "load_archive": "evolution.runfolder",
}

if TYPE_CHECKING:
    from evolution.evaluators import DaskEvaluator, EvaluationError, Evaluator, PoolEvaluator, SerialEvaluator, make_evaluator
    from evolution.files import InputFileError, atomic_write
    from evolution.optimizers import Optimizer
    from evolution.problem import Evaluation, Problem
    from evolution.registry import DEFAULT_OPTIMIZER, OPTIMIZERS, make_optimizer
    from evolution.run import RunSettings, advance, graceful_interrupt
    from evolution.runfolder import Archive, Best, RunFolder, RunFolderError, RunState, library_versions, load_archive

__all__ = [
    "Archive",
    "Best",
    "DEFAULT_OPTIMIZER",
    "DaskEvaluator",
    "Evaluation",
    "EvaluationError",
    "Evaluator",
    "InputFileError",
    "OPTIMIZERS",
    "Optimizer",
    "PoolEvaluator",
    "Problem",
    "RunFolder",
    "RunFolderError",
    "RunSettings",
    "RunState",
    "SerialEvaluator",
    "advance",
    "atomic_write",
    "graceful_interrupt",
    "library_versions",
    "load_archive",
    "make_evaluator",
    "make_optimizer",
]


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    raise AttributeError(f"module 'evolution' has no attribute {name!r}")
