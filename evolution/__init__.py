"""evolution: a generic ask/tell evolution engine with resumable runs.

A library of its own: it sees only *problems* (genomes in; objectives, measures and fields out) and imports nothing
from ``structgen`` or ``physics``. Optimisers are chosen by name (``ga``, ``cma_es``, ``map_elites``, ``cma_mae``);
evaluation goes through one batch call that runs in this process, in local worker processes or on a Dask cluster;
a run is a folder with an atomic checkpoint, metrics, the best candidate, the archive and plots.

Modules, each using only those listed before it: ``problem`` (what is optimised), ``optimizers`` (the interface, GA,
CMA-ES, all settings), ``qd`` (pyribs), ``registry`` (optimisers by name), ``evaluators`` (where evaluation runs),
``runfolder`` (the files of a run), ``plots``, ``run`` (the loop), ``toys`` (two small problems).
"""

from evolution.evaluators import DaskEvaluator, EvaluationError, Evaluator, PoolEvaluator, SerialEvaluator, make_evaluator
from evolution.optimizers import Optimizer
from evolution.problem import Evaluation, Problem
from evolution.registry import DEFAULT_OPTIMIZER, OPTIMIZERS, make_optimizer
from evolution.run import RunSettings, advance, graceful_interrupt
from evolution.runfolder import Best, RunFolder, RunFolderError, RunState, atomic_write, library_versions

__all__ = [
    "DEFAULT_OPTIMIZER",
    "OPTIMIZERS",
    "Best",
    "DaskEvaluator",
    "Evaluation",
    "EvaluationError",
    "Evaluator",
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
    "make_evaluator",
    "make_optimizer",
]
