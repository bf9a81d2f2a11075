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
from structgen.domains.layouts.maze.agent_settings import AgentSettings
from structgen.domains.layouts.maze.walkers import AGENTS, MAZE_KINDS
from structgen.domains.layouts.warehouse.simulator import PLANNERS
from structgen.ppo_settings import PPO_OPTIONS
from structgen.registry.commands import (
    EXIT_OK,
    Adder,
    DomainCommands,
    InputError,
    Verb,
    device,
    dpi,
    flag,
    given_settings,
    json_flag,
    nca_weights,
    number,
    one_of,
    option,
    output,
    output_folder,
    overwrite,
    png_output_path,
    real,
    resumed_training_settings,
    seed,
    settings,
    verb,
    verbs,
    verbs_wanted,
    workers,
)

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
    """grow a {kind} layout with the conv NCA

    Grow a {kind} layout from the seed block with the conv NCA (random weights or saved ones) and write it,
    unrepaired, as a map JSON file.
    """
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
    """repeat a small {kind} layout to fill a larger size (the paper's tiling baseline)

    Repeat the part of FILE that the NCA grows (for warehouses, the storage area between the workstation columns)
    along both axes until it fills --size, cut it there from the top-left, add the fixed parts and write the result,
    unrepaired, as a map JSON file. The warehouse paper's baseline against growing large: tile a trained 33x36
    layout to 101x102, then repair it (the repair command) and evaluate it.
    """
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
    """repair a {kind} layout with the fewest tile changes (HiGHS MILP)

    Make FILE a valid {kind} layout changing as few cells as possible, with the MILP solved by HiGHS, and write it
    with the Hamming distance, similarity, proof status and time in its metadata. Exit 2 if the rules cannot be
    met.
    """
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
    """print a {kind} layout's measures

    Print the layout's tile counts and the original's measures {measures}
    """
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
    """run robots on a {kind} layout and print its throughput

    Simulate N robots {goals} on the layout in FILE for T steps, planning collision-free paths 10 steps ahead every
    5 steps, and print the throughput (tasks finished per step), the tasks finished, whether the floor congested
    (more than half of the robots stood still, not counting tasks, for 5 steps, which stops the run) and the wall
    time.
    """
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
    """judge a {kind} layout as the paper's tables do: success rate and throughput over many runs

    Simulate N robots on the {kind} layout in FILE in many runs (seeds drawn from --seed) and report the success
    rate (runs that did not congest) and the mean and standard error of the throughput over the successful runs,
    as the paper's tables do (N/A when every run congested). Training averages fewer, shorter runs (the problem's
    simulations and simulation_steps).
    """
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
    """draw one {kind} layout, or two side by side with the changed cells marked

    Draw FILE (and FILE2 beside it, cells that differ outlined in red) to a PNG image, each tile kind in the
    legend.
    """
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
    """train the maze agent (PPO with a PLR/ACCEL curriculum) in a run folder

    Train the learning maze agent: it sees the 5x5 cells in front of it and its direction, keeps a map of what it
    has seen and where it has walked, reads from it which way the goal or the nearest unexplored floor lies, and
    learns by PPO on random 16x16 mazes chosen by a curriculum that replays and edits the levels it still learns
    most from. The run folder gets checkpoints (the same command resumes it; more --updates go on),
    history.jsonl, learning.png and agent.pt. The defaults are the settings of the shipped agent
    (docs/maze_agent.pt).
    """
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


def cmd_test_agent(args: argparse.Namespace) -> int:
    """run the learning maze agent on maze files or random mazes and print its success rate

    Run the learned maze agent (the shipped docs/maze_agent.pt, or --weights) on the maze JSON files given (all of
    one size, with or without their outer wall), or on --count random mazes, and print the share of episodes that
    reached the goal within the horizon (twice the cells of the walled maze), with its standard error (over mazes,
    or over episodes for a single maze).
    """
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


