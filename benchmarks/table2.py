"""The warehouse paper's Table 2 from a generator trained here: its layout at 33x36 with 200 robots and grown at
101x102 with the robot count of the paper's configuration, judged with `pbs` as the paper's tables are, beside the
paper's numbers.

    python benchmarks/table2.py WEIGHTS.npy [--kind even|uneven|manufacturing] [--simulations 10] [--steps 5000]
        [--sizes 33x36,101x102] [--robots N] [--repair-time-limit 120] [--workers 2] [--papers] [--tiling]
        [--output DIR]

The robot counts: 200 at 33x36 (``agent_num = 200`` in every training configuration of the paper's repository);
1,000 at 101x102, the only count that repository gives for that size (``agent_num=1000`` for ``xxlarge`` in
``env_search/warehouse/generator/offline_run_nca_generator.py`` and in
``env_search/analysis/gen_tile_baseline_env.py``, which makes the tiling baseline the paper runs "with the agents
specified in Table 1"). The paper's Table 1 itself did not survive into the text we have. ``--robots`` runs another
count at 101x102; the counts at which `pbs` gives the paper's 101x102 throughputs on its own layouts (1,400 even,
1,000 uneven, 1,800 manufacturing) were found by matching and are not the paper's configuration.

WEIGHTS is a generator's NCA weights (a run's `best/genome.npy`, or `docs/layout_runs/even_generator.npy`). It grows
50 NCA steps at 33x36 and 200 at 101x102 (the paper's rule), is repaired (at 33x36 as training repairs it; at
101x102 with `--repair-time-limit` seconds of the default repair) and simulated `--simulations` times for `--steps`
steps with `pbs`. `--tiling` adds the paper's tiling baseline (our 33x36 layout repeated to fill 101x102, repaired
the same way). `--papers` also re-simulates the paper's own trained layouts the same way (needs the original's
maps: $STRUCTGEN_REFERENCE_DATA). `--output` keeps our repaired layouts and the table as JSON.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evolution.files import atomic_write
from structgen.domains.layouts.grid import Grid
from structgen.domains.layouts.kinds import MANUFACTURING, WAREHOUSE, reference_maps
from structgen.domains.layouts.problem import LayoutProblem, ManufacturingSettings, WarehouseSettings
from structgen.domains.layouts.repair import REPAIR_GREEDY_BEYOND, repair
from structgen.domains.layouts.warehouse.simulator import evaluate_layout

OURS = "warehouse/ours/nca_to_show"


@dataclass(frozen=True)
class Row:
    """One domain of Table 2: its robot count at 101x102 and the paper's figures and layouts."""

    settings: type
    uneven: bool
    large_robots: int  # the paper's configuration's count at 101x102 (the module's description says where from)
    paper_small: float  # throughput at 33x36 with 200 robots
    paper_large: tuple[float, float]  # success rate and throughput at 101x102
    paper_small_map: str
    paper_large_map: str


ROWS = {
    "even": Row(
        WarehouseSettings,
        False,
        1000,
        6.74,
        (0.90, 16.01),
        f"{OURS}/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_throughput_hamming_a=5.json",
        f"{OURS}/xxlarge_maps/iter=200/kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5.json",
    ),
    "uneven": Row(
        WarehouseSettings,
        True,
        1000,
        6.82,
        (0.84, 12.03),
        f"{OURS}/cma_mae/kiva_large_200_agents_cma-mae_opt_entropy_uneven_throughput_hamming_a=5.json",
        f"{OURS}/xxlarge_maps/iter=200/kiva_xxlarge_cma-mae_global_opt_repaired_one_endpt_uneven_throughput-hamming_a=5.json",
    ),
    "manufacturing": Row(
        ManufacturingSettings,
        False,
        1000,
        6.82,
        (1.00, 23.11),
        "manufacture/ours/nca_to_show/manufacture_large_200_agents_cma-mae_opt_alpha=5_sw=5.json",
        "manufacture/ours/xxlarge/"
        "manufacture_xxlarge_cma-mae_global_opt_repaired_one_endpt_throughput-hamming_a=5_sw=5_iter=200.json",
    ),
}


