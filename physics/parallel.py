"""Checking many structures in parallel: one PyBullet client per worker process, results in input order.

The workers are the project's one pool (:class:`evolution.pool.WorkerPool`): a worker that dies (a crash inside the
simulator, a kill from outside) or overruns its time limit costs only the structure it was working on, which gets a
failed report (I = 0, ``error`` set); a fresh worker takes the dead one's place, and the rest of the batch completes.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable, Sequence
from typing import Any

from evolution.pool import Lost, WorkerPool, available_cpus
from physics._quiet import import_pybullet
from physics.config import PhysicsConfig
from physics.model import read_structure
from physics.report import StabilityReport
from physics.stability import check_or_fail

__all__ = ["CheckPool", "check_many", "default_workers"]

log = logging.getLogger(__name__)

#: The number of CPUs this process may use: the default number of workers.
default_workers = available_cpus


class _Check:
    """The job the workers run: check one ``(vertices, edges, config)``. Unpickled in a worker, it imports the
    simulator first, so that a worker's time limit starts once it is ready to simulate."""

    def __call__(self, payload: tuple[Any, Any, PhysicsConfig]) -> StabilityReport:
        return check_or_fail(*payload)

    def __reduce__(self) -> tuple[Any, tuple]:
        return _loaded_check, ()


def _loaded_check() -> _Check:
    import_pybullet()
    return _CHECK


_CHECK = _Check()


class CheckPool:
    """Worker processes that each keep one PyBullet client and check structures sent to them.

    Keep one pool for many batches (an evolution run) to pay the start-up once; use it as a context manager or call
    :meth:`close`. ``workers=0`` checks in this process, without the crash isolation.

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
        # The simulator prints engine warnings from C; in a worker they would only be noise.
        self._pool = WorkerPool(self.workers, timeout=timeout, quiet=True)

    @property
    def pids(self) -> list[int]:
        """Process ids of the running workers."""
        return self._pool.pids

    def __enter__(self) -> CheckPool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Stop all workers."""
        self._pool.close()

    def check(self, structures: Iterable[Any], config: PhysicsConfig | None = None) -> list[StabilityReport]:
        """Check every structure; the reports come back in input order.

        Raises:
            physics.InputError: a structure cannot be read at all (before any simulation starts). Structures that
                are readable but too large get failed reports instead, like any other per-structure failure.
        """
        config = config or PhysicsConfig()
        payloads = [(*read_structure(s), config) for s in structures]
        reports = self._pool.map(_CHECK, payloads)
        for index, (payload, report) in enumerate(zip(payloads, reports)):
            if isinstance(report, Lost):
                log.warning("structure %d: %s", index, report.reason)
                reports[index] = StabilityReport.failed(payload[0], payload[1], report.reason, config)
        return reports


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