def _size_option(kind: LayoutKind) -> Any:
    """An argparse ``type`` for a size of ``kind`` (``33x36`` or any ``RxC`` it can grow), checked before any work."""

    def parse(text: str) -> str:
        try:
            kind.size(text)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
        return text

    return parse


def _grown_pair(args: argparse.Namespace, kind: LayoutKind) -> tuple[np.ndarray, np.ndarray, str, np.ndarray | None]:
    """The small and large mazes (without their outer walls) the experiment plays, where they came from, and the
    generator that grew them (None for maze files)."""
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
        source = f"{args.run_dir} (elite {elite}), grown at {problem.settings.size} and {args.large_size}"
        return small, large, source, np.asarray(genome, dtype=np.float64)
    if not (args.small and args.large):
        raise InputError("give a maze RUN_DIR, or --small FILE and --large FILE (e.g. the paper's grown mazes)")
    pair = []
    for path in (args.small, args.large):
        pair.append(_grown_maze(_load(path, kind), kind))
    return pair[0], pair[1], f"{args.small} and {args.large}", None


def _check_keep(folder: Path | None) -> None:
    """Refuse a --keep folder that holds anything already: the experiment's files are never mixed with another's."""
    if folder is None:
        return
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise InputError(f"--keep {folder}: exists and is not an empty folder; give a new one")


def _keep(folder: Path, kind: LayoutKind, small: np.ndarray, large: np.ndarray, genome: np.ndarray | None,
          report: dict[str, Any]) -> None:  # fmt: skip
    """The mazes played, their generator and the rows, each written whole (temporary file, then rename)."""
    from evolution.files import atomic_write
    from structgen.nca import save_weights

    folder.mkdir(parents=True, exist_ok=True)
    for name, maze in (("small", small), ("large", large)):
        kind.grid(kind.complete(maze), name=name, kind=kind.name, source=report["source"]).save(folder / f"{name}.json")
    if genome is not None:
        save_weights(folder / "generator.npy", genome)
    atomic_write(folder / "experiment.json", json.dumps(report, indent=1) + "\n")


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
    """the paper's maze experiment: the agent on small and large grown mazes and on random baselines

    Grow a maze with a generator trained small (an elite of a maze RUN_DIR) at its own size and at --large-size,
    or take the two mazes from --small and --large files, run the learned agent on each --episodes times, make
    --baselines random mazes as the original does (as many walls as the large maze, placed uniformly, drawn again
    until the longest shortest path is within 80-120 % of the large maze's) and run it --baseline-episodes times on
    each; print the success rates beside the paper's (90 %, 93 %, 22 %).
    """
    from structgen.domains.layouts.maze.experiment import PAPER, maze_experiment
    from structgen.domains.layouts.maze.training import agent_policy

    kind = _kind(args)
    keep = Path(args.keep) if args.keep else None
    _check_keep(keep)
    small, large, source, genome = _grown_pair(args, kind)
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
    report = {"source": source, "rows": [dataclasses.asdict(r) for r in rows]}
    if keep is not None:
        _keep(keep, kind, small, large, genome, report)
    if args.json:
        print(json.dumps(report))
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


_GOALS = {
    "manufacturing": "visiting stations of kind 0, 1, 2, 0, ... in turn and standing 2, 5 or 10 steps on an endpoint beside "
    "each for its task",
    "warehouse": "fetching goals (an endpoint, then a workstation, and so on)",
}
_MEASURES = {
    "maze": "(pattern entropy, solvability, longest shortest path, and an agent's success rate and path length).",
    "layout": "(pattern entropy, shelf components) and whether it is valid.",
}
_PLANNERS = {
    "pp": "windowed prioritized planning, ranks layouts as the paper's simulator does, 2-6 %% below its throughput",
    "pbs": "windowed priority-based search with RHCR's start-cell rules, the paper's planner: carries the paper's robot "
    "counts at 101x102 and is within 1 %% of RHCR at 33x36, but jams on DSAGE's layout in some long runs",
    "pibt": "one step of look-ahead, fastest, but stalls in one-wide dead ends and ranks layouts differently",
}
_MAP_OUT = output("OUT.json", "map file to write")
_WEIGHTS = option("--weights", metavar="FILE", help="agent weights (a run folder's agent.pt; default the shipped agent)")
_MAZE_SEED = dict(high=2**32 - 1, metavar="S")


