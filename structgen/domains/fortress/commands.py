"""The verbs of the Amorphous Fortress: ``structgen fortress evaluate|replay|show|robustness`` (``evolve`` comes with every
domain).

A world is named by a fortress file (the original's format: ``FORTS/*.txt``, saved elites, what ``--save`` or an
export writes), by a run folder (its best world, or ``--elite index:I`` for an archive cell), or by ``--random SEED``.
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path
from typing import Any

import numpy as np

from structgen.registry.commands import (
    EXIT_OK,
    MAX_SEED,
    DomainCommands,
    InputError,
    flag,
    json_flag,
    number,
    option,
    output,
    output_path,
    png_output_path,
    print_table,
    seed,
    seed_run_options,
    verb,
    verbs,
    write_by_suffix,
)


def _rules(args: argparse.Namespace) -> Any:
    from structgen.domains.fortress.engine import RULES

    return RULES[args.rules]


def load_world(args: argparse.Namespace) -> tuple[Any, str]:
    """The world the arguments name, and a label for it."""
    from structgen.domains.fortress.formats import read_fortress_file
    from structgen.domains.fortress.world import random_world

    if (args.world is None) == (args.random is None):
        raise InputError("give a WORLD file or run folder, or --random SEED (one of them)")
    if args.random is not None:
        return random_world(np.random.default_rng(args.random)).to_file(), f"random world {args.random}"
    path = Path(args.world)
    if path.is_dir():
        from structgen.domains.fortress import FORTRESS
        from structgen.domains.fortress.problem import FortressProblem
        from structgen.runs import elite_genome, open_run

        folder, experiment = open_run(path)
        if experiment.domain != FORTRESS.id:
            raise InputError(f"{path}: a run of the {experiment.domain} domain, not a fortress run")
        return elite_genome(folder, FortressProblem(), args.elite).to_file(), f"{path} ({args.elite})"
    if not path.is_file():
        raise InputError(f"{path}: no such fortress file or run folder")
    world = read_fortress_file(path)
    if not world.initial:  # an entity file (the original's ENT/*.txt) defines classes and places nothing
        logging.getLogger("structgen").warning(
            "%s places no entities (no -- INIT ENT POS -- or -- INIT FORT -- block): the world starts empty", path
        )
    return world, str(path)


def _simulate(args: argparse.Namespace, world: Any, label: str) -> Any:
    """The world's one simulation under ``--seed`` and ``--steps``, every tick recorded."""
    from structgen.domains.fortress.engine import simulate

    return simulate([world], [args.seed], args.steps, _rules(args), record=True, where=[label])


def _save(world: Any, path: Path | None) -> None:
    if path is not None:
        from evolution.files import atomic_write
        from structgen.domains.fortress.formats import format_fortress

        atomic_write(path, format_fortress(world))


# -- run ------------------------------------------------------------------------------------------------------------------
def cmd_run(args: argparse.Namespace) -> int:
    """simulate a world and print its final map and the population of each class

    Simulate WORLD for --steps ticks under --seed and print the final map (the original's text form), why it
    stopped, the share of its machines visited, and how many entities of each class are left.
    """
    from structgen.domains.fortress.engine import describe
    from structgen.domains.fortress.show import map_text

    world, label = load_world(args)
    outcome = _simulate(args, world, label)
    trace = outcome.traces[0][0]
    chars = list(world.classes)
    populations = dict(zip(chars, trace.populations(chars)[-1].tolist()))
    summary = describe(outcome, 0, 0) | {"populations": populations, "map": map_text(trace.entities[-1])}
    _save(world, args.save)
    if args.json:
        print(json.dumps(summary))
        return EXIT_OK
    print(summary["map"])
    print(
        f"{label}, seed {args.seed}: stopped after {summary['ticks']} ticks ({summary['stopped']}); "
        f"{summary['entities']} entities; visited {summary['visited_nodes']} nodes and {summary['visited_edges']} "
        f"edges (fitness {summary['fitness']:.3f})"
    )
    print("population: " + ", ".join(f"{c} {n}" for c, n in summary["populations"].items()))
    return EXIT_OK


