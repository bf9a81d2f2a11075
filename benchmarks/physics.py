"""Cost and fidelity of the physics checks.

    python benchmarks/physics.py [--quick] [--workers 2]

Prints markdown tables:

1. cost per structure against size (10, 50, 200 vertices): fast vs faithful preset, stopping when settled vs
   simulating the full horizon;
2. fidelity of the fast preset against the faithful one on a set of grown structures (verdict agreement, Spearman
   rank correlation of Q, mean differences), with the cost of each;
3. 1 vs 2 worker processes on the same batch;
4. populations of 100 grown structures checked end to end (growth + checks), next to the paper's Unity figures.

CPU times are measured inside the process that ran the simulation; wall times include process start-up.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path and this file would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from physics import PhysicsConfig, check_many, check_stability  # noqa: E402
from structgen import NCAConfig, Structure, grow_population, random_weights  # noqa: E402
from structgen.domains.structures.samples import random_growth  # noqa: E402

FAST = PhysicsConfig.preset("fast")
FAITHFUL = PhysicsConfig.preset("faithful")


def fidelity_set(count: int) -> list[Structure]:
    """Grown structures of 4 to 40 vertices with both outcomes: half random lattice growth (low and tall shapes),
    half stars grown by random NCAs in one step from the seed, free or under the no-building-down rule."""
    structures = []
    sizes = [4, 6, 8, 10, 12, 16, 20, 24, 30, 40]
    shapes = [(0.05, 0.2), (0.1, 0.3), (0.1, 0.6), (0.25, 0.3)]  # (upward, extra_edges)
    for seed in range(count // 2):
        upward, extra = shapes[seed % len(shapes)]
        structures.append(random_growth(sizes[seed % len(sizes)], seed, extra_edges=extra, upward=upward))
    for build_down in (True, False):
        config = NCAConfig(iterations=1, build_down=build_down)
        grown = [s for s in grow_population(random_weights(4 * count, seed=7, config=config), config) if s.n_vertices >= 4]
        structures.extend(grown[: (count - len(structures)) if not build_down else count // 4])
    return structures


def size_table(repeats: int) -> None:
    print("## Cost per structure against size\n")
    print("Random lattice growth (`random_growth(n, seed, upward=0.1)`), which collapses at these sizes; median of")
    print(f"{repeats} structures per size, one process.\n")
    print("| vertices | joints | preset | stop | simulated s | CPU s | wall s | CPU s per simulated s |")
    print("|---|---|---|---|---|---|---|---|")
    check_stability(random_growth(4, 0), FAST)  # connect this process's client before timing
    for n in (10, 50, 200):
        structures = [random_growth(n, seed, upward=0.1) for seed in range(repeats)]
        joints = statistics.median(2 * s.n_edges for s in structures)
        for name, preset in (("fast", FAST), ("faithful", FAITHFUL)):
            for stop in ("settled", "full horizon"):
                config = preset.replace(early_stop=stop == "settled")
                reports = [check_stability(s, config) for s in structures]
                wall = [r.wall_time for r in reports]
                cpu = [r.cpu_time for r in reports]
                sim = [r.sim_time for r in reports]
                print(
                    f"| {n} | {joints:.0f} | {name} | {stop} | {statistics.median(sim):.2f} | {statistics.median(cpu):.3f} "
                    f"| {statistics.median(wall):.3f} | {statistics.median(c / s for c, s in zip(cpu, sim)):.3f} |"
                )
    print()


def fidelity_table(count: int, workers: int) -> None:
    structures = fidelity_set(count)
    sizes = np.array([s.n_vertices for s in structures])
    print("## Fast preset against the faithful preset\n")
    print(f"{len(structures)} grown structures of {sizes.min()} to {sizes.max()} vertices (median {np.median(sizes):.0f});")
    print(f"checked with {workers} worker processes.\n")
    started = time.perf_counter()
    faithful = check_many(structures, FAITHFUL, workers=workers)
    faithful_wall = time.perf_counter() - started
    started = time.perf_counter()
    fast = check_many(structures, FAST, workers=workers)
    fast_wall = time.perf_counter() - started
    assert all(r.error is None for r in faithful + fast), [r.error for r in faithful + fast if r.error]
    same_verdict = np.mean([a.intact == b.intact for a, b in zip(fast, faithful)])
    rho = spearmanr([r.score for r in fast], [r.score for r in faithful]).statistic
    d_integrity = np.mean([abs(a.integrity - b.integrity) for a, b in zip(fast, faithful)])
    d_height = np.mean([abs(a.height - b.height) for a, b in zip(fast, faithful)])
    intact = sum(r.intact for r in faithful)
    small = sizes <= 16
    print(f"Faithful verdicts: {intact} intact, {len(structures) - intact} broken.\n")
    print(
        "| preset | same verdict as faithful | Spearman rho of Q | mean abs dI | mean abs dH | CPU s per structure (median, <= 16 vertices) | CPU s per structure (median, all) | CPU s per structure (max, <= 16 vertices) | wall s for the set |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, reports, wall in (("faithful", faithful, faithful_wall), ("fast", fast, fast_wall)):
        cpu = np.array([r.cpu_time for r in reports])
        agreement = "100 %" if reports is faithful else f"{100 * same_verdict:.1f} %"
        correlation = "1" if reports is faithful else f"{rho:.3f}"
        di = "0" if reports is faithful else f"{d_integrity:.3f}"
        dh = "0" if reports is faithful else f"{d_height:.3f}"
        print(
            f"| {name} | {agreement} | {correlation} | {di} | {dh} | {np.median(cpu[small]):.3f} | {np.median(cpu):.3f} "
            f"| {cpu[small].max():.3f} | {wall:.1f} |"
        )
    disagreements = [
        (i, s.n_vertices, a.integrity, b.integrity)
        for i, (s, a, b) in enumerate(zip(structures, fast, faithful))
        if a.intact != b.intact
    ]
    if disagreements:
        print(
            "\nVerdicts that differ (index, vertices, I fast, I faithful): "
            + ", ".join(f"({i}, {v}, {a:.2f}, {b:.2f})" for i, v, a, b in disagreements)
        )
    print()
    return structures


def workers_table(structures: list[Structure]) -> None:
    print("## Worker processes\n")
    print(f"The same {len(structures)} structures, fast preset.\n")
    print("| workers | wall s | speed-up |")
    print("|---|---|---|")
    base = None
    for workers in (1, 2):
        started = time.perf_counter()
        check_many(structures, FAST, workers=workers)
        wall = time.perf_counter() - started
        base = base or wall
        print(f"| {workers} | {wall:.2f} | {base / wall:.2f}x |")
    print()


def populations_table(workers: int) -> None:
    print("## Populations of 100, grown and checked end to end\n")
    print(f"Growth in this process, checks with the fast preset in {workers} worker processes (start-up included).\n")
    print(
        "| population | median vertices | max vertices | refused (over size caps) | intact | grow s | check s (wall) | total s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    populations = {
        "random NCAs, paper settings": (NCAConfig(), None),
        "random NCAs, cutoff 0.6, no build down": (NCAConfig(cutoff=0.6, build_down=False), None),
        "random NCAs, 2 steps, no build down": (NCAConfig(iterations=2, build_down=False), None),
        "random lattice growth, 4-40 vertices": (
            None,
            lambda: [random_growth(4 + (i * 7) % 37, i, upward=0.1) for i in range(100)],
        ),
    }
    for name, (config, make) in populations.items():
        started = time.perf_counter()
        structures = grow_population(random_weights(100, seed=3, config=config), config) if config else make()
        grown = time.perf_counter()
        reports = check_many(structures, FAST, workers=workers)
        done = time.perf_counter()
        sizes = [s.n_vertices for s in structures]
        refused = sum(1 for r in reports if r.error)
        print(
            f"| {name} | {np.median(sizes):.0f} | {max(sizes)} | {refused} | {sum(r.intact for r in reports)} "
            f"| {grown - started:.2f} | {done - grown:.2f} | {done - started:.2f} |"
        )
    print()
    print("The paper (Unity, one structure at a time): 1.42 to 25.06 s per structure in the evaluator, 131 to 2,044 s")
    print("per generation of 100.\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer structures (a smoke run, not for the record)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes for batch checks (default 2)")
    args = parser.parse_args()
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores; Python {platform.python_version()}\n")
    size_table(repeats=1 if args.quick else 3)
    structures = fidelity_table(count=12 if args.quick else 60, workers=args.workers)
    workers_table(structures)
    populations_table(args.workers)


if __name__ == "__main__":
    main()
