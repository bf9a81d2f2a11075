"""The evaluation pool: a worker that dies or hangs costs only the candidates it held (tried again alone, then scored
as failed), a problem's own exception ends the batch with its traceback, workers die with their parent, and a problem
defined in the script that runs evolution works without any guard."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import psutil
import pytest

from evolution import EvaluationError, PoolEvaluator, RunFolder, RunSettings, RunState, SerialEvaluator, advance, make_optimizer
from evolution.optimizers import GASettings
from evolution.pool import TaskError, WorkerPool
from evolution.toys import Sphere, SphereSettings


def batch(count: int = 13):
    problem = Sphere(SphereSettings(noise=0.5))
    genomes = problem.initial_genomes(count, np.random.default_rng(0))
    return genomes, np.random.SeedSequence(9).generate_state(count)


class DiesOnOne(Sphere):
    """Kills the process evaluating it when its batch holds the candidate whose first coordinate is the largest
    one of the test batch: a simulator crash that always strikes the same candidate."""

    def __init__(self, fatal: float) -> None:
        super().__init__(SphereSettings(noise=0.5))
        self.fatal = fatal

    def evaluate(self, genomes, seeds):
        if np.any(np.asarray(genomes)[:, 0] == self.fatal):
            os._exit(3)
        return super().evaluate(genomes, seeds)


class HangsOnOne(DiesOnOne):
    def evaluate(self, genomes, seeds):
        if np.any(np.asarray(genomes)[:, 0] == self.fatal):
            time.sleep(3600)
        return Sphere.evaluate(self, genomes, seeds)


class Raises(Sphere):
    def evaluate(self, genomes, seeds):
        raise ZeroDivisionError("a bug in the problem")


def same_except(result, expected, failed: np.ndarray) -> None:
    assert result.failed.tolist() == failed.tolist()
    keep = ~failed
    assert np.array_equal(result.objective[keep], expected.objective[keep])
    assert np.array_equal(result.measures[keep], expected.measures[keep])


@pytest.mark.parametrize("problem_type", [DiesOnOne, HangsOnOne], ids=["dies", "hangs"])
def test_a_worker_that_dies_or_hangs_costs_only_its_candidate(problem_type):
    genomes, seeds = batch()
    fatal = genomes[:, 0].max()
    problem = problem_type(fatal)
    expected = SerialEvaluator().evaluate(Sphere(SphereSettings(noise=0.5)), genomes, seeds)
    with PoolEvaluator(2, timeout=1.0) as pool:
        result = pool.evaluate(problem, genomes, seeds)
        bad = genomes[:, 0] == fatal
        same_except(result, expected, bad)
        assert result.objective[bad] == [problem.objective_floor] and (result.measures[bad] == -1.0).all()
        again = pool.evaluate(problem, genomes[~bad], seeds[~bad])  # the pool goes on with fresh workers
        same_except(again, SerialEvaluator().evaluate(Sphere(SphereSettings(noise=0.5)), genomes[~bad], seeds[~bad]), bad[~bad])


def test_a_run_goes_on_past_a_dying_worker_and_says_so_in_its_metrics(tmp_path):
    genomes, _ = batch(10)
    problem = DiesOnOne(np.float64(np.nan))  # dies on nothing yet
    ga = make_optimizer("ga", problem, GASettings(population=10, parents=2), seed=0)
    first = ga.ask()
    problem.fatal = first[:, 0].max()  # the first generation's best-placed candidate kills its worker
    ga = make_optimizer("ga", problem, GASettings(population=10, parents=2), seed=0)
    folder = RunFolder.create(tmp_path / "run", "", {})
    with PoolEvaluator(2) as pool:
        state = advance(folder, problem, RunState(ga), RunSettings(generations=2, workers=2), pool, progress=False)
    rows = folder.metrics()
    assert state.generation == 2 and rows[0]["failed_evaluations"] == 1
    assert "failed_evaluations" not in rows[1]


def test_an_exception_in_the_problem_ends_the_batch_with_its_traceback():
    genomes, seeds = batch()
    with (
        PoolEvaluator(2) as pool,
        pytest.raises(EvaluationError, match="(?s)sphere failed on candidates.*ZeroDivisionError: a bug"),
    ):
        pool.evaluate(Raises(), genomes, seeds)


def alive(pid: int) -> bool:
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


SCRIPT = """
import sys, time
import numpy as np
from evolution import Evaluation, PoolEvaluator, Problem

