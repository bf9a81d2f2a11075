"""The one worker pool: crash-isolating processes that run a job over many payloads, results in input order.

Every step of the project that runs in parallel goes through :class:`WorkerPool`: batch evaluation
(:class:`evolution.PoolEvaluator`), physics checks (:func:`physics.check_many`) and the searches of the domains.

- **A job** is a picklable callable of one payload (a function, or an object holding a problem). It is pickled once
  with cloudpickle (so a job defined in the script that runs it works too) and sent to each worker once; after that
  only payloads and results travel. A new job is sent to the running workers, which swap it in; none restarts.
- **Crash isolation.** A worker that dies (a crash inside a simulator, a kill from outside) or holds one payload
  longer than its time limit is replaced, and its payload comes back as :class:`Lost` saying why. The rest of the
  batch completes; the caller decides what a lost payload means (try it again alone, score it as failed). This is
  why the pool is ours rather than ``concurrent.futures``, whose pool is marked broken for every pending task once
  one worker dies.
- **A job's own exception** is a bug, not bad luck: it ends the call with :class:`TaskError` carrying the worker's
  traceback.
- **Workers are fresh interpreters** (not forked, not multiprocessing's spawn), so they never re-run the caller's
  script or copy its threads, and they die with the process that started them. Their module search path is the
  parent's, fixed when the pool starts: never the folder a worker happens to run in, so a ``signal.py`` in a run
  folder is not imported in place of the standard library's. They ignore Ctrl-C, which is the parent's to handle,
  run one thread each (libraries must not start a thread per core in every worker), and send their standard output
  to standard error (results travel on pipes; the parent's standard output is for its own results), or to nowhere
  with ``quiet=True``.

``WorkerPool(0)`` runs every payload in the calling process, with no isolation: for debugging, and for callers whose
work is too small to be worth a process.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from typing import Any

__all__ = ["Lost", "TaskError", "WorkerPool", "available_cpus", "worker_command"]

log = logging.getLogger(__name__)

#: What a worker starts with: the module search path it is given (its arguments after the first four), then the serving
#: loop. Nothing is imported before the path is set (``sys`` is built in): the working folder is first on the path
#: until then.
_BOOT = "import sys; sys.path[:] = sys.argv[5:]; from evolution._worker import main; main(sys.argv[1:5])"
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMBA_NUM_THREADS")


def available_cpus() -> int:
    """The number of CPUs this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass(frozen=True)
class Lost:
    """A payload whose worker died or ran out of time before answering; ``reason`` says which."""

    reason: str


class TaskError(RuntimeError):
    """The job raised an exception on a payload; ``index`` is the payload's position and ``details`` the worker's
    traceback."""

    def __init__(self, index: int, details: str) -> None:
        super().__init__(f"payload {index} failed:\n{details}")
        self.index, self.details = index, details


def worker_command(quiet: bool = False) -> tuple[list[str], list[str]]:
    """The command line that starts a worker (before its two pipes), and the module search path it is given: this
    process's (a relative entry made absolute against the current folder, now), so a worker imports what this
    process would and nothing from the folder it runs in."""
    here = os.getcwd()
    path = [os.path.join(here, entry) if not os.path.isabs(entry) else entry for entry in sys.path]
    return [sys.executable, "-c", _BOOT, "quiet" if quiet else "loud", str(os.getpid())], path


class _Worker:
    """One worker process, the pipes to it, the job it holds and the payload it is working on."""

    def __init__(self, quiet: bool) -> None:
        to_child_read, to_child_write = os.pipe()
        from_child_read, from_child_write = os.pipe()
        threads = dict.fromkeys(_THREAD_VARIABLES, "1")
        command, path = worker_command(quiet)
        self.process = subprocess.Popen(
            [*command, str(to_child_read), str(from_child_write), *path],
            pass_fds=(to_child_read, from_child_write),
            stdin=subprocess.DEVNULL,
            env={**os.environ, **threads},
        )
        os.close(to_child_read)
        os.close(from_child_write)
        self.sender = Connection(to_child_write, readable=False)
        self.receiver = Connection(from_child_read, writable=False)
        self.job: Any = None  # the job this worker was sent last
        self.task: int | None = None
        self.started = 0.0
        self.ready = False  # set when the worker has loaded its job; its clock starts then

    def give(self, job: Any, job_bytes: bytes, task: int, payload: Any) -> None:
        self.task, self.started = task, time.monotonic()
        if self.job is not job:
            self.job, self.ready = job, False
            self.sender.send(("job", job_bytes))
        self.sender.send(("task", task, payload))

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


