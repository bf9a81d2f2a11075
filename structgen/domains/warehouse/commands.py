"""The verbs of the layout domains: ``structgen warehouse|manufacturing|maze
generate|repair|simulate|evaluate|show|measure`` (``simulate`` and ``evaluate``: warehouses and manufacturing
floors)."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np

from structgen.commands import DomainCommands, InputError, device_name, finite_number, output_path, verbs_wanted, whole_number
from structgen.conv_nca import HIDDEN
from structgen.domains.warehouse.layouts import KINDS, REPAIR_TIME_LIMIT, LayoutKind
from structgen.grid import Grid

EXIT_OK = 0
MAX_SEED = 2**63 - 1
#: The repair's three-way choices as its keyword arguments take them (None: the repair decides by the map's size).
AUTO_YES_NO = {"auto": None, "yes": True, "no": False}


def _kind(args: argparse.Namespace) -> LayoutKind:
    return KINDS[args.kind]


def _load(path: str, kind: LayoutKind) -> Grid:
    return Grid.load(path, kind.vocabulary)


def _size_of(kind: LayoutKind, shape: tuple[int, int]):
    """The named size whose whole map has ``shape``, or None."""
    for name, size in kind.sizes.items():
        if kind.complete(np.zeros(size.grown, dtype=np.uint8)).shape == shape:
            return name, size
    return None


def _check_output(path: Path, suffix: str) -> None:
    if path.suffix.lower() != suffix:
        raise InputError(f"{path}: this command writes {suffix} files; give a name ending in {suffix}")


# -- generate ---------------------------------------------------------------------------------------------------------
def cmd_generate(args: argparse.Namespace) -> int:
    from evolution.files import read_weights
    from structgen.conv_nca import ConvNCA

    kind = _kind(args)
    _check_output(args.output, ".json")
    try:
        size = kind.size(args.size)
    except ValueError as err:
        raise InputError(f"--size: {err}") from None
    nca = ConvNCA(kind.nca_tiles, args.hidden)
    if args.weights:
        try:
            genome = read_weights(args.weights, nca.n_params, f"a {kind.name} NCA with {args.hidden} hidden channels")
        except ValueError as err:
            raise InputError(str(err)) from None
        origin: dict[str, Any] = {"weights_file": str(args.weights)}
    else:
        genome = np.random.default_rng(args.seed).normal(0.0, 0.2, nca.n_params)
        origin = {"random_seed": args.seed}
    iterations = args.iterations if args.iterations is not None else size.iterations
    started = time.perf_counter()
    grown = nca.grow(genome, kind.seed(size.grown), iterations, args.device)
    seconds = time.perf_counter() - started
    tiles = kind.complete(grown)
    grid = kind.grid(tiles, name=args.output.stem, kind=kind.name, iterations=iterations, nca_runtime=seconds, **origin)
    grid.save(args.output)
    print(
        f"{args.output}: {kind.name} {tiles.shape[0]}x{tiles.shape[1]} grown in {iterations} steps ({seconds:.2f} s); "
        f"{_counts(grid, kind)}"
    )
    return EXIT_OK


def _counts(grid: Grid, kind: LayoutKind) -> str:
    named = [(c, kind.tile_names[c]) for c in kind.vocabulary if grid.count(c)]
    return ", ".join(f"{grid.count(c)} {name}" for c, name in named)


# -- repair -----------------------------------------------------------------------------------------------------------
def cmd_repair(args: argparse.Namespace) -> int:
    from structgen.domains.warehouse.measures import similarity
    from structgen.domains.warehouse.repair import repair

    kind = _kind(args)
    _check_output(args.output, ".json")
    grid = _load(args.file, kind)
    shelves = getattr(args, "shelves", None)
    if kind.name == "warehouse" and shelves is None:
        named = _size_of(kind, grid.shape)
        if named is None or not named[1].shelves:
            raise InputError(f"{args.file}: a {grid.shape[0]}x{grid.shape[1]} map is none of the paper's sizes; give --shelves")
        shelves = named[1].shelves
    result = repair(
        grid.tiles,
        kind,
        shelves=shelves,
        agents=args.agents if kind.name == "manufacturing" else 0,
        time_limit=args.time_limit,
        seed=args.seed,
        threads=args.threads,
        greedy_first=AUTO_YES_NO[args.greedy],
        round_relaxation=AUTO_YES_NO[args.round_relaxation],
        good_enough=args.good_enough,
    )
    hamming, score = similarity(grid.tiles, result.tiles, kind)
    metadata = {
        **grid.metadata,
        "name": args.output.stem,
        "repaired_from": str(args.file),
        "hamming": hamming,
        "sim_score": score,
        "milp_runtime": result.seconds,
        "optimal": result.optimal,
        "gap": result.gap if np.isfinite(result.gap) else None,  # JSON has no infinity: null is "no bound known"
        "repair_method": result.method,
    }
    Grid(result.tiles, kind.vocabulary, metadata).save(args.output)
    proof = "proven optimal" if result.optimal else f"{result.gap_text}, not proven optimal"
    print(f"{args.output}: {hamming} cells changed ({proof}; {result.method}, {result.seconds:.1f} s), similarity {score:.4f}")
    return EXIT_OK


# -- measure ----------------------------------------------------------------------------------------------------------
def measure(grid: Grid, kind: LayoutKind, *, agent: str = "explorer", episodes: int = 50, seed: int = 0) -> dict[str, Any]:
    """The layout's measures as a flat dictionary."""
    from structgen.domains.warehouse.measures import pattern_entropy, shelf_components, violations

    out: dict[str, Any] = {"rows": grid.shape[0], "columns": grid.shape[1]}
    for c in kind.vocabulary:
        if grid.count(c):
            out[kind.tile_names[c].split(" (")[0].replace(" ", "_") + "_tiles"] = grid.count(c)
    if kind.name == "maze":
        from structgen.domains.warehouse.maze import run_episodes

        grown = kind.storage(grid.tiles) if _is_walled(grid) else grid.tiles
        stats = run_episodes(grown, agent, episodes=episodes, seed=seed)
        out.update(
            entropy=pattern_entropy(grown, kind),
            solvable=stats.shortest_path >= 1,
            shortest_path=stats.shortest_path,
            agent=agent,
            episodes=episodes,
            success_rate=stats.success_rate,
            mean_path_length=stats.mean_steps,
        )
        return out
    storage_ok = kind.storage(grid.tiles).max(initial=0) < kind.nca_tiles
    out["entropy"] = pattern_entropy(grid.tiles, kind) if storage_ok else None
    out["shelf_components" if kind.name == "warehouse" else "station_components"] = shelf_components(grid.tiles, kind)
    named = _size_of(kind, grid.shape)
    shelves = named[1].shelves if named and named[1].shelves else None
    problems = violations(grid.tiles, kind, shelves=shelves, agents=0)
    out["valid"] = not problems
    out["problems"] = problems
    return out


