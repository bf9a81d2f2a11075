"""Does behaviour cloning learn? Cloned policies against an untrained network and constant actions on held-out games.

On an Autoverse run's games (split as the original splits them), for each view asked for (a window of 5, 10, 20 or
the whole map; rules shown or hidden) and each seed, a policy is cloned from the training games' search playtraces
(:func:`structgen.domains.autoverse.clone.fit_policy`) and played on the test games for ``--eval-steps`` steps with
sampled actions, scored in normalised return per episode (:func:`.clone.normalisation`). The baselines are played
the same way: the untrained network of each seed, and each of the five actions held for the whole play (the best of
the five is the baseline; the original's "random" baseline is one such action). With ``--ppo-updates`` the cloned
full-view policy of each seed is then trained by PPO on the training games (:func:`.ppo.train_ppo`) and played again.

Margins are paired by game: for each test game the policy's return minus the baseline's, averaged over seeds; the
table gives their mean and standard error over the test games, and the policy's mean with its standard error over
seeds.

    python benchmarks/autoverse_learning.py RUN_DIR [--seeds 3] [--clone-steps 2000] [--views full 5 hidden]

The paper's scale, on a GPU: ``--clone-steps 100000 --clone-batch 4096 --hidden 256 --eval-steps 10000 --views full
5 10 20 hidden --device cuda``.

The original's figures (research notes A9: its cross_eval/obs_win table, test means over 10,000 steps, 3 seeds, 100,000
cloning steps of batch 4,096 on the games of a 100-generation map-only run) are printed beside ours, scaled to our
per-episode unit (x 101 / 10,000); the original's normalisation differs from ours on cascading games (see
:func:`.clone.normalisation`).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch
from torch import nn

from structgen.domains.autoverse.clone import Policy, collect_playtraces, evaluate_policy, fit_policy, split, transitions
from structgen.domains.autoverse.engine import EPISODE_STEPS, Observation
from structgen.domains.autoverse.ppo import PPOSettings, train_ppo

# The original's test means over 10,000 steps (3 seeds), by view.
ORIGINAL_TEST = {"5": (154.22, 12.21), "10": (136.69, 27.53), "20": (145.08, 18.95), "full": (165.85, 16.16)}
VIEWS = {"full": (-1, False), "5": (5, False), "10": (10, False), "20": (20, False), "hidden": (-1, True)}


class Constant(nn.Module):
    """Always the same action."""

    def __init__(self, action: int) -> None:
        super().__init__()
        self.action = action

    def forward(self, view: torch.Tensor, flat: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        logits = torch.full((len(view), 5), -1e9, device=view.device)
        logits[:, self.action] = 0.0
        return logits, torch.zeros(len(view), device=view.device)


def per_episode(policy: nn.Module, games: list, observation: Observation, steps: int, seed: int, device: str) -> np.ndarray:
    policy.to(device).eval()
    return evaluate_policy(policy, games, observation, steps, seed, device) / (steps / (EPISODE_STEPS + 1))


def paired(policy: np.ndarray, baseline: np.ndarray) -> str:
    """Mean and standard error over games of ``policy - baseline`` (``(seeds, games)`` arrays averaged over seeds)."""
    difference = (policy - baseline).mean(axis=0)
    error = difference.std(ddof=1) / np.sqrt(len(difference))
    return f"{difference.mean():+.3f} ± {error:.3f} ({difference.mean() / error:+.1f} SE)"


def over_seeds(values: np.ndarray) -> str:
    means = values.mean(axis=1)
    error = means.std(ddof=1) / np.sqrt(len(means)) if len(means) > 1 else 0.0
    return f"{means.mean():.3f} ± {error:.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", type=Path, help="an Autoverse evolution run folder")
    parser.add_argument("--seeds", type=int, default=3, help="seeds of each policy (default 3)")
    parser.add_argument("--clone-steps", type=int, default=2000, help="cloning gradient steps (default 2000)")
    parser.add_argument("--clone-batch", type=int, default=256, help="cloning batch (default 256)")
    parser.add_argument("--lr", type=float, default=1e-4, help="cloning learning rate (default 1e-4, the original's)")
    parser.add_argument("--hidden", type=int, default=64, help="network width (default 64; the original's 256)")
    parser.add_argument("--eval-steps", type=int, default=303, help="steps each test game is played (default 303)")
    parser.add_argument("--views", nargs="+", default=["full"], choices=tuple(VIEWS), help="views to clone (default full)")
    parser.add_argument("--ppo-updates", type=int, default=0, help="PPO updates after cloning, full view (default 0: none)")
    parser.add_argument("--threads", type=int, default=2, help="torch threads (default 2)")
    parser.add_argument("--device", default="cpu", help="torch device (default cpu; cuda for the paper's scale)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    parts = split(collect_playtraces(args.run_dir))
    test = parts["test"]
    print(
        f"games with fitness >= 2: train {len(parts['train'])}, val {len(parts['val'])}, test {len(test)}; cloning "
        f"{args.clone_steps} steps of batch {args.clone_batch}, width {args.hidden}; {args.seeds} seeds; each test game "
        f"played {args.eval_steps} steps\n"
    )
    full = Observation()
    seeds = range(args.seeds)
    constants = np.stack([per_episode(Constant(a), test, full, args.eval_steps, 0, args.device) for a in range(5)])
    best_action = int(constants.mean(axis=1).argmax())
    constant = constants[best_action][None]
    started = time.perf_counter()
    untrained = []
    for seed in seeds:
        torch.manual_seed(seed)
        untrained.append(per_episode(Policy(hidden=args.hidden), test, full, args.eval_steps, seed, args.device))
    untrained = np.stack(untrained)
    rows = [
        (f"constant action {best_action} (best of 5)", "-", f"{constant.mean():.3f}", "-", "-", "-"),
        ("untrained network", "full", over_seeds(untrained), paired(untrained, constant), "-", "-"),
    ]
    timings = {"baselines": time.perf_counter() - started}
    cloned_full = {}
    for view in args.views:
        window, hide = VIEWS[view]
        observation = Observation(window=window, hide_rules=hide)
        started = time.perf_counter()
        views, flats, actions = transitions(parts["train"], observation, device=args.device)
        returns = []
        for seed in seeds:
            torch.manual_seed(seed)
            policy = Policy(hidden=args.hidden).to(args.device)
            fit_policy(policy, views, flats, actions, args.clone_steps, args.clone_batch, args.lr, seed, progress=False)
            returns.append(per_episode(policy, test, observation, args.eval_steps, seed, args.device))
            if view == "full":
                cloned_full[seed] = policy
        returns = np.stack(returns)
        del views, flats, actions
        original = ORIGINAL_TEST.get(view)
        scaled = f"{original[0] * 101 / 10_000:.3f} ± {original[1] * 101 / 10_000:.3f}" if original else "-"
        label = "rules hidden" if hide else ("whole map" if window == -1 else f"{window}x{window}")
        rows.append(
            (f"cloned ({label})", view, over_seeds(returns), paired(returns, constant), paired(returns, untrained), scaled)
        )
        timings[f"cloned {view}"] = time.perf_counter() - started
    if args.ppo_updates and cloned_full:
        started = time.perf_counter()
        returns = []
        for seed, policy in cloned_full.items():
            settings = PPOSettings(
                updates=args.ppo_updates, envs=32, steps=101, hidden=args.hidden, seed=seed, learning_rate=1e-4
            )
            trained, _ = train_ppo(parts["train"], settings, full, policy)
            returns.append(per_episode(trained, test, full, args.eval_steps, seed, args.device))
        returns = np.stack(returns)
        label = f"cloned, then {args.ppo_updates} PPO updates"
        rows.append((label, "full", over_seeds(returns), paired(returns, constant), paired(returns, untrained), "-"))
        timings["PPO"] = time.perf_counter() - started
    print(
        "| policy | view | test return per episode (mean ± SE over seeds) | minus the constant action (by game) | minus the untrained network (by game) | the original's, per episode |"
    )
    print("|---|---|---:|---:|---:|---:|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print("\nseconds: " + ", ".join(f"{name} {seconds:.0f}" for name, seconds in timings.items()))


if __name__ == "__main__":
    main()
