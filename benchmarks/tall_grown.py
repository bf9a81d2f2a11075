"""The tallest structures a local NCA can grow that stand: level-by-level designs that the NCA's shared local rule can
express, searched for, then taught to the paper's network (``structgen.teach``) and grown by it.

    python benchmarks/tall_grown.py [--levels 8] [--beam 30] [--candidates 12] [--no-refine] [--save-weights DIR] [--verdict 8]

A design grows down from one top vertex, one rule per level (``structgen.samples.by_level_rules``), each level
optionally tied to its side neighbours. Beam search from the top: the ``--beam`` designs of each height with the
smallest largest static joint load go on to the next, keeping only those whose levels an NCA can tell apart (no two
vertices above the lowest level see the same neighbourhood and must act differently). Of each height, the
``--candidates`` best by static load that an NCA can grow whole are simulated for the first 0.3 s of the faithful
preset with joints that hold (``physics.check_transient``, where these designs carry most), and the one with the
smallest peak is taught to a 52-60-26 network and grown from its weights. The beam ranks by static load, which
misses designs that carry less in the transient, so the tallest height's design is then refined (``--refine``, on by
default): every design that differs from it in two levels' rules, the best ``--candidates`` by static load that an
NCA can grow simulated, the lowest peak kept. One row per height: the design, its loads, the rules taught and the
teaching time (``teach`` grows the weights and checks they give the design exactly).

``--verdict N`` also simulates the grown N-level structure for the faithful preset's full 30 s with breakable joints
(minutes for a few hundred vertices). ``--save-weights DIR`` writes each height's weights to
``DIR/tall_grown_<levels>.npy``; grow one with ``structgen grow --weights FILE --max-extent <levels - 1> -o out.json``.
"""

from __future__ import annotations

import argparse
import functools
import itertools
import sys
import time
from multiprocessing import Pool
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig, check_stability, check_transient  # noqa: E402
from physics.statics import bounding_loads  # noqa: E402
from structgen.nca import save_weights  # noqa: E402
from structgen.samples import LEVEL_RULES, by_level_rules, by_level_rules_one_taller  # noqa: E402
from structgen.structure import Structure  # noqa: E402
from structgen.teach import TeachError, growth_config, growth_schedule, local_rules, teach  # noqa: E402

PHYSICS = PhysicsConfig()
# These designs pass the default joint cap from seven levels on; the transient is only a first look, so let them in.
ROOMY = PHYSICS.replace(max_vertices=10_000, max_joints=20_000)


def teachable(design: Structure, *, whole: bool) -> bool:
    """Whether a local rule grows ``design`` from its top; with ``whole=False`` the lowest level's own actions are
    left out (they change when a level is added below)."""
    states = growth_schedule(design)
    try:
        if whole:
            local_rules(states, growth_config(states))
        else:  # state t holds the levels down to t, so the lowest level first acts in the step after state `height`
            local_rules(states[: design.height + 1], growth_config(states), fixed_point=False)
    except TeachError:
        return False
    return True


def transient_peak(design: Structure) -> float:
    return check_transient(design, ROOMY, window=0.3).peak_force


def search(max_levels: int, beam: int, candidates: int, max_vertices: int, pool: Pool) -> dict[int, tuple]:
    """Per height, the teachable design with the smallest transient peak among the best by static load."""
    best: dict[int, tuple] = {}
    kept: list[tuple[tuple[str, ...], int]] = [((), 0)]
    for levels in range(2, max_levels + 1):
        scored = []
        for rules, tied, design in by_level_rules_one_taller([rules for rules, _ in kept], max_vertices):
            if teachable(design, whole=False):
                load = float(np.nan_to_num(np.max(bounding_loads(design, PHYSICS)), nan=np.inf))
                scored.append((load, rules, tied, design))
        if not scored:
            break
        scored.sort(key=lambda row: row[0])
        kept = list(dict.fromkeys((row[1], row[2]) for row in scored))[:beam]
        whole = list(itertools.islice((row for row in scored if teachable(row[3], whole=True)), candidates))
        if not whole:
            continue
        peaks = pool.map(transient_peak, [row[3] for row in whole])
        k = int(np.argmin(peaks))
        best[levels] = (*whole[k], peaks[k])
    return best


def _static_if_teachable(candidate: tuple[tuple[str, ...], int], max_vertices: int) -> float:
    design = by_level_rules(*candidate)
    if design is None or design.n_vertices > max_vertices or not teachable(design, whole=True):
        return np.inf
    return float(np.nan_to_num(np.max(bounding_loads(design, PHYSICS)), nan=np.inf))


