"""Autoverse as a problem for the evolution engine: games evolved so that best-first search needs many iterations to
find their best play.

A genome is a game (:mod:`.game`). Evaluating a batch searches every game at once (:func:`.search.search`); the
objective is the iteration at which the search first found its best return. The search budget is the run's
schedule: it starts at ``budget`` and grows by ``budget_step`` after every generation whose best objective so far
is above half of it, as the original does (elites are not re-evaluated when it grows, as in the original). Each
evaluated game's best playtrace is kept in the run folder, ``playtraces/gen-NNNNNN.npz``.

The original's loop is the ``ga`` optimiser with ``population = 80, parents = 40, initial = 40``: 40 random games,
then 40 children a generation from parents drawn with replacement, the best 40 of parents and children kept.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from evolution.files import atomic_write
from evolution.problem import Evaluation, Problem
from structgen.config import Limit, check_limits
from structgen.devices import check_device_name
from structgen.domains.autoverse.game import MUTATIONS, game_from_json, game_to_json, mutate_game, random_game

__all__ = ["AutoverseProblem", "AutoverseSettings", "PLAYTRACES"]

#: The run-folder directory of the playtraces, one file per generation.
PLAYTRACES = "playtraces"
#: Longest playtrace: an episode's steps.
TRACE_LENGTH = 101


@dataclass(frozen=True)
class AutoverseSettings:
    """Attributes:
    budget: search expansions per game at the start of a run (200 in the original).
    budget_step: added to the budget after a generation whose best fitness so far exceeds half of it (200).
    mutation: "rules_and_map" (rewards, rule patterns and the map mutate, as the paper describes) or "map_only"
        (what the released code runs: its rule mutation is a no-op).
    fitness_tiebreak: add ``iterations / (budget + 2)`` to a fitness of 1 (the original computes this and its
        sequential evaluation drops it: false reproduces that).
    force_clear: the original's quirk: every action but placing clears force in front of the player.
    empty_rules_fire: the original's quirk: a rule with an empty input matches every cell.
    device: where games are stepped and states hashed ("cpu", "cuda").
    """

    section: ClassVar[str] = "problem"
    limits: ClassVar[dict[str, Limit]] = {
        "budget": Limit(1, 10**7, "search expansions per game at the start of a run"),
        "budget_step": Limit(1, 10**7, "added to the budget after a generation whose best fitness exceeds half of it"),
    }

    budget: int = 200
    budget_step: int = 200
    mutation: str = "rules_and_map"
    fitness_tiebreak: bool = True
    force_clear: bool = False
    empty_rules_fire: bool = False
    device: str = "cpu"

    def __post_init__(self) -> None:
        check_limits(self)
        if self.mutation not in MUTATIONS:
            raise ValueError(f"problem mutation must be one of {', '.join(MUTATIONS)}, got {self.mutation!r}")
        for name in ("fitness_tiebreak", "force_clear", "empty_rules_fire"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"problem {name} must be true or false, got {getattr(self, name)!r}")
        check_device_name(self.device, "problem device")

    def mechanics(self) -> Any:
        from structgen.domains.autoverse.engine import Mechanics

        return Mechanics(force_clear=self.force_clear, empty_rules_fire=self.empty_rules_fire)


class AutoverseProblem(Problem):
    name = "autoverse"
    n_params = None
    field_names = ("best_return", "iterations", "budget", "trace_length")
    plot_fields = ("best_return", "budget")
    objective_floor = 0.0

    def __init__(self, settings: AutoverseSettings | None = None) -> None:
        self.settings = settings or AutoverseSettings()

    def initial_genomes(self, count: int, rng: np.random.Generator) -> list[dict[str, np.ndarray]]:
        return [random_game(rng) for _ in range(count)]

    def mutate(self, genome: dict[str, Any], rng: np.random.Generator) -> dict[str, np.ndarray]:
        return mutate_game(genome, rng, self.settings.mutation)

    # -- the budget schedule ----------------------------------------------------------------------------------------------
    def initial_schedule(self) -> dict[str, Any]:
        return {"budget": self.settings.budget}

    def prepare(self, genomes: Any, schedule: dict[str, Any]) -> list[dict[str, Any]]:
        return [{**genome, "budget": int(schedule["budget"])} for genome in genomes]

    def next_schedule(self, schedule: dict[str, Any], best_objective: float) -> dict[str, Any]:
        budget = int(schedule["budget"])
        if best_objective > budget / 2:
            budget += self.settings.budget_step
        return {"budget": budget}

    # -- evaluation -------------------------------------------------------------------------------------------------------
    def evaluate(self, genomes: Any, seeds: np.ndarray) -> Evaluation:
        from structgen.domains.autoverse.search import search, search_fitness

        genomes = list(genomes)
        budgets = [int(g.get("budget", self.settings.budget)) for g in genomes]
        seeds = [int(s) % 2**63 for s in np.asarray(seeds).reshape(-1)]
        results = search(genomes, budgets, seeds, device=self.settings.device, mechanics=self.settings.mechanics())
        return Evaluation(
            objective=[search_fitness(r, self.settings.fitness_tiebreak) for r in results],
            measures=np.zeros((len(genomes), 0)),
            fields={
                "best_return": [r.best_return for r in results],
                "iterations": [r.iterations for r in results],
                "budget": budgets,
                "trace_length": [len(r.actions) for r in results],
            },
            extras=[r.actions for r in results],
        )

    def record(self, folder: Path, generation: int, genomes: Any, evaluation: Evaluation) -> None:
        if evaluation.extras is None:
            return
        traces = np.full((len(genomes), TRACE_LENGTH), -1, dtype=np.int8)
        for row, actions in enumerate(evaluation.extras):
            traces[row, : len(actions)] = actions
        buffer = io.BytesIO()
        np.savez_compressed(
            buffer,
            rules=np.stack([g["rules"] for g in genomes]),
            rewards=np.stack([g["rewards"] for g in genomes]),
            map=np.stack([g["map"] for g in genomes]),
            actions=traces,
            fitness=evaluation.objective,
            best_return=evaluation.fields["best_return"],
            budget=evaluation.fields["budget"],
            generation=np.full(len(genomes), generation),
        )
        target = Path(folder) / PLAYTRACES
        target.mkdir(exist_ok=True)
        atomic_write(target / f"gen-{generation:06d}.npz", buffer.getvalue())

    # -- files ------------------------------------------------------------------------------------------------------------
    def genome_to_json(self, genome: Any) -> Any:
        return game_to_json(genome)

    def genome_from_json(self, data: Any) -> Any:
        return game_from_json(data)

    def write_artifacts(self, genome: Any, folder: Path) -> list[Path]:
        from structgen.domains.autoverse.search import search
        from structgen.domains.autoverse.show import draw_game

        # The best play search finds in the game, at the budget it was scored with, drawn with the return along it.
        budget = int(genome.get("budget", self.settings.budget)) if isinstance(genome, dict) else self.settings.budget
        result = search([genome], budgets=budget, seeds=[0], mechanics=self.settings.mechanics(), device=self.settings.device)[0]
        path = Path(folder) / "game.png"
        draw_game(genome, path, result.actions, mechanics=self.settings.mechanics(), device=self.settings.device)
        return [path]
