"""The verbs of Autoverse: ``structgen autoverse play|search|show|clone`` (``evolve`` comes with every domain).

A game is named by a JSON file (``rules``, ``rewards``, ``map``: what ``best/genome.json`` of a run holds, or what
``--save`` writes), by a run folder (its best game), or by ``--random SEED``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

from structgen.domains.autoverse.game import MUTATIONS
from structgen.domains.autoverse.train_settings import PRESETS, CloneSettings, TrainSettings
from structgen.ppo_settings import PPO_OPTIONS
from structgen.registry.commands import (
    MAX_SEED,
    DomainCommands,
    InputError,
    device,
    flag,
    given_settings,
    json_flag,
    number,
    option,
    output,
    output_folder,
    output_path,
    overwrite,
    resumed_training_settings,
    seed,
    settings,
    verb,
    verbs,
    write_by_suffix,
)

EXIT_OK = 0


def _mechanics(args: argparse.Namespace) -> Any:
    from structgen.domains.autoverse.engine import Mechanics

    return Mechanics.original() if args.original else Mechanics()


def load_game(args: argparse.Namespace) -> dict[str, Any]:
    from evolution.files import parse_json, read_text
    from structgen.domains.autoverse.game import game_from_json, random_game

    if sum(source is not None for source in (args.game, args.random, args.builtin)) != 1:
        raise InputError("give a GAME file or run folder, --random SEED or --builtin NAME (one of them)")
    if args.random is not None:
        return random_game(np.random.default_rng(args.random))
    if args.builtin is not None:
        from structgen.domains.autoverse.library import builtin_game

        return builtin_game(args.builtin)
    path = Path(args.game)
    if path.is_dir():
        path = path / "best" / "genome.json"
        if not path.is_file():
            raise InputError(f"{args.game}: not a run folder with a best game ({path} is missing)")
    data = parse_json(read_text(path, 10 << 20, what="a game JSON file"), str(path))
    return game_from_json(data, str(path))


def _parse_actions(text: str) -> np.ndarray:
    # Each action is one digit between commas (spaces around them allowed): "2,,2" has an empty action, not two.
    items = [item.strip() for item in text.split(",")]
    if len(text) > 10**6 or not items or any(item not in ("0", "1", "2", "3", "4") for item in items):
        raise argparse.ArgumentTypeError(f"expected actions 0-4 separated by commas, got {text[:60]!r}")
    return np.array([int(item) for item in items], dtype=np.int64)


def _save(game: dict[str, Any], path: Path | None) -> None:
    if path is None:
        return
    from evolution.files import atomic_write
    from structgen.domains.autoverse.game import game_to_json

    atomic_write(path, json.dumps(game_to_json(game)) + "\n")


# -- play -----------------------------------------------------------------------------------------------------------------
def cmd_play(args: argparse.Namespace) -> int:
    """play a game with given or random actions and print the return

    Step GAME with ACTIONS (or --steps random ones) and print the return; optionally save the game and a GIF of the
    play. Actions: 0 and 1 turn, 2 moves forward, 3 back, 4 places force in front.
    """
    from structgen.domains.autoverse.show import playtrace_gif, replay

    game = load_game(args)
    if args.actions is None:
        actions = np.random.default_rng(args.seed).integers(0, 5, size=args.steps)
    else:
        actions = args.actions
    _, returns, _ = replay(game, actions, mechanics=_mechanics(args))
    _save(game, args.save)
    if args.gif is not None:
        playtrace_gif(game, actions, args.gif, mechanics=_mechanics(args))
    if args.json:
        print(json.dumps({"actions": actions.tolist(), "return": returns[-1], "returns": returns[1:]}))
    else:
        print(f"{len(actions)} actions, return {returns[-1]:g}" + (f"; {args.gif}" if args.gif else ""))
    return EXIT_OK


# -- search ---------------------------------------------------------------------------------------------------------------
def cmd_search(args: argparse.Namespace) -> int:
    """find a game's best play with best-first search and print its fitness

    Run greedy best-first search on cumulative reward for BUDGET expansions and print the best return, the
    iteration it was first found at (the evolution's fitness) and the actions that reach it.
    """
    from structgen.domains.autoverse.search import search, search_fitness
    from structgen.domains.autoverse.show import playtrace_gif

    game = load_game(args)
    result = search([game], args.budget, args.seed, device=args.device, mechanics=_mechanics(args))[0]
    _save(game, args.save)
    if args.gif is not None:
        playtrace_gif(game, result.actions, args.gif, mechanics=_mechanics(args))
    summary = {
        "fitness": search_fitness(result),
        "best_iteration": result.best_iteration,
        "best_return": result.best_return,
        "iterations": result.iterations,
        "expansions": result.expansions,
        "actions": result.actions.tolist(),
    }
    if args.json:
        print(json.dumps(summary))
    else:
        print(
            f"best return {result.best_return:g} first found at iteration {result.best_iteration} "
            f"(of {result.expansions} expansions, budget {args.budget}); actions {','.join(map(str, result.actions))}"
        )
    return EXIT_OK


# -- show -----------------------------------------------------------------------------------------------------------------
def cmd_show(args: argparse.Namespace) -> int:
    """draw a game (PNG: map and rules) or a playtrace (GIF)

    Draw GAME: a .png shows the initial map and each rule as before/after 1x3 patterns with its reward (and, with
    actions, the final map and the return along the play); a .gif animates a playtrace.
    """
    from structgen.domains.autoverse.search import search
    from structgen.domains.autoverse.show import draw_game, playtrace_gif

    game = load_game(args)
    actions = args.actions
    if actions is None and args.search:
        actions = search([game], args.search, 0, mechanics=_mechanics(args))[0].actions
    suffix = args.output.suffix.lower()
    if suffix == ".gif":
        if actions is None:
            raise InputError(f"{args.output}: a GIF shows a playtrace; give --actions or --search BUDGET")
        playtrace_gif(game, actions, args.output, mechanics=_mechanics(args))
    elif suffix == ".png":
        from structgen.domains.autoverse.library import TILES

        draw_game(game, args.output, actions, TILES.get(args.builtin), mechanics=_mechanics(args))
    else:
        raise InputError(f"{args.output}: write a .png (map and rules) or a .gif (a playtrace)")
    print(args.output)
    return EXIT_OK


# -- clone ----------------------------------------------------------------------------------------------------------------
def cmd_clone(args: argparse.Namespace) -> int:
    """train a policy by behaviour cloning on a run's playtraces and evaluate it

    Collect the best playtrace of every distinct game a run evaluated (fitness at least --min-fitness), split the
    games into train/val/test as the original does, train the original's network by behaviour cloning on
    observations of the traces, and evaluate it on every game for --eval-steps steps in the original's normalised
    return. Writes OUTPUT/policy.pt and OUTPUT/report.json.
    """
    from structgen.domains.autoverse.clone import clone_run

    values = given_settings(args, _CLONE_FIELDS) | _observed(args)
    try:
        settings = CloneSettings(**values, device=args.device, original_pairing=args.original_pairing)
    except ValueError as err:
        raise InputError(str(err)) from None
    report = clone_run(Path(args.run_dir), settings, args.output, progress=not args.json)
    if args.json:
        print(json.dumps(report))
    else:
        for split in ("train", "val", "test"):
            if f"{split}_mean" in report:
                print(f"{split}: {report[f'{split}_games']} games, mean normalised return {report[f'{split}_mean']:.2f}")
        print(f"{args.output}: policy and report")
    return EXIT_OK


# -- train ----------------------------------------------------------------------------------------------------------------
#: The settings train takes as options, each made from the field's limit (TrainSettings.limits); the defaults shown
#: are the cpu preset's (the settings' own).
_TRAIN_FIELDS = (
    "clone_steps",
    "clone_batch",
    "clone_learning_rate",
    *PPO_OPTIONS,
    "evaluate_every",
    "eval_steps",
    "eval_games",
    "checkpoint_every",
    "evolve_every",
    "pool",
    "min_fitness",
    "seed",
)


def cmd_train(args: argparse.Namespace) -> int:
    """train a player for a run's games: behaviour cloning, then PPO (optionally on games evolved for it)

    Clone a policy from the search playtraces of the Autoverse run RUN_DIR (its games split into
    train/validation/test as the original splits them), then train it by PPO on the training games, each episode on
    a game drawn at random; with --evolve-every K, every K updates the games are mutated and those where the agent's
    value prediction errs most are kept (the paper's open-ended phase). Evaluates on every split as it goes. OUT_DIR
    gets checkpoints (the same command resumes it; more --updates go on; so does structgen resume OUT_DIR),
    history.jsonl, learning.png (evolution.png) and policy.pt. Defaults are the 'cpu' preset (about 4 minutes on 2
    cores for the games of a 100-generation run); --preset original takes the original's settings (meant for a
    GPU).
    """
    from structgen.domains.autoverse.train import train

    values = dict(PRESETS[args.preset])
    values.update(given_settings(args, (*_TRAIN_FIELDS, "evolve_mutation")))
    try:
        settings = TrainSettings(**values, **_observed(args), device=args.device)
    except ValueError as err:
        raise InputError(str(err)) from None
    rows = train(args.run_dir, args.output, settings, overwrite=args.overwrite, progress=True)
    _print_training(args.output, rows)
    return EXIT_OK


def _print_training(output: Path, rows: list[dict[str, Any]]) -> None:
    from structgen.domains.autoverse.train import LEARNING_PLOT, POLICY_FILE

    tested = [row for row in rows if "test" in row]
    if tested:
        first, last = tested[0], tested[-1]
        print(
            f"{output}: {last['update']} PPO updates; mean normalised return per episode on the test games "
            f"{first['test']:.2f} after cloning, {last['test']:.2f} at the end (train {last['train']:.2f})"
        )
    print(f"policy: {Path(output) / POLICY_FILE}; learning curve: {Path(output) / LEARNING_PLOT}")


#: Where a verb's game comes from.
_GAME = (
    option("game", nargs="?", metavar="GAME", help="game JSON file, or a run folder (its best game)"),
    number("--random", 0, MAX_SEED, metavar="SEED", help="a random game from this seed instead"),
    option("--builtin", choices=("maze", "lava_maze", "sokoban"), help="a hand-written game instead (after the "
           "original's; docs/autoverse.md)"),
    flag("--original", "the original's mechanics: actions other than placing clear force in front of the player, and "
         "rules with an empty input fire on every cell"),
)  # fmt: skip


def _observed(args: argparse.Namespace) -> dict[str, Any]:
    """What the player sees, as the options of :data:`_OBSERVATION` give it."""
    return {name: getattr(args, name) for name in ("window", "hide_rules", "padding", "blank_window")}


#: The settings clone takes as options, each made from the field's limit (CloneSettings.limits).
_CLONE_FIELDS = ("hidden", "steps", "batch_size", "learning_rate", "eval_steps", "min_fitness", "seed")
#: What the player sees: every setting of :class:`.engine.Observation`.
_OBSERVATION = (
    option("--window", type=int, default=-1, choices=(-1, 5, 10, 20), help="side of the view around the player (-1: the "
           "whole map)"),
    flag("--hide-rules", "zero the rules and rewards in the observation"),
    option("--padding", choices=("zeros", "wrap"), default="zeros", help="beyond the map's edges the view shows zeros "
           "(default, as the paper and the original) or wraps around the torus"),
    flag("--blank-window", "the original environment's windowed view, all zeros for any window but the whole map (to "
         "reproduce it)"),
)  # fmt: skip
_ACTIONS = option("--actions", type=_parse_actions, metavar="A,A,...", help="actions 0-4, comma-separated")
_SAVE = option("--save", type=output_path, metavar="OUT.json", help="write the game as JSON")


def game_view(game: dict[str, Any]) -> dict[str, Any]:
    """A game as a report shows it: its initial map, and how many rules and what rewards it has."""
    from structgen.domains.autoverse.show import map_image
    from structgen.runs.report import image_figure

    picture = map_image(game["map"], scale=1)  # a cell a square: the player white, several tiles their mean colour
    rewards = np.asarray(game["rewards"], dtype=float)
    fields = {"rules": int(len(rewards)), "rewards (sum)": float(rewards.sum())}
    return {"figure": image_figure(picture, f"initial map: {picture.shape[0]} x {picture.shape[1]}"), "fields": fields}


class AutoverseCommands(DomainCommands):
    renamed = {"search": "evaluate"}  # until 0.5
    examples = {
        "export": ["structgen autoverse export runs/autoverse best.json", "structgen autoverse export runs/autoverse best.png"]
    }
    adders = verbs(
        verb("play", cmd_play, *_GAME, _ACTIONS, number("--steps", 1, 10**6, 101, "random actions"),
             seed("seed of random actions", metavar="S"),
             option("--gif", type=output_path, metavar="OUT.gif", help="write an animation of the play"), _SAVE, json_flag(),
             examples=["structgen autoverse play --builtin maze --actions 2,2,0,2",
                       "structgen autoverse play game.json --steps 50"]),
        verb("evaluate", cmd_search, *_GAME, number("--budget", 1, 10**7, 200, "expansions"),
             seed("seed of the child order", metavar="S"), device("cpu", "torch device of the engine: cpu, cuda, cuda:N"),
             option("--gif", type=output_path, metavar="OUT.gif", help="write an animation of the best play"), _SAVE,
             json_flag(),
             examples=["structgen autoverse evaluate --random 6 --budget 200 --save game.json",
                       "structgen autoverse evaluate --builtin maze --budget 2000"]),
        verb("show", cmd_show, *_GAME, output("OUT.png|OUT.gif"),
             option("--actions", type=_parse_actions, metavar="A,A,...", help="a playtrace to draw"),
             number("--search", 1, 10**7, metavar="BUDGET", help="draw the best play search finds"),
             examples=["structgen autoverse show game.json -o game.png",
                       "structgen autoverse show game.json -o play.gif --search 200"]),
        verb("clone", cmd_clone, option("run_dir", metavar="RUN_DIR", help="an Autoverse run folder"),
             option("-o", "--output", required=True, type=output_folder, metavar="OUT_DIR", help="folder to write"),
             *_OBSERVATION,
             settings(CloneSettings, _CLONE_FIELDS),
             flag("--original-pairing", "pair each observation with the action that led to it"),
             device("cpu"), json_flag("print the report as one JSON object"),
             examples=["structgen autoverse clone runs/autoverse -o runs/autoverse-bc --window 5"]),
        verb("train", cmd_train, option("run_dir", metavar="RUN_DIR", help="an Autoverse evolution run folder (its playtraces)"),
             option("-o", "--output", required=True, type=output_folder, metavar="OUT_DIR",
                    help="training folder (made, or resumed)"),
             option("--preset", choices=tuple(PRESETS), default="cpu", help="starting settings"),
             settings(TrainSettings, _TRAIN_FIELDS, "cpu preset:"),
             option("--evolve-mutation", choices=MUTATIONS, help=f"how evolved games differ from their parents (cpu preset: "
                    f"{TrainSettings.evolve_mutation})"),
             *_OBSERVATION, device("cpu"), overwrite("a training folder that holds another training"),
             examples=["structgen autoverse train runs/autoverse -o runs/av-player"]),
    )  # fmt: skip

    def resume_run(self, kind: str, run_dir: Path, args: argparse.Namespace) -> int:
        from structgen.domains.autoverse.train import RUN_KIND, read_settings, source_run, train

        if kind != RUN_KIND:
            return super().resume_run(kind, run_dir, args)
        settings = resumed_training_settings(run_dir, args, read_settings, "an Autoverse player's training")
        _print_training(run_dir, train(source_run(run_dir), run_dir, settings, progress=True))
        return EXIT_OK

    def describe_run(self, kind: str, run_dir: Path) -> tuple[dict[str, Any], str]:
        from structgen.domains.autoverse.train import RUN_KIND, training_summary

        if kind != RUN_KIND:
            return super().describe_run(kind, run_dir)
        summary = training_summary(run_dir)
        text = (
            f"{run_dir}: Autoverse player training on {summary['source_run']}, {summary['updates_done']} of "
            f"{summary['updates']} PPO updates"
            + (f"; last test return {summary['test']:.2f} per episode" if summary["test"] is not None else "")
            + ("; policy.pt written" if summary["finished"] else "; resume with structgen resume")
        )
        return summary, text

    def report_view(self, problem: Any, genome: Any) -> dict[str, Any]:
        return game_view(genome)

    def report_file(self, path: Path) -> dict[str, Any] | None:
        from evolution.files import parse_json, read_text
        from structgen.domains.autoverse.game import game_from_json

        if path.is_dir():
            return None
        return game_view(game_from_json(parse_json(read_text(path, 10 << 20, what="a game JSON file"), str(path)), str(path)))

    def export_elite(self, problem: Any, genome: Any, output: Path, args: argparse.Namespace, origin) -> str:
        from structgen.domains.autoverse.show import draw_game

        return write_by_suffix(output, {".json": lambda path: _save(genome, path), ".png": lambda path: draw_game(genome, path)},
                               "Autoverse game")  # fmt: skip


AUTOVERSE_COMMANDS = AutoverseCommands()
