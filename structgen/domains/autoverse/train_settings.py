"""The settings of ``structgen autoverse train`` (:mod:`.train`), apart from the training so that the command line
can show their defaults without loading torch."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from structgen.domains.autoverse.game import MUTATIONS

__all__ = ["PRESETS", "TrainSettings"]


@dataclass(frozen=True)
class TrainSettings:
    """Attributes:
    clone_steps, clone_batch, clone_learning_rate: behaviour cloning (0 steps: PPO from an untrained network).
    updates, envs, steps, epochs, minibatches, learning_rate, gamma, gae_lambda, clip, entropy, value_coef,
        max_grad_norm: PPO (see :class:`structgen.ppo.PPOSettings`).
    hidden: the network's width (the original's 256; its convolution has as many channels).
    window, hide_rules, padding, blank_window: what the player sees (:class:`.engine.Observation`).
    min_fitness: games of the run below this fitness are left out (the original's 2).
    evaluate_every, eval_steps: updates between evaluations; steps each game is played for in one.
    eval_games: games of each split evaluated, evenly spaced along the split's order of fitness (0: all).
    checkpoint_every: updates between checkpoints.
    evolve_every: updates between rounds of regret-driven evolution of the training games (0: the pool stays the
        training games).
    pool: games kept by evolution (0: as many as the training split has).
    evolve_mutation: how children differ from their parents (``rules_and_map`` or ``map_only``, as the run's).
    seed, device.
    """

    clone_steps: int = 2000
    clone_batch: int = 256
    clone_learning_rate: float = 1e-4
    updates: int = 50
    envs: int = 32
    steps: int = 101
    epochs: int = 4
    minibatches: int = 4
    learning_rate: float = 1e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.2
    entropy: float = 0.01
    value_coef: float = 0.5
    max_grad_norm: float = 0.5
    hidden: int = 64
    window: int = -1
    hide_rules: bool = False
    padding: str = "zeros"
    blank_window: bool = False
    min_fitness: float = 2.0
    evaluate_every: int = 10
    eval_steps: int = 303
    eval_games: int = 200
    checkpoint_every: int = 5
    evolve_every: int = 0
    pool: int = 0
    evolve_mutation: str = "rules_and_map"
    seed: int = 0
    device: str = "cpu"

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if item.type == "int" and (not isinstance(value, int) or isinstance(value, bool)):
                raise ValueError(f"train {item.name} must be a whole number, got {value!r}")
            if item.type == "float" and (
                isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value)
            ):
                raise ValueError(f"train {item.name} must be a finite number, got {value!r}")
        at_least_one = ("clone_batch", "envs", "steps", "epochs", "minibatches", "hidden", "evaluate_every", "eval_steps")
        for name in at_least_one + ("checkpoint_every",):
            if getattr(self, name) < 1:
                raise ValueError(f"train {name} must be at least 1, got {getattr(self, name)!r}")
        for name in ("clone_steps", "updates", "evolve_every", "pool", "seed", "eval_games"):
            if getattr(self, name) < 0:
                raise ValueError(f"train {name} must not be negative, got {getattr(self, name)!r}")
        for name in ("clone_learning_rate", "learning_rate"):
            if not getattr(self, name) > 0:
                raise ValueError(f"train {name} must be positive, got {getattr(self, name)!r}")
        if self.evolve_mutation not in MUTATIONS:
            raise ValueError(f"train evolve_mutation must be one of {', '.join(MUTATIONS)}, got {self.evolve_mutation!r}")
        try:
            self.observation()
        except ValueError as err:
            raise ValueError(f"train {err}") from None
        self.ppo()

    def observation(self) -> Any:
        """The :class:`.engine.Observation` of these settings."""
        from structgen.domains.autoverse.engine import Observation

        return Observation(window=self.window, hide_rules=self.hide_rules, padding=self.padding, blank_window=self.blank_window)

    def ppo(self) -> Any:
        """The :class:`structgen.ppo.PPOSettings` of these settings."""
        from structgen.ppo import PPOSettings

        names = ("envs", "steps", "updates", "epochs", "minibatches", "learning_rate", "gamma", "gae_lambda", "clip")
        more = ("entropy", "value_coef", "max_grad_norm", "hidden", "seed", "device")
        return PPOSettings(**{name: getattr(self, name) for name in names + more})


#: ``cpu``: what fits 2 CPU cores in about an hour (the defaults). ``original``: the original's settings: cloning
#: 100,000 steps of batch 4,096 at learning rate 1e-4; PPO with 100 games of 200 steps an update, 10 epochs of 4
#: minibatches at learning rate 1e-5, a 256-wide network; 10,000 evaluation steps (for a GPU).
PRESETS: dict[str, dict[str, Any]] = {
    "cpu": {},
    "original": {
        "clone_steps": 100_000,
        "clone_batch": 4096,
        "clone_learning_rate": 1e-4,
        "envs": 100,
        "steps": 200,
        "epochs": 10,
        "minibatches": 4,
        "learning_rate": 1e-5,
        "hidden": 256,
        "eval_steps": 10_000,
        "eval_games": 0,
        "evaluate_every": 10,
    },
}
