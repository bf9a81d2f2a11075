"""What a fresh PyBullet world's first step costs, and what emptying the world instead of resetting it saves.

    python benchmarks/first_step.py [--sizes 2 3 4] [--count 2]

Bullet grows its constraint solver's buffers one row at a time on a world's first step, so that step costs time
growing with the square of the joint count; ``physics.bullet`` empties its world between structures and keeps the
buffers. This grows random networks' structures (no building down, cutoff 0.5) for each number of growth steps,
times the first step in a fresh world and in an emptied one that held a larger structure before, and times the
fast preset's whole check both ways. Prints a markdown table (CPU seconds of this process).
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig, bullet  # noqa: E402
from physics.model import place, read_structure  # noqa: E402
from structgen.nca import NCAConfig, grow_population, n_params  # noqa: E402


def _timed_first_step(client: bullet._Client, bodies, config: PhysicsConfig) -> float:
    bullet._build(client, bodies, config)
    started = time.process_time()
    client.pb.stepSimulation(physicsClientId=client.id)
    return time.process_time() - started


def _timed_check(client: bullet._Client, bodies, config: PhysicsConfig) -> float:
    started = time.process_time()
    handles = bullet._build(client, bodies, config)
    bullet._run(client, bodies, handles, config)
    return time.process_time() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2, 3, 4], help="growth steps of the structures")
    parser.add_argument("--count", type=int, default=2, help="structures per size")
    args = parser.parse_args()
    config = PhysicsConfig.preset("fast")
    structures = []
    for steps in args.sizes:
        nca = NCAConfig(max_vertices=2**31 - 1, build_down=False, iterations=steps)
        genomes = np.random.default_rng(steps).uniform(-0.25, 0.25, size=(args.count, n_params(nca)))
        structures += grow_population(genomes, nca)
    largest = max(structures, key=lambda s: s.n_edges)
    print(f"machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}")
    print("| vertices | joints | first step, fresh world | first step, emptied world | fast check, fresh | fast check, emptied |")
    print("|---:|---:|---:|---:|---:|---:|")
    for structure in structures:
        bodies = place(*read_structure(structure), config, enforce_caps=False)
        timings = []
        for measure in (_timed_first_step, _timed_check):
            fresh = bullet._Client()  # a world that never held anything
            cost_fresh = measure(fresh, bodies, config)
            fresh.pb.disconnect(physicsClientId=fresh.id)
            bullet.simulate(place(*read_structure(largest), config, enforce_caps=False), config.replace(horizon=config.timestep))
            warm = bullet._this_process_client()
            timings.append((cost_fresh, measure(warm, bodies, config)))
        (step_fresh, step_warm), (check_fresh, check_warm) = timings
        print(
            f"| {structure.n_vertices:,} | {2 * structure.n_edges:,} | {step_fresh:.2f} s | {step_warm:.3f} s | "
            f"{check_fresh:.1f} s | {check_warm:.1f} s |"
        )


if __name__ == "__main__":
    main()
