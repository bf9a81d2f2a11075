"""Where a structure is stressed: each member's static load as a share of the break force, and the one colour scale
that pictures, mesh exports and run reports draw it in.

A member's share is the larger of its two joints' loads (the static analysis of the intact structure, load factors
applied) over the joint break force: 0 carries nothing, 1 is at the point of breaking, above 1 breaks. A member in a
piece with no static answer (it falls or tips whole) has no share (NaN) and gets its own colour.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from physics import PhysicsConfig, StabilityReport
    from structgen.structure import Structure

__all__ = ["LOAD_SCALE", "NO_ANSWER", "OVERLOADED", "load_colours", "load_key", "load_colormap", "member_load_shares"]

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
        shares = np.fmax(loads[0::2], loads[1::2]) / config.break_force
    return report, shares


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
