"""physics: judge lattice structures under gravity with breakable-joint rigid bodies in headless PyBullet.

A library of its own: it takes anything that offers ``vertices`` and ``edges`` arrays and imports nothing from
``structgen``. ``check_stability`` simulates; ``check_statics`` predicts the same report from a static frame solve
in milliseconds; ``check_transient`` simulates only the first moments, with joints that hold, and says how far the
largest load is from breaking one.

>>> from physics import PhysicsConfig, check_stability
>>> report = check_stability({"vertices": [[0, 0, 0], [0, 0, 1], [0, 0, 2]], "edges": [[0, 1], [1, 2]]},
...                          PhysicsConfig.preset("fast"))
>>> report.integrity
1.0
"""

from typing import TYPE_CHECKING, Any

from physics.config import PRESETS, PhysicsConfig

# Everything but the settings loads on first use: reading PhysicsConfig (for its defaults, say) should not cost the
# import of scipy's sparse solvers.
_LAZY = {
    "InputError": "physics.model",
    "CheckPool": "physics.parallel",
    "check_many": "physics.parallel",
    "BrokenJoint": "physics.report",
    "StabilityReport": "physics.report",
    "quality": "physics.report",
    "check_stability": "physics.stability",
    "check_transient": "physics.stability",
    "check_statics": "physics.statics",
    "joint_forces": "physics.statics",
}

if TYPE_CHECKING:
    from physics.model import InputError
    from physics.parallel import CheckPool, check_many
    from physics.report import BrokenJoint, StabilityReport, quality
    from physics.stability import check_stability, check_transient
    from physics.statics import check_statics, joint_forces

__all__ = [
    "PRESETS",
    "BrokenJoint",
    "CheckPool",
    "InputError",
    "PhysicsConfig",
    "StabilityReport",
    "check_many",
    "check_stability",
    "check_statics",
    "check_transient",
    "joint_forces",
    "quality",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'physics' has no attribute {name!r}")
