"""The paper's robustness table: each run's MAP-Elites archive of worlds re-simulated on new seeds and on longer
episodes and re-binned into a fresh archive, the runs' archives merged.

As the original's re-evaluation does, an elite's new simulations are averaged with the ones it was stored with (5 +
5 = 10 simulations) before it is placed again, and a cell keeps the best newcomer. Each run is re-evaluated on its
own and the results merged afterwards (the best elite of each cell over all runs), which is how the paper reports
its QD numbers over 10 seeds.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from evolution.runfolder import RunFolder
from structgen.domains.fortress.problem import FortressProblem
from structgen.errors import InputError

__all__ = ["Elites", "load_elites", "merge", "open_runs", "rebin", "reevaluate"]


class Elites:
    """Elites of an archive: worlds, objectives, measures (n, 2), and how many simulations each mean is over."""

    def __init__(self, worlds: list, objective: np.ndarray, measures: np.ndarray, sims: int) -> None:
        self.worlds, self.objective, self.measures, self.sims = worlds, objective, measures, sims

    def __len__(self) -> int:
        return len(self.worlds)


def open_runs(run_dirs: Sequence[Any]) -> tuple[list[RunFolder], Any]:
    """Run folders to merge, and the first one's experiment; their [problem] settings must agree."""
    from structgen.runs import open_run

    opened = [open_run(run_dir) for run_dir in run_dirs]
    experiment = opened[0][1]
    for folder, other in opened[1:]:
        if other.problem_settings != experiment.problem_settings:
            raise InputError(f"{folder.path}: its [problem] settings differ from {opened[0][0].path}'s; merge like runs only")
    return [folder for folder, _ in opened], experiment


def load_elites(folder: RunFolder, problem: FortressProblem, rows: list[dict[str, str]] | None = None) -> Elites:
    """A fortress run's archive (``rows``: its :meth:`RunFolder.archive_rows`, if already read)."""
    rows = folder.archive_rows() if rows is None else rows
    names = problem.measure_names
    missing = [name for name in names if rows and name not in rows[0]]
    if missing:
        table = folder / RunFolder.ARCHIVE
        raise InputError(f"{table}: no column {', '.join(missing)} (not a fortress archive with these measures)")
    worlds = folder.archive_genomes(problem, rows)
    objective = np.array([float(r["objective"]) for r in rows])
    measures = np.array([[float(r[name]) for name in names] for r in rows]).reshape(len(rows), len(names))
    return Elites(worlds, objective, measures, problem.settings.sims)


def _cells(problem: FortressProblem, measures: np.ndarray, cells: Sequence[int]) -> np.ndarray:
    """The cell each elite falls in, as the run's archive bins it."""
    from ribs.archives import GridArchive

    if len(measures) == 0:
        return np.zeros(0, dtype=np.int64)
    return GridArchive(solution_dim=1, dims=tuple(cells), ranges=problem.measure_ranges).index_of(measures)


def rebin(problem: FortressProblem, elites: Elites, cells: Sequence[int]) -> Elites:
    """A fresh archive: each elite placed by its measures, a cell keeping the best (the first of equals)."""
    where = _cells(problem, elites.measures, cells)
    best: dict[int, int] = {}
    for i, cell in enumerate(where):
        if cell not in best or elites.objective[i] > elites.objective[best[cell]]:
            best[int(cell)] = i
    keep = sorted(best.values())
    return Elites([elites.worlds[i] for i in keep], elites.objective[keep], elites.measures[keep], elites.sims)


def merge(problem: FortressProblem, archives: Sequence[Elites], cells: Sequence[int]) -> Elites:
    """The best elite of each cell over several archives."""
    worlds = [w for a in archives for w in a.worlds]
    objective = np.concatenate([a.objective for a in archives])
    measures = np.concatenate([a.measures for a in archives])
    return rebin(problem, Elites(worlds, objective, measures, archives[0].sims), cells)


