"""Do structures keep standing as they grow? Integrity against growth steps for the best NCA of each run given.

    python benchmarks/grow_stable.py RUN_DIR [RUN_DIR ...] [--multiples 1 2 4 8] [--max-vertices 20000] [-o plot.png]

Each run's best NCA is grown for each multiple of the steps it was trained with (its other NCA settings kept, the
vertex cap raised to --max-vertices) and judged by the static analysis with the run's physics settings; where the
structure has at most --bullet-up-to joints (600: a faithful simulation of 30 s takes minutes beyond that), the
simulation confirms it. Prints a markdown table and draws integrity against growth steps, one line per run.
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
    parser.add_argument("--multiples", type=int, nargs="+", default=[1, 2, 4, 8], help="of the training steps")
    parser.add_argument("--max-vertices", type=int, default=20_000)
    parser.add_argument(
        "--bullet-up-to",
        type=int,
        default=600,
        metavar="JOINTS",
        help="confirm with PyBullet up to this many joints (default 600)",
    )
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
        lengths = [m * settings.nca.iterations for m in args.multiples]
        for steps in lengths:
            nca = replace(settings.nca, iterations=steps, max_vertices=args.max_vertices)
            structure = grow(genome, nca)
            predicted = check_statics(structure, physics)
            integrities.append(predicted.integrity)
            simulated = "-"
            if 2 * structure.n_edges > args.bullet_up_to:
                simulated = f"not simulated ({2 * structure.n_edges:,} joints)"
            else:
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
        axes.plot(
            args.multiples, integrities, marker="o", label=f"{Path(run_dir).name} (trained at {settings.nca.iterations} steps)"
        )
    axes.axhline(0.95, color="grey", lw=0.8, ls="--")
    axes.set_xscale("log", base=2)
    axes.set_xticks(args.multiples, [f"{m}x" for m in args.multiples])
    axes.set_xlabel("growth steps, as a multiple of the training steps")
    axes.set_ylabel("integrity (static analysis)")
    axes.set_ylim(-0.02, 1.02)
    axes.set_title("the best NCA of each run, grown for more steps than it was trained for")
    axes.legend(fontsize=8)
    atomic_write(args.output, figure_png(figure, 110))
    print(f"\nwrote {args.output}")


if __name__ == "__main__":
    main()