def _is_walled(grid: Grid) -> bool:
    t = grid.tiles
    return bool((t[0] == 1).all() and (t[-1] == 1).all() and (t[:, 0] == 1).all() and (t[:, -1] == 1).all())


def cmd_measure(args: argparse.Namespace) -> int:
    kind = _kind(args)
    grid = _load(args.file, kind)
    values = measure(
        grid, kind, **({"agent": args.agent, "episodes": args.episodes, "seed": args.seed} if kind.name == "maze" else {})
    )
    if args.json:
        print(json.dumps({"file": str(args.file), **values}))
    else:
        width = max(map(len, values))
        print(f"{'file':<{width}}  {args.file}")
        for key, value in values.items():
            shown = (
                f"{value:.4f}" if isinstance(value, float) else ("; ".join(value) or "none") if isinstance(value, list) else value
            )
            print(f"{key:<{width}}  {shown}")
    return EXIT_OK


# -- simulate ---------------------------------------------------------------------------------------------------------
def cmd_simulate(args: argparse.Namespace) -> int:
    from structgen.domains.warehouse.simulator import simulate

    kind = _kind(args)
    if args.frames is not None:
        _check_output(args.frames, ".png")
    grid = _load(args.file, kind)
    try:
        result = simulate(
            grid.tiles,
            args.agents,
            args.steps,
            kind=kind,
            seed=args.seed,
            planner=args.planner,
            uneven=getattr(args, "uneven", False),
            trace=args.frames is not None,
        )
    except InputError as error:
        raise InputError(f"{args.file}: {error}") from None
    values = {
        "file": str(args.file),
        "throughput": result.throughput,
        "tasks": result.tasks,
        "agents": result.agents,
        "steps": result.steps,
        "congested": result.congested,
        "stopped_at": result.stopped_at,
        "planner": result.planner,
        "seed": args.seed,
        "uneven": getattr(args, "uneven", False),
        "seconds": round(result.seconds, 3),
    }
    if args.frames is not None:
        from structgen.domains.warehouse.show import draw_frames

        last = result.positions.shape[0] - 1
        times = sorted({round(last * i / 5) for i in range(6)})
        title = f"{Path(args.file).name}: {result.agents} agents, throughput {result.throughput:.3f}"
        draw_frames(grid, kind, result.positions, times, args.frames, title=title)
        values["frames"] = str(args.frames)
    if args.json:
        print(json.dumps(values))
    else:
        jam = f", congested: stopped at step {result.stopped_at}" if result.congested else ""
        print(
            f"{args.file}: throughput {result.throughput:.3f} ({result.tasks} tasks in {result.steps} steps{jam}); "
            f"{result.agents} agents, planner {result.planner}, seed {args.seed}, {result.seconds:.1f} s"
        )
        if args.frames is not None:
            print(f"{args.frames}: {len(times)} frames")
    return EXIT_OK


