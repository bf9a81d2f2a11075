"""How many structures per second the local NCA grows: a population of random NCAs, one by one vs. batched.

    python benchmarks/grow.py [--population 100] [--repeats 7] [--threads 1 2]

Prints a markdown table (median over repeats) and the machine it ran on. Random NCAs with the paper's settings fill
most of their growth box (about 1,100 vertices each), which is the worst case for growth speed; the other rows use
the paper's variants that grow less.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402
import torch  # noqa: E402

from structgen import NCAConfig, grow, grow_population, random_weights  # noqa: E402

VARIANTS = {
    "paper (cutoff 0.5)": NCAConfig(),
    "cutoff 0.6": NCAConfig(cutoff=0.6),
    "cutoff 0.6, no build down": NCAConfig(cutoff=0.6, build_down=False),
}


def median_seconds(task, repeats: int) -> float:
    task()  # warm up allocators and caches
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        task()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--population", type=int, default=100, help="random NCAs per population (default 100)")
    parser.add_argument("--repeats", type=int, default=7, help="timed repetitions; the median is shown (default 7)")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="torch thread counts to try")
    args = parser.parse_args()

    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores; Python {platform.python_version()}, torch {torch.__version__}")
    print(f"population {args.population}, median of {args.repeats} runs\n")
    print("| variant | threads | mean vertices | mean edges | one by one (structures/s) | batched (structures/s) | speed-up |")
    print("|---|---|---|---|---|---|---|")
    for name, config in VARIANTS.items():
        weights = random_weights(args.population, seed=0, config=config)
        structures = grow_population(weights, config)
        vertices = np.mean([s.n_vertices for s in structures])
        edges = np.mean([s.n_edges for s in structures])
        for threads in args.threads:
            torch.set_num_threads(threads)
            single = median_seconds(lambda w=weights, c=config: [grow(x, c) for x in w], args.repeats)
            batched = median_seconds(lambda w=weights, c=config: grow_population(w, c), args.repeats)
            print(
                f"| {name} | {threads} | {vertices:.0f} | {edges:.0f} | {args.population / single:,.0f} "
                f"| {args.population / batched:,.0f} | {single / batched:.1f}x |"
            )


if __name__ == "__main__":
    main()
