"""How many threads structgen's compiled and tensor code uses, and how its idle threads wait.

torch (on CPU) and numba's parallel kernels both run on OpenMP thread pools. By default an OpenMP thread that has
finished its share spins for a while before it sleeps, so that the next parallel region starts at once. That pays on a
machine nobody else uses, and collapses on a shared one: a spinning thread takes the core that a busy neighbour (or the
other half of our own batch) needed, and every region then waits for the slowest thread. Measured on a 2-core machine
beside one CPU-bound process (``benchmarks/threads.py``), spinning threads made the Autoverse kernel and layout growth
slower on two threads than on one; sleeping threads kept two threads within about a tenth of one thread's speed, and
the fortress engine level with it.

So ``import structgen`` (this module runs first) sets, for itself and every process it starts:

- ``OMP_WAIT_POLICY=PASSIVE``: idle threads sleep;
- ``OMP_NUM_THREADS`` and ``NUMBA_NUM_THREADS`` to the cores this process may use, when a container's CPU quota
  allows fewer than its affinity mask does (torch and numba already follow the affinity mask, not the quota);
- ``NUMBA_NUM_THREADS`` to ``OMP_NUM_THREADS`` when only the latter is set, so one variable sets both pools.

A variable the user has set is never changed. The policy reaches a library only if structgen is imported before it:
a script that imports torch or numba first gets their defaults (set ``OMP_WAIT_POLICY=PASSIVE`` in the environment
to have it there too). On a machine of your own, ``OMP_WAIT_POLICY=ACTIVE`` buys back the spin-waiting speed (the
Autoverse kernel at batch 64: about 130,000 env-steps/s on two threads instead of 80,000).
"""

from __future__ import annotations

import math
import os
from collections.abc import MutableMapping
from pathlib import Path

__all__ = ["apply_thread_policy", "usable_cores"]

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
