"""Quality diversity with pyribs: grid archives, emitters and schedulers behind the :class:`Optimizer` interface.

Imported only when a quality-diversity optimiser is built (pyribs pulls in numba, which is slow to load).
"""

from __future__ import annotations

from functools import partial
from typing import Any

import numpy as np
from ribs.archives import GridArchive
from ribs.emitters import EmitterBase, EvolutionStrategyEmitter, GaussianEmitter, IsoLineEmitter
from ribs.schedulers import Scheduler

from evolution.optimizers import CMAMAESettings, MapElitesSettings, Optimizer, RandomSettings, start_genome
from evolution.problem import Problem

__all__ = [
    "FieldRankedArchive",
    "ProblemMutationEmitter",
    "RibsOptimizer",
    "archive_bytes",
    "cma_mae",
    "compile_kernels",
    "map_elites",
    "random_archive",
]


def _cache_ribs_kernels() -> None:
    """Keep pyribs's numba kernels compiled on disk between processes.

    pyribs compiles its evolution strategies' helpers on their first call and never caches them: on the 2-core box
    every process that ran CMA-MAE spent 7 to 9 s of its first generation compiling (a 3-generation run took 13.6 s,
    of which 13.0 s in the first). With numba's cache (files beside pyribs's own ``__pycache__``, or in numba's
    user-wide cache folder where that is read-only) the compiled code is loaded instead; the machine code, and so
    every result, is the same."""
    from ribs.emitters.opt import _cma_es, _lm_ma_es, _sep_cma_es

    for strategy in (_sep_cma_es.SeparableCMAEvolutionStrategy, _cma_es.CMAEvolutionStrategy, _lm_ma_es.LMMAEvolutionStrategy):
        for name in vars(strategy):
            kernel = getattr(strategy, name)
            if callable(getattr(kernel, "enable_caching", None)):
                try:
                    kernel.enable_caching()
                except RuntimeError:  # no writable place for the cache: compiled on first use, as before
                    return


_cache_ribs_kernels()


def _cells(settings: Any, problem: Problem) -> tuple[int, ...]:
    cells = tuple(settings.cells)
    if len(cells) != len(problem.measure_names):
        raise ValueError(
            f"optimizer cells has {len(cells)} entries but {problem.name} has {len(problem.measure_names)} measures "
            f"({', '.join(problem.measure_names)})"
        )
    if any(not isinstance(c, int) or isinstance(c, bool) or c < 1 for c in cells):
        raise ValueError(f"optimizer cells must be positive integers, got {list(cells)}")
    return cells


def archive_bytes(problem: Problem, cells: tuple[int, ...], archives: int = 1) -> int:
    """About what ``archives`` grid archives of ``cells`` take for ``problem``: pyribs allocates every cell's
    solution, objective, measures, threshold, index and fields up front."""
    per_cell = 8 * ((problem.n_params if problem.flat else 1) + 3 + len(problem.measure_names) + len(problem.field_names))
    return archives * int(np.prod([int(c) for c in cells], dtype=np.float64)) * per_cell


def _grid_archive(
    problem: Problem, cells: tuple[int, ...], seed: int, ranked_by: str | None = None, **options: Any
) -> GridArchive:
    """A grid archive over the problem's measures; ``ranked_by`` names a field that ranks its elites instead of
    the objective (:class:`FieldRankedArchive`)."""
    if not problem.measure_names:
        raise ValueError(f"quality diversity needs measures, and {problem.name} defines none")
    solution = {"solution_dim": problem.n_params} if problem.flat else {"solution_dim": (), "solution_dtype": object}
    kind: Any = GridArchive if ranked_by is None else partial(FieldRankedArchive, ranked_by)
    return kind(
        **solution,
        dims=cells,
        ranges=problem.measure_ranges,
        extra_fields={name: ((), np.float64) for name in problem.field_names},
        qd_score_offset=problem.objective_floor,
        seed=seed,
        **options,
    )


class FieldRankedArchive(GridArchive):
    """A grid archive whose elites are ranked by one of the candidates' fields instead of their objective: the
    scheduler hands every archive the same data, and this one swaps the objective for ``ranked_by`` on the way in."""

    def __init__(self, ranked_by: str, **options: Any) -> None:
        super().__init__(**options)
        if ranked_by not in self.field_list:
            raise ValueError(f"result archive ranked by {ranked_by!r}, which is not one of its fields {self.field_list}")
        self.ranked_by = ranked_by

    def add(self, solution: Any, objective: Any, measures: Any, **fields: Any) -> Any:
        return super().add(solution, fields[self.ranked_by], measures, **fields)

    def add_single(self, solution: Any, objective: Any, measures: Any, **fields: Any) -> Any:
        return super().add_single(solution, fields[self.ranked_by], measures, **fields)


class RibsOptimizer(Optimizer):
    """A pyribs scheduler behind our interface; ``archive`` is its result archive."""

    def __init__(self, scheduler: Scheduler, problem: Problem) -> None:
        self.scheduler, self.problem = scheduler, problem
        self.archive = scheduler.result_archive

    def attach(self, problem: Problem) -> None:
        self.problem = problem
        for emitter in self.scheduler.emitters:
            if isinstance(emitter, ProblemMutationEmitter):
                emitter.problem = problem

    def ask(self) -> Any:
        genomes = self.scheduler.ask()
        return genomes if self.problem.flat else list(genomes)

    def tell(self, objective: np.ndarray, measures: np.ndarray, **fields: np.ndarray) -> None:
        self.scheduler.tell(objective, measures, **fields)


