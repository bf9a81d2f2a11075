"""Checking many structures in parallel: one PyBullet client per worker process, results in input order.

A worker that dies (a crash inside the simulator, a kill from outside) or overruns its time limit costs only the
structure it was working on: that structure gets a failed report (I = 0, ``error`` set), a fresh worker takes the
dead one's place, and the rest of the batch completes. This is why the pool is written here rather than taken from
``concurrent.futures``, whose pool is marked broken for every pending task once one worker dies.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import time
from collections import deque
from collections.abc import Iterable, Sequence
from multiprocessing.connection import Connection, wait
from typing import Any

from physics.config import PhysicsConfig
from physics.model import read_structure
from physics.report import StabilityReport
from physics.stability import check_or_fail

__all__ = ["CheckPool", "check_many", "default_workers"]

log = logging.getLogger(__name__)


def default_workers() -> int:
    """The number of CPUs this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


class _Worker:
    """One worker process and the two pipes to it."""

    def __init__(self) -> None:
        to_child_read, to_child_write = os.pipe()
        from_child_read, from_child_write = os.pipe()
        self.process = subprocess.Popen(
            [sys.executable, "-m", "physics._worker", str(to_child_read), str(from_child_write)],
            pass_fds=(to_child_read, from_child_write),
            stdin=subprocess.DEVNULL,
        )
        os.close(to_child_read)
        os.close(from_child_write)
        self.sender = Connection(to_child_write, readable=False)
        self.receiver = Connection(from_child_read, writable=False)
        self.task: int | None = None
        self.started = 0.0
        self.ready = False  # set when the worker reports its start-up done

    @property
    def pid(self) -> int:
        return self.process.pid

    def give(self, task: int, payload: tuple) -> None:
        # A worker still starting up restarts this clock when it reports ready.
        self.task, self.started = task, time.monotonic()
        self.sender.send((task, *payload))

    def stop(self, *, kill: bool = False) -> None:
        if not kill:
            try:
                self.sender.send(None)
            except OSError:
                pass
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                kill = True
        if kill:
            self.process.kill()
            self.process.wait()
        self.sender.close()
        self.receiver.close()


class CheckPool:
    """Worker processes that each keep one PyBullet client and check structures sent to them.

    Keep one pool for many batches (an evolution run) to pay the start-up once; use it as a context manager or call
    :meth:`close`. ``workers=0`` checks in this process, without the crash isolation.

    Workers are fresh interpreters (``python -m physics._worker``) talking over pipes: unlike multiprocessing's
    spawn and forkserver they never re-import the caller's main script, and unlike fork they never copy the caller's
    threads (torch's, for example).

    Args:
        workers: number of worker processes (default: one per available CPU).
        timeout: wall-clock seconds one structure may take before its worker is killed and it fails (None: no limit).
    """

    def __init__(self, workers: int | None = None, *, timeout: float | None = None):
        self.workers = default_workers() if workers is None else workers
        if self.workers < 0:
            raise ValueError(f"workers must be 0 or more, got {workers}")
        if timeout is not None and timeout <= 0:
            raise ValueError(f"timeout must be positive, got {timeout}")
        self.timeout = timeout
        self._pool: list[_Worker] = []

    @property
    def pids(self) -> list[int]:
        """Process ids of the running workers."""
        return [worker.pid for worker in self._pool]

    def __enter__(self) -> CheckPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop all workers."""
        for worker in self._pool:
            worker.stop()
        self._pool = []

    def check(self, structures: Iterable[Any], config: PhysicsConfig | None = None) -> list[StabilityReport]:
        """Check every structure; the reports come back in input order.

        Raises:
            physics.InputError: a structure cannot be read at all (before any simulation starts). Structures that
                are readable but too large get failed reports instead, like any other per-structure failure.
        """
        config = config or PhysicsConfig()
        payloads = [(*read_structure(s), config) for s in structures]
        if self.workers == 0:
            return [check_or_fail(*payload) for payload in payloads]
        reports: list[StabilityReport | None] = [None] * len(payloads)
        queue = deque(range(len(payloads)))
        while len(self._pool) < min(self.workers, len(payloads)):
            self._pool.append(_Worker())
        busy: dict[Connection, _Worker] = {}
        try:
            while queue or busy:
                for worker in self._pool:
                    if queue and worker.task is None:
                        task = queue.popleft()
                        worker.give(task, payloads[task])
                        busy[worker.receiver] = worker
                self._collect(busy, reports, payloads)
        except BaseException:
            for worker in self._pool:  # a worker may be mid-task; do not leave it running
                worker.stop(kill=True)
            self._pool = []
            raise
        return reports  # type: ignore[return-value]

    def _collect(self, busy: dict[Connection, _Worker], reports: list, payloads: list) -> None:
        """Wait for results, deaths (end of file on a worker's pipe) or time-outs, and record them."""
        timed = [w for w in busy.values() if w.ready] if self.timeout is not None else []
        wait_for = None
        if timed:
            deadline = min(w.started for w in timed) + self.timeout
            wait_for = max(0.0, deadline - time.monotonic())
        for connection in wait(list(busy), timeout=wait_for):
            worker = busy[connection]
            try:
                message = connection.recv()
            except (EOFError, OSError):
                code = worker.process.wait()
                self._replace(worker, busy, reports, payloads, f"worker process died (exit code {code})")
                continue
            if message == "ready":
                worker.ready, worker.started = True, time.monotonic()
                continue
            task, report = message
            reports[task] = report
            worker.task = None
            del busy[connection]
        if self.timeout is not None:
            now = time.monotonic()
            for worker in list(busy.values()):
                if worker.ready and now - worker.started >= self.timeout:
                    self._replace(worker, busy, reports, payloads, f"timed out after {self.timeout:g} s", kill=True)

    def _replace(self, worker: _Worker, busy: dict, reports: list, payloads: list, reason: str, *, kill: bool = False) -> None:
        task = worker.task
        vertices, edges, config = payloads[task]
        log.warning("structure %d: %s", task, reason)
        reports[task] = StabilityReport.failed(vertices, edges, reason, config)
        del busy[worker.receiver]
        worker.stop(kill=True)
        self._pool[self._pool.index(worker)] = _Worker()


def check_many(
    structures: Sequence[Any],
    config: PhysicsConfig | None = None,
    *,
    workers: int | None = None,
    timeout: float | None = None,
) -> list[StabilityReport]:
    """Check a batch of structures in ``workers`` processes (default: one per CPU); reports in input order.

    Per-structure failures (a dead worker, a time-out, a structure over the size caps) give failed reports (I = 0,
    ``error`` set) and never stop the batch. See :class:`CheckPool` to reuse workers across batches.
    """
    structures = list(structures)
    if not structures:
        return []
    workers = default_workers() if workers is None else workers
    with CheckPool(min(workers, len(structures)), timeout=timeout) as pool:
        return pool.check(structures, config)