# -- evaluate ---------------------------------------------------------------------------------------------------------
def cmd_evaluate(args: argparse.Namespace) -> int:
    import sys

    from structgen.domains.warehouse.simulator import evaluate_layout

    kind = _kind(args)
    grid = _load(args.file, kind)
    try:
        result = evaluate_layout(
            grid.tiles,
            args.agents,
            args.simulations,
            args.steps,
            seed=args.seed,
            progress=sys.stderr.isatty(),
            kind=kind,
            planner=args.planner,
            uneven=getattr(args, "uneven", False),
        )
    except InputError as error:
        raise InputError(f"{args.file}: {error}") from None
    values = {
        "file": str(args.file),
        "agents": args.agents,
        "steps": args.steps,
        "planner": args.planner,
        "seed": args.seed,
        "uneven": getattr(args, "uneven", False),
        "simulations": result.simulations,
        "success_rate": result.success_rate,
        "throughput_mean": result.mean,
        "throughput_standard_error": result.standard_error,
        "throughputs": [round(float(t), 6) for t in result.throughputs],
        "congested": [bool(c) for c in result.congested],
        "seconds": round(result.seconds, 3),
    }
    if args.json:
        print(json.dumps(values))
        return EXIT_OK
    value = "N/A (every run congested)" if result.mean is None else f"{result.mean:.3f} ± {result.standard_error:.3f}"
    print(
        f"{args.file}: success {result.successes} of {result.simulations} ({100 * result.success_rate:.0f} %), "
        f"throughput {value} (mean ± standard error over the successful runs); {args.agents} agents, {args.steps} "
        f"steps, planner {args.planner}, {result.seconds:.1f} s"
    )
    return EXIT_OK