def grow_and_repair(weights: np.ndarray, row: Row, size: str, robots: int, time_limit: float) -> dict:
    """Our layout at ``size``: grown for the paper's steps there and repaired; at 33x36 as training repairs it."""
    problem = LayoutProblem(row.settings(size=size, agents=robots))
    if size == "33x36":
        return _repaired(problem, problem.grow(weights[None])[0], robots, 60.0, REPAIR_GREEDY_BEYOND)
    return _repaired(problem, problem.grow(weights[None])[0], robots, time_limit)


def tile_and_repair(small: np.ndarray, row: Row, robots: int, time_limit: float, size: str = "101x102") -> dict:
    """The paper's tiling baseline: our trained 33x36 layout repeated to fill ``size``, then repaired."""
    problem = LayoutProblem(row.settings(size=size, agents=robots))
    return _repaired(problem, problem.kind.tiled(small, size), robots, time_limit)


def _repaired(problem: LayoutProblem, tiles: np.ndarray, robots: int, time_limit: float, greedy_beyond=None) -> dict:
    began = time.perf_counter()
    result = repair(
        tiles,
        problem.kind,
        shelves=problem.shelves if problem.kind is WAREHOUSE else None,
        agents=robots if problem.kind is MANUFACTURING else 0,
        time_limit=time_limit,
        greedy_beyond=greedy_beyond,
    )
    return {
        "kind": problem.kind,
        "tiles": result.tiles,
        "changed": result.hamming,
        "method": result.method,
        "repair_seconds": round(time.perf_counter() - began, 1),
    }


def judge(tiles: np.ndarray, kind, robots: int, row: Row, args) -> dict:
    result = evaluate_layout(
        tiles,
        robots,
        args.simulations,
        args.steps,
        kind=kind,
        planner="pbs",
        uneven=row.uneven,
        workers=args.workers,
        progress=True,
    )
    return {
        "robots": robots,
        "successes": result.successes,
        "simulations": result.simulations,
        "throughput": result.mean,
        "standard_error": result.standard_error,
        "seconds": round(result.seconds, 1),
    }


