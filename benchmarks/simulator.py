"""The lifelong warehouse and manufacturing simulator against the paper's (RHCR with PBS), and its speed.

    python benchmarks/simulator.py [--seeds 5] [--skip-large] [--skip-speed] [--skip-fidelity] [--planners pp,pbs]

Prints two tables. Speed: wall time and agent-steps per second of 1,000 steps at 200 agents (33x36) and at the
paper's robot counts and 2,000 agents (101x102), with the process's peak memory and RHCR's recorded time where there
is one. Fidelity: the original's layouts, our throughput with each planner (mean and standard deviation over seeds,
and how many runs congested; PIBT apart, never mixed into the first's numbers) beside RHCR's: measured with the
authors' code at 1,000 steps (research notes 1.8) and the paper's README values at 5,000 steps, at 101x102 with the
robot counts that match the paper's (benchmarks/layouts.md).
"""

from __future__ import annotations

import argparse
import os
import platform
import resource
from pathlib import Path

import numpy as np

from structgen.domains.layouts.grid import Grid
from structgen.domains.layouts.kinds import MANUFACTURING, WAREHOUSE, reference_maps
from structgen.domains.layouts.warehouse.simulator import PLANNERS, simulate

MAPS = reference_maps() or Path("no reference maps")
OURS = "warehouse/ours/nca_to_show"
CMA_MAE = f"{OURS}/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_throughput_hamming_a=5.json"
DSAGE = f"{OURS}/dsage_comp/kiva_large_200_agents_dsage_opt_entropy_throughput_hamming_a=5.json"
HUMAN = "warehouse/human/kiva_large_w_mode.json"
LARGE = f"{OURS}/xxlarge_maps/iter=200/kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5.json"
LARGE_UNEVEN = (
    f"{OURS}/xxlarge_maps/iter=200/kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_uneven_throughput-hamming_a=5.json"
)
FACTORY = "manufacture/ours/nca_to_show/manufacture_large_200_agents_{}_opt_alpha=5_sw=5.json"
FACTORY_HUMAN = "manufacture/human/manufacture_large_93_stations.json"
FACTORY_LARGE = (
    "manufacture/ours/xxlarge/manufacture_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5_sw=5_iter=200.json"
)
# (label, map, agents, steps, uneven, RHCR's throughput as recorded); manufacturing maps are under manufacture/.
FIDELITY = [
    ("CMA-MAE a=5", CMA_MAE, 200, 1000, False, "6.698"),
    ("DSAGE a=5", DSAGE, 200, 1000, False, "6.323"),
    ("human", HUMAN, 200, 1000, False, "congested (1.098)"),
    ("human", HUMAN, 150, 1000, False, "4.887"),
    ("human", HUMAN, 100, 1000, False, "3.346"),
    ("CMA-MAE a=5", CMA_MAE, 200, 5000, False, "6.74 (README)"),
    ("DSAGE a=5", DSAGE, 200, 5000, False, "6.35 (README)"),
    ("CMA-MAE a=5 uneven", CMA_MAE.replace("throughput_hamming", "uneven_throughput_hamming"), 200, 5000, True, "6.82 (README)"),
    (
        "DSAGE a=5 uneven",
        DSAGE.replace("throughput_hamming_a=5", "throughput_hamming_uneven_a=5"),
        200,
        5000,
        True,
        "6.40 (README)",
    ),
    ("manufacturing CMA-MAE a=5", FACTORY.format("cma-mae"), 200, 5000, False, "6.82 (README)"),
    ("manufacturing DSAGE a=5", FACTORY.format("dsage"), 200, 5000, False, "5.61 (README)"),
    ("manufacturing human (93 stations)", FACTORY_HUMAN, 200, 5000, False, "5.92 (README)"),
]
LARGE_FIDELITY = [
    ("CMA-MAE a=5, 101x102", LARGE, 1400, 5000, False, "16.01 (README, 90 % success)"),
    ("CMA-MAE a=5 uneven, 101x102", LARGE_UNEVEN, 1000, 5000, True, "12.03 (README, 84 % success)"),
    ("manufacturing CMA-MAE a=5, 101x102", FACTORY_LARGE, 1800, 5000, False, "23.11 (README, 100 % success)"),
]


