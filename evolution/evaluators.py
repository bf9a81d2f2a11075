"""One call evaluates a batch: in this process, in a local process pool, or on a Dask cluster.

An evaluator splits the batch into consecutive slices, has ``problem.evaluate`` run on each slice wherever it runs,
and joins the results in order. Because evaluation is a pure function of each genome and its seed, every evaluator
gives the same results; they differ only in where the work happens.
"""

from __future__ import annotations

import logging
from concurrent.futures import CancelledError
from typing import Any

import numpy as np

from evolution.pool import Lost, TaskError, WorkerPool
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


class _EvaluateSlice:
    """The job a pool's workers run: evaluate one slice ``(genomes, seeds)`` of a batch with the problem they hold."""

    def __init__(self, problem: Problem) -> None:
        self.problem = problem

    def __call__(self, payload: tuple[Any, np.ndarray]) -> Evaluation:
        return self.problem.evaluate(*payload)


class PoolEvaluator(Evaluator):
    """``workers`` local processes (:class:`evolution.pool.WorkerPool`); each batch is cut into
    ``slices_per_worker * workers`` slices so that uneven evaluation costs even out.

    - The problem goes to each worker once; after that only genomes and seeds travel.
    - A worker that dies, or holds one slice longer than ``timeout`` seconds per candidate (None: no limit), is
      replaced and costs only what it held: each candidate of the slice is tried again alone, and a candidate whose
      second try fails too gets the problem's :meth:`~evolution.Problem.failed_evaluation`, flagged in
      ``Evaluation.failed``. The batch always completes.
    - An exception raised by the problem itself is a bug, not bad luck: it ends the batch with an EvaluationError
      carrying the worker's traceback. So does a batch in which every candidate was lost twice: workers that die on
      everything (they cannot load the problem, something kills them at once) would otherwise score the whole run at
      the floor.
    """

    def __init__(self, workers: int, *, slices_per_worker: int = 4, timeout: float | None = None) -> None:
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self.pool = WorkerPool(workers, timeout=timeout)
        self.workers, self.slices_per_worker, self.timeout = workers, slices_per_worker, timeout
        self._job: _EvaluateSlice | None = None

    @property
    def pids(self) -> list[int]:
        """Process ids of the running workers."""
        return self.pool.pids

    def evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        seeds = np.asarray(seeds)
        if self._job is None or self._job.problem is not problem:
            self._job = _EvaluateSlice(problem)
        parts = _slices(len(seeds), self.workers * self.slices_per_worker)
        results = self._run(problem, genomes, seeds, parts)
        # A slice lost with its worker comes back as single candidates, so that one candidate that kills its worker
        # does not take its neighbours with it; a candidate lost twice is scored as failed.
        singles = [
            slice(k, k + 1)
            for part, result in zip(parts, results)
            if isinstance(result, Lost)
            for k in range(part.start, part.stop)
        ]
        retried = dict(zip((s.start for s in singles), self._run(problem, genomes, seeds, singles)))
        lost_twice = [again.reason for again in retried.values() if isinstance(again, Lost)]
        if lost_twice and len(lost_twice) == len(seeds):
            raise EvaluationError(
                f"{problem.name}: every candidate of the batch was lost, twice ({lost_twice[0]}): the workers die on "
                "everything, so the run stops rather than score every candidate at the floor (their errors are above)"
            )
        pieces: list[Evaluation] = []
        for part, result in zip(parts, results):
            if not isinstance(result, Lost):
                pieces.append(result)
                continue
            for k in range(part.start, part.stop):
                again = retried[k]
                pieces.append(problem.failed_evaluation(1) if isinstance(again, Lost) else again)
        return Evaluation.concatenate(pieces)

    def _run(self, problem: Problem, genomes: Any, seeds: np.ndarray, parts: list[slice]) -> list[Any]:
        if not parts:
            return []
        assert self._job is not None
        try:
            results = self.pool.map(
                self._job,
                [(_take(genomes, part), seeds[part]) for part in parts],
                weights=[part.stop - part.start for part in parts],
            )
        except TaskError as err:
            part = parts[err.index]
            raise EvaluationError(
                f"{problem.name} failed on candidates {part.start} to {part.stop - 1}:\n{err.details}"
            ) from None
        for part, result in zip(parts, results):
            if isinstance(result, Lost):
                log.warning("candidates %d to %d: %s", part.start, part.stop - 1, result.reason)
        return results

    def close(self) -> None:
        self.pool.close()
        self._job = None


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
        except (ValueError, TypeError) as err:  # not an address at all
            raise UnreachableClusterError(f"{address!r} is not a Dask scheduler's address (tcp://host:port): {err}") from None
        self.address, self.slices = address, slices
        self._problem: Problem | None = None
        self._problem_future: Any = None
        self._lost = False

    def evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        seeds = np.asarray(seeds)
        for attempt in (1, 2):
            try:
                return self._evaluate(problem, genomes, seeds)
            except (OSError, TimeoutError, CancelledError) as err:
                reason = str(err).splitlines()[0] if str(err) else type(err).__name__
                if attempt == 1 and self.client.status == "running":
                    # The scheduler is there but lost part of the batch: a worker died holding the problem's only
                    # copy the scheduler trusts (Dask cannot remake scattered data, dask/distributed#3149). The
                    # batch is a pure function of its genomes and seeds: sent again, it gives the same results.
                    log.warning("the Dask cluster lost part of a batch (%s); evaluating it again", reason)
                    self._problem = None
                    continue
                # The scheduler gone, or the connection to it: the run stops here, its last checkpoint intact.
                self._lost = True
                raise EvaluationError(
                    f"lost the Dask scheduler at {self.address} during evaluation ({reason}); the run keeps its last "
                    "checkpoint: start the scheduler again and resume the run (resume RUN_DIR --cluster ADDRESS) to go "
                    "on from there"
                ) from None
        raise AssertionError("unreachable")

    def _evaluate(self, problem: Problem, genomes: Any, seeds: np.ndarray) -> Evaluation:
        if problem is not self._problem:
            self._problem, self._problem_future = problem, self.client.scatter(problem, broadcast=True)
        workers = max(1, sum(info.get("nthreads", 1) for info in self.client.scheduler_info()["workers"].values()))
        parts = _slices(len(seeds), self.slices or 4 * workers)
        futures = [
            self.client.submit(_evaluate_slice, self._problem_future, _take(genomes, p), seeds[p], pure=False) for p in parts
        ]
        return Evaluation.concatenate(self.client.gather(futures))

    def close(self) -> None:
        if self._lost:  # the client's attempts to reconnect end in tracebacks on closing that tell nothing more
            for name in [n for n in logging.root.manager.loggerDict if n == "distributed" or n.startswith("distributed.")]:
                logging.getLogger(name).setLevel(logging.CRITICAL)
        self.client.close()


def make_evaluator(workers: int, cluster: str = "", timeout: float | None = None) -> Evaluator:
    """Dask if a cluster address is given; otherwise a local pool of ``workers`` processes (``timeout``: seconds a
    candidate may take there), or this process if 0."""
    if cluster:
        return DaskEvaluator(cluster)
    if workers <= 0:
        return SerialEvaluator()
    return PoolEvaluator(workers, timeout=timeout)
