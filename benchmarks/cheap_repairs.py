"""The two repairs that answer layouts far from valid without HiGHS, side by side on random NCAs' 33x36 warehouses:
the row repair (`repair.greedy_repair`) and the patch repair (`patch.patch_repair`).

    python benchmarks/cheap_repairs.py [--layouts 15] [--simulations 0]

Growths come from random NCAs drawn with step sizes 0.05, 0.2, 0.5 and 1 (`--layouts` each, seed 1): a run's
emitters start at 0.2 and move on from there. Prints, per step size, how many cells each repair changed (mean),
how often the patch changed fewer (the router takes the fewer), the shelf components each leaves (the archive's first
measure, [140, 240] in the paper's configuration) and the time; with `--simulations K`, also the throughput of K
`pp` runs of 1,000 steps with 200 robots, as training judges.
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from structgen.domains.layouts.kinds import WAREHOUSE
from structgen.domains.layouts.measures import shelf_components, violations
from structgen.domains.layouts.patch import patch_repair
from structgen.domains.layouts.problem import LayoutProblem, WarehouseSettings
from structgen.domains.layouts.repair import greedy_repair
from structgen.domains.layouts.warehouse.simulator import simulate

STEP_SIZES = (0.05, 0.2, 0.5, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--layouts", type=int, default=15, help="random NCAs per step size (default 15)")
    parser.add_argument("--simulations", type=int, default=0, help="pp runs per repaired layout (default 0: none)")
    args = parser.parse_args()
    problem = LayoutProblem(WarehouseSettings(size="33x36", agents=200))
    rng = np.random.default_rng(1)
    print(f"{platform.processor() or platform.machine()}, {time.strftime('%Y-%m-%d')}\n")
    header = "| NCA step size | layouts | cells changed: rows, patch | patch fewer | shelf components: rows, patch |"
    header += " ms: rows, patch |" + (" throughput: rows, patch |" if args.simulations else "")
    print(header)
    print("|" + "---|" * (header.count("|") - 1))
    for step in STEP_SIZES:
        grown = problem.grow(rng.normal(0.0, step, size=(args.layouts, problem.n_params)))
        stats = {"rows": [], "patch": []}
        for tiles in grown:
            for name, repair in (("rows", greedy_repair), ("patch", patch_repair)):
                began = time.perf_counter()
                layout = repair(tiles, shelves=problem.shelves)
                seconds = time.perf_counter() - began
                assert layout is not None and not violations(layout, WAREHOUSE, shelves=problem.shelves, fixed=tiles)
                throughput = (
                    np.mean([simulate(layout, 200, 1000, seed=s).throughput for s in range(args.simulations)])
                    if args.simulations
                    else np.nan
                )
                stats[name].append((int((layout != tiles).sum()), shelf_components(layout), 1000 * seconds, throughput))
        rows, patch = np.array(stats["rows"]), np.array(stats["patch"])
        fewer = int((patch[:, 0] < rows[:, 0]).sum())
        line = (
            f"| {step} | {len(grown)} | {rows[:, 0].mean():.0f}, {patch[:, 0].mean():.0f} | {fewer} of {len(grown)} | "
            f"{rows[:, 1].min():.0f}-{rows[:, 1].max():.0f}, {patch[:, 1].min():.0f}-{patch[:, 1].max():.0f} | "
            f"{rows[:, 2].mean():.1f}, {patch[:, 2].mean():.1f} |"
        )
        if args.simulations:
            line += f" {rows[:, 3].mean():.2f}, {patch[:, 3].mean():.2f} |"
        print(line, flush=True)


if __name__ == "__main__":
    main()
