"""physics: judge lattice structures under gravity with breakable-joint rigid bodies in headless PyBullet.

A library of its own: it takes anything that offers ``vertices`` and ``edges`` arrays and imports nothing from
``structgen``. ``check_stability`` simulates; ``check_statics`` predicts the same report from a static frame solve
in milliseconds.

>>> from physics import PhysicsConfig, check_stability
>>> report = check_stability({"vertices": [[0, 0, 0], [0, 0, 1], [0, 0, 2]], "edges": [[0, 1], [1, 2]]},
...                          PhysicsConfig.preset("fast"))
>>> report.integrity
1.0
"""

from physics.config import PRESETS, PhysicsConfig
from physics.model import InputError
from physics.parallel import CheckPool, check_many
from physics.report import BrokenJoint, StabilityReport, quality
from physics.stability import check_stability
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
    "joint_forces",
    "quality",
]