def _robot_options(kind: LayoutKind, steps: int, planner: str, seed_help: str) -> list[Adder]:
    """The options ``simulate`` and ``evaluate`` share: the map, robots, steps, planner, seed and task weights."""
    described = "; ".join(f"{name}: {_PLANNERS[name]}{' (default)' * (name == planner)}" for name in PLANNERS)
    return [
        option("file", metavar="FILE", help="map JSON file (a repaired, valid layout)"),
        number("--agents", 1, 10**6, 200, "robots"), number("--steps", 1, 10**7, steps, "steps per run", metavar="T"),
        option("--planner", choices=PLANNERS, default=planner, help=described), seed(seed_help, metavar="S"),
        *[flag("--uneven", "left-half workstations five times likelier goals")] * (kind.name == "warehouse"),
    ]  # fmt: skip


def _verbs(kind: LayoutKind) -> dict[str, Verb]:
    """The verbs of ``kind``'s layouts (a kind's domain adds those it names)."""
    sizes, maze, me = ", ".join(kind.sizes), kind.name == "maze", f"structgen {kind.name}"
    three_way = dict(choices=tuple(AUTO_YES_NO), default="auto")
    return verbs(
        verb("grow", cmd_generate,
             one_of(seed("random NCA (normal, sd 0.2, as the original's search starts) drawn with this seed"), nca_weights()),
             option("--size", default=kind.default_size, help=f"map size: {sizes}, or ROWSxCOLUMNS of the grown area"),
             number("--iterations", 0, 100_000, help="NCA steps (default: the paper's for the size, 50, or 200 at 101x102)"),
             number("--hidden", 1, 1024, HIDDEN, "hidden channels"), device(), _MAP_OUT,
             examples=[f"{me} grow --seed 1 -o layout.json", f"{me} grow --weights generator.npy --size 101x102 -o large.json"]),
        verb("tile", cmd_tile, option("file", metavar="FILE", help="map JSON file to repeat (a whole map)"),
             option("--size", required=True, help=f"size to fill: {sizes}, or ROWSxCOLUMNS of the grown area"), _MAP_OUT,
             examples=[f"{me} tile layout.json --size 101x102 -o tiled.json"]),
        verb("repair", cmd_repair, option("file", metavar="FILE", help="map JSON file (unrepaired)"), _MAP_OUT,
             real("--time-limit", 0, 86400, REPAIR_TIME_LIMIT, "seconds for HiGHS", above=True, metavar="S"),
             number("--threads", 1, 1024, 1, "HiGHS threads"), seed("HiGHS random seed", high=2**31 - 1),
             option("--greedy", **three_way, help="start HiGHS from the greedy repair: auto (above 4,000 cells), yes, no"),
             option("--round-relaxation", **three_way, help="before the full search, solve the linear relaxation and the "
                    "smaller MILP left by holding the tiles it decided; its answer ends the repair when it meets the "
                    "relaxation's bound: auto (warehouses of 1,000 to 4,000 cells with a time limit of 30 s or more), yes, no"),
             number("--good-enough", 0, 10**7, help="stop at the first valid layout that changes at most N cells, proven "
                    "optimal or not (default: search for the fewest changes until the time limit)"),
             *[option("--local", **three_way, help="first solve only around the cells that break a rule (and the cells "
                      "that can fix a wrong shelf count), holding the rest; its answer ends the repair, keeping a large "
                      "layout's pattern: auto (above 4,000 cells, when that region is at most 40 %% of the storage area), "
                      "yes, no"),
               number("--shelves", 0, 10**7, help="exact shelf count (default: the paper's for the map's size, 240 at "
                      "33x36)")] * (kind.name == "warehouse"),
             *[number("--agents", 0, 10**7, 200, "cells that must stay free of stations")] * (kind.name != "warehouse"),
             examples=[f"{me} repair layout.json -o repaired.json --time-limit 60"]),
        verb("simulate", cmd_simulate,
             *_robot_options(kind, 1000, "pp", "seed of the start cells, the goals and the planners' tie-breaks"),
             option("--frames", type=png_output_path, metavar="OUT.png", help="also draw six snapshots"), json_flag(),
             text={"goals": _GOALS.get(kind.name, _GOALS["warehouse"])},
             examples=[f"{me} simulate repaired.json --agents 200 --planner pbs --frames robots.png"]),
        verb("evaluate", cmd_evaluate, number("--simulations", 1, 10**5, 50, "runs (default 50, as the paper)", metavar="K"),
             workers(), *_robot_options(kind, 5000, "pbs", "seed the runs' seeds are drawn from"),
             json_flag("print one JSON object, with every run's throughput"),
             examples=[f"{me} evaluate repaired.json --simulations 10 --steps 5000 --planner pbs --workers 2"]),
        verb("show", cmd_show,
             option("files", nargs="+", metavar="FILE", help="one or two map JSON files (unrepaired, then repaired)"),
             output("OUT.png", "image to write"), dpi(),
             examples=[f"{me} show layout.json -o layout.png", f"{me} show layout.json repaired.json -o changes.png"]),
        verb("measure", cmd_measure, option("file", metavar="FILE", help="map JSON file"), json_flag(),
             *[option("--agent", choices=["learned", *sorted(AGENTS)], default="learned", help="agent to run (default "
                      "learned: the shipped learning agent, the maze domain's judge)"),
               option("--weights", metavar="FILE", help="the learned agent's weights (default the shipped agent)"),
               number("--episodes", 1, 10_000, 50, "episodes"), seed("episodes' seed")] * maze,
             text={"measures": _MEASURES["maze" if maze else "layout"]}, examples=[f"{me} measure layout.json --json"]),
        verb("train", cmd_train_agent,
             option("--run-dir", required=True, type=output_folder, metavar="DIR",
                    help="run folder (made, or resumed if it holds this training)"),
             settings(AgentSettings, _AGENT_FIELDS),
             flag("--no-way-on", "do not tell the network which way the goal or the nearest unexplored floor lies on its "
                  "map (the agents of structgen 0.4 and before; give it again to go on with such a run, or use structgen "
                  "resume)"),
             device("cpu"), overwrite(),
             examples=[f"{me} train --run-dir runs/maze_agent", f"{me} train --run-dir runs/maze_agent --updates 1000"]),
        verb("test-agent", cmd_test_agent, option("files", nargs="*", metavar="FILE", help="maze JSON files (none: random "
             "mazes)"), _WEIGHTS,
             option("--kind", dest="maze_kind", choices=MAZE_KINDS, default="rooms", help="random mazes' kind (default "
                    "rooms, never trained on)"),
             number("--size", 4, 256, 16, "random mazes' side"), number("--count", 1, 10**6, 200, "random mazes"),
             number("--episodes", 1, 10_000, 1, "episodes per maze"),
             seed("seed of the mazes and the agent's actions", **_MAZE_SEED), device("cpu"), json_flag(),
             examples=[f"{me} test-agent --kind rooms --size 32 --count 200", f"{me} test-agent maze.json"]),
        verb("experiment", cmd_experiment,
             option("run_dir", nargs="?", metavar="RUN_DIR", help="a maze evolution run (its generators trained small)"),
             option("--elite", default="longest", help="the generator: longest (default: the elite with the longest agent "
                    "path among those the agent solves in 90 %% of episodes), best, or index:I (the archive cell)"),
             option("--large-size", type=_size_option(kind), default="64x64", metavar="RxC", help="size to grow the large "
                    "maze at: ROWSxCOLUMNS, each at least 4, at most 4096 x 4096 cells"),
             option("--small", metavar="FILE", help="small maze JSON file, instead of a run"),
             option("--large", metavar="FILE", help="large maze JSON file, instead of a run"), _WEIGHTS,
             number("--episodes", 1, 100_000, 100, "runs on each grown maze"),
             number("--baselines", 1, 10_000, 100, "baseline mazes"),
             number("--baseline-episodes", 1, 10_000, 10, "runs on each baseline"),
             seed("seed of the baselines and the runs", **_MAZE_SEED), device("cpu"), json_flag(),
             option("--keep", metavar="DIR", help="also write into DIR (new or empty) the two mazes played (small.json, "
                    "large.json), the generator that grew them (generator.npy, from a RUN_DIR) and the rows "
                    "(experiment.json): --small DIR/small.json --large DIR/large.json repeats the experiment"),
             examples=[f"{me} experiment runs/maze", f"{me} experiment --small small.json --large large.json --json",
                       f"{me} experiment runs/maze --keep kept",
                       f"{me} experiment --small kept/small.json --large kept/large.json"]),
        kind=kind.name,
    )  # fmt: skip


