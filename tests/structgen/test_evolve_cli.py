"""structgen evolve / resume / export RUN_DIR: run folders, reproducibility, interruption, clusters, bad configs."""

from __future__ import annotations

import hashlib
import json
import shutil
import signal
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from structgen.cli import main
from tests.helpers import OPTIMIZER_SETTINGS, cli, kill_during_evolve, outcome, structgen_command, tiny_config, wait_for_lines


# The paper's problem in miniature: growth capped at 16 vertices, 4 children a generation, fast physics.
# -- evolve ---------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("optimizer", list(OPTIMIZER_SETTINGS))
def test_evolve_writes_a_complete_run_folder(tmp_path, capsys, optimizer):
    run = tmp_path / "run"
    code, out, err = cli(capsys, "evolve", tiny_config(tmp_path, optimizer), "--run-dir", run)
    assert code == 0, err
    assert out.splitlines()[0].startswith(f"{run}: 4 generations") and "best: objective" in out
    names = {p.name for p in run.iterdir()}
    assert {"config.toml", "manifest.json", "checkpoint.pkl", "metrics.jsonl", "objective.png", "best"} <= names
    quality_diversity = optimizer in ("map_elites", "cma_mae")
    assert ({"archive.csv", "archive_solutions.npy", "archive.png", "qd.png"} <= names) is quality_diversity
    if quality_diversity:  # one column per name: height is a measure and a field, written once
        header = (run / "archive.csv").read_text().splitlines()[0].split(",")
        assert len(header) == len(set(header)) and header.count("height") == 1 and "cell_height" in header
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert [r["generation"] for r in rows] == [1, 2, 3, 4]
    for key in ("evaluations", "best_objective", "mean_objective", "best_integrity", "best_height", "best_complexity", "wall_s"):
        assert key in rows[-1]
    assert ("qd_score" in rows[-1] and "coverage" in rows[-1]) is quality_diversity
    assert {p.name for p in (run / "best").iterdir()} >= {
        "genome.npy",
        "structure.json",
        "structure.glb",
        "structure.png",
        "report.json",
    }
    manifest = json.loads((run / "manifest.json").read_text())
    assert manifest["versions"]["pybullet"] and manifest["versions"]["torch"]
    assert f'name = "{optimizer}"' in (run / "config.toml").read_text()


@pytest.mark.slow
def test_same_config_and_seed_give_the_same_run(tmp_path, capsys):
    config = tiny_config(tmp_path)
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "a")
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "b")
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "c", "--seed", 4)
    assert outcome(tmp_path / "a") == outcome(tmp_path / "b")
    assert outcome(tmp_path / "a") != outcome(tmp_path / "c")


def test_evolve_never_overwrites_a_run_unless_told(tmp_path, capsys):
    config, run = tiny_config(tmp_path), tmp_path / "run"
    assert cli(capsys, "evolve", config, "--run-dir", run, "--generations", 1)[0] == 0
    before = (run / "metrics.jsonl").read_bytes()
    code, out, err = cli(capsys, "evolve", config, "--run-dir", run)
    assert code == 2 and "already exists; choose another --run-dir or pass --overwrite" in err
    assert (run / "metrics.jsonl").read_bytes() == before
    assert cli(capsys, "evolve", config, "--run-dir", run, "--overwrite")[0] == 0
    assert len((run / "metrics.jsonl").read_text().splitlines()) == 4


@pytest.mark.parametrize(
    "content, args, message",
    [
        ("[optimizer]\nname = 'nsga'\n", [], "unknown optimizer.name 'nsga'"),
        ("[run]\ngenerations = 'many'\n", [], "run.generations = 'many': expected an integer"),
        ("[problem.nca]\nhiden = 30\n", [], "unknown setting 'problem.nca.hiden'"),
        ("", ["--optimizer", "pso"], "unknown optimizer.name 'pso'"),
        ("", ["--set", "optimizer.parents=-1"], "parents must be a positive integer"),
    ],
)
def test_bad_configurations_fail_before_any_work(tmp_path, capsys, content, args, message):
    config = tmp_path / "bad.toml"
    config.write_text(content)
    code, out, err = cli(capsys, "evolve", config, "--run-dir", tmp_path / "run", *args)
    assert code == 2 and out == "" and message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "run").exists()


