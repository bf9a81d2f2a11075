"""Training layouts through the generic run machinery: the paper's CMA-MAE shape on a tiny warehouse, its run folder,
and a run killed with SIGKILL that resumes to the result of one never stopped."""

from __future__ import annotations

import json

import pytest

from structgen.domains.layouts.grid import Grid
from tests.helpers import cli, kill_during_evolve, outcome

# configs/warehouse_cma_mae.toml in miniature: every optimiser setting of the paper's, a 6x8 floor, 4 robots.
TINY_WAREHOUSE = """\
[run]
generations = 4
seed = 1
workers = 0
checkpoint_every = 1

[problem]
name = "warehouse-v0"
size = "6x8"
shelves = 6
iterations = 5
hidden = 8
repair_node_limit = 50
agents = 4
simulations = 2
simulation_steps = 40

[optimizer]
name = "cma_mae"
emitters = 2
batch_size = 3
sigma0 = 0.2
learning_rate = 0.01
threshold_min = 0.0
es = "cma_es"
ranker = "imp"
selection = "mu"
restart = "no_improvement"
result_archive = true
x0 = "zeros"
cells = [6, 10]
"""


@pytest.mark.slow
def test_a_killed_warehouse_run_resumes_to_the_same_result(tmp_path, capsys):
    config = tmp_path / "warehouse.toml"
    config.write_text(TINY_WAREHOUSE)
    code, out, err = cli(capsys, "evolve", config, "--run-dir", tmp_path / "whole")
    assert code == 0, err
    whole = tmp_path / "whole"
    names = {p.name for p in whole.iterdir()}
    assert {"objective.png", "archive.png", "qd.png", "archive.csv", "metrics.jsonl"} <= names
    best = json.loads((whole / "best" / "best.json").read_text())
    layout = Grid.load(whole / "best" / "layout.json")
    assert layout.shape == (6, 12) and layout.count("@") == 6  # repaired to the exact shelf count, with workstations
    assert (whole / "best" / "layout.png").read_bytes()[:4] == b"\x89PNG"
    assert best["objective"] == pytest.approx(best["fields"]["throughput"] + 5 * best["fields"]["similarity"])
    rows = [json.loads(line) for line in (whole / "metrics.jsonl").read_text().splitlines()]
    assert [r["generation"] for r in rows] == [1, 2, 3, 4] and rows[-1]["num_elites"] >= 1

    run = tmp_path / "killed"
    kill_during_evolve(config, run, 2, limit=300)
    code, out, err = cli(capsys, "resume", run)
    assert code == 0, err
    assert outcome(run) == outcome(whole)
    assert (run / "best" / "layout.json").read_bytes() == (whole / "best" / "layout.json").read_bytes()


def test_the_best_layout_written_is_the_one_that_was_scored(tmp_path, monkeypatch):
    """A run's best/layout.json is the repaired layout its score came from, not a new repair: with a time limit a
    second repair can end elsewhere (a 33x36 best was scored on 204 changed cells and written with 518)."""
    import numpy as np

    from evolution.problem import Evaluation
    from structgen.domains.layouts.problem import LayoutProblem, WarehouseSettings

    settings = WarehouseSettings(size="6x8", shelves=6, iterations=5, hidden=8, repair_node_limit=50, agents=4, simulations=1)
    problem = LayoutProblem(settings)
    genomes = problem.initial_genomes(3, np.random.default_rng(0))
    scored = problem.evaluate(genomes, np.arange(3))
    top = int(np.argmax(scored.objective))
    # Stand-ins for what a second repair might give, told apart from the scored layouts by their shelves' places.
    moved = [(np.roll(tiles, 1, axis=1), optimal) for tiles, optimal in scored.extras]
    assert not (moved[top][0] == scored.extras[top][0]).all()
    problem.record(tmp_path, 1, genomes, Evaluation(scored.objective, scored.measures, scored.fields, extras=moved))
    repairs = []
    monkeypatch.setattr(problem, "_repair", lambda tiles, seed: repairs.append(seed) or pytest.fail("repaired again"))
    problem.write_artifacts(genomes[top], tmp_path)
    assert repairs == [] and (Grid.load(tmp_path / "layout.json").tiles == moved[top][0]).all()
    # A lower score later does not displace it; any other genome is repaired afresh (seed 0).
    worse = Evaluation(scored.objective - 1.0, scored.measures, scored.fields, extras=scored.extras)
    problem.record(tmp_path, 2, genomes[::-1], worse)
    problem.write_artifacts(genomes[top], tmp_path)
    assert (Grid.load(tmp_path / "layout.json").tiles == moved[top][0]).all()
    with pytest.raises(pytest.fail.Exception, match="repaired again"):
        problem.write_artifacts(genomes[(top + 1) % 3], tmp_path)
    assert repairs == [0]


