"""Refine a grown structure that nearly stands: CMA-ES on the NCA's weights, judged by the transient the faithful
simulation sees while the structure takes up its weight (or, to bring a far-off start near first, by statics).

    python benchmarks/tall_refine.py START.npy [--levels 5] [--max-vertices 200] [--judge transient|statics]
        [--generations 70] [--sigma 0.01] [--seed 0] [-o BEST.npy]

``START.npy`` holds the weights of an NCA grown with the settings of ``configs/tall.toml`` (ten steps, cutoff 0.6, no
building down, at most 200 vertices unless ``--max-vertices`` says otherwise), such as a near-miss elite of that
run. Each generation grows 16 weight vectors around the current mean and scores each structure by the largest force
any joint carries in the first 0.3 s of the faithful preset with joints that cannot break (plus a fiftieth of the
mean of that peak and the nineteen largest forces at the end, so that ties go to the structure with less load
elsewhere); a structure less than ``--levels`` vertices tall, or one that falls, scores far worse than any that is
tall enough.

``--judge statics`` scores by the static loads instead, the larger of held and sliding ground
(``physics.statics.bounding_loads``; largest plus a fiftieth of the mean of the twenty largest), about a hundred
times cheaper. It cannot finish the job: held ground alone lowered its own prediction on the tall run's elites from
60 to 46 N while the simulated peak rose from 60 to 65 N, and even the bound misses the transient. It serves to
bring a start whose structure is far from standing (a taller growth of a shorter NCA) near enough for the
transient stage.

Every generation that improves on the best prints a line; the best weights are written to ``-o`` as they improve, and
at the end the best structure gets the faithful verdict (30 s, joints that break above 52.5 N), unless its transient
peak is already over the break force: then it breaks, as the breakable simulation takes the same steps until then.
``structgen evolve configs/tall_six_refine.toml`` does the transient stage as a run (the ``transient`` evaluator,
Q with the strength ratio instead of integrity), with checkpoints and ``structgen resume``. Deterministic on one
machine: the same arguments give the same generations.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

# Run as a script, this file's folder comes first on sys.path, and benchmarks/physics.py would shadow the physics package.
sys.path = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]

import cma  # noqa: E402
import numpy as np  # noqa: E402

from evolution.pool import Lost, WorkerPool  # noqa: E402
from physics import PhysicsConfig, check_stability, check_transient  # noqa: E402
from physics.statics import bounding_loads  # noqa: E402
from structgen.nca import NCAConfig, grow_population, load_weights, save_weights  # noqa: E402
from structgen.structure import Structure  # noqa: E402

#: The growth rules of configs/tall.toml.
TALL = NCAConfig(iterations=10, cutoff=0.6, build_down=False, max_vertices=200)
POPULATION = 16
TOO_SHORT, FELL = 1000.0, 500.0


def rate(job: tuple[np.ndarray, np.ndarray, int, str]) -> tuple[float, float]:
    """(score, largest joint force) of one structure by the chosen judge: lower is better."""
    vertices, edges, levels, judge = job
    top = int(vertices[:, 2].max())
    if top < levels - 1:
        return TOO_SHORT - 100 * top, math.nan
    structure = Structure(vertices, edges, {})
    if judge == "statics":
        loads = bounding_loads(structure, PhysicsConfig())
        if np.isnan(loads).any():
            return FELL, math.nan
        largest = np.sort(loads)[::-1]
        return float(largest[0] + 0.02 * largest[:20].mean()), float(largest[0])
    report = check_transient(structure, PhysicsConfig(), window=0.3)
    if report.exploded or report.error or report.height < top - 0.5:
        return FELL, math.nan
    final = np.sort(report.joint_forces)[::-1]
    return float(report.peak_force + 0.02 * np.concatenate([[report.peak_force], final])[:20].mean()), report.peak_force


def levels_of(structure: Structure) -> list[int]:
    return np.bincount(structure.vertices[:, 2]).tolist()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("start", metavar="START.npy", help="weights to start from (.npy or .json)")
    parser.add_argument("--levels", type=int, default=5, help="how many vertices tall a structure must be (default 5)")
    parser.add_argument(
        "--max-vertices",
        type=int,
        default=TALL.max_vertices,
        help=f"growth stops at this many vertices (default {TALL.max_vertices}, as in configs/tall.toml); a taller "
        "structure needs room to grow",
    )
    parser.add_argument(
        "--judge",
        choices=("transient", "statics"),
        default="transient",
        help="transient (default): the faithful simulation's first 0.3 s; statics: the static loads, the larger of "
        "held and sliding ground (a hundred times cheaper, to bring a far-off start near before the transient stage)",
    )
    parser.add_argument("--generations", type=int, default=70, help="CMA-ES generations of 16 (default 70)")
    parser.add_argument("--sigma", type=float, default=0.01, help="CMA-ES initial step size (default 0.01)")
    parser.add_argument("--seed", type=int, default=0, help="CMA-ES seed (default 0)")
    parser.add_argument("-o", "--output", default="refined.npy", help="where the best weights go (default refined.npy)")
    parser.add_argument("--workers", type=int, default=2, help="processes that simulate (default 2)")
    args = parser.parse_args()
    if args.generations < 1:
        parser.error(f"--generations must be at least 1, got {args.generations}")
    if args.max_vertices < args.levels:
        parser.error(f"--max-vertices must be at least --levels ({args.levels}), got {args.max_vertices}")
    growth = dataclasses.replace(TALL, max_vertices=args.max_vertices)

    try:
        start = load_weights(args.start, growth)
    except ValueError as err:  # the file gate's errors name the file and what is wrong
        parser.error(str(err))
    strategy = cma.CMAEvolutionStrategy(
        start, args.sigma, {"popsize": POPULATION, "CMA_diagonal": True, "seed": args.seed + 1, "verbose": -9}
    )
    best = (math.inf, math.nan, start, None, 0)
    began = time.perf_counter()
    with WorkerPool(args.workers) as pool:
        for generation in range(1, args.generations + 1):
            asked = strategy.ask()
            structures = grow_population(np.array(asked), growth)
            jobs = [(s.vertices, s.edges, args.levels, args.judge) for s in structures]
            # A structure whose worker died scores as one that fell.
            results = [(FELL, math.nan) if isinstance(r, Lost) else r for r in pool.map(rate, jobs)]
            scores = [score for score, _ in results]
            strategy.tell(asked, scores)
            i = int(np.argmin(scores))
            if scores[i] < best[0]:
                best = (scores[i], results[i][1], np.array(asked[i]), structures[i], generation)
                save_weights(args.output, best[2])
                print(
                    f"generation {generation}: {args.judge} {best[1]:.1f} N, {structures[i].n_vertices} vertices, levels "
                    f"{levels_of(structures[i])}, {time.perf_counter() - began:.0f} s",
                    flush=True,
                )
    structure = best[3]
    # A transient run already measured its best's peak; a statics run has not simulated it yet.
    peak = best[1] if args.judge == "transient" else rate((structure.vertices, structure.edges, args.levels, "transient"))[1]
    if peak > PhysicsConfig().break_force:
        # The simulation with breakable joints takes the same steps until the first joint breaks, so a peak over the
        # break force settles the verdict; the 30 s would take minutes for a large structure.
        print(f"best: generation {best[4]}, transient peak {peak:.1f} N, over the break force: it breaks", flush=True)
        verdict, height = "breaks (its transient peak is over the break force)", "-"
    else:
        print(f"best: generation {best[4]}, transient peak {peak:.1f} N; the faithful verdict (30 s) ...", flush=True)
        report = check_stability(structure, PhysicsConfig())
        verdict, height = report.verdict(), f"{report.height:.3f}"
    print(
        f"| start | judge | generations | best at | its score's force | transient peak | vertices | edges | levels | "
        f"faithful 30 s | height |\n"
        f"|---|---|---:|---:|---:|---:|---:|---:|---|---|---:|\n"
        f"| {args.start} | {args.judge} | {args.generations} | {best[4]} | {best[1]:.1f} N | {peak:.1f} N | "
        f"{structure.n_vertices} | {structure.n_edges} | {levels_of(structure)} | {verdict} | {height} |"
    )


if __name__ == "__main__":
    main()
