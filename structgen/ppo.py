"""Proximal policy optimisation over batched torch environments, shared by every domain whose agents learn.

Why not a library: Stable-Baselines3 wants a numpy ``VecEnv`` (a host copy of every observation) and its own rollout
buffer; CleanRL is scripts, not a library; TorchRL would fit but is a large dependency for one loop. This is the
standard clipped-objective PPO with generalised advantage estimation, everything on one torch device.

What it asks of the two sides:

- an environment: ``step(actions) -> (observation, reward, done)``, where ``observation`` is a tuple of ``(B, ...)``
  tensors and an environment whose episode ends restarts in the same step (Autoverse's :class:`TorchGames` and the
  mazes' :class:`TorchMazes` both do);
- a policy: a module called as ``policy(*observation) -> (logits, value)``.

A domain drives the loop itself (``collect`` then ``update``, as often as it likes), so that it can change levels
between updates (a curriculum) or read the advantages (a level's learning potential) in between.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import torch
from torch import nn

from structgen.budget import check_memory
from structgen.ppo_settings import PPOSettings

__all__ = ["PPO", "PPOSettings", "Rollout", "BatchedEnv", "EpisodeReturns", "check_rollout_memory"]


def check_rollout_memory(probe: Any, envs: int, steps: int, *, what: str) -> None:
    """Refuse ``envs`` environments played ``steps`` steps an update before any is made, when one environment's
    observation (``probe``: a tuple of tensors for a batch of one) times the rollout's transitions would take more
    than the memory budget (:mod:`structgen.budget`); ``what`` names the options in the message."""
    per_step = sum(t.element_size() * t.numel() for t in probe) + 64  # the action, value, reward... of a transition
    check_memory(per_step * envs * (steps + 1), f"{what}: {envs:,} environments x {steps:,} steps", "use fewer")


class BatchedEnv(Protocol):
    def step(self, actions: torch.Tensor) -> tuple[tuple[torch.Tensor, ...], torch.Tensor, torch.Tensor]: ...


@dataclass
class Rollout:
    """``steps`` transitions of every environment, time first: ``observations`` (a tuple of ``(T, B, ...)``),
    ``actions``, ``log_probs``, ``values``, ``rewards``, ``dones`` (``(T, B)``), and after :meth:`PPO.advantages`
    the ``advantages`` and ``returns``. ``last`` is the observation after the final step (where the next collection
    starts)."""

    observations: tuple[torch.Tensor, ...]
    actions: torch.Tensor
    log_probs: torch.Tensor
    values: torch.Tensor
    rewards: torch.Tensor
    dones: torch.Tensor
    last: tuple[torch.Tensor, ...]
    last_value: torch.Tensor
    advantages: torch.Tensor | None = None
    returns: torch.Tensor | None = None


class EpisodeReturns:
    """Sums each environment's rewards until its episode ends; :meth:`add` returns the sums of the episodes that
    just ended."""

    def __init__(self, envs: int, device: Any) -> None:
        self.running = torch.zeros(envs, device=device)

    def add(self, reward: torch.Tensor, done: torch.Tensor) -> list[float]:
        self.running += reward
        ended = self.running[done].tolist()
        self.running = torch.where(done, torch.zeros_like(self.running), self.running)
        return ended

    def add_rollout(self, rollout: Rollout) -> list[float]:
        ended: list[float] = []
        for reward, done in zip(rollout.rewards, rollout.dones.bool()):
            ended.extend(self.add(reward, done))
        return ended


class PPO:
    """One policy and its optimiser. :meth:`collect` plays ``settings.steps`` steps in every environment;
    :meth:`update` computes the advantages (if not done yet) and takes ``epochs`` passes of ``minibatches``
    clipped-objective steps over them."""

    def __init__(self, policy: nn.Module, settings: PPOSettings) -> None:
        self.settings = settings
        self.policy = policy.to(settings.device)
        self.optimiser = torch.optim.Adam(self.policy.parameters(), lr=settings.learning_rate, eps=1e-5)

    @torch.no_grad()
    def collect(self, env: BatchedEnv, observation: tuple[torch.Tensor, ...], steps: int | None = None) -> Rollout:
        steps = self.settings.steps if steps is None else steps
        seen: list[tuple[torch.Tensor, ...]] = []
        actions, log_probs, values, rewards, dones = [], [], [], [], []
        for _ in range(steps):
            logits, value = self.policy(*observation)
            dist = torch.distributions.Categorical(logits=logits)
            action = dist.sample()
            seen.append(observation)
            actions.append(action)
            log_probs.append(dist.log_prob(action))
            values.append(value)
            observation, reward, done = env.step(action)
            rewards.append(reward)
            dones.append(done.float())
        _, last_value = self.policy(*observation)
        stacked = tuple(torch.stack(parts) for parts in zip(*seen))
        return Rollout(
            stacked,
            torch.stack(actions),
            torch.stack(log_probs),
            torch.stack(values),
            torch.stack(rewards),
            torch.stack(dones),
            observation,
            last_value,
        )

    def advantages(self, rollout: Rollout) -> Rollout:
        """Generalised advantage estimates; an episode's end cuts the bootstrap (a cut-off at a horizon is treated
        as an end too, as the domains' horizons are part of their tasks)."""
        s = self.settings
        advantages = torch.zeros_like(rollout.rewards)
        running = torch.zeros_like(rollout.last_value)
        steps = len(rollout.rewards)
        for step in reversed(range(steps)):
            next_value = rollout.last_value if step == steps - 1 else rollout.values[step + 1]
            alive = 1.0 - rollout.dones[step]
            delta = rollout.rewards[step] + s.gamma * next_value * alive - rollout.values[step]
            running = delta + s.gamma * s.gae_lambda * alive * running
            advantages[step] = running
        rollout.advantages, rollout.returns = advantages, advantages + rollout.values
        return rollout

    def update(self, rollout: Rollout) -> dict[str, float]:
        """Returns the last minibatch's policy loss, value loss and entropy."""
        s = self.settings
        if rollout.advantages is None:
            self.advantages(rollout)
        assert rollout.advantages is not None and rollout.returns is not None
        flat = tuple(part.reshape(-1, *part.shape[2:]) for part in rollout.observations)
        actions, old_log_probs = rollout.actions.reshape(-1), rollout.log_probs.reshape(-1)
        all_advantages, returns = rollout.advantages.reshape(-1), rollout.returns.reshape(-1)
        size = len(actions)
        batch = size // s.minibatches
        stats: dict[str, float] = {}
        for _ in range(s.epochs):
            order = torch.randperm(size, device=actions.device)
            for start in range(0, size - batch + 1, batch):
                index = order[start : start + batch]
                logits, value = self.policy(*(part[index] for part in flat))
                dist = torch.distributions.Categorical(logits=logits)
                ratio = torch.exp(dist.log_prob(actions[index]) - old_log_probs[index])
                advantage = all_advantages[index]
                advantage = (advantage - advantage.mean()) / (advantage.std() + 1e-8)
                clipped = torch.clamp(ratio, 1 - s.clip, 1 + s.clip)
                policy_loss = -torch.min(ratio * advantage, clipped * advantage).mean()
                value_loss = 0.5 * (value - returns[index]).pow(2).mean()
                entropy = dist.entropy().mean()
                loss = policy_loss + s.value_coef * value_loss - s.entropy * entropy
                self.optimiser.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(self.policy.parameters(), s.max_grad_norm)
                self.optimiser.step()
                stats = {"policy_loss": policy_loss.item(), "value_loss": value_loss.item(), "entropy": entropy.item()}
        return stats
