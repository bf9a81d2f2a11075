"""Behaviour cloning and PPO on an Autoverse run's games, beside the original's observation-window table.

For each view (window 5, 10, 20, full; and full with the rules hidden) a policy is cloned from the run's playtraces
(``structgen autoverse clone`` with the settings below) and evaluated on the train, validation and test games in the
original's normalised reward; an untrained network and PPO (trained on the train games, from scratch) are evaluated
the same way.

    python benchmarks/autoverse_learning.py RUN_DIR [--steps 500] [--eval-steps 1010] [--ppo-updates 30]

The original's numbers (cross_eval/obs_win, research notes A9) are test means over 10,000 evaluation steps, 3 seeds,
100,000 gradient steps of batch 4,096 on the elites of 100 generations; this script's are sums over ``--eval-steps``
steps, so they are multiplied by 10,000 / eval-steps in the last columns to put them on the original's scale.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from structgen.domains.autoverse.clone import CloneSettings, clone_run, collect_playtraces, evaluate_policy, split
from structgen.domains.autoverse.engine import Observation
from structgen.domains.autoverse.ppo import PPOSettings, train_ppo

ORIGINAL_TEST = {"5": "154.22 ± 12.21", "10": "136.69 ± 27.53", "20": "145.08 ± 18.95", "full": "165.85 ± 16.16"}
ORIGINAL_TRAIN = {"5": "148.23 ± 27.30", "10": "124.31 ± 23.53", "20": "133.38 ± 15.21", "full": "187.85 ± 14.53"}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--steps", type=int, default=500, help="gradient steps of behaviour cloning (default 500)")
    parser.add_argument("--batch-size", type=int, default=128, help="cloning batch (default 128)")
    parser.add_argument("--eval-steps", type=int, default=1010, help="evaluation steps per game (default 1010)")
    parser.add_argument("--ppo-updates", type=int, default=30, help="PPO updates (default 30; 0 to skip)")
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    scale = 10_000 / args.eval_steps
    parts = split(collect_playtraces(args.run_dir))
    sizes = ", ".join(f"{name} {len(games)}" for name, games in parts.items())
    print(f"games with fitness >= 2: {sizes}; evaluation {args.eval_steps} steps, x{scale:.2f} for the 10,000-step scale\n")
    print(
        "| policy | view | rules | train mean | val mean | test mean | test (10k scale) | original test (10k) | original train (10k) | seconds |"
    )
    print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|")
    configs = [("untrained", -1, False, 1)] + [("cloned", w, False, args.steps) for w in (5, 10, 20, -1)]
    configs.append(("cloned", -1, True, args.steps))
    with tempfile.TemporaryDirectory() as scratch:
        for kind, window, hidden, steps in configs:
            started = time.perf_counter()
            settings = CloneSettings(
                window=window, hide_rules=hidden, steps=steps, batch_size=args.batch_size, eval_steps=args.eval_steps
            )
            report = clone_run(args.run_dir, settings, Path(scratch) / f"{kind}{window}{hidden}", progress=False)
            view = "full" if window == -1 else str(window)
            original = ORIGINAL_TEST.get(view, "-") if kind == "cloned" and not hidden else "-"
            original_train = ORIGINAL_TRAIN.get(view, "-") if kind == "cloned" and not hidden else "-"
            print(
                f"| {kind} | {view} | {'hidden' if hidden else 'shown'} | {report['train_mean']:.2f} | {report['val_mean']:.2f} | "
                f"{report['test_mean']:.2f} | {report['test_mean'] * scale:.1f} | {original} | {original_train} | {time.perf_counter() - started:.0f} |"
            )
        if args.ppo_updates:
            started = time.perf_counter()
            policy, history = train_ppo(parts["train"], PPOSettings(updates=args.ppo_updates))
            policy.eval()
            means = {
                name: float(np.mean(evaluate_policy(policy, games, Observation(), args.eval_steps)))
                for name, games in parts.items()
            }
            print(
                f"| PPO, {args.ppo_updates} updates (hidden 64) | full | shown | {means['train']:.2f} | {means['val']:.2f} | "
                f"{means['test']:.2f} | {means['test'] * scale:.1f} | - | - | {time.perf_counter() - started:.0f} |"
            )
            print(f"\nPPO mean normalised episode return per update: {', '.join(f'{h:.2f}' for h in history)}")


if __name__ == "__main__":
    main()
