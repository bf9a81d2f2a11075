"""PPO on Autoverse games: the project's PPO (:mod:`structgen.ppo`) over the batched engine
(:class:`.gym_env.TorchGames`), on the same network as behaviour cloning, so a cloned policy can start it.

Rewards are the original's normalised rewards (:func:`.clone.normalisation`), so returns compare with the
behaviour-cloning table. The defaults are the original's purejaxrl-style trainer's, except the learning rate and
sizes, chosen for CPU runs.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from structgen.domains.autoverse.clone import Policy, normalisation
from structgen.domains.autoverse.engine import EPISODE_STEPS, Observation
from structgen.domains.autoverse.gym_env import TorchGames
from structgen.ppo import PPO, EpisodeReturns, PPOSettings

__all__ = ["PPOSettings", "train_ppo"]


class _NormalisedGames:
    """:class:`TorchGames` with the original's reward normalisation and the done flag PPO wants."""

    def __init__(self, games: TorchGames, bias: float, scale: float) -> None:
        self.games, self.bias, self.scale = games, bias, scale

    def step(self, actions: torch.Tensor) -> tuple[tuple[torch.Tensor, ...], torch.Tensor, torch.Tensor]:
        observation, reward, done = self.games.step(actions)
        return observation, (reward + self.bias / EPISODE_STEPS) * self.scale, done


def train_ppo(
    games: list[dict[str, Any]], settings: PPOSettings, observation: Observation | None = None, policy: Policy | None = None
) -> tuple[Policy, list[float]]:
    """Train on ``games`` (env ``i`` plays game ``i % len(games)``); returns the policy and the mean normalised
    return per episode after each update."""
    torch.manual_seed(settings.seed)
    played = [games[i % len(games)] for i in range(settings.envs)]
    games_env = TorchGames(played, device=settings.device, observation=observation)
    env = _NormalisedGames(games_env, *normalisation(games_env.engine, settings.seed))
    ppo = PPO(policy or Policy(hidden=settings.hidden), settings)
    state = games_env.reset()
    returns = EpisodeReturns(settings.envs, settings.device)
    history: list[float] = []
    for _ in range(settings.updates):
        rollout = ppo.collect(env, state)
        state = rollout.last
        finished = returns.add_rollout(rollout)
        ppo.update(rollout)
        history.append(float(np.mean(finished)) if finished else float("nan"))
    return ppo.policy, history