def layout_view(tiles: np.ndarray, kind: LayoutKind, title: str) -> dict[str, Any]:
    """A layout as a report shows it: its picture, each tile in its kind's colour, and its tile counts."""
    from structgen.runs.report import hex_rgb, image_figure

    palette = np.array([hex_rgb(kind.colours[c]) for c in kind.vocabulary], dtype=np.uint8)
    counts = {f"tiles '{c}' ({kind.tile_names[c]})": int((tiles == i).sum()) for i, c in enumerate(kind.vocabulary)}
    return {"figure": image_figure(palette[tiles], f"{title}: {tiles.shape[0]} x {tiles.shape[1]}"), "fields": counts}


class LayoutCommands(DomainCommands):
    renamed = {"generate": "grow", "train-agent": "train"}  # until 0.5

    def __init__(self, kind: str, verbs: tuple[str, ...]) -> None:
        self.kind = kind
        self.verbs = verbs
        self.renamed = {old: new for old, new in self.renamed.items() if new in verbs}
        me = f"structgen {kind}"
        self.examples = {
            "export": [f"{me} export runs/{kind} best.json", f"{me} export runs/{kind} elite.json --elite index:120"]
        }

    def add_verbs(self, subparsers: Any, domain: Any, only: Collection[str] | None = None) -> None:
        declared = _verbs(KINDS[self.kind])
        subparsers = self.verb_parsers(subparsers)
        for name in verbs_wanted([v for v in declared if v in self.verbs], only):
            declared[name](subparsers)

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

    def report_view(self, problem: Any, genome: Any) -> dict[str, Any]:
        return layout_view(problem.grow(np.asarray(genome)[None])[0], problem.kind, "as grown (unrepaired)")

    def report_file(self, path: Path) -> dict[str, Any] | None:
        if path.is_dir():
            return None
        kind = KINDS[self.kind]
        return layout_view(_load(str(path), kind).tiles, kind, path.name)

    def export_elite(self, problem: Any, genome: Any, output: Path, args: argparse.Namespace, origin) -> str:
        _check_output(output, ".json")
        tiles = problem.grow(np.asarray(genome)[None])[0]
        grid = problem.kind.grid(tiles, name=output.stem, kind=problem.kind.name, **dict(origin))
        grid.save(output)
        return f"{output}: {problem.kind.name} {tiles.shape[0]}x{tiles.shape[1]} (unrepaired)"


WAREHOUSE_COMMANDS = LayoutCommands("warehouse", ("grow", "tile", "repair", "simulate", "evaluate", "show", "measure"))
MANUFACTURING_COMMANDS = LayoutCommands("manufacturing", ("grow", "tile", "repair", "simulate", "evaluate", "show", "measure"))
MAZE_COMMANDS = LayoutCommands("maze", ("grow", "tile", "show", "measure", "train", "test-agent", "experiment"))
