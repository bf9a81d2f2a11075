"""What a stability check reports, and the paper's score."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, overload

import numpy as np

from physics.config import PhysicsConfig

__all__ = ["BrokenJoint", "EveryJointFell", "StabilityReport", "quality"]


def quality(integrity: float, height: float, complexity: float, config: PhysicsConfig) -> float:
    """The paper's score Q = I + (W_h * H + W_c * C) * I: height and complexity only count as far as it stands."""
    return integrity + (config.height_weight * height + config.complexity_weight * complexity) * integrity


def integrity_of(n_broken: int, n_joints: int) -> float:
    """I: the share of joints unbroken (1 for a structure without joints)."""
    return 1.0 - n_broken / n_joints if n_joints else 1.0


def height_of(z: np.ndarray, config: PhysicsConfig) -> float:
    """H in lattice units from vertex heights in metres: highest minus lowest, or mean above lowest."""
    if len(z) == 0 or not np.isfinite(z).all():
        return 0.0
    top = z.max() if config.height_mode == "max" else z.mean()
    return float((top - z.min()) / config.spacing)


@dataclass(frozen=True)
class BrokenJoint:
    """A joint that gave way: which one, between which edge and vertex, when, and under what load. ``fell`` (static
    analysis only): the joint was not overloaded, but its piece lost its support or tipped over and falls."""

    joint: int
    edge: int
    vertex: int
    time: float
    force: float
    torque: float
    fell: bool = False


