"""The quality-diversity paper's result figures, drawn from run folders.

- ``archive``: the archive of one run, or the best elite per cell over several (the paper's merge), as a heatmap
  over its two measures, coloured by fitness (Figures 4 left, 7a and 8a), by the entropy of the class sizes
  (Figures 4 right and 7b, over experiment 1's archive) or by total nodes (8b, over experiment 2's);
- ``robustness``: one run's archive as evolved, re-evaluated on new seeds, and on new seeds with longer episodes,
  each re-binned into a fresh archive (Figure 5);
- ``populations``: entities of each class over a simulation several times longer than evolution's, for the
  elite with the most even class sizes (highest entropy) and the two ends of the entities measure (Figure 6).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure
from evolution.runfolder import RunFolder
from structgen.errors import InputError

__all__ = ["FIGURES", "archive_figure", "populations_figure", "robustness_figure"]

FIGURES = ("archive", "robustness", "populations")
# What each colour (and a measure on an axis) is, spelled out.
_COLOURS = {
    "fitness": "share of machines visited (fitness)",
    "entropy": "entropy of the classes' FSM sizes",
    "nodes": "total FSM nodes",
}


def _open(run_dirs: Sequence[str | Path]) -> tuple[list[RunFolder], Any, Any]:
    from structgen.domains.fortress.problem import FortressProblem
    from structgen.domains.fortress.robustness import open_runs

    folders, experiment = open_runs(run_dirs)
    problem = experiment.make_problem()
    if not isinstance(problem, FortressProblem):
        raise InputError(f"{folders[0].path}: not a fortress run (its domain is {experiment.domain})")
    return folders, experiment, problem


def _cells(experiment: Any) -> tuple[int, ...]:
    return tuple(getattr(experiment.optimizer_settings, "cells", (100, 100)))


def _merged(folders: list[RunFolder], problem: Any, cells: tuple[int, ...]) -> tuple[Any, list[tuple[int, int]]]:
    """The best elite per cell over the runs (numbers only), and which (run, row) each is."""
    from structgen.domains.fortress.robustness import Elites, merge

    parts = []
    for r, folder in enumerate(folders):
        rows = folder.archive_rows()
        names = problem.measure_names
        measures = np.array([[float(row[n]) for n in names] for row in rows]).reshape(len(rows), len(names))
        objective = np.array([float(row["objective"]) for row in rows])
        parts.append(Elites([(r, i) for i in range(len(rows))], objective, measures, problem.settings.sims))
    merged = merge(problem, parts, cells)
    return merged, merged.worlds


def _heatmap(
    axes: Any, problem: Any, measures: np.ndarray, values: np.ndarray, cells: Sequence[int], label: str, **options: Any
) -> Any:
    """Each elite's value in its cell (empty cells blank), the measures on the axes."""
    from structgen.domains.fortress.robustness import _cells as cell_of

    grid = np.full(tuple(cells), np.nan)
    if len(values):
        index = cell_of(problem, measures, cells)
        grid.reshape(-1)[index] = values
    (x_low, x_high), (y_low, y_high) = problem.measure_ranges
    image = axes.imshow(grid.T, origin="lower", aspect="auto", extent=(x_low, x_high, y_low, y_high), cmap="viridis", **options)
    axes.set_xlabel(f"{problem.measure_names[0]} at the end of an episode")
    axes.set_ylabel(_COLOURS.get(problem.measure_names[1], problem.measure_names[1]))
    colourbar = axes.figure.colorbar(image, ax=axes)
    colourbar.set_label(label)
    return image


def archive_figure(run_dirs: Sequence[str | Path], output: str | Path, colour: str = "fitness") -> Path:
    """Figures 4, 7 and 8: the (merged) archive coloured by fitness, class-size entropy or total nodes."""
    from structgen.domains.fortress.world import fsm_size_entropy

    if colour not in _COLOURS:
        raise InputError(f"--colour must be one of {', '.join(_COLOURS)}, got {colour!r}")
    folders, experiment, problem = _open(run_dirs)
    cells = _cells(experiment)
    merged, labels = _merged(folders, problem, cells)
    if colour == "fitness":
        values = merged.objective
    elif colour in problem.measure_names:  # a measure of this run: its cell's own value
        values = merged.measures[:, problem.measure_names.index(colour)]
    else:
        # The other size measure, computed from each elite's world (the runs keep them in their genome stores).
        values = np.zeros(len(labels))
        for r, folder in enumerate(folders):
            rows = [i for i, (run, _) in enumerate(labels) if run == r]
            worlds = folder.archive_genomes(problem) if rows else []
            for i in rows:
                world = worlds[labels[i][1]]
                values[i] = fsm_size_entropy(world) if colour == "entropy" else world.size()[0]
    figure = new_figure(figsize=(7.5, 5))
    axes = figure.add_subplot(1, 1, 1)
    _heatmap(axes, problem, merged.measures, values, cells, _COLOURS[colour])
    runs = f"best per cell over {len(folders)} runs" if len(folders) > 1 else f"run {folders[0].path.name}"
    axes.set_title(
        f"{_COLOURS[colour]}: {len(merged):,} cells filled, QD score {merged.objective.sum():,.0f} ({runs})", fontsize=9
    )
    figure.tight_layout()
    return atomic_write(output, figure_png(figure))


