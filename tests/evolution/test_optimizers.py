"""Optimisers: the paper's GA, CMA-ES, MAP-Elites and CMA-MAE, on flat and object genomes, by name."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from evolution import OPTIMIZERS, Evaluation, make_optimizer
from evolution.optimizers import CMAESSettings, CMAMAESettings, GASettings, MapElitesSettings, RandomSettings
from evolution.toys import Ones, Sphere

SMALL = {
    "ga": GASettings(population=12, parents=3),
    "cma_es": CMAESSettings(population=8),
    "map_elites": MapElitesSettings(cells=(6, 6), batch_size=10, sigma=0.2),
    "cma_mae": CMAMAESettings(cells=(6, 6), emitters=2, batch_size=5),
    "random": RandomSettings(population=10),
}
#: The optimisers that learn from the scores (random search is the baseline they are held against).
LEARNING = [name for name in OPTIMIZERS if name != "random"]


def step(optimizer, problem, generation: int = 0):
    genomes = optimizer.ask()
    result = problem.evaluate(genomes, np.arange(len(genomes)) + 1000 * generation)
    optimizer.tell(result.objective, result.measures, **result.fields)
    return genomes, result


def best_after(name: str, problem, generations: int, seed: int = 0) -> float:
    optimizer = make_optimizer(name, problem, SMALL[name], seed=seed)
    return max(step(optimizer, problem, g)[1].objective.max() for g in range(generations))


# -- the registry -----------------------------------------------------------------------------------------------------
def test_registry_names_the_optimizers():
    assert list(OPTIMIZERS) == ["ga", "cma_es", "map_elites", "cma_mae", "random"]


def test_unknown_optimizer_lists_the_known_ones():
    with pytest.raises(ValueError, match="unknown optimizer 'de'; choose one of ga, cma_es, map_elites, cma_mae, random"):
        make_optimizer("de", Sphere())


@pytest.mark.slow
@pytest.mark.parametrize("name", LEARNING)
def test_every_optimizer_improves_the_sphere(name):
    problem = Sphere()
    first = make_optimizer(name, problem, SMALL[name], seed=1)
    start = step(first, problem)[1].objective.max()
    assert best_after(name, problem, 25, seed=1) > start + 0.5


@pytest.mark.parametrize("name", list(OPTIMIZERS))
def test_every_optimizer_is_deterministic_given_its_seed(name):
    problem = Sphere()
    runs = []
    for _ in range(2):
        optimizer = make_optimizer(name, problem, SMALL[name], seed=7)
        runs.append([step(optimizer, problem, g)[0] for g in range(4)])
    for a, b in zip(*runs):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("name", list(OPTIMIZERS))
def test_every_optimizer_pickles_mid_run_and_continues_identically(name):
    problem = Sphere()
    optimizer = make_optimizer(name, problem, SMALL[name], seed=3)
    for g in range(3):
        step(optimizer, problem, g)
    copy = pickle.loads(pickle.dumps(optimizer))
    copy.attach(problem)
    for g in range(3, 6):
        a, _ = step(optimizer, problem, g)
        b, _ = step(copy, problem, g)
        assert np.array_equal(a, b)


def test_pickled_optimizers_leave_their_problem_behind():
    # Problems may hold worker pools; a checkpoint must not try to carry them.
    problem = Ones()
    for name in ("ga", "map_elites"):
        optimizer = make_optimizer(name, problem, SMALL[name], seed=0)
        step(optimizer, problem)
        restored = pickle.loads(pickle.dumps(optimizer))
        assert restored.problem is None
        for emitter in getattr(getattr(restored, "scheduler", None), "emitters", []):
            assert emitter.problem is None
        restored.attach(problem)
        for emitter in getattr(getattr(restored, "scheduler", None), "emitters", []):
            assert emitter.problem is problem


def test_optimizers_do_not_touch_numpys_global_generator():
    np.random.seed(123)
    expected = np.random.random()
    np.random.seed(123)
    for name in OPTIMIZERS:
        optimizer = make_optimizer(name, Sphere(), SMALL[name], seed=0)
        for g in range(2):
            step(optimizer, Sphere(), g)
    assert np.random.random() == expected


# -- the paper's GA -----------------------------------------------------------------------------------------------------
def test_ga_generation_sizes_and_elitism():
    problem = Sphere()
    ga = make_optimizer("ga", problem, GASettings(population=10, parents=4), seed=0)
    first, result = step(ga, problem)
    assert first.shape == (10, problem.n_params)
    kept = np.argsort(-result.objective, kind="stable")[:4]
    np.testing.assert_array_equal(ga.parents, first[kept])
    children, _ = step(ga, problem, 1)
    assert children.shape == (6, problem.n_params)
    best = [ga.parent_objective.max()]
    for g in range(2, 12):
        step(ga, problem, g)
        best.append(ga.parent_objective.max())
    assert all(b >= a for a, b in zip(best, best[1:]))  # the best is never lost


def test_ga_keeps_the_newest_among_equal_scores_when_asked():
    # A population whose scores are all equal (the paper's experiments, where every random structure is crushed to 0)
    # must drift with ties = "newest"; by default the first parents stay.
    class Flat(Sphere):
        def evaluate(self, genomes, seeds):
            result = super().evaluate(genomes, seeds)
            return type(result)(np.zeros(len(genomes)), result.measures, result.fields)

    problem = Flat()
    for ties, parents_stay in (("parents", True), ("newest", False)):
        ga = make_optimizer("ga", problem, GASettings(population=10, parents=4, ties=ties), seed=0)
        step(ga, problem)
        first_parents = ga.parents.copy()
        children, _ = step(ga, problem, 1)
        assert np.array_equal(ga.parents, first_parents) is parents_stay
        if not parents_stay:
            np.testing.assert_array_equal(ga.parents, children[:4])
    with pytest.raises(ValueError, match="ties"):
        GASettings(ties="oldest")


def test_ga_mutation_moves_a_share_of_genes_within_the_scale():
    problem = Sphere()
    settings = GASettings(population=101, parents=1, mutation_rate=0.25, mutation_scale=0.1)
    ga = make_optimizer("ga", problem, settings, seed=2)
    step(ga, problem)
    parent = ga.parents[0]
    children = ga.ask()
    moved = children != parent
    assert 0.15 < moved.mean() < 0.35
    assert np.abs(children - parent).max() <= 0.1


def test_ga_crossover_uses_the_problems_recombination():
    class Recorder(Sphere):
        calls = 0

        def crossover(self, first, second, rng):
            Recorder.calls += 1
            return (first + second) / 2

    problem = Recorder()
    ga = make_optimizer("ga", problem, GASettings(population=20, parents=5, crossover_rate=1.0), seed=0)
    step(ga, problem)
    ga.ask()
    assert Recorder.calls == 15


@pytest.mark.parametrize(
    "field, value", [("parents", 100), ("parents", 0), ("mutation_rate", 0.0), ("mutation_scale", -1.0), ("crossover_rate", 1.5)]
)
def test_ga_settings_are_checked(field, value):
    with pytest.raises(ValueError, match=field):
        GASettings(**{field: value})


# -- object genomes with the problem's own mutation ----------------------------------------------------------------------
@pytest.mark.parametrize("name", ["ga", "map_elites"])
def test_object_genomes_evolve_through_the_problems_mutation(name):
    problem = Ones()
    optimizer = make_optimizer(name, problem, SMALL[name], seed=4)
    genomes, first = step(optimizer, problem)
    assert isinstance(genomes, list) and isinstance(genomes[0], tuple)
    best = max(step(optimizer, problem, g)[1].objective.max() for g in range(1, 40))
    assert best > first.objective.max() + 3


@pytest.mark.parametrize("name", ["cma_es", "cma_mae"])
def test_vector_only_optimizers_refuse_object_genomes(name):
    with pytest.raises(ValueError, match="needs flat genomes"):
        make_optimizer(name, Ones(), SMALL[name])


def test_map_elites_keeps_object_genomes_in_its_archive():
    problem = Ones()
    optimizer = make_optimizer("map_elites", problem, SMALL["map_elites"], seed=0)
    for g in range(5):
        step(optimizer, problem, g)
    elites = optimizer.archive.data()
    assert len(elites["index"]) > 3
    assert all(isinstance(s, tuple) and sum(s) == o for s, o in zip(elites["solution"], elites["objective"]))


# -- quality diversity ----------------------------------------------------------------------------------------------------
def test_cma_mae_learns_in_one_archive_and_keeps_results_in_another():
    optimizer = make_optimizer("cma_mae", Sphere(), SMALL["cma_mae"], seed=0)
    for g in range(5):
        step(optimizer, Sphere(), g)
    learning = optimizer.scheduler.archive
    assert optimizer.archive is optimizer.scheduler.result_archive and optimizer.archive is not learning
    assert learning.learning_rate == 0.01
    assert optimizer.archive.stats.num_elites > 0


def test_a_result_archive_can_rank_by_a_field_instead_of_the_objective():
    # The layout domains search on throughput + alpha * similarity and keep the best throughput per cell.
    class FarthestKept(Sphere):
        result_objective = "distance"

    problem = FarthestKept()
    optimizer = make_optimizer("cma_mae", problem, SMALL["cma_mae"], seed=0)
    for g in range(5):
        step(optimizer, problem, g)
    elites = optimizer.archive.data()
    assert len(elites["objective"]) > 0
    np.testing.assert_array_equal(elites["objective"], elites["distance"])
    learning = optimizer.scheduler.archive.data()
    assert not np.array_equal(learning["objective"], learning["distance"])
    from evolution import checkpoint

    restored = checkpoint.loads(pickle.dumps(optimizer))  # the checkpoint loader admits the archive's class
    assert restored.archive.ranked_by == "distance"


def test_iso_line_emitters_search_cma_maes_archives_deterministically_and_resume():
    # The warehouse work's "MAP-Elites" baseline: Iso+LineDD emitters on CMA-MAE's learning and result archives.
    settings = CMAMAESettings(cells=(6, 6), emitters=2, batch_size=5, sigma0=0.3, emitter="iso_line", x0="zeros")
    problem = Sphere()
    optimizer = make_optimizer("cma_mae", problem, settings, seed=4)
    first, _ = step(optimizer, problem)
    assert np.array_equal(first, make_optimizer("cma_mae", problem, settings, seed=4).ask())
    for g in range(1, 4):
        step(optimizer, problem, g)
    assert optimizer.scheduler.result_archive is not None and len(optimizer.scheduler.result_archive) > 1
    copy = pickle.loads(pickle.dumps(optimizer))
    copy.attach(problem)
    assert np.array_equal(step(optimizer, problem, 4)[0], step(copy, problem, 4)[0])
    with pytest.raises(ValueError, match="optimizer emitter must be 'es' or 'iso_line', got 'line'"):
        CMAMAESettings(emitter="line")


def test_cma_me_settings_reach_the_emitters_and_report_the_learning_archive():
    # The maze run of the warehouse paper: 2imp ranking, filter selection, learning rate 0.5, no result archive.
    settings = CMAMAESettings(
        cells=(6, 6), emitters=2, batch_size=5, learning_rate=0.5, threshold_min=0.0, es="cma_es", ranker="2imp",
        selection="filter", result_archive=False, x0="zeros",
    )  # fmt: skip
    optimizer = make_optimizer("cma_mae", Sphere(), settings, seed=0)
    emitter = optimizer.scheduler.emitters[0]
    assert type(emitter._ranker).__name__ == "TwoStageImprovementRanker" and emitter._selection_rule == "filter"
    assert emitter._opt.__class__.__name__ == "CMAEvolutionStrategy" and not emitter.x0.any()
    for g in range(3):
        step(optimizer, Sphere(), g)
    assert optimizer.archive is optimizer.scheduler.archive and optimizer.archive.learning_rate == 0.5
    with pytest.raises(ValueError, match="optimizer selection must be 'mu' or 'filter', got 'best'"):
        CMAMAESettings(selection="best")


@pytest.mark.parametrize("name", ["cma_es", "cma_mae"])
def test_a_search_can_start_from_a_genome_in_a_file(tmp_path, name):
    # Refining an elite: the first samples lie around the genome in the file, not around a random one.
    problem = Sphere()
    start = np.full(problem.n_params, 0.7)
    np.save(tmp_path / "elite.npy", start)
    settings = dataclasses.replace(SMALL[name], x0=str(tmp_path / "elite.npy"), sigma0=1e-3)
    genomes = make_optimizer(name, problem, settings, seed=0).ask()
    assert np.abs(np.asarray(genomes) - start).max() < 0.02


def test_a_start_file_that_does_not_fit_is_refused_by_name(tmp_path):
    problem = Sphere()
    np.save(tmp_path / "short.npy", np.zeros(problem.n_params - 1))
    with pytest.raises(ValueError, match=f"short.npy: holds {problem.n_params - 1} weights, but a genome of sphere has"):
        make_optimizer("cma_es", problem, CMAESSettings(population=8, x0=str(tmp_path / "short.npy")))
    with pytest.raises(ValueError, match="optimizer x0 must be 'random', 'zeros' or the path of a .npy or .json file"):
        CMAESSettings(x0="elite.txt")


def test_quality_diversity_settings_must_match_the_measures():
    with pytest.raises(ValueError, match="cells has 3 entries but sphere has 2 measures"):
        make_optimizer("map_elites", Sphere(), MapElitesSettings(cells=(4, 4, 4)))


# -- evaluations --------------------------------------------------------------------------------------------------------
def test_evaluation_refuses_nan_and_mismatched_fields():
    with pytest.raises(ValueError, match="finite"):
        Evaluation(np.array([1.0, np.nan]), np.zeros((2, 0)))
    with pytest.raises(ValueError, match="field 'x' has 1 values for 2 candidates"):
        Evaluation(np.ones(2), np.zeros((2, 0)), {"x": np.ones(1)})


def test_evaluations_join_in_order():
    a = Evaluation(np.array([1.0]), np.array([[0.1, 0.2]]), {"f": [5]})
    b = Evaluation(np.array([2.0, 3.0]), np.array([[0.3, 0.4], [0.5, 0.6]]), {"f": [6, 7]})
    joined = Evaluation.concatenate([a, b])
    assert joined.objective.tolist() == [1.0, 2.0, 3.0] and joined.fields["f"].tolist() == [5, 6, 7]
    assert joined.row(2) == {"objective": 3.0, "measures": [0.5, 0.6], "f": 7.0}


def test_cma_mae_survives_a_generation_where_everything_scores_the_floor():
    class Flat(Sphere):
        objective_floor = 0.0

        def evaluate(self, genomes, seeds):
            result = super().evaluate(genomes, seeds)
            return Evaluation(np.zeros(len(genomes)), result.measures, result.fields)

    problem = Flat()
    optimizer = make_optimizer("cma_mae", problem, SMALL["cma_mae"], seed=0)
    for g in range(3):
        step(optimizer, problem, g)
    assert optimizer.archive.stats.num_elites > 0


def test_pyribs_kernels_are_compiled_once_per_machine_not_once_per_process():
    # Uncached, every process running CMA-MAE compiled them again, 7 to 9 s of its first generation.
    from numba.core.caching import NullCache
    from ribs.emitters.opt._sep_cma_es import SeparableCMAEvolutionStrategy

    import evolution.qd  # noqa: F401  (enables the cache)

    kernels = [getattr(SeparableCMAEvolutionStrategy, name) for name in ("_calc_mean", "_calc_cov_update")]
    assert all(not isinstance(kernel._cache, NullCache) for kernel in kernels)


# -- random search --------------------------------------------------------------------------------------------------------
def test_random_search_draws_every_generation_from_the_initial_distribution():
    """The baseline learns nothing: each generation is what ``initial_genomes`` gives for the next draws of its
    generator, whatever the scores told it, on vector and object genomes alike."""
    for problem in (Sphere(), Ones()):
        search = make_optimizer("random", problem, RandomSettings(population=5), seed=4)
        rng = np.random.default_rng(4)
        for generation in range(3):
            asked = search.ask()
            expected = problem.initial_genomes(5, rng)
            assert all(np.array_equal(np.asarray(a), np.asarray(b)) for a, b in zip(asked, expected))
            result = problem.evaluate(asked, np.arange(5) + 10 * generation)
            search.tell(result.objective, result.measures, **result.fields)
    with pytest.raises(ValueError, match="optimizer population must be a positive integer"):
        RandomSettings(population=0)
    with pytest.raises(ValueError, match=r"optimizer cells must be positive integers, got \[4, 0\]"):
        RandomSettings(cells=(4, 0))


def test_random_search_with_cells_keeps_every_genome_in_a_grid_archive_as_map_elites_would():
    """With ``cells`` the baseline's archive holds, in each cell, the best genome random search drew there: the same
    archive a quality-diversity run over those cells keeps, so QD score and coverage compare. The genomes asked do
    not change with the archive."""
    for problem in (Sphere(), Ones()):
        plain = make_optimizer("random", problem, RandomSettings(population=8), seed=2)
        kept = make_optimizer("random", problem, RandomSettings(population=8, cells=(4, 4)), seed=2)
        assert plain.archive is None
        best: dict[tuple[int, ...], float] = {}
        for generation in range(3):
            asked = kept.ask()
            assert all(np.array_equal(np.asarray(a), np.asarray(b)) for a, b in zip(asked, plain.ask()))
            result = problem.evaluate(asked, np.arange(8) + 10 * generation)
            kept.tell(result.objective, result.measures, **result.fields)
            cells = kept.archive.index_of(np.asarray(result.measures))
            for cell, value in zip(cells, result.objective):
                best[int(cell)] = max(best.get(int(cell), -np.inf), float(value))
        data = kept.archive.data()
        assert dict(zip(data["index"].tolist(), data["objective"].tolist())) == pytest.approx(best)
    with pytest.raises(ValueError, match="optimizer cells has 1 entries but"):
        make_optimizer("random", Sphere(), RandomSettings(cells=(4,)), seed=0)
