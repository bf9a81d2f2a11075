"""A structure as a run report draws it (:mod:`structgen.runs.report`): a 3D view to turn, each member coloured by
its static load as a share of the break force, and the static analysis's verdict and I, H, C and Q beside it."""

from __future__ import annotations

from typing import Any

import numpy as np

from structgen.structure import Structure

__all__ = ["structure_view"]

#: Load shares from none (pale) through half the break force to the break force and over (dark red).
LOAD_COLOURS = [[0.0, "#cfd8dc"], [0.5, "#fdae61"], [1.0, "#a50026"]]


def structure_view(structure: Structure, config: Any = None) -> dict[str, Any]:
    """``{"figure", "verdict", "fields"}`` for a report: members as lines coloured by the larger of their two joints'
    static loads over the break force (the intact structure, load factors applied; grey where a piece has no static
    answer), vertices as dots, and the static analysis's verdict with I, H, C and Q."""
    import plotly.graph_objects as go

    from physics import PhysicsConfig
    from physics.statics import check_statics_with_loads
    from structgen.runs.report import plain_figure

    config = config or PhysicsConfig()
    report, loads = check_statics_with_loads(structure, config)
    vertices = structure.vertices.astype(float)
    edges = structure.edges
    share = np.fmax(loads[0::2], loads[1::2]) / config.break_force if len(edges) else np.zeros(0)
    # Each member is a separate stretch of one line: its two ends, then a gap; all three points carry its share.
    points = np.full((len(edges) * 3, 3), np.nan)
    points[0::3], points[1::3] = vertices[edges[:, 0]], vertices[edges[:, 1]]
    # Single precision and a hover template over the shares keep a view a few kilobytes: an archive has thousands.
    colour = np.repeat(np.where(np.isnan(share), -1.0, np.minimum(share, 1.0)), 3).astype(np.float32)
    points = points.astype(np.float32)
    members = go.Scatter3d(
        x=points[:, 0], y=points[:, 1], z=points[:, 2], mode="lines", name="members",
        customdata=np.repeat(np.where(np.isnan(share), -1.0, share), 3).astype(np.float32),
        hovertemplate="load %{customdata:.0%} of the break force (negative: no static answer)<extra></extra>",
        line={"color": colour, "colorscale": LOAD_COLOURS, "cmin": 0.0, "cmax": 1.0, "width": 7,
              "colorbar": {"title": "load / break force", "tickformat": ".0%"}},
    )  # fmt: skip
    corners = vertices.astype(np.int16)
    joints = go.Scatter3d(
        x=corners[:, 0], y=corners[:, 1], z=corners[:, 2], mode="markers", name="vertices", hoverinfo="skip",
        marker={"size": 3, "color": "#37474f"},
    )  # fmt: skip
    figure = go.Figure([members, joints])
    figure.update_layout(
        height=560, margin={"l": 0, "r": 0, "t": 10, "b": 0}, showlegend=False,
        scene={"aspectmode": "data", "xaxis_title": "x", "yaxis_title": "y", "zaxis_title": "z (up)"},
    )  # fmt: skip
    return {
        "figure": plain_figure(figure),
        "verdict": f"static analysis: {report.verdict()}",
        "fields": {
            "statics: integrity I": report.integrity,
            "statics: height H": report.height,
            "statics: complexity C": report.complexity,
            "statics: score Q": report.score,
            "statics: peak load / break force": float(np.nanmax(share)) if np.isfinite(share).any() else None,
            "vertices": structure.n_vertices,
            "edges": structure.n_edges,
        },
    }
