"""The settings of :mod:`structgen.ppo`, apart from it so that command lines can show their defaults (and settings
that extend them can be checked) without loading torch."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from structgen.devices import check_device_name

__all__ = ["PPOSettings"]


@dataclass(frozen=True)
class PPOSettings:
    """Attributes: envs (environments stepped at once), steps (per environment per update), updates, epochs,
    minibatches, learning_rate, gamma, gae_lambda, clip, entropy, value_coef, max_grad_norm, hidden (network
    width), seed, device.

    A domain's training settings extend these (their own defaults, more fields); ``section`` names them in errors."""

    section: ClassVar[str] = "ppo"

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
        for name in ("envs", "steps", "updates", "epochs", "minibatches", "hidden", "seed"):
            value = getattr(self, name)
            low = 0 if name in ("updates", "seed") else 1
            if not isinstance(value, int) or isinstance(value, bool) or value < low:
                raise ValueError(f"{self.section} {name} must be a whole number of at least {low}, got {value!r}")
        for name in ("learning_rate", "gamma", "gae_lambda", "clip", "entropy", "value_coef", "max_grad_norm"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"{self.section} {name} must be a finite number of at least 0, got {value!r}")
        if not self.learning_rate > 0:
            raise ValueError(f"{self.section} learning_rate must be positive, got {self.learning_rate!r}")
        if self.envs * self.steps < self.minibatches:
            raise ValueError(
                f"{self.section} minibatches ({self.minibatches}) cannot exceed envs x steps ({self.envs * self.steps})"
            )