def cell(judged: dict) -> str:
    if judged["throughput"] is None:
        return f"0 of {judged['simulations']}, N/A"
    return f"{judged['successes']} of {judged['simulations']}, {judged['throughput']:.3f} ± {judged['standard_error']:.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("weights", type=Path, metavar="WEIGHTS.npy", help="the generator's NCA weights (1-D .npy)")
    parser.add_argument("--kind", choices=tuple(ROWS), default="even", help="which row of Table 2 (default even)")
    parser.add_argument("--simulations", type=int, default=10, help="runs per layout (default 10; the paper ran 50)")
    parser.add_argument("--steps", type=int, default=5000, help="steps per run (default 5000, as the paper)")
    parser.add_argument("--robots", type=int, default=None, help="robots at 101x102 (default 1,000, the paper's configuration's)")
    parser.add_argument("--repair-time-limit", type=float, default=120.0, help="seconds for the 101x102 repair (default 120)")
    parser.add_argument("--workers", type=int, default=2, help="processes that share the runs (default 2)")
    parser.add_argument(
        "--sizes", default="33x36,101x102", help="which of the two sizes, comma-separated (default 33x36,101x102)"
    )
    parser.add_argument("--papers", action="store_true", help="also re-simulate the paper's own layouts the same way")
    parser.add_argument(
        "--tiling", action="store_true", help="add the tiling baseline: our 33x36 layout tiled to 101x102 and repaired"
    )
    parser.add_argument("--output", type=Path, default=None, metavar="DIR", help="keep our layouts and the table here")
    args = parser.parse_args()
    row = ROWS[args.kind]
    weights = np.load(args.weights)
    maps = reference_maps()
    if args.papers and maps is None:
        parser.error("--papers needs the original's maps: set $STRUCTGEN_REFERENCE_DATA")
    wanted = args.sizes.split(",")
    if unknown := [size for size in wanted if size not in ("33x36", "101x102")]:
        parser.error(f"--sizes: {', '.join(unknown)}: Table 2 has 33x36 and 101x102")
    large_robots = row.large_robots if args.robots is None else args.robots
    sizes = [("33x36", 200, row.paper_small, None), ("101x102", large_robots, row.paper_large[1], row.paper_large[0])]
    sizes = [entry for entry in sizes if entry[0] in wanted]
    if args.tiling:
        sizes.append(("101x102 tiled", large_robots, row.paper_large[1], row.paper_large[0]))
    table = []
    small = None
    for size, robots, paper_throughput, paper_success in sizes:
        if size.endswith("tiled"):
            if small is None:  # the tiling repeats our 33x36 layout even where its row was not asked for
                small = grow_and_repair(weights, row, "33x36", 200, args.repair_time_limit)["tiles"]
            ours = tile_and_repair(small, row, robots, args.repair_time_limit)
        else:
            ours = grow_and_repair(weights, row, size, robots, args.repair_time_limit)
            small = ours["tiles"] if size == "33x36" else small
        entry = {
            "size": size,
            "repair": {k: ours[k] for k in ("changed", "method", "repair_seconds")},
            "ours": judge(ours["tiles"], ours["kind"], robots, row, args),
            "paper": {"success_rate": paper_success, "throughput": paper_throughput},
        }
        if args.papers and not size.endswith("tiled"):
            path = maps / (row.paper_small_map if size == "33x36" else row.paper_large_map)
            entry["papers_layout_here"] = judge(Grid.load(path, ours["kind"].vocabulary).tiles, ours["kind"], robots, row, args)
        if args.output is not None:
            args.output.mkdir(parents=True, exist_ok=True)
            Grid(ours["tiles"], ours["kind"].vocabulary, {"size": size, "weights": str(args.weights)}).save(
                args.output / f"{args.kind}_{size.replace(' ', '_')}.json"
            )
        table.append(entry)
        print(f"{size} done: {cell(entry['ours'])}", flush=True)
    print(
        f"\nTable 2, {args.kind}: `pbs`, {args.simulations} runs of {args.steps} steps (the paper: 50 of 5,000); "
        f"{platform.processor() or platform.machine()}, {time.strftime('%Y-%m-%d')}\n"
    )
    print(
        "| size | robots | cells the repair changed | ours: success, throughput | "
        + ("paper's layout here | " if args.papers else "")
        + "paper | ours / paper |"
    )
    print("|---|---:|---|---|" + ("---|" if args.papers else "") + "---|---:|")
    for entry in table:
        paper = entry["paper"]
        paper_text = (
            f"{paper['success_rate']:.0%}, " if paper["success_rate"] is not None else ""
        ) + f"{paper['throughput']:.2f}"
        ours = entry["ours"]
        ratio = "" if ours["throughput"] is None else f"{ours['throughput'] / paper['throughput']:.3f}"
        papers = f" {cell(entry['papers_layout_here'])} |" if "papers_layout_here" in entry else (" |" if args.papers else "")
        repair_text = f"{entry['repair']['changed']:,} ({entry['repair']['method']}, {entry['repair']['repair_seconds']} s)"
        print(f"| {entry['size']} | {ours['robots']:,} | {repair_text} | {cell(ours)} |{papers} {paper_text} | {ratio} |")
    if args.output is not None:
        text = json.dumps({"kind": args.kind, "weights": str(args.weights), "rows": table}, indent=1)
        atomic_write(args.output / f"{args.kind}_table2.json", text)


if __name__ == "__main__":
    main()
