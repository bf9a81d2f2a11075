"""Can a rule per in-degree class carry a taller tower than one rule per level? A local search over
:func:`structgen.domains.structures.samples.by_level_rules` designs whose levels give each in-degree class (how many
members reach a vertex from above: 1, 2, 3-4, 5+) its own rule.

    python benchmarks/tall_classes.py [--start "V S V C SC S SC SC"] [--tied 0] [--static-minutes 10]
        [--transient-minutes 20] [--seed 0] [--save DESIGN.json]

Two stages of first-improvement descent, each move one class's rule in one level (any of the 14 rules) or the number
of tied levels (0 to 3), moves tried in a shuffled order, a stage ending when a whole pass improves nothing or its
minutes run out:

1. **static**: the largest static joint load (``physics.statics.bounding_loads``, load factors applied), over designs
   whose levels a local rule can tell apart as they grow (``tall.teachable(whole=False)``);
2. **transient**: the largest joint force in the faithful preset's first 0.1 s (joints unbreakable; tall towers
   peak within 0.05 s), over designs an NCA can grow whole, a move simulated only when its static load is within
   ``--slack`` of the current design's.

Prints each improvement and a closing line with the design's static load, its peak in 0.1 s and in 0.3 s, and whether
it holds (peak within the break force).
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig, check_transient  # noqa: E402
from structgen.domains.structures.samples import IN_DEGREE_CLASSES, LEVEL_RULES, by_level_rules  # noqa: E402
from structgen.domains.structures.tall import largest_static_load, teachable  # noqa: E402

Rules = list[tuple[str, ...]]


def peak(design, physics: PhysicsConfig, window: float) -> float:
    physics = physics.replace(**physics.room_for(design.n_vertices, design.n_edges))
    return check_transient(design, physics, window=window).peak_force


def moves(rules: Rules, tied: int, rng: random.Random) -> list[tuple[Rules, int]]:
    found = []
    for level, rule in enumerate(rules):
        for k in range(len(IN_DEGREE_CLASSES)):
            for other in LEVEL_RULES:
                if other != rule[k]:
                    changed = list(rules)
                    changed[level] = rule[:k] + (other,) + rule[k + 1 :]
                    found.append((changed, tied))
    found += [(rules, t) for t in range(4) if t != tied]
    rng.shuffle(found)
    return found


def describe(rules: Rules) -> str:
    return " ".join(rule[0] if len(set(rule)) == 1 else "/".join(rule) for rule in rules)


def descend(rules, tied, score, minutes: float, rng: random.Random, label: str):
    best = score(rules, tied, np.inf)
    print(f"{label}: start {best:.2f} N: {describe(rules)} (tied {tied})", flush=True)
    deadline = time.perf_counter() + minutes * 60
    improved = True
    while improved and time.perf_counter() < deadline:
        improved = False
        for candidate, candidate_tied in moves(rules, tied, rng):
            if time.perf_counter() >= deadline:
                break
            value = score(candidate, candidate_tied, best)
            if value < best - 1e-6:
                best, rules, tied, improved = value, candidate, candidate_tied, True
                print(f"{label}: {best:.2f} N: {describe(rules)} (tied {tied})", flush=True)
    return rules, tied, best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--start", default="V S V C SC S SC SC", help="one rule per level, top first (space-separated)")
    parser.add_argument("--tied", type=int, default=0, help="tied lowest levels of the start (default 0)")
    parser.add_argument("--static-minutes", type=float, default=10.0, help="time limit of the static stage")
    parser.add_argument("--transient-minutes", type=float, default=20.0, help="time limit of the transient stage")
    parser.add_argument("--slack", type=float, default=1.2, help="simulate moves whose static load is within this factor")
    parser.add_argument("--max-vertices", type=int, default=3000, help="largest design tried (default 3000)")
    parser.add_argument("--seed", type=int, default=0, help="order of the moves")
    parser.add_argument("--save", type=Path, help="write the final design here (structure JSON)")
    args = parser.parse_args()
    physics = PhysicsConfig()
    rules: Rules = [(rule,) * len(IN_DEGREE_CLASSES) for rule in args.start.split()]
    if by_level_rules(rules, args.tied) is None:
        parser.error(f"--start {args.start!r} does not reach the ground")
    rng = random.Random(args.seed)

    def static_score(candidate, tied, _best):
        design = by_level_rules(candidate, tied)
        if design is None or design.n_vertices > args.max_vertices or not teachable(design, whole=False):
            return np.inf
        return largest_static_load(design, physics)

    static_of = {}

    def transient_score(candidate, tied, best):
        design = by_level_rules(candidate, tied)
        if design is None or design.n_vertices > args.max_vertices or not teachable(design, whole=True):
            return np.inf
        static = largest_static_load(design, physics)
        if np.isfinite(best) and static > args.slack * static_of["current"]:
            return np.inf
        value = peak(design, physics, 0.1)
        if value < best:
            static_of["current"] = static
        return value

    started = time.perf_counter()
    rules, tied, static = descend(rules, args.tied, static_score, args.static_minutes, rng, "static")
    design = by_level_rules(rules, tied)
    if not teachable(design, whole=True):
        print("the static stage's design cannot be grown whole by a local rule; the transient stage starts from it anyway")
    static_of["current"] = largest_static_load(design, physics)
    rules, tied, _ = descend(rules, tied, transient_score, args.transient_minutes, rng, "transient")
    design = by_level_rules(rules, tied)
    short, full = peak(design, physics, 0.1), peak(design, physics, 0.3)
    holds = "holds" if full <= physics.break_force else "breaks"
    print(
        f"\n{design.height + 1} levels, {design.n_vertices} vertices, {design.n_edges} edges: static {largest_static_load(design, physics):.1f} N, "
        f"peak {short:.1f} N in 0.1 s, {full:.1f} N in 0.3 s ({holds}; break force {physics.break_force:g} N); "
        f"teachable whole: {teachable(design, whole=True)}; {time.perf_counter() - started:.0f} s\n"
        f"rules: {describe(rules)} (tied {tied})"
    )
    if args.save:
        design.save(args.save)
        print(f"wrote {args.save}")


if __name__ == "__main__":
    main()
