"""The verbs of the layout domains: ``structgen warehouse|manufacturing|maze
grow|tile|repair|simulate|evaluate|show|measure`` (``simulate`` and ``evaluate``: warehouses and manufacturing
floors; ``train``, ``test-agent`` and ``experiment``: mazes)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np

from structgen.domains.layouts.conv_nca import HIDDEN
from structgen.domains.layouts.grid import Grid
from structgen.domains.layouts.kinds import KINDS, REPAIR_TIME_LIMIT, LayoutKind
from structgen.ppo_settings import PPO_OPTIONS
from structgen.registry.commands import (
    DomainCommands,
    InputError,
    add_setting_options,
    device_name,
    finite_number,
    given_settings,
    output_path,
    png_output_path,
    resumed_training_settings,
    verbs_wanted,
    whole_number,
)

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


# -- grow -------------------------------------------------------------------------------------------------------------
def cmd_generate(args: argparse.Namespace) -> int:
    from evolution.files import read_weights
    from structgen.domains.layouts.conv_nca import ConvNCA

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


# -- tile -------------------------------------------------------------------------------------------------------------
def cmd_tile(args: argparse.Namespace) -> int:
    kind = _kind(args)
    _check_output(args.output, ".json")
    grid = _load(args.file, kind)
    small = kind.storage(grid.tiles)
    if small.size == 0 or (kind.name != "maze" and small.max(initial=0) >= kind.nca_tiles):
        raise InputError(f"{args.file}: the part of the map to repeat holds tiles the {kind.name} NCA does not grow")
    try:
        tiles = kind.tiled(grid.tiles, args.size)
    except ValueError as err:
        raise InputError(f"--size: {err}") from None
    out = kind.grid(tiles, name=args.output.stem, kind=kind.name, tiled_from=str(args.file))
    out.save(args.output)
    print(
        f"{args.output}: {kind.name} {tiles.shape[0]}x{tiles.shape[1]} tiled from {grid.shape[0]}x{grid.shape[1]} "
        f"(unrepaired); {_counts(out, kind)}"
    )
    return EXIT_OK


def _counts(grid: Grid, kind: LayoutKind) -> str:
    named = [(c, kind.tile_names[c]) for c in kind.vocabulary if grid.count(c)]
    return ", ".join(f"{grid.count(c)} {name}" for c, name in named)


# -- repair -----------------------------------------------------------------------------------------------------------
def cmd_repair(args: argparse.Namespace) -> int:
    from structgen.domains.layouts.measures import similarity
    from structgen.domains.layouts.repair import repair

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
        local_first=AUTO_YES_NO[getattr(args, "local", "no")],
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
def measure(
    grid: Grid, kind: LayoutKind, *, agent: str = "learned", episodes: int = 50, seed: int = 0, weights: str | None = None
) -> dict[str, Any]:
    """The layout's measures as a flat dictionary."""
    from structgen.domains.layouts.measures import pattern_entropy, shelf_components, violations

    out: dict[str, Any] = {"rows": grid.shape[0], "columns": grid.shape[1]}
    for c in kind.vocabulary:
        if grid.count(c):
            out[kind.tile_names[c].split(" (")[0].replace(" ", "_") + "_tiles"] = grid.count(c)
    if kind.name == "maze":
        from structgen.domains.layouts.maze.walkers import diameter, run_episodes

        grown = _grown_maze(grid, kind)
        ends = diameter(grown)
        if agent == "learned" and ends is not None:
            from structgen.domains.layouts.maze.agent import run_agent
            from structgen.domains.layouts.maze.training import agent_policy

            results = run_agent(agent_policy(weights), [grown], episodes=episodes, seed=seed)
            success, steps = results.success_rate, float(results.steps[0])
        elif agent == "learned":  # no path: nothing to run
            success, steps = 0.0, float(2 * (grown.shape[0] + 2) * (grown.shape[1] + 2))
        else:
            stats = run_episodes(grown, agent, episodes=episodes, seed=seed)
            success, steps = stats.success_rate, stats.mean_steps
        out.update(
            entropy=pattern_entropy(grown, kind),
            walls=int((grown == 1).sum()),
            solvable=ends is not None,
            shortest_path=ends[2] if ends is not None else -1,
            agent=agent,
            episodes=episodes,
            success_rate=success,
            mean_path_length=steps,
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


def _grown_maze(grid: Grid, kind: LayoutKind) -> np.ndarray:
    """The maze inside its outer wall, whether the file holds the wall or not."""
    t = grid.tiles
    walled = bool((t[0] == 1).all() and (t[-1] == 1).all() and (t[:, 0] == 1).all() and (t[:, -1] == 1).all())
    return kind.storage(t) if walled else t


def cmd_measure(args: argparse.Namespace) -> int:
    kind = _kind(args)
    grid = _load(args.file, kind)
    values = measure(
        grid,
        kind,
        **(
            {"agent": args.agent, "episodes": args.episodes, "seed": args.seed, "weights": args.weights}
            if kind.name == "maze"
            else {}
        ),
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
    from structgen.domains.layouts.warehouse.simulator import simulate

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
        from structgen.domains.layouts.show import draw_frames

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

    from structgen.domains.layouts.warehouse.simulator import evaluate_layout

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
            workers=args.workers,
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
    from structgen.domains.layouts.show import draw

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
        "grow",
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


def _add_tile(subparsers: Any, kind: LayoutKind) -> None:
    p = subparsers.add_parser(
        "tile",
        help=f"repeat a small {kind.name} layout to fill a larger size (the paper's tiling baseline)",
        description="Repeat the part of FILE that the NCA grows (for warehouses, the storage area between the "
        "workstation columns) along both axes until it fills --size, cut it there from the top-left, add the fixed "
        "parts and write the result, unrepaired, as a map JSON file. The warehouse paper's baseline against growing "
        "large: tile a trained 33x36 layout to 101x102, then repair it (the repair command) and evaluate it.",
    )
    p.add_argument("file", metavar="FILE", help="map JSON file to repeat (a whole map)")
    p.add_argument(
        "--size",
        required=True,
        help=f"size to fill: {', '.join(kind.sizes)}, or ROWSxCOLUMNS of the grown area",
    )
    p.add_argument("-o", "--output", required=True, type=output_path, metavar="OUT.json", help="map file to write")
    p.set_defaults(handler=cmd_tile, kind=kind.name)


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
            "--local",
            choices=tuple(AUTO_YES_NO),
            default="auto",
            help="first solve only around the cells that break a rule (and the cells that can fix a wrong shelf "
            "count), holding the rest; its answer ends the repair, keeping a large layout's pattern: auto (above "
            "4,000 cells, when that region is at most 40 %% of the storage area), yes, no",
        )
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
    p.add_argument("-o", "--output", required=True, type=png_output_path, metavar="OUT.png", help="image to write")
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
        from structgen.domains.layouts.maze.walkers import AGENTS

        p.add_argument(
            "--agent",
            choices=["learned", *sorted(AGENTS)],
            default="learned",
            help="agent to run (default learned: the shipped learning agent, the maze domain's judge)",
        )
        p.add_argument("--weights", default=None, metavar="FILE", help="the learned agent's weights (default the shipped agent)")
        p.add_argument("--episodes", type=whole_number(1, 10_000), default=50, metavar="N", help="episodes (default 50)")
        p.add_argument("--seed", type=whole_number(0, MAX_SEED), default=0, metavar="N", help="episodes' seed (default 0)")
    p.set_defaults(handler=cmd_measure, kind=kind.name)


def _add_robot_arguments(p: argparse.ArgumentParser, kind: LayoutKind, steps: int, planner: str, seed_help: str) -> None:
    """The arguments ``simulate`` and ``evaluate`` share: the map, robots, steps, planner, seed and task weights."""
    from structgen.domains.layouts.warehouse.simulator import PLANNERS

    p.add_argument("file", metavar="FILE", help="map JSON file (a repaired, valid layout)")
    p.add_argument("--agents", type=whole_number(1, 10**6), default=200, metavar="N", help="robots (default 200)")
    p.add_argument("--steps", type=whole_number(1, 10**7), default=steps, metavar="T", help=f"steps per run (default {steps})")
    described = {
        "pp": "windowed prioritized planning, ranks layouts as the paper's simulator does, 2-6 %% below its throughput",
        "pbs": "windowed priority-based search with RHCR's start-cell rules, the paper's planner: carries the paper's "
        "robot counts at 101x102 and is within 1 %% of RHCR at 33x36, but jams on DSAGE's layout in some long runs",
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
    p.add_argument("--frames", type=png_output_path, default=None, metavar="OUT.png", help="also draw six snapshots")
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
    p.add_argument(
        "--workers",
        type=whole_number(0, 1024),
        default=0,
        metavar="N",
        help="processes that share the runs (default 0: this one); the result is the same with any number",
    )
    _add_robot_arguments(p, kind, steps=5000, planner="pbs", seed_help="seed the runs' seeds are drawn from")
    p.add_argument("--json", action="store_true", help="print one JSON object, with every run's throughput")
    p.set_defaults(handler=cmd_evaluate, kind=kind.name)


# -- the maze agent ---------------------------------------------------------------------------------------------------
#: The settings maze train takes as options: each made from the field's limit (AgentSettings.limits).
_AGENT_FIELDS = (
    *PPO_OPTIONS,
    "size",
    "replay",
    "edit",
    "buffer",
    "temperature",
    "staleness",
    "checkpoint_every",
    "evaluate_every",
    "seed",
)


def cmd_train_agent(args: argparse.Namespace) -> int:
    from structgen.domains.layouts.maze.agent_settings import AgentSettings
    from structgen.domains.layouts.maze.training import AGENT_FILE, train_agent

    values = given_settings(args, _AGENT_FIELDS)
    if args.no_way_on:
        values["way_on"] = False
    try:
        settings = AgentSettings(**values, device=args.device)
    except ValueError as err:
        raise InputError(str(err)) from None
    _, rows = train_agent(args.run_dir, settings, overwrite=args.overwrite, progress=True)
    last = rows[-1] if rows else {}
    tested = [r["held_out"] for r in rows if r.get("held_out") is not None]
    print(
        f"{args.run_dir}: {last.get('update', 0)} updates, {last.get('agent_steps', 0):,} agent steps; held-out rooms "
        f"mazes reached {tested[-1]:.0%}"
        if tested
        else f"{args.run_dir}: trained"
    )
    print(f"weights: {Path(args.run_dir) / AGENT_FILE}; learning curve: {Path(args.run_dir) / 'learning.png'}")
    return EXIT_OK


def _add_train_agent(subparsers: Any, kind: LayoutKind) -> None:
    from structgen.domains.layouts.maze.agent_settings import AgentSettings

    p = subparsers.add_parser(
        "train",
        help="train the maze agent (PPO with a PLR/ACCEL curriculum) in a run folder",
        description="Train the learning maze agent: it sees the 5x5 cells in front of it and its direction, keeps a "
        "map of what it has seen and where it has walked, reads from it which way the goal or the nearest unexplored "
        "floor lies, and learns by PPO on random 16x16 mazes chosen by a "
        "curriculum that replays and edits the levels it still learns most from. The run folder gets checkpoints "
        "(the same command resumes it; more --updates go on), history.jsonl, learning.png and agent.pt. The defaults "
        "are the settings of the shipped agent (docs/maze_agent.pt).",
    )
    p.add_argument(
        "--run-dir", required=True, type=Path, metavar="DIR", help="run folder (made, or resumed if it holds this training)"
    )
    add_setting_options(p, AgentSettings, _AGENT_FIELDS)
    p.add_argument(
        "--no-way-on",
        action="store_true",
        help="do not tell the network which way the goal or the nearest unexplored floor lies on its map (the agents "
        "of structgen 0.4 and before; give it again to go on with such a run, or use structgen resume)",
    )
    p.add_argument("--device", type=device_name, default="cpu", help="torch device (default cpu)")
    p.add_argument(
        "--overwrite", action="store_true", help="replace a run folder that holds another run (never any other folder)"
    )
    p.set_defaults(handler=cmd_train_agent, kind=kind.name)


def cmd_test_agent(args: argparse.Namespace) -> int:
    from structgen.domains.layouts.maze.agent import run_agent
    from structgen.domains.layouts.maze.env import random_maze
    from structgen.domains.layouts.maze.training import agent_policy

    kind = _kind(args)
    policy = agent_policy(args.weights)
    if args.files:
        from structgen.domains.layouts.maze.walkers import diameter

        grids = [_load(f, kind) for f in args.files]
        mazes = [_grown_maze(g, kind) for g in grids]
        for path, maze in zip(args.files, mazes):
            if diameter(maze) is None:
                raise InputError(f"{path}: no two floor cells are connected, so the maze has no start and goal to test")
        shapes = {m.shape for m in mazes}
        if len(shapes) != 1:
            raise InputError(f"the mazes must have one size, got {sorted(shapes)}")
        source = f"{len(mazes)} maze files"
    else:
        rng = np.random.default_rng(args.seed)
        mazes = [random_maze(rng, args.size, args.maze_kind) for _ in range(args.count)]
        source = f"{args.count} random {args.maze_kind} mazes of {args.size}x{args.size} (seed {args.seed})"
    results = run_agent(policy, mazes, episodes=args.episodes, seed=args.seed, device=args.device)
    error = results.standard_error
    summary = {
        "mazes": len(mazes),
        "episodes": args.episodes,
        "success_rate": results.success_rate,
        "standard_error": error,
        "mean_steps": float(results.steps.mean()),
    }
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"{source}, {args.episodes} episode(s) each: the agent reached the goal in {results.success_rate:.1%} "
            f"(standard error {error:.1%}), in {summary['mean_steps']:.0f} steps on average"
        )
    return EXIT_OK


def _add_test_agent(subparsers: Any, kind: LayoutKind) -> None:
    from structgen.domains.layouts.maze.walkers import MAZE_KINDS

    p = subparsers.add_parser(
        "test-agent",
        help="run the learning maze agent on maze files or random mazes and print its success rate",
        description="Run the learned maze agent (the shipped docs/maze_agent.pt, or --weights) on the maze JSON files "
        "given (all of one size, with or without their outer wall), or on --count random mazes, and print the share "
        "of episodes that reached the goal within the horizon (twice the cells of the walled maze), with its "
        "standard error (over mazes, or over episodes for a single maze).",
    )
    p.add_argument("files", nargs="*", metavar="FILE", help="maze JSON files (none: random mazes)")
    p.add_argument(
        "--weights", default=None, metavar="FILE", help="agent weights (a run folder's agent.pt; default the shipped agent)"
    )
    p.add_argument(
        "--kind",
        dest="maze_kind",
        choices=MAZE_KINDS,
        default="rooms",
        help="random mazes' kind (default rooms, never trained on)",
    )
    p.add_argument("--size", type=whole_number(4, 256), default=16, metavar="N", help="random mazes' side (default 16)")
    p.add_argument("--count", type=whole_number(1, 10**6), default=200, metavar="N", help="random mazes (default 200)")
    p.add_argument("--episodes", type=whole_number(1, 10_000), default=1, metavar="N", help="episodes per maze (default 1)")
    p.add_argument(
        "--seed",
        type=whole_number(0, 2**32 - 1),
        default=0,
        metavar="S",
        help="seed of the mazes and the agent's actions (default 0)",
    )
    p.add_argument("--device", type=device_name, default="cpu", help="torch device (default cpu)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=cmd_test_agent, kind=kind.name)


def _size_option(kind: LayoutKind) -> Any:
    """An argparse ``type`` for a size of ``kind`` (``33x36`` or any ``RxC`` it can grow), checked before any work."""

    def parse(text: str) -> str:
        try:
            kind.size(text)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
        return text

    return parse


def _grown_pair(args: argparse.Namespace, kind: LayoutKind) -> tuple[np.ndarray, np.ndarray, str]:
    """The small and large mazes (without their outer walls) the experiment plays, and where they came from."""
    if args.run_dir is not None:
        if args.small or args.large:
            raise InputError("give a RUN_DIR or --small and --large maze files, not both")
        from structgen.domains.layouts.problem import LayoutProblem
        from structgen.runs import load_run

        run = load_run(args.run_dir)
        problem = run.problem
        if getattr(problem, "kind", None) is not kind:
            raise InputError(f"{args.run_dir}: not a maze run (its problem is {run.experiment.domain!r})")
        large_problem = LayoutProblem(dataclasses.replace(problem.settings, size=args.large_size))
        genome, elite = _experiment_elite(run, args.elite, large_problem, args.seed)
        small = kind.storage(problem.grow(np.asarray(genome)[None])[0])
        large = kind.storage(large_problem.grow(np.asarray(genome)[None])[0])
        return small, large, f"{args.run_dir} (elite {elite}), grown at {problem.settings.size} and {args.large_size}"
    if not (args.small and args.large):
        raise InputError("give a maze RUN_DIR, or --small FILE and --large FILE (e.g. the paper's grown mazes)")
    pair = []
    for path in (args.small, args.large):
        pair.append(_grown_maze(_load(path, kind), kind))
    return pair[0], pair[1], f"{args.small} and {args.large}"


#: How many elites ``--elite longest`` tries, and how many random baselines it draws for each, before giving up.
_CANDIDATES, _SCREEN_DRAWS = 10, 20


def _experiment_elite(run: Any, elite: str, large_problem: Any, seed: int) -> tuple[Any, str]:
    """The generator and its name. ``longest``: of the archive elites whose maze the agent solves in at least 90 %
    of its episodes, by longest mean agent path, the first whose large maze random baselines can match (one of
    :data:`_SCREEN_DRAWS` random mazes of its wall count within the path-length band: some grow large mazes whose
    longest path no random maze of that wall count reaches). Else as ``structgen export --elite``."""
    from structgen.domains.layouts.maze.experiment import baseline_mazes
    from structgen.domains.layouts.maze.walkers import diameter
    from structgen.runs import elite_genome

    if elite != "longest":
        return elite_genome(run.folder, run.problem, elite), elite
    rows = [r for r in run.folder.archive_rows() if float(r.get("success_rate", 0.0)) >= 0.9]
    if not rows:
        raise InputError(f"{run.path}: no archive elite whose maze the agent solves in 90 % of its episodes; give --elite")
    rows.sort(key=lambda r: (-float(r["path_length"]), int(r["index"])))
    rng = np.random.default_rng([seed, 3])
    for row in rows[:_CANDIDATES]:
        genome = run.folder.archive_genome(int(row["index"]), run.problem)
        large = run.problem.kind.storage(large_problem.grow(np.asarray(genome)[None])[0])
        ends = diameter(large)
        if ends is None:
            continue
        try:
            baseline_mazes(large, 1, rng, tries=_SCREEN_DRAWS, reference_length=ends[2])
        except ValueError:
            continue
        return genome, f"index:{row['index']}"
    raise InputError(
        f"{run.path}: none of the {min(len(rows), _CANDIDATES)} longest-path elites grows a large maze that random "
        "baselines can match; give --elite"
    )


def cmd_experiment(args: argparse.Namespace) -> int:
    from structgen.domains.layouts.maze.experiment import PAPER, maze_experiment
    from structgen.domains.layouts.maze.training import agent_policy

    kind = _kind(args)
    small, large, source = _grown_pair(args, kind)
    policy = agent_policy(args.weights)
    try:
        rows, _ = maze_experiment(
            policy,
            small,
            large,
            episodes=args.episodes,
            baselines=args.baselines,
            baseline_episodes=args.baseline_episodes,
            seed=args.seed,
            device=args.device,
            progress=not args.json,
        )
    except ValueError as err:
        raise InputError(f"{source}: {err}") from None
    if args.json:
        print(json.dumps({"source": source, "rows": [dataclasses.asdict(r) for r in rows]}))
        return EXIT_OK
    print(f"mazes: {source}")
    print(f"{'maze':<12} {'size':>6} {'mazes':>5} {'runs':>5} {'walls':>6} {'path':>6} {'success':>8} {'s.e.':>6} {'paper':>12}")
    for row in rows:
        rate, error = PAPER[row.name]
        paper = f"{rate:.0%}" + (f" ({error:.0%})" if error is not None else "")
        print(
            f"{row.name:<12} {row.size:>6} {row.mazes:>5} {row.episodes:>5} {row.walls:>6.0f} {row.path_length:>6.1f} "
            f"{row.success_rate:>8.1%} {row.standard_error:>6.1%} {paper:>12}"
        )
    return EXIT_OK


def _add_experiment(subparsers: Any, kind: LayoutKind) -> None:
    p = subparsers.add_parser(
        "experiment",
        help="the paper's maze experiment: the agent on small and large grown mazes and on random baselines",
        description="Grow a maze with a generator trained small (an elite of a maze RUN_DIR) at its own size and at "
        "--large-size, or take the two mazes from --small and --large files, run the learned agent on each "
        "--episodes times, make --baselines random mazes as the original does (as many walls as the large maze, "
        "placed uniformly, drawn again until the longest shortest path is within 80-120 % of the large maze's) and "
        "run it --baseline-episodes times on each; print the success rates beside the paper's (90 %, 93 %, 22 %).",
    )
    p.add_argument(
        "run_dir", nargs="?", default=None, metavar="RUN_DIR", help="a maze evolution run (its generators trained small)"
    )
    p.add_argument(
        "--elite",
        default="longest",
        help="the generator: longest (default: the elite with the longest agent path among those the agent solves in "
        "90 %% of episodes), best, or index:I (the archive cell)",
    )
    p.add_argument(
        "--large-size", type=_size_option(kind), default="64x64", metavar="RxC",
        help="size to grow the large maze at: ROWSxCOLUMNS, each at least 4, at most 4096 x 4096 cells (default 64x64)",
    )  # fmt: skip
    p.add_argument("--small", default=None, metavar="FILE", help="small maze JSON file, instead of a run")
    p.add_argument("--large", default=None, metavar="FILE", help="large maze JSON file, instead of a run")
    p.add_argument("--weights", default=None, metavar="FILE", help="agent weights (default the shipped agent)")
    p.add_argument(
        "--episodes", type=whole_number(1, 100_000), default=100, metavar="N", help="runs on each grown maze (default 100)"
    )
    p.add_argument("--baselines", type=whole_number(1, 10_000), default=100, metavar="N", help="baseline mazes (default 100)")
    p.add_argument(
        "--baseline-episodes", type=whole_number(1, 10_000), default=10, metavar="N", help="runs on each baseline (default 10)"
    )
    p.add_argument(
        "--seed", type=whole_number(0, 2**32 - 1), default=0, metavar="S", help="seed of the baselines and the runs (default 0)"
    )
    p.add_argument("--device", type=device_name, default="cpu", help="torch device (default cpu)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(handler=cmd_experiment, kind=kind.name)


def _examples(kind: str) -> dict[str, list[str]]:
    """Each verb's ``--help`` examples for the ``kind`` family member."""
    verb = f"structgen {kind}"
    return {
        "grow": [f"{verb} grow --seed 1 -o layout.json", f"{verb} grow --weights generator.npy --size 101x102 -o large.json"],
        "tile": [f"{verb} tile layout.json --size 101x102 -o tiled.json"],
        "repair": [f"{verb} repair layout.json -o repaired.json --time-limit 60"],
        "simulate": [f"{verb} simulate repaired.json --agents 200 --planner pbs --frames robots.png"],
        "evaluate": [f"{verb} evaluate repaired.json --simulations 10 --steps 5000 --planner pbs --workers 2"],
        "show": [f"{verb} show layout.json -o layout.png", f"{verb} show layout.json repaired.json -o changes.png"],
        "measure": [f"{verb} measure layout.json --json"],
        "train": [f"{verb} train --run-dir runs/maze_agent", f"{verb} train --run-dir runs/maze_agent --updates 1000"],
        "test-agent": [f"{verb} test-agent --kind rooms --size 32 --count 200", f"{verb} test-agent maze.json"],
        "experiment": [f"{verb} experiment runs/maze", f"{verb} experiment --small small.json --large large.json --json"],
        "export": [f"{verb} export runs/{kind} best.json", f"{verb} export runs/{kind} elite.json --elite index:120"],
    }


class LayoutCommands(DomainCommands):
    renamed = {"generate": "grow", "train-agent": "train"}  # until 0.5

    def __init__(self, kind: str, verbs: tuple[str, ...]) -> None:
        self.kind = kind
        self.verbs = verbs
        self.renamed = {old: new for old, new in self.renamed.items() if new in verbs}
        self.examples = {verb: lines for verb, lines in _examples(kind).items() if verb in (*verbs, "export")}

    def add_verbs(self, subparsers: Any, domain: Any, only: Collection[str] | None = None) -> None:
        adders = {
            "grow": _add_generate,
            "tile": _add_tile,
            "repair": _add_repair,
            "simulate": _add_simulate,
            "evaluate": _add_evaluate,
            "show": _add_show,
            "measure": _add_measure,
            "train": _add_train_agent,
            "test-agent": _add_test_agent,
            "experiment": _add_experiment,
        }
        subparsers = self.verb_parsers(subparsers)
        for name in verbs_wanted([v for v in adders if v in self.verbs], only):
            adders[name](subparsers, KINDS[self.kind])

    def resume_run(self, kind: str, run_dir: Path, args: argparse.Namespace) -> int:
        from structgen.domains.layouts.maze.training import RUN_KIND, read_settings, train_agent

        if kind != RUN_KIND:
            return super().resume_run(kind, run_dir, args)
        settings = resumed_training_settings(run_dir, args, read_settings, "a maze-agent training")
        train_agent(run_dir, settings, progress=True)
        return EXIT_OK

    def describe_run(self, kind: str, run_dir: Path) -> tuple[dict[str, Any], str]:
        from structgen.domains.layouts.maze.training import RUN_KIND, agent_run_summary

        if kind != RUN_KIND:
            return super().describe_run(kind, run_dir)
        summary = agent_run_summary(run_dir)
        tested = summary["held_out"]
        text = (
            f"{run_dir}: maze-agent training, {summary['updates_done']} of {summary['updates']} updates, "
            f"{summary['agent_steps']:,} agent steps"
            + (f"; last held-out test {tested:.0%} of rooms mazes reached" if tested is not None else "")
            + ("; agent.pt written" if summary["finished"] else "; resume with the same command or structgen resume")
        )
        return summary, text

    def export_elite(self, problem: Any, genome: Any, output: Path, args: argparse.Namespace, origin) -> str:
        _check_output(output, ".json")
        tiles = problem.grow(np.asarray(genome)[None])[0]
        grid = problem.kind.grid(tiles, name=output.stem, kind=problem.kind.name, **dict(origin))
        grid.save(output)
        return f"{output}: {problem.kind.name} {tiles.shape[0]}x{tiles.shape[1]} (unrepaired)"


WAREHOUSE_COMMANDS = LayoutCommands("warehouse", ("grow", "tile", "repair", "simulate", "evaluate", "show", "measure"))
MANUFACTURING_COMMANDS = LayoutCommands("manufacturing", ("grow", "tile", "repair", "simulate", "evaluate", "show", "measure"))
MAZE_COMMANDS = LayoutCommands("maze", ("grow", "tile", "show", "measure", "train", "test-agent", "experiment"))
