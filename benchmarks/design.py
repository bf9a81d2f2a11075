"""Designs to a spec: success, time, variety, and the static verdict against the faithful preset.

    python benchmarks/design.py [--library FILE.npz] [--specs 500] [--faithful 12] [--min-height 1] [--any-size]

500 random specs of the documented range (footprints 1-11 by 1-11 cells, heights 1-8 levels), each designed with a
random seed on one CPU core (torch and BLAS held to one thread): the share met (a structure of exactly that
footprint and height that the static analysis finds standing), how many of those are a smaller tower on a floor mat
(``design.on_a_mat``), and the time per design, the first call's start-up apart. Variety: for the met specs among the first 100, how many different structures five seeds give. Agreement:
``--faithful`` met designs (of specs at least ``--min-height`` levels tall), the smallest of a random draw of four
times as many (``--any-size``: the draw itself), simulated with the faithful preset (30 s), the verdicts compared.
Prints markdown tables.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import torch  # noqa: E402

from physics import PhysicsConfig, check_stability  # noqa: E402
from structgen.domains.structures.design import MAX_LEVELS, MAX_SIDE, Spec, UnmeetableSpec, design, load_library  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--library", type=Path, default=None, help="design library (default: the shipped one)")
    parser.add_argument("--specs", type=int, default=500, help="random specs to design (default 500)")
    parser.add_argument("--faithful", type=int, default=12, help="designs to simulate with the faithful preset")
    parser.add_argument("--seed", type=int, default=0, help="seed of the spec draw")
    parser.add_argument(
        "--min-height",
        type=int,
        default=1,
        help="draw the --faithful designs from met specs at least "
        "this many levels tall (default 1: any; the static analysis is lenient on tall, narrow frames)",
    )
    parser.add_argument(
        "--any-size",
        action="store_true",
        help="simulate the first --faithful designs of the random draw whatever their size, rather than the smallest "
        "of four times as many (slower: minutes a design of a hundred vertices or more)",
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores (one used); Python {platform.python_version()}, torch {torch.__version__}\n")
    library = load_library(args.library)
    print(f"library: {library.info.get('name')}: {len(library.families)} NCAs, {len(library.answers)} answers for "
          f"{len(library.specs())} of the {MAX_SIDE * (MAX_SIDE + 1) // 2 * MAX_LEVELS} specs with width at most depth "
          f"(built in {library.info.get('seconds', '?')} s"
          + (f", its transient screen {library.info['screen_seconds']} s" if "screen_seconds" in library.info else "") + ")\n")  # fmt: skip
    rng = np.random.default_rng(args.seed)
    specs = [Spec(int(rng.integers(1, MAX_SIDE + 1)), int(rng.integers(1, MAX_SIDE + 1)), int(rng.integers(1, MAX_LEVELS + 1)))
             for _ in range(args.specs)]  # fmt: skip
    seeds = rng.integers(0, 1000, size=len(specs))
    warm = min(library.specs())  # the first call imports the physics: not a design's cost
    design(Spec(*warm), 0, library)
    times, met, unmet = [], [], []
    for position, (spec, seed) in enumerate(zip(specs, seeds)):
        started = time.process_time()
        try:
            structure = design(spec, int(seed), library)
        except UnmeetableSpec:
            unmet.append(spec)
            times.append(time.process_time() - started)
            continue
        times.append(time.process_time() - started)
        met.append((spec, int(seed), structure, position))
    times_ms = 1e3 * np.array(times)
    on_mats = sum(structure.metadata["design"]["on_mat"] for _, _, structure, _ in met)
    print("| specs | met | share met | of them on a floor mat | median ms | 95th percentile ms | max ms | designs over 1 s |")
    print("|---|---|---|---|---|---|---|---|")
    print(f"| {len(specs)} | {len(met)} | {100 * len(met) / len(specs):.1f} % | {on_mats} | {np.median(times_ms):.0f} | "
          f"{np.percentile(times_ms, 95):.0f} | {times_ms.max():.0f} | {(times_ms > 1000).sum()} |\n")  # fmt: skip

    print("Specs not met, by height and by the narrower side of the footprint:\n")
    print("| | " + " | ".join(f"height {h}" for h in range(1, MAX_LEVELS + 1)) + " |")
    print("|---|" + "---|" * MAX_LEVELS)
    for narrow in range(1, MAX_SIDE + 1):
        cells = []
        for h in range(1, MAX_LEVELS + 1):
            asked = [s for s in specs if min(s.width, s.depth) == narrow and s.height == h]
            missed = [s for s in unmet if min(s.width, s.depth) == narrow and s.height == h]
            cells.append(f"{len(missed)} of {len(asked)}" if asked else "-")
        print(f"| narrower side {narrow} | " + " | ".join(cells) + " |")
    print()

    sample = [(spec, seed) for spec, seed, _, position in met if position < 100]
    distinct = []
    for spec, _ in sample:
        shapes = {(d.vertices.tobytes(), d.edges.tobytes()) for d in (design(spec, s, library) for s in range(5))}
        distinct.append(len(shapes))
    counts = np.bincount(distinct, minlength=6)[1:]
    print("| met specs (first 100 drawn) | " + " | ".join(f"{k} different of 5 seeds" for k in range(1, 6)) + " | mean |")
    print("|---|" + "---|" * 6)
    print(f"| {len(distinct)} | " + " | ".join(str(c) for c in counts) + f" | {np.mean(distinct):.2f} |\n")

    if args.faithful:
        tall = [m for m in met if m[0].height >= args.min_height]
        order = rng.permutation(len(tall))
        drawn = [tall[i] for i in order[: (1 if args.any_size else 4) * args.faithful]]
        chosen = sorted(drawn, key=lambda m: m[2].n_vertices)[: args.faithful]
        print("| spec | vertices | members | static verdict | faithful verdict (30 s) | faithful cpu s |")
        print("|---|---|---|---|---|---|")
        agree = 0
        for spec, _, structure, _ in chosen:
            report = check_stability(structure, PhysicsConfig(max_joints=10**5))
            agree += report.stands
            print(f"| {spec.width}x{spec.depth}x{spec.height} | {structure.n_vertices} | {structure.n_edges} | stands "
                  f"| {'stands' if report.stands else report.verdict()} | {report.cpu_time:.0f} |")  # fmt: skip
        print(f"\nThe faithful preset agrees on {agree} of {len(chosen)}.")


if __name__ == "__main__":
    main()