# -- show -------------------------------------------------------------------------------------------------------------
def cmd_show(args: argparse.Namespace) -> int:
    from structgen.domains.warehouse.show import draw

    kind = _kind(args)
    _check_output(args.output, ".png")
    grids = [_load(path, kind) for path in args.files]
    if len(grids) == 2 and grids[0].shape != grids[1].shape:
        raise InputError(
            f"{args.files[1]}: {grids[1].shape[0]}x{grids[1].shape[1]}, but {args.files[0]} is "
            f"{grids[0].shape[0]}x{grids[0].shape[1]}; only maps of one size compare"
        )
    draw(grids, kind, args.output, titles=[Path(p).name for p in args.files], dpi=args.dpi)
    changed = f", {int((grids[0].tiles != grids[1].tiles).sum())} cells differ (marked)" if len(grids) == 2 else ""
    print(f"{args.output}: {len(grids)} {kind.name} map{'s' if len(grids) > 1 else ''}{changed}")
    return EXIT_OK


# -- the parsers ------------------------------------------------------------------------------------------------------
def _add_generate(subparsers: Any, kind: LayoutKind) -> None:
    p = subparsers.add_parser(
        "generate",
        help=f"grow a {kind.name} layout with the conv NCA",
        description=f"Grow a {kind.name} layout from the seed block with the conv NCA (random weights or saved ones) "
        "and write it, unrepaired, as a map JSON file.",
    )
    source = p.add_mutually_exclusive_group()
    source.add_argument(
        "--seed",
        type=whole_number(0, MAX_SEED),
        default=0,
        metavar="N",
        help="random NCA (normal, sd 0.2, as the original's search starts) drawn with this seed (default 0)",
    )
    source.add_argument("--weights", metavar="FILE", help="NCA weights: .npy (1-D array) or .json (list of numbers)")
    p.add_argument(
        "--size",
        default=kind.default_size,
        help=f"map size: {', '.join(kind.sizes)}, or ROWSxCOLUMNS of the grown area (default {kind.default_size})",
    )
    p.add_argument(
        "--iterations",
        type=whole_number(0, 100_000),
        default=None,
        metavar="N",
        help="NCA steps (default: the paper's for the size, 50, or 200 at 101x102)",
    )
    p.add_argument(
        "--hidden", type=whole_number(1, 1024), default=HIDDEN, metavar="N", help=f"hidden channels (default {HIDDEN})"
    )
    p.add_argument("--device", type=device_name, default=None, help="torch device: cpu, cuda, cuda:N (default: the CPU)")
    p.add_argument("-o", "--output", required=True, type=output_path, metavar="OUT.json", help="map file to write")
    p.set_defaults(handler=cmd_generate, kind=kind.name)


def _add_repair(subparsers: Any, kind: LayoutKind) -> None:
    p = subparsers.add_parser(
        "repair",
        help=f"repair a {kind.name} layout with the fewest tile changes (HiGHS MILP)",
        description=f"Make FILE a valid {kind.name} layout changing as few cells as possible, with the MILP solved by "
        "HiGHS, and write it with the Hamming distance, similarity, proof status and time in its metadata. Exit 2 "
        "if the rules cannot be met.",
    )
    p.add_argument("file", metavar="FILE", help="map JSON file (unrepaired)")
    p.add_argument("-o", "--output", required=True, type=output_path, metavar="OUT.json", help="map file to write")
    p.add_argument(
        "--time-limit",
        type=finite_number(0, 86400, above=True),
        default=REPAIR_TIME_LIMIT,
        metavar="S",
        help=f"seconds for HiGHS (default {REPAIR_TIME_LIMIT:g})",
    )
    p.add_argument("--threads", type=whole_number(1, 1024), default=1, metavar="N", help="HiGHS threads (default 1)")
    p.add_argument("--seed", type=whole_number(0, 2**31 - 1), default=0, metavar="N", help="HiGHS random seed (default 0)")
    p.add_argument(
        "--greedy",
        choices=tuple(AUTO_YES_NO),
        default="auto",
        help="start HiGHS from the greedy repair: auto (above 4,000 cells), yes, no",
    )
    p.add_argument(
        "--round-relaxation",
        choices=tuple(AUTO_YES_NO),
        default="auto",
        help="before the full search, solve the linear relaxation and the smaller MILP left by holding the tiles it "
        "decided; its answer ends the repair when it meets the relaxation's bound: auto (warehouses of 1,000 to "
        "4,000 cells with a time limit of 30 s or more), yes, no",
    )
    p.add_argument(
        "--good-enough",
        type=whole_number(0, 10**7),
        default=None,
        metavar="N",
        help="stop at the first valid layout that changes at most N cells, proven optimal or not (default: search "
        "for the fewest changes until the time limit)",
    )
    if kind.name == "warehouse":
        p.add_argument(
            "--shelves",
            type=whole_number(0, 10**7),
            default=None,
            metavar="N",
            help="exact shelf count (default: the paper's for the map's size, 240 at 33x36)",
        )
    else:
        p.add_argument(
            "--agents",
            type=whole_number(0, 10**7),
            default=200,
            metavar="N",
            help="cells that must stay free of stations (default 200)",
        )
    p.set_defaults(handler=cmd_repair, kind=kind.name)


