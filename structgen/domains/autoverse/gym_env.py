"""Autoverse games as Gymnasium environments, so that any RL library can train on evolved games.

- ``structgen/Autoverse-v0`` (:class:`AutoverseEnv`): one game at a time; each reset plays the next game of the
  list it was given (or a random game). Observations are a dict: ``view`` (5, 31, 31) uint8 and ``flat`` (1811,)
  int8 (see :meth:`Engine.observe`). Rewards are the rules' raw rewards; an episode is truncated after 101 steps.
- :class:`AutoverseVectorEnv` (the registered vector entry point): ``num_envs`` games stepped together by the
  batched engine, on CPU or GPU, restarting each game in the step where it ends (``AutoresetMode.SAME_STEP``; the
  last observation of an episode is in ``info["final_obs"]``).
- :class:`TorchGames`: the same batch with torch tensors in and out, for training loops that stay on the device
  (:mod:`.ppo` uses it).

Importing this module registers the ids.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from structgen.domains.autoverse.engine import FLAT_SIZE, VIEW, Engine, Mechanics, Observation
from structgen.domains.autoverse.game import random_game

__all__ = ["ENV_ID", "AutoverseEnv", "AutoverseVectorEnv", "TorchGames"]

ENV_ID = "structgen/Autoverse-v0"


def _spaces() -> spaces.Dict:
    return spaces.Dict(
        {
            "view": spaces.Box(0, 1, shape=(5, VIEW, VIEW), dtype=np.uint8),
            "flat": spaces.Box(-1, 1, shape=(FLAT_SIZE,), dtype=np.int8),
        }
    )


class TorchGames:
    """``count`` games stepped together, restarting each where it ends; tensors on ``device`` in and out."""

    def __init__(
        self,
        games: list[dict[str, Any]],
        *,
        device: str = "cpu",
        observation: Observation | None = None,
        mechanics: Mechanics | None = None,
    ) -> None:
        self.engine = Engine(games, device=device, mechanics=mechanics)
        self.observation = observation or Observation()
        self.start = self.engine.reset()
        self.state = self.start
        #: the states the last step reached, before games that ended were restarted
        self.reached = self.start

    def reset(self) -> tuple[torch.Tensor, torch.Tensor]:
        self.state = self.start
        return self.engine.observe(self.state, self.observation)

    def step(self, actions: torch.Tensor) -> tuple[tuple[torch.Tensor, torch.Tensor], torch.Tensor, torch.Tensor]:
        """``(observation after the step or the restart, reward, done)``."""
        self.reached, reward, done = self.engine.step(self.state, actions)
        self.state = self.reached.where(done, self.start)
        return self.engine.observe(self.state, self.observation), reward, done


def _games(games: list[dict[str, Any]] | None, count: int, seed: int) -> list[dict[str, Any]]:
    if games:
        return [games[i % len(games)] for i in range(count)]
    rng = np.random.default_rng(seed)
    return [random_game(rng) for _ in range(count)]


class AutoverseEnv(gymnasium.Env):
    """One Autoverse game at a time (the next of ``games`` at every reset; random games when none are given)."""

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(
        self,
        games: list[dict[str, Any]] | None = None,
        *,
        observation: Observation | None = None,
        mechanics: Mechanics | None = None,
        render_mode: str | None = None,
    ) -> None:
        self.games = list(games) if games else None
        self.observation = observation or Observation()
        self.mechanics = mechanics
        self.observation_space = _spaces()
        self.action_space = spaces.Discrete(5)
        self.render_mode = render_mode
        self._next = 0
        self._engine: Engine | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, np.ndarray], dict]:
        super().reset(seed=seed)
        if self.games:
            game = self.games[self._next % len(self.games)]
            self._next += 1
        else:
            game = random_game(self.np_random)
        self._engine = Engine([game], mechanics=self.mechanics)
        self._state = self._engine.reset()
        return self._observe(), {}

    def _observe(self) -> dict[str, np.ndarray]:
        view, flat = self._engine.observe(self._state, self.observation)
        return {"view": view[0].numpy(), "flat": flat[0].numpy()}

    def step(self, action: int) -> tuple[dict[str, np.ndarray], float, bool, bool, dict]:
        if self._engine is None:
            raise RuntimeError("call reset() before step()")
        self._state, reward, done = self._engine.step(self._state, torch.tensor([int(action)]))
        return self._observe(), float(reward[0]), False, bool(done[0]), {}

    def render(self) -> np.ndarray | None:
        from structgen.domains.autoverse.show import map_image

        if self._engine is None:
            return None
        return map_image(self._state.multi_hot()[0].numpy(), rot=int(self._state.rot[0]))


class AutoverseVectorEnv(VectorEnv):
    """``num_envs`` games in one batched engine; env ``i`` plays ``games[i % len(games)]`` (random games from
    ``seed`` when none are given)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        num_envs: int = 8,
        games: list[dict[str, Any]] | None = None,
        *,
        seed: int = 0,
        device: str = "cpu",
        observation: Observation | None = None,
        mechanics: Mechanics | None = None,
    ) -> None:
        self.num_envs = num_envs
        self.games = TorchGames(_games(games, num_envs, seed), device=device, observation=observation, mechanics=mechanics)
        self.single_observation_space = _spaces()
        self.single_action_space = spaces.Discrete(5)
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)

    @staticmethod
    def _numpy(observation: tuple[torch.Tensor, torch.Tensor]) -> dict[str, np.ndarray]:
        view, flat = observation
        return {"view": view.cpu().numpy(), "flat": flat.cpu().numpy()}

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None) -> tuple[dict, dict]:
        return self._numpy(self.games.reset()), {}

    def step(self, actions: np.ndarray) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, dict]:
        observation, reward, done = self.games.step(torch.as_tensor(np.asarray(actions), dtype=torch.int64))
        info: dict[str, Any] = {}
        if bool(done.any()):
            info["final_obs"] = self._numpy(self.games.engine.observe(self.games.reached, self.games.observation))
            info["_final_obs"] = done.cpu().numpy()
        done = done.cpu().numpy()
        return self._numpy(observation), reward.cpu().numpy(), np.zeros_like(done), done, info


if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        ENV_ID,
        entry_point="structgen.domains.autoverse.gym_env:AutoverseEnv",
        vector_entry_point="structgen.domains.autoverse.gym_env:AutoverseVectorEnv",
        max_episode_steps=None,
    )
