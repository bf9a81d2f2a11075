"""A structure as a run report draws it (:mod:`structgen.runs.report`): a 3D view to turn, each member coloured by
its static load as a share of the break force, and the static analysis's verdict and I, H, C and Q beside it."""

from __future__ import annotations

from typing import Any

import numpy as np

from structgen.structure import Structure

__all__ = ["structure_view"]


def structure_view(structure: Structure, config: Any = None) -> dict[str, Any]:
    """``{"lines3d", "verdict", "fields"}`` for a report (:func:`structgen.runs.report.line_set`): members as lines
    coloured by the larger of their two joints' static loads over the break force (the intact structure, load factors
    applied; grey where a piece has no static answer), vertices as dots, and the static analysis's verdict with I, H,
    C and Q."""
    import plotly.graph_objects as go

    from physics import InputError as TooLarge
    from structgen.domains.structures.stress import LOAD_SCALE, member_load_shares
    from structgen.runs.report import line_set

    try:
        report, share = member_load_shares(structure, config)
    except TooLarge as err:  # a structure past the static solve's memory budget is still drawn, its loads unknown
        report, share = None, np.full(structure.n_edges, np.nan)
        why = str(err)
    edges = structure.edges
    members = go.Scatter3d(
        mode="lines", name="members", hovertemplate="load %{customdata:.0%} of the break force (negative: no static "
        "answer)<extra></extra>",
        line={"colorscale": [list(stop) for stop in LOAD_SCALE], "cmin": 0.0, "cmax": 1.0, "width": 7,
              "colorbar": {"title": "load / break force", "tickformat": ".0%"}},
    )  # fmt: skip
    joints = go.Scatter3d(mode="markers", name="vertices", hoverinfo="skip", marker={"size": 3, "color": "#37474f"})
    layout = go.Layout(
        height=560, margin={"l": 0, "r": 0, "t": 10, "b": 0}, showlegend=False,
        scene={"aspectmode": "data", "xaxis_title": "x", "yaxis_title": "y", "zaxis_title": "z (up)"},
    )  # fmt: skip
    view = line_set(structure.vertices, edges, share, lines=members, markers=joints, layout=layout)
    if report is None:
        return {
            **view,
            "verdict": f"static analysis not run: {why}",
            "fields": {"vertices": structure.n_vertices, "edges": structure.n_edges},
        }
    return {
        **view,
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