def _add_show(subparsers: Any, kind: LayoutKind) -> None:
    p = subparsers.add_parser(
        "show",
        help=f"draw one {kind.name} layout, or two side by side with the changed cells marked",
        description="Draw FILE (and FILE2 beside it, cells that differ outlined in red) to a PNG image, each tile "
        "kind in the legend.",
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="one or two map JSON files (unrepaired, then repaired)")
    p.add_argument("-o", "--output", required=True, type=output_path, metavar="OUT.png", help="image to write")
    p.add_argument("--dpi", type=whole_number(10, 1200), default=110, help="image resolution, 10..1200 (default 110)")
    p.set_defaults(handler=cmd_show, kind=kind.name)


def _add_measure(subparsers: Any, kind: LayoutKind) -> None:
    p = subparsers.add_parser(
        "measure",
        help=f"print a {kind.name} layout's measures",
        description="Print the layout's tile counts and the original's measures "
        + (
            "(pattern entropy, solvability, longest shortest path, and an agent's success rate and path length)."
            if kind.name == "maze"
            else "(pattern entropy, shelf components) and whether it is valid."
        ),
    )
    p.add_argument("file", metavar="FILE", help="map JSON file")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    if kind.name == "maze":
        from structgen.domains.warehouse.maze import AGENTS

        p.add_argument("--agent", choices=sorted(AGENTS), default="explorer", help="agent to run (default explorer)")
        p.add_argument("--episodes", type=whole_number(1, 10_000), default=50, metavar="N", help="episodes (default 50)")
        p.add_argument("--seed", type=whole_number(0, MAX_SEED), default=0, metavar="N", help="episodes' seed (default 0)")
    p.set_defaults(handler=cmd_measure, kind=kind.name)


def _add_robot_arguments(p: argparse.ArgumentParser, kind: LayoutKind, steps: int, planner: str, seed_help: str) -> None:
    """The arguments ``simulate`` and ``evaluate`` share: the map, robots, steps, planner, seed and task weights."""
    from structgen.domains.warehouse.simulator import PLANNERS

    p.add_argument("file", metavar="FILE", help="map JSON file (a repaired, valid layout)")
    p.add_argument("--agents", type=whole_number(1, 10**6), default=200, metavar="N", help="robots (default 200)")
    p.add_argument("--steps", type=whole_number(1, 10**7), default=steps, metavar="T", help=f"steps per run (default {steps})")
    described = {
        "pp": "windowed prioritized planning, ranks layouts as the paper's simulator does, 2-6 %% below its throughput",
        "pbs": "windowed priority-based search, the paper's planner, within 1.2 %% of it on its 33x36 warehouses but 4 "
        "to 5 times slower, and congests from 1,500 robots at 101x102",
        "pibt": "one step of look-ahead, fastest, but stalls in one-wide dead ends and ranks layouts differently",
    }
    p.add_argument(
        "--planner",
        choices=PLANNERS,
        default=planner,
        help="; ".join(f"{name}: {described[name]}{' (default)' if name == planner else ''}" for name in PLANNERS),
    )
    p.add_argument("--seed", type=whole_number(0, MAX_SEED), default=0, metavar="S", help=f"{seed_help} (default 0)")
    if kind.name == "warehouse":
        p.add_argument("--uneven", action="store_true", help="left-half workstations five times likelier goals")


