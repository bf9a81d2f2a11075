"""What sending layouts far from valid to the greedy repair does to training's objective: the elites of a warehouse
or manufacturing run that the greedy repair answered (field ``highs`` 0), repaired again by HiGHS alone within the
run's time limit, and both repairs judged as the run judges (same seed).

    python benchmarks/repair_route.py RUN_DIR [--layouts 20] [--workers 2]

Prints one row per layout (distance from valid, cells changed, objective with each repair, HiGHS's seconds and
method) and the mean difference of the objective, HiGHS's minus the greedy one's, with its standard error.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from structgen.domains.layouts.measures import similarity
from structgen.domains.layouts.problem import LayoutProblem
from structgen.domains.layouts.repair import distance_from_valid
from structgen.runs.experiment import load_experiment


def _compare(run: str, genome: np.ndarray, seed: int) -> dict:
    routed = load_experiment(Path(run) / "config.toml").make_problem()
    highs_only = LayoutProblem(dataclasses.replace(routed.settings, repair_greedy_beyond=-1))
    tiles = routed.grow(genome[None])[0]
    row = {"distance": distance_from_valid(tiles, routed.kind, shelves=routed.shelves)}
    for name, problem in (("greedy", routed), ("highs", highs_only)):
        began = time.perf_counter()
        repaired = problem._repair(tiles, seed)
        seconds = time.perf_counter() - began
        hamming, kept = similarity(tiles, repaired.tiles, problem.kind)
        throughput, _ = problem._simulate(repaired.tiles, seed)
        row[name] = {
            "hamming": hamming,
            "throughput": throughput,
            "objective": throughput + problem.settings.alpha * kept,
            "seconds": seconds,
            "method": repaired.method,
            "timed_out": repaired.timed_out,
        }
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run", help="a warehouse or manufacturing run folder")
    parser.add_argument("--layouts", type=int, default=20, help="greedy-repaired elites to compare (default 20)")
    parser.add_argument("--workers", type=int, default=2, help="processes (default 2)")
    args = parser.parse_args()
    archive = pd.read_csv(Path(args.run) / "archive.csv")
    genomes = np.load(Path(args.run) / "archive_solutions.npy")
    greedy = np.flatnonzero(archive["highs"].to_numpy() == 0)
    chosen = np.sort(np.random.default_rng(0).choice(greedy, min(args.layouts, len(greedy)), replace=False))
    print(f"{len(greedy)} of {len(archive)} elites of {args.run} were repaired greedily; comparing {len(chosen)}")
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(_compare, [args.run] * len(chosen), genomes[chosen], chosen.tolist()))
    print()
    print("| distance | greedy: changed, objective | HiGHS: changed, objective, seconds, method |")
    print("|---|---|---|")
    for row in rows:
        g, h = row["greedy"], row["highs"]
        stopped = ", stopped by its clock" if h["timed_out"] else ""
        print(
            f"| {row['distance']} | {g['hamming']}, {g['objective']:.3f} | "
            f"{h['hamming']}, {h['objective']:.3f}, {h['seconds']:.1f}, {h['method']}{stopped} |"
        )
    gain = np.array([r["highs"]["objective"] - r["greedy"]["objective"] for r in rows])
    error = gain.std(ddof=1) / np.sqrt(len(gain)) if len(gain) > 1 else float("nan")
    seconds = np.mean([r["highs"]["seconds"] for r in rows])
    print()
    print(f"objective, HiGHS minus greedy: {gain.mean():+.3f} +- {error:.3f} (mean +- standard error)")
    print(f"HiGHS: {seconds:.1f} s a layout on average, greedy {np.mean([r['greedy']['seconds'] for r in rows]):.3f} s")


if __name__ == "__main__":
    main()
