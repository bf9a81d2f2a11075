"""Train small, grow large: a warehouse NCA trained at 33x36 grown at every larger size of the paper, repaired and
simulated beside the human layout of the same size.

    python benchmarks/scale_up.py RUN_DIR [--seeds 3] [--repair-time-limit 120] [--sizes 33x36,101x102]
        [--layouts DIR] [--output docs/scale_up.png]

RUN_DIR is a warehouse training run (configs/warehouse_cma_mae.toml); its best genome grows 50 steps at 33x36 (as
trained) and 200 steps at 45x47 ... 101x102 (the paper's rule for the large maps), and each layout is repaired to
the paper's shelf count for its size. Prints two tables: per size, the repair and the throughput of ours and the
human layout with robots at the density of 150 robots on 33x36 (at most 800); and throughput against robot count
at 33x36 and 101x102, with the paper's own CMA-MAE layouts for reference. Draws both (planner pp, 1,000 steps).
"""

from __future__ import annotations

import argparse
import os
import platform
from pathlib import Path

import numpy as np
from throughput_vs_agents import sweep  # the script beside this one

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure
from structgen.domains.warehouse.commands import AUTO_YES_NO
from structgen.domains.warehouse.layouts import WAREHOUSE, reference_maps
from structgen.domains.warehouse.measures import similarity
from structgen.domains.warehouse.repair import repair
from structgen.domains.warehouse.simulator import simulate
from structgen.grid import Grid
from structgen.runs import open_run

MAPS = reference_maps() or Path("no reference maps")
HUMAN = {
    "33x36": "warehouse/human/kiva_large_w_mode.json",
    **{
        size: f"warehouse/human/additional_eval/kiva_human_{size}_w_mode.json"
        for size in ("45x47", "57x58", "69x69", "81x80", "93x91")
    },
    "101x102": "warehouse/human/kiva_xxlarge_w_mode.json",
}
PAPER = {
    "33x36": "warehouse/ours/nca_to_show/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_throughput_hamming_a=5.json",
    "101x102": "warehouse/ours/nca_to_show/xxlarge_maps/iter=200/"
    "kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5.json",
}
SWEEPS = {"33x36": (50, 100, 150, 200, 250), "101x102": (200, 400, 600, 800, 1000, 1200)}
STEPS = 1000


def robots_for(tiles: np.ndarray) -> int:
    """150 robots on 33x36 (the most the human layout takes without congesting), the same density elsewhere, at
    most 800 (the most its 101x102 layout takes)."""
    return min(800, int(round(150 * tiles.size / (33 * 36) / 50)) * 50)


def mean_throughput(tiles: np.ndarray, agents: int, seeds: int) -> tuple[float, int]:
    runs = [simulate(tiles, agents, STEPS, seed=seed) for seed in range(seeds)]
    return float(np.mean([r.throughput for r in runs])), sum(r.congested for r in runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="a warehouse training run")
    parser.add_argument("--seeds", type=int, default=3, help="simulations per point (seeds 0, 1, ...; default 3)")
    parser.add_argument("--repair-time-limit", type=float, default=120.0, help="seconds per repair (default 120)")
    parser.add_argument(
        "--round-relaxation",
        choices=tuple(AUTO_YES_NO),
        default="auto",
        help="round the linear relaxation before each repair's full search: auto (the repair's default), yes, no",
    )
    parser.add_argument("--sizes", default=",".join(HUMAN), help="comma-separated sizes (default: all seven)")
    parser.add_argument("--layouts", type=Path, default=None, metavar="DIR", help="also save every layout here")
    parser.add_argument("--output", type=Path, default=Path("docs/scale_up.png"), help="the plot to write")
    args = parser.parse_args()
    if not MAPS.is_dir():
        parser.error("needs the original's maps: set $STRUCTGEN_REFERENCE_MAPS to their folder")
    folder, experiment = open_run(args.run_dir)
    problem = experiment.make_problem()
    if problem.kind.name != "warehouse":
        parser.error(f"{args.run_dir} trained {problem.kind.name} layouts, not warehouses")
    genome = np.asarray(folder.best_genome(problem))
    print(f"machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}; Python {platform.python_version()}")
    print(f"run: {args.run_dir} (best of {folder.metrics()[-1]['evaluations']} evaluations)\n")

    ours: dict[str, np.ndarray] = {}
    print("| size | NCA steps | cells changed by the repair | repair s | robots | ours | human | congested (ours, human) |")
    print("|---|---|---|---|---|---|---|---|")
    sizes = args.sizes.split(",")
    if unknown := [size for size in sizes if size not in HUMAN]:
        parser.error(f"--sizes: {', '.join(unknown)} not among {', '.join(HUMAN)}")
    for size in sizes:
        human_file = HUMAN[size]
        shape = WAREHOUSE.size(size)
        steps = problem.iterations if size == experiment.problem_settings.size else 200
        grown = WAREHOUSE.complete(problem.nca.grow(genome, WAREHOUSE.seed(shape.grown), steps))
        fixed = repair(
            grown,
            WAREHOUSE,
            shelves=shape.shelves,
            time_limit=args.repair_time_limit,
            seed=0,
            round_relaxation=AUTO_YES_NO[args.round_relaxation],
        )
        changed, score = similarity(grown, fixed.tiles, WAREHOUSE)
        ours[size] = fixed.tiles
        if args.layouts is not None:
            args.layouts.mkdir(parents=True, exist_ok=True)
            name = f"ours_{size}"
            WAREHOUSE.grid(fixed.tiles, name=name, iterations=steps, hamming=changed, sim_score=score).save(
                args.layouts / f"{name}.json"
            )
        human = Grid.load(MAPS / human_file, WAREHOUSE.vocabulary).tiles
        robots = robots_for(fixed.tiles)
        (mine, my_jams), (theirs, their_jams) = (mean_throughput(t, robots, args.seeds) for t in (fixed.tiles, human))
        print(
            f"| {size} | {steps} | {changed:,} | {fixed.seconds:.0f} | {robots} | {mine:.3f} | {theirs:.3f} | "
            f"{my_jams}, {their_jams} of {args.seeds} |",
            flush=True,
        )

    swept = {size: counts for size, counts in SWEEPS.items() if size in ours}
    if not swept:
        return
    figure = new_figure(figsize=(5.5 * len(swept), 4.2), layout="constrained")
    axes = figure.subplots(1, len(swept), squeeze=False)[0]
    print("\n| size | layout | robots | throughput (mean over seeds) | congested |")
    print("|---|---|---|---|---|")
    for ax, (size, counts) in zip(axes, swept.items()):
        layouts = {
            "ours (trained at 33x36)": ours[size],
            "paper's CMA-MAE": Grid.load(MAPS / PAPER[size], WAREHOUSE.vocabulary).tiles,
            "human": Grid.load(MAPS / HUMAN[size], WAREHOUSE.vocabulary).tiles,
        }
        sweep(ax, size, layouts, counts, args.seeds)
    atomic_write(args.output, figure_png(figure, 110))
    print(f"{args.output}: written")


if __name__ == "__main__":
    main()
