"""The settings of :mod:`structgen.ppo`, apart from it so that command lines can show their defaults (and settings
that extend them can be checked) without loading torch."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from structgen.config import Limit, check_limits
from structgen.devices import check_device_name

__all__ = ["PPO_OPTIONS", "PPOSettings"]

#: PPO's settings that a training command takes as named options (made from their limits), in the order its
#: ``--help`` lists them.
PPO_OPTIONS = ("updates", "envs", "steps", "epochs", "minibatches", "learning_rate", "gamma", "entropy", "hidden")


@dataclass(frozen=True)
class PPOSettings:
    """Attributes: envs (environments stepped at once), steps (per environment per update), updates, epochs,
    minibatches, learning_rate, gamma, gae_lambda, clip, entropy, value_coef, max_grad_norm, hidden (network
    width), seed, device.

    A domain's training settings extend these (their own defaults, more fields); ``section`` names them in errors."""

    section: ClassVar[str] = "ppo"
    #: Each numeric field's range and meaning (:class:`structgen.config.Limit`): its check and its option.
    limits: ClassVar[dict[str, Limit]] = {
        "envs": Limit(1, 10**6, "environments played at once"),
        "steps": Limit(1, 10**5, "steps per environment in each update"),
        "updates": Limit(0, 10**7, "PPO updates in all (a resumed run goes on to this many)"),
        "epochs": Limit(1, 1000, "passes over each update's steps"),
        "minibatches": Limit(1, 10**6, "minibatches per pass"),
        "learning_rate": Limit(0, 1, "Adam's learning rate", whole=False, above=True),
        "gamma": Limit(0, 1, "discount", whole=False),
        "gae_lambda": Limit(0, 1, "GAE's lambda", whole=False),
        "clip": Limit(0, math.inf, "PPO's clip range", whole=False),
        "entropy": Limit(0, math.inf, "weight of the entropy bonus", whole=False),
        "value_coef": Limit(0, math.inf, "weight of the value loss", whole=False),
        "max_grad_norm": Limit(0, math.inf, "gradient norm clipped to", whole=False),
        "hidden": Limit(1, 65536, "width of the network's hidden layers"),
        "seed": Limit(0, 2**63 - 1, "seed of the levels, the actions sampled and the network"),
    }

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
        check_device_name(self.device, f"{self.section} device")
        check_limits(self)
        if self.envs * self.steps < self.minibatches:
            raise ValueError(
                f"{self.section} minibatches ({self.minibatches}) cannot exceed envs x steps ({self.envs * self.steps})"
            )
