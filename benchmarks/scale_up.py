"""Train small, grow large, as the paper's Appendix E.3 measures it: generators trained at 33x36 grown at each of the
paper's sizes, repaired, and swept over robot counts beside the paper's grown layouts, the human ones and the tiling
baseline; per size and layout, the highest mean throughput and the robot count where it is reached.

    python benchmarks/scale_up.py [NAME=]WEIGHTS.npy ... [--kind even|uneven] [--sizes 33x36,...,101x102]
        [--planner pbs] [--steps 1000] [--seeds 3] [--workers 2] [--repair-time-limit 120] [--no-tiling]
        [--layouts DIR] [--json OUT.json] [--output docs/scale_up.png]
    python benchmarks/scale_up.py --redraw OUT.json [--output docs/scale_up.png]
    python benchmarks/scale_up.py NAME=WEIGHTS.npy --add-to OUT.json [--output docs/scale_up.png]

Each WEIGHTS is a generator's NCA weights (`docs/layout_runs/even_generator.npy`; a CMA-ES baseline's beside it, as
`cma-es=FILE.npy`). It grows the size's NCA steps (50, 200 at 101x102) and is repaired (at 33x36 as training
repairs it, above with `--repair-time-limit` seconds of the default repair). The first generator's 33x36 layout,
tiled to each larger size and repaired, is the tiling baseline. Robot counts go up in steps of 50 per 33x36's area
(50, 100, ... at 33x36; 450, 900, ... at 101x102) until the mean throughput (over `--seeds` runs, congested ones
counted with what they reached) has fallen below its best twice or every run congests. Needs the original's maps
($STRUCTGEN_REFERENCE_DATA) for the paper's and the human layouts. Prints one table, draws the paper's two panels
(highest mean throughput, and the robot count there, against size) and, with `--json`, keeps every point (after
each size, so a sweep stopped part way keeps what it measured; `--redraw` draws the panels from it). `--add-to`
measures only the named generators, with the kept JSON's kind, planner, steps, runs and sizes, and adds their rows to
it (a baseline trained later joins the figure without measuring the rest again).
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
from table2 import ROWS, grow_and_repair, tile_and_repair  # the script beside this one

from evolution.files import InputFileError, MiB, atomic_write, read_json
from evolution.plots import figure_png, new_figure
from structgen.domains.layouts.grid import Grid
from structgen.domains.layouts.kinds import WAREHOUSE, reference_maps
from structgen.domains.layouts.warehouse.simulator import PLANNERS, evaluate_layout

SIZES = ("33x36", "45x47", "57x58", "69x69", "81x80", "93x91", "101x102")
OURS = "warehouse/ours/nca_to_show/cma_mae"


def papers_layout(size: str, uneven: bool) -> str:
    """The paper's CMA-MAE (alpha 5) layout of ``size``, relative to the original's maps."""
    variant = "entropy_uneven_throughput_hamming_a=5" if uneven else "entropy_throughput_hamming_a=5"
    if size == "33x36":
        return f"{OURS}/kiva_large_200_agents_cma-mae_opt_{variant}.json"
    if size == "101x102":
        return ROWS["uneven" if uneven else "even"].paper_large_map
    return f"{OURS}/additional_eval/kiva_{size}_cma-mae_opt_{variant}.json"


def human_layout(size: str) -> str:
    if size == "33x36":
        return "warehouse/human/kiva_large_w_mode.json"
    if size == "101x102":
        return "warehouse/human/kiva_xxlarge_w_mode.json"
    return f"warehouse/human/additional_eval/kiva_human_{size}_w_mode.json"


def robot_step(size: str) -> int:
    """50 robots per 33x36's storage area, rounded to 50."""
    rows, cols = WAREHOUSE.size(size).grown
    return max(50, int(round(50 * rows * cols / (33 * 32) / 50)) * 50)


