"""PPO on Autoverse games: the project's PPO (:mod:`structgen.ppo`) over the batched engine, on the same network as
behaviour cloning, so a cloned policy can start it.

:class:`GamePool` plays ``envs`` episodes at once, each on a game drawn at random from a pool when the last one
ended; rewards are the normalised rewards of :func:`.clone.normalisation`, so returns compare with the cloning
table. :func:`train_ppo` is the loop alone; ``structgen autoverse train`` (:mod:`.train`) adds cloning first,
evaluation, checkpoints and regret-driven evolution of the games.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from structgen.domains.autoverse.clone import Policy, normalisation
from structgen.domains.autoverse.engine import EPISODE_STEPS, Engine, Mechanics, Observation, State
from structgen.ppo import PPO, EpisodeReturns, PPOSettings

__all__ = ["GamePool", "PPOSettings", "train_ppo"]


class GamePool:
    """``envs`` episodes played at once on games of a pool: each episode plays a game drawn uniformly from the pool
    (by ``generator``), and a new one is drawn where one ends. Rewards are normalised per game (see
    :func:`.clone.normalisation`); ``step`` returns ``(observation, reward, done)`` as :class:`structgen.ppo.PPO`
    wants."""

    def __init__(self, games: list[dict[str, Any]], envs: int, observation: Observation, device: str, generator) -> None:
        self.games = games
        self.engine = Engine(games, device=device, mechanics=Mechanics())
        self.bias, self.scale = normalisation(self.engine)
        self.observation = observation
        self.generator = generator
        self.envs = envs
        self.state = self.engine.reset(self._draw(envs))

    def _draw(self, count: int) -> torch.Tensor:
        return torch.randint(self.engine.n_games, (count,), generator=self.generator)

    def observe(self) -> tuple[torch.Tensor, torch.Tensor]:
        return self.engine.observe(self.state, self.observation)

    def step(self, actions: torch.Tensor) -> tuple[tuple[torch.Tensor, torch.Tensor], torch.Tensor, torch.Tensor]:
        game = self.state.game
        reached, reward, done = self.engine.step(self.state, actions)
        normalised = (reward + self.bias[game] / EPISODE_STEPS) * self.scale[game]
        self.state = reached.where(done, self.engine.reset(self._draw(self.envs)))
        return self.observe(), normalised, done

    def state_dict(self) -> dict[str, torch.Tensor]:
        s = self.state
        return {"map": s.map, "rot": s.rot, "pos": s.pos, "step": s.step, "game": s.game}

    def load_state_dict(self, saved: dict[str, torch.Tensor]) -> None:
        device = self.engine.device
        self.state = State(*(saved[name].to(device) for name in ("map", "rot", "pos", "step", "game")))


def train_ppo(
    games: list[dict[str, Any]], settings: PPOSettings, observation: Observation | None = None, policy: Policy | None = None
) -> tuple[Policy, list[float]]:
    """Train on ``games`` (each episode on one drawn at random); returns the policy and the mean normalised return of
    the episodes that ended in each update."""
    torch.manual_seed(settings.seed)
    generator = torch.Generator().manual_seed(settings.seed)
    env = GamePool(games, settings.envs, observation or Observation(), settings.device, generator)
    ppo = PPO(policy or Policy(hidden=settings.hidden), settings)
    returns = EpisodeReturns(settings.envs, settings.device)
    history: list[float] = []
    for _ in range(settings.updates):
        rollout = ppo.collect(env, env.observe())
        finished = returns.add_rollout(rollout)
        ppo.update(rollout)
        history.append(float(np.mean(finished)) if finished else float("nan"))
    return ppo.policy, history
