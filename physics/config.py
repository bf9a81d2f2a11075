"""Settings of a stability check: the physical model, the simulation's speed knobs, the score, and the guard rails.

The model follows the paper (and Unity's defaults it relied on): 1 kg spheres and cylinders, gravity 9.81 m/s^2, and
fixed joints that break when the force on them exceeds 52.5 N. With lattice spacing 1 m, sphere radius 0.25 m and
cylinder radius 0.08 m, that threshold lets a 3-vertex column stand while a 4-vertex column breaks, and a 4-vertex
column braced by four ground struts stands.

Two presets differ only in how the simulation is run, never in the model:

- ``faithful``: the paper's protocol: 1/240 s steps, 50 solver iterations, a full 30 s under gravity.
- ``fast``: 1/120 s steps, 20 solver iterations, stop once every vertex has been slower than 0.02 m/s for 0.5 s,
  and never simulate more than 2 s (in the benchmark's faithful runs every joint that broke did so within 1.6 s).
  ``benchmarks/physics.py`` measures how often it agrees with ``faithful``.

``PhysicsConfig()`` is the faithful preset.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from types import MappingProxyType
from typing import Any, Literal

__all__ = ["PRESETS", "PhysicsConfig"]


@dataclass(frozen=True)
class PhysicsConfig:
    """Everything a stability check depends on. Frozen: derive variants with :meth:`replace` or :meth:`preset`.

    Attributes:
        timestep: simulated seconds per physics step.
        solver_iterations: constraint solver iterations per step (more: stiffer joints, slower).
        solver_residual: the solver stops iterating early once its residual is below this (Bullet's default 1e-7).
        horizon: longest simulated time, seconds (the paper: 30).
        early_stop: stop before the horizon once the structure has settled.
        settle_speed: a vertex slower than this (m/s) counts as at rest.
        settle_window: the structure has settled when every vertex has been at rest for this long (s).
        check_interval: how often (simulated s) the settled and explosion tests run.
        gravity: downward acceleration, m/s^2.
        break_force: a joint breaks when the force it carries exceeds this, N.
        break_torque: a joint also breaks above this torque, N m (infinite: torque never breaks, as in the paper).
        sphere_radius: radius of a vertex sphere, m.
        cylinder_radius: radius of an edge cylinder, m.
        spacing: distance between neighbouring lattice cells, m.
        sphere_mass: mass of a vertex sphere, kg.
        cylinder_mass: mass of an edge cylinder, kg (whatever its length, as in Unity).
        friction: ground contact friction coefficient.
        rolling_friction: rolling friction of spheres; a little keeps debris from rolling forever.
        spinning_friction: spinning friction of spheres.
        height_weight: W_h in Q = I + (W_h * H + W_c * C) * I.
        complexity_weight: W_c in the same formula.
        height_mode: "max": H is highest minus lowest vertex; "mean": mean vertex height above the lowest (the
            paper's "average height" variant).
        max_vertices: structures with more vertices are refused before simulating.
        max_joints: structures with more joints (two per edge) are refused; PyBullet's first step costs time
            growing with the square of the joint count.
        max_memory_mb: the static analysis refuses structures whose solve it estimates to need more memory than
            this (MiB; about 20,000 vertices by default).
        max_steps: a check that would take more simulation steps than this (``horizon / timestep``) is refused
            when the settings are made: a tiny timestep would otherwise run for days.
        fall_speed: a vertex still faster than this (m/s) when the simulation ends is still falling (faster than a
            fall from half a lattice unit): it adds no height, and the structure is not said to stand. Settling
            debris moves far slower (at most 2.5 m/s at the end of the fast preset's 2 s, measured on 600 random
            structures).
        max_speed: a body faster than this (m/s) means the simulation exploded.
        max_distance: a body further than this from where it started (m) means the simulation exploded.
        statics_load_factor: the static analysis (``physics.statics``) multiplies the part of a joint's force along
            its cylinder by this before comparing with ``break_force``: it stands in for the overshoot a simulation
            sees when gravity switches on, which is small for loads along a member.
        statics_shear_factor: the same for the part across the cylinder (a cantilever's load), which overshoots
            far more in the simulation.
        statics_beam_radius: radius (m) of the solid beams whose stiffness the static analysis gives the edges. Only
            the ratio of bending to axial stiffness matters; PyBullet's fixed joints resist bending far more than a
            slender 0.08 m cylinder would, and a larger radius matches the simulation's load sharing better.
        statics_tip_margin: the static analysis lets a piece tip over unless its centre of mass lies at least this far
            (m) inside the convex hull of its ground contacts; a compliant structure sags, and one balanced close to
            an edge of its footprint rolls over in the simulation.

    The four statics settings were fitted on half of the 240 structures of ``benchmarks/statics.py`` and checked on
    the other half (see ``benchmarks/structures.md``).
    """

    timestep: float = 1 / 240
    solver_iterations: int = 50
    solver_residual: float = 1e-7
    horizon: float = 30.0
    early_stop: bool = False
    settle_speed: float = 0.02
    settle_window: float = 0.5
    check_interval: float = 0.05
    gravity: float = 9.81
    break_force: float = 52.5
    break_torque: float = math.inf
    sphere_radius: float = 0.25
    cylinder_radius: float = 0.08
    spacing: float = 1.0
    sphere_mass: float = 1.0
    cylinder_mass: float = 1.0
    friction: float = 0.5
    rolling_friction: float = 0.01
    spinning_friction: float = 0.01
    height_weight: float = 1.0
    complexity_weight: float = 1.0
    height_mode: Literal["max", "mean"] = "max"
    max_vertices: int = 2000
    max_joints: int = 3000
    max_memory_mb: float = 4096.0
    max_steps: int = 100_000
    fall_speed: float = 3.0
    max_speed: float = 100.0
    max_distance: float = 1000.0
    statics_load_factor: float = 1.05
    statics_shear_factor: float = 1.2
    statics_beam_radius: float = 0.3
    statics_tip_margin: float = 0.05

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name == "height_mode":
                if value not in ("max", "mean"):
                    raise ValueError(f"physics height_mode must be 'max' or 'mean', got {value!r}")
            elif item.name == "early_stop":
                if not isinstance(value, bool):
                    raise ValueError(f"physics {item.name} must be true or false, got {value!r}")
            elif item.type in ("int", int):
                if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                    raise ValueError(f"physics {item.name} must be a positive integer, got {value!r}")
            else:
                ok = isinstance(value, (int, float)) and not isinstance(value, bool) and not math.isnan(value)
                lower_ok = value >= 0 if item.name in _MAY_BE_ZERO else value > 0
                if not ok or not lower_ok or (math.isinf(value) and item.name not in _MAY_BE_INFINITE):
                    bound = "a non-negative" if item.name in _MAY_BE_ZERO else "a positive"
                    raise ValueError(f"physics {item.name} must be {bound} number, got {value!r}")
        if self.cylinder_radius > self.sphere_radius:
            raise ValueError(f"physics cylinder_radius {self.cylinder_radius} must not exceed sphere_radius {self.sphere_radius}")
        if 2 * self.sphere_radius >= self.spacing:
            raise ValueError(
                f"physics sphere_radius {self.sphere_radius} must be less than half the spacing {self.spacing}, "
                "or edges have no length"
            )
        if self.timestep > self.horizon:
            raise ValueError(f"physics timestep {self.timestep} is longer than the horizon {self.horizon}")
        steps = self.horizon / self.timestep
        if steps > self.max_steps:
            raise ValueError(
                f"physics horizon {self.horizon:g} s in steps of {self.timestep:g} s is {steps:,.0f} steps, more than "
                f"max_steps = {self.max_steps:,}; use a longer timestep or a shorter horizon (or raise max_steps)"
            )

    @classmethod
    def presets(cls) -> Mapping[str, PhysicsConfig]:
        """The named presets, ``faithful`` first (it is also ``PhysicsConfig()``)."""
        return MappingProxyType(PRESETS)

    @classmethod
    def preset(cls, name: str, **changes: Any) -> PhysicsConfig:
        """A named preset (``"faithful"`` or ``"fast"``), optionally with some fields changed."""
        if name not in PRESETS:
            raise ValueError(f"unknown physics preset {name!r}; choose one of {', '.join(PRESETS)}")
        return replace(PRESETS[name], **changes)

    def replace(self, **changes: Any) -> PhysicsConfig:
        """A copy with some fields changed (validated like the constructor)."""
        return replace(self, **changes)

    def stepped_as(self, name: str) -> PhysicsConfig:
        """The same physical model (masses, sizes, joints, score) simulated with preset ``name``'s time stepping, so
        a run judged with one preset can be re-checked with another."""
        if name not in PRESETS:
            raise ValueError(f"unknown physics preset {name!r}; choose one of {', '.join(PRESETS)}")
        return replace(self, **{field: getattr(PRESETS[name], field) for field in _STEPPING})

    def room_for(self, n_vertices: int, n_edges: int) -> dict[str, int]:
        """The cap settings a structure of this size needs beyond this configuration's, raised to its own size
        (``max_vertices``, and ``max_joints`` at two joints per edge); empty when it fits.
        ``config.replace(**config.room_for(v, e))`` simulates it."""
        needs = {"max_vertices": n_vertices, "max_joints": 2 * n_edges}
        return {name: need for name, need in needs.items() if need > getattr(self, name)}

    @property
    def preset_name(self) -> str | None:
        """Name of the preset this configuration equals, or None if it was customised."""
        return next((name for name, preset in PRESETS.items() if preset == self), None)


_MAY_BE_ZERO = {
    "friction",
    "rolling_friction",
    "spinning_friction",
    "height_weight",
    "complexity_weight",
    "settle_speed",
    "statics_tip_margin",
}
_MAY_BE_INFINITE = {"break_force", "break_torque", "max_speed", "max_distance"}

PRESETS: dict[str, PhysicsConfig] = {}
# What the presets differ in: how the simulation steps through time, not the structure or its score.
_STEPPING = ("timestep", "solver_iterations", "horizon", "early_stop")
PRESETS["faithful"] = PhysicsConfig()
PRESETS["fast"] = PhysicsConfig(timestep=1 / 120, solver_iterations=20, horizon=2.0, early_stop=True)
