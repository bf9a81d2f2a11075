"""Grow a trained NCA far beyond its training size and judge it: time and memory of growth, statics and PyBullet.

    python benchmarks/large.py RUN_DIR [--elite best] [--iterations 6 8 10 12 16] [--max-extent 40] [--bullet-max-joints 6000]

The NCA of a run (its settings, with more growth steps and a larger box) grows structures of hundreds to thousands
of vertices. Each size is measured in a fresh process, so its peak memory is its own: growth, the static analysis
(``physics.statics``), and the fast PyBullet preset on the sizes it can still do in reasonable time (its cap on joints
raised to ``--bullet-max-joints``; its first step costs time growing with the square of the joint count). Prints a
markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux reports kilobytes


def measure(run_dir: str, elite: str, iterations: int, max_extent: int, bullet_max_joints: int) -> dict:
    """One size, in this (fresh) process."""
    from dataclasses import replace

    from physics import check_stability, check_statics
    from structgen.nca import LocalNCA
    from structgen.runs import elite_genome, open_run

    folder, experiment = open_run(run_dir)
    config = replace(experiment.problem_settings.nca, iterations=iterations, max_extent=max_extent, max_vertices=10**6)
    problem = experiment.make_problem()
    nca = LocalNCA(elite_genome(folder, problem, elite), config)
    before = peak_mb()
    started = time.perf_counter()
    structure = nca.grow()
    grown = time.perf_counter() - started
    after_growth = peak_mb()
    physics = experiment.problem_settings.physics
    started = time.perf_counter()
    statics = check_statics(structure, physics)
    solved = time.perf_counter() - started
    row = {
        "iterations": iterations,
        "vertices": structure.n_vertices,
        "edges": structure.n_edges,
        "height": structure.height,
        "grow_s": grown,
        "grow_mb": after_growth - before,
        "statics_s": solved,
        "statics_mb": peak_mb() - after_growth,
        "statics_integrity": statics.integrity,
        "statics_height": statics.height,
        "rounds": statics.steps,
    }
    if 2 * structure.n_edges <= bullet_max_joints:
        started = time.perf_counter()
        simulated = check_stability(structure, replace(physics, max_joints=bullet_max_joints, max_vertices=10**6))
        row.update(bullet_s=time.perf_counter() - started, bullet_cpu_s=simulated.cpu_time, bullet_integrity=simulated.integrity)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", help="a structures run folder")
    parser.add_argument("--elite", default="best", help="best or index:I (default best)")
    parser.add_argument("--iterations", type=int, nargs="+", default=[6, 8, 10, 12, 16], help="growth steps to try")
    parser.add_argument("--max-extent", type=int, default=40, help="growth box half-width (default 40)")
    parser.add_argument(
        "--bullet-max-joints",
        type=int,
        default=6000,
        help="simulate with PyBullet only structures with at most this many joints (default 6000, about 40 s each; 0 skips PyBullet)",
    )
    parser.add_argument("--one", type=int, help=argparse.SUPPRESS)  # internal: measure one size in this process
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(measure(args.run_dir, args.elite, args.one, args.max_extent, args.bullet_max_joints)))
        return
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")), "?")
    print(f"machine: {cpu}, {os.cpu_count()} cores; Python {platform.python_version()}; run {args.run_dir} ({args.elite})\n")
    print(
        "| steps | vertices | edges | height | grow s | grow MB | statics s | statics MB | failure rounds | statics I | PyBullet fast s (CPU) | PyBullet I |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for iterations in args.iterations:
        command = [sys.executable, __file__, args.run_dir, "--elite", args.elite, "--one", str(iterations)]
        command += ["--max-extent", str(args.max_extent), "--bullet-max-joints", str(args.bullet_max_joints)]
        done = subprocess.run(command, capture_output=True, text=True, check=True)
        r = json.loads(done.stdout.strip().splitlines()[-1])
        bullet = (
            f"{r['bullet_s']:.1f} ({r['bullet_cpu_s']:.1f})"
            if "bullet_s" in r
            else f"not run (> {args.bullet_max_joints:,} joints)"
        )
        bullet_i = f"{r['bullet_integrity']:.3f}" if "bullet_s" in r else "-"
        print(
            f"| {iterations} | {r['vertices']:,} | {r['edges']:,} | {r['height']} | {r['grow_s']:.2f} | {r['grow_mb']:.0f} "
            f"| {r['statics_s']:.2f} | {r['statics_mb']:.0f} | {r['rounds']} | {r['statics_integrity']:.3f} | {bullet} | {bullet_i} |"
        )


if __name__ == "__main__":
    main()
