"""Pictures of layouts: tiles coloured by kind with a legend; two maps side by side with the cells that differ
outlined."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure
from structgen.domains.layouts.grid import Grid
from structgen.domains.layouts.kinds import LayoutKind


def _draw_tiles(ax, tiles: np.ndarray, kind: LayoutKind, title: str) -> None:
    """The layout on ``ax``, each tile in its kind's colour, without ticks."""
    from matplotlib.colors import ListedColormap

    colours = ListedColormap([kind.colours[c] for c in kind.vocabulary])
    ax.imshow(tiles, cmap=colours, vmin=-0.5, vmax=len(kind.vocabulary) - 0.5, interpolation="nearest")
    ax.set_title(title, fontsize=8)
    ax.set_xticks([])
    ax.set_yticks([])


#: How start and goal are marked on a maze: the ends of its longest shortest path.
_ENDS = (("start", "#2ca02c", "o"), ("goal", "#d62728", "*"))


def draw(grids: list[Grid], kind: LayoutKind, output: Path, *, titles: list[str], dpi: int = 110) -> Path:
    """The maps side by side, tiles in their kind's colours with a legend; two maps of a size get the cells that differ
    outlined, and a maze its start and goal marked (or the title says no two floor cells connect)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch, Rectangle

    rows, cols = grids[0].shape
    scale = min(0.22, 9.0 / max(cols, 1))
    fig = new_figure(figsize=(max(3.0, cols * scale) * len(grids) + 0.5, rows * scale + 1.4))
    axes = fig.subplots(1, len(grids), squeeze=False)
    changed = grids[0].tiles != grids[1].tiles if len(grids) == 2 else None
    marked = False
    for ax, grid, title in zip(axes[0], grids, titles):
        if kind.name == "maze":
            from structgen.domains.layouts.maze.walkers import diameter

            ends = diameter(grid.tiles)
            if ends is None:
                title += ": no two floor cells connect"
            else:
                title += f": shortest path from start to goal {ends[2]} moves"
                for (r, c), (_, colour, marker) in zip(ends[:2], _ENDS):
                    ax.plot(c, r, marker=marker, color=colour, markersize=9, markeredgecolor="black")
                marked = True
        _draw_tiles(ax, grid.tiles, kind, title)
        if changed is not None:
            for r, c in np.argwhere(changed):
                ax.add_patch(Rectangle((c - 0.5, r - 0.5), 1, 1, fill=False, edgecolor="#e41a1c", linewidth=0.9))
    present = [c for c in kind.vocabulary if any(g.count(c) for g in grids)]
    handles = [Patch(facecolor=kind.colours[c], edgecolor="#999999", label=f"{kind.tile_names[c]} '{c}'") for c in present]
    if changed is not None:
        handles.append(Patch(facecolor="none", edgecolor="#e41a1c", label=f"changed ({int(changed.sum())})"))
    if marked:
        handles += [
            Line2D([], [], marker=marker, color="none", markerfacecolor=colour, markeredgecolor="black", label=name)
            for name, colour, marker in _ENDS
        ]
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 4), fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    return atomic_write(output, figure_png(fig, dpi))


def _legend(kind: LayoutKind, grid: Grid, extra: list) -> list:
    from matplotlib.patches import Patch

    present = [c for c in kind.vocabulary if grid.count(c)]
    return [Patch(facecolor=kind.colours[c], edgecolor="#999999", label=f"{kind.tile_names[c]} '{c}'") for c in present] + extra


def draw_frames(
    grid: Grid, kind: LayoutKind, positions: np.ndarray, times: list[int], output: Path, *, title: str, dpi: int = 110
) -> Path:
    """A strip of snapshots of a simulation: the layout with every agent as a dot, at each of ``times``.

    ``positions`` is the simulation's trace, ``(steps + 1, agents)`` flat cell indices."""
    rows, cols = grid.shape
    scale = min(0.16, 6.0 / max(cols, 1))  # inches per cell
    across = min(3, len(times))
    down = -(-len(times) // across)
    fig = new_figure(figsize=(max(2.5, cols * scale) * across + 0.3, (rows * scale + 0.3) * down + 0.6))
    axes = fig.subplots(down, across, squeeze=False).ravel()
    for ax in axes[len(times) :]:
        ax.set_axis_off()
    from matplotlib.lines import Line2D

    dot = (scale * 72 * 0.7) ** 2  # marker area in points squared: most of a cell
    for ax, t in zip(axes, times):
        _draw_tiles(ax, grid.tiles, kind, f"step {t}")
        cells = positions[t]
        ax.scatter(cells % cols, cells // cols, s=dot, color="#d62728", linewidths=0)
    fig.suptitle(title, fontsize=9)
    robot = Line2D([], [], marker="o", color="none", markerfacecolor="#d62728", markeredgecolor="none", label="robot")
    handles = _legend(kind, grid, [robot])
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 6), fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    return atomic_write(output, figure_png(fig, dpi))
