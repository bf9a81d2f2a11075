"""Where a structure is stressed: each member's static load as a share of the break force, and the one colour scale
that pictures, mesh exports and run reports draw it in.

A member's share is the larger of its two joints' loads (the static analysis of the intact structure, load factors
applied) over the joint break force: 0 carries nothing, 1 is at the point of breaking, above 1 breaks. A member in a
piece with no static answer (it falls or tips whole) has no share (NaN) and gets its own colour.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from physics import PhysicsConfig, StabilityReport
    from structgen.structure import Structure

__all__ = [
    "LOAD_SCALE",
    "NO_ANSWER",
    "OVERLOADED",
    "LevelShare",
    "level_shares",
    "load_colours",
    "load_colormap",
    "load_key",
    "member_load_shares",
    "member_peak_shares",
]

#: Shares from none (pale grey) through half the break force (orange) to the break force (dark red).
LOAD_SCALE = ((0.0, "#cfd8dc"), (0.5, "#fdae61"), (1.0, "#a50026"))
#: Members loaded beyond the break force: they break.
OVERLOADED = "#3d0010"
#: Members of a piece the static analysis has no answer for (it falls or tips whole).
NO_ANSWER = "#6a51a3"
# Mesh formats group members of one colour (GLB: one material each), so shares are drawn in steps of 1 %.
_STEPS = 100


def member_load_shares(structure: Structure, config: PhysicsConfig | None = None) -> tuple[StabilityReport, np.ndarray]:
    """The static analysis's report and each edge's load share (E,), NaN where its piece has no static answer."""
    from physics import PhysicsConfig
    from physics.statics import check_statics_with_loads

    config = config or PhysicsConfig()
    report, loads = check_statics_with_loads(structure, config)
    if not structure.n_edges:
        return report, np.zeros(0)
    with np.errstate(invalid="ignore"):  # both joints NaN: fmax keeps NaN, as it should
        shares = _member_shares(loads, config.break_force)
    return report, shares


def member_peak_shares(report: StabilityReport) -> np.ndarray:
    """Each edge's share (E,) of the break force by a simulation: the largest force either of its joints carried in
    any step of ``report``'s check (a joint that broke, up to the step it broke in). Where the static analysis and
    PyBullet part ways on where a frame's load goes (tall towers: ``benchmarks/tall_sharing.py``), this is where the
    simulation put it; a check in the first moments (``check_transient``) shows the spawn transient's peaks."""
    if report.peak_forces is None:
        raise ValueError(f"a {report.method} report has no simulated joint forces: peak shares need a PyBullet check")
    return _member_shares(report.peak_forces, report.config.break_force)


def _member_shares(joint_values: np.ndarray, break_force: float) -> np.ndarray:
    """(E,) each edge's more loaded joint of ``joint_values`` (J,), two joints an edge, over ``break_force``; NaN only
    where both joints are."""
    return np.fmax(joint_values[0::2], joint_values[1::2]) / break_force


def _rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)], dtype=np.float64)


def load_colours(shares: np.ndarray) -> np.ndarray:
    """(E, 4) RGBA bytes for the shares: the scale interpolated in steps of 1 %, :data:`OVERLOADED` above 1 and
    :data:`NO_ANSWER` where NaN."""
    shares = np.asarray(shares, dtype=np.float64)
    stops = np.array([stop for stop, _ in LOAD_SCALE])
    rgb = np.array([_rgb(colour) for _, colour in LOAD_SCALE])
    stepped = np.round(np.clip(np.nan_to_num(shares), 0.0, 1.0) * _STEPS) / _STEPS
    colours = np.stack([np.interp(stepped, stops, rgb[:, c]) for c in range(3)], axis=1)
    colours[shares > 1.0] = _rgb(OVERLOADED)
    colours[np.isnan(shares)] = _rgb(NO_ANSWER)
    alpha = np.full((len(shares), 1), 255.0)
    return np.rint(np.concatenate([colours, alpha], axis=1)).astype(np.uint8)


