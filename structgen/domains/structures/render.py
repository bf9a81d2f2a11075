"""Pictures of structures (matplotlib, no display): before and after a stability check with broken joints marked, a
single structure, and its growth step by step as numbered frames or an animated GIF.

Large structures (hundreds of vertices and more) are drawn with thin edges and small vertices coloured by height, so
their levels read apart instead of merging into one tangle.
"""

from __future__ import annotations

import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure

if TYPE_CHECKING:
    from physics import StabilityReport
    from structgen.structure import Structure

__all__ = ["check_figure", "render_check", "render_growth", "render_regrowth", "render_structure"]

INTACT, BROKEN, VERTEX, GROUND = "#5b6f8a", "#d62728", "#e0703c", "#d9d4c7"
# Beyond this many broken joints, crosses would hide the structure; the red edges still show where it failed.
_MAX_CROSSES = 200
# From this many edges on, a structure is drawn coloured by height with thin lines and small vertices.
_LARGE = 300


def _after_title(report: StabilityReport) -> str:
    if report.method == "statics":
        rounds = report.steps
        return f"after the static analysis ({rounds} failure round{'s' if rounds != 1 else ''})"
    return f"after {report.sim_time:.2f} s" + (" (settled)" if report.settled else "")


def _draw(
    axes, centres: np.ndarray, segments: np.ndarray, broken: np.ndarray, size: float, title: str, top: float,
    loads: np.ndarray | None = None,
) -> None:  # fmt: skip
    """Edges (broken ones red) and vertices; large structures coloured by height on the scale 0 .. ``top``, the same
    for every picture of one figure or animation. ``loads`` (E, 4 RGBA bytes): every edge in its load colour instead
    (see :mod:`structgen.domains.structures.stress`), vertices small and grey."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    # One collection for all edges: thousands of separate lines would take minutes to draw.
    shown = np.isfinite(segments).all(axis=(1, 2))
    large = len(segments) >= _LARGE
    if shown.any() and loads is not None:
        axes.add_collection3d(Line3DCollection(segments[shown], colors=loads[shown] / 255, linewidths=1.0 if large else 2.6))
    elif shown.any():
        if large:  # height colours separate the levels that a single colour would merge
            colours = _height_colours(segments[shown, :, 2].mean(axis=1) / top)
            colours[broken[shown]] = _rgba(BROKEN)
        else:
            colours = np.array([_rgba(c) for c in np.where(broken[shown], BROKEN, INTACT)])
        widths = np.where(broken[shown], 2.5, 1.8) * (0.35 if large else 1.0)
        axes.add_collection3d(Line3DCollection(segments[shown], colors=colours, linewidths=widths))
    if loads is not None:
        axes.scatter(*centres.T, s=size / 3, color="#607d8b", depthshade=False, edgecolors="none")
    elif large:
        axes.scatter(*centres.T, s=size, c=_height_colours(centres[:, 2] / top), depthshade=True, edgecolors="none")
    else:
        axes.scatter(*centres.T, s=size, color=VERTEX, depthshade=False, edgecolors="black", linewidths=0.4)
    axes.set_title(title, fontsize=10)


def _rgba(colour: str) -> np.ndarray:
    from matplotlib.colors import to_rgba

    return np.array(to_rgba(colour))


def _height_colours(fraction: np.ndarray) -> np.ndarray:
    from matplotlib import colormaps

    return colormaps["viridis"](np.clip(fraction, 0.0, 1.0) * 0.9)


def _scene(centres: np.ndarray) -> tuple[np.ndarray, float, float, float]:
    """(middle, half width, top of the vertical axis, marker size) of a picture holding these points."""
    finite = centres[np.isfinite(centres).all(axis=1)]
    low, high = (finite.min(axis=0), finite.max(axis=0)) if len(finite) else (np.zeros(3), np.ones(3))
    low[2] = 0.0
    middle, half = (low + high) / 2, max((high - low).max() / 2, 1.0) + 0.5
    # The vertical axis ends a little above the top, at the same scale as x and y, so wide flat structures get a
    # readable picture instead of a thin slab in a tall empty box.
    top = min(2 * half, max(high[2] + 0.5, 0.35 * half))
    return middle, half, top, max(1.5, min(80.0, 400.0 / max(1.0, half) ** 2))


def _stage(axes, middle: np.ndarray, half: float, top: float) -> None:
    """The ground square, equal axis scales and the viewing angle shared by every picture."""
    from matplotlib.ticker import MaxNLocator

    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half + middle[:2]
    axes.plot_trisurf(corners[:, 0], corners[:, 1], np.zeros(4), color=GROUND, alpha=0.35, linewidth=0)
    axes.set_xlim(middle[0] - half, middle[0] + half)
    axes.set_ylim(middle[1] - half, middle[1] + half)
    axes.set_zlim(0, top)
    axes.set_box_aspect((2 * half, 2 * half, top))
    axes.zaxis.set_major_locator(MaxNLocator(nbins=4, integer=True))
    axes.set_xlabel("x")
    axes.set_ylabel("y")
    axes.set_zlabel("z")
    axes.view_init(elev=22, azim=-60)


def _on_ground(structure: Structure) -> np.ndarray:
    """Vertex positions in lattice units with the lowest level at height 0."""
    vertices = structure.vertices.astype(float)
    if len(vertices):
        vertices[:, 2] -= vertices[:, 2].min()
    return vertices


def _structure_figure(structure: Structure, title: str, scene: tuple[np.ndarray, float, float, float]) -> Any:
    vertices = _on_ground(structure)
    edges = structure.edges
    segments = np.stack([vertices[edges[:, 0]], vertices[edges[:, 1]]], axis=1) if len(edges) else np.zeros((0, 2, 3))
    figure = new_figure(figsize=(6, 5.4))
    axes = figure.add_subplot(projection="3d")
    middle, half, top, size = scene
    _stage(axes, middle, half, top)
    _draw(axes, vertices, segments, np.zeros(len(segments), dtype=bool), size, title, top)
    return figure


def render_structure(structure: Structure, path: str | os.PathLike, *, title: str | None = None, dpi: int = 110) -> Path:
    """Draw one structure on the ground (lattice units, no physics) and write a PNG to ``path`` atomically."""
    title = title or f"{structure.n_vertices} vertices, {structure.n_edges} edges, height {structure.height}"
    figure = _structure_figure(structure, title, _scene(_on_ground(structure)))
    return atomic_write(path, figure_png(figure, dpi))


def render_growth(
    frames: Sequence[Structure],
    *,
    folder: str | os.PathLike | None = None,
    gif: str | os.PathLike | None = None,
    dpi: int = 90,
    seconds_per_frame: float = 0.6,
) -> list[Path]:
    """Draw every growth step (as :func:`structgen.nca.grow_steps` returns them) in one fixed frame of view:
    ``folder/step_000.png``, ... and/or one animated ``gif``. Returns the files written."""
    if not frames:
        raise ValueError("no growth steps to draw")
    scene = _scene(np.concatenate([_on_ground(f) for f in frames]))
    pictures = []
    for step, structure in enumerate(frames):
        title = f"step {step}: {structure.n_vertices} vertices, {structure.n_edges} edges"
        pictures.append(figure_png(_structure_figure(structure, title, scene), dpi))
    written = []
    if folder is not None:
        folder = Path(folder)
        written += [atomic_write(folder / f"step_{step:03d}.png", png) for step, png in enumerate(pictures)]
    if gif is not None:
        from PIL import Image

        images = [Image.open(io.BytesIO(png)).convert("RGB") for png in pictures]
        buffer = io.BytesIO()
        # The last picture stays up longer, so the finished structure can be looked at before the loop restarts.
        durations = [int(1000 * seconds_per_frame)] * (len(images) - 1) + [int(3000 * seconds_per_frame)]
        images[0].save(buffer, format="GIF", save_all=True, append_images=images[1:], duration=durations, loop=0)
        written.append(atomic_write(gif, buffer.getvalue()))
    return written


def render_regrowth(
    original: Structure, damaged: Structure, regrown: Structure, path: str | os.PathLike, *, cut: str = "", dpi: int = 100
) -> Path:
    """Grown, damaged (by ``cut``, words for the caption) and regrown side by side, in one frame of view (the
    original's ground at height 0); members that regrew where the original had none are red. Written as a PNG to
    ``path`` atomically."""
    from structgen.domains.structures.regrow import member_keys

    ground = original.vertices[:, 2].min() if original.n_vertices else 0
    scene = _scene(original.vertices - [0, 0, ground])
    figure = new_figure(figsize=(15, 5.2), layout="constrained")
    before, after = set(member_keys(original)), member_keys(regrown)
    back = len(before & set(after)) / max(1, len(before))
    captions = (
        f"grown: {original.n_edges} members",
        f"damaged{f' ({cut})' if cut else ''}: {damaged.n_edges} members",
        f"regrown: {regrown.n_edges} members, {back:.1%} of the grown ones, {len(set(after) - before)} new (red)",
    )
    for column, (structure, caption) in enumerate(zip((original, damaged, regrown), captions), start=1):
        vertices = (structure.vertices - [0, 0, ground]).astype(float)
        edges = structure.edges
        segments = np.stack([vertices[edges[:, 0]], vertices[edges[:, 1]]], axis=1) if len(edges) else np.zeros((0, 2, 3))
        new = np.array([key not in before for key in after] if structure is regrown else [False] * len(edges), dtype=bool)
        axes = figure.add_subplot(1, 3, column, projection="3d")
        middle, half, top, size = scene
        _stage(axes, middle, half, top)
        _draw(axes, vertices, segments, new, size, caption, top)
    return atomic_write(path, figure_png(figure, dpi))


def _after_segments(report: StabilityReport) -> np.ndarray:
    """Each edge's cylinder at the end, drawn from its vertices where its joints hold: a cylinder that broke away at
    one end still hangs from the vertex at the other (drawn from its centre, as the intact ones are), and only a
    cylinder loose at both ends is drawn where its own body lies."""
    ends = report.final_edge_ends.copy()
    edges, after = report.edges, report.final_positions
    loose = np.zeros((len(edges), 2), dtype=bool)
    for joint in report.broken_joints:
        loose[joint.edge, 0 if edges[joint.edge][0] == joint.vertex else 1] = True
    for side in (0, 1):
        held = ~loose[:, side]
        ends[held, side] = after[edges[held, side]]
    return ends


def render_check(
    report: StabilityReport,
    path: str | os.PathLike,
    *,
    dpi: int = 110,
    load_shares: np.ndarray | None = None,
    load_label: str = "member load",
) -> Path:
    """Write :func:`check_figure`'s picture of ``report`` to ``path`` as a PNG, atomically."""
    return atomic_write(path, figure_png(check_figure(report, load_shares, load_label), dpi))


def check_figure(report: StabilityReport, load_shares: np.ndarray | None = None, load_label: str = "member load") -> Any:
    """The structure as placed and as it ended up, side by side, as a matplotlib figure.

    Edges with a broken joint are red, in both pictures; in the first, a red cross marks each broken joint (when
    there are at most 200). The title spells out the paper's measures (integrity, height, complexity, score) and a
    legend says what the colours are; structures of 300 edges or more are drawn in height colours, with a colour bar.
    With ``load_shares`` (each edge's static load over the break force, from
    :func:`structgen.domains.structures.stress.member_load_shares`, or the simulated peaks of
    :func:`~structgen.domains.structures.stress.member_peak_shares`) every edge is drawn in its load colour instead,
    with that colour bar, ``load_label`` naming what the shares are, and the broken joints are black crosses.
    """
    from matplotlib.lines import Line2D

    edges = report.edges
    before, after = report.initial_positions, report.final_positions
    broken_edges = np.zeros(len(edges), dtype=bool)
    broken_edges[report.broken_edges] = True
    start_segments = np.stack([before[edges[:, 0]], before[edges[:, 1]]], axis=1) if len(edges) else np.zeros((0, 2, 3))
    after_segments = _after_segments(report) if len(edges) else np.zeros((0, 2, 3))

    middle, half, top, size = _scene(np.concatenate([before, after, after_segments.reshape(-1, 3)]))
    # A flat structure gets a low picture: the 3D boxes are as wide as they are deep, and only as tall as the structure.
    height = 3.4 + 2.2 * min(1.0, top / (2 * half))
    figure = new_figure(figsize=(10, height))
    figure.suptitle(
        f"{report.verdict()}\nintegrity I = {report.integrity:.3f} (share of joints intact), height H = {report.height:.2f}, "
        f"complexity C = {report.complexity} (vertices), score Q = {report.score:.2f}",
        fontsize=10,
    )
    loads = None
    if load_shares is not None:
        from structgen.domains.structures.stress import load_colours

        loads = load_colours(load_shares)
    cross = BROKEN if loads is None else "black"
    panels = [
        (before, start_segments, "before (as placed on the ground)"),
        (after, after_segments, _after_title(report)),
    ]
    large = len(edges) >= _LARGE
    width = 0.44 if loads is not None else 0.46 if large else 0.5  # room on the right for a colour bar
    for column, (centres, segments, title) in enumerate(panels, start=1):
        axes = figure.add_axes([(column - 1) * width, 0.02, width, 0.78], projection="3d")
        _stage(axes, middle, half, top)
        _draw(axes, centres, segments, broken_edges, size, title, top, loads)
        if column == 1 and 0 < len(report.broken_joints) <= _MAX_CROSSES:
            radius = report.config.sphere_radius
            joints = []
            for joint in report.broken_joints:
                a, b = edges[joint.edge]
                here, there = (before[a], before[b]) if joint.vertex == a else (before[b], before[a])
                joints.append(here + radius * (there - here) / np.linalg.norm(there - here))
            axes.scatter(*np.array(joints).T, marker="x", s=60, color=cross, depthshade=False, linewidths=2)
    if loads is not None:
        legend = _load_bar(figure, load_shares, report.config.break_force, load_label)
    elif large:  # drawn in height colours (see _draw), which a colour bar explains
        from matplotlib.cm import ScalarMappable
        from matplotlib.colors import ListedColormap, Normalize

        scale = ScalarMappable(Normalize(0.0, top), ListedColormap(_height_colours(np.linspace(0.0, 1.0, 256))))
        bar = figure.colorbar(scale, cax=figure.add_axes([0.955, 0.22, 0.01, 0.5]))
        bar.set_label("height of an intact edge or vertex", fontsize=8)
        legend = [Line2D([], [], color=BROKEN, linewidth=2, label="edge with a broken joint")]
    else:
        legend = [
            Line2D([], [], color=INTACT, linewidth=2, label="edge, joints intact"),
            Line2D([], [], color=BROKEN, linewidth=2, label="edge with a broken joint"),
            Line2D([], [], marker="o", color="none", markerfacecolor=VERTEX, markeredgecolor="black", label="vertex"),
        ]
    if 0 < len(report.broken_joints) <= _MAX_CROSSES:  # the crosses are drawn only then (see above)
        legend.append(Line2D([], [], marker="x", color="none", markeredgecolor=cross, markeredgewidth=2, label="broken joint"))
    figure.legend(handles=legend, loc="lower center", ncol=len(legend), fontsize=8, frameon=False)
    return figure


def _load_bar(figure: Any, shares: np.ndarray, break_force: float, label: str = "member load") -> list[Any]:
    """The load colours' colour bar on the right, and legend entries for the colours off the scale."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.lines import Line2D

    from structgen.domains.structures.stress import NO_ANSWER, OVERLOADED, load_colormap

    scale = ScalarMappable(Normalize(0.0, 1.0), load_colormap())
    bar = figure.colorbar(scale, cax=figure.add_axes([0.9, 0.22, 0.012, 0.5]), format=lambda x, _: f"{x:.0%}")
    finite = shares[np.isfinite(shares)]
    peak = f"; peak {finite.max():.0%}" if len(finite) else ""
    bar.set_label(f"{label} / break force ({break_force:g} N){peak}", fontsize=8)
    legend = [Line2D([], [], color=OVERLOADED, linewidth=2.6, label="over the break force")]
    if np.isnan(shares).any():
        legend.append(Line2D([], [], color=NO_ANSWER, linewidth=2.6, label="no static answer (falls whole)"))
    return legend
