"""Optimisers by name: what ``optimizer.name`` in a run configuration can say, and how each is built.

Unknown names fail with the list of known ones. The quality-diversity optimisers load pyribs (and through it numba)
only when one is built, so choosing by name stays cheap.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from evolution.optimizers import (
    CMAES,
    CMAESSettings,
    CMAMAESettings,
    GASettings,
    GeneticAlgorithm,
    MapElitesSettings,
    Optimizer,
    RandomSearch,
    RandomSettings,
)
from evolution.problem import Problem

__all__ = ["DEFAULT_OPTIMIZER", "OPTIMIZERS", "OptimizerSpec", "make_optimizer"]


@dataclass(frozen=True)
class OptimizerSpec:
    """An optimiser by name: its settings class, how to build it for a problem and a seed, and one line about it."""

    settings: type
    build: Callable[[Problem, Any, int], Optimizer]
    summary: str


def _map_elites(problem: Problem, settings: MapElitesSettings, seed: int) -> Optimizer:
    from evolution.qd import map_elites

    return map_elites(problem, settings, seed)


def _cma_mae(problem: Problem, settings: CMAMAESettings, seed: int) -> Optimizer:
    from evolution.qd import cma_mae

    return cma_mae(problem, settings, seed)


def _random(problem: Problem, settings: RandomSettings, seed: int) -> Optimizer:
    if not settings.cells:
        return RandomSearch(problem, settings, seed)
    from evolution.qd import random_archive

    return RandomSearch(problem, settings, seed, archive=random_archive(problem, settings, seed))


OPTIMIZERS: dict[str, OptimizerSpec] = {
    "ga": OptimizerSpec(GASettings, GeneticAlgorithm, "the paper's elitist genetic algorithm (any genome)"),
    "cma_es": OptimizerSpec(CMAESSettings, CMAES, "CMA-ES from pycma, diagonal by default (vector genomes)"),
    "map_elites": OptimizerSpec(MapElitesSettings, _map_elites, "MAP-Elites on a pyribs grid archive (any genome)"),
    "cma_mae": OptimizerSpec(CMAMAESettings, _cma_mae, "CMA-MAE from pyribs with a separate result archive (vector genomes)"),
    "random": OptimizerSpec(RandomSettings, _random, "random search from the problem's initial distribution: the baseline"),
}
#: What a configuration that names no optimiser gets.
DEFAULT_OPTIMIZER = "ga"


def make_optimizer(name: str, problem: Problem, settings: Any = None, seed: int = 0) -> Optimizer:
    """Build the optimiser called ``name`` for ``problem``; unknown names fail with the list of known ones.

    Raises ValueError when the optimiser cannot work on the problem (CMA-ES on genomes that are not vectors, an
    archive whose cells do not match the problem's measures).
    """
    if name not in OPTIMIZERS:
        raise ValueError(f"unknown optimizer {name!r}; choose one of {', '.join(OPTIMIZERS)}")
    spec = OPTIMIZERS[name]
    return spec.build(problem, settings if settings is not None else spec.settings(), seed)
