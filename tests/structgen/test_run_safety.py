"""Run folders are owned: one writer at a time, edits to config.toml applied only where sound, leftovers of killed
writes cleaned, and a run that fails before its first checkpoint leaves nothing behind."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import structgen.runs.experiment
from evolution.toys import Sphere
from structgen.cli import main
from structgen.runs import evolve
from structgen.runs.experiment import load_experiment
from tests.helpers import findings

SPHERE = """\
[run]
generations = {generations}
workers = 0
seed = 2
[problem]
name = "sphere-v0"
[optimizer]
name = "ga"
population = 8
parents = 2
"""


def config(tmp_path: Path, generations: int = 4) -> Path:
    path = tmp_path / "sphere.toml"
    path.write_text(SPHERE.format(generations=generations))
    return path


def cli(capsys, *argv) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


@pytest.mark.slow
def test_a_second_writer_is_refused_while_a_run_is_going(tmp_path, capsys):
    slow = tmp_path / "slow.toml"
    # The structures domain with faithful physics: slow enough to be caught in the middle.
    slow.write_text(
        "[run]\ngenerations = 50\nworkers = 0\n[problem.nca]\nmax_vertices = 16\n"
        "[problem.physics]\npreset = 'faithful'\n[optimizer]\npopulation = 4\nparents = 1\n"
    )
    run = tmp_path / "run"
    process = subprocess.Popen(
        [sys.executable, "-m", "structgen", "evolve", str(slow), "--run-dir", str(run)], stderr=subprocess.PIPE
    )
    try:
        deadline = time.monotonic() + 120
        while not (run / "metrics.jsonl").exists():
            assert process.poll() is None and time.monotonic() < deadline, process.stderr.read().decode()
            time.sleep(0.1)
        code, err = cli(capsys, "resume", run)
        assert code == 2 and f"another process (pid {process.pid}) is writing this run" in err
        code, err = cli(capsys, "evolve", slow, "--run-dir", run, "--overwrite")
        assert code == 2 and "is writing this run" in err
        assert run.exists() and process.poll() is None
    finally:
        process.kill()
        process.wait()
    rows = findings(run / "metrics.jsonl")
    assert [row["generation"] for row in rows] == list(range(1, len(rows) + 1))  # one writer, nothing interleaved


def test_editing_how_long_a_run_goes_is_applied_and_recorded(tmp_path, capsys):
    cli(capsys, "evolve", config(tmp_path, 4), "--run-dir", tmp_path / "whole")
    assert cli(capsys, "evolve", config(tmp_path, 2), "--run-dir", tmp_path / "run")[0] == 0
    path = tmp_path / "run" / "config.toml"
    path.write_text(path.read_text().replace("generations = 2", "generations = 4").replace("plot_every = 10", "plot_every = 3"))
    assert cli(capsys, "resume", tmp_path / "run")[0] == 0
    assert findings(tmp_path / "run" / "metrics.jsonl") == findings(tmp_path / "whole" / "metrics.jsonl")
    assert "plot_every = 3" in path.read_text()


@pytest.mark.parametrize("edit, named", [("population = 8", "optimizer.population 8 -> 9"), ("seed = 2", "run.seed 2 -> 3")])
def test_editing_what_a_run_computes_is_refused_naming_the_setting(tmp_path, capsys, edit, named):
    run = tmp_path / "run"
    cli(capsys, "evolve", config(tmp_path, 2), "--run-dir", run)
    before = {name: (run / name).read_bytes() for name in ("metrics.jsonl", "checkpoint.pkl")}
    path = run / "config.toml"
    path.write_text(path.read_text().replace(edit, edit[:-1] + str(int(edit[-1]) + 1)))
    code, err = cli(capsys, "resume", run, "--generations", 4)
    assert code == 2 and "edited since the run began, in settings a run cannot change" in err and named in err
    assert len(err.strip().splitlines()) == 1
    assert {name: (run / name).read_bytes() for name in before} == before


def test_leftovers_of_a_killed_write_are_cleaned_on_resume(tmp_path, capsys):
    run = tmp_path / "run"
    cli(capsys, "evolve", config(tmp_path, 2), "--run-dir", run)
    leftover = run / ".checkpoint.pkl.0123456789ab.tmp"
    leftover.write_bytes(b"half a checkpoint")
    assert cli(capsys, "resume", run, "--generations", 3)[0] == 0
    assert not leftover.exists()


class Failing(Sphere):
    def evaluate(self, genomes, seeds):
        raise RuntimeError("the simulator broke")


def test_a_run_that_fails_before_its_first_checkpoint_leaves_no_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(structgen.runs.experiment.Experiment, "make_problem", lambda self: Failing())
    experiment = load_experiment(config(tmp_path))
    with pytest.raises(RuntimeError, match="the simulator broke"):
        evolve(experiment, tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()


def test_a_run_that_fails_in_a_folder_the_user_made_leaves_the_folder_as_it_was(tmp_path, monkeypatch):
    monkeypatch.setattr(structgen.runs.experiment.Experiment, "make_problem", lambda self: Failing())
    (tmp_path / "mine").mkdir()
    with pytest.raises(RuntimeError, match="the simulator broke"):
        evolve(load_experiment(config(tmp_path)), tmp_path / "mine", progress=False)
    assert (tmp_path / "mine").is_dir() and list((tmp_path / "mine").iterdir()) == []


def test_a_run_killed_before_its_first_checkpoint_resumes_from_the_beginning_to_the_same_run(tmp_path, monkeypatch, capsys):
    straight = tmp_path / "straight"
    assert cli(capsys, "evolve", config(tmp_path, 4), "--run-dir", straight)[0] == 0
    calls = {"n": 0}

    class FailsThird(Sphere):  # two generations end, neither checkpointed, then the process dies
        def evaluate(self, genomes, seeds):
            calls["n"] += 1
            if calls["n"] == 3:
                raise RuntimeError("killed")
            return super().evaluate(np.asarray(genomes), seeds)

    with monkeypatch.context() as patch:
        patch.setattr(structgen.runs.experiment.Experiment, "make_problem", lambda self: FailsThird())
        experiment = load_experiment(config(tmp_path, 4), overrides=["run.checkpoint_every=100", "run.checkpoint_seconds=0"])
        with pytest.raises(RuntimeError, match="killed"):
            evolve(experiment, tmp_path / "run", progress=False)
    run = tmp_path / "run"
    assert not (run / "checkpoint.pkl").exists() and len(findings(run / "metrics.jsonl")) == 2  # kept: two generations ended
    code, err = cli(capsys, "resume", run, "-v")
    assert code == 0, err
    assert "no checkpoint was written (2 generations recorded after none): starting again from the beginning" in err
    assert findings(run / "metrics.jsonl") == findings(straight / "metrics.jsonl")


def test_a_checkpoint_is_written_when_its_time_has_come_and_waits_longer_after_a_slow_one(tmp_path, monkeypatch):
    import itertools
    import types

    import evolution.run
    from evolution import RunFolder

    experiment = load_experiment(config(tmp_path, 4), overrides=["run.checkpoint_every=100", "run.checkpoint_seconds=1.5"])
    seen = []
    original = RunFolder.save_checkpoint

    def save(self, state, problem=None):
        seen.append(state.generation)
        original(self, state, problem)

    # The run loop's clock reads 0, 1, 2, ... seconds, a second a reading: each generation's check costs one, each
    # checkpoint two (its start and its end).
    clock = itertools.count()
    monkeypatch.setattr(
        evolution.run, "time", types.SimpleNamespace(monotonic=lambda: next(clock), perf_counter=time.perf_counter)
    )
    monkeypatch.setattr(RunFolder, "save_checkpoint", save)
    evolve(experiment, tmp_path / "run", progress=False)
    # 1.5 s after the start (0): at generation 2 (reading 2); that one took a second, so the next waits 9 s, and only
    # the last generation is checkpointed again.
    assert seen == [2, 4]
    seen.clear()
    evolve(experiment.with_run(checkpoint_seconds=0.0), tmp_path / "other", progress=False)
    assert seen == [4]  # by checkpoint_every (100) alone: only the last generation


def test_a_run_that_fails_later_keeps_its_folder_to_resume(tmp_path, monkeypatch):
    calls = {"n": 0}

    class FailsSecond(Sphere):
        def evaluate(self, genomes, seeds):
            calls["n"] += 1
            if calls["n"] == 2:
                raise RuntimeError("the simulator broke")
            return super().evaluate(np.asarray(genomes), seeds)

    monkeypatch.setattr(structgen.runs.experiment.Experiment, "make_problem", lambda self: FailsSecond())
    with pytest.raises(RuntimeError):
        evolve(load_experiment(config(tmp_path)), tmp_path / "run", progress=False)
    assert (tmp_path / "run" / "checkpoint.pkl").exists()


@pytest.mark.slow
def test_killing_evolve_leaves_no_worker_behind(tmp_path):
    import psutil

    config = tmp_path / "slow.toml"
    config.write_text(
        "[run]\ngenerations = 1000\nworkers = 2\n[problem.nca]\nmax_vertices = 16\n[optimizer]\npopulation = 8\nparents = 2\n"
    )
    run = tmp_path / "run"
    parent = subprocess.Popen(
        [sys.executable, "-m", "structgen", "evolve", str(config), "--run-dir", str(run)], stderr=subprocess.DEVNULL
    )
    try:
        deadline = time.monotonic() + 120
        while not (run / "metrics.jsonl").exists():  # a generation done: the workers are up
            assert parent.poll() is None and time.monotonic() < deadline
            time.sleep(0.1)
        workers = psutil.Process(parent.pid).children(recursive=True)
        assert len(workers) == 2
    finally:
        parent.kill()
        parent.wait()
    gone, alive = psutil.wait_procs(workers, timeout=5)
    assert alive == []