# -- replay ---------------------------------------------------------------------------------------------------------------
def cmd_replay(args: argparse.Namespace) -> int:
    """print a simulation tick by tick, or write it as an animated GIF or a strip of frames

    Simulate WORLD and print its map after every --every ticks (or, with --json, every entity of every tick and the
    nodes and edges visited); --gif writes an animation (one frame a tick), --strip a PNG of evenly spaced frames.
    """
    from structgen.domains.fortress.show import map_text, trace_gif, trace_strip

    world, label = load_world(args)
    outcome = _simulate(args, world, label)
    trace = outcome.traces[0][0]
    chars = list(world.classes)
    if args.json:
        visits = outcome.visit_sets(0, 0, [world])
        print(
            json.dumps(
                {
                    "entities": [[list(e) for e in entities] for entities in trace.entities],
                    "visits": {c: {"nodes": sorted(v["nodes"]), "edges": sorted(v["edges"])} for c, v in visits.items()},
                }
            )
        )
    elif not args.quiet:
        for t, entities in enumerate(trace.entities):
            if t % args.every == 0 or t == len(trace.entities) - 1:
                print(f"-- tick {t}: {len(entities)} entities --")
                print(map_text(entities))
    written = []
    if args.gif is not None:
        written.append(trace_gif(trace, chars, args.gif))
    if args.strip is not None:
        written.append(trace_strip(trace, chars, args.strip, frames=args.frames))
    for path in written:
        print(path)
    return EXIT_OK


# -- show -----------------------------------------------------------------------------------------------------------------
def cmd_show(args: argparse.Namespace) -> int:
    """draw a world's initial map and machine sizes, and the population of each class over a simulation

    Write OUT.png with WORLD's initial map and the nodes and edges of each class; --populations also simulates it
    and plots how many entities of each class there are after each tick.
    """
    from evolution.files import atomic_write
    from evolution.plots import figure_png
    from structgen.domains.fortress.show import draw_world, population_figure

    world, label = load_world(args)
    trace = _simulate(args, world, label).traces[0][0] if args.populations is not None else None
    draw_world(world, args.output)
    print(f"{args.output}: initial map and machine sizes")
    if trace is not None:
        figure = population_figure(trace, list(world.classes), f"{Path(label).name}: population by class, seed {args.seed}")
        atomic_write(args.populations, figure_png(figure))
        print(f"{args.populations}: population of each class over {len(trace.entities) - 1} ticks")
    return EXIT_OK


# -- robustness -----------------------------------------------------------------------------------------------------------
def cmd_robustness(args: argparse.Namespace) -> int:
    """re-evaluate runs' archives on new seeds and on longer episodes (the paper's robustness table)

    For one or more fortress MAP-Elites runs: re-simulate every elite of each run on new seeds (as many as the run
    used, after them) and on new seeds with --longer times longer episodes, average the new results with the stored
    ones and re-bin them into a fresh archive per run (as the original does); merge the runs' archives (best elite
    per cell), and print QD score, cells filled, mean and best fitness of every archive.
    """
    from evolution.files import atomic_write
    from structgen.domains.fortress.robustness import open_runs, reevaluate

    folders, experiment = open_runs(args.run_dirs)
    report = reevaluate(folders, experiment, longer=args.longer, chunk=args.chunk, progress=not args.json)
    if args.output is not None:
        atomic_write(args.output, json.dumps(report, indent=1) + "\n")
    if args.json:
        print(json.dumps(report))
    else:
        width = max(len(row["name"]) for row in report["rows"]) + 2
        print(f"{'archive':<{width}}{'QD score':>10}{'cells':>8}{'mean fitness':>14}{'best':>8}")
        for row in report["rows"]:
            print(
                f"{row['name']:<{width}}{row['qd_score']:>10.1f}{row['cells']:>8}{row['mean_fitness']:>14.3f}{row['best']:>8.3f}"
            )
    return EXIT_OK


