"""The tallest structure a run found that really stands: its archive's elites (or its best candidate) by height,
re-checked with PyBullet's faithful preset until one stands with no joint broken.

    python benchmarks/tall.py RUN_DIR [RUN_DIR ...] [--candidates 10] [--save-best tall.json]

Prints a markdown table, one row per run: optimiser, evaluator, generations and run time, and the tallest elite that
the faithful simulation confirms (vertices tall = height + 1), with how many taller ones it broke.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from evolution import RunFolderError  # noqa: E402
from physics import InputError, check_stability  # noqa: E402
from structgen.runs import load_run  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", metavar="RUN_DIR")
    parser.add_argument("--candidates", type=int, default=10, help="elites to try per run, tallest first (default 10)")
    parser.add_argument("--save-best", metavar="FILE.json", help="save the tallest confirmed structure of all runs")
    args = parser.parse_args()
    print(
        "| run | optimizer | evaluator | generations | run time | tallest confirmed standing | vertices | taller ones that broke |"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|")
    tallest = (-1.0, None)
    for run_dir in args.runs:
        with load_run(run_dir) as run:
            rows = run.metrics()
            settings = run.experiment.problem_settings
            try:
                archive = run.archive()
                order = np.argsort(-archive.columns["height"], kind="stable")
                intact = archive.columns["integrity"][order] == 1
                genomes = [archive.genomes[i] for i in order[intact][: args.candidates]]
            except RunFolderError:  # no archive: the best candidate alone
                genomes = [run.best_genome()]
            faithful = settings.physics.stepped_as("faithful")
            found, broke = None, 0
            for genome in genomes:
                structure = run.problem.structure_of(genome)
                try:
                    report = check_stability(structure, faithful)
                except InputError:
                    continue
                if report.stands:
                    found = (report.height, structure)
                    break
                broke += 1
        height = f"{found[0]:.2f} ({round(found[0]) + 1} tall)" if found else "none"
        vertices = found[1].n_vertices if found else "-"
        print(
            f"| {Path(run_dir).name} | {run.experiment.optimizer_name} | {settings.evaluator} | {rows[-1]['generation']} | "
            f"{rows[-1]['wall_s'] / 60:.1f} min | {height} | {vertices} | {broke} |",
            flush=True,
        )
        if found and found[0] > tallest[0]:
            tallest = found
    if args.save_best and tallest[1] is not None:
        print(f"\n{tallest[1].save(args.save_best)}: {tallest[1].n_vertices} vertices, height {tallest[0]:.2f}")


if __name__ == "__main__":
    main()