class ProblemMutationEmitter(EmitterBase):
    """A pyribs emitter whose variation is the problem's own mutation: random genomes while the archive is empty,
    then mutated copies of elites sampled from it (uniformly over filled cells, with replacement), followed by
    ``immigrants`` fresh random genomes. This is how genomes that are not flat vectors take part in MAP-Elites."""

    def __init__(self, archive: GridArchive, problem: Problem, batch_size: int, seed: int, immigrants: int = 0) -> None:
        super().__init__(archive, solution_dim=archive.solution_dim, bounds=None, lower_bounds=None, upper_bounds=None)
        self.problem, self.batch_size, self.immigrants = problem, batch_size, immigrants
        self.rng = np.random.default_rng(seed)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["problem"] = None  # re-attached by RibsOptimizer.attach
        return state

    def ask(self) -> np.ndarray:
        if self.archive.empty:
            genomes = list(self.problem.initial_genomes(self.batch_size, self.rng))
        else:
            immigrants = min(getattr(self, "immigrants", 0), self.batch_size)
            genomes = []
            if immigrants < self.batch_size:
                elites = self.archive.sample_elites(self.batch_size - immigrants)["solution"]
                # Problem.mutate_many returns copies and leaves its arguments alone, so the elites are not copied here.
                genomes = self.problem.mutate_many(list(elites), self.rng)
            if immigrants:
                genomes += list(self.problem.immigrant_genomes(immigrants, self.rng))
        if self.problem.flat:
            return np.stack([np.asarray(g, dtype=np.float64) for g in genomes])
        batch = np.empty(len(genomes), dtype=object)
        batch[:] = genomes
        return batch


def map_elites(problem: Problem, settings: MapElitesSettings, seed: int) -> Optimizer:
    # One seed for the archive, then two per emitter (its first genomes, its own generator).
    seeds = [int(x) for x in np.random.SeedSequence(seed).generate_state(1 + 2 * settings.emitters)]
    archive = _grid_archive(problem, _cells(settings, problem), seeds[0])
    variation = settings.variation if problem.flat else "problem"
    emitters = []
    for k in range(settings.emitters):
        first, own = seeds[1 + 2 * k], seeds[2 + 2 * k]
        if variation == "gaussian":
            emitters.append(
                GaussianEmitter(
                    archive,
                    sigma=settings.sigma,
                    initial_solutions=np.asarray(problem.initial_genomes(settings.batch_size, np.random.default_rng(first))),
                    batch_size=settings.batch_size,
                    seed=own,
                )
            )
        else:
            emitters.append(ProblemMutationEmitter(archive, problem, settings.batch_size, own, settings.immigrants))
    return RibsOptimizer(Scheduler(archive, emitters), problem)


def random_archive(problem: Problem, settings: RandomSettings, seed: int) -> GridArchive:
    """The archive random search keeps: the grid a quality-diversity run over the same cells keeps, its elites
    ranked as a CMA-MAE result archive ranks them (by the problem's result objective where it names one), so that
    the baseline's QD score and coverage compare cell for cell."""
    return _grid_archive(problem, _cells(settings, problem), seed, ranked_by=problem.result_objective)


def cma_mae(problem: Problem, settings: CMAMAESettings, seed: int) -> Optimizer:
    if not problem.flat:
        raise ValueError(f"cma_mae needs flat genomes; {problem.name} has object genomes (use ga or map_elites)")
    seeds = np.random.SeedSequence(seed).generate_state(settings.emitters + 3)
    cells = _cells(settings, problem)
    threshold = settings.threshold_min
    if threshold is None:  # a hair below the floor: a candidate scoring exactly the floor must still get in
        threshold = problem.objective_floor - 1e-6 * max(1.0, abs(problem.objective_floor))
    archive = _grid_archive(problem, cells, int(seeds[0]), learning_rate=settings.learning_rate, threshold_min=threshold)
    result_archive = None
    if settings.result_archive:
        result_archive = _grid_archive(problem, cells, int(seeds[1]), ranked_by=problem.result_objective)
    x0 = start_genome(problem, settings.x0, np.random.default_rng(int(seeds[2])))
    if settings.emitter == "iso_line":
        emitters = [
            IsoLineEmitter(
                archive,
                iso_sigma=settings.iso_sigma,
                line_sigma=settings.sigma0,
                x0=x0,
                batch_size=settings.batch_size,
                seed=int(seeds[k + 3]),
            )
            for k in range(settings.emitters)
        ]
    else:
        emitters = [
            EvolutionStrategyEmitter(
                archive,
                x0=x0,
                sigma0=settings.sigma0,
                ranker=settings.ranker,
                selection_rule=settings.selection,
                restart_rule=settings.restart,
                es=settings.es,
                batch_size=settings.batch_size,
                seed=int(seeds[k + 3]),
            )
            for k in range(settings.emitters)
        ]
    return RibsOptimizer(Scheduler(archive, emitters, result_archive=result_archive), problem)


def compile_kernels() -> None:
    """Compile pyribs's kernels into numba's cache (:func:`_cache_ribs_kernels`) with two generations of a small
    CMA-MAE on each evolution strategy the optimisers use, so that a first quality-diversity run does not spend 7-9 s
    compiling; ``make install`` calls it (through ``structgen.registry.compile_kernels``)."""
    from evolution.toys import Sphere

    problem = Sphere()
    for es in ("sep_cma_es", "cma_es"):
        optimizer = cma_mae(problem, CMAMAESettings(cells=(4, 4), emitters=1, batch_size=4, es=es), seed=0)
        for generation in range(2):
            genomes = optimizer.ask()
            evaluation = problem.evaluate(genomes, np.arange(len(genomes)) + generation)
            optimizer.tell(evaluation.objective, evaluation.measures, **evaluation.fields)
