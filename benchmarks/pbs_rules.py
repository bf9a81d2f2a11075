"""What each of the ``pbs`` planner's rules does at scale: one simulation with all of them, then one with each switched
off in turn (RHCR's start-cell rules 1-3, the replanning cap 4, the search order 5, the failed-round repair 6).

    python benchmarks/pbs_rules.py [--agents 1500] [--steps 300] [--map NAME] [--uneven]

Default: the paper's CMA-MAE a=5 warehouse grown to 101x102, 1,500 robots, 300 steps, seed 0. Prints one table row
per setting: throughput, whether and when the floor jammed, rounds the search gave up on, children that could not be
made consistent, nodes and seconds. Needs the reference maps (found as the tests find them).
"""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path; the repository root must be importable instead.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.anchors.rhcr import LARGE  # noqa: E402
from structgen.domains.layouts.grid import Grid  # noqa: E402
from structgen.domains.layouts.kinds import MANUFACTURING, WAREHOUSE, reference_maps  # noqa: E402
from structgen.domains.layouts.warehouse.simulator import PBS_RULES, simulate  # noqa: E402

#: Each row: its label and the settings it changes (rule 4 is the cap, rule 6 the fall-back).
SETTINGS = [
    ("all rules (RHCR's)", {}),
    *((f"without {name} (rule {rule})", {"pbs_off": (name,)}) for rule, name in zip((1, 2, 3, 5), PBS_RULES)),
    ("without the replanning cap (rule 4)", {"replan_cap": 0}),
    ("failed rounds planned by pp instead of repaired (rule 6)", {"fallback": "pp"}),
    ("without rules 1-3 (prioritize_start off)", {"pbs_off": PBS_RULES[:3]}),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--agents", type=int, default=1500, help="robots (default 1500)")
    parser.add_argument("--steps", type=int, default=300, help="steps (default 300)")
    parser.add_argument("--seed", type=int, default=0, help="simulation seed (default 0)")
    parser.add_argument("--map", default=LARGE, help="a reference map under the data folder (default: the paper's "
                        "CMA-MAE a=5 warehouse grown to 101x102)")  # fmt: skip
    parser.add_argument("--uneven", action="store_true", help="left workstations five times likelier")
    args = parser.parse_args()
    maps = reference_maps()
    if maps is None:
        raise SystemExit("the reference maps are not here (set STRUCTGEN_REFERENCE_MAPS to the warehouse-maps folder)")
    kind = MANUFACTURING if "manufacture" in Path(args.map).parts else WAREHOUSE
    tiles = Grid.load(maps / args.map, kind.vocabulary).tiles
    simulate(tiles, 10, 10, kind=kind, planner="pbs")  # compile before timing
    print(
        f"\n{args.map}, {args.agents} robots, {args.steps} steps, seed {args.seed}; {platform.processor() or platform.machine()}\n"
    )
    print("| setting | throughput | jammed at | rounds given up | failed children | nodes | seconds |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for label, options in SETTINGS:
        r = simulate(tiles, args.agents, args.steps, kind=kind, seed=args.seed, planner="pbs", uneven=args.uneven, **options)
        jammed = f"step {r.stopped_at}" if r.congested else "no"
        rounds = -(-r.stopped_at // 5)
        print(
            f"| {label} | {r.throughput:.3f} | {jammed} | {r.fallbacks} of {rounds} | {r.failed_children:,} | "
            f"{r.nodes:,} | {r.seconds:.1f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
