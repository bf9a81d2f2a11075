"""Run folders and the loop: checkpoints, resume equivalence, metrics, evaluators (local pool and Dask)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from evolution import (
    EvaluationError,
    PoolEvaluator,
    RunFolder,
    RunFolderError,
    RunSettings,
    RunState,
    SerialEvaluator,
    advance,
    make_optimizer,
)
from evolution.optimizers import CMAESSettings, CMAMAESettings, GASettings, MapElitesSettings
from evolution.toys import Ones, Sphere, SphereSettings
from tests.helpers import comparable

CASES = {
    "ga-sphere": ("ga", Sphere, GASettings(population=10, parents=3)),
    "ga-ones": ("ga", Ones, GASettings(population=10, parents=3, crossover_rate=0.5)),
    "cma_es-sphere": ("cma_es", Sphere, CMAESSettings(population=8)),
    "map_elites-sphere": ("map_elites", Sphere, MapElitesSettings(cells=(5, 5), batch_size=8)),
    "map_elites-ones": ("map_elites", Ones, MapElitesSettings(cells=(5, 5), batch_size=8)),
    "cma_mae-sphere": ("cma_mae", Sphere, CMAMAESettings(cells=(5, 5), emitters=2, batch_size=4)),
}


def new_run(tmp_path, name: str, case: str, generations: int, **settings):
    optimizer_name, problem_type, optimizer_settings = CASES[case]
    problem = problem_type()
    folder = RunFolder.create(tmp_path / name, "[run]\n", {"test": True})
    run = RunSettings(generations=generations, seed=5, workers=0, **settings)
    return folder, problem, RunState(optimizer=make_optimizer(optimizer_name, problem, optimizer_settings, seed=5)), run


def results(folder: RunFolder) -> dict:
    """Everything a run leaves that must match bit for bit (not the timings)."""
    metrics = comparable(folder.metrics())
    files = {}
    for name in ("archive.csv", "archive_solutions.npy", "best/genome.npy", "best/genome.json", "best/best.json"):
        path = folder / name
        if path.exists():
            files[name] = path.read_bytes()
    return {"metrics": metrics, "files": files}


@pytest.mark.parametrize("case", list(CASES))
def test_two_plus_two_generations_equal_four(tmp_path, case):
    folder, problem, state, settings = new_run(tmp_path, "straight", case, 4)
    advance(folder, problem, state, settings, SerialEvaluator(), progress=False)

    first, problem, state, settings = new_run(tmp_path, "resumed", case, 4)
    advance(first, problem, state, settings, SerialEvaluator(), until=2, progress=False)
    restored = first.load_checkpoint()
    assert restored.generation == 2
    advance(first, problem, restored, settings, SerialEvaluator(), progress=False)

    assert results(first) == results(folder)
    assert len(results(folder)["metrics"]) == 4


def test_metrics_after_the_checkpoint_are_dropped_on_resume(tmp_path):
    folder, problem, state, settings = new_run(tmp_path, "r", "ga-sphere", 6, checkpoint_every=3)
    advance(folder, problem, state, settings, SerialEvaluator(), until=5, progress=False)
    assert len(folder.metrics()) == 5
    restored = folder.load_checkpoint()  # written at generation 3 and at the stop (generation 5)
    assert restored.generation == 5
    # Simulate a kill after generation 4's metrics but before its checkpoint: the checkpoint says 3.
    folder.truncate_metrics(3)
    assert [row["generation"] for row in folder.metrics()] == [1, 2, 3]


def test_checkpoints_follow_checkpoint_every_and_the_end(tmp_path):
    folder, problem, state, settings = new_run(tmp_path, "r", "ga-sphere", 5, checkpoint_every=2)
    seen = []

    def record(row: dict) -> None:
        seen.append(folder.load_checkpoint().generation if (folder / "checkpoint.pkl").exists() else None)

    advance(folder, problem, state, settings, SerialEvaluator(), progress=False, on_generation=record)
    assert seen == [None, 2, 2, 4, 5]


def test_a_stop_request_finishes_the_generation_and_checkpoints(tmp_path):
    folder, problem, state, settings = new_run(tmp_path, "r", "ga-sphere", 10, checkpoint_every=5)
    calls = {"n": 0}

    def stop_after_three() -> bool:
        calls["n"] += 1
        return calls["n"] >= 3

    state = advance(folder, problem, state, settings, SerialEvaluator(), progress=False, stop_requested=stop_after_three)
    assert state.generation == 3 and folder.load_checkpoint().generation == 3


def test_run_folder_contents(tmp_path):
    folder, problem, state, settings = new_run(tmp_path, "qd", "map_elites-sphere", 3)
    advance(folder, problem, state, settings, SerialEvaluator(), progress=False)
    names = {p.name for p in folder.path.iterdir()}
    assert {"config.toml", "manifest.json", "checkpoint.pkl", "metrics.jsonl", "archive.csv", "archive_solutions.npy"} <= names
    assert {"best", "objective.png", "archive.png", "qd.png"} <= names
    row = folder.metrics()[-1]
    for key in (
        "generation",
        "evaluations",
        "best_objective",
        "mean_objective",
        "qd_score",
        "coverage",
        "wall_s",
        "best_distance",
    ):
        assert key in row
    lines = (folder / "archive.csv").read_text().splitlines()
    assert lines[0] == "index,objective,x0,x1,cell_x0,cell_x1,threshold,distance"
    solutions = np.load(folder / "archive_solutions.npy")
    assert len(solutions) == len(lines) - 1 == row["num_elites"]
    first = [float(x) for x in lines[1].split(",")]
    assert np.isclose(Sphere().evaluate(solutions[:1], np.zeros(1)).objective[0], first[1])
    best = json.loads((folder / "best" / "best.json").read_text())
    assert best["objective"] == row["best_objective"]
    assert np.array_equal(folder.archive_genome(int(first[0]), problem), solutions[0])


def test_object_genomes_are_written_as_json_beside_a_numbers_only_csv(tmp_path):
    import pandas

    folder, problem, state, settings = new_run(tmp_path, "ones", "map_elites-ones", 3)
    advance(folder, problem, state, settings, SerialEvaluator(), progress=False)
    genome = json.loads((folder / "best" / "genome.json").read_text())
    assert set(genome) <= {0, 1} and len(genome) == 16
    assert folder.best_genome(problem) == tuple(genome)  # the problem's own type back, not JSON's list
    table = pandas.read_csv(folder / "archive.csv")
    assert list(table.columns) == [
        "index", "objective", "ones_left", "ones_right", "cell_ones_left", "cell_ones_right", "threshold", "ones",
    ]  # fmt: skip
    assert all(dtype.kind in "if" for dtype in table.dtypes)
    # the cell coordinates are the flat index's
    cells = np.ravel_multi_index((table["cell_ones_left"], table["cell_ones_right"]), (5, 5))
    assert cells.tolist() == table["index"].tolist()
    genomes = [json.loads(line) for line in (folder / "archive_genomes.jsonl").read_text().splitlines()]
    assert len(genomes) == len(table) and not (folder / "archive_solutions.npy").exists()
    for index, genome, ones in zip(table["index"], genomes, table["ones"]):
        assert folder.archive_genome(int(index), problem) == tuple(genome) and sum(genome) == ones


def test_an_archive_whose_genome_file_was_cut_short_is_refused(tmp_path):
    folder, problem, state, settings = new_run(tmp_path, "ones", "map_elites-ones", 2)
    advance(folder, problem, state, settings, SerialEvaluator(), progress=False)
    lines = (folder / "archive_genomes.jsonl").read_text().splitlines()
    (folder / "archive_genomes.jsonl").write_text(lines[0] + "\n")
    index = int((folder / "archive.csv").read_text().splitlines()[1].split(",")[0])
    with pytest.raises(RunFolderError, match=f"holds 1 genomes for the {len(lines)} rows of archive.csv"):
        folder.archive_genome(index, problem)


# -- run folders are never overwritten by accident ---------------------------------------------------------------------
def test_existing_folders_are_refused_unless_overwriting_a_marked_run(tmp_path):
    RunFolder.create(tmp_path / "run", "[run]\n", {})
    with pytest.raises(RunFolderError, match="already exists"):
        RunFolder.create(tmp_path / "run", "[run]\n", {})
    RunFolder.create(tmp_path / "run", "[run]\nnew = 1\n", {}, overwrite=True)
    assert "new = 1" in (tmp_path / "run" / "config.toml").read_text()
    # A project that happens to hold a config.toml is not a run folder: nothing in it is touched.
    project = tmp_path / "proj"
    (project / "src").mkdir(parents=True)
    for name in ("config.toml", "important.txt", "src/main.py"):
        (project / name).write_text("keep me")
    with pytest.raises(RunFolderError, match="not a run folder .*lacks the run-folder mark.*refusing"):
        RunFolder.create(project, "[run]\n", {}, overwrite=True)
    assert sorted(str(p.relative_to(project)) for p in project.rglob("*")) == [
        "config.toml",
        "important.txt",
        "src",
        "src/main.py",
    ]
    (tmp_path / "link").symlink_to(tmp_path / "run")
    with pytest.raises(RunFolderError, match="is a symbolic link"):
        RunFolder.create(tmp_path / "link", "[run]\n", {}, overwrite=True)
    RunFolder.create(tmp_path / "empty", "[run]\n", {})  # a missing folder is fine
    (tmp_path / "blank").mkdir()
    RunFolder.create(tmp_path / "blank", "[run]\n", {})  # and so is an empty one


def test_one_process_at_a_time_writes_a_run(tmp_path):
    folder = RunFolder.create(tmp_path / "run", "[run]\n", {})
    with folder.locked():
        with pytest.raises(RunFolderError, match=rf"another process \(pid {os.getpid()}\) is writing this run"):
            with RunFolder(folder.path).locked():
                pass
        with pytest.raises(RunFolderError, match="is writing this run"):
            RunFolder.create(folder.path, "[run]\n", {}, overwrite=True)
    with RunFolder(folder.path).locked():  # released at the end of the block
        pass


def test_leftovers_of_cut_writes_are_removed_and_nothing_else(tmp_path):
    folder = RunFolder.create(tmp_path / "run", "[run]\n", {})
    (folder / "best").mkdir()
    leftovers = [folder / ".archive.csv.0123456789ab.tmp", folder / "best" / ".genome.npy.abcdef012345.tmp"]
    keep = [folder / "notes.tmp", folder / ".hidden", folder / "best" / "genome.npy"]
    for path in leftovers + keep:
        path.write_text("x")
    assert sorted(folder.remove_temporary_files()) == sorted(leftovers)
    assert all(path.exists() for path in keep) and not any(path.exists() for path in leftovers)


def test_writes_never_follow_a_symbolic_link_out_of_the_run(tmp_path):
    folder, problem, state, settings = new_run(tmp_path, "run", "ga-sphere", 1)
    outside = tmp_path / "outside"
    outside.mkdir()
    (folder / "best").symlink_to(outside)
    with pytest.raises(RunFolderError, match="best: is not a folder of this run"):
        advance(folder, problem, state, settings, SerialEvaluator(), progress=False)
    assert list(outside.iterdir()) == []
    (folder / "best").unlink()
    (folder / "metrics.jsonl").unlink(missing_ok=True)
    (folder / "metrics.jsonl").symlink_to(outside / "stolen.jsonl")
    with pytest.raises(RunFolderError, match="metrics.jsonl: is a symbolic link"):
        folder.append_metrics({"generation": 1})
    assert list(outside.iterdir()) == []


def test_metrics_reach_the_disk_before_the_checkpoint_that_covers_them(tmp_path, monkeypatch):
    folder, _, state, _ = new_run(tmp_path, "run", "ga-ones", 2)
    synced = []
    real_fsync = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(os.fstat(fd).st_ino), real_fsync(fd))[1])
    for generation in (1, 2):
        folder.append_metrics({"generation": generation})
    metrics = os.stat(folder / "metrics.jsonl").st_ino
    assert synced == []  # no sync a generation: under load it cost a fortress run 3 ms of its 40
    folder.save_checkpoint(state)
    assert synced[0] == metrics and len(synced) == 2  # the metrics, then the checkpoint's temporary file
    assert [row["generation"] for row in folder.metrics()] == [1, 2]


def test_opening_and_resuming_broken_folders_fails_clearly(tmp_path):
    with pytest.raises(RunFolderError, match="no such run folder"):
        RunFolder.open(tmp_path / "missing")
    (tmp_path / "plain").mkdir()
    with pytest.raises(RunFolderError, match="not a run folder"):
        RunFolder.open(tmp_path / "plain")
    folder = RunFolder.create(tmp_path / "run", "[run]\n", {})
    with pytest.raises(RunFolderError, match="no checkpoint yet"):
        folder.load_checkpoint()
    (folder / "checkpoint.pkl").write_bytes(b"not a pickle")
    with pytest.raises(RunFolderError, match="cannot read the checkpoint"):
        folder.load_checkpoint()


@pytest.mark.parametrize("field, value", [("generations", 0), ("checkpoint_every", 0), ("workers", -1), ("seed", -3)])
def test_run_settings_are_checked(field, value):
    with pytest.raises(ValueError, match=field):
        RunSettings(**{field: value})


# -- evaluators -----------------------------------------------------------------------------------------------------------
def noisy_batch():
    problem = Sphere(SphereSettings(noise=0.5))
    genomes = problem.initial_genomes(13, np.random.default_rng(0))
    seeds = np.random.SeedSequence(9).generate_state(13)
    return problem, genomes, seeds


def same(a, b) -> bool:
    return (
        np.array_equal(a.objective, b.objective)
        and np.array_equal(a.measures, b.measures)
        and all(np.array_equal(a.fields[k], b.fields[k]) for k in a.fields)
    )


def test_pool_evaluation_equals_serial_evaluation():
    problem, genomes, seeds = noisy_batch()
    serial = SerialEvaluator().evaluate(problem, genomes, seeds)
    with PoolEvaluator(2) as pool:
        assert same(pool.evaluate(problem, genomes, seeds), serial)
        ones = Ones()
        batch = ones.initial_genomes(7, np.random.default_rng(1))
        assert same(pool.evaluate(ones, batch, np.arange(7)), ones.evaluate(batch, np.arange(7)))


class CountsPickles(Sphere):
    """Counts how often it is pickled in this process."""

    pickled = 0

    def __getstate__(self):
        type(self).pickled += 1
        return self.__dict__


def test_the_pool_sends_the_problem_to_its_workers_once():
    problem = CountsPickles(SphereSettings(noise=0.5))
    genomes = problem.initial_genomes(13, np.random.default_rng(0))
    with PoolEvaluator(2) as pool:
        for generation in range(3):
            seeds = np.random.SeedSequence(generation).generate_state(13)
            assert same(pool.evaluate(problem, genomes, seeds), problem.evaluate(genomes, seeds))
    assert CountsPickles.pickled == 1


def test_dask_evaluation_equals_serial_evaluation():
    distributed = pytest.importorskip("distributed")
    from evolution import DaskEvaluator

    problem, genomes, seeds = noisy_batch()
    serial = SerialEvaluator().evaluate(problem, genomes, seeds)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with DaskEvaluator(cluster.scheduler_address) as dask:
            assert same(dask.evaluate(problem, genomes, seeds), serial)
            assert same(
                dask.evaluate(problem, genomes[:3], seeds[:3]), SerialEvaluator().evaluate(problem, genomes[:3], seeds[:3])
            )


def test_an_unreachable_cluster_is_an_evaluation_error():
    pytest.importorskip("distributed")
    from evolution import DaskEvaluator

    with pytest.raises(EvaluationError, match="cannot reach the Dask scheduler"):
        DaskEvaluator("tcp://127.0.0.1:9", timeout=1.0)


def test_the_lock_file_goes_with_its_holder_and_two_writers_never_hold_the_folder_at_once(tmp_path, monkeypatch):
    import fcntl
    import threading
    import time

    folder = RunFolder.create(tmp_path / "run", "", {})
    with folder.locked():
        assert (folder / ".lock").exists()
    assert not (folder / ".lock").exists()  # a finished run leaves no lock behind

    inside, most, errors = [0], [0], []
    guard = threading.Lock()
    real_flock = fcntl.flock

    def slow_flock(descriptor, operation):  # widens the moment between opening the lock file and locking it
        time.sleep(0.0005)
        return real_flock(descriptor, operation)

    monkeypatch.setattr(fcntl, "flock", slow_flock)

    def writer() -> None:
        for _ in range(200):
            try:
                with folder.locked():
                    with guard:
                        inside[0] += 1
                        most[0] = max(most[0], inside[0])
                    time.sleep(0.0005)  # a moment of writing
                    with guard:
                        inside[0] -= 1
            except RunFolderError:
                pass  # held by another: refused, as a second process is
            except Exception as err:  # anything else is a bug
                errors.append(err)

    threads = [threading.Thread(target=writer) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert errors == [] and most[0] == 1
