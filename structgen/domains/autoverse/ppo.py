"""A compact PPO over the batched engine (:class:`.gym_env.TorchGames`), everything on one torch device.

Why not a library: Stable-Baselines3 wants a numpy ``VecEnv`` (a host copy of every observation, 26 KB an env-step)
and its own rollout buffer; CleanRL is scripts, not a library; TorchRL would fit but adds a large dependency for one
loop. This file is the standard clipped-objective PPO with GAE (the hyperparameters of the original's purejaxrl-style
trainer are the defaults, except the learning rate and sizes, chosen for CPU runs) on the same network as behaviour
cloning, so a cloned policy can start it.

Rewards are the original's normalised rewards (:func:`.clone.normalisation`), so returns compare with the
behaviour-cloning table.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch import nn

from structgen.devices import check_device_name
from structgen.domains.autoverse.clone import Policy, normalisation
from structgen.domains.autoverse.engine import EPISODE_STEPS, Observation
from structgen.domains.autoverse.gym_env import TorchGames

__all__ = ["PPOSettings", "train_ppo"]


@dataclass(frozen=True)
class PPOSettings:
    """Attributes: envs (games played at once), steps (per env per update), updates, epochs, minibatches,
    learning_rate, gamma, gae_lambda, clip, entropy, value_coef, max_grad_norm, hidden (network width; the original
    uses 256), seed, device."""

    envs: int = 32
    steps: int = 128
    updates: int = 20
    epochs: int = 4
    minibatches: int = 4
    learning_rate: float = 2.5e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.2
    entropy: float = 0.01
    value_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: int = 64
    seed: int = 0
    device: str = "cpu"

    def __post_init__(self) -> None:
        check_device_name(self.device, "ppo device")


def train_ppo(
    games: list[dict[str, Any]], settings: PPOSettings, observation: Observation | None = None, policy: Policy | None = None
) -> tuple[Policy, list[float]]:
    """Train on ``games`` (env ``i`` plays game ``i % len(games)``); returns the policy and the mean normalised
    return per episode after each update."""
    torch.manual_seed(settings.seed)
    device = settings.device
    played = [games[i % len(games)] for i in range(settings.envs)]
    env = TorchGames(played, device=device, observation=observation)
    bias, scale = normalisation(env.engine, settings.seed)
    policy = policy or Policy(hidden=settings.hidden)
    policy = policy.to(device)
    optimiser = torch.optim.Adam(policy.parameters(), lr=settings.learning_rate, eps=1e-5)
    view, flat = env.reset()
    n, t = settings.envs, settings.steps
    history: list[float] = []
    episode_return = torch.zeros(n, device=device)
    for _ in range(settings.updates):
        views, flats, actions, logps, values, rewards, dones = [], [], [], [], [], [], []
        finished: list[float] = []
        with torch.no_grad():
            for _ in range(t):
                logits, value = policy(view, flat)
                dist = torch.distributions.Categorical(logits=logits)
                action = dist.sample()
                views.append(view)
                flats.append(flat)
                actions.append(action)
                logps.append(dist.log_prob(action))
                values.append(value)
                (view, flat), reward, done = env.step(action)
                reward = (reward + bias / EPISODE_STEPS) * scale
                rewards.append(reward)
                dones.append(done.float())
                episode_return += reward
                finished.extend(episode_return[done].tolist())
                episode_return = torch.where(done, torch.zeros_like(episode_return), episode_return)
            _, last_value = policy(view, flat)
        rewards_t, dones_t, values_t = torch.stack(rewards), torch.stack(dones), torch.stack(values)
        advantages = torch.zeros_like(rewards_t)
        running = torch.zeros(n, device=device)
        for step in reversed(range(t)):
            next_value = last_value if step == t - 1 else values_t[step + 1]
            alive = 1.0 - dones_t[step]
            delta = rewards_t[step] + settings.gamma * next_value * alive - values_t[step]
            running = delta + settings.gamma * settings.gae_lambda * alive * running
            advantages[step] = running
        targets = advantages + values_t
        flat_views, flat_flats = torch.cat(views), torch.cat(flats)
        flat_actions, flat_logps = torch.cat(actions), torch.cat(logps)
        flat_adv, flat_targets = advantages.reshape(-1), targets.reshape(-1)
        size = n * t
        batch = size // settings.minibatches
        for _ in range(settings.epochs):
            order = torch.randperm(size, device=device)
            for start in range(0, size - batch + 1, batch):
                index = order[start : start + batch]
                logits, value = policy(flat_views[index], flat_flats[index])
                dist = torch.distributions.Categorical(logits=logits)
                ratio = torch.exp(dist.log_prob(flat_actions[index]) - flat_logps[index])
                adv = flat_adv[index]
                adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                clipped = torch.clamp(ratio, 1 - settings.clip, 1 + settings.clip)
                policy_loss = -torch.min(ratio * adv, clipped * adv).mean()
                value_loss = 0.5 * (value - flat_targets[index]).pow(2).mean()
                loss = policy_loss + settings.value_coef * value_loss - settings.entropy * dist.entropy().mean()
                optimiser.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(policy.parameters(), settings.max_grad_norm)
                optimiser.step()
        history.append(float(np.mean(finished)) if finished else float("nan"))
    return policy, history
