"""One call evaluates a batch: in this process, in a local process pool, or on a Dask cluster.

An evaluator splits the batch into consecutive slices, has ``problem.evaluate`` run on each slice wherever it runs,
and joins the results in order. Because evaluation is a pure function of each genome and its seed, every evaluator
gives the same results; they differ only in where the work happens.
"""

from __future__ import annotations

import logging
import os
import pickle
import signal
import uuid
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

import numpy as np

from evolution.problem import Evaluation, Problem

__all__ = ["DaskEvaluator", "EvaluationError", "Evaluator", "PoolEvaluator", "SerialEvaluator", "make_evaluator"]

log = logging.getLogger(__name__)


class EvaluationError(RuntimeError):
    """Evaluation could not complete (a worker died, the cluster went away)."""


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


# The problem a pool worker evaluates, installed once when the worker starts (see PoolEvaluator).
_worker_problem: tuple[str, Problem] | None = None


def _start_worker(token: str, problem_bytes: bytes) -> None:
    global _worker_problem
    # Ctrl-C is for the parent, which finishes the generation and checkpoints; a worker that died of it would break
    # the pool. One core per worker: libraries must not start a thread per core in every worker.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
        os.environ[name] = "1"
    _worker_problem = (token, pickle.loads(problem_bytes))


def _evaluate_in_worker(token: str, genomes: Any, seeds: np.ndarray) -> Evaluation:
    if _worker_problem is None or _worker_problem[0] != token:  # cannot happen unless a pool is reused wrongly
        raise RuntimeError("this worker was started for another problem")
    return _worker_problem[1].evaluate(genomes, seeds)


class PoolEvaluator(Evaluator):
    """A persistent pool of ``workers`` local processes; each batch is cut into ``slices_per_worker * workers`` slices
    so that uneven evaluation costs even out.

    The problem goes to each worker once, when the pool starts for it; after that only genomes and seeds travel. (A
    problem may hold a heavy simulator; pickling it with every slice would cost more than the slice.) Evaluating a
    different problem object restarts the pool.

    Workers are started with multiprocessing's "spawn" method (fresh interpreters), so a script that uses this pool
    must guard its entry point with ``if __name__ == "__main__":``, as for any spawn-based pool.
    """

    def __init__(self, workers: int, *, slices_per_worker: int = 4) -> None:
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self.workers, self.slices_per_worker = workers, slices_per_worker
        self._pool: ProcessPoolExecutor | None = None
        self._problem: Problem | None = None
        self._token = ""

    def _pool_for(self, problem: Problem) -> ProcessPoolExecutor:
        if self._pool is None or problem is not self._problem:
            import multiprocessing

            self.close()
            self._problem, self._token = problem, uuid.uuid4().hex
            self._pool = ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_start_worker,
                initargs=(self._token, pickle.dumps(problem)),
            )
        return self._pool

    def evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        seeds = np.asarray(seeds)
        pool = self._pool_for(problem)
        parts = _slices(len(seeds), self.workers * self.slices_per_worker)
        futures = [pool.submit(_evaluate_in_worker, self._token, _take(genomes, p), seeds[p]) for p in parts]
        try:
            return Evaluation.concatenate([f.result() for f in futures])
        except BrokenProcessPool as err:
            raise EvaluationError(f"an evaluation worker process died: {err}") from None

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool, self._problem = None, None


class DaskEvaluator(Evaluator):
    """Send each batch to a Dask distributed scheduler at ``address`` (``tcp://host:8786``), one slice per task.

    The problem is sent to the workers once and reused. Needs the ``distributed`` package (``pip install
    structgen[cluster]``).
    """

    def __init__(self, address: str, *, slices: int | None = None, timeout: float = 10.0) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise EvaluationError("--cluster needs the 'distributed' package: pip install 'structgen[cluster]'") from None
        try:
            self.client = Client(address, timeout=f"{timeout}s")
        except OSError as err:
            raise EvaluationError(f"cannot reach the Dask scheduler at {address}: {err}") from None
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


def make_evaluator(workers: int, cluster: str = "") -> Evaluator:
    """Dask if a cluster address is given; otherwise a local pool of ``workers`` processes, or this process if 0."""
    if cluster:
        return DaskEvaluator(cluster)
    if workers <= 0:
        return SerialEvaluator()
    return PoolEvaluator(workers)
