"""Two small problems that exercise the engine without any simulator, one per kind of genome.

- :class:`Sphere`: flat float genomes; climb towards a target point. Every optimiser can run it.
- :class:`Ones`: object genomes (tuples of bits) with the problem's own mutation and crossover, the way the rule-set
  and finite-state-machine domains will bring theirs. ``ga`` and ``map_elites`` can run it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from evolution.problem import Evaluation, Problem

__all__ = ["Ones", "OnesSettings", "Sphere", "SphereSettings"]


@dataclass(frozen=True)
class SphereSettings:
    """Attributes:
    dimensions: genome length.
    noise: standard deviation of evaluation noise drawn from each candidate's seed (0: deterministic).
    """

    dimensions: int = 8
    noise: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.dimensions, int) or self.dimensions < 2:
            raise ValueError(f"problem dimensions must be an integer of at least 2, got {self.dimensions!r}")
        if not self.noise >= 0:
            raise ValueError(f"problem noise must be non-negative, got {self.noise!r}")


class Sphere(Problem):
    """Maximise ``10 - sum((x - 0.5)^2)``; the measures are the first two coordinates (clipped to [-1, 1])."""

    name = "sphere"
    objective_floor = -100.0  # 10 - |x - 0.5|^2, far below anything a search visits
    measure_names = ("x0", "x1")
    measure_ranges = ((-1.0, 1.0), (-1.0, 1.0))
    field_names = ("distance",)
    plot_fields = ("distance",)

    def __init__(self, settings: SphereSettings | None = None) -> None:
        self.settings = settings or SphereSettings()
        self.n_params = self.settings.dimensions

    def initial_genomes(self, count: int, rng: np.random.Generator) -> np.ndarray:
        return rng.uniform(-1.0, 1.0, size=(count, self.n_params))

    def evaluate(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        genomes = np.asarray(genomes, dtype=np.float64)
        distance = np.sqrt(((genomes - 0.5) ** 2).sum(axis=1))
        objective = 10.0 - distance**2
        if self.settings.noise:
            objective = objective + np.array([np.random.default_rng(int(s)).normal(0, self.settings.noise) for s in seeds])
        return Evaluation(objective, np.clip(genomes[:, :2], -1.0, 1.0), {"distance": distance})


@dataclass(frozen=True)
class OnesSettings:
    """Attributes:
    length: bits per genome (even).
    """

    length: int = 16

    def __post_init__(self) -> None:
        if not isinstance(self.length, int) or self.length < 2 or self.length % 2:
            raise ValueError(f"problem length must be an even integer of at least 2, got {self.length!r}")


class Ones(Problem):
    """Genomes are tuples of 0/1; the objective counts ones; the measures count ones in each half."""

    name = "ones"
    n_params = None
    measure_names = ("ones_left", "ones_right")
    field_names = ("ones",)
    plot_fields = ("ones",)

    def __init__(self, settings: OnesSettings | None = None) -> None:
        self.settings = settings or OnesSettings()
        half = self.settings.length // 2
        self.measure_ranges = ((0.0, half + 1.0), (0.0, half + 1.0))

    def initial_genomes(self, count: int, rng: np.random.Generator) -> list[tuple[int, ...]]:
        # Start low (about a quarter ones) so that there is something to climb.
        return [tuple(int(b) for b in rng.random(self.settings.length) < 0.25) for _ in range(count)]

    def mutate(self, genome: tuple[int, ...], rng: np.random.Generator) -> tuple[int, ...]:
        flip = int(rng.integers(len(genome)))
        return tuple(1 - b if i == flip else b for i, b in enumerate(genome))

    def crossover(self, first: tuple[int, ...], second: tuple[int, ...], rng: np.random.Generator) -> tuple[int, ...]:
        cut = int(rng.integers(1, len(first)))
        return first[:cut] + second[cut:]

    def genome_from_json(self, data: list[int]) -> tuple[int, ...]:
        return tuple(int(bit) for bit in data)

    def evaluate(self, genomes: list[tuple[int, ...]], seeds: np.ndarray) -> Evaluation:
        bits = np.array([list(g) for g in genomes], dtype=np.float64).reshape(len(genomes), -1)
        half = self.settings.length // 2
        ones = bits.sum(axis=1)
        return Evaluation(ones, np.stack([bits[:, :half].sum(axis=1), bits[:, half:].sum(axis=1)], axis=1), {"ones": ones})
