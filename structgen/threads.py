"""How many threads structgen's compiled and tensor code uses, and how its idle threads wait.

torch (on CPU) and numba's parallel kernels both run on OpenMP thread pools. By default an OpenMP thread that has
finished its share spins for a while before it sleeps, so that the next parallel region starts at once. That pays on a
machine nobody else uses, and collapses on a shared one: a spinning thread takes the core that a busy neighbour (or the
other half of our own batch) needed, and every region then waits for the slowest thread. Measured on a 2-core machine
beside one CPU-bound process (``benchmarks/threads.py``), spinning threads made the Autoverse kernel, the fortress
and layout growth slower on two threads than on one (the fortress at 57 %); with sleeping threads (and the changes
that :class:`FasterOf` and :func:`one_torch_thread` serve) two threads stay within 2 % of one or ahead.

So ``import structgen`` (this module runs first) sets, for itself and every process it starts:

- ``OMP_WAIT_POLICY=PASSIVE``: idle threads sleep;
- ``OMP_NUM_THREADS`` and ``NUMBA_NUM_THREADS`` to the cores this process may use, when a container's CPU quota
  allows fewer than its affinity mask does (torch and numba already follow the affinity mask, not the quota);
- ``NUMBA_NUM_THREADS`` to ``OMP_NUM_THREADS`` when only the latter is set, so one variable sets both pools.

A variable the user has set is never changed. The policy reaches a library only if structgen is imported before it:
a script that imports torch or numba first gets their defaults (set ``OMP_WAIT_POLICY=PASSIVE`` in the environment
to have it there too). On a machine of your own, ``OMP_WAIT_POLICY=ACTIVE`` buys back the spin-waiting speed (the
Autoverse step and observation at batch 64: about 110,000 env-steps/s on two threads instead of 100,000).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
from pathlib import Path

__all__ = ["FasterOf", "apply_thread_policy", "one_torch_thread", "usable_cores"]

_CGROUP_CPU_MAX = Path("/sys/fs/cgroup/cpu.max")


def _affinity_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # macOS and Windows have no affinity call
        return os.cpu_count() or 1


def usable_cores(cgroup_cpu_max: Path = _CGROUP_CPU_MAX) -> int:
    """The cores this process may use: its affinity mask, capped by a cgroup (v2) CPU quota when one is set."""
    cores = _affinity_cores()
    try:
        quota, period = cgroup_cpu_max.read_text().split()[:2]
        if quota != "max":
            cores = min(cores, max(1, math.ceil(int(quota) / int(period))))
    except (OSError, ValueError):  # no cgroup v2 file, or one we cannot read: the affinity mask stands
        pass
    return max(1, cores)


def apply_thread_policy(environ: MutableMapping[str, str] | None = None, cores: int | None = None) -> None:
    """Set the thread variables described above in ``environ`` (``os.environ``), leaving any already set alone."""
    environ = os.environ if environ is None else environ
    environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    cores = usable_cores() if cores is None else cores
    if cores < _affinity_cores():
        environ.setdefault("OMP_NUM_THREADS", str(cores))
    # OMP_NUM_THREADS may also be a list for nested regions ("4,2"); numba takes one whole number, or refuses to load.
    if environ.get("OMP_NUM_THREADS", "").strip().isdigit() and int(environ["OMP_NUM_THREADS"]) > 0:
        environ.setdefault("NUMBA_NUM_THREADS", environ["OMP_NUM_THREADS"].strip())


class FasterOf:
    """Picks, call by call, the faster of interchangeable ways to do the same work: a parallel kernel and its serial
    twin, which compute the same results.

    Which one wins depends on the load of the moment: beside a busy process, the parallel kernel's threads wait at
    each step's end for the one that shares its core, and two threads ran the Autoverse step about a tenth slower
    than one (``benchmarks/threads.py``); on an idle machine they ran it up to twice as fast. So each way's cost per
    unit of work is smoothed over its recent calls, the cheaper one is used, and every ``explore_every`` calls the
    other one gets ``trials`` calls to show whether the load has changed. The first call of each way is not counted:
    it may include loading or compiling.
    """

    def __init__(self, ways: tuple[str, ...] = ("serial", "parallel"), explore_every: int = 50, trials: int = 2) -> None:
        if len(ways) < 2 or trials < 1 or explore_every <= trials * (len(ways) - 1):
            raise ValueError("FasterOf needs two ways or more, and more calls between explorations than trials")
        self.ways = ways
        self.explore_every, self.trials = explore_every, trials
        self.cost: dict[str, float | None] = dict.fromkeys(ways)  # smoothed seconds per unit of work
        self._seen: set[str] = set()
        self._calls = 0

    def pick(self) -> str:
        """The way to use for the next call."""
        self._calls += 1
        for way in self.ways:  # each way is timed twice before choosing: once to warm up, once to count
            if self.cost[way] is None:
                return way
        best = min(self.ways, key=lambda way: self.cost[way])
        others = [way for way in self.ways if way != best]
        slot = self._calls % self.explore_every
        if slot < self.trials * len(others):
            return others[slot // self.trials]
        return best

    def record(self, way: str, seconds: float, units: int = 1) -> None:
        """How long the call that used ``way`` took, for ``units`` of work."""
        if way not in self._seen:
            self._seen.add(way)
            return
        per_unit = seconds / max(units, 1)
        old = self.cost[way]
        self.cost[way] = per_unit if old is None else old + 0.3 * (per_unit - old)


@contextmanager
def one_torch_thread() -> Iterator[None]:
    """Runs the block with torch on one CPU thread, then restores the count the caller had.

    For code made of many small tensor operations: torch splits an operation over its threads from about 32,000
    elements, and waking them can cost more than it gives. The Autoverse observation of 64 games took 0.2 ms on one
    thread and 0.4 ms on two; at 2,048 games two threads won on an idle machine and lost beside a busy process, so
    the engine lets :class:`FasterOf` choose. Setting the count costs a fraction of a microsecond. Torch's count is
    process-wide, so other threads' torch work in the block runs on one thread too."""
    import torch

    previous = torch.get_num_threads()
    if previous == 1:
        yield
        return
    torch.set_num_threads(1)
    try:
        yield
    finally:
        torch.set_num_threads(previous)