def cmd_experiment(args: argparse.Namespace) -> int:
    """one of the paper's experiments end to end: 10 MAP-Elites runs, then its half of Table 3

    Run the paper's configuration once per seed (OUT_DIR/seed-S; a folder there is resumed, or kept if finished),
    several runs at a time, then re-evaluate every archive as the paper's Table 3 does (on new seeds, and on new
    seeds with --longer times longer episodes; each run re-binned, the runs merged best per cell) and write
    OUT_DIR/table.json and OUT_DIR/table.md beside the paper's numbers.
    """
    from structgen.domains.fortress.experiment import run_experiment, table_markdown

    report = run_experiment(
        args.measures, args.out_dir, config=args.config, seeds=args.seeds, parallel=args.parallel, threads=args.threads,
        cluster=args.cluster or "", generations=args.generations, longer=args.longer, progress=not args.json,
        optimizer=args.optimizer,
    )  # fmt: skip
    return print_table(report, args, table_markdown)


def cmd_figure(args: argparse.Namespace) -> int:
    """draw one of the paper's result figures from run folders (archive heatmaps, robustness, populations)

    archive: the archive of one run, or the best elite per cell over several, as a heatmap over its measures
    coloured by --colour (Figures 4, 7a/7b, 8a/8b); robustness: one run's archive as evolved, on new seeds, and on
    new seeds with --longer times longer episodes (Figure 5); populations: entities of each class over --longer
    times the evolution episode for the highest-entropy elite and the two ends of the entities measure (Figure 6).
    """
    from structgen.domains.fortress import figures

    if args.kind == "archive":
        written = figures.archive_figure(args.run_dirs, args.output, args.colour)
    elif args.kind == "robustness":
        if len(args.run_dirs) != 1:
            raise InputError("the robustness figure shows one run: give one RUN_DIR")
        written = figures.robustness_figure(args.run_dirs[0], args.output, longer=args.longer)
    else:
        written = figures.populations_figure(args.run_dirs, args.output, longer=args.longer, seed=args.seed)
    print(written)
    return EXIT_OK


#: Where a verb's world comes from, and how it is simulated.
_WORLD = (
    option("world", nargs="?", metavar="WORLD", help="fortress file, or a run folder (its best world)"),
    option("--elite", default="best", metavar="best|index:I", help="which world of a run folder"),
    number("--random", 0, MAX_SEED, metavar="SEED", help="a random world from this seed instead"),
    number("--steps", 0, 10**6, 100, "ticks at most"),
    seed("simulation seed", metavar="S"),
    option("--rules", choices=["code", "af-paper", "qd-paper"], default="code", help="whose rules: the original code's "
           "(default); 'af-paper', the first paper's words where they differ (nextTo north/south/east/west only, a stop "
           "after 20 ticks without an event, more than 120 entities overpopulate); 'qd-paper', the quality-diversity "
           "paper's (nextTo north/south/east/west only, move_wall blocked by any entity of its class). docs/fortress.md "
           "quotes the sentence behind each"),
    option("--paper-rules", action="store_const", const="af-paper", dest="rules", help="the same as --rules af-paper"),
)  # fmt: skip
_LONGER = number("--longer", 2, 100, 5, "episode length factor", metavar="X")
_RUNS = option("run_dirs", nargs="+", metavar="RUN_DIR", help="fortress MAP-Elites run folders (same settings)")


