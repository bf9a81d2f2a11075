"""Pictures of a structure before and after its stability check, with broken joints marked (matplotlib, no display)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure

if TYPE_CHECKING:
    from physics import StabilityReport

__all__ = ["render_check"]

INTACT, BROKEN, VERTEX, GROUND = "#5b6f8a", "#d62728", "#e0703c", "#d9d4c7"
# Beyond this many broken joints, crosses would hide the structure; the red edges still show where it failed.
_MAX_CROSSES = 200


def _after_title(report: StabilityReport) -> str:
    if report.method == "statics":
        rounds = report.steps
        return f"after the static analysis ({rounds} failure round{'s' if rounds != 1 else ''})"
    return f"after {report.sim_time:.2f} s" + (" (settled)" if report.settled else "")


def _draw(axes, centres: np.ndarray, segments: np.ndarray, broken: np.ndarray, size: float, title: str) -> None:
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    # One collection for all edges: thousands of separate lines would take minutes to draw.
    shown = np.isfinite(segments).all(axis=(1, 2))
    if shown.any():
        colours = np.where(broken[shown], BROKEN, INTACT)
        widths = np.where(broken[shown], 2.5, 1.8) * (1.0 if len(segments) < 500 else 0.4)
        axes.add_collection3d(Line3DCollection(segments[shown], colors=list(colours), linewidths=widths))
    edge = "black" if len(centres) < 500 else "none"
    axes.scatter(*centres.T, s=size, color=VERTEX, depthshade=False, edgecolors=edge, linewidths=0.4)
    axes.set_title(title, fontsize=10)


def render_check(report: StabilityReport, path: str | os.PathLike, *, dpi: int = 110) -> Path:
    """Draw the structure as placed and as it ended up, side by side, and write a PNG to ``path`` atomically.

    Edges with a broken joint are red, in both pictures; in the first, a red cross marks each broken joint (when
    there are at most 200).
    """
    from matplotlib.ticker import MaxNLocator

    edges = report.edges
    before, after = report.initial_positions, report.final_positions
    broken_edges = np.zeros(len(edges), dtype=bool)
    broken_edges[report.broken_edges] = True
    start_segments = np.stack([before[edges[:, 0]], before[edges[:, 1]]], axis=1) if len(edges) else np.zeros((0, 2, 3))

    finite = np.concatenate([before, after, report.final_edge_ends.reshape(-1, 3)])
    finite = finite[np.isfinite(finite).all(axis=1)]
    low, high = (finite.min(axis=0), finite.max(axis=0)) if len(finite) else (np.zeros(3), np.ones(3))
    low[2] = 0.0
    middle, half = (low + high) / 2, max((high - low).max() / 2, 1.0) + 0.5
    # The vertical axis ends a little above the top, at the same scale as x and y, so wide flat structures get a
    # readable picture instead of a thin slab in a tall empty box.
    top = min(2 * half, max(high[2] + 0.5, 0.35 * half))
    size = max(3.0, min(80.0, 400.0 / max(1.0, half) ** 2))

    figure = new_figure(figsize=(10, 5.2))
    summary = (
        f"{report.verdict()}   I = {report.integrity:.2f}, H = {report.height:.2f}, C = {report.complexity}, "
        f"Q = {report.score:.2f}"
    )
    figure.suptitle(summary, fontsize=11)
    panels = [
        (before, start_segments, "before (as placed on the ground)"),
        (after, report.final_edge_ends, _after_title(report)),
    ]
    for column, (centres, segments, title) in enumerate(panels, start=1):
        axes = figure.add_subplot(1, 2, column, projection="3d")
        ground = np.array(
            [
                [middle[0] - half, middle[1] - half],
                [middle[0] + half, middle[1] - half],
                [middle[0] + half, middle[1] + half],
                [middle[0] - half, middle[1] + half],
            ]
        )
        axes.plot_trisurf(ground[:, 0], ground[:, 1], np.zeros(4), color=GROUND, alpha=0.35, linewidth=0)
        _draw(axes, centres, segments, broken_edges, size, title)
        if column == 1 and 0 < len(report.broken_joints) <= _MAX_CROSSES:
            radius = report.config.sphere_radius
            joints = []
            for joint in report.broken_joints:
                a, b = edges[joint.edge]
                here, there = (before[a], before[b]) if joint.vertex == a else (before[b], before[a])
                joints.append(here + radius * (there - here) / np.linalg.norm(there - here))
            axes.scatter(*np.array(joints).T, marker="x", s=60, color=BROKEN, depthshade=False, linewidths=2)
        axes.set_xlim(middle[0] - half, middle[0] + half)
        axes.set_ylim(middle[1] - half, middle[1] + half)
        axes.set_zlim(0, top)
        axes.set_box_aspect((2 * half, 2 * half, top))
        axes.zaxis.set_major_locator(MaxNLocator(nbins=4, integer=True))
        axes.set_xlabel("x")
        axes.set_ylabel("y")
        axes.set_zlabel("z")
        axes.view_init(elev=22, azim=-60)
    return atomic_write(path, figure_png(figure, dpi))
