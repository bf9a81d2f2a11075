"""The optimiser interface, the paper's GA, CMA-ES (pycma) and random search, and the settings of every optimiser.

Every optimiser has the shape of a pyribs scheduler: :meth:`Optimizer.ask` returns a batch of genomes and
:meth:`Optimizer.tell` takes their ``objective`` (higher is better), ``measures`` and extra ``fields``. All state,
random generators included, lives in the object and pickles, so a checkpoint is the pickled optimiser and a resumed
run continues exactly where it stopped.

Settings are one frozen dataclass per optimiser. The quality-diversity optimisers are built from pyribs in
:mod:`evolution.qd`, which only loads when one is asked for; :mod:`evolution.registry` chooses optimisers by name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from evolution.files import read_weights
from evolution.problem import Problem

__all__ = [
    "CMAES",
    "CMAESSettings",
    "CMAMAESettings",
    "GASettings",
    "GeneticAlgorithm",
    "MapElitesSettings",
    "Optimizer",
    "RandomSearch",
    "RandomSettings",
]


def _whole_numbers(settings: Any, *names: str, low: int) -> None:
    for name in names:
        value = getattr(settings, name)
        if not isinstance(value, int) or isinstance(value, bool) or value < low:
            wanted = "a positive integer" if low == 1 else f"a whole number >= {low}"
            raise ValueError(f"optimizer {name} must be {wanted}, got {value!r}")


def _positive_int(settings: Any, *names: str) -> None:
    _whole_numbers(settings, *names, low=1)


def _in_range(settings: Any, name: str, low: float, high: float, *, low_open: bool = False) -> None:
    value = getattr(settings, name)
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    if not ok or value > high or value < low or (low_open and value == low):
        bound = f"({low}, {high}]" if low_open else f"[{low}, {high}]"
        raise ValueError(f"optimizer {name} must be a number in {bound}, got {value!r}")


class Optimizer:
    """Base class: ``ask()`` a batch, evaluate it, ``tell()`` the results. ``archive`` is the quality-diversity
    archive that holds the results (None for optimisers without one).

    An optimiser pickles without its problem (problems may hold worker pools); after unpickling, :meth:`attach` the
    problem again before asking.
    """

    archive: Any = None
    problem: Problem | None = None

    def attach(self, problem: Problem) -> None:
        """Give the optimiser its problem again (after loading from a checkpoint)."""
        self.problem = problem

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["problem"] = None
        return state

    def ask(self) -> Any:
        raise NotImplementedError

    def tell(self, objective: np.ndarray, measures: np.ndarray, **fields: np.ndarray) -> None:
        raise NotImplementedError


# -- the paper's genetic algorithm ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GASettings:
    """The paper's loop: keep the best ``parents``, fill the population with mutated copies of random parents.

    Attributes:
        population: genomes per generation, parents included (100 in the paper).
        parents: best genomes kept unchanged, without re-evaluation (20 in the paper).
        mutation_rate: share of the genes of a flat genome moved in each mutation.
        mutation_scale: a moved gene changes by a uniform value in [-scale, scale] (0.25 in the paper).
        crossover_rate: chance that a child starts from two parents combined (``Problem.crossover``) before mutation;
            0 by default, as the paper found recombination no better than random networks.
        initial: random genomes in the first generation; 0 for ``population``. With ``parents = initial`` and
            ``population = 2 * parents`` this is a (mu + lambda) strategy with mu = lambda (Autoverse's 40 + 40).
        ties: who is kept among equal scores: "parents" (the old stay ahead) or "newest" (children stay ahead, so a
            population whose scores are all equal drifts instead of standing still: the paper's experiments at full
            size, where every random network's structure is crushed to a score of 0).
    """

    population: int = 100
    parents: int = 20
    mutation_rate: float = 0.05
    mutation_scale: float = 0.25
    crossover_rate: float = 0.0
    initial: int = 0
    ties: str = "parents"

    def __post_init__(self) -> None:
        _positive_int(self, "population", "parents")
        if self.ties not in ("parents", "newest"):
            raise ValueError(f"optimizer ties must be 'parents' or 'newest', got {self.ties!r}")
        if self.parents >= self.population:
            raise ValueError(f"optimizer parents ({self.parents}) must be fewer than population ({self.population})")
        _in_range(self, "mutation_rate", 0.0, 1.0, low_open=True)
        _in_range(self, "mutation_scale", 0.0, math.inf, low_open=True)
        _in_range(self, "crossover_rate", 0.0, 1.0)
        _whole_numbers(self, "initial", low=0)  # 0: population

    def random_counterpart(self) -> RandomSettings:
        """Random search evaluating as many genomes as this GA, generation by generation (parents are not
        re-evaluated, so a later generation evaluates ``population - parents``)."""
        return RandomSettings(population=self.population - self.parents, initial=self.initial or self.population)


class GeneticAlgorithm(Optimizer):
    """Elitist GA: the first generation is ``initial`` (default ``population``) random genomes; every later one is
    ``population - parents`` children, and the parents for the next come from parents and children together."""

    def __init__(self, problem: Problem, settings: GASettings, seed: int) -> None:
        self.problem, self.settings = problem, settings
        self.rng = np.random.default_rng(seed)
        self.parents: Any = None  # genomes
        self.parent_objective = np.zeros(0)
        self._asked: Any = None

    def ask(self) -> Any:
        s = self.settings
        if self.parents is None:
            self._asked = self.problem.initial_genomes(s.initial or s.population, self.rng)
            return self._asked
        children = []
        n_parents = len(self.parent_objective)
        for _ in range(s.population - s.parents):
            parent = self.parents[int(self.rng.integers(n_parents))]
            if s.crossover_rate and self.rng.random() < s.crossover_rate:
                other = self.parents[int(self.rng.integers(n_parents))]
                parent = self.problem.crossover(parent, other, self.rng)
            children.append(self._mutate(parent))
        self._asked = np.array(children) if self.problem.flat else children
        return self._asked

    def _mutate(self, genome: Any) -> Any:
        if not self.problem.flat:
            return self.problem.mutate(genome, self.rng)
        s = self.settings
        moved = self.rng.random(len(genome)) < s.mutation_rate
        return genome + moved * self.rng.uniform(-s.mutation_scale, s.mutation_scale, len(genome))

    def tell(self, objective: np.ndarray, measures: np.ndarray, **fields: np.ndarray) -> None:
        if self._asked is None:
            raise RuntimeError("tell() before ask()")
        if self.parents is None:
            pool, scores = list(self._asked), np.asarray(objective, dtype=np.float64)
        elif self.settings.ties == "newest":
            pool = list(self._asked) + list(self.parents)
            scores = np.concatenate([np.asarray(objective, dtype=np.float64), self.parent_objective])
        else:
            pool = list(self.parents) + list(self._asked)
            scores = np.concatenate([self.parent_objective, objective])
        # Stable sort: among equal scores, whoever is listed first stays ahead.
        keep = np.argsort(-scores, kind="stable")[: self.settings.parents]
        chosen = [pool[i] for i in keep]
        self.parents = np.array(chosen) if self.problem.flat else chosen
        self.parent_objective = scores[keep]
        self._asked = None


# -- random search: the baseline every learning result is held against ----------------------------------------------
@dataclass(frozen=True)
class RandomSettings:
    """Random search: every generation ``population`` new genomes from the problem's own initial distribution (the
    one every other optimiser starts from), nothing learned from the scores. At the same number of evaluations and the
    same judge, the best of these is what a method must beat to be said to learn.

    Attributes:
        population: genomes per generation (evaluations count as for any optimiser: one per genome).
        initial: genomes in the first generation; 0 for ``population`` (so that random search can match a GA, whose
            first generation is larger than the later ones, evaluation for evaluation).
        cells: archive cells along each of the problem's measures, to keep what random search finds in the same grid
            archive a quality-diversity run keeps (its QD score and coverage are then the baseline's); empty for no
            archive.
    """

    population: int = 100
    initial: int = 0
    cells: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        _positive_int(self, "population")
        _whole_numbers(self, "initial", low=0)  # 0: population
        if any(not isinstance(c, int) or isinstance(c, bool) or c < 1 for c in self.cells):
            raise ValueError(f"optimizer cells must be positive integers, got {list(self.cells)}")

    def random_counterpart(self) -> RandomSettings:
        return self


class RandomSearch(Optimizer):
    """Draws ``population`` genomes with ``problem.initial_genomes`` each generation and learns nothing from their
    scores; with ``cells``, every genome told is offered to a grid archive (:func:`evolution.qd.random_archive`), as
    a quality-diversity optimiser's results are."""

    def __init__(self, problem: Problem, settings: RandomSettings, seed: int, archive: Any = None) -> None:
        self.problem, self.settings = problem, settings
        self.rng = np.random.default_rng(seed)
        self.archive = archive
        self.asked_generations = 0
        self._asked: Any = None

    def ask(self) -> Any:
        first = self.asked_generations == 0 and self.settings.initial
        self._asked = self.problem.initial_genomes(self.settings.initial if first else self.settings.population, self.rng)
        self.asked_generations += 1
        return self._asked

    def tell(self, objective: np.ndarray, measures: np.ndarray, **fields: np.ndarray) -> None:
        if self._asked is None:
            raise RuntimeError("tell() before ask()")
        if self.archive is not None:
            solutions = np.asarray(self._asked) if self.problem.flat else _object_array(self._asked)
            self.archive.add(solutions, objective, measures, **fields)
        self._asked = None


def _object_array(genomes: Any) -> np.ndarray:
    """Genomes that are not vectors as a one-dimensional object array (numpy would otherwise try to stack them)."""
    out = np.empty(len(genomes), dtype=object)
    out[:] = list(genomes)
    return out


# -- where a search starts ---------------------------------------------------------------------------------------------
#: Values of ``x0`` that name a way to start rather than a genome file.
START_WORDS = ("random", "zeros")


def _start_setting(settings: Any) -> None:
    x0 = settings.x0
    if not isinstance(x0, str) or not (x0 in START_WORDS or x0.lower().endswith((".npy", ".json"))):
        raise ValueError(
            f"optimizer x0 must be 'random', 'zeros' or the path of a .npy or .json file holding a genome, got {x0!r}"
        )


def start_genome(problem: Problem, x0: str, rng: np.random.Generator) -> np.ndarray:
    """The genome a search starts from: one random genome drawn with ``rng`` (drawn for "zeros" and files too,
    so that what ``rng`` gives next does not depend on ``x0``), zeros, or the genome in the file ``x0`` (a path
    relative to the working directory; an error names the file and what is wrong with it)."""
    genome = np.asarray(problem.initial_genomes(1, rng), dtype=np.float64)[0]
    if x0 == "random":
        return genome
    if x0 == "zeros":
        return np.zeros_like(genome)
    return read_weights(x0, len(genome), f"a genome of {problem.name}")


# -- CMA-ES (pycma) ---------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CMAESSettings:
    """CMA-ES from the ``cma`` package.

    Attributes:
        population: samples per generation (pycma's popsize).
        sigma0: initial step size.
        diagonal: learn only a diagonal covariance (sep-CMA-ES). Needed for thousands of parameters: a full
            covariance of the NCA's 4766 weights is 180 MB and its decomposition takes seconds.
        x0: where the search starts: "random" (one genome from the problem's initial distribution), "zeros", or
            a ``.npy``/``.json`` file holding one genome (such as an elite's weights), to refine it.
    """

    population: int = 100
    sigma0: float = 0.1
    diagonal: bool = True
    x0: str = "random"

    def __post_init__(self) -> None:
        _positive_int(self, "population")
        if self.population < 2:
            raise ValueError("optimizer population must be at least 2 for CMA-ES")
        _in_range(self, "sigma0", 0.0, math.inf, low_open=True)
        _start_setting(self)

    def random_counterpart(self) -> RandomSettings:
        """Random search evaluating as many genomes a generation as this CMA-ES."""
        return RandomSettings(population=self.population)


class _Normal:
    """Standard normal samples from our own generator (pycma would otherwise use numpy's global one, which a
    checkpoint cannot capture). A class rather than a lambda so that it pickles."""

    def __init__(self, seed: int) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, *shape: int) -> np.ndarray:
        return self.rng.standard_normal(shape)


class CMAES(Optimizer):
    """pycma's CMAEvolutionStrategy, started from one random genome; it minimises, so objectives are negated."""

    def __init__(self, problem: Problem, settings: CMAESSettings, seed: int) -> None:
        import cma

        if not problem.flat:
            raise ValueError(f"cma_es needs flat genomes; {problem.name} has object genomes (use ga or map_elites)")
        rng = np.random.default_rng(seed)
        x0 = start_genome(problem, settings.x0, rng)
        options = {
            "popsize": settings.population,
            "randn": _Normal(int(rng.integers(2**63))),
            "seed": np.nan,  # leave numpy's global generator alone
            "CMA_diagonal": settings.diagonal,
            "verbose": -9,
            "verb_disp": 0,
            "verb_log": 0,
        }
        self.es = cma.CMAEvolutionStrategy(x0, settings.sigma0, options)
        self._asked: np.ndarray | None = None

    def ask(self) -> np.ndarray:
        self._asked = np.array(self.es.ask())
        return self._asked

    def tell(self, objective: np.ndarray, measures: np.ndarray, **fields: np.ndarray) -> None:
        if self._asked is None:
            raise RuntimeError("tell() before ask()")
        self.es.tell(list(self._asked), (-np.asarray(objective, dtype=np.float64)).tolist())
        self._asked = None


# -- quality diversity (settings here, built from pyribs in evolution.qd) ----------------------------------------------
@dataclass(frozen=True)
class MapElitesSettings:
    """MAP-Elites on a pyribs grid archive.

    Attributes:
        cells: archive cells along each measure.
        emitters: number of emitters; each proposes ``batch_size`` genomes per generation.
        batch_size: genomes per emitter per generation.
        sigma: Gaussian mutation strength for flat genomes (pyribs' GaussianEmitter).
        variation: "gaussian" (flat genomes only) or "problem" (the problem's own mutation, for any genome).
        immigrants: with the problem's mutation, how many of each emitter's batch are new random genomes instead of
            mutated elites (the Amorphous Fortress's MAP-Elites: 1 of 10).
    """

    cells: tuple[int, ...] = (16, 16)
    emitters: int = 1
    batch_size: int = 100
    sigma: float = 0.05
    variation: str = "gaussian"
    immigrants: int = 0

    def __post_init__(self) -> None:
        _positive_int(self, "emitters", "batch_size")
        _whole_numbers(self, "immigrants", low=0)
        if self.immigrants > self.batch_size:
            raise ValueError(f"optimizer immigrants ({self.immigrants}) cannot exceed batch_size ({self.batch_size})")
        _in_range(self, "sigma", 0.0, math.inf, low_open=True)
        if self.variation not in ("gaussian", "problem"):
            raise ValueError(f"optimizer variation must be 'gaussian' or 'problem', got {self.variation!r}")

    def random_counterpart(self) -> RandomSettings:
        """Random search evaluating as many genomes a generation, into an archive of the same cells."""
        return RandomSettings(population=self.emitters * self.batch_size, cells=tuple(self.cells))


@dataclass(frozen=True)
class CMAMAESettings:
    """CMA-MAE: CMA-ES emitters improving an archive that learns (``learning_rate``), results kept in a second,
    ordinary archive. Defaults follow the warehouse NCA work (5 emitters, ranker "imp", restart on no improvement);
    CMA-ME is ``learning_rate = 1``, ``ranker = "2imp"``, ``selection = "filter"``, ``result_archive = false``.

    Attributes:
        cells: archive cells along each measure.
        emitters: number of CMA-ES emitters.
        batch_size: genomes per emitter per generation.
        sigma0: initial step size of each emitter.
        learning_rate: the archive's learning rate (0.01 in the warehouse work; 1 would be CMA-ME).
        threshold_min: initial acceptance threshold of every cell; unset, just below the problem's objective floor,
            so that candidates scoring the floor still enter the archive (an empty archive stalls the emitters).
        es: the evolution strategy inside the emitters: "sep_cma_es" (diagonal, for thousands of parameters) or
            "cma_es" (full covariance: the original's, slower per generation with thousands of parameters).
        ranker: how an emitter ranks its batch (pyribs' names): "imp" (improvement over the cell's threshold),
            "2imp" (new cells first, then improvement), "obj" (objective) or "2obj".
        selection: "mu" (the better half becomes the parents) or "filter" (those that entered the archive).
        restart: "no_improvement" (restart an emitter when none of its batch entered the archive) or "basic"
            (only when its step size collapses).
        result_archive: keep the best of each cell in a second archive (CMA-MAE), or report the learning archive
            itself (CMA-ME).
        x0: where the emitters start: "random" (one genome from the problem's initial distribution), "zeros"
            (the origin, as the warehouse work does), or a ``.npy``/``.json`` file holding one genome.
        emitter: "es" (CMA-ES emitters: CMA-MAE) or "iso_line" (pyribs' Iso+LineDD emitters on the same two
            archives: the warehouse work's "MAP-Elites" baseline, whose configuration keeps CMA-MAE's learning
            archive and result archive). With "iso_line", ``sigma0`` is the line step and ``iso_sigma`` the
            isotropic one, and ``es``, ``ranker``, ``selection`` and ``restart`` do not apply.
        iso_sigma: the isotropic mutation of the "iso_line" emitters (0.01 in the warehouse work).
    """

    cells: tuple[int, ...] = (16, 16)
    emitters: int = 5
    batch_size: int = 20
    sigma0: float = 0.1
    learning_rate: float = 0.01
    threshold_min: float | None = None
    es: str = "sep_cma_es"
    ranker: str = "imp"
    selection: str = "mu"
    restart: str = "no_improvement"
    result_archive: bool = True
    x0: str = "random"
    emitter: str = "es"
    iso_sigma: float = 0.01

    def __post_init__(self) -> None:
        _positive_int(self, "emitters", "batch_size")
        _in_range(self, "sigma0", 0.0, math.inf, low_open=True)
        _in_range(self, "learning_rate", 0.0, 1.0, low_open=True)
        if self.threshold_min is not None and not math.isfinite(self.threshold_min):
            raise ValueError(f"optimizer threshold_min must be finite, got {self.threshold_min!r}")
        choices = {
            "es": ("sep_cma_es", "cma_es"),
            "ranker": ("imp", "2imp", "obj", "2obj"),
            "selection": ("mu", "filter"),
            "restart": ("no_improvement", "basic"),
            "emitter": ("es", "iso_line"),
        }
        _in_range(self, "iso_sigma", 0.0, math.inf, low_open=True)
        for name, allowed in choices.items():
            if getattr(self, name) not in allowed:
                options = " or ".join(repr(a) for a in allowed)
                raise ValueError(f"optimizer {name} must be {options}, got {getattr(self, name)!r}")
        _start_setting(self)
        if not isinstance(self.result_archive, bool):
            raise ValueError(f"optimizer result_archive must be true or false, got {self.result_archive!r}")

    def random_counterpart(self) -> RandomSettings:
        """Random search evaluating as many genomes a generation, into an archive of the same cells."""
        return RandomSettings(population=self.emitters * self.batch_size, cells=tuple(self.cells))
