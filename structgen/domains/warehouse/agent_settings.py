"""The maze agent's training settings, apart from the training itself so that the command line can show their
defaults without loading torch (:mod:`.maze_training` trains with them)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ["AgentSettings"]


@dataclass(frozen=True)
class AgentSettings:
    """Attributes: updates (PPO updates), envs (mazes played at once), steps (per maze per update), epochs,
    minibatches, learning_rate, gamma, gae_lambda, entropy, hidden (network width), size (maze side), replay,
    edit, buffer, temperature, staleness (the curriculum, see :mod:`.maze_training`), checkpoint_every and evaluate_every
    (updates), seed, device."""

    updates: int = 500
    envs: int = 256
    steps: int = 128
    epochs: int = 4
    minibatches: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.995
    gae_lambda: float = 0.95
    entropy: float = 0.01
    hidden: int = 256
    size: int = 16
    replay: float = 0.5
    edit: float = 0.5
    buffer: int = 1000
    temperature: float = 0.3
    staleness: float = 0.3
    checkpoint_every: int = 10
    evaluate_every: int = 10
    seed: int = 0
    device: str = "cpu"

    def __post_init__(self) -> None:
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
        from structgen.devices import check_device_name

        check_device_name(self.device, "agent device")
        for name in ("updates", "envs", "steps", "epochs", "minibatches", "hidden"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"agent {name} must be a positive whole number, got {value!r}")
        if self.envs * self.steps < self.minibatches:
            raise ValueError(f"agent minibatches ({self.minibatches}) cannot exceed envs x steps ({self.envs * self.steps})")

    def ppo(self) -> Any:
        """The :class:`structgen.ppo.PPOSettings` of these settings."""
        from structgen.ppo import PPOSettings

        return PPOSettings(
            envs=self.envs,
            steps=self.steps,
            updates=self.updates,
            epochs=self.epochs,
            minibatches=self.minibatches,
            learning_rate=self.learning_rate,
            gamma=self.gamma,
            gae_lambda=self.gae_lambda,
            entropy=self.entropy,
            hidden=self.hidden,
            seed=self.seed,
            device=self.device,
        )
