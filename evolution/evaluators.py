"""One call evaluates a batch: in this process, in a local process pool, or on a Dask cluster.

An evaluator splits the batch into consecutive slices, has ``problem.evaluate`` run on each slice wherever it runs,
and joins the results in order. Because evaluation is a pure function of each genome and its seed, every evaluator
gives the same results; they differ only in where the work happens.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import time
from collections import deque
from multiprocessing.connection import Connection, wait
from typing import Any

import numpy as np

from evolution.problem import Evaluation, Problem

__all__ = [
    "DaskEvaluator",
    "EvaluationError",
    "Evaluator",
    "PoolEvaluator",
    "SerialEvaluator",
    "UnreachableClusterError",
    "make_evaluator",
]

log = logging.getLogger(__name__)


class EvaluationError(RuntimeError):
    """Evaluation could not complete (the problem raised an exception, the cluster went away)."""


class UnreachableClusterError(EvaluationError):
    """No Dask scheduler answers at the address given: the address is wrong, or the cluster is not running."""


def _slices(count: int, parts: int) -> list[slice]:
    """``parts`` consecutive slices of ``range(count)``, as even as possible, none empty."""
    parts = max(1, min(parts, count))
    edges = np.linspace(0, count, parts + 1).round().astype(int)
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def _take(genomes: Any, part: slice) -> Any:
    return genomes[part] if isinstance(genomes, np.ndarray) else list(genomes)[part]


def _evaluate_slice(problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
    return problem.evaluate(genomes, seeds)


class Evaluator:
    """Base class: ``evaluate(problem, genomes, seeds)`` returns one :class:`Evaluation` in input order."""

    def evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        raise NotImplementedError

    def close(self) -> None:
        """Release workers or connections."""

    def __enter__(self) -> Evaluator:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SerialEvaluator(Evaluator):
    """Everything in this process."""

    def evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        return problem.evaluate(genomes, np.asarray(seeds))


class _Worker:
    """One worker process (``python -m evolution._worker``), the pipes to it, and the task it holds."""

    def __init__(self, problem_bytes: bytes) -> None:
        to_child_read, to_child_write = os.pipe()
        from_child_read, from_child_write = os.pipe()
        # One core per worker: libraries must not start a thread per core in every worker.
        threads = {name: "1" for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
        self.process = subprocess.Popen(
            [sys.executable, "-m", "evolution._worker", str(to_child_read), str(from_child_write), str(os.getpid())],
            pass_fds=(to_child_read, from_child_write),
            stdin=subprocess.DEVNULL,
            env={**os.environ, **threads},
        )
        os.close(to_child_read)
        os.close(from_child_write)
        self.sender = Connection(to_child_write, readable=False)
        self.receiver = Connection(from_child_read, writable=False)
        self.sender.send_bytes(problem_bytes)
        self.task: int | None = None
        self.started = 0.0
        self.ready = False  # set when the worker has loaded the problem

    def give(self, task: int, genomes: Any, seeds: np.ndarray) -> None:
        self.task, self.started = task, time.monotonic()  # a worker still starting restarts the clock when ready
        self.sender.send((task, genomes, seeds))

    def stop(self, *, kill: bool = False) -> None:
        if not kill:
            try:
                self.sender.send(None)
                self.process.wait(timeout=5)
            except (OSError, subprocess.TimeoutExpired):
                kill = True
        if kill:
            self.process.kill()
            self.process.wait()
        self.sender.close()
        self.receiver.close()


class PoolEvaluator(Evaluator):
    """``workers`` local processes; each batch is cut into ``slices_per_worker * workers`` slices so that uneven
    evaluation costs even out.

    - The problem goes to each worker once, when the pool starts for it (pickled with cloudpickle, so a problem
      defined in the script that runs evolution works too); after that only genomes and seeds travel. Evaluating a
      different problem object starts fresh workers.
    - A worker that dies, or holds one slice longer than ``timeout`` seconds per candidate (None: no limit), is
      replaced and costs only what it held: each candidate of the slice is tried again alone, and a candidate whose
      second try fails too gets the problem's :meth:`~evolution.Problem.failed_evaluation`, flagged in
      ``Evaluation.failed``. The batch always completes.
    - An exception raised by the problem itself is a bug, not bad luck: it ends the batch with an EvaluationError
      carrying the worker's traceback.
    - Workers are fresh interpreters (``python -m evolution._worker``) on pipes, so they never re-run the caller's
      script, and they die with the process that started them.
    """

    def __init__(self, workers: int, *, slices_per_worker: int = 4, timeout: float | None = None) -> None:
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        if timeout is not None and not timeout > 0:
            raise ValueError(f"timeout must be positive, got {timeout}")
        self.workers, self.slices_per_worker, self.timeout = workers, slices_per_worker, timeout
        self._pool: list[_Worker] = []
        self._problem: Problem | None = None
        self._problem_bytes = b""

    @property
    def pids(self) -> list[int]:
        """Process ids of the running workers."""
        return [worker.process.pid for worker in self._pool]

    def _start(self, problem: Problem) -> None:
        if problem is not self._problem:
            import cloudpickle

            self.close()
            self._problem, self._problem_bytes = problem, cloudpickle.dumps(problem)
        while len(self._pool) < self.workers:
            self._pool.append(_Worker(self._problem_bytes))

    def evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        seeds = np.asarray(seeds)
        self._start(problem)
        # A task is a slice of the batch and how many times it was tried; a slice that failed once comes back as
        # single candidates, so that one candidate that kills its worker does not take its neighbours with it.
        tasks: list[tuple[slice, int]] = [(part, 0) for part in _slices(len(seeds), self.workers * self.slices_per_worker)]
        results: dict[int, Evaluation] = {}
        queue = deque(range(len(tasks)))
        busy: dict[Connection, _Worker] = {}
        try:
            while queue or busy:
                failed = []
                for worker in self._pool:
                    if queue and worker.task is None:
                        task = queue.popleft()
                        part = tasks[task][0]
                        busy[worker.receiver] = worker
                        try:
                            worker.give(task, _take(genomes, part), seeds[part])
                        except OSError:  # it died while idle
                            failed.append((worker, f"the worker died (exit code {worker.process.wait()})"))
                failed += self._collect(busy, tasks, results, problem)
                for worker, reason in failed:
                    task = worker.task
                    del busy[worker.receiver]
                    worker.stop(kill=True)
                    self._pool[self._pool.index(worker)] = _Worker(self._problem_bytes)
                    part, tries = tasks[task]
                    log.warning("candidates %d to %d: %s", part.start, part.stop - 1, reason)
                    if tries == 0:  # try each candidate again, alone
                        for k in range(part.start, part.stop):
                            tasks.append((slice(k, k + 1), 1))
                            queue.appendleft(len(tasks) - 1)
                    else:
                        results[task] = problem.failed_evaluation(part.stop - part.start)
        except BaseException:
            self.close()  # a worker may be mid-task; do not leave it running
            raise
        # The results cover the batch once: slices that succeeded, and single candidates where a slice failed.
        return Evaluation.concatenate([results[task] for task in sorted(results, key=lambda t: tasks[t][0].start)])

    def _collect(
        self, busy: dict[Connection, _Worker], tasks: list, results: dict[int, Evaluation], problem: Problem
    ) -> list[tuple[_Worker, str]]:
        """Wait for results, deaths or time-outs; record results and return the workers that failed, with why."""
        timed = [w for w in busy.values() if w.ready and w.task is not None] if self.timeout else []
        limit = {w: self.timeout * (tasks[w.task][0].stop - tasks[w.task][0].start) for w in timed}
        wait_for = max(0.0, min(w.started + limit[w] for w in timed) - time.monotonic()) if timed else None
        failed: list[tuple[_Worker, str]] = []
        for connection in wait(list(busy), timeout=wait_for):
            worker = busy[connection]
            try:
                message = connection.recv()
            except (EOFError, OSError):
                failed.append((worker, f"the worker died (exit code {worker.process.wait()})"))
                continue
            if message == "ready":
                worker.ready, worker.started = True, time.monotonic()
                continue
            task, status, payload = message
            if status == "error":
                part = tasks[task][0]
                raise EvaluationError(f"{problem.name} failed on candidates {part.start} to {part.stop - 1}:\n{payload}")
            results[task] = payload
            worker.task = None
            del busy[connection]
        now = time.monotonic()
        for worker in timed:
            if worker.receiver in busy and worker.task is not None and now - worker.started >= limit[worker]:
                if all(worker is not w for w, _ in failed):
                    failed.append((worker, f"timed out after {limit[worker]:g} s"))
        return failed

    def close(self) -> None:
        for worker in self._pool:
            worker.stop()
        self._pool, self._problem = [], None


class DaskEvaluator(Evaluator):
    """Send each batch to a Dask distributed scheduler at ``address`` (``tcp://host:8786``), one slice per task.

    The problem is sent to the workers once and reused. Needs the ``distributed`` package (``pip install
    structgen[cluster]``).
    """

    def __init__(self, address: str, *, slices: int | None = None, timeout: float = 10.0) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise EvaluationError("a Dask cluster needs the 'distributed' package (pip install distributed)") from None
        try:
            self.client = Client(address, timeout=f"{timeout}s")
        except OSError as err:
            raise UnreachableClusterError(f"cannot reach the Dask scheduler at {address}: {err}") from None
        self.slices = slices
        self._problem: Problem | None = None
        self._problem_future: Any = None

    def evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        if problem is not self._problem:
            self._problem, self._problem_future = problem, self.client.scatter(problem, broadcast=True)
        seeds = np.asarray(seeds)
        workers = max(1, sum(info.get("nthreads", 1) for info in self.client.scheduler_info()["workers"].values()))
        parts = _slices(len(seeds), self.slices or 4 * workers)
        futures = [
            self.client.submit(_evaluate_slice, self._problem_future, _take(genomes, p), seeds[p], pure=False) for p in parts
        ]
        try:
            return Evaluation.concatenate(self.client.gather(futures))
        except (OSError, TimeoutError) as err:
            raise EvaluationError(f"the Dask cluster failed during evaluation: {err}") from None

    def close(self) -> None:
        self.client.close()


def make_evaluator(workers: int, cluster: str = "", timeout: float | None = None) -> Evaluator:
    """Dask if a cluster address is given; otherwise a local pool of ``workers`` processes (``timeout``: seconds a
    candidate may take there), or this process if 0."""
    if cluster:
        return DaskEvaluator(cluster)
    if workers <= 0:
        return SerialEvaluator()
    return PoolEvaluator(workers, timeout=timeout)
