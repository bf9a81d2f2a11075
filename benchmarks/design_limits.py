"""How tall a narrow footprint can stand: the evidence behind the design library's tall, narrow misses.

    python benchmarks/design_limits.py [--max-levels 7]

A 1x1 footprint holds one structure per height, a column (its only members are vertical), and it is judged by the
static analysis for each height. For 1-cell-wide footprints it judges every one-rule-per-level wall: from a top
vertex, each level's vertices reach the level below straight down (V), both ways along the wall (S), outwards only
(O), or a mix (VS, VO): ``by_level_rules(rules, wall=True)`` over :data:`.samples.WALL_RULES`. A
wall carries its own weight in its plane, and a wider footprint of the same kind (walls side by side) carries at
least as much per wall, so the height where no wall stands bounds what this family meets at any narrow footprint.
Prints a markdown table: distinct walls, how many stand (the static analysis's verdict, load factor applied), and
the lowest largest joint load (:func:`physics.statics.bounding_loads`: the larger of held and sliding ground).

    python benchmarks/design_limits.py --bound

What equilibrium alone allows, for any structure of a footprint, however its members are arranged: cut between
two levels, everything above is held up only by the members crossing the cut, through the joints at their lower
ends, and the static verdict lets each of those carry at most the break force over the load factor (50 N), its own
weight included. Fewest bodies above each cut (a vertex on each level, no more members than carry the load
there, every load shared perfectly) gives the most levels a footprint could stand: the table of that bound by
width and depth. It is an upper bound, not a design: real frames share their load unevenly.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig  # noqa: E402
from physics.statics import bounding_loads, check_statics  # noqa: E402
from structgen.domains.structures.design import tallest_possible  # noqa: E402
from structgen.domains.structures.samples import WALL_RULES, by_level_rules, column  # noqa: E402


def print_bound(max_side: int) -> None:
    print("| narrower side \\ longer side | " + " | ".join(str(d) for d in range(1, max_side + 1)) + " |")
    print("|---" * (max_side + 1) + "|")
    for width in range(1, max_side + 1):
        cells = [str(tallest_possible(width, depth)) if depth >= width else "" for depth in range(1, max_side + 1)]
        print(f"| {width} | " + " | ".join(cells) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--max-levels", type=int, default=7, help="tallest walls to judge (default 7: 5^6 rule choices)")
    parser.add_argument("--bound", action="store_true", help="print the equilibrium bound by footprint instead of judging walls")
    parser.add_argument("--max-side", type=int, default=11, help="largest footprint side of the --bound table (default 11)")
    args = parser.parse_args()
    if args.bound:
        print_bound(args.max_side)
        return
    limit = PhysicsConfig().break_force
    print(
        "| levels | 1x1 column | one-wide walls | standing | narrowest standing (cells) | lowest largest joint load (N) "
        "| that wall's rules | seconds |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for levels in range(2, args.max_levels + 1):
        started = time.perf_counter()
        column_verdict = "stands" if check_statics(column(levels)).stands else "breaks"
        judged = standing = 0
        lowest, lowest_rules, narrowest = np.inf, (), 10**9
        seen = set()
        for rules in itertools.product(WALL_RULES, repeat=levels - 1):
            design = by_level_rules(rules, wall=True)
            if design is None or (shape := design.edges.tobytes() + design.vertices.tobytes()) in seen:
                continue  # some rules give the same wall (outwards is no direction on the axis)
            seen.add(shape)
            judged += 1
            loads = bounding_loads(design)
            load = float(np.nanmax(loads)) if np.isfinite(loads).any() else np.inf
            if load < lowest:
                lowest, lowest_rules = load, rules
            if check_statics(design).stands:
                standing += 1
                narrowest = min(narrowest, int(np.ptp(design.vertices[:, 1])) + 1)
        print(f"| {levels} | {column_verdict} | {judged:,} | {standing:,} | {narrowest if standing else '-'} | "
              f"{lowest:.1f} (limit {limit}) | "
              f"{'/'.join(lowest_rules)} | {time.perf_counter() - started:.0f} |")  # fmt: skip


if __name__ == "__main__":
    main()
