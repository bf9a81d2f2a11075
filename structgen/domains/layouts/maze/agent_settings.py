"""The maze agent's training settings, apart from the training itself so that the command line can show their
defaults without loading torch (:mod:`.training` trains with them)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from structgen.ppo_settings import PPOSettings

__all__ = ["AgentSettings"]


@dataclass(frozen=True)
class AgentSettings(PPOSettings):
    """PPO's settings (:class:`structgen.ppo_settings.PPOSettings`: updates, envs (mazes played at once), steps (per
    maze per update), epochs, minibatches, learning_rate, gamma, gae_lambda, clip, entropy, value_coef,
    max_grad_norm, hidden (network width), seed, device) with the maze agent's defaults, and: size (maze side),
    replay, edit, buffer, temperature, staleness (the curriculum, see :mod:`.training`), checkpoint_every and
    evaluate_every (updates)."""

    section: ClassVar[str] = "agent"

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

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("replay", "edit", "staleness"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"agent {name} must be a probability from 0 to 1, got {value!r}")
        if not self.temperature > 0:
            raise ValueError(f"agent temperature must be positive, got {self.temperature!r}")
        for name in ("size", "buffer", "checkpoint_every", "evaluate_every"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < (4 if name == "size" else 1):
                raise ValueError(f"agent {name} must be a whole number of at least {4 if name == 'size' else 1}, got {value!r}")
