"""Throughput against the number of robots, on the paper's optimised layouts and its human-designed ones.

    python benchmarks/throughput_vs_agents.py [--seeds 3] [--planner pp] [--steps 1000] [--large-robots 200,400,...]
                                              [--rhcr SWEEP.json] [--output PNG]

At 33x36 (CMA-MAE, DSAGE, human) and 101x102 (CMA-MAE grown at 200 steps and repaired, human), 1,000 steps each,
planner ``pp`` unless told otherwise. Prints a table (mean throughput over seeds; a run that congested counts with the
throughput it reached, and the table says how many did) and draws both sizes side by side. ``--rhcr`` adds RHCR's
points at 101x102 from ``benchmarks/anchors/rhcr.py sweep`` (measured on the CMA-MAE layout over the same steps).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

import numpy as np

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure
from structgen.domains.layouts.grid import Grid
from structgen.domains.layouts.kinds import WAREHOUSE, reference_maps
from structgen.domains.layouts.warehouse.simulator import PLANNERS, simulate

MAPS = reference_maps() or Path("no reference maps")
OURS = "warehouse/ours/nca_to_show"
SIZES = {
    "33x36": (
        {
            "CMA-MAE": f"{OURS}/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_throughput_hamming_a=5.json",
            "DSAGE": f"{OURS}/dsage_comp/kiva_large_200_agents_dsage_opt_entropy_throughput_hamming_a=5.json",
            "human": "warehouse/human/kiva_large_w_mode.json",
        },
        (50, 100, 150, 200, 250),
    ),
    "101x102": (
        {
            "CMA-MAE": f"{OURS}/xxlarge_maps/iter=200/kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5.json",
            "human": "warehouse/human/kiva_xxlarge_w_mode.json",
        },
        (200, 400, 600, 800, 1000, 1200),
    ),
}


def sweep(ax, size: str, layouts: dict[str, np.ndarray], counts: tuple[int, ...], seeds: int, planner: str, steps: int) -> None:
    """Simulate each layout at each robot count, print a table row per point and draw a line per layout on ``ax``."""
    for label, tiles in layouts.items():
        means = []
        for agents in counts:
            runs = [simulate(tiles, agents, steps, seed=seed, planner=planner) for seed in range(seeds)]
            means.append(float(np.mean([r.throughput for r in runs])))
            jams = sum(r.congested for r in runs)
            print(f"| {size} | {label} | {agents} | {means[-1]:.3f} | {jams} of {seeds} |", flush=True)
        ax.plot(counts, means, marker="o", label=label)
    ax.set_title(f"{size}, {steps:,} steps, planner {planner}")
    ax.set_xlabel("robots")
    ax.set_ylabel("throughput (tasks per step)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="simulations per point (seeds 0, 1, ...; default 3)")
    parser.add_argument("--planner", choices=PLANNERS, default="pp", help="the simulator's planner (default pp)")
    parser.add_argument("--steps", type=int, default=1000, help="steps a simulation (default 1000)")
    parser.add_argument(
        "--rhcr", type=Path, default=None, metavar="SWEEP.json",
        help="RHCR's points at 101x102 (benchmarks/anchors/rhcr.py sweep), drawn beside the lines",
    )  # fmt: skip
    parser.add_argument(
        "--large-robots", default=None, metavar="N,N,...", help="robot counts at 101x102 (default 200,400,...,1200)"
    )
    parser.add_argument(
        "--output", type=Path, default=None, help="the plot to write (default docs/throughput_vs_agents.png, or "
        "docs/throughput_vs_agents_PLANNER.png for another planner)"
    )  # fmt: skip
    args = parser.parse_args()
    if args.output is None:
        suffix = "" if args.planner == "pp" else f"_{args.planner}"
        args.output = Path(f"docs/throughput_vs_agents{suffix}.png")
    sizes = dict(SIZES)
    if args.large_robots:
        try:
            counts = tuple(int(n) for n in args.large_robots.split(","))
        except ValueError:
            parser.error(f"--large-robots must be whole numbers separated by commas, got {args.large_robots!r}")
        sizes["101x102"] = (SIZES["101x102"][0], counts)
    if not MAPS.is_dir():
        parser.error("needs the original's maps: set $STRUCTGEN_REFERENCE_MAPS to their folder")
    print(f"machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}; Python {platform.python_version()}")
    figure = new_figure(figsize=(11, 4.2), layout="constrained")
    axes = figure.subplots(1, len(sizes))
    print("| size | layout | robots | throughput (mean over seeds) | congested |")
    print("|---|---|---|---|---|")
    for ax, (size, (layouts, counts)) in zip(axes, sizes.items()):
        tiles = {label: Grid.load(MAPS / name, WAREHOUSE.vocabulary).tiles for label, name in layouts.items()}
        sweep(ax, size, tiles, counts, args.seeds, args.planner, args.steps)
        if args.rhcr and size == "101x102":
            measured = json.loads(args.rhcr.read_text())
            if measured["steps"] != args.steps:
                parser.error(f"{args.rhcr}: RHCR ran {measured['steps']} steps, the lines {args.steps}")
            points = measured["points"]
            for point in points:
                print(
                    f"| {size} | CMA-MAE, RHCR | {point['robots']} | {point['throughput']:.3f} | {int(point['congested'])} of 1 |"
                )
            ax.plot([p["robots"] for p in points], [p["throughput"] for p in points], "k*", markersize=11,
                    label="CMA-MAE, RHCR (authors' code)")  # fmt: skip
            ax.legend(fontsize=8)
    atomic_write(args.output, figure_png(figure, 110))
    print(f"{args.output}: written")


if __name__ == "__main__":
    main()
