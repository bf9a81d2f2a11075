"""Do structures keep standing as they grow? Integrity against growth steps for the best NCA of each run given.

    python benchmarks/grow_stable.py RUN_DIR [RUN_DIR ...] [--steps 4 8 16 32] [--max-vertices 20000] [-o plot.png]

Each run's best NCA is grown for every step count (its other NCA settings kept, the vertex cap raised to
--max-vertices) and judged by the static analysis with the run's physics settings; where the structure is within
PyBullet's size caps (3,000 joints), the faithful simulation confirms it. Prints a markdown table and draws integrity
against growth steps, one line per run.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from evolution.files import atomic_write  # noqa: E402
from evolution.plots import figure_png, new_figure  # noqa: E402
from physics import InputError, check_stability, check_statics  # noqa: E402
from structgen.nca import grow  # noqa: E402
from structgen.runs import load_run  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", metavar="RUN_DIR")
    parser.add_argument("--steps", type=int, nargs="+", default=[4, 8, 16, 32])
    parser.add_argument("--max-vertices", type=int, default=20_000)
    parser.add_argument("--no-bullet", action="store_true", help="skip the PyBullet confirmation")
    parser.add_argument("-o", "--output", default="integrity_vs_steps.png")
    args = parser.parse_args()
    figure = new_figure(figsize=(7, 4.2), layout="constrained")
    axes = figure.add_subplot()
    print("| run | trained at | steps | vertices | height | statics integrity | PyBullet (faithful) integrity |")
    print("|---|---:|---:|---:|---:|---:|---|")
    for run_dir in args.runs:
        with load_run(run_dir) as run:
            settings = run.experiment.problem_settings
            genome = run.best_genome()
        physics = settings.physics
        integrities = []
        for steps in args.steps:
            nca = replace(settings.nca, iterations=steps, max_vertices=args.max_vertices)
            structure = grow(genome, nca)
            predicted = check_statics(structure, physics)
            integrities.append(predicted.integrity)
            simulated = "-"
            if not args.no_bullet:
                try:
                    report = check_stability(structure, physics.stepped_as("faithful"))
                    simulated = f"{report.integrity:.3f}"
                except InputError:
                    simulated = "over the size caps"
            print(
                f"| {Path(run_dir).name} | {settings.nca.iterations} | {steps} | {structure.n_vertices:,} | "
                f"{structure.height} | {predicted.integrity:.3f} | {simulated} |",
                flush=True,
            )
        axes.plot(args.steps, integrities, marker="o", label=f"{Path(run_dir).name} (trained at {settings.nca.iterations})")
    axes.axhline(0.95, color="grey", lw=0.8, ls="--")
    axes.set_xscale("log", base=2)
    axes.set_xticks(args.steps, [str(s) for s in args.steps])
    axes.set_xlabel("growth steps")
    axes.set_ylabel("integrity (static analysis)")
    axes.set_ylim(-0.02, 1.02)
    axes.set_title("the best NCA of each run, grown for more steps than it was trained for")
    axes.legend(fontsize=8)
    atomic_write(args.output, figure_png(figure, 110))
    print(f"\nwrote {args.output}")


if __name__ == "__main__":
    main()
