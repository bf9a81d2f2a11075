"""What the evolution engine optimises: a problem turns a batch of genomes into objectives, measures and fields.

The engine never looks inside a genome. Two kinds are supported:

- **Flat vectors** (``n_params`` is an int): a batch is a ``(n, n_params)`` float array, the form every optimiser
  understands (the NCA weights of the structures domain, continuous toy problems).
- **Objects** (``n_params`` is None): a batch is a list of arbitrary picklable genomes (rule sets, finite-state
  machines). The problem must then supply :meth:`Problem.mutate` (and may supply :meth:`Problem.crossover`), and only
  optimisers that vary genomes through those hooks can run it (``ga``, ``map_elites``).

Evaluation must be a pure function of each genome and its seed, so results do not depend on how a batch is split
across workers, and any elite can be re-created later.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["Evaluation", "GenomeStore", "Problem"]


@dataclass(frozen=True)
class Evaluation:
    """Results for a batch of ``n`` candidates, in the order they were given.

    Attributes:
        objective: ``(n,)`` float, higher is better.
        measures: ``(n, m)`` float behaviour descriptors for quality diversity; ``(n, 0)`` if the problem has none.
        fields: extra per-candidate numbers, each ``(n,)`` float (integrity, vertex count, ...).
        failed: ``(n,)`` bool: candidates that could not be evaluated at all (their worker died or hung twice) and
            carry the scores of :meth:`Problem.failed_evaluation` instead. All False unless an evaluator says so.
        extras: one picklable object per candidate that is not a number (a playtrace), handed to
            :meth:`Problem.record`; None when the problem has none.
    """

    objective: np.ndarray
    measures: np.ndarray
    fields: dict[str, np.ndarray] = field(default_factory=dict)
    failed: np.ndarray | None = None
    extras: list[Any] | None = None

    def __post_init__(self) -> None:
        objective = np.asarray(self.objective, dtype=np.float64).reshape(-1)
        n = len(objective)
        measures = np.asarray(self.measures, dtype=np.float64).reshape(n, -1)
        fields = {name: np.asarray(values, dtype=np.float64).reshape(-1) for name, values in self.fields.items()}
        for name, values in fields.items():
            if len(values) != n:
                raise ValueError(f"field {name!r} has {len(values)} values for {n} candidates")
        if not np.isfinite(objective).all() or not np.isfinite(measures).all():
            raise ValueError("objective and measures must be finite numbers (a problem returned NaN or infinity)")
        failed = np.zeros(n, dtype=bool) if self.failed is None else np.asarray(self.failed, dtype=bool).reshape(n)
        object.__setattr__(self, "objective", objective)
        object.__setattr__(self, "measures", measures)
        object.__setattr__(self, "fields", fields)
        object.__setattr__(self, "failed", failed)
        if self.extras is not None:
            extras = list(self.extras)
            if len(extras) != n:
                raise ValueError(f"{len(extras)} extras for {n} candidates")
            object.__setattr__(self, "extras", extras)

    def __len__(self) -> int:
        return len(self.objective)

    @classmethod
    def concatenate(cls, parts: list[Evaluation]) -> Evaluation:
        """Join evaluations of consecutive slices of a batch back into one."""
        names = list(parts[0].fields)
        return cls(
            objective=np.concatenate([p.objective for p in parts]),
            measures=np.concatenate([p.measures for p in parts]),
            fields={name: np.concatenate([p.fields[name] for p in parts]) for name in names},
            failed=np.concatenate([p.failed for p in parts]),
            extras=None if any(p.extras is None for p in parts) else [x for p in parts for x in p.extras],
        )

    def row(self, i: int) -> dict[str, Any]:
        """Candidate ``i`` as plain numbers: objective, measures and fields."""
        return {
            "objective": float(self.objective[i]),
            "measures": self.measures[i].tolist(),
            **{name: float(values[i]) for name, values in self.fields.items()},
        }


class GenomeStore:
    """A run folder's genomes as arrays, for problems whose genomes are large: every genome is written once, when a
    checkpoint first holds it, and the checkpoint and the archive refer to it by a whole-number key.

    :meth:`keys` gives the key of each genome, registering those not stored yet; :meth:`flush` writes them (a new
    file, atomically, before the checkpoint that refers to them); :meth:`load` reads genomes back by key. Genomes
    read back, or derived from stored ones, share what is already stored: a mutant costs only what changed.
    ``genome_type`` is the class of the genomes it keeps (checkpoints name objects of exactly this class by key)."""

    genome_type: type = object

    def keys(self, genomes: Any) -> list[int]:
        raise NotImplementedError

    def flush(self) -> None:
        raise NotImplementedError

    def load(self, keys: Any) -> list[Any]:
        raise NotImplementedError


class Problem:
    """Base class of everything the engine can optimise. Subclasses set the attributes and override the methods.

    Attributes:
        name: short identifier, used in run folders and logs.
        n_params: length of a flat genome vector, or None for object genomes.
        measure_names: names of the quality-diversity measures, e.g. ``("height", "vertices")``.
        measure_ranges: ``(low, high)`` for each measure; they lay out quality-diversity archives.
        field_names: names of the extra per-candidate fields :meth:`evaluate` reports.
        plot_fields: fields of the best candidate worth plotting over generations.
        mean_fields: fields whose mean over each generation's candidates the metrics also record
            (``generation_mean_<field>``; each generation's maximum of every field is always recorded).
        result_objective: the name of a field that ranks candidates in a quality-diversity result archive instead of
            the objective (the layout domains search on throughput plus similarity but keep the best throughput per
            cell, as the original does); None: the objective.
        objective_floor: the lowest objective the problem gives. Quality-diversity archives start their acceptance
            thresholds just below it (so even the worst candidates are kept while nothing better exists) and
            measure their QD score from it.
        genome_types: for object genomes, the classes they are made of beyond numbers, strings and containers
            (a world and its entity classes). Checkpoints hold genomes, and loading one admits no class it is not
            told of (:mod:`evolution.checkpoint`): each must be a plain dataclass, whose restore only sets fields.
            A problem with a genome store (:meth:`open_genome_store`) needs none: its genomes stay out of pickles.
    """

    name: str = "problem"
    n_params: int | None = None
    measure_names: tuple[str, ...] = ()
    measure_ranges: tuple[tuple[float, float], ...] = ()
    field_names: tuple[str, ...] = ()
    plot_fields: tuple[str, ...] = ()
    mean_fields: tuple[str, ...] = ()
    objective_floor: float = 0.0
    result_objective: str | None = None
    genome_types: tuple[type, ...] = ()

    @property
    def flat(self) -> bool:
        """Whether genomes are flat float vectors."""
        return self.n_params is not None

    def initial_genomes(self, count: int, rng: np.random.Generator) -> Any:
        """``count`` random genomes: a ``(count, n_params)`` array, or a list for object genomes."""
        raise NotImplementedError

    def immigrant_genomes(self, count: int, rng: np.random.Generator) -> Any:
        """``count`` random genomes that join a running quality-diversity search (``immigrants``); by default drawn
        as :meth:`initial_genomes` draws them."""
        return self.initial_genomes(count, rng)

    def evaluate(self, genomes: Any, seeds: np.ndarray) -> Evaluation:
        """Evaluate a batch; ``seeds[i]`` is the seed for candidate ``i`` (deterministic problems may ignore it)."""
        raise NotImplementedError

    def failed_evaluation(self, count: int) -> Evaluation:
        """What ``count`` candidates that could not be evaluated at all score: the objective floor, the low corner of
        the measure space, zero in every field, flagged as failed. They stay in the run (an optimiser needs a result
        for every candidate it asked for) and lose to anything that was evaluated."""
        low = [low for low, _ in self.measure_ranges]
        return Evaluation(
            objective=np.full(count, self.objective_floor),
            measures=np.tile(np.asarray(low, dtype=np.float64), (count, 1)).reshape(count, len(low)),
            fields={name: np.zeros(count) for name in self.field_names},
            failed=np.ones(count, dtype=bool),
        )

    def mutate(self, genome: Any, rng: np.random.Generator) -> Any:
        """A mutated copy of ``genome`` (required for object genomes; never modify the argument)."""
        raise NotImplementedError(f"{self.name} does not define its own mutation")

    def mutate_many(self, genomes: list[Any], rng: np.random.Generator) -> list[Any]:
        """A mutated copy of each genome, drawn in turn; a problem whose mutation is compiled may do them in one call
        (with the same draws as :meth:`mutate` on each)."""
        return [self.mutate(genome, rng) for genome in genomes]

    def crossover(self, first: Any, second: Any, rng: np.random.Generator) -> Any:
        """A child combining two parents; optional. The default mixes flat vectors gene by gene."""
        if not self.flat:
            raise NotImplementedError(f"{self.name} does not define crossover for its genomes")
        take_first = rng.random(len(first)) < 0.5
        return np.where(take_first, first, second)

    def genome_to_json(self, genome: Any) -> Any:
        """A JSON-ready form of a genome, for people and other tools. Flat vectors become lists; other genomes are
        used as they are if JSON can hold them (strings, numbers, lists, tuples, dicts). Override for anything else."""
        if self.flat:
            return np.asarray(genome, dtype=np.float64).tolist()
        try:
            json.dumps(genome)
        except (TypeError, ValueError):
            raise NotImplementedError(
                f"{self.name}: a {type(genome).__name__} genome is not JSON-ready; define genome_to_json()"
            ) from None
        return genome

    def genome_from_json(self, data: Any) -> Any:
        """The genome that :meth:`genome_to_json` turned into ``data``; evaluating it must give the same results as
        evaluating the original. Flat vectors come back as float arrays; other genomes as JSON gives them (lists for
        tuples), unless the problem overrides this."""
        if self.flat:
            return np.asarray(data, dtype=np.float64)
        return data

    # -- what a problem may add to a run ------------------------------------------------------------------------------
    def initial_schedule(self) -> dict[str, Any]:
        """For problems whose evaluation changes over a run (a search budget that grows): the starting settings, a
        small dict of plain data that the run checkpoints. Evaluation stays a pure function of each genome as
        :meth:`prepare` hands it over."""
        return {}

    def prepare(self, genomes: Any, schedule: dict[str, Any]) -> Any:
        """The genomes as they are evaluated under ``schedule`` (the default: unchanged). Must not modify its
        arguments: the optimiser keeps the genomes it asked for."""
        return genomes

    def next_schedule(self, schedule: dict[str, Any], best_objective: float) -> dict[str, Any]:
        """The schedule for the next generation, after one whose best objective so far is ``best_objective``."""
        return schedule

    def record(self, folder: Path, generation: int, genomes: Any, evaluation: Evaluation) -> None:
        """Keep what a generation's evaluation found beyond its numbers (``evaluation.extras``) in the run folder.
        Called after every generation with the genomes as evaluated; must write atomically, and writing the same
        generation again (a resumed run repeats the generations after its checkpoint) must give the same files."""

    def open_genome_store(self, folder: Path) -> GenomeStore | None:
        """Where a run folder keeps this problem's genomes as arrays, written once each (see :class:`GenomeStore`);
        None (the default): checkpoints pickle genomes and the archive's are written as JSON lines."""
        return None

    def write_artifacts(self, genome: Any, folder: Path) -> list[Path]:
        """Write files that show a genome (a structure, a picture) into ``folder``; returns their paths."""
        return []

    def close(self) -> None:
        """Release resources held for evaluation (worker pools)."""
