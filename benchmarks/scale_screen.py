"""Which of a training run's generators grow large layouts that still carry the paper's robots: a screen of the
archive's elites at 101x102 (the paper shows one generator; ours, the best by training's objective, jams there).

    python benchmarks/scale_screen.py RUN_DIR [--candidates 40] [--size 101x102] [--robots N (default: the paper's count, table2.py)] [--steps 500]
        [--planner pp] [--workers 2] [--repair-time-limit 120] [--json OUT.json] [--weights-out WINNER.npy]

The archive's cells are grouped into blocks of 10x10; the elite of highest training objective (throughput plus
alpha times the similarity to its repaired layout) in each block is a candidate, the ``--candidates`` best of them
are grown for the size's NCA steps, repaired as Table 2 repairs them and simulated once for ``--steps`` steps with
``--robots`` robots (one run is a screen, not a verdict: judge the winner with ``table2.py WINNER.npy``). Prints one
row per candidate, best first; ``--weights-out`` keeps the weights of the candidate that did not congest and moved
the most (none is written when every candidate congests).
"""

from __future__ import annotations

import argparse
import functools
import json
import platform
import time
from pathlib import Path

import numpy as np
from table2 import ROWS, grow_and_repair  # the script beside this one

from evolution.files import atomic_write
from evolution.pool import Lost, WorkerPool
from structgen.domains.layouts.problem import LayoutProblem
from structgen.domains.layouts.warehouse.simulator import PLANNERS, simulate
from structgen.nca import save_weights
from structgen.runs import open_run

BLOCK = 10  # archive cells per side of a block: one candidate per block keeps the screen spread over the archive


def candidates(archive, alpha: float, count: int) -> list[int]:
    """Rows of the archive: the best elite by training's objective in each block of cells, the ``count`` best."""
    objective = archive.columns["throughput"] + alpha * archive.columns["similarity"]
    best: dict[tuple[int, ...], int] = {}
    for row, cell in enumerate(map(tuple, archive.cells // BLOCK)):
        if cell not in best or objective[row] > objective[best[cell]]:
            best[cell] = row
    return sorted(best.values(), key=lambda row: -objective[row])[:count]


def screen_one(kind: str, size: str, robots: int, steps: int, planner: str, time_limit: float, genome) -> dict:
    row = ROWS[kind]
    repaired = grow_and_repair(np.asarray(genome), row, size, robots, time_limit)
    began = time.perf_counter()
    run = simulate(repaired["tiles"], robots, steps, kind=repaired["kind"], planner=planner, uneven=row.uneven, seed=0)
    return {
        "changed": int(repaired["changed"]),
        "method": repaired["method"],
        "throughput": float(run.throughput),
        "congested": bool(run.congested),
        "seconds": round(repaired["repair_seconds"] + time.perf_counter() - began, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", type=Path, help="a warehouse or manufacturing CMA-MAE run folder")
    parser.add_argument("--kind", choices=sorted(ROWS), default="even", help="the run's domain (default even)")
    parser.add_argument("--candidates", type=int, default=40, help="elites to screen (default 40)")
    parser.add_argument("--size", default="101x102", help="the size to grow at (default 101x102)")
    parser.add_argument("--robots", type=int, help="robots (default: the paper's count at 101x102 for the kind)")
    parser.add_argument("--steps", type=int, default=500, help="simulated steps of the one screening run (500)")
    parser.add_argument("--planner", choices=PLANNERS, default="pp", help="the screening run's planner (default pp)")
    parser.add_argument("--workers", type=int, default=2, help="processes that share the candidates (default 2)")
    parser.add_argument("--repair-time-limit", type=float, default=120.0, help="seconds for each repair (120)")
    parser.add_argument("--json", type=Path, help="also write every candidate's result to this file")
    parser.add_argument("--weights-out", type=Path, help="write the winner's NCA weights (.npy) here")
    args = parser.parse_args()
    if args.candidates < 1 or args.workers < 0 or args.steps < 1:
        parser.error("--candidates and --steps must be positive, --workers 0 or more")
    if args.robots is not None and args.robots < 1:
        parser.error(f"--robots must be positive, got {args.robots}")
    if not args.repair_time_limit > 0:
        parser.error(f"--repair-time-limit must be positive seconds, got {args.repair_time_limit}")
    robots = args.robots or ROWS[args.kind].large_robots

    folder, experiment = open_run(args.run)
    problem = experiment.make_problem()
    archive = folder.load_archive(problem)
    large = LayoutProblem(ROWS[args.kind].settings(size=args.size, agents=robots))
    if archive.genomes.shape[1] != large.n_params:
        raise SystemExit(
            f"{args.run}: its genomes have {archive.genomes.shape[1]} weights, the paper's NCA {large.n_params}: "
            "the screen grows the paper's NCA (its hidden channels) and cannot grow this run's"
        )
    chosen = candidates(archive, problem.settings.alpha, args.candidates)
    job = functools.partial(screen_one, args.kind, args.size, robots, args.steps, args.planner, args.repair_time_limit)
    from tqdm import tqdm

    began = time.perf_counter()
    with tqdm(total=len(chosen), desc="candidates", unit="layout") as bar, WorkerPool(args.workers) as pool:
        screened = pool.map(job, [archive.genomes[row] for row in chosen], done=lambda _: bar.update())
    results = []
    for row, result in zip(chosen, screened):
        if isinstance(result, Lost):
            raise SystemExit(f"candidate {row}: {result.reason}")
        fields = {name: float(archive.columns[name][row]) for name in ("throughput", "similarity", "hamming")}
        measures = dict(zip(archive.measure_names, map(float, archive.measures[row])))
        results.append({"row": row, "at_33x36": fields, "measures": measures, args.size: result})
    results.sort(key=lambda r: (r[args.size]["congested"], -r[args.size]["throughput"]))

    print(
        f"| archive row | measures | 33x36 throughput, similarity | cells repaired at {args.size} | {robots} robots, "
        f"{args.steps} steps ({args.planner}) |"
    )
    print("|---:|---|---|---|---|")
    for r in results:
        big = r[args.size]
        state = "congested" if big["congested"] else "moving"
        measures = ", ".join(f"{value:g}" for value in r["measures"].values())
        print(
            f"| {r['row']} | {measures} | {r['at_33x36']['throughput']:.2f}, {r['at_33x36']['similarity']:.2f} | "
            f"{big['changed']} ({big['method']}) | {big['throughput']:.2f}, {state} |"
        )
    moving = [r for r in results if not r[args.size]["congested"]]
    print(
        f"{len(moving)} of {len(results)} candidates kept moving; {time.perf_counter() - began:.0f} s on "
        f"{args.workers} worker(s), {platform.processor() or platform.machine()}"
    )
    if args.weights_out is not None and moving:
        save_weights(args.weights_out, archive.genomes[moving[0]["row"]])
        print(f"the winner (archive row {moving[0]['row']}) -> {args.weights_out}")
    if args.json is not None:
        report = {
            "run": str(args.run),
            "size": args.size,
            "robots": robots,
            "steps": args.steps,
            "planner": args.planner,
            "candidates": results,
        }
        atomic_write(args.json, json.dumps(report, indent=1) + "\n")


if __name__ == "__main__":
    main()
