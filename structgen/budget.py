"""How much memory one piece of work may take: the budget that exports and growth are checked against before they
allocate anything.

The default is 4,096 MiB; the environment variable ``STRUCTGEN_MEMORY_MB`` sets another (``STRUCTGEN_MEMORY_MB=16000
structgen export big.json big.glb``). Estimates come from measurements on this project's machine and err on the
generous side; the physics has its own setting for the same purpose (``PhysicsConfig.max_memory_mb``).
"""

from __future__ import annotations

import os

from structgen.errors import InputError

__all__ = ["DEFAULT_MEMORY_MB", "ENVIRONMENT_VARIABLE", "check_memory", "memory_budget_mb"]

DEFAULT_MEMORY_MB = 4096
ENVIRONMENT_VARIABLE = "STRUCTGEN_MEMORY_MB"


def memory_budget_mb() -> float:
    """The budget in MiB: ``STRUCTGEN_MEMORY_MB`` if set, else the default."""
    text = os.environ.get(ENVIRONMENT_VARIABLE, "").strip()
    if not text:
        return float(DEFAULT_MEMORY_MB)
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value < float("inf"):
        raise InputError(f"{ENVIRONMENT_VARIABLE}={text!r}: expected a positive number of MiB")
    return value


def check_memory(needed_bytes: float, what: str, lighter: str = "") -> None:
    """Refuse, before any allocation, work estimated to need more than the budget; ``lighter`` says how to make it
    smaller."""
    budget = memory_budget_mb()
    needed = needed_bytes / (1 << 20)
    if needed > budget:
        hint = f"{lighter}, or set " if lighter else "set "
        raise InputError(
            f"{what} needs about {needed:,.0f} MiB, more than the memory budget of {budget:,.0f} MiB ({hint}"
            f"{ENVIRONMENT_VARIABLE} to raise it)"
        )
