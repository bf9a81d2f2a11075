"""The shipped maze agent against its baselines on held-out mazes: success rate over mazes, with standard errors.

    python benchmarks/maze_agent.py [--weights docs/maze_agent.pt] [--count 200] [--size 16] [--seed 2026]
        [--kinds rooms,perfect] [--compare NAME=FILE ...] [--skip "random walk"]

Mazes: ``rooms`` (a kind the agent never trained on), ``perfect`` (carved corridors with no wall knocked down:
one path between any two cells, a harder case of a trained kind) and fresh ``scattered`` and ``carved`` mazes (the
kinds it trained on, seeds it never saw). One episode per maze, horizon twice the walled maze's cells. Baselines:
the same network untrained, and the scripted agents (the wall follower with 5 % random actions, which breaks its
loops; the explorer, which remembers what it saw and walks to the nearest unseen floor; the random walk).
"""

from __future__ import annotations

import argparse
import platform
import time

import numpy as np
import torch

from structgen.domains.layouts.maze.agent import MazePolicy, run_agent
from structgen.domains.layouts.maze.env import random_maze
from structgen.domains.layouts.maze.training import load_agent, shipped_agent_path
from structgen.domains.layouts.maze.walkers import WallFollower, run_episodes


def mazes_of(kind: str, count: int, size: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng([seed, ["rooms", "perfect", "scattered", "carved"].index(kind)])
    return [random_maze(rng, size, kind) for _ in range(count)]  # a perfect maze draws as a carved one of density 0


def summary(successes: np.ndarray) -> str:
    error = successes.std(ddof=1) / np.sqrt(len(successes))
    return f"{successes.mean():6.1%} ± {error:4.1%}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--weights", default=None, help="agent weights (default the shipped docs/maze_agent.pt)")
    parser.add_argument("--count", type=int, default=200, help="mazes of each kind (default 200)")
    parser.add_argument("--size", type=int, default=16, help="maze side without the outer wall (default 16)")
    parser.add_argument("--seed", type=int, default=2026, help="seed of the mazes and the runs (default 2026)")
    parser.add_argument(
        "--kinds", default="rooms,perfect,scattered,carved", help="maze kinds, comma-separated (default all four)"
    )
    parser.add_argument(
        "--compare",
        nargs="*",
        default=[],
        metavar="NAME=FILE",
        help="more learned agents as baselines, each named, e.g. 'agent 0.4=docs/maze_agent_0.4.pt'",
    )
    parser.add_argument("--skip", nargs="*", default=[], metavar="NAME", help="rows to leave out (slow on large mazes)")
    args = parser.parse_args()
    torch.manual_seed(args.seed)
    policy, about = load_agent(args.weights or shipped_agent_path())
    untrained = MazePolicy(about["hidden"], way_on=about.get("way_on", False))
    scripted = {
        "wall follower": lambda: WallFollower(epsilon=0.05),
        "explorer": lambda: "explorer",
        "random walk": lambda: "random_walk",
    }
    compared = {name: load_agent(file)[0] for name, file in (item.split("=", 1) for item in args.compare)}
    kinds = args.kinds.split(",")
    print(
        f"{args.count} mazes of {args.size}x{args.size} of each kind, one episode each; success rate ± standard error, "
        "then mean steps (a failure counts the horizon)"
    )
    print(f"{'agent':<20}" + "".join(f"{k:>25}" for k in kinds) + f"{'seconds':>9}")
    agents = {"learned (shipped)": policy, **compared, "untrained": untrained, **scripted}
    for name, agent in agents.items():
        if name in args.skip:
            continue
        began = time.perf_counter()
        cells = []
        for kind in kinds:
            mazes = mazes_of(kind, args.count, args.size, args.seed)
            if isinstance(agent, MazePolicy):
                results = run_agent(agent, mazes, seed=args.seed)
                reached, steps = results.reached, results.steps
            else:
                runs = [run_episodes(m, agent(), episodes=1, seed=args.seed + i) for i, m in enumerate(mazes)]
                reached, steps = np.array([r.success_rate for r in runs]), np.array([r.mean_steps for r in runs])
            cells.append(f"{summary(reached)} {steps.mean():>6,.0f}")
        print(f"{name:<20}" + "".join(f"{c:>25}" for c in cells) + f"{time.perf_counter() - began:>9.1f}", flush=True)
    print(f"machine: {platform.processor() or platform.machine()}, torch {torch.__version__}, {torch.get_num_threads()} threads")


if __name__ == "__main__":
    main()