def robustness_figure(run_dir: str | Path, output: str | Path, *, longer: int = 5, chunk: int = 256) -> Path:
    """Figure 5: one run's archive as evolved, re-evaluated on new seeds, and on new seeds with ``longer`` times
    longer episodes (each elite's new simulations averaged with its stored ones, re-binned into a fresh archive)."""
    from tqdm import tqdm

    from structgen.domains.fortress.robustness import load_elites, rebin, resimulate

    folders, experiment, problem = _open([run_dir])
    cells = _cells(experiment)
    settings = problem.settings
    elites = load_elites(folders[0], problem)
    seeds = list(range(settings.sim_seed + settings.sims, settings.sim_seed + 2 * settings.sims))
    panels = [("as evolved", elites)]
    with tqdm(total=2 * len(elites), desc="re-simulating elites", unit="world") as bar:
        for name, steps in (
            ("new seeds", settings.steps),
            (f"new seeds, {settings.steps * longer} ticks", settings.steps * longer),
        ):
            again = resimulate(problem, elites, seeds, steps, chunk, bar.update)
            panels.append((name, rebin(problem, again, cells)))
    figure = new_figure(figsize=(16, 4.6))
    for k, (name, part) in enumerate(panels):
        axes = figure.add_subplot(1, 3, k + 1)
        _heatmap(axes, problem, part.measures, part.objective, cells, "fitness", vmin=0, vmax=1)
        axes.set_title(f"{name}: {len(part):,} cells, QD score {part.objective.sum():,.0f}", fontsize=9)
    figure.tight_layout()
    return atomic_write(output, figure_png(figure))


def populations_figure(run_dirs: Sequence[str | Path], output: str | Path, *, longer: int = 5, seed: int = 0) -> Path:
    """Figure 6: entities of each class over ``longer`` times evolution's episode, for three elites of the (merged)
    archive: the most even class sizes (highest entropy), and the fewest and the most entities at the end."""
    from structgen.domains.fortress.engine import simulate
    from structgen.domains.fortress.show import population_panel
    from structgen.domains.fortress.world import fsm_size_entropy

    folders, experiment, problem = _open(run_dirs)
    merged, labels = _merged(folders, problem, _cells(experiment))
    if not len(merged):
        raise InputError(f"{folders[0].path}: the archive is empty")
    worlds: dict[tuple[int, int], Any] = {}
    for r, folder in enumerate(folders):
        wanted = [row for run, row in labels if run == r]
        if wanted:
            stored = folder.archive_genomes(problem)
            worlds.update({(r, row): stored[row] for row in wanted})
    entropy = np.array([fsm_size_entropy(worlds[label]) for label in labels])
    entities = merged.measures[:, 0]
    chosen = [
        ("highest class-size entropy", int(np.argmax(entropy))),
        ("fewest entities at the end", int(np.argmin(entities))),
        ("most entities at the end", int(np.argmax(entities))),
    ]
    steps = problem.settings.steps
    figure = new_figure(figsize=(16, 4.4))
    for k, (name, i) in enumerate(chosen):
        world = worlds[labels[i]]
        trace = simulate([world], [seed], steps * longer, problem.rules, record=True).traces[0][0]
        axes = figure.add_subplot(1, 3, k + 1)
        axes.axvline(steps, color="tab:blue", linestyle=":", linewidth=1.2, label=f"evolution's episode ({steps})")
        title = f"{name}:\nentropy {entropy[i]:.2f}, {world.size()[0]} nodes, fitness {merged.objective[i]:.2f}"
        population_panel(axes, trace, world.chars, title)
        axes.set_xlim(0, steps * longer)  # a simulation that stopped early ends where it stopped
        axes.set_ylim(bottom=0)
    figure.tight_layout()
    return atomic_write(output, figure_png(figure))