@pytest.mark.slow
def test_main_job_defaults_run(tmp_path, capsys):
    code, out, err = cli(capsys, "evolve", "--generations", 1, "--workers", 0, "--run-dir", tmp_path / "main")
    assert code == 0, err
    config = (tmp_path / "main" / "config.toml").read_text()
    assert 'name = "structures-v0"' in config and "population = 40" in config and "max_vertices = 64" in config
    assert "40 evaluations" in out


# -- resume -------------------------------------------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("optimizer", ["ga", "cma_mae"])
def test_two_plus_two_generations_equal_four(tmp_path, capsys, optimizer):
    config = tiny_config(tmp_path, optimizer)
    assert cli(capsys, "evolve", config, "--run-dir", tmp_path / "whole")[0] == 0
    assert cli(capsys, "evolve", config, "--run-dir", tmp_path / "split", "--generations", 2)[0] == 0
    code, out, _ = cli(capsys, "resume", tmp_path / "split", "--generations", 4)
    assert code == 0 and "4 generations" in out
    assert outcome(tmp_path / "split") == outcome(tmp_path / "whole")
    assert "generations = 4" in (tmp_path / "split" / "config.toml").read_text()


@pytest.mark.slow
@pytest.mark.parametrize("stage", ["between checkpoints", "before the first checkpoint"])
def test_killed_run_resumes_to_the_same_result(tmp_path, capsys, stage):
    config = tiny_config(tmp_path)
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "whole", "--generations", 12)
    run = tmp_path / "killed"
    never = ["--set", "run.checkpoint_every=100", "--set", "run.checkpoint_seconds=0"] if stage.startswith("before") else []
    kill_during_evolve(config, run, 3, "--generations", "12", *never)
    assert (run / "checkpoint.pkl").exists() == (not never)
    code, out, err = cli(capsys, "resume", run)
    assert code == 0, err
    assert ("starting again from the beginning" in err) == bool(never)
    assert outcome(run) == outcome(tmp_path / "whole")


@pytest.mark.slow
def test_ctrl_c_finishes_the_generation_checkpoints_and_exits_130(tmp_path, capsys):
    config = tiny_config(tmp_path)
    run = tmp_path / "interrupted"
    process = subprocess.Popen(
        [*structgen_command(), "evolve", str(config), "--run-dir", str(run), "--generations", "40"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    wait_for_lines(run / "metrics.jsonl", 2, process)
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert "finishing this generation" in err
    rows = (run / "metrics.jsonl").read_text().splitlines()
    stopped_at = json.loads(rows[-1])["generation"]
    assert 2 <= stopped_at < 40 and f"{stopped_at} generations" in out
    assert cli(capsys, "resume", run, "--generations", stopped_at + 2)[0] == 0
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "whole", "--generations", stopped_at + 2)
    assert outcome(run) == outcome(tmp_path / "whole")


def test_resume_of_a_finished_run_does_nothing_and_bad_folders_fail(tmp_path, capsys):
    config = tiny_config(tmp_path)
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "run", "--generations", 2)
    before = outcome(tmp_path / "run")
    assert cli(capsys, "resume", tmp_path / "run")[0] == 0
    assert outcome(tmp_path / "run") == before
    code, _, err = cli(capsys, "resume", tmp_path / "run", "--generations", 1)
    assert code == 2 and "fewer than the 2 already run" in err
    code, _, err = cli(capsys, "resume", tmp_path / "nowhere")
    assert code == 2 and "no such run folder" in err
    (tmp_path / "run" / "config.toml").write_text("[optimizer]\nname = 'x'\n")
    code, _, err = cli(capsys, "resume", tmp_path / "run")
    assert code == 2 and "config.toml: unknown optimizer.name 'x'" in err


