"""Amorphous Fortress engine speed, beside the original's measured speed (research notes B8).

Prints a Markdown table:

- fortress-steps/s (one tick of one simulation) and entity updates/s on random QD worlds (the original's random
  start, as its QD runs draw them), for the note's workload (30 worlds x 5 simulations x 100 ticks) and larger
  batches, on 1 and 2 numba threads;
- one MAP-Elites generation of the original's shape (9 mutants + 1 random world, 5 x 100 ticks each, archive of
  100 x 100), and the part of it its 50 simulations spend in the kernel, averaged over 50 generations halfway
  through and at the end of ``--generations`` (10,000: the paper's run, with no files written).

The original's code runs 78 fortress-steps/s on this machine when timed in alternation with ours on the same worlds
(``benchmarks/anchors/fortress.py``, 2026-11-24); speed-ups are against that. Both sides are the median of
``--repeats`` runs.

    python benchmarks/fortress.py [--worlds 30 200] [--threads 1 2] [--generations 400] [--paper-run]

``--paper-run`` also times the paper's full run (``structgen evolve configs/fortress_paper.toml --seed 20``, about
3 minutes) in a temporary folder: run time, wall time, peak memory and the folder's size.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np

from structgen.domains.fortress.engine import simulate
from structgen.domains.fortress.world import random_world

# The original's speed: the research notes' measurement (one process, a 2-core AMD EPYC VM); an earlier run of its
# code alone on its own random worlds here (Intel Xeon 2 vCPU, 2026-11-22: 14,830 steps in 47.7 s, 311/s); and the
# figure speed-ups use, its code timed in alternation with ours on the same 10 random worlds x 5 seeds, one thread
# each, median of 3 (benchmarks/anchors/fortress.py, AMD EPYC 2 vCPU, 2026-11-24: 4,951 steps in 63.1 s).
ORIGINAL = {"steps_per_s": 103, "updates_per_s": 2500, "generation_s": 50}
ORIGINAL_ALONE = {"steps_per_s": 311, "updates_per_s": 8505}
ORIGINAL_HERE = {"steps_per_s": 78, "generation_s": 5000 / 78}
# This engine before worlds became arrays (commit c79a476, the same machine, 2 threads, 2026-11-25, timed back to back
# with this version): seconds per generation over generations 151-200 and 351-400 of this script's run.
BEFORE = {"151-200": 0.137, "351-400": 0.138}
# The paper's full run (seed 20) at commit 6dc049b, before the kernel's row bits and the compiled mutation and layout
# (AMD EPYC 2 vCPU, 2026-11-25, nothing else running): run time, wall time, peak memory, folder.
PAPER_RUN_BEFORE = {"run_s": 401.5, "wall_s": 453, "peak_gb": 0.84, "folder_mb": 46}


def engine_rows(worlds_counts: list[int], threads: list[int], repeats: int) -> list[str]:
    rows = []
    rng = np.random.default_rng(0)
    pool = [random_world(rng) for _ in range(max(worlds_counts))]
    simulate(pool[:2], [0], 5)  # compile
    for count in worlds_counts:
        for n in threads:
            numba.set_num_threads(n)
            times = []
            for _ in range(repeats):
                start = time.perf_counter()
                outcome = simulate(pool[:count], range(5), 100)
                times.append(time.perf_counter() - start)
            median = statistics.median(times)
            steps, updates = int(outcome.ticks.sum()), int(outcome.updates.sum())
            rows.append(
                f"| {count} worlds x 5 sims x 100 ticks | {n} | {steps:,} | {median:.3f} | {steps / median:,.0f} | "
                f"{updates / median:,.0f} | {steps / median / ORIGINAL_HERE['steps_per_s']:,.0f}x |"
            )
    return rows


def generation_rows(generations: int, threads: int) -> list[str]:
    """Seconds per generation of the original's MAP-Elites, from the engine's own run loop (no files)."""
    from evolution.optimizers import MapElitesSettings
    from evolution.qd import map_elites
    from structgen.domains.fortress import engine
    from structgen.domains.fortress.problem import FortressProblem

    numba.set_num_threads(threads)
    problem = FortressProblem()
    optimizer = map_elites(problem, MapElitesSettings(cells=(100, 100), batch_size=10, immigrants=1, variation="problem"), 0)
    # The kernel's share of a generation: the goal is a generation whose Python costs no more than its simulations.
    kernel_s = [0.0]
    run_kernel = engine._run

    def timed_kernel(*args, **kwargs):
        start = time.perf_counter()
        run_kernel(*args, **kwargs)
        kernel_s[0] += time.perf_counter() - start

    engine._run = timed_kernel
    rows = []
    timings: list[float] = []
    kernel_timings: list[float] = []
    marks = {1, generations // 2, generations}
    try:
        for generation in range(1, generations + 1):
            start, kernel_s[0] = time.perf_counter(), 0.0
            genomes = optimizer.ask()
            evaluation = problem.evaluate(genomes, np.zeros(len(genomes), dtype=np.int64))
            optimizer.tell(evaluation.objective, evaluation.measures, **evaluation.fields)
            timings.append(time.perf_counter() - start)
            kernel_timings.append(kernel_s[0])
            if generation in marks and generation > 1:
                window = min(50, len(timings))
                mean, kernel = float(np.mean(timings[-window:])), float(np.mean(kernel_timings[-window:]))
                cells = len(optimizer.archive)
                rows.append(
                    f"| generations {generation - window + 1}-{generation} ({cells} cells filled) | {threads} | "
                    f"{mean:.4f} s | {kernel:.4f} s | {mean * 10_000 / 3600:.2f} h | "
                    f"{ORIGINAL_HERE['generation_s'] / mean:,.0f}x |"
                )
    finally:
        engine._run = run_kernel
    mean, kernel = float(np.mean(timings)), float(np.mean(kernel_timings))
    rows.append(
        f"| all {generations:,} generations | {threads} | {mean:.4f} s | {kernel:.4f} s | {mean * 10_000 / 3600:.2f} h | "
        f"{ORIGINAL_HERE['generation_s'] / mean:,.0f}x |"
    )
    return rows


def paper_run() -> str:
    """Time the paper's full run in a temporary folder (a first run after installing compiles the kernels: about a
    minute more, not counted here because a warm-up run of 20 generations compiles them first)."""
    config = Path(__file__).resolve().parents[1] / "configs" / "fortress_paper.toml"
    command = [sys.executable, "-m", "structgen", "evolve", str(config), "--seed", "20"]
    with tempfile.TemporaryDirectory() as scratch:
        subprocess.run([*command, "--run-dir", f"{scratch}/warm", "--set", "run.generations=20"], check=True, capture_output=True)
        folder = Path(scratch) / "paper"
        start = time.perf_counter()
        subprocess.run([*command, "--run-dir", str(folder)], check=True, capture_output=True)
        wall = time.perf_counter() - start
        rows = [json.loads(line) for line in (folder / "metrics.jsonl").read_text().splitlines()]
        size = sum(f.stat().st_size for f in folder.rglob("*") if f.is_file()) / 1e6
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1e6  # kilobytes on Linux
    run = rows[-1]["wall_s"]
    before = PAPER_RUN_BEFORE
    return "\n".join(
        [
            "| paper run (10,000 generations, seed 20) | run time | s per generation | wall time | peak memory | folder | best |",
            "|---|---:|---:|---:|---:|---:|---:|",
            f"| 6dc049b | {before['run_s']:.1f} s | {before['run_s'] / 10_000:.4f} | {before['wall_s'] / 60:.1f} min | "
            f"{before['peak_gb']} GB | {before['folder_mb']} MB | 0.913 |",
            f"| this version | {run:.1f} s | {run / 10_000:.4f} | {wall / 60:.1f} min | {peak:.2f} GB | {size:.0f} MB | "
            f"{max(r['best_objective'] for r in rows):.3f} |",
        ]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--worlds", type=int, nargs="+", default=[30, 200], help="worlds per batch (default 30 200)")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="numba threads (default 1 2)")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each engine row; the median is shown (default 3)")
    parser.add_argument("--generations", type=int, default=400, help="MAP-Elites generations to time (default 400)")
    parser.add_argument("--paper-run", action="store_true", help="also time the paper's full run (about 3 minutes)")
    args = parser.parse_args()
    print(
        f"machine: {platform.processor() or platform.machine()}, numba {numba.__version__}, {numba.config.NUMBA_NUM_THREADS} threads"
    )
    print()
    print("| workload | threads | fortress-steps | seconds | fortress-steps/s | entity updates/s | vs the original here |")
    print("|---|---|---|---|---|---|---|")
    print(f"| original (notes B8, AMD EPYC) | 1 | | | {ORIGINAL['steps_per_s']} | {ORIGINAL['updates_per_s']:,} | |")
    print(
        f"| original alone on its own worlds, this machine | 1 | 14,830 | 47.7 | {ORIGINAL_ALONE['steps_per_s']} | "
        f"{ORIGINAL_ALONE['updates_per_s']:,} | |"
    )
    print(
        f"| original in alternation with ours, this machine (anchors/fortress.py) | 1 | 4,951 | 63.1 | {ORIGINAL_HERE['steps_per_s']} | | 1x |"
    )
    for row in engine_rows(args.worlds, args.threads, args.repeats):
        print(row)
    print()
    print(
        "| MAP-Elites (9 mutants + 1 random, 5 x 100 ticks) | threads | s per generation | of which the 50 simulations | "
        "10,000 generations | vs the original here |"
    )
    print("|---|---|---|---|---|---|")
    print(f"| original (notes B8, AMD EPYC) | 1 | {ORIGINAL['generation_s']} s | | 139 h | |")
    here = ORIGINAL_HERE["generation_s"]
    print(
        f"| original, this machine (5,000 steps at {ORIGINAL_HERE['steps_per_s']}/s) | 1 | {here:.0f} s | | "
        f"{here * 10_000 / 3600:.0f} h | 1x |"
    )
    for window, seconds in BEFORE.items():
        print(
            f"| before worlds were arrays (c79a476), generations {window} | 2 | {seconds:.3f} s | | "
            f"{seconds * 10_000 / 3600:.2f} h | {here / seconds:,.0f}x |"
        )
    for row in generation_rows(args.generations, max(args.threads)):
        print(row)
    if args.paper_run:
        print()
        print(paper_run())


if __name__ == "__main__":
    main()