def kind_of(name: str):
    return MANUFACTURING if name.startswith("manufacture/") else WAREHOUSE


def load(name: str) -> np.ndarray:
    return Grid.load(MAPS / name, kind_of(name).vocabulary).tiles


def fidelity(cases, seeds: int, planners=PLANNERS) -> None:
    head = " | ".join(f"{p}: mean ± sd | congested" for p in planners)
    print(f"| layout | agents | steps | RHCR (PBS) | {head} |")
    print("|---|---|---|---|" + "---|---|" * len(planners))
    for label, name, agents, steps, uneven, theirs in cases:
        cells = []
        for planner in planners:
            runs = [
                simulate(load(name), agents, steps, kind=kind_of(name), seed=s, uneven=uneven, planner=planner)
                for s in range(seeds)
            ]
            values = np.array([r.throughput for r in runs])
            cells.append(f"{values.mean():.3f} ± {values.std():.3f} | {sum(r.congested for r in runs)} of {seeds}")
        print(f"| {label} | {agents} | {steps:,} | {theirs} | {' | '.join(cells)} |", flush=True)


# RHCR's recorded times for the same workloads (benchmarks/anchors/README.md), where there is one.
RHCR_TIMES = {
    (CMA_MAE, 200): "16.3 s CPU (-O3 build, one core)",
    (LARGE, 1400): "about 1.2 s CPU a step (371 s for 300 steps at 1,500)",
    (LARGE, 2000): "jams by step 95, after 1,162 s CPU",
}


def speed(skip_large: bool = False, planners=PLANNERS) -> None:
    print("| map | agents | steps run | planner | wall s | agent-steps per s | congested | peak memory (process) | RHCR |")
    print("|---|---|---|---|---|---|---|---|---|")
    cases = [(CMA_MAE, 200), (FACTORY.format("cma-mae"), 200)]
    if not skip_large:
        cases += [(LARGE, 1400), (LARGE, 2000), (FACTORY_LARGE, 2000)]
    for name, agents in cases:
        tiles = load(name)
        for planner in planners:
            result = simulate(tiles, agents, 1000, kind=kind_of(name), seed=0, planner=planner)
            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            print(
                f"| {kind_of(name).name} {tiles.shape[0]}x{tiles.shape[1]} | {agents} | {result.stopped_at} | {planner} | "
                f"{result.seconds:.2f} | {agents * result.stopped_at / result.seconds:,.0f} | "
                f"{'yes' if result.congested else 'no'} | {peak:.0f} MiB | {RHCR_TIMES.get((name, agents), '')} |",
                flush=True,
            )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=5, help="simulations per row (seeds 0, 1, ...)")
    parser.add_argument("--skip-large", action="store_true", help="leave out the 101x102 rows (1,000 to 2,000 agents)")
    parser.add_argument(
        "--planners",
        default=",".join(PLANNERS),
        help=f"comma-separated planners for both tables (default {','.join(PLANNERS)})",
    )
    parser.add_argument("--skip-speed", action="store_true", help="leave out the speed table")
    parser.add_argument("--skip-fidelity", action="store_true", help="leave out the fidelity table")
    args = parser.parse_args()
    if not MAPS.is_dir():
        parser.error("needs the original's maps: set $STRUCTGEN_REFERENCE_MAPS to their folder")
    print(f"machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}; Python {platform.python_version()}")
    for planner in PLANNERS:  # compile (or load the compiled planners) before timing anything
        simulate(load(CMA_MAE), 10, 10, planner=planner)
    planners = tuple(args.planners.split(","))
    if unknown := set(planners) - set(PLANNERS):
        parser.error(f"unknown planners {sorted(unknown)}; choose from {', '.join(PLANNERS)}")
    if not args.skip_speed:
        speed(args.skip_large, planners)
        print()
    if not args.skip_fidelity:
        fidelity(FIDELITY + ([] if args.skip_large else LARGE_FIDELITY), args.seeds, planners)


if __name__ == "__main__":
    main()
