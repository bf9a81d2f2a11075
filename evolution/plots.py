"""Plots written with a run: the objective over generations and, for quality diversity, the archive as a heatmap and
its QD score and coverage over generations.

Drawn with matplotlib's object interface on the Agg canvas: no display, no global pyplot state.
"""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from evolution.problem import Problem
from evolution.runfolder import RunFolder, atomic_write

__all__ = ["compare_figure", "figure_png", "new_figure", "write_plots"]


def new_figure(**options: Any) -> Any:
    """A matplotlib ``Figure`` on its own Agg canvas (``options`` go to ``Figure``): every picture the project draws
    starts here, so none touches pyplot's global state or needs a display."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(**options)
    FigureCanvasAgg(figure)
    return figure


def figure_png(figure: Any, dpi: int = 100) -> bytes:
    """The figure as PNG bytes, for an atomic write."""
    buffer = io.BytesIO()
    figure.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def objective_figure(rows: list[dict[str, Any]], problem: Problem) -> Any:
    """Best objective so far, this generation's best and mean; below, the best candidate's plotted fields."""
    fields = [name for name in problem.plot_fields if f"best_{name}" in rows[-1]]
    figure = new_figure(figsize=(8, 3.6 + 1.6 * len(fields)), layout="constrained")
    axes = figure.subplots(1 + len(fields), 1, sharex=True, squeeze=False, height_ratios=[2.2] + [1] * len(fields))[:, 0]
    generation = [row["generation"] for row in rows]
    top = axes[0]
    top.plot(generation, [row["best_objective"] for row in rows], lw=2, label="best so far")
    top.plot(generation, [row["generation_best_objective"] for row in rows], lw=1, alpha=0.8, label="best this generation")
    top.plot(generation, [row["mean_objective"] for row in rows], lw=1, alpha=0.8, label="mean this generation")
    top.set_ylabel("objective")
    top.set_title(f"{problem.name}: objective over generations ({rows[-1]['evaluations']} evaluations)")
    top.legend(loc="best", fontsize=8)
    top.grid(alpha=0.3)
    # Each field of the best candidate on its own scale (integrity lives in [0, 1], complexity in the tens).
    for ax, name, colour in zip(axes[1:], fields, ("tab:green", "tab:red", "tab:purple", "tab:brown")):
        ax.plot(generation, [row[f"best_{name}"] for row in rows], lw=1.5, color=colour)
        ax.set_ylabel(f"best's\n{name}", fontsize=9)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("generation")
    return figure


def archive_figure(archive: Any, problem: Problem) -> Any:
    """The archive's elites: objective by cell, measures on the axes."""
    figure = new_figure(figsize=(7, 5.5), layout="constrained")
    ax = figure.add_subplot()
    dims = tuple(archive.dims)
    grid = np.full(dims, np.nan)
    data = archive.data(["index", "objective"])
    if len(data["index"]):
        grid[np.unravel_index(data["index"], dims)] = data["objective"]
    if len(dims) == 1:
        grid = grid[:, None]
    (x_low, x_high), *rest = problem.measure_ranges
    y_low, y_high = rest[0] if rest else (0.0, 1.0)
    image = ax.imshow(
        grid.T, origin="lower", aspect="auto", extent=(x_low, x_high, y_low, y_high), cmap="viridis", interpolation="nearest"
    )
    figure.colorbar(image, ax=ax, label="objective")
    ax.set_xlabel(problem.measure_names[0])
    ax.set_ylabel(problem.measure_names[1] if len(problem.measure_names) > 1 else "")
    stats = archive.stats
    ax.set_title(
        f"archive: {stats.num_elites} elites, coverage {float(stats.coverage):.1%}, QD score {float(stats.qd_score):.4g}"
    )
    return figure


def qd_figure(rows: list[dict[str, Any]], problem: Problem) -> Any:
    """The archive's QD score and coverage over generations, one above the other."""
    figure = new_figure(figsize=(8, 5), layout="constrained")
    top, bottom = figure.subplots(2, 1, sharex=True)
    generation = [row["generation"] for row in rows]
    top.plot(generation, [row["qd_score"] for row in rows], lw=2, color="tab:blue")
    top.set_ylabel(f"QD score\n(objective above {problem.objective_floor:g}, summed)", fontsize=9)
    top.set_title(f"{problem.name}: archive over generations ({rows[-1]['evaluations']} evaluations)")
    bottom.plot(generation, [100 * row["coverage"] for row in rows], lw=2, color="tab:orange")
    bottom.set_ylabel("coverage (% of cells)", fontsize=9)
    bottom.set_xlabel("generation")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    return figure


def write_plots(folder: RunFolder, problem: Problem, archive: Any = None) -> None:
    """Redraw ``objective.png`` from metrics.jsonl and, for quality diversity, ``archive.png`` and ``qd.png``."""
    rows = folder.metrics()
    if rows:
        atomic_write(folder / folder.OBJECTIVE_PLOT, figure_png(objective_figure(rows, problem)))
    if rows and "qd_score" in rows[-1]:
        atomic_write(folder / folder.QD_PLOT, figure_png(qd_figure([r for r in rows if "qd_score" in r], problem)))
    if archive is not None and len(problem.measure_names) in (1, 2):
        atomic_write(folder / folder.ARCHIVE_PLOT, figure_png(archive_figure(archive, problem)))


def compare_figure(runs: dict[str, list[dict[str, Any]]]) -> Any:
    """Several runs' metrics side by side: best objective so far per generation and, when every run is a
    quality-diversity run, QD score and coverage too. ``runs`` maps a label to its metrics rows."""
    quality_diversity = all(rows and "qd_score" in rows[-1] for rows in runs.values())
    panels = [("best_objective", "best objective so far", 1.0)]
    if quality_diversity:
        panels += [("qd_score", "QD score", 1.0), ("coverage", "coverage (% of cells)", 100.0)]
    figure = new_figure(figsize=(8, 2.2 + 2.4 * len(panels)), layout="constrained")
    axes = figure.subplots(len(panels), 1, sharex=True, squeeze=False)[:, 0]
    for ax, (key, label, scale) in zip(axes, panels):
        for name, rows in runs.items():
            kept = [row for row in rows if key in row]
            ax.plot([row["generation"] for row in kept], [scale * row[key] for row in kept], lw=1.6, label=name)
        ax.set_ylabel(label, fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].set_title(f"{len(runs)} runs compared")
    axes[0].legend(loc="best", fontsize=8)
    axes[-1].set_xlabel("generation")
    return figure
