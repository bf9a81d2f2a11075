"""An example domain outside structgen: evolve the faces of a die towards a target mean with many distinct faces.

It shows each part a domain can have: settings (a frozen dataclass), a problem whose genomes are objects of its own
(a ``Die`` dataclass, declared in ``genome_types`` so that its runs' checkpoints may hold it) with its own mutation
and JSON form, measures for quality diversity, a spec that registers it, a verb of its own
(``structgen dice roll``) and an export of run elites (``structgen export RUN_DIR die.json``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from evolution import Evaluation, Problem, atomic_write
from structgen.domains import DomainSpec, MainJob
from structgen.registry.commands import EXIT_OK, DomainCommands, InputError, number, option, seed, verb, verbs


@dataclass(frozen=True)
class DiceSettings:
    """The ``[problem]`` table.

    Attributes:
        faces: faces on the die.
        highest: the highest number a face may show.
        target_mean: the mean roll the die should have.
    """

    faces: int = 6
    highest: int = 12
    target_mean: float = 5.0

    def __post_init__(self) -> None:
        if not (isinstance(self.faces, int) and 2 <= self.faces <= 100):
            raise ValueError(f"problem faces must be an integer in 2..100, got {self.faces!r}")
        if not (isinstance(self.highest, int) and self.highest >= 1):
            raise ValueError(f"problem highest must be a positive integer, got {self.highest!r}")


@dataclass(frozen=True)
class Die:
    """A genome: the number on each face."""

    faces: tuple[int, ...]


class Dice(Problem):
    """A genome is a :class:`Die`; the objective rewards a mean near the target and distinct faces."""

    name = "dice"
    n_params = None
    genome_types = (Die,)
    measure_names = ("mean", "distinct")
    field_names = ("mean", "distinct")
    plot_fields = ("mean",)
    objective_floor = -200.0

    def __init__(self, settings: DiceSettings) -> None:
        self.settings = settings
        self.measure_ranges = ((1.0, float(settings.highest)), (1.0, float(settings.faces)))

    def initial_genomes(self, count, rng):
        highest, faces = self.settings.highest + 1, self.settings.faces
        return [Die(tuple(int(v) for v in rng.integers(1, highest, faces))) for _ in range(count)]

    def mutate(self, genome, rng):
        faces = list(genome.faces)
        faces[int(rng.integers(len(faces)))] = int(rng.integers(1, self.settings.highest + 1))
        return Die(tuple(faces))

    def genome_to_json(self, genome):
        return list(genome.faces)

    def genome_from_json(self, data):
        return Die(tuple(int(v) for v in data))

    def evaluate(self, genomes, seeds):
        faces = np.array([list(g.faces) for g in genomes], dtype=float).reshape(len(genomes), -1)
        mean = faces.mean(axis=1)
        distinct = np.array([len(set(g.faces)) for g in genomes], dtype=float)
        objective = distinct - (mean - self.settings.target_mean) ** 2
        return Evaluation(objective, np.stack([mean, distinct], axis=1), {"mean": mean, "distinct": distinct})


def cmd_roll(args) -> int:
    """roll a die

    Roll a die with the given faces and print the faces rolled.
    """
    try:
        faces = [int(v) for v in args.faces.split(",")]
    except ValueError:
        raise InputError(f"--faces {args.faces!r}: expected numbers separated by commas") from None
    rolls = np.random.default_rng(args.seed).choice(faces, size=args.times)
    print(" ".join(str(int(r)) for r in rolls))
    return EXIT_OK


class DiceCommands(DomainCommands):
    # A verb is its handler (whose docstring is its help) and its options; `structgen dice roll --help` shows them.
    adders = verbs(
        verb(
            "roll",
            cmd_roll,
            option("--faces", default="1,2,3,4,5,6", help="face values, comma-separated"),
            number("--times", 1, 10**6, 10, "how many rolls"),
            seed("random seed"),
            examples=["structgen dice roll --faces 1,1,2,3,5,8 --times 5"],
        )
    )

    def export_elite(self, problem, genome, output: Path, args, origin) -> str:
        if output.suffix != ".json":
            raise InputError(f"{output}: a die is written as .json")
        atomic_write(output, json.dumps({"faces": list(genome.faces), **origin}) + "\n")
        return f"{output}: faces {', '.join(map(str, genome.faces))}"


COMMANDS = DiceCommands()

DOMAIN = DomainSpec(
    id="dice-v0",
    entry_point="dice_domain:Dice",
    settings="dice_domain:DiceSettings",
    summary="example plugin: the faces of a die, mean near a target and all different",
    commands="dice_domain:COMMANDS",
    main_job=MainJob(run={"generations": 20, "workers": 0}, optimizers={"ga": {"population": 20, "parents": 4}}),
)