def refine(found: tuple, candidates: int, max_vertices: int, pool: Pool) -> tuple:
    """The beam keeps whole designs by static load and misses some that carry less in the transient: try every design
    that differs from ``found`` in the rules of two levels, the best by static load that an NCA can grow simulated."""
    _, rules, tied, _, peak = found
    variants = {
        (tuple(rule_a if k == i else rule_b if k == j else rule for k, rule in enumerate(rules)), tied)
        for i, j in itertools.combinations(range(len(rules)), 2)
        for rule_a in LEVEL_RULES
        for rule_b in LEVEL_RULES
    } - {(rules, tied)}
    variants = sorted(variants)
    loads = pool.map(functools.partial(_static_if_teachable, max_vertices=max_vertices), variants, chunksize=16)
    ranked = [(load, variant) for load, variant in sorted(zip(loads, variants)) if np.isfinite(load)][:candidates]
    peaks = pool.map(transient_peak, [by_level_rules(*variant) for _, variant in ranked])
    if peaks and min(peaks) < peak:
        k = int(np.argmin(peaks))
        load, (rules, tied) = ranked[k]
        return load, rules, tied, by_level_rules(rules, tied), peaks[k]
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--levels", type=int, default=8, help="tallest design to search, in vertices (default 8)")
    parser.add_argument("--beam", type=int, default=30, help="designs of each height kept for the next (default 30)")
    parser.add_argument("--candidates", type=int, default=12, help="teachable designs of each height simulated (default 12)")
    parser.add_argument("--max-vertices", type=int, default=700, help="largest design tried (default 700)")
    parser.add_argument("--workers", type=int, default=2, help="processes for the simulations (default 2)")
    parser.add_argument(
        "--refine",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="then try every change of two levels' rules of the tallest design (default on; a few minutes)",
    )
    parser.add_argument("--save-weights", metavar="DIR", help="write each height's taught weights here")
    parser.add_argument("--verdict", type=int, metavar="N", help="the faithful 30 s verdict of the grown N-level one")
    args = parser.parse_args()
    if min(args.levels - 1, args.beam, args.candidates, args.max_vertices, args.workers) < 1:
        parser.error("--levels must be at least 2, and --beam, --candidates, --max-vertices, --workers at least 1")
    started = time.perf_counter()
    with Pool(args.workers) as pool:
        best = search(args.levels, args.beam, args.candidates, args.max_vertices, pool)
        print(f"search: {time.perf_counter() - started:.0f} s; joints break above {PHYSICS.break_force:g} N")
        tallest = max(best)
        if args.refine:
            clock, peak = time.perf_counter(), best[tallest][-1]
            best[tallest] = refine(best[tallest], args.candidates, args.max_vertices, pool)
            print(
                f"refined the {tallest}-level design (every change of two levels' rules): peak {peak:.1f} N -> "
                f"{best[tallest][-1]:.1f} N, {time.perf_counter() - clock:.0f} s"
            )
    print()
    print(
        "| levels | rules, top level first | tied levels | vertices | edges | largest static load | peak in the first "
        "0.3 s | rules taught | teaching |"
    )
    print("|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    grown_by_levels = {}
    for levels, (load, rules, tied, design, peak) in sorted(best.items()):
        clock = time.perf_counter()
        taught = teach(design)
        seconds = time.perf_counter() - clock
        grown_by_levels[levels] = taught
        shown = [f"{f:.1f} N" if f <= PHYSICS.break_force else f"**{f:.1f} N**" for f in (load, peak)]
        print(
            f"| {levels} | {' '.join(rules)} | {tied} | {design.n_vertices} | {design.n_edges} | {shown[0]} | "
            f"{shown[1]} | {taught.n_rules} | {seconds:.1f} s |",
            flush=True,
        )
        if args.save_weights:
            folder = Path(args.save_weights)
            folder.mkdir(parents=True, exist_ok=True)
            save_weights(folder / f"tall_grown_{levels}.npy", taught.weights)
    if args.verdict:
        if args.verdict not in grown_by_levels:
            parser.error(f"--verdict {args.verdict}: no teachable design of that height was found")
        clock = time.perf_counter()
        grown = grown_by_levels[args.verdict].grown
        report = check_stability(grown, PHYSICS.replace(max_joints=max(PHYSICS.max_joints, 2 * grown.n_edges)))
        verdict = "stands, no joint broken" if report.stands else f"{len(report.broken_joints)} joints break"
        print(
            f"\nfaithful 30 s, the grown {args.verdict}-level structure: {verdict}, height {report.height:.3f} "
            f"({time.perf_counter() - clock:.0f} s)"
        )


if __name__ == "__main__":
    main()