class FortressCommands(DomainCommands):
    renamed = {"run": "evaluate"}  # until 0.5
    examples = {
        "export": ["structgen fortress export runs/af best.txt", "structgen fortress export runs/af elite.png --elite index:40"]
    }
    adders = verbs(
        verb("evaluate", cmd_run, *_WORLD, json_flag(),
             option("--save", type=output_path, metavar="OUT.txt", help="write the world as a fortress file"),
             examples=["structgen fortress evaluate --random 4 --steps 100 --save world.txt",
                       "structgen fortress evaluate runs/af --elite best"]),
        verb("replay", cmd_replay, *_WORLD,
             number("--every", 1, 10**6, 1, "print every K-th tick", metavar="K"),
             flag("--quiet", "print no maps, only the files written"),
             json_flag("print one JSON object instead of maps: 'entities', per tick (0 = the start) the live entities as "
                       "[class, x, y, node] in creation order, and 'visits', per class the nodes and edges visited"),
             option("--gif", type=output_path, metavar="OUT.gif", help="write an animated GIF"),
             option("--strip", type=png_output_path, metavar="OUT.png", help="write a PNG strip of frames"),
             number("--frames", 2, 50, 6, "frames in the strip"),
             examples=["structgen fortress replay world.txt --steps 50 --every 10",
                       "structgen fortress replay runs/af --gif af.gif"]),
        verb("show", cmd_show, *_WORLD, output("OUT.png", "picture to write"),
             option("--populations", type=png_output_path, metavar="OUT.png", help="also plot populations over time"),
             examples=["structgen fortress show world.txt -o world.png --populations populations.png"]),
        verb("robustness", cmd_robustness, _RUNS, _LONGER, number("--chunk", 1, 10**5, 256, "worlds per engine call"),
             output("OUT.json", "write the table as JSON", required=False), json_flag(),
             examples=["structgen fortress robustness runs/exp1/seed-0 -o robustness.json"]),
        verb("experiment", cmd_experiment,
             option("measures", choices=["entities_nodes", "entities_entropy"], help="the experiment: its measures"),
             seed_run_options(config_default="configs/fortress_paper.toml", config_help="default "
                              "configs/fortress_paper.toml: the paper's run", seeds=list(range(20, 30)),
                              seeds_help="default 20 to 29, the original's sweep"),
             number("--threads", 1, 1024, 1, "engine threads of each run (default 1: on a few cores, runs side by side "
                    "use them best)", metavar="T"),
             option("--cluster", metavar="ADDRESS", help="run the seeds on the Dask scheduler at ADDRESS instead"),
             number("--generations", 1, 10**7, help="generations of each run (default: the config's)"), _LONGER,
             examples=["structgen fortress experiment entities_nodes runs/exp1 --seeds 0 1 2"]),
        verb("figure", cmd_figure, option("kind", choices=["archive", "robustness", "populations"], help="which figure"),
             _RUNS, output("OUT.png", "picture to write"),
             option("--colour", choices=["fitness", "entropy", "nodes"], default="fitness", help="archive: colour cells "
                    "by fitness (default), by the entropy of the class sizes or by total nodes"),
             _LONGER, seed("populations: simulation seed", high=2**31, metavar="S"),
             examples=["structgen fortress figure archive runs/exp1/seed-0 -o archive.png"]),
    )  # fmt: skip

    def report_view(self, problem: Any, genome: Any) -> dict[str, Any]:
        from structgen.domains.fortress.show import world_view

        return world_view(genome.to_file())

    def report_file(self, path: Path) -> dict[str, Any] | None:
        from structgen.domains.fortress.formats import read_fortress_file
        from structgen.domains.fortress.show import world_view

        return None if path.is_dir() else world_view(read_fortress_file(path))

    def export_elite(self, problem: Any, genome: Any, output: Path, args: argparse.Namespace, origin) -> str:
        from structgen.domains.fortress.show import draw_world

        genome = genome.to_file()  # the run's array world, as the original's text (.txt)
        return write_by_suffix(output, {".txt": lambda path: _save(genome, path), ".png": lambda path: draw_world(genome, path)},
                               "fortress world")  # fmt: skip


FORTRESS_COMMANDS = FortressCommands()