def sweep(tiles: np.ndarray, size: str, uneven: bool, args) -> list[dict]:
    """Robot counts up in :func:`robot_step`s until the mean has fallen below its best twice or every run jams."""
    points: list[dict] = []
    best, falls, robots = -1.0, 0, 0
    free = int((~np.isin(tiles, WAREHOUSE.blocking_tiles())).sum())
    while falls < 2:
        robots += robot_step(size)
        if robots > free // 2:
            break
        result = evaluate_layout(tiles, robots, args.seeds, args.steps, planner=args.planner, uneven=uneven, workers=args.workers)
        mean = float(result.throughputs.mean())
        points.append({"robots": robots, "mean": mean, "successes": result.successes, "runs": result.simulations})
        if result.successes == 0:
            break
        falls = 0 if mean > best else falls + 1
        best = max(best, mean)
    return points


def draw(results: dict[str, dict[str, dict]], kind: str, planner: str, steps: int, output: Path) -> None:
    """The paper's two panels: per size, each layout's highest mean throughput and the robot count there."""
    sizes = [size for size in SIZES if size in results]
    figure = new_figure(figsize=(11, 4.2), layout="constrained")
    left, right = figure.subplots(1, 2)
    labels = list(dict.fromkeys(label for size in sizes for label in results[size]))
    for label in labels:
        xs = [size for size in sizes if label in results[size]]
        left.plot(xs, [results[s][label]["best"]["mean"] for s in xs], marker="o", label=label)
        right.plot(xs, [results[s][label]["best"]["robots"] for s in xs], marker="o", label=label)
    for ax, what in ((left, "highest mean throughput"), (right, "robots at the highest throughput")):
        ax.set_xlabel("map size")
        ax.set_ylabel(what)
        ax.grid(alpha=0.3)
        ax.tick_params(axis="x", rotation=30)
    left.legend(fontsize=8)
    figure.suptitle(f"warehouse ({kind}): trained at 33x36, grown larger; {planner}, {steps:,} steps")
    atomic_write(output, figure_png(figure, 110))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("generators", nargs="*", metavar="[NAME=]WEIGHTS.npy", help="generators' NCA weights")
    parser.add_argument("--kind", choices=("even", "uneven"), default="even", help="which warehouse (default even)")
    parser.add_argument("--sizes", default=",".join(SIZES), help="comma-separated sizes (default: the paper's seven)")
    parser.add_argument("--planner", choices=PLANNERS, default="pbs", help="the simulator's planner (default pbs)")
    parser.add_argument("--steps", type=int, default=1000, help="steps a simulation (default 1000)")
    parser.add_argument("--seeds", type=int, default=3, help="simulations per robot count (default 3)")
    parser.add_argument("--workers", type=int, default=2, help="processes that share the simulations (default 2)")
    parser.add_argument("--repair-time-limit", type=float, default=120.0, help="seconds per repair above 33x36")
    parser.add_argument("--no-tiling", action="store_true", help="leave out the tiling baseline")
    parser.add_argument("--layouts", type=Path, default=None, metavar="DIR", help="also save our layouts here")
    parser.add_argument("--json", type=Path, default=None, metavar="OUT.json", help="keep every point here")
    parser.add_argument("--output", type=Path, default=Path("docs/scale_up.png"), help="the plot to write")
    parser.add_argument(
        "--redraw", type=Path, default=None, metavar="IN.json", help="draw the plot from a --json file, measure nothing"
    )
    parser.add_argument(
        "--add-to", type=Path, default=None, metavar="IN.json", help="measure only the named generators; add them to IN.json"
    )
    args = parser.parse_args()
    if args.redraw is not None and args.add_to is not None:
        parser.error("--redraw and --add-to: give one")
    kept = None
    if args.redraw is not None or args.add_to is not None:
        option, path = ("--redraw", args.redraw) if args.redraw is not None else ("--add-to", args.add_to)
        try:
            kept = read_json(path, 10 * MiB, what="scale-up JSON")
            results, kind, planner = kept["results"], kept["kind"], kept["planner"]
        except InputFileError as err:
            parser.error(f"{option}: {err}")
        except (KeyError, TypeError):
            parser.error(f"{option}: {path} is not a JSON this script kept (results, kind and planner)")
    if args.redraw is not None:
        draw(results, kind, planner, kept.get("steps", args.steps), args.output)
        print(f"{args.output}: written")
        return
    if kept is not None:  # measure as the kept sweep did
        first = next(iter(next(iter(results.values())).values()))
        args.kind, args.planner, args.steps, args.seeds = kind, planner, kept.get("steps", args.steps), first["points"][0]["runs"]
        args.sizes, args.no_tiling, args.json = ",".join(results), True, args.add_to
    if not args.generators:
        parser.error("name at least one generator's weights (or --redraw a kept JSON)")
    maps = reference_maps()
    if maps is None:
        parser.error("needs the original's maps for the paper's and the human layouts: set $STRUCTGEN_REFERENCE_DATA")
    sizes = args.sizes.split(",")
    if unknown := [size for size in sizes if size not in SIZES]:
        parser.error(f"--sizes: {', '.join(unknown)} not among {', '.join(SIZES)}")
    generators = {}
    for entry in args.generators:
        name, _, path = entry.rpartition("=")
        generators[name or ("ours" if not generators else Path(path).stem)] = np.load(path)
    row = ROWS[args.kind]
    print(
        f"{platform.processor() or platform.machine()}, {time.strftime('%Y-%m-%d')}; planner {args.planner}, "
        f"{args.seeds} runs of {args.steps} steps a point\n"
    )
    print("| size | layout | cells the repair changed | highest mean throughput | at robots | runs that jammed there |")
    print("|---|---|---:|---:|---:|---|")
    results: dict[str, dict[str, dict]] = {} if kept is None else kept["results"]
    first_small = None
    for size in sizes:
        layouts: dict[str, tuple[np.ndarray, int | None]] = {}
        for name, weights in generators.items():
            ours = grow_and_repair(weights, row, size, robot_step(size), args.repair_time_limit)
            layouts[name] = (ours["tiles"], ours["changed"])
            if size == "33x36" and first_small is None:
                first_small = ours["tiles"]
        if not args.no_tiling and size != "33x36":
            if first_small is None:
                first_small = grow_and_repair(next(iter(generators.values())), row, "33x36", 50, 60.0)["tiles"]
            tiled = tile_and_repair(first_small, row, robot_step(size), args.repair_time_limit, size=size)
            layouts["tiling"] = (tiled["tiles"], tiled["changed"])
        if kept is None:
            layouts["paper's CMA-MAE"] = (Grid.load(maps / papers_layout(size, row.uneven), WAREHOUSE.vocabulary).tiles, None)
            layouts["human"] = (Grid.load(maps / human_layout(size), WAREHOUSE.vocabulary).tiles, None)
        results.setdefault(size, {})
        for label, (tiles, changed) in layouts.items():
            if args.layouts is not None and changed is not None:
                args.layouts.mkdir(parents=True, exist_ok=True)
                WAREHOUSE.grid(tiles, name=f"{label}_{size}").save(args.layouts / f"{label}_{size}.json")
            points = sweep(tiles, size, row.uneven, args)
            top = max(points, key=lambda p: p["mean"])
            results[size][label] = {"changed": changed, "points": points, "best": top}
            print(
                f"| {size} | {label} | {'' if changed is None else f'{changed:,}'} | {top['mean']:.3f} | "
                f"{top['robots']:,} | {top['runs'] - top['successes']} of {top['runs']} |",
                flush=True,
            )
        if args.json is not None:  # after every size: an hour's sweep stopped part way keeps what it measured
            atomic_write(
                args.json,
                json.dumps({"kind": args.kind, "planner": args.planner, "steps": args.steps, "results": results}, indent=1),
            )
    draw(results, args.kind, args.planner, args.steps, args.output)
    print(f"{args.output}: written")


if __name__ == "__main__":
    main()