# -- evaluation on a Dask cluster ---------------------------------------------------------------------------------------
@pytest.mark.slow
def test_cluster_evaluation_gives_the_same_run(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    config = tiny_config(tmp_path)
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "local", "--generations", 2)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        code, _, err = cli(
            capsys,
            "evolve",
            config,
            "--run-dir",
            tmp_path / "cluster",
            "--generations",
            2,
            "--cluster",
            cluster.scheduler_address,
        )
    assert code == 0, err
    assert outcome(tmp_path / "cluster") == outcome(tmp_path / "local")


# -- export -------------------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def qd_run(tmp_path_factory) -> Path:
    """A finished MAP-Elites run, shared by the tests that only read it."""
    folder = tmp_path_factory.mktemp("qd")
    assert main(["evolve", str(tiny_config(folder, "map_elites")), "--run-dir", str(folder / "run")]) == 0
    return folder / "run"


@pytest.fixture(scope="module")
def ga_run(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("ga")
    assert main(["evolve", str(tiny_config(folder)), "--run-dir", str(folder / "run"), "--generations", "1"]) == 0
    return folder / "run"


def test_export_the_best_and_an_archive_elite(tmp_path, capsys, qd_run):
    code, out, _ = cli(capsys, "export", qd_run, "-o", tmp_path / "best.glb")
    assert code == 0
    best = json.loads((qd_run / "best" / "structure.json").read_text())
    assert f"{len(best['vertices'])} vertices" in out
    assert trimesh.load(tmp_path / "best.glb").metadata["n_vertices"] == len(best["vertices"])
    header, *rows = (qd_run / "archive.csv").read_text().splitlines()
    columns = header.split(",")
    row = dict(zip(columns, rows[-1].split(",")))
    code, out, _ = cli(capsys, "export", qd_run, "-o", tmp_path / "elite.json", "--elite", f"index:{row['index']}")
    assert code == 0
    elite = json.loads((tmp_path / "elite.json").read_text())
    assert len(elite["vertices"]) == int(float(row["vertices"])) and elite["metadata"]["elite"] == f"index:{row['index']}"


def test_export_takes_its_output_after_the_options_too(tmp_path, capsys, qd_run):
    # argparse alone gives both positionals to the words before the first option and refuses an OUT after them.
    code, _, err = cli(capsys, "export", qd_run, "--elite", "best", tmp_path / "best.obj")
    assert code == 0, err
    assert trimesh.load(tmp_path / "best.obj").vertices.shape[0] > 0
    code, _, err = cli(capsys, "export", qd_run, "--elite", "best", tmp_path / "best.obj", tmp_path / "again.obj")
    assert code == 2 and "unrecognized arguments" in err and not (tmp_path / "again.obj").exists()
    code, _, err = cli(capsys, "export", qd_run, "--elite", "best", tmp_path / "no-folder" / "x" / "best.obj")
    assert code == 2 and "no-folder" in err


def test_a_run_loads_back_from_python_with_its_archive_and_best_nca(qd_run):
    from evolution import load_archive
    from structgen.nca import LocalNCA
    from structgen.runs import load_run

    with load_run(qd_run) as run:
        archive, best_genome = run.archive(), run.best_genome()
        nca = run.problem.nca(best_genome)
        with pytest.deprecated_call():
            assert np.array_equal(run.best_nca().get_weights(), best_genome)
        rows = run.metrics()
    assert isinstance(nca, LocalNCA) and np.array_equal(nca.get_weights(), best_genome)
    assert nca.config.max_vertices == 16  # the run's NCA settings, not the defaults
    header, *lines = (qd_run / "archive.csv").read_text().splitlines()
    assert len(archive) == len(lines) == rows[-1]["num_elites"]
    assert archive.measure_names == ("height", "vertices") and archive.cells.shape == (len(lines), 2)
    first = dict(zip(header.split(","), lines[0].split(",")))
    assert archive.row(0)["index"] == int(first["index"]) and archive.objective[0] == float(first["objective"])
    assert archive.genomes.shape == (len(lines), best_genome.size)
    # the best archive elite grows the structure its row describes
    top = archive.best()
    assert run.problem.structure_of(archive.genomes[top]).n_vertices == archive.columns["vertices"][top]
    numbers_only = load_archive(qd_run)
    assert numbers_only.genomes is None and np.array_equal(numbers_only.objective, archive.objective)


def test_info_summarises_a_run_folder(capsys, qd_run, ga_run):
    code, out, err = cli(capsys, "info", qd_run)
    assert code == 0, err
    assert "structures-v0" in out and "map_elites, seed 3" in out and "4 of 4 generations" in out
    assert "elites, coverage" in out and "QD score" in out
    code, out, _ = cli(capsys, "info", qd_run, "--json")
    summary = json.loads(out)
    rows = [json.loads(line) for line in (qd_run / "metrics.jsonl").read_text().splitlines()]
    assert summary["archive"]["qd_score"] == rows[-1]["qd_score"] and summary["generations"] == 4
    code, out, _ = cli(capsys, "info", ga_run)
    assert "1 of 1 generations" in out and "(resume to go on)" not in out and "archive" not in out


def test_compare_tabulates_and_plots_several_runs(tmp_path, capsys, qd_run, ga_run):
    code, out, err = cli(capsys, "compare", qd_run, ga_run, "-o", tmp_path / "c.png", "--json")
    assert code == 0, err
    table = json.loads(out)
    assert [row["optimizer"] for row in table] == ["map_elites", "ga"]
    assert table[0]["qd_score"] is not None and table[1]["qd_score"] is None
    assert (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG"
    code, _, err = cli(capsys, "compare", qd_run, tmp_path / "nowhere", "-o", tmp_path / "d.png")
    assert code == 2 and "nowhere" in err and not (tmp_path / "d.png").exists()
    tampered = tmp_path / "tampered"
    shutil.copytree(ga_run, tampered)
    rows = (tampered / "metrics.jsonl").read_text().splitlines()
    rows[-1] = rows[-1].replace('"best_objective": ', '"best_objective": "lots", "was": ', 1)
    (tampered / "metrics.jsonl").write_text("\n".join(rows) + "\n")
    code, _, err = cli(capsys, "compare", qd_run, tampered, "-o", tmp_path / "e.png")
    assert code == 2 and f"metrics.jsonl, line {len(rows)}: best_objective = 'lots' is not a finite number" in err
    assert not (tmp_path / "e.png").exists()


@pytest.mark.parametrize(
    "elite, message",
    [("index:99999", "no elite in cell 99999"), ("top", "use 'best' or 'index:I'"), ("index:x", "use 'best' or 'index:I'")],
)
def test_export_of_unknown_elites_fails_clearly(tmp_path, capsys, qd_run, elite, message):
    code, _, err = cli(capsys, "export", qd_run, "-o", tmp_path / "x.glb", "--elite", elite)
    assert code == 2 and message in err and not (tmp_path / "x.glb").exists()


def test_export_index_needs_an_archive(tmp_path, capsys, ga_run):
    code, _, err = cli(capsys, "export", ga_run, "-o", tmp_path / "x.glb", "--elite", "index:0")
    assert code == 2 and "has no archive" in err


def test_export_from_a_toy_run_says_there_is_no_structure(tmp_path, capsys):
    config = tmp_path / "sphere.toml"
    config.write_text(
        "[run]\ngenerations = 1\nworkers = 0\n[problem]\nname = 'sphere'\n[optimizer]\nname = 'ga'\npopulation = 4\nparents = 1\n"
    )
    cli(capsys, "evolve", config, "--run-dir", tmp_path / "toy")
    assert (tmp_path / "toy" / "best" / "genome.npy").exists()
    assert np.load(tmp_path / "toy" / "best" / "genome.npy").shape == (8,)
    code, _, err = cli(capsys, "export", tmp_path / "toy", "-o", tmp_path / "x.glb")
    assert code == 2 and "the sphere-v0 domain has nothing to export" in err


@pytest.mark.parametrize("evaluator", ["statics", "statics+bullet"])
def test_evolve_with_the_static_evaluators_records_which_scored(tmp_path, capsys, evaluator):
    run = tmp_path / "run"
    code, _, err = cli(capsys, "evolve", tiny_config(tmp_path, "map_elites"), "--run-dir", run, "--set", f"evaluator={evaluator}")
    assert code == 0, err
    assert f'evaluator = "{evaluator}"' in (run / "config.toml").read_text()
    header, *rows = (run / "archive.csv").read_text().splitlines()
    column = header.split(",").index("evaluator")
    scored_by = {float(row.split(",")[column]) for row in rows}
    # With statics+bullet, what statics predicts to fall keeps its score and what it predicts to stand is simulated:
    # this run has both.
    assert scored_by == ({0.0} if evaluator == "statics" else {0.0, 1.0})


def test_evolve_with_the_transient_evaluator_records_the_peak_force(tmp_path, capsys):
    run = tmp_path / "run"
    code, _, err = cli(capsys, "evolve", tiny_config(tmp_path, "cma_es"), "--run-dir", run, "--set", "evaluator=transient")
    assert code == 0, err
    rows = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    assert all(row["best_evaluator"] == 1 and 0 < row["best_integrity"] <= 1 for row in rows)
    assert "best_peak_force" in rows[-1]
    assert json.loads((run / "best" / "report.json").read_text())["method"] == "transient"


def test_a_run_keeps_its_own_copy_of_the_genome_it_starts_from(tmp_path, capsys):
    start = tmp_path / "start.npy"
    np.save(start, np.full(8, 0.25))
    config = tmp_path / "sphere.toml"
    config.write_text(
        f"[run]\ngenerations = 2\nworkers = 0\n[problem]\nname = 'sphere'\n[optimizer]\nname = 'cma_es'\n"
        f"population = 4\nx0 = '{start}'\n"
    )
    code, _, err = cli(capsys, "evolve", config, "--run-dir", tmp_path / "run")
    assert code == 0, err
    assert (tmp_path / "run" / "x0.npy").read_bytes() == start.read_bytes()
    recorded = json.loads((tmp_path / "run" / "manifest.json").read_text())["x0"]
    assert recorded["source"] == str(start) and recorded["copy"] == "x0.npy"
    assert recorded["sha256"] == hashlib.sha256(start.read_bytes()).hexdigest()
    start.unlink()  # the run goes on from its checkpoint without the file it started from
    code, out, err = cli(capsys, "resume", tmp_path / "run", "--generations", "3")
    assert code == 0, err


def test_an_option_that_is_a_setting_points_to_set(tmp_path, capsys):
    code, out, err = cli(capsys, "evolve", "--evaluator", "statics", "--run-dir", tmp_path / "run")
    assert code == 2 and out == "" and not (tmp_path / "run").exists()
    assert "unrecognized arguments: --evaluator statics (settings go through --set: --set evaluator=statics)" in err


def test_grow_a_runs_best_further(tmp_path, capsys, ga_run):
    code, out, err = cli(capsys, "grow", "--run", ga_run, "--iterations", 2, "--max-vertices", 5000, "-o", tmp_path / "more.json")
    assert code == 0, err
    grown = json.loads((tmp_path / "more.json").read_text())
    assert grown["metadata"]["growth"]["iterations"] == 2 and grown["metadata"]["growth"]["max_vertices"] == 5000
    assert grown["metadata"]["growth"]["hidden"] == 60 and grown["metadata"]["run"] == str(ga_run)
    code, _, err = cli(capsys, "grow", "--run", tmp_path / "nowhere", "-o", tmp_path / "x.json")
    assert code == 2 and "no such run folder" in err