class Squares(Problem):          # defined in the script itself, with no __main__ guard anywhere
    name, n_params = "squares", 3
    def initial_genomes(self, count, rng):
        return rng.normal(size=(count, 3))
    def evaluate(self, genomes, seeds):
        return Evaluation(-(np.asarray(genomes) ** 2).sum(1), np.zeros((len(genomes), 0)))

pool = PoolEvaluator(2)
genomes = np.arange(12.0).reshape(4, 3)
print(pool.evaluate(Squares(), genomes, np.arange(4)).objective.tolist(), *pool.pids, flush=True)
time.sleep(float(sys.argv[1]))
"""


def test_a_problem_from_the_running_script_works_and_workers_die_with_their_parent(tmp_path):
    script = tmp_path / "script.py"
    script.write_text(textwrap.dedent(SCRIPT))
    parent = subprocess.Popen([sys.executable, str(script), "60"], stdout=subprocess.PIPE, text=True)
    first = parent.stdout.readline().split("] ")
    assert first[0] + "]" == "[-5.0, -50.0, -149.0, -302.0]"
    workers = [int(pid) for pid in first[1].split()]
    assert len(workers) == 2 and all(alive(pid) for pid in workers)
    parent.send_signal(signal.SIGKILL)
    parent.wait()
    deadline = time.monotonic() + 5
    while any(alive(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(alive(pid) for pid in workers)


def test_one_pool_runs_any_job_in_input_order_and_swaps_jobs_without_restarting_its_workers():
    with WorkerPool(2) as pool:
        assert pool.map(abs, [-3, 1, -2, 5, -8]) == [3, 1, 2, 5, 8]
        pids = pool.pids
        assert pool.map(str, range(4)) == ["0", "1", "2", "3"]
        assert pool.pids == pids
        with pytest.raises(TaskError, match="(?s)payload 1 failed.*ZeroDivisionError") as caught:
            pool.map(lambda x: 1 / x, [1, 0, 2])
        assert caught.value.index == 1
        assert pool.map(len, ["ab", ""]) == [2, 0]  # a fresh pool after the error
    assert WorkerPool(0).map(abs, [-1, -2]) == [1, 2]


SHADOWS = """
import pathlib
pathlib.Path({marker!r}).write_text("imported from the folder the process runs in")
"""


def test_workers_never_import_from_the_folder_they_run_in(tmp_path):
    # A run folder holding signal.py or numbers.py (standard modules a worker imports) must not run them: workers get
    # the parent's module search path, not their working folder.
    for name in ("signal", "numbers", "json", "pickle"):
        (tmp_path / f"{name}.py").write_text(SHADOWS.format(marker=str(tmp_path / f"{name}.imported")))
    code = "from evolution.pool import WorkerPool\nwith WorkerPool(2) as pool: print(pool.map(abs, [-1, -2, 3]))"
    # -I keeps the parent itself from the folder too (it would import them anyway, before any worker did).
    done = subprocess.run([sys.executable, "-I", "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[1, 2, 3]"
    assert sorted(p.name for p in tmp_path.glob("*.imported")) == []


def test_what_a_worker_prints_goes_to_standard_error_not_to_the_parents_results(tmp_path):
    code = (
        "from evolution.pool import WorkerPool\nwith WorkerPool(1) as pool: pool.map(print, ['from a worker'])\nprint('result')"
    )
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout == "result\n" and "from a worker" in done.stderr


@pytest.mark.parametrize("when", ["idle", "starting"])
def test_a_worker_killed_between_batches_or_while_starting_costs_at_most_a_retry(when):
    genomes, seeds = batch()
    problem = Sphere(SphereSettings(noise=0.5))
    expected = SerialEvaluator().evaluate(problem, genomes, seeds)
    with PoolEvaluator(2) as pool:
        if when == "idle":
            pool.evaluate(problem, genomes, seeds)  # both workers started and idle
        else:
            pool.pool._start_workers(2)  # started, not yet told the job
        os.kill(pool.pids[0], signal.SIGKILL)
        time.sleep(0.2)
        result = pool.evaluate(problem, genomes, seeds)
    same_except(result, expected, np.zeros(len(seeds), dtype=bool))


class AlwaysDies(Sphere):
    def evaluate(self, genomes, seeds):
        os._exit(3)


def test_a_batch_whose_workers_die_on_everything_stops_the_run_instead_of_scoring_the_floor():
    genomes, seeds = batch(6)
    with PoolEvaluator(2) as pool, pytest.raises(EvaluationError, match="every candidate of the batch was lost, twice"):
        pool.evaluate(AlwaysDies(), genomes, seeds)