def _add_simulate(subparsers: Any, kind: LayoutKind) -> None:
    if kind.name == "manufacturing":
        goals = (
            "visiting stations of kind 0, 1, 2, 0, ... in turn and standing 2, 5 or 10 steps on an endpoint beside "
            "each for its task"
        )
    else:
        goals = "fetching goals (an endpoint, then a workstation, and so on)"
    p = subparsers.add_parser(
        "simulate",
        help=f"run robots on a {kind.name} layout and print its throughput",
        description=f"Simulate N robots {goals} on the layout in FILE for T steps, planning collision-free paths 10 "
        "steps ahead every 5 steps, and print the throughput (tasks finished per step), the tasks finished, whether "
        "the floor congested (more than half of the robots stood still, not counting tasks, for 5 steps, which stops "
        "the run) and the wall time.",
    )
    _add_robot_arguments(
        p, kind, steps=1000, planner="pp", seed_help="seed of the start cells, the goals and the planners' tie-breaks"
    )
    p.add_argument("--frames", type=output_path, default=None, metavar="OUT.png", help="also draw six snapshots")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=cmd_simulate, kind=kind.name)


def _add_evaluate(subparsers: Any, kind: LayoutKind) -> None:
    p = subparsers.add_parser(
        "evaluate",
        help=f"judge a {kind.name} layout as the paper's tables do: success rate and throughput over many runs",
        description=f"Simulate N robots on the {kind.name} layout in FILE in many runs (seeds drawn from --seed) and "
        "report the success rate (runs that did not congest) and the mean and standard error of the throughput over "
        "the successful runs, as the paper's tables do (N/A when every run congested). Training averages fewer, "
        "shorter runs (the problem's simulations and simulation_steps).",
    )
    p.add_argument("--simulations", type=whole_number(1, 10**5), default=50, metavar="K", help="runs (default 50, as the paper)")
    _add_robot_arguments(p, kind, steps=5000, planner="pbs", seed_help="seed the runs' seeds are drawn from")
    p.add_argument("--json", action="store_true", help="print one JSON object, with every run's throughput")
    p.set_defaults(handler=cmd_evaluate, kind=kind.name)


class LayoutCommands(DomainCommands):
    def __init__(self, kind: str, verbs: tuple[str, ...]) -> None:
        self.kind = kind
        self.verbs = verbs

    def add_verbs(self, subparsers: Any, domain: Any, only: Collection[str] | None = None) -> None:
        adders = {
            "generate": _add_generate,
            "repair": _add_repair,
            "simulate": _add_simulate,
            "evaluate": _add_evaluate,
            "show": _add_show,
            "measure": _add_measure,
        }
        for name in verbs_wanted([v for v in adders if v in self.verbs], only):
            adders[name](subparsers, KINDS[self.kind])

    def export_elite(self, problem: Any, genome: Any, output: Path, args: argparse.Namespace, origin) -> str:
        _check_output(output, ".json")
        tiles = problem.grow(np.asarray(genome)[None])[0]
        grid = problem.kind.grid(tiles, name=output.stem, kind=problem.kind.name, **dict(origin))
        grid.save(output)
        return f"{output}: {problem.kind.name} {tiles.shape[0]}x{tiles.shape[1]} (unrepaired)"


WAREHOUSE_COMMANDS = LayoutCommands("warehouse", ("generate", "repair", "simulate", "evaluate", "show", "measure"))
MANUFACTURING_COMMANDS = LayoutCommands("manufacturing", ("generate", "repair", "simulate", "evaluate", "show", "measure"))
MAZE_COMMANDS = LayoutCommands("maze", ("generate", "show", "measure"))