def test_training_sends_layouts_far_from_valid_to_the_greedy_repair_as_its_setting_says(monkeypatch):
    import numpy as np

    from structgen.domains.layouts import problem as layout_problem
    from structgen.domains.layouts.problem import LayoutProblem, WarehouseSettings

    with pytest.raises(ValueError, match="problem repair_greedy_beyond = -2: expected a whole number from -1 to 1,000,000,000"):
        WarehouseSettings(repair_greedy_beyond=-2)
    asked = []
    real = layout_problem.repair
    monkeypatch.setattr(layout_problem, "repair", lambda *a, **k: asked.append(k["greedy_beyond"]) or real(*a, **k))
    tiny = dict(size="6x8", shelves=6, iterations=5, hidden=8, repair_node_limit=50, agents=4, simulations=1)
    genomes = LayoutProblem(WarehouseSettings(**tiny)).initial_genomes(1, np.random.default_rng(0))
    for beyond, expected in ((-1, None), (0, 0), (100, 100)):
        LayoutProblem(WarehouseSettings(**tiny, repair_greedy_beyond=beyond)).evaluate(genomes, np.arange(1))
        assert asked.pop() == expected
    # Which path each layout took is in its fields: HiGHS, or the cheap path's patch repair (else its row repair).
    many = LayoutProblem(WarehouseSettings(**{**tiny, "size": "33x36", "shelves": 240, "iterations": 50, "hidden": 32}))
    monkeypatch.setattr(layout_problem, "repair", real)
    grown = many.initial_genomes(6, np.random.default_rng(4)) * 5  # far from valid: the cheap path
    fields = many.evaluate(grown, np.arange(6)).fields
    assert set(many.mean_fields) == {"highs", "patched", "timed_out"}
    assert (fields["highs"] == 0).all() and 0 < fields["patched"].sum() < 6


def test_training_repairs_with_the_bounded_search_unless_told_to_search_in_full(monkeypatch):
    import numpy as np

    from structgen.domains.layouts import problem as layout_problem
    from structgen.domains.layouts.problem import LayoutProblem, ManufacturingSettings

    with pytest.raises(ValueError, match="problem repair_search must be one of bounded, full, got 'fast'"):
        ManufacturingSettings(repair_search="fast")
    asked = []
    real = layout_problem.repair
    monkeypatch.setattr(layout_problem, "repair", lambda *a, **k: asked.append(k["bounded"]) or real(*a, **k))
    tiny = dict(size="4x4", iterations=5, hidden=8, agents=1, simulations=1, simulation_steps=10)
    genomes = LayoutProblem(ManufacturingSettings(**tiny)).initial_genomes(1, np.random.default_rng(0))
    for search, expected in (("bounded", True), ("full", False)):
        LayoutProblem(ManufacturingSettings(**tiny, repair_search=search)).evaluate(genomes, np.arange(1))
        assert asked.pop() is expected
    assert ManufacturingSettings().repair_search == "bounded"


@pytest.mark.slow
def test_a_run_summed_up_for_docs_regrows_its_best_layout_from_the_committed_weights(tmp_path, capsys):
    import runpy
    import sys
    from pathlib import Path

    import numpy as np

    from structgen.runs.experiment import load_experiment

    config = tmp_path / "warehouse.toml"
    config.write_text(TINY_WAREHOUSE.replace("generations = 4", "generations = 1"))
    code, _, err = cli(capsys, "evolve", config, "--run-dir", tmp_path / "run")
    assert code == 0, err
    script = Path(__file__).parents[2] / "benchmarks" / "layout_run_summary.py"

    def summed_up(run: str, name: str, out: str) -> dict:
        argv, sys.argv = sys.argv, [str(script), str(tmp_path / run), "--name", name, "-o", str(tmp_path / out)]
        try:
            runpy.run_path(str(script), run_name="__main__")
        finally:
            sys.argv = argv
        return json.loads((tmp_path / out / f"{name}_summary.json").read_text())

    summary = summed_up("run", "tiny", "docs")
    assert summary["evaluations"] == 6 and summary["share_of_paper_budget"] == 6 / 10_000
    assert [row["generation"] for row in summary["curve"]] == [1]
    assert {p.name for p in (tmp_path / "docs").iterdir()} == {
        "tiny_generator.npy", "tiny_throughput_generator.npy", "tiny_summary.json", "tiny_qd.png", "tiny_archive.png",
        "tiny_layout.png",
    }  # fmt: skip
    # The result archive's highest throughput, kept beside the best by the objective.
    archive = (tmp_path / "run" / "archive.csv").read_text().splitlines()
    objective = [float(line.split(",")[1]) for line in archive[1:]]
    assert summary["top_throughput"]["objective"] == max(objective)
    assert sum(summary["elite_repair_paths"].values()) == len(objective)  # each elite's repair, by its path
    solutions = np.load(tmp_path / "run" / "archive_solutions.npy")
    np.testing.assert_array_equal(np.load(tmp_path / "docs" / "tiny_throughput_generator.npy"), solutions[np.argmax(objective)])
    problem = load_experiment(tmp_path / "run" / "config.toml").make_problem()
    regrown = problem.grow(np.load(tmp_path / "docs" / "tiny_generator.npy")[None])[0]
    assert (regrown == Grid.load(tmp_path / "run" / "best" / "unrepaired.json").tiles).all()
    # A maze run: against the paper's maze budget (100,000) and Table 4 row, with no throughput or repair to report.
    code, _, err = cli(
        capsys, "evolve", "--domain", "maze-v0", "--set", "problem.size=8x8", "--set", "problem.episodes=2",
        "--set", "optimizer.batch_size=4", "--set", "optimizer.emitters=1", "--generations", "1",
        "--run-dir", tmp_path / "maze",
    )  # fmt: skip
    assert code == 0, err
    summary = summed_up("maze", "maze", "mazes")
    assert summary["domain"] == "maze" and summary["share_of_paper_budget"] == 4 / 100_000
    assert summary["paper"]["qd_score"]["mean"] == 22299.0 and "top_throughput" not in summary
