"""The settings of ``structgen autoverse train`` (:mod:`.train`) and ``clone`` (:mod:`.clone`), apart from the
training so that the command line can show their defaults without loading torch."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from structgen.config import Limit, check_limits
from structgen.domains.autoverse.game import MUTATIONS
from structgen.ppo_settings import PPOSettings

__all__ = ["PRESETS", "CloneSettings", "TrainSettings"]


class _Observed:
    """What the player sees, for settings that have the fields ``window``, ``hide_rules``, ``padding`` and
    ``blank_window`` (:class:`.engine.Observation`'s) and a ``section`` that names them in errors."""

    section: ClassVar[str]

    def observation(self) -> Any:
        """The :class:`.engine.Observation` of these settings."""
        from structgen.domains.autoverse.engine import Observation

        names = ("window", "hide_rules", "padding", "blank_window")
        return Observation(**{name: getattr(self, name) for name in names})

    def _check_observation(self) -> None:
        try:
            self.observation()
        except ValueError as err:
            raise ValueError(f"{self.section} {err}") from None


@dataclass(frozen=True)
class CloneSettings(_Observed):
    """Behaviour cloning on a run's playtraces (:func:`.clone.clone_run`): what the player sees (``window``,
    ``hide_rules``, ``padding``, ``blank_window``: :class:`.engine.Observation`), the network's width, the cloning's
    gradient steps, batch, learning rate and seed, its torch device, the steps each game is played in the evaluation,
    the fitness below which a game is left out, and ``original_pairing`` (each observation paired with the action that
    led to it, as the original pairs them)."""

    section: ClassVar[str] = "clone"
    limits: ClassVar[dict[str, Limit]] = {
        "hidden": Limit(1, 4096, "network width (the original's 256)"),
        "steps": Limit(1, 10**7, "gradient steps"),
        "batch_size": Limit(1, 10**6, "batch"),
        "learning_rate": Limit(0, 1, "Adam learning rate (the original's 1e-4)", whole=False, above=True, option="--lr"),
        "seed": Limit(0, 2**63 - 1, "seed"),
        "eval_steps": Limit(1, 10**7, "steps each game is played in the evaluation"),
        "min_fitness": Limit(-math.inf, math.inf, "games below this fitness are left out", whole=False),
    }

    window: int = -1
    hide_rules: bool = False
    padding: str = "zeros"
    blank_window: bool = False
    hidden: int = 256
    steps: int = 2000
    batch_size: int = 256
    learning_rate: float = 1e-4
    seed: int = 0
    device: str = "cpu"
    eval_steps: int = 10_000
    min_fitness: float = 2.0
    original_pairing: bool = False

    def __post_init__(self) -> None:
        from structgen.devices import check_device_name

        check_limits(self)
        if self.window not in (-1, 5, 10, 20):
            raise ValueError(f"clone window must be -1 (the full map), 5, 10 or 20, got {self.window!r}")
        check_device_name(self.device, "clone device")
        self._check_observation()


@dataclass(frozen=True)
class TrainSettings(PPOSettings, _Observed):
    """PPO's settings (:class:`structgen.ppo_settings.PPOSettings`; ``hidden`` is the network's width, the original's
    256, its convolution having as many channels), with their defaults for 2 CPU cores, and:

    clone_steps, clone_batch, clone_learning_rate: behaviour cloning (0 steps: PPO from an untrained network).
    window, hide_rules, padding, blank_window: what the player sees (:class:`.engine.Observation`).
    min_fitness: games of the run below this fitness are left out (the original's 2).
    evaluate_every, eval_steps: updates between evaluations; steps each game is played for in one.
    eval_games: games of each split evaluated, evenly spaced along the split's order of fitness (0: all).
    checkpoint_every: updates between checkpoints.
    evolve_every: updates between rounds of regret-driven evolution of the training games (0: the pool stays the
        training games).
    pool: games kept by evolution (0: as many as the training split has).
    evolve_mutation: how children differ from their parents (``rules_and_map`` or ``map_only``, as the run's).
    """

    section: ClassVar[str] = "train"
    limits: ClassVar[dict[str, Limit]] = {
        "envs": Limit(1, 10**6, "games played at once"),
        "steps": Limit(1, 10**5, "steps per game in each update"),
        "learning_rate": Limit(0, 1, "PPO's Adam learning rate", whole=False, above=True, option="--lr"),
        "hidden": Limit(1, 65536, "network width (the convolution's channels and the layers')"),
        "seed": Limit(0, 2**63 - 1, "seed of cloning, the games drawn, the actions sampled and evolution"),
        "clone_steps": Limit(0, 10**8, "behaviour-cloning gradient steps (0: PPO from scratch)"),
        "clone_batch": Limit(1, 10**6, "cloning batch"),
        "clone_learning_rate": Limit(0, 1, "cloning learning rate", whole=False, above=True, option="--clone-lr"),
        "min_fitness": Limit(-math.inf, math.inf, "games of the run below this fitness are left out", whole=False),
        "evaluate_every": Limit(1, 10**7, "updates between evaluations on every split"),
        "eval_steps": Limit(1, 10**7, "steps each game is played for in an evaluation"),
        "eval_games": Limit(0, 10**6, "games of each split evaluated, spread over its fitness (0: all)"),
        "checkpoint_every": Limit(1, 10**7, "updates between checkpoints"),
        "evolve_every": Limit(0, 10**7, "updates between rounds of regret-driven evolution of the training games (0: off)"),
        "pool": Limit(0, 10**6, "games the evolution keeps (0: as many as the training split)"),
    }

    updates: int = 50
    steps: int = 101
    learning_rate: float = 1e-4
    hidden: int = 64
    clone_steps: int = 2000
    clone_batch: int = 256
    clone_learning_rate: float = 1e-4
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

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.evolve_mutation not in MUTATIONS:
            raise ValueError(f"train evolve_mutation must be one of {', '.join(MUTATIONS)}, got {self.evolve_mutation!r}")
        self._check_observation()


#: ``cpu``: the defaults, a few minutes on 2 CPU cores for a 100-generation run's games. ``original``: the
#: original's settings: cloning 100,000 steps of batch 4,096 at learning rate 1e-4; PPO with 100 games of 200 steps an
#: update, 10 epochs of 4 minibatches at learning rate 1e-5, a 256-wide network; 10,000 evaluation steps (for a GPU).
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