class EveryJointFell(Sequence[BrokenJoint]):
    """The broken joints of a structure that fell apart entirely: joint ``j`` joins edge ``j // 2`` to its end
    ``j % 2``, all at time 0, none overloaded. Each is made when read: a random network's block has some 12,000 joints,
    and making them all took nine tenths of the time to judge it, for a report that is mostly only counted."""

    def __init__(self, edges: np.ndarray) -> None:
        self._edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)

    def __len__(self) -> int:
        return 2 * len(self._edges)

    @overload
    def __getitem__(self, index: int) -> BrokenJoint: ...
    @overload
    def __getitem__(self, index: slice) -> tuple[BrokenJoint, ...]: ...
    def __getitem__(self, index: int | slice) -> BrokenJoint | tuple[BrokenJoint, ...]:
        if isinstance(index, slice):
            return tuple(self[j] for j in range(*index.indices(len(self))))
        j = range(len(self))[index]  # negative indices, and IndexError past the end, as a tuple's
        vertex = int(self._edges[j // 2, j % 2])
        return BrokenJoint(joint=j, edge=j // 2, vertex=vertex, time=0.0, force=0.0, torque=0.0, fell=True)

    def __eq__(self, other: object) -> bool:
        if isinstance(other, EveryJointFell):
            return np.array_equal(self._edges, other._edges)
        return isinstance(other, Sequence) and tuple(self) == tuple(other)

    __hash__ = None  # type: ignore[assignment]  # equal to tuples, which hash otherwise

    def __repr__(self) -> str:
        return f"EveryJointFell({len(self)} joints)"


@dataclass(frozen=True)
class StabilityReport:
    """The outcome of simulating one structure under gravity.

    ``integrity`` (I) is the share of joints still unbroken, ``height`` (H) the final height in lattice units (see
    ``PhysicsConfig.height_mode``) of the vertices that are not still falling, ``complexity`` (C) the vertex count,
    and ``score`` (Q) the paper's ``I + (W_h * H + W_c * C) * I``. A simulation that exploded, or a check that
    failed, reports I = 0 and Q = 0. Positions are in metres, z up, with the ground at z = 0.

    ``falling`` counts the vertices still faster than ``PhysicsConfig.fall_speed`` when the simulation ended (a
    piece dropping from above, cut short by the horizon): they add no height. ``final_speed`` is the fastest
    vertex's speed then. :attr:`stands` is the verdict: no joint broke and everything came to rest.

    A transient report (``method = "transient"``, from ``check_transient``) covers only the first moments, with
    joints that hold: its ``integrity`` is the strength ratio min(1, break force / ``peak_force``), and it is
    intact when no joint's force went past the break force.
    """

    integrity: float
    height: float
    complexity: int
    score: float
    n_joints: int
    broken_joints: Sequence[BrokenJoint]  # a tuple, or EveryJointFell
    joint_forces: np.ndarray  # (J,) force each joint carried in the last step, N; NaN for broken joints
    peak_force: float  # the largest force any joint carried in any step, N (the spawn transient included)
    initial_positions: np.ndarray  # (V, 3) sphere centres as placed
    final_positions: np.ndarray  # (V, 3) sphere centres at the end
    final_edge_ends: np.ndarray  # (E, 2, 3) cylinder end points at the end
    edges: np.ndarray  # (E, 2) the structure's edges, for drawing
    sim_time: float
    steps: int
    settled: bool
    exploded: bool = False
    error: str | None = None
    wall_time: float = 0.0
    cpu_time: float = 0.0
    config: PhysicsConfig = field(default_factory=PhysicsConfig)
    method: str = "bullet"  # "bullet": simulated; "statics": predicted by physics.statics; "transient": first moments;
    # "collapse": screened out by physics.statics.overload_ratio as falling apart entirely
    falling: int = 0
    final_speed: float = 0.0
    peak_forces: np.ndarray | None = None  # (J,) the largest force each joint carried in any step, N; simulated only

    @property
    def intact(self) -> bool:
        """No joint broke (for a transient report: none was loaded past the break force) and the simulation ran
        normally."""
        if self.method == "transient" and self.peak_force > self.config.break_force:
            return False
        return not self.broken_joints and not self.exploded and self.error is None

    @property
    def stands(self) -> bool:
        """The verdict: no joint broke and nothing was still falling when the simulation ended. (A standing
        structure may still be settling slowly then: half of those that stand under the faithful preset still move
        at 0.01 to 0.15 m/s when the fast preset's 2 s end.)"""
        return self.intact and self.falling == 0

    def verdict(self) -> str:
        """The outcome in a few words: stands, breaks, still falling, still moving, exploded, or failed."""
        if self.error:
            return f"check failed: {self.error}"
        if self.exploded:
            return "the simulation exploded (scored as collapsed)"
        if self.method == "transient":
            within = self.peak_force <= self.config.break_force
            return (
                f"{'holds' if within else 'breaks'} in the first {self.sim_time:g} s: the largest joint force, "
                f"{self.peak_force:.1f} N, is {'within' if within else 'over'} the {self.config.break_force:g} N limit"
            )
        if self.broken_joints:
            return f"breaks: {len(self.broken_joints)} of {self.n_joints} joints broke"
        if self.method == "statics":  # nothing moves in a static analysis, so "came to rest" would say nothing
            return "stands: the static analysis finds no joint over the break force"
        if self.falling:
            return (
                f"still falling when the simulation ended: {self.falling} "
                f"{'vertex' if self.falling == 1 else 'vertices'} faster than {self.config.fall_speed:g} m/s, which add "
                "no height"
            )
        if not self.settled:
            return (
                f"stands: no joint broke (still settling when the simulation ended after {self.sim_time:g} s, fastest "
                f"vertex {self.final_speed:.2f} m/s)"
            )
        return "stands: no joint broke, and it came to rest"

    @property
    def broken_edges(self) -> np.ndarray:
        """Indices of edges with at least one broken joint, sorted."""
        return np.unique(np.array([b.edge for b in self.broken_joints], dtype=np.int64))

    def to_dict(self, *, positions: bool = True) -> dict[str, Any]:
        """Plain JSON-ready values; ``positions=False`` leaves out the per-body coordinates."""
        data: dict[str, Any] = {
            "integrity": self.integrity,
            "height": self.height,
            "complexity": self.complexity,
            "score": self.score,
            "intact": self.intact,
            "stands": self.stands,
            "n_joints": self.n_joints,
            "broken_joints": [asdict(b) for b in self.broken_joints],
            "peak_force": self.peak_force,
            "sim_time": self.sim_time,
            "steps": self.steps,
            "settled": self.settled,
            "falling": self.falling,
            "final_speed": self.final_speed,
            "exploded": self.exploded,
            "error": self.error,
            "wall_time": self.wall_time,
            "cpu_time": self.cpu_time,
            "method": self.method,
            "preset": self.config.preset_name,
            "config": {k: (v if not (isinstance(v, float) and math.isinf(v)) else "inf") for k, v in asdict(self.config).items()},
        }
        if positions:
            data["initial_positions"] = self.initial_positions.tolist()
            data["final_positions"] = self.final_positions.tolist()
            data["final_edge_ends"] = self.final_edge_ends.tolist()
            data["edges"] = self.edges.tolist()
            data["joint_forces"] = [None if np.isnan(f) else f for f in self.joint_forces.tolist()]
            if self.peak_forces is not None:
                data["peak_forces"] = self.peak_forces.tolist()
        return data

    @classmethod
    def failed(cls, vertices: np.ndarray, edges: np.ndarray, message: str, config: PhysicsConfig) -> StabilityReport:
        """The report of a check that could not be completed: integrity and score 0, with the reason."""
        n_vertices, n_edges = len(vertices), len(edges)
        nowhere = np.full((n_vertices, 3), np.nan)
        return cls(
            integrity=0.0,
            height=0.0,
            complexity=n_vertices,
            score=0.0,
            n_joints=2 * n_edges,
            broken_joints=(),
            joint_forces=np.full(2 * n_edges, np.nan),
            peak_force=0.0,
            initial_positions=nowhere,
            final_positions=nowhere,
            final_edge_ends=np.full((n_edges, 2, 3), np.nan),
            edges=np.asarray(edges, dtype=np.int64).reshape(-1, 2),
            sim_time=0.0,
            steps=0,
            settled=False,
            error=message,
            config=config,
        )
