"""The statics+bullet screen on what evolution meets first: random NCAs grown for one, two and five steps.

    python benchmarks/screen.py [--count 1000]

For each growth length, ``--count`` random NCAs (the paper's network and initial range, vertex cap 64); structures
that overflow the cap or stay a lone seed are left out, as are those statics says lose their support (no static
answer: they fall in PyBullet too). Each of the rest with its intact joints loaded to at most 2.5 times the break
force is simulated (fast preset). Prints how many stand in PyBullet, how many of those statics predicts to stand,
and, for several screen margins, how many structures the screen would simulate and how many of the standing ones
it would keep.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import numpy as np  # noqa: E402

from physics import PhysicsConfig, check_stability  # noqa: E402
from physics.statics import predict  # noqa: E402
from structgen import NCAConfig, grow_population  # noqa: E402
from structgen.nca import INIT_SCALE, n_params  # noqa: E402

MARGINS = (1.0, 1.1, 1.25, 1.5, 2.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--count", type=int, default=1000, help="random NCAs per growth length (default 1000)")
    args = parser.parse_args()
    fast = PhysicsConfig.preset("fast")
    started = time.perf_counter()
    rows = []  # (load ratio, statics says it stands, PyBullet says it stands)
    grown = 0
    for steps in (1, 2, 5):
        config = NCAConfig(max_vertices=64, iterations=steps)
        weights = np.random.default_rng(steps - 1).uniform(-INIT_SCALE, INIT_SCALE, size=(args.count, n_params(config)))
        for structure in grow_population(weights, config):
            if structure.n_vertices < 2 or structure.metadata["growth"]["hit_max_vertices"]:
                continue
            grown += 1
            prediction = predict(structure, fast)
            if np.isnan(prediction.first_loads).any():
                continue
            ratio = float(prediction.first_loads.max() / fast.break_force)
            if ratio > 2.5:
                continue
            rows.append((ratio, not prediction.broken.any(), check_stability(structure, fast).intact))
    standing = [r for r in rows if r[2]]
    print(f"{grown:,} structures of 2 to 64 vertices; {len(rows)} loaded to at most 2.5x the break force were simulated")
    print(f"{len(standing)} stand in PyBullet; statics predicts {sum(r[1] for r in standing)} of them to stand")
    print(f"({time.perf_counter() - started:.0f} s)\n")
    print("| screen margin | structures simulated | share of all | standing ones kept |")
    print("|---:|---:|---:|---:|")
    for margin in MARGINS:
        kept = [r for r in rows if r[1] or r[0] <= margin]
        print(f"| {margin:g} | {len(kept)} | {len(kept) / grown:.1%} | {sum(r[2] for r in kept)} of {len(standing)} |")


if __name__ == "__main__":
    main()
