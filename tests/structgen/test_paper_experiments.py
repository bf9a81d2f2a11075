"""The stable-structures paper's four experiments: their configuration files hold the paper's settings, spawns map to
generations as the paper counts them, the screened judge routes structures as it says, and the experiment command
runs seeds, keeps their structures at the paper's spawn numbers, resumes, writes the table and draws the figure."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from structgen.domains.structures.experiment import EXPERIMENTS, generation_of, spawns_by
from structgen.domains.structures.problem import StableStructures, StructuresSettings
from structgen.domains.structures.samples import column
from structgen.nca import NCAConfig
from structgen.runs.experiment import load_experiment
from tests.helpers import cli, outcome

ROOT = Path(__file__).resolve().parents[2]


def test_spawns_fall_in_generations_as_the_paper_counts_them():
    # 100 networks in the first generation, 80 in every later one; the paper's spawn 7,480 came in its 93rd
    # iteration after the first population, generation 94 here.
    assert [generation_of(s) for s in (1, 100, 101, 180, 181)] == [1, 1, 2, 2, 3]
    assert generation_of(7_480) == 94 and generation_of(28_577) == 357
    assert spawns_by(357) == 28_580 and spawns_by(1) == 100


@pytest.mark.parametrize("name", list(EXPERIMENTS))
def test_each_configuration_file_holds_the_papers_settings(name):
    experiment = load_experiment(ROOT / EXPERIMENTS[name].config)
    ga, problem = experiment.optimizer_settings, experiment.problem_settings
    assert experiment.optimizer_name == "ga"
    assert (ga.population, ga.parents, ga.crossover_rate, ga.mutation_scale) == (100, 20, 0.0, 0.25)
    assert problem.nca.iterations == 5 and problem.nca.hidden == 60 and problem.nca.max_vertices == 2**31 - 1
    assert (problem.physics.break_force, problem.physics.height_weight, problem.physics.complexity_weight) == (52.5, 1, 1)
    assert problem.nca.cutoff == (0.6 if name == "cutoff" else 0.5)
    assert problem.nca.build_down is (name != "no-build-down")
    assert problem.physics.height_mode == ("mean" if name == "average-height" else "max")
    # The run reaches the end of the generation holding the paper's spawn budget.
    assert experiment.run.generations == generation_of(EXPERIMENTS[name].spawns)


def test_the_screened_judge_scores_crushed_blocks_as_collapsed_without_a_solve():
    problem = StableStructures(StructuresSettings(evaluator="screened", nca=NCAConfig(max_vertices=2**31 - 1)))
    # A random network of the paper's settings builds a block of about a thousand vertices.
    genome = problem.initial_genomes(1, np.random.default_rng(0))
    result = problem.evaluate(genome, np.zeros(1))
    assert result.fields["complexity"][0] > 500
    assert result.fields["evaluator"][0] == 2 and result.objective[0] == 0 and result.fields["integrity"][0] == 0
    # Below the threshold the static analysis decides, and the simulation where it says the structure stands.
    lenient = StableStructures(StructuresSettings(evaluator="screened", collapse_ratio=2.0))
    assert lenient.judge(column(6)).method == "statics"  # 1.87 times over: far past the margin, a solve decides
    assert lenient.judge(column(4)).method == "bullet"  # 1.12 times over: close enough to simulate
    assert lenient.judge(column(3)).method == "bullet"  # predicted to stand: simulated
    strict = StableStructures(StructuresSettings(evaluator="screened", collapse_ratio=1.0))
    assert strict.judge(column(4)).method == "collapse"
    with pytest.raises(ValueError, match="collapse_ratio"):
        StructuresSettings(collapse_ratio=0.5)


@pytest.mark.slow
def test_an_experiment_keeps_its_spawns_writes_its_table_and_draws_its_figure(tmp_path, capsys):
    out = tmp_path / "cutoff"
    # 400 spawns: five generations, the last holding the paper's spawn 381. Evaluated in the run's own process
    # (--workers 0): the suite already keeps both cores busy, and a worker process only adds its start-up.
    results = tmp_path / "results" / "table"
    experiment = ("structures", "experiment", "cutoff", out, "--seeds", "3", "--workers", "0", "--json")
    code, printed, _ = cli(capsys, *experiment, "--spawns", "400", "--results", results)
    assert code == 0
    report = json.loads(printed)
    # The tables of all four experiments gain this one, keyed by its name.
    assert json.loads(results.with_suffix(".json").read_text()) == {"cutoff": report}
    assert "### cutoff: 1 run of" in results.with_suffix(".md").read_text()
    assert report == json.loads((out / "table.json").read_text())
    run = report["runs"][0]
    assert run["generations"] == 5 and run["spawns"] == 420
    assert report["paper_spawn_budget"] == 5_800 and report["spawn_budget"] == 400
    kept = out / "seed-3-spawns"
    assert sorted(p.name for p in kept.iterdir()) == ["spawn-381"]
    assert np.load(kept / "spawn-381" / "parents.npy").shape == (20, 4766)
    assert "| 3 | 420 |" in (out / "table.md").read_text()
    assert sum(r["generations"] for r in run["table_1"].values()) == 5
    # With no worker processes the run's own process is the one core that evaluated (0 once divided by zero).
    assert all(r["core_seconds_per_structure"] > 0 for r in run["table_1"].values())
    # Run again: nothing to do.
    metrics = (out / "seed-3" / "metrics.jsonl").read_text()
    assert cli(capsys, *experiment, "--spawns", "400")[0] == 0
    assert (out / "seed-3" / "metrics.jsonl").read_text() == metrics
    assert json.loads((out / "table.json").read_text())["experiment"] == "cutoff"  # a folder already there kept the name
    # Asked for more, the run resumes where it stopped and keeps its best at the next sample spawn, 500.
    assert cli(capsys, *experiment, "--spawns", "500")[0] == 0
    assert json.loads((out / "table.json").read_text())["runs"][0]["generations"] == 6
    assert (out / "seed-3" / "metrics.jsonl").read_text().startswith(metrics)
    assert json.loads((kept / "spawn-500" / "best.json").read_text())["generation"] <= 6
    # --table-only runs nothing, even short of the budget: the table shows how far the run got.
    code, printed, _ = cli(
        capsys, "structures", "experiment", "cutoff", out, "--seeds", "3", "--spawns", "800", "--table-only", "--json"
    )
    assert code == 0 and json.loads(printed)["runs"][0]["generations"] == 6
    assert (out / "seed-3" / "metrics.jsonl").read_text().count("\n") == 6
    code, _, err = cli(capsys, "structures", "experiment", "cutoff", out, "--seeds", "3", "4", "--table-only")
    assert code == 2 and "seed-4" in err and not (out / "seed-4").exists()
    # Run in stages, a seed comes out as it would have run straight through.
    straight = tmp_path / "straight"
    config = ROOT / "configs/paper_cutoff.toml"
    assert cli(capsys, "evolve", config, "--seed", 3, "--generations", 6, "--run-dir", straight, "--set", "run.workers=0")[0] == 0
    assert outcome(straight) == outcome(out / "seed-3")
    code, printed, _ = cli(capsys, "structures", "figure", out)
    assert code == 0 and (out / "figure.png").read_bytes().startswith(b"\x89PNG")
    # Another configuration's run in a seed's folder is refused before anything runs, as is a missing file.
    code, _, err = cli(
        capsys, "structures", "experiment", "cutoff", out, "--seeds", "3", "--config", ROOT / "configs/paper_baseline.toml"
    )
    assert code == 2 and "seed-3" in err and "other settings" in err
    assert (out / "seed-3" / "metrics.jsonl").read_text().count("\n") == 6
    code, _, err = cli(capsys, "structures", "experiment", "cutoff", tmp_path / "b", "--config", tmp_path / "none.toml")
    assert code == 2 and "none.toml" in err
    assert not (tmp_path / "b").exists()  # refused before the folder was made
    code, _, err = cli(capsys, "structures", "figure", tmp_path / "b")
    assert code == 2 and "no such folder" in err
    (tmp_path / "b").mkdir()
    code, _, err = cli(capsys, "structures", "figure", tmp_path / "b")
    assert code == 2 and "no pictures" in err


def test_random_search_runs_an_experiment_at_the_gas_spawns_and_its_table_says_whether_the_ga_learns(tmp_path, capsys):
    """``--optimizer random`` runs the experiment's seeds as random search (100 genomes, then 80 a generation: the
    GA's spawns), its table kept beside the GA's in the results, with the three-standard-error verdict between them."""
    results = tmp_path / "results" / "table"
    common = ("--seeds", "0", "1", "--workers", "0", "--spawns", "180", "--results", results, "--json")
    assert cli(capsys, "structures", "experiment", "cutoff", tmp_path / "ga", *common)[0] == 0
    code, printed, _ = cli(capsys, "structures", "experiment", "cutoff", tmp_path / "random", *common, "--optimizer", "random")
    assert code == 0
    report = json.loads(printed)
    assert report["optimizer"] == "random" and [r["spawns"] for r in report["runs"]] == [180, 180]
    assert 'name = "random"' in (tmp_path / "random" / "seed-0" / "config.toml").read_text()
    assert not (tmp_path / "random" / "seed-0-spawns" / "spawn-381").exists()  # 180 spawns: before the first kept
    tables = json.loads(results.with_suffix(".json").read_text())
    assert list(tables) == ["cutoff", "cutoff --optimizer random"]
    text = results.with_suffix(".md").read_text()
    assert "### cutoff --optimizer random: 2 runs of configs/paper_cutoff.toml with --optimizer random" in text
    assert "#### cutoff: does the GA learn? Against random search at the same spawns and judge" in text
    assert "- best Q: the GA" in text and "three-standard-error rule" in text
    # The GA's folder is not random search's: running the baseline into it is refused before anything runs.
    code, _, err = cli(capsys, "structures", "experiment", "cutoff", tmp_path / "ga", *common, "--optimizer", "random")
    assert code == 2 and "other settings than this experiment's" in err


def test_the_learning_rule_is_three_standard_errors_of_the_difference():
    from evolution.stats import compare

    ahead = compare([10.0, 11.0, 12.0], [5.0, 6.0, 7.0])  # 5 apart, standard error of the difference 0.82
    assert ahead.standard_errors == pytest.approx(5 / np.hypot(1 / np.sqrt(3), 1 / np.sqrt(3)))
    assert ahead.learns and "the GA learns by the three-standard-error rule" in ahead.sentence("the GA", "random search")
    close = compare([10.0, 12.0, 14.0], [9.0, 10.0, 11.0])  # 2 apart, 1.29 standard errors
    assert not close.learns and "is not shown to learn" in close.sentence("the GA", "random search")
    assert not compare([0.0, 0.0], [0.0, 0.0]).learns  # both crushed to nothing: nothing learned
    behind = compare([0.0, 0.0, 0.0], [0.8, 1.2, 1.7])  # random search ahead: said so
    assert "random search is ahead of it by more than three" in behind.sentence("the GA", "random search")
    assert compare([1.0, 1.0], [0.0, 0.0]).learns  # no spread either side, yet always ahead
    one_seed = compare([10.0], [1.0, 2.0])
    assert not one_seed.learns and "cannot be told" in one_seed.sentence("the GA", "random search")


def test_a_comparisons_sentence_shows_small_measures_with_their_digits():
    from evolution.stats import compare, decimals_for

    assert decimals_for([429.3, 124.7], [45.9, 3.8]) == 2 and decimals_for([0.0106, 0.0031]) == 4
    assert decimals_for([9.75, 9.77], [0.0045, 0.0037]) == 3 and decimals_for([0.0, 0.0], [0.0, 0.0]) == 2
    coverage = compare([0.0084, 0.0111, 0.0122], [0.0030, 0.0029, 0.0033])
    assert "0.0106 ± 0.0011 against random search 0.0031 ± 0.0001" in coverage.sentence("CMA-MAE", "random search", decimals=4)


def test_a_seed_run_keeps_its_worker_count_when_it_is_resumed(tmp_path, monkeypatch):
    # A resumed run reads only its own config.toml: the experiment's --workers must reach it as an option, or a
    # resumed seed silently runs on the one process it was started with.
    import subprocess

    from structgen.runs import seed_runs

    commands = []

    def record(command, **_):
        commands.append(command)
        return subprocess.CompletedProcess(command, 0, "", "")

    monkeypatch.setattr(seed_runs.subprocess, "run", record)
    fresh, started = tmp_path / "fresh", tmp_path / "started"
    started.mkdir()
    (started / "config.toml").write_text("")
    seed_runs.run_seed("c.toml", (), 0, str(fresh), 1, 5, workers=2)
    seed_runs.run_seed("c.toml", (), 0, str(started), 1, 5, workers=2)
    assert commands[0][3] == "evolve" and commands[0][-2:] == ["--workers", "2"]
    assert commands[1][3:5] == ["resume", str(started)] and commands[1][-2:] == ["--workers", "2"]


def test_a_seed_run_stopped_by_ctrl_c_stops_the_experiment_with_exit_130_and_says_how_to_resume(tmp_path, monkeypatch, capsys):
    # Ctrl-C reaches the seed's own `structgen evolve`, which checkpoints and exits 130; the experiment once reported
    # that as a failed run (a RuntimeError, exit 1) though nothing had failed and the same command resumes it.
    import subprocess

    from structgen.runs import seed_runs

    monkeypatch.setattr(seed_runs.subprocess, "run", lambda command, **_: subprocess.CompletedProcess(command, 130, "", ""))
    out = tmp_path / "cutoff"
    code, _, err = cli(capsys, "structures", "experiment", "cutoff", out, "--seeds", "0", "--spawns", "100", "--json")
    assert code == 130
    assert "seed 0" in err and "stopped after its last checkpoint" in err and "same command resumes" in err
    assert not (out / "table.json").exists()
