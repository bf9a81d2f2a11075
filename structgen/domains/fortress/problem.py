"""The Amorphous Fortress as a problem for the evolution engine: worlds whose machines are well explored, spread over
how many entities they end with and how large (or how unevenly sized) their machines are.

A genome is a world (:class:`.formats.FortressFile`). Evaluating a batch runs every world under the seeds
``sim_seed, sim_seed + 1, ...`` (``sims`` of them; the original uses 0 to 4 for every evaluation) for ``steps`` ticks
in one engine call. The objective is the share of FSM nodes and edges visited, summed over classes, the mean over
the simulations; the measures are the entities at the end (capped at 156, mean over the simulations) and either the
total FSM nodes or the entropy of the class sizes. Mutation is the original's (:func:`.world.mutate_world`).

The original's MAP-Elites is the ``map_elites`` optimiser with ``cells = [100, 100]``, ``batch_size = 10``,
``immigrants = 1``: 10 random worlds, then each generation 9 mutants of elites drawn uniformly from filled cells
and 1 random world; a cell takes a newcomer that is strictly better. The measure ranges are stretched by 100/99 so
that 100 cells bin a value as the original's ``int((v - low) / (high - low) * 99)`` does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from evolution.files import atomic_write
from evolution.problem import Evaluation, Problem
from structgen.budget import check_memory
from structgen.config import Limit, check_limits
from structgen.domains.fortress.engine import POPULATION_CAP, Outcome, Rules, memory_needed, simulate
from structgen.domains.fortress.formats import format_fortress, parse_fortress
from structgen.domains.fortress.genome import CHARACTERS, Genome, node_types
from structgen.domains.fortress.world import Variation, fsm_size_entropy, mutate_world, mutate_worlds, random_world

__all__ = ["FortressProblem", "FortressSettings", "MEASURES"]

#: The measure pairs of the two experiments: the first over total nodes (exp1), the second over entropy (exp2).
MEASURES = ("entities_nodes", "entities_entropy")
# The original's cells: 100 along each measure, a value binned by int(fraction * 99).
_ORIGINAL_CELLS = 100


def _stretched(low: float, high: float) -> tuple[float, float]:
    return (low, low + (high - low) * _ORIGINAL_CELLS / (_ORIGINAL_CELLS - 1))


@dataclass(frozen=True)
class FortressSettings:
    """Attributes:
    measures: "entities_nodes" (entities at the end, total FSM nodes) or "entities_entropy" (entities, entropy of
        the class sizes); a run over entropy also starts from worlds drawn evenly over entropy, as the original.
    sims: simulations per evaluation (5); steps: ticks per simulation (100; the paper also ran 500).
    sim_seed: the first simulation seed; every evaluation uses ``sim_seed .. sim_seed + sims - 1``.
    next_to, take_reach, wall_blocks, inactivity_limit, visit_start_nodes, population_cap: :class:`.engine.Rules`
        (defaults: the original's code; :data:`.engine.RULES` lists each paper's).
    orphan_edges, edge_coin, node_coin, instance_coin: :class:`.world.Variation` (defaults: the original's).
    """

    section: ClassVar[str] = "problem"
    limits: ClassVar[dict[str, Limit]] = {
        "sims": Limit(1, math.inf, "simulations per evaluation"),
        "steps": Limit(1, math.inf, "ticks per simulation"),
        "sim_seed": Limit(0, math.inf, "the first simulation seed"),
        "take_reach": Limit(-1, math.inf, "how far a take reaches (-1: anywhere)"),
        "inactivity_limit": Limit(0, math.inf, "ticks without change that end a simulation (0: never)"),
    }

    measures: str = "entities_nodes"
    sims: int = 5
    steps: int = 100
    sim_seed: int = 0
    next_to: str = "chebyshev"
    take_reach: int = -1
    wall_blocks: str = "first"
    inactivity_limit: int = 0
    visit_start_nodes: bool = False
    population_cap: int = POPULATION_CAP
    orphan_edges: str = "every_node"
    edge_coin: float = 0.5
    node_coin: float = 0.5
    instance_coin: float = 0.5

    def __post_init__(self) -> None:
        if self.measures not in MEASURES:
            raise ValueError(f"problem measures must be one of {', '.join(MEASURES)}, got {self.measures!r}")
        check_limits(self)
        self.rules()
        self.variation()

    def rules(self) -> Rules:
        try:
            return Rules(
                next_to=self.next_to,
                take_reach=None if self.take_reach < 0 else self.take_reach,
                wall_blocks=self.wall_blocks,
                inactivity_limit=self.inactivity_limit,
                visit_start_nodes=self.visit_start_nodes,
                population_cap=self.population_cap,
            )
        except ValueError as error:
            raise ValueError(f"problem {error}") from None

    def variation(self) -> Variation:
        try:
            return Variation(
                orphan_edges=self.orphan_edges,
                edge_coin=self.edge_coin,
                node_coin=self.node_coin,
                instance_coin=self.instance_coin,
            )
        except ValueError as error:
            raise ValueError(f"problem {error}") from None


class FortressProblem(Problem):
    name = "fortress"
    n_params = None
    field_names = ("nodes", "edges", "entities", "ticks", "visited_nodes", "visited_edges")
    plot_fields = ("nodes", "entities")
    objective_floor = 0.0
    genome_types = ()

    def __init__(self, settings: FortressSettings = FortressSettings()) -> None:
        self.settings = settings
        self.rules, self.variation = settings.rules(), settings.variation()
        # One world's evaluation at a time is the least a run needs: refused now, before a run folder is made.
        what = f"problem steps = {settings.steps:,} x sims = {settings.sims}: one evaluation"
        check_memory(memory_needed(1, settings.sims, settings.steps), what, "fewer steps or sims")
        n_types = len(node_types(CHARACTERS))
        if settings.measures == "entities_nodes":
            self.measure_names = ("entities", "nodes")
            self.measure_ranges = (
                _stretched(0, POPULATION_CAP),
                _stretched(len(CHARACTERS), len(CHARACTERS) * n_types),
            )
        else:
            self.measure_names = ("entities", "entropy")
            self.measure_ranges = (_stretched(0, POPULATION_CAP), _stretched(0.0, 1.0))

    def initial_genomes(self, count: int, rng: np.random.Generator) -> list[Genome]:
        start = "entropy" if self.settings.measures == "entities_entropy" else "n_nodes"
        return [random_world(rng, self.variation, start=start) for _ in range(count)]

    def immigrant_genomes(self, count: int, rng: np.random.Generator) -> list[Genome]:
        # The original draws later random worlds by total nodes whatever the measures (illuminate.py's immigrants
        # always use init_strat 'n_nodes'); these bring the small worlds that score best.
        return [random_world(rng, self.variation, start="n_nodes") for _ in range(count)]

    def mutate(self, genome: Genome, rng: np.random.Generator) -> Genome:
        return mutate_world(genome, rng, self.variation)

    def mutate_many(self, genomes: list[Genome], rng: np.random.Generator) -> list[Genome]:
        return mutate_worlds(genomes, rng, self.variation)

    def seeds(self) -> list[int]:
        return list(range(self.settings.sim_seed, self.settings.sim_seed + self.settings.sims))

    def scores(self, worlds: list[Genome], seeds: list[int], steps: int) -> tuple[Outcome, np.ndarray, np.ndarray]:
        """Simulate the worlds under ``seeds``: the outcome, each world's objective (mean share of its machines
        visited) and its entities measure (mean of the ends, each capped at 156)."""
        outcome = simulate(worlds, seeds, steps, self.rules)
        return outcome, outcome.fitness.mean(axis=1), np.minimum(outcome.entities, POPULATION_CAP).mean(axis=1)

    def evaluate(self, genomes: Any, seeds: np.ndarray) -> Evaluation:
        # Every world runs under the same simulation seeds (as the original); the engine's seeds are not needed.
        worlds = list(genomes)
        outcome, objective, entities = self.scores(worlds, self.seeds(), self.settings.steps)
        sizes = np.stack([outcome.tables.n_nodes, outcome.tables.n_edges], axis=1).astype(np.float64)
        if self.settings.measures == "entities_nodes":
            second = sizes[:, 0]
        else:
            second = np.array([fsm_size_entropy(w) for w in worlds])
        return Evaluation(
            objective=objective,
            measures=np.stack([entities, second], axis=1),
            fields={
                "nodes": sizes[:, 0],
                "edges": sizes[:, 1],
                "entities": entities,
                "ticks": outcome.ticks.mean(axis=1),
                "visited_nodes": outcome.visited_nodes.mean(axis=1),
                "visited_edges": outcome.visited_edges.mean(axis=1),
            },
        )

    def genome_to_json(self, genome: Genome) -> str:
        return format_fortress(genome.to_file())

    def genome_from_json(self, data: Any) -> Genome:
        return Genome.from_file(parse_fortress(data, "genome"), "genome")

    def open_genome_store(self, folder: Path) -> Any:
        from structgen.domains.fortress.store import FortressStore

        return FortressStore(folder)

    def write_artifacts(self, genome: Genome, folder: Path) -> list[Path]:
        from structgen.domains.fortress.show import draw_world

        folder = Path(folder)
        world = genome.to_file()
        text = folder / "world.txt"
        atomic_write(text, format_fortress(world).encode())
        picture = folder / "world.png"
        draw_world(world, picture)
        return [text, picture]
