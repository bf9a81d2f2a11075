"""structgen: grow 3D lattice structures with neural cellular automata and judge them in rigid-body physics.

``import structgen`` is light: the Structure type eagerly, the NCA (which needs torch) and the domain checker
(:func:`check_domain`) on first use. It never imports the ``physics`` or ``evolution`` packages itself.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from structgen import _moved
from structgen._version import __version__
from structgen.structure import Structure, StructureError
from structgen.threads import apply_thread_policy

# Before anything loads torch or numba (the imports above do not): their thread pools read these variables once, at start.
apply_thread_policy()
_moved.install()  # old module names (moved in 0.4) import for one more release, with a warning

__all__ = [
    "LocalNCA",
    "NCAConfig",
    "Structure",
    "StructureError",
    "__version__",
    "check_domain",
    "grow",
    "grow_population",
    "random_weights",
]

_NCA_NAMES = {"LocalNCA", "NCAConfig", "grow", "grow_population", "random_weights"}

if TYPE_CHECKING:
    from structgen.nca import LocalNCA, NCAConfig, grow, grow_population, random_weights
    from structgen.runs.domain_check import check_domain


def __getattr__(name: str) -> Any:
    # torch takes a second or two to import; commands that only read structures should not pay for it.
    if name in _NCA_NAMES:
        from structgen import nca

        return getattr(nca, name)
    if name == "check_domain":  # it reaches the engine (evolution) and the run commands: load them only when asked
        from structgen.runs.domain_check import check_domain

        return check_domain
    raise AttributeError(f"module 'structgen' has no attribute {name!r}")
