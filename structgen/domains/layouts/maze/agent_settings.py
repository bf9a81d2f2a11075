"""The maze agent's training settings, apart from the training itself so that the command line can show their
defaults without loading torch (:mod:`.training` trains with them)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from structgen.config import Limit
from structgen.ppo_settings import PPOSettings

__all__ = ["AgentSettings"]


@dataclass(frozen=True)
class AgentSettings(PPOSettings):
    """PPO's settings (:class:`structgen.ppo_settings.PPOSettings`: updates, envs (mazes played at once), steps (per
    maze per update), epochs, minibatches, learning_rate, gamma, gae_lambda, clip, entropy, value_coef,
    max_grad_norm, hidden (network width), seed, device) with the maze agent's defaults, and: size (maze side),
    replay, edit, buffer, temperature, staleness (the curriculum, see :mod:`.training`), checkpoint_every and
    evaluate_every (updates), and way_on (whether the network is told which way the goal or the nearest unexplored
    floor lies on its map, :mod:`.way_on`)."""

    section: ClassVar[str] = "agent"
    #: What a training folder written before a setting existed ran with (structgen 0.4's agents had no way on).
    before_added: ClassVar[dict[str, object]] = {"way_on": False}
    limits: ClassVar[dict[str, Limit]] = {
        "updates": Limit(1, 10**7, "PPO updates in all (a resumed run goes on to this many)"),
        "envs": Limit(1, 10**6, "mazes played at once"),
        "steps": Limit(1, 10**5, "steps per maze in each update"),
        "hidden": Limit(1, 65536, "width of the network's two hidden layers"),
        "seed": Limit(0, 2**32 - 1, "seed of the levels, the starting directions and the network"),
        "size": Limit(4, 256, "side of the training mazes (inside their outer wall)"),
        "replay": Limit(0, 1, "chance that a finished episode's next level is replayed from the buffer", whole=False),
        "edit": Limit(0, 1, "chance that a new level is an edit of a buffer level (else random)", whole=False),
        "buffer": Limit(1, 10**6, "levels the curriculum keeps"),
        "temperature": Limit(0, math.inf, "of the replay's rank weights", whole=False, above=True),
        "staleness": Limit(0, 1, "share of the replay chance given by how long ago a level was played", whole=False),
        "checkpoint_every": Limit(1, 10**7, "updates between checkpoints"),
        "evaluate_every": Limit(1, 10**7, "updates between tests on the held-out mazes"),
    }

    updates: int = 500
    envs: int = 256
    learning_rate: float = 3e-4
    gamma: float = 0.995
    hidden: int = 256
    size: int = 16
    replay: float = 0.5
    edit: float = 0.5
    buffer: int = 1000
    temperature: float = 0.3
    staleness: float = 0.3
    checkpoint_every: int = 10
    evaluate_every: int = 10
    way_on: bool = True

    def __post_init__(self) -> None:
        super().__post_init__()
        if not isinstance(self.way_on, bool):
            raise ValueError(f"agent way_on must be true or false, got {self.way_on!r}")
