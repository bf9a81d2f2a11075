"""evolution: a generic ask/tell evolution engine with resumable runs.

A library of its own: it sees only *problems* (genomes in; objectives, measures and fields out) and imports nothing
from ``structgen`` or ``physics``. Optimisers are chosen by name (``ga``, ``cma_es``, ``map_elites``, ``cma_mae``);
evaluation goes through one batch call that runs in this process, in local worker processes or on a Dask cluster;
a run is a folder with an atomic checkpoint, metrics, the best candidate, the archive and plots.
"""

from evolution.evaluators import DaskEvaluator, EvaluationError, Evaluator, PoolEvaluator, SerialEvaluator, make_evaluator
from evolution.optimizers import OPTIMIZERS, Optimizer, make_optimizer
from evolution.problem import Evaluation, Problem
from evolution.run import RunFolder, RunFolderError, RunSettings, RunState, advance, graceful_interrupt

__all__ = [
    "OPTIMIZERS",
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
    "graceful_interrupt",
    "make_evaluator",
    "make_optimizer",
]
