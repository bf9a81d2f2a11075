"""The stable-structures domain: NCA weights in; the paper's Q, height and vertex count out."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from physics import PhysicsConfig, check_stability
from structgen import NCAConfig, grow
from structgen.domains.structures import StableStructures, StructuresSettings
from structgen.nca import _split

SMALL = StructuresSettings(nca=NCAConfig(max_vertices=16))


@pytest.fixture(scope="module")
def batch():
    problem = StableStructures(SMALL)
    genomes = problem.initial_genomes(6, np.random.default_rng(3))
    return problem, genomes, problem.evaluate(genomes, np.arange(6))


def test_objective_is_the_physics_score_of_the_grown_structure(batch):
    problem, genomes, result = batch
    for genome, objective, measures, integrity in zip(genomes, result.objective, result.measures, result.fields["integrity"]):
        report = check_stability(grow(genome, SMALL.nca), PhysicsConfig.preset("fast"))
        assert objective == report.score and integrity == report.integrity
        assert measures.tolist() == [report.height, report.complexity]


def test_fields_and_measures_are_declared(batch):
    problem, _, result = batch
    assert set(result.fields) == set(problem.field_names) and problem.measure_names == ("height", "vertices")
    assert result.measures.shape == (6, 2)
    assert problem.n_params == 4766 and problem.measure_ranges == ((-0.5, 10.5), (0.5, 16.5))


def test_evaluation_is_deterministic_and_independent_of_batching(batch):
    problem, genomes, result = batch
    again = problem.evaluate(genomes[3:], np.arange(3, 6))
    assert np.array_equal(again.objective, result.objective[3:]) and np.array_equal(again.measures, result.measures[3:])


def test_structures_the_physics_refuses_score_zero_and_are_flagged():
    settings = replace(SMALL, physics=PhysicsConfig.preset("fast", max_joints=2))
    problem = StableStructures(settings)
    genomes = problem.initial_genomes(8, np.random.default_rng(0))
    result = problem.evaluate(genomes, np.arange(8))
    too_big = result.fields["edges"] > 1
    assert too_big.any()
    assert (result.objective[too_big] == 0).all() and (result.fields["failed"][too_big] == 1).all()


def test_no_build_down_shrinks_the_height_range():
    problem = StableStructures(replace(SMALL, nca=NCAConfig(max_vertices=16, build_down=False)))
    assert problem.measure_ranges[0] == (-0.5, 5.5)


def test_crossover_swaps_one_hidden_neuron():
    problem = StableStructures(SMALL)
    first, second = problem.initial_genomes(2, np.random.default_rng(1))
    child = problem.crossover(first, second, np.random.default_rng(2))
    w1, b1, w2, b2 = _split(child, 60)
    f1, fb1, f2, fb2 = _split(first, 60)
    s1, sb1, s2, _ = _split(second, 60)
    swapped = [j for j in range(60) if not np.array_equal(w1[:, j], f1[:, j])]
    assert len(swapped) == 1
    j = swapped[0]
    assert np.array_equal(w1[:, j], s1[:, j]) and b1[j] == sb1[j] and np.array_equal(w2[j], s2[j])
    assert np.array_equal(b2, fb2) and (child != first).sum() == 52 + 1 + 26
    assert not np.shares_memory(child, first)


def test_artifacts_show_the_structure(tmp_path, batch):
    problem, genomes, result = batch
    best = int(np.argmax(result.objective))
    paths = problem.write_artifacts(genomes[best], tmp_path)
    assert {p.name for p in paths} >= {"structure.json", "structure.glb", "report.json"}
    report = json.loads((tmp_path / "report.json").read_text())
    assert report["score"] == result.objective[best]
    assert json.loads((tmp_path / "structure.json").read_text())["metadata"]["score"] == result.objective[best]


def test_a_later_best_that_is_not_simulated_leaves_no_earlier_simulation_behind(tmp_path):
    # The statics evaluator simulates the best for its picture only when statics says it stands; a run's best folder
    # is rewritten as the best improves, and a simulation of an earlier best must not stay beside a later one.
    problem = StableStructures(replace(SMALL, evaluator="statics"))
    genomes = problem.initial_genomes(12, np.random.default_rng(0))
    result = problem.evaluate(genomes, np.arange(12))
    broken = int(np.argmin(result.fields["integrity"]))
    assert result.fields["integrity"][broken] < 1
    (tmp_path / "simulation.json").write_text("{}")  # what an earlier, standing best left
    problem.write_artifacts(genomes[broken], tmp_path)
    assert not (tmp_path / "simulation.json").exists() and (tmp_path / "report.json").exists()


# -- evaluators: simulation, static solve, or both --------------------------------------------------------------------------
def evaluate_with(evaluator: str, count: int = 8):
    problem = StableStructures(replace(SMALL, evaluator=evaluator))
    genomes = problem.initial_genomes(count, np.random.default_rng(5))
    return problem, genomes, problem.evaluate(genomes, np.arange(count))


def test_statics_evaluator_scores_with_the_static_solve():
    from physics import check_statics

    problem, genomes, result = evaluate_with("statics")
    assert (result.fields["evaluator"] == 0).all()
    for genome, objective in zip(genomes, result.objective):
        assert objective == check_statics(grow(genome, SMALL.nca), SMALL.physics).score


def test_statics_then_bullet_rechecks_exactly_the_structures_predicted_to_stand_or_near_it():
    from physics import check_statics
    from physics.statics import predict

    problem, genomes, result = evaluate_with("statics+bullet", count=12)
    predicted = [check_statics(grow(g, SMALL.nca), SMALL.physics) for g in genomes]
    loads = [predict(grow(g, SMALL.nca), SMALL.physics, rounds=0).first_loads for g in genomes]
    near = [len(x) > 0 and not np.isnan(x).any() and x.max() <= 1.5 * SMALL.physics.break_force for x in loads]
    rechecked = result.fields["evaluator"] == 1
    assert rechecked.tolist() == [p.intact or n for p, n in zip(predicted, near)]
    assert rechecked.any() and (~rechecked).any()
    for genome, objective, by_bullet in zip(genomes, result.objective, rechecked):
        if by_bullet:
            assert objective == check_stability(grow(genome, SMALL.nca), SMALL.physics).score


def test_mixed_evaluation_does_not_depend_on_batching():
    problem, genomes, whole = evaluate_with("statics+bullet", count=12)
    parts = [problem.evaluate(genomes[a:b], np.arange(a, b)) for a, b in ((0, 5), (5, 12))]
    assert np.array_equal(np.concatenate([p.objective for p in parts]), whole.objective)
    assert np.array_equal(np.concatenate([p.fields["evaluator"] for p in parts]), whole.fields["evaluator"])


def test_the_screen_simulates_a_star_statics_narrowly_breaks_and_it_stands():
    from physics import check_statics
    from structgen.domains.structures.samples import star_on_five_legs

    star = star_on_five_legs()
    problem = StableStructures(StructuresSettings(evaluator="statics+bullet"))
    assert not check_statics(star, problem.settings.physics).intact
    report = problem.judge(star)
    assert report.method == "bullet" and report.intact
    strict = StableStructures(StructuresSettings(evaluator="statics+bullet", screen_margin=1))
    assert strict.judge(star).method == "statics"


def test_a_screen_margin_below_one_is_refused():
    for bad in (0.5, float("nan"), True):
        with pytest.raises(ValueError, match=f"screen_margin must be a number of at least 1 \\(or inf\\), got {bad!r}"):
            StructuresSettings(screen_margin=bad)


def test_an_infinite_screen_margin_simulates_what_statics_says_breaks_far_over(tmp_path):
    # A column of four breaks at the bottom under statics; with margin inf it goes to the simulation, whose verdict
    # (it breaks too) then counts, and the setting survives a run folder's config.toml.
    from structgen.domains.structures.samples import column
    from structgen.runs.experiment import load_experiment

    tower = column(6)
    assert StableStructures(StructuresSettings(evaluator="statics+bullet", screen_margin=1)).judge(tower).method == "statics"
    report = StableStructures(StructuresSettings(evaluator="statics+bullet", screen_margin=float("inf"))).judge(tower)
    assert report.method == "bullet" and not report.intact
    config = tmp_path / "c.toml"
    config.write_text('[problem]\nname = "structures-v0"\nevaluator = "screened"\nscreen_margin = inf\n')
    experiment = load_experiment(config)
    assert experiment.problem_settings.screen_margin == float("inf")
    again = tmp_path / "again.toml"
    again.write_text(experiment.to_toml())
    assert load_experiment(again).problem_settings.screen_margin == float("inf")


def test_unknown_evaluator_is_refused():
    with pytest.raises(ValueError, match="evaluator must be one of bullet, statics, statics\\+bullet, screened, transient"):
        StructuresSettings(evaluator="fem")


def test_the_transient_evaluator_scores_with_the_transient_check():
    from physics import check_transient

    nca = NCAConfig(max_vertices=64, cutoff=0.6, build_down=False)
    problem = StableStructures(StructuresSettings(evaluator="transient", transient_window=0.2, nca=nca))
    assert problem.field_names[-1] == "peak_force"
    genomes = problem.initial_genomes(12, np.random.default_rng(5))
    result = problem.evaluate(genomes, np.arange(12))
    strengths = result.fields["integrity"]
    for genome, objective, strength, peak in zip(genomes, result.objective, strengths, result.fields["peak_force"]):
        report = check_transient(grow(genome, nca), problem.settings.physics, window=0.2)
        assert (objective, strength, peak) == (report.score, report.integrity, report.peak_force)
    assert (strengths == 1).any() and (strengths < 1).any() and (result.fields["evaluator"] == 1).all()
    # Overloaded in the window: not standing, whatever its height.
    assert (result.fields["standing_height"][strengths < 1] == 0).all()


def test_structures_below_the_height_floor_score_zero(batch):
    problem, genomes, result = batch
    floor = float(np.median(result.measures[:, 0]))
    floored = StableStructures(replace(SMALL, min_height=floor)).evaluate(genomes, np.arange(6))
    low = result.measures[:, 0] < floor
    assert low.any() and (~low).any()
    assert (floored.objective[low] == 0).all() and np.array_equal(floored.objective[~low], result.objective[~low])
    assert np.array_equal(floored.measures, result.measures)
    with pytest.raises(ValueError, match=r"problem min_height = -1: expected a number from 0 to 1e\+06"):
        StructuresSettings(min_height=-1)


@pytest.mark.parametrize("window", [0, -1, "0.3", 1e9])
def test_a_bad_transient_window_is_refused(window):
    with pytest.raises(ValueError, match="problem transient_window = .*: expected a number above 0, at most 3600"):
        StructuresSettings(transient_window=window)


def test_also_grow_scores_q_times_the_lowest_integrity_of_the_longer_growths():
    from physics import check_statics

    nca = NCAConfig(hidden=8, iterations=2, max_vertices=200)
    settings = StructuresSettings(evaluator="statics", nca=nca, also_grow=[3, 4])
    assert settings.also_grow == (3, 4)  # a TOML array becomes a tuple
    problem = StableStructures(settings)
    assert problem.field_names[-1] == "grown_integrity"
    genomes = problem.initial_genomes(6, np.random.default_rng(2))
    genomes[0] = 0.0  # never fires: the lone seed at any length, integrity 1 (random blobs break)
    result = problem.evaluate(genomes, np.arange(6))
    for genome, objective, grown in zip(genomes, result.objective, result.fields["grown_integrity"]):
        q = check_statics(grow(genome, nca), settings.physics).score
        lowest = min(check_statics(grow(genome, replace(nca, iterations=n)), settings.physics).integrity for n in (3, 4))
        assert grown == lowest and objective == pytest.approx(q * lowest)
    assert result.fields["grown_integrity"][0] == 1 and min(result.fields["grown_integrity"]) < 1


@pytest.mark.parametrize("lengths", [[0], [2.5], "8", [True]])
def test_bad_growth_lengths_are_refused(lengths):
    with pytest.raises(ValueError, match="also_grow must be a list of growth lengths"):
        StructuresSettings(also_grow=lengths)