def load_key(shares: np.ndarray, config: PhysicsConfig) -> dict[str, Any]:
    """What the colours of a stressed mesh mean, for the file's metadata (a mesh carries no colour bar)."""
    finite = shares[np.isfinite(shares)]
    return {
        "colours": "each member's static load (the larger of its two joints', load factors applied) over the joint "
        f"break force of {config.break_force:g} N",
        "scale": [[stop, colour] for stop, colour in LOAD_SCALE],
        "above_break_force": OVERLOADED,
        "no_static_answer": NO_ANSWER,
        "peak_share": float(finite.max()) if len(finite) else None,
        "members_over_break_force": int((finite > 1.0).sum()),
    }


def load_colormap() -> Any:
    """The scale as a matplotlib colour map for colour bars (over: :data:`OVERLOADED`, bad: :data:`NO_ANSWER`)."""
    from matplotlib.colors import LinearSegmentedColormap

    colormap = LinearSegmentedColormap.from_list("load share", [(stop, colour) for stop, colour in LOAD_SCALE])
    return colormap.with_extremes(over=OVERLOADED, bad=NO_ANSWER)


@dataclass(frozen=True)
class LevelShare:
    """How evenly the members between one level and the next carry what lies above them (forces in N)."""

    level: int  # the lower level of the two, counted from the ground (0)
    members: int  # members joining it to the level above
    bodies_above: int  # spheres and cylinders above those members
    even: float  # the force on each member's lower joint were they all loaded alike, along their axes
    peak: float  # the largest force on a lower joint of those members

    @property
    def ratio(self) -> float:
        """The peak over the even share: 1 where every member carries alike; below 1 where diagonals pass part of
        their load by bending rather than along their axes."""
        return self.peak / self.even


def level_shares(structure: Structure, joint_forces: np.ndarray, config: PhysicsConfig | None = None) -> list[LevelShare]:
    """Each pair of neighbouring levels of ``structure``, lowest first: the members between them, the even share and
    the peak of ``joint_forces`` ((J,) N, in :mod:`physics.model`'s joint order, two per edge; the static analysis's
    :func:`physics.statics.joint_forces` or a simulation's ``peak_forces``) on their lower joints.

    Everything above a pair of levels stands on the lower joints of the members between them, so their forces'
    upright parts add up to its weight and theirs, whatever the design. Were every member loaded alike along its
    axis, each would carry that weight over the sum of the members' cosines of slope: the even share. A design holds
    where the peak is within the break force, so the ratio of the two is what uneven sharing (and the simulation's
    spawn transient) costs: ``benchmarks/tall_sharing.py``. A level whose forces are all NaN (broken joints, pieces
    with no static answer) has a NaN peak."""
    from physics import PhysicsConfig

    config = config or PhysicsConfig()
    if config.sphere_mass != config.cylinder_mass:
        raise ValueError("level shares count bodies: spheres and cylinders must weigh alike")
    vertices, edges = np.asarray(structure.vertices), np.asarray(structure.edges).reshape(-1, 2)
    forces = np.asarray(joint_forces, dtype=np.float64)
    if forces.shape != (2 * len(edges),):
        raise ValueError(
            f"joint_forces must hold two forces an edge ({2 * len(edges)} for this structure), got shape {forces.shape}"
        )
    levels = vertices[:, 2] - vertices[:, 2].min() if len(vertices) else np.zeros(0, dtype=np.int64)
    ends = levels[edges]  # (E, 2) each end's level
    lower = np.minimum(ends[:, 0], ends[:, 1])
    rises = ends[:, 1] - ends[:, 0]
    lower_joint = forces.reshape(-1, 2)[np.arange(len(edges)), (rises < 0).astype(np.int64)]
    span = vertices[edges[:, 1]] - vertices[edges[:, 0]]
    cosine = np.abs(span[:, 2]) / np.linalg.norm(span, axis=1) if len(edges) else np.zeros(0)
    body = config.sphere_mass * config.gravity
    rows = []
    for level in range(int(levels.max(initial=0))):
        between = (lower == level) & (np.abs(rises) == 1)
        if not between.any():
            continue
        above = int((levels > level).sum() + (lower > level).sum())
        members = int(between.sum())
        even = body * (above + members) / float(cosine[between].sum())
        rows.append(LevelShare(level, members, above, even, float(np.fmax.reduce(lower_joint[between]))))
    return rows