def resimulate(
    problem: FortressProblem, elites: Elites, seeds: Sequence[int], steps: int, chunk: int,
    progress: Callable[[int], None] = lambda n: None,
) -> Elites:  # fmt: skip
    """The elites re-simulated under ``seeds`` for ``steps`` ticks, the results averaged with their stored ones."""
    fitness = np.zeros(len(elites))
    entities = np.zeros(len(elites))
    for start in range(0, len(elites), chunk):
        part = elites.worlds[start : start + chunk]
        _, fitness[start : start + len(part)], entities[start : start + len(part)] = problem.scores(part, seeds, steps)
        progress(len(part))
    old, new = elites.sims, len(seeds)
    measures = elites.measures.copy()
    measures[:, 0] = (measures[:, 0] * old + entities * new) / (old + new)
    objective = (elites.objective * old + fitness * new) / (old + new)
    return Elites(elites.worlds, objective, measures, old + new)


def _row(name: str, elites: Elites) -> dict[str, Any]:
    return {
        "name": name,
        "qd_score": float(elites.objective.sum()),
        "cells": len(elites),
        "mean_fitness": float(elites.objective.mean()) if len(elites) else 0.0,
        "best": float(elites.objective.max()) if len(elites) else 0.0,
    }


def reevaluate(
    folders: Sequence[RunFolder], experiment: Any, *, longer: int = 5, chunk: int = 256, progress: bool = True
) -> dict[str, Any]:
    """The table: each run's archive and their merge, then the same after each run's elites are re-simulated on new
    seeds (and on new seeds with ``longer`` times longer episodes) and re-binned into a fresh archive per run, the
    fresh archives merged: the order the original's cross-evaluation takes for the paper's table."""
    problem = experiment.make_problem()
    if not isinstance(problem, FortressProblem):
        raise InputError(f"{folders[0].path}: not a fortress run (its domain is {experiment.domain})")
    cells = tuple(getattr(experiment.optimizer_settings, "cells", (100, 100)))
    names = [f"run {folder.path.name}" for folder in folders]
    settings = problem.settings
    new_seeds = list(range(settings.sim_seed + settings.sims, settings.sim_seed + 2 * settings.sims))
    passes = ((", new seeds", settings.steps), (f", new seeds, {longer}x longer", settings.steps * longer))
    # One run's worlds in memory at a time (a paper run's archive is ~9,800 worlds, several GB as objects); the
    # archives are kept as numbers, each elite named by (run, row).
    tables = [folder.archive_rows() for folder in folders]
    evolved: list[Elites] = []
    again: list[list[Elites]] = [[] for _ in passes]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=2 * sum(len(rows) for rows in tables), desc="re-simulating elites", unit="world")
    step = (lambda n: bar.update(n)) if bar is not None else (lambda n: None)
    try:
        for r, (folder, rows) in enumerate(zip(folders, tables)):
            elites = load_elites(folder, problem, rows)
            for p, (_, steps) in enumerate(passes):
                found = resimulate(problem, elites, new_seeds, steps, chunk, step)
                labelled = Elites([(r, i) for i in range(len(found))], found.objective, found.measures, found.sims)
                again[p].append(rebin(problem, labelled, cells))
            labels = [(r, i) for i in range(len(elites))]
            evolved.append(Elites(labels, elites.objective, elites.measures, elites.sims))
            del elites
    finally:
        if bar is not None:
            bar.close()

    def summarise(label: str, parts: list[Elites]) -> list[dict[str, Any]]:
        found = [_row(f"{name}{label}", part) for name, part in zip(names, parts)]
        if len(parts) > 1:
            found.append(_row(f"merged ({len(parts)} runs){label}", merge(problem, parts, cells)))
        return found

    rows = summarise("", evolved)
    for (label, steps), parts in zip(passes, again):
        rows += summarise(f"{label} ({steps} ticks)", parts)
    return {"rows": rows, "cells": list(cells), "seeds": new_seeds, "steps": settings.steps}
