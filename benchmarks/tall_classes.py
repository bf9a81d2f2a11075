"""Can a rule per in-degree class carry a taller tower than one rule per level? A local search over
:func:`structgen.domains.structures.samples.by_level_rules` designs whose levels give each in-degree class (how many
members reach a vertex from above: 1, 2, 3-4, 5+) its own rule.

    python benchmarks/tall_classes.py [--start "V S V C SC S SC SC"] [--tied 0] [--stages static transient pairs]
        [--passes 3] [--seed 0] [--save DESIGN.json] [--weights WEIGHTS.npy]

A rule per level is written as one of the 14 one-level rules (every class follows it) or four joined by slashes,
one per class (``o/C/SC/SC``). Stages run in the order given, each a first-improvement descent whose moves change one
class's rule in one level (any of the 14 rules) or the number of tied levels (0 to 3), tried in an order shuffled by
``--seed``; a stage ends when a pass over all moves improves nothing, or after ``--passes`` passes (no clock, so the
same command finds the same design on any machine):

- ``static``: the largest static joint load (``physics.statics.bounding_loads``, load factors applied), over designs
  whose levels a local rule can tell apart as they grow (``tall.teachable(whole=False)``);
- ``transient``: the largest joint force in the faithful preset's first 0.1 s (joints unbreakable; these towers peak
  within 0.05 s), over designs an NCA can grow whole;
- ``pairs``: as ``transient``, but a move that leaves a design no NCA can grow whole is not dropped at once: the three
  such moves with the lowest peak are each tried with every second move that makes them growable.

The transient is far from the static analysis on these designs (it peaks near the top, the static analysis at the
feet), so the search is judged by the simulation once the static stage has brought it near. Prints each improvement
and a closing line with the design's static load, its peak in 0.1 s and 0.3 s in the design's and in the grown body
order (PyBullet's solver visits joints in the order the bodies were made), and whether it holds. ``--weights``
teaches the design to the paper's 52-60-26 network and saves the weights.
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

from physics import PhysicsConfig  # noqa: E402
from structgen.domains.structures.samples import (  # noqa: E402
    IN_DEGREE_CLASSES,
    by_level_rules,
    describe_level_rules,
    level_rule_moves,
    parse_level_rules,
)
from structgen.domains.structures.tall import largest_static_load, teachable, transient_peak  # noqa: E402
from structgen.domains.structures.teach import teach  # noqa: E402
from structgen.nca import save_weights  # noqa: E402
from structgen.nca_config import grow_command  # noqa: E402

Rules = list[tuple[str, ...]]
Design = tuple[Rules, int]
CLASSES = len(IN_DEGREE_CLASSES)
#: Seconds of the faithful preset the transient stages simulate: these towers peak within 0.05 s.
SEARCH_WINDOW = 0.1


def parse_rules(text: str) -> Rules:
    """``text`` (:func:`parse_level_rules`) with every level written as one rule per class."""
    return [rule if isinstance(rule, tuple) else (rule,) * CLASSES for rule in parse_level_rules(text)]


class Search:
    def __init__(self, physics: PhysicsConfig, max_vertices: int, rng: random.Random):
        self.physics, self.max_vertices, self.rng = physics, max_vertices, rng

    def build(self, design: Design, whole: bool):
        structure = by_level_rules(*design)
        if structure is None or structure.n_vertices > self.max_vertices or not teachable(structure, whole=whole):
            return None
        return structure

    def static(self, design: Design) -> float:
        structure = self.build(design, whole=False)
        return np.inf if structure is None else largest_static_load(structure, self.physics)

    def transient(self, design: Design) -> float:
        structure = self.build(design, whole=True)
        return np.inf if structure is None else transient_peak(structure, self.physics, SEARCH_WINDOW)

    def descend(self, design: Design, score, passes: int, label: str) -> tuple[Design, float]:
        best = score(design)
        print(f"{label}: start {best:.2f} N: {describe_level_rules(design[0])} (tied {design[1]})", flush=True)
        for _ in range(passes):
            improved = False
            for candidate in level_rule_moves(*design, self.rng):
                value = score(candidate)
                if value < best - 1e-6:
                    best, design, improved = value, candidate, True
                    print(f"{label}: {best:.2f} N: {describe_level_rules(design[0])} (tied {design[1]})", flush=True)
            if not improved:
                break
        return design, best

    def pairs(self, design: Design, label: str) -> tuple[Design, float]:
        best = self.transient(design)
        print(f"{label}: start {best:.2f} N: {describe_level_rules(design[0])} (tied {design[1]})", flush=True)
        ungrowable = []
        for candidate in level_rule_moves(*design, self.rng):
            structure = by_level_rules(*candidate)
            if structure is None or structure.n_vertices > self.max_vertices:
                continue
            if teachable(structure, whole=True):
                value = transient_peak(structure, self.physics, SEARCH_WINDOW)
                if value < best - 1e-6:
                    best, design = value, candidate
                    print(f"{label}: {best:.2f} N: {describe_level_rules(design[0])} (tied {design[1]})", flush=True)
            else:
                ungrowable.append((transient_peak(structure, self.physics, SEARCH_WINDOW), candidate))
        ungrowable.sort(key=lambda row: row[0])
        for first_peak, first in ungrowable[:3]:
            if first_peak >= best:
                break
            for candidate in level_rule_moves(*first, self.rng):
                value = self.transient(candidate)
                if value < best - 1e-6:
                    best, design = value, candidate
                    print(f"{label}: {best:.2f} N: {describe_level_rules(design[0])} (tied {design[1]})", flush=True)
        return design, best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--start", default="V S V C SC S SC SC", help="the rules, top level first, space-separated")
    parser.add_argument("--tied", type=int, default=0, help="tied lowest levels of the start (default 0)")
    parser.add_argument("--stages", nargs="+", default=["static", "transient", "pairs"], choices=["static", "transient", "pairs"])
    parser.add_argument("--passes", type=int, default=3, help="most passes over the moves in a stage (default 3)")
    parser.add_argument("--max-vertices", type=int, default=3000, help="largest design tried (default 3000)")
    parser.add_argument("--seed", type=int, default=0, help="order of the moves")
    parser.add_argument("--save", type=Path, help="write the design, as grown by the taught NCA, here (structure JSON)")
    parser.add_argument("--weights", type=Path, help="write the taught weights here (.npy)")
    args = parser.parse_args()
    try:
        rules = parse_rules(args.start)
    except ValueError as err:
        parser.error(f"--start: {err}")
    if by_level_rules(rules, args.tied) is None:
        parser.error(f"--start {args.start!r} does not reach the ground")
    physics = PhysicsConfig()
    search = Search(physics, args.max_vertices, random.Random(args.seed))
    started = time.perf_counter()
    design: Design = (rules, args.tied)
    for stage in args.stages:
        if stage == "static":
            design, _ = search.descend(design, search.static, args.passes, stage)
        elif stage == "transient":
            design, _ = search.descend(design, search.transient, args.passes, stage)
        else:
            design, _ = search.pairs(design, stage)
    structure = by_level_rules(*design)
    whole = teachable(structure, whole=True)
    # transient_peak simulates the order growth lists the bodies in, so this is the taught NCA's structure's peak too.
    peak = transient_peak(structure, physics)
    line = (
        f"\n{structure.height + 1} levels, {structure.n_vertices} vertices, {structure.n_edges} edges: static "
        f"{largest_static_load(structure, physics):.1f} N; peak {transient_peak(structure, physics, SEARCH_WINDOW):.1f} N in 0.1 s, "
        f"{peak:.1f} N in 0.3 s"
    )
    if whole:
        taught = teach(structure)
        holds = "holds" if peak <= physics.break_force else "breaks"
        line += f"; grown by the taught NCA: {peak:.1f} N in 0.3 s ({holds}, break force {physics.break_force:g} N)"
    else:
        line += "; no local rule grows it whole"
    print(f"{line}; {time.perf_counter() - started:.0f} s\nrules: {describe_level_rules(design[0])} (tied {design[1]})")
    if whole and args.save:
        taught.grown.save(args.save)
        print(f"wrote {args.save}")
    if whole and args.weights:
        save_weights(args.weights, taught.weights)
        print(f"wrote {args.weights}: {grow_command(args.weights, taught.config, 'tower.json')}")


if __name__ == "__main__":
    main()