class WorkerPool:
    """``workers`` processes that run jobs over payloads; keep one for many calls to pay the start-up once, and use
    it as a context manager or call :meth:`close`.

    Args:
        workers: processes to run (0: run in this process, without isolation).
        timeout: seconds a worker may hold one payload (times its weight, see :meth:`map`) before it is taken for
            hung and replaced; None for no limit. The clock starts when the worker has loaded the job.
        quiet: discard what workers print to standard output (a simulator's own messages) instead of passing it to
            standard error.
    """

    def __init__(self, workers: int, *, timeout: float | None = None, quiet: bool = False) -> None:
        if not isinstance(workers, int) or isinstance(workers, bool) or workers < 0:
            raise ValueError(f"workers must be a whole number, 0 or more, got {workers!r}")
        if timeout is not None and not timeout > 0:
            raise ValueError(f"timeout must be positive, got {timeout}")
        self.workers, self.timeout, self.quiet = workers, timeout, quiet
        self._pool: list[_Worker] = []
        self._job: Any = None
        self._job_bytes = b""

    @property
    def pids(self) -> list[int]:
        """Process ids of the running workers."""
        return [worker.process.pid for worker in self._pool]

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop every worker (each finishes the payload it holds, or is killed after 5 s)."""
        for worker in self._pool:
            worker.stop()
        self._pool = []

    def map(
        self,
        job: Callable[[Any], Any],
        payloads: Sequence[Any],
        *,
        weights: Sequence[float] | None = None,
        done: Callable[[int], None] | None = None,
    ) -> list[Any]:
        """``job(payload)`` for every payload, in input order; a payload whose worker died or timed out is a
        :class:`Lost` instead.

        ``weights`` scale each payload's time limit (the number of candidates in a slice, say); ``done`` is called
        with each payload's index as it finishes (a progress bar). Raises :class:`TaskError` when the job raises.
        """
        payloads = list(payloads)
        if self.workers == 0:
            results = []
            for index, payload in enumerate(payloads):
                results.append(job(payload))
                if done is not None:
                    done(index)
            return results
        if job is not self._job:
            import cloudpickle

            self._job, self._job_bytes = job, cloudpickle.dumps(job)
        results: list[Any] = [None] * len(payloads)
        queue = deque(range(len(payloads)))
        self._start_workers(min(self.workers, len(payloads)))
        busy: dict[Connection, _Worker] = {}
        try:
            while queue or busy:
                for worker in self._pool:
                    if queue and worker.task is None:
                        task = queue.popleft()
                        busy[worker.receiver] = worker
                        try:
                            worker.give(job, self._job_bytes, task, payloads[task])
                        except OSError:  # it died while idle
                            self._lose(worker, busy, results, f"the worker died (exit code {worker.process.wait()})", done)
                self._collect(busy, results, weights, done)
        except BaseException:
            for worker in self._pool:  # a worker may be mid-task; do not leave it running
                worker.stop(kill=True)
            self._pool = []
            raise
        return results

    def _start_workers(self, count: int) -> None:
        while len(self._pool) < count:
            self._pool.append(_Worker(self.quiet))

    def _collect(
        self, busy: dict[Connection, _Worker], results: list, weights: Sequence[float] | None, done: Callable[[int], None] | None
    ) -> None:
        """Wait for results, deaths or time-outs, and record them."""
        limits: dict[_Worker, float] = {}
        if self.timeout is not None:
            for worker in busy.values():
                if worker.ready and worker.task is not None:
                    limits[worker] = self.timeout * (1.0 if weights is None else float(weights[worker.task]))
        wait_for = max(0.0, min(w.started + limit for w, limit in limits.items()) - time.monotonic()) if limits else None
        for connection in wait(list(busy), timeout=wait_for):
            worker = busy[connection]
            try:
                message = connection.recv()
            except (EOFError, OSError):
                self._lose(worker, busy, results, f"the worker died (exit code {worker.process.wait()})", done)
                continue
            if message == "ready":
                worker.ready, worker.started = True, time.monotonic()
                continue
            status, task, payload = message
            if status == "error":
                raise TaskError(task, payload)
            results[task] = payload
            worker.task = None
            del busy[connection]
            if done is not None:
                done(task)
        now = time.monotonic()
        for worker, limit in limits.items():
            if worker.receiver in busy and now - worker.started >= limit:
                self._lose(worker, busy, results, f"timed out after {limit:g} s", done)

    def _lose(
        self, worker: _Worker, busy: dict[Connection, _Worker], results: list, reason: str, done: Callable[[int], None] | None
    ) -> None:
        task = worker.task
        assert task is not None
        log.debug("payload %d: %s", task, reason)
        results[task] = Lost(reason)
        del busy[worker.receiver]
        worker.stop(kill=True)
        self._pool[self._pool.index(worker)] = _Worker(self.quiet)
        if done is not None:
            done(task)
