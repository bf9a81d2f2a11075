"""Agent-steps per second of the batched maze environment, observations included.

    python benchmarks/maze_env.py [--mazes 1024] [--size 16] [--steps 300] [--device cpu]

Random actions on random scattered mazes (episodes that end restart in the same step); median of 3 timed runs after
one untimed, at each torch thread count from 1 to the cores this process may use (CPU), or once on a GPU.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np
import torch

from structgen.domains.layouts.maze.env import TorchMazes, random_maze


def rate(batch: TorchMazes, actions: torch.Tensor) -> float:
    batch.reset()
    began = time.perf_counter()
    for row in actions:
        batch.step(row)
    if batch.device.type == "cuda":
        torch.cuda.synchronize()
    return actions.numel() / (time.perf_counter() - began)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mazes", type=int, default=1024, help="mazes stepped together (default 1024)")
    parser.add_argument("--size", type=int, default=16, help="maze side without the outer wall (default 16)")
    parser.add_argument("--steps", type=int, default=300, help="steps per timed run (default 300)")
    parser.add_argument("--device", default="cpu", help="torch device (default cpu)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    mazes = [random_maze(rng, args.size) for _ in range(args.mazes)]
    batch = TorchMazes(mazes, device=args.device)
    actions = torch.randint(0, 4, (args.steps, args.mazes), generator=torch.Generator().manual_seed(0)).to(batch.device)
    print(f"machine: {os.cpu_count()} cores, {platform.processor() or platform.machine()}; torch {torch.__version__}")
    print("| mazes | size | device | torch threads | agent-steps per s (median of 3) |")
    print("|---|---|---|---|---|")
    counts = [1] if batch.device.type != "cpu" else range(1, len(os.sched_getaffinity(0)) + 1)
    for threads in counts:
        torch.set_num_threads(threads)
        rate(batch, actions[:20])
        rates = sorted(rate(batch, actions) for _ in range(3))
        print(f"| {args.mazes:,} | {args.size}x{args.size} | {args.device} | {threads} | {rates[1]:,.0f} |", flush=True)


if __name__ == "__main__":
    main()
