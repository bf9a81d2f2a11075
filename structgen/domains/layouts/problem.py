"""The three layout domains as problems: a genome is the conv NCA's weights; evaluating grows a layout from the seed
block, repairs it (warehouse, manufacturing) and measures it.

The warehouse and manufacturing objective is the original's: the mean throughput of ``simulations`` runs of the
multi-robot simulator on the repaired layout plus ``alpha * similarity`` (with ``simulations = 0``, the similarity
term alone). The maze's objective is the original's: 1 if solvable, else 0.
Measures are the original's: shelf components and pattern entropy (warehouse), station count and pattern entropy
(manufacturing), pattern entropy and the agent's mean path length (maze).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from evolution.problem import Evaluation, Problem
from structgen.budget import check_memory
from structgen.config import Limit, check_limits
from structgen.domains.layouts.conv_nca import HIDDEN, ConvNCA
from structgen.domains.layouts.kinds import KINDS, REPAIR_TIME_LIMIT, LayoutKind
from structgen.domains.layouts.maze.walkers import MAX_DIAMETER_FLOOR
from structgen.domains.layouts.measures import pattern_entropy, shelf_components, similarity
from structgen.domains.layouts.repair import REPAIR_BYTES_PER_CELL, REPAIR_GREEDY_BEYOND, RepairError, repair
from structgen.domains.layouts.warehouse.simulator import PLANNERS
from structgen.errors import InputError

#: What each warehouse or manufacturing evaluation records beside its objective and measures: ``highs`` is 1 where
#: HiGHS repaired the layout (0: a cheap repair alone, see ``repair_greedy_beyond``), ``patched`` 1 where that cheap
#: repair was the patch repair (0 with ``highs`` 0: the row repair), ``timed_out`` 1 where a HiGHS solve stopped at
#: its time limit.
REPAIRED_FIELDS = (
    "throughput",
    "congested",
    "similarity",
    "hamming",
    "optimal",
    "failed",
    "highs",
    "patched",
    "timed_out",
)

#: The repair's ways of searching (``repair_search``; see :class:`WarehouseSettings`).
REPAIR_SEARCHES = ("bounded", "full")

__all__ = ["LayoutProblem", "ManufacturingSettings", "MazeSettings", "REPAIR_SEARCHES", "WarehouseSettings"]


#: The NCA steps and hidden channels of any layout problem.
_NCA_LIMITS = {
    "iterations": Limit(0, 100_000, "NCA steps (0: the paper's for the size)"),
    "hidden": Limit(1, 1024, "the NCA's hidden channels"),
}


@dataclass(frozen=True)
class WarehouseSettings:
    """Attributes:
    size: map size, full map with workstation columns (``"33x36"``, ..., ``"101x102"``; ``"9x16"`` for quick runs).
    iterations: NCA steps (0: the paper's for the size, 50 or 200).
    shelves: exact shelf count of the repair (0: the paper's for the size; required for sizes it did not use).
    alpha: weight of the similarity score in the objective.
    agents: robots in each simulation (200 in the paper); for manufacturing, the cells kept free of stations.
    simulations: simulations per layout, their throughputs averaged (5 in the paper; 0: the objective is the
        similarity term alone).
    simulation_steps: steps of each simulation (1,000 in the paper's training).
    planner: the simulator's planner (``pp``, ``pbs`` or ``pibt``; see ``structgen warehouse simulate --help``).
    uneven: left workstations five times likelier as goals.
    repair_time_limit: seconds HiGHS may spend on one layout.
    repair_threads: HiGHS's threads per repair.
    repair_search: ``"bounded"`` (the default): every HiGHS solve without its sub-MIP heuristics and stopped after
        ``repair_node_limit`` nodes (0: after the root), the fewer changes of its answer and the cheap repairs'
        kept, so that the answer depends on counts, never on the clock, and a run repeats exactly (the time limit
        is then only a safety net, and ``timed_out`` counts the repairs that reached it); ``"full"``: HiGHS as the
        paper ran its solver, searching for the fewest changes until the time limit, so that a repair cut short
        by the clock depends on the machine's speed (11 of the 2,500 evaluations of the manufacturing run of
        structgen 0.4, 1 of the even warehouse's 10,000).
    repair_node_limit: stop each repair after this many branch-and-bound nodes (0: no limit in a full search, the
        root alone in a bounded one). In a full search HiGHS can spend the whole time limit before branching, on
        layouts far from valid or with sub-MIP heuristics at the root, whatever the node limit.
    repair_greedy_beyond: layouts more than this many cells from valid (the shelf count's difference plus the cells
        breaking a rule: ``repair.distance_from_valid``) get the greedy repair without HiGHS; -1: every layout goes
        to HiGHS, as in the paper. HiGHS proves the fewest changes within about a second on layouts up to 100 cells
        from valid and can spend its whole time limit on layouts far from it (random NCAs' empty ones), so with the
        default a training run costs little and repeats exactly (measured: docs/layouts.md).
    hidden: the NCA's hidden channels (32 in the paper).
    """

    size: str = "33x36"
    iterations: int = 0
    shelves: int = 0
    alpha: float = 5.0
    agents: int = 200
    simulations: int = 5
    simulation_steps: int = 1000
    planner: str = "pp"
    uneven: bool = False
    repair_time_limit: float = REPAIR_TIME_LIMIT
    repair_threads: int = 1
    repair_node_limit: int = 0
    repair_greedy_beyond: int = REPAIR_GREEDY_BEYOND
    repair_search: str = "bounded"
    hidden: int = HIDDEN

    kind = "warehouse"
    section: ClassVar[str] = "problem"
    limits: ClassVar[dict[str, Limit]] = {
        **_NCA_LIMITS,
        "shelves": Limit(0, 10**7, "exact shelf count of the repair (0: the paper's for the size)"),
        "alpha": Limit(-math.inf, math.inf, "weight of the similarity score in the objective", whole=False),
        "agents": Limit(0, 10**7, "robots in each simulation"),
        "simulations": Limit(0, 1000, "simulations per layout (0: the similarity term alone)"),
        "simulation_steps": Limit(1, 10**7, "steps of each simulation"),
        "repair_time_limit": Limit(0, 86400, "seconds HiGHS may spend on one layout", whole=False, above=True),
        "repair_threads": Limit(1, 1024, "HiGHS's threads per repair"),
        "repair_node_limit": Limit(0, 10**9, "branch-and-bound nodes per repair (0: no limit)"),
        "repair_greedy_beyond": Limit(-1, 10**9, "layouts further than this from valid skip HiGHS (-1: none do)"),
    }

    def __post_init__(self) -> None:
        KINDS[self.kind].size(self.size)
        check_limits(self)
        if self.planner not in PLANNERS:
            raise ValueError(f"problem planner must be one of {', '.join(PLANNERS)}, got {self.planner!r}")
        if self.repair_search not in REPAIR_SEARCHES:
            raise ValueError(f"problem repair_search must be one of {', '.join(REPAIR_SEARCHES)}, got {self.repair_search!r}")


@dataclass(frozen=True)
class ManufacturingSettings(WarehouseSettings):
    """The warehouse's attributes; ``agents`` is also the number of cells the repair keeps free of stations (200 in
    the paper), and ``uneven`` does not apply."""

    kind = "manufacturing"

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.uneven:
            raise ValueError("problem uneven applies to warehouses only (manufacturing has no workstations)")


@dataclass(frozen=True)
class MazeSettings:
    """Attributes:
    size: the maze inside its outer wall (``"16x16"``, ``"32x32"``, ``"64x64"``, ``"96x96"``, or ``"RxC"``).
    iterations: NCA steps (0: 50).
    agent: ``learned`` (the learning agent of :mod:`.maze.agent`, the paper's judge) or a scripted one: ``oracle``,
        ``wall_follower``, ``explorer`` or ``random_walk``.
    agent_weights: the learned agent's weights (a ``structgen maze train`` run's ``agent.pt``); empty: the shipped agent.
    episodes: episodes per maze (50 in the paper).
    measures: ``walls`` (number of walls x the agent's mean path length, the paper's main run) or ``entropy``
        (pattern entropy x mean path length, its second).
    hidden: the NCA's hidden channels.
    """

    size: str = "16x16"
    iterations: int = 0
    agent: str = "learned"
    agent_weights: str = ""
    episodes: int = 50
    measures: str = "walls"
    hidden: int = HIDDEN

    kind = "maze"
    section: ClassVar[str] = "problem"
    limits: ClassVar[dict[str, Limit]] = {**_NCA_LIMITS, "episodes": Limit(1, 10_000, "episodes per maze")}

    def __post_init__(self) -> None:
        from structgen.domains.layouts.maze.walkers import AGENTS

        KINDS[self.kind].size(self.size)
        check_limits(self)
        if self.agent not in ("learned", *AGENTS):
            raise ValueError(f"problem agent must be one of learned, {', '.join(AGENTS)}, got {self.agent!r}")
        if self.measures not in ("walls", "entropy"):
            raise ValueError(f"problem measures must be walls or entropy, got {self.measures!r}")
        if self.agent_weights and self.agent != "learned":
            raise ValueError(f"problem agent_weights is for the learned agent, not {self.agent!r}")


class LayoutProblem(Problem):
    """Grow, repair and measure layouts of one kind."""

    objective_floor = 0.0

    def __init__(self, settings) -> None:
        self.settings = settings
        self.kind: LayoutKind = KINDS[settings.kind]
        self.size = self.kind.size(settings.size)
        self.iterations = settings.iterations or self.size.iterations
        self.nca = ConvNCA(self.kind.nca_tiles, settings.hidden)
        self.n_params = self.nca.n_params
        self.seed_tiles = self.kind.seed(self.size.grown)
        self.name = self.kind.name
        self.shelves = getattr(settings, "shelves", 0) or self.size.shelves
        self._scored_best: tuple[float, bytes, Any] | None = None  # (objective, genome key, its repair), see record()
        full = self.kind.complete(self.seed_tiles).shape
        # Refused now, before a run folder is made, rather than in the first evaluation.
        if self.kind.name == "maze":
            if full[0] * full[1] > MAX_DIAMETER_FLOOR:
                raise InputError(
                    f"problem size = {settings.size!r}: a {full[0]}x{full[1]} maze may have more than "
                    f"{MAX_DIAMETER_FLOOR:,} floor cells, and finding its start and goal searches from every one"
                )
        else:
            where = f"problem size = {settings.size!r}: repairing one {full[0]}x{full[1]} layout"
            check_memory(full[0] * full[1] * REPAIR_BYTES_PER_CELL, where, "a smaller size")
        if self.kind.name == "warehouse":
            low, high = (140.0, 240.0) if settings.size == "33x36" and self.shelves == 240 else (0.0, float(max(self.shelves, 1)))
            self.measure_names = ("shelf_components", "entropy")
            self.measure_ranges = ((low, high), (0.0, 1.0))
            self.field_names = REPAIRED_FIELDS
            # The original's result archive keeps each cell's best throughput, without the similarity term.
            self.result_objective = "throughput" if settings.simulations else None
        elif self.kind.name == "manufacturing":
            self.measure_names = ("stations", "entropy")
            self.measure_ranges = ((0.0, 600.0 if settings.size == "33x36" else float(full[0] * full[1])), (0.0, 1.0))
            self.field_names = REPAIRED_FIELDS
            self.result_objective = "throughput" if settings.simulations else None
        if self.kind.name != "maze":
            # Each generation's share of layouts HiGHS repaired, of those the patch repair answered (the rest of the
            # cheap path took the row repair), and of repairs stopped by the clock (a run repeats exactly only while
            # that stays 0).
            self.mean_fields = ("highs", "patched", "timed_out")
        else:
            horizon = float(2 * full[0] * full[1])
            if settings.measures == "walls":
                self.measure_names = ("walls", "path_length")
                self.measure_ranges = ((0.0, float(self.size.grown[0] * self.size.grown[1])), (0.0, horizon))
            else:
                self.measure_names = ("entropy", "path_length")
                self.measure_ranges = ((0.0, 1.0), (0.0, horizon))
            self.field_names = ("success_rate", "shortest_path", "walls", "entropy")
            self._agent = None  # the learned agent, loaded on first use (in each worker)
            if settings.agent == "learned" and settings.agent_weights:
                # Read now, so that a file that is not an agent stops the run before its first generation instead of
                # going unread while no grown maze is solvable (a run of zeros).
                from structgen.domains.layouts.maze.training import agent_policy

                self._agent = agent_policy(settings.agent_weights)
        self.plot_fields = self.field_names[:2]

    def initial_genomes(self, count: int, rng: np.random.Generator) -> np.ndarray:
        # The original starts its emitters at zero with step size 0.2.
        return rng.normal(0.0, 0.2, size=(count, self.n_params))

    def grow(self, genomes: np.ndarray, device: str | None = None) -> np.ndarray:
        """Whole unrepaired maps, ``(P, H, W)``."""
        grown = self.nca.grow(np.asarray(genomes), self.seed_tiles, self.iterations, device)
        return np.stack([self.kind.complete(g) for g in grown])

    def evaluate(self, genomes: np.ndarray, seeds: np.ndarray) -> Evaluation:
        maps = self.grow(genomes)
        if self.kind.name == "maze":
            rows = self._judge_mazes(maps, seeds)
        else:
            rows = [self._judge(tiles, int(seed)) for tiles, seed in zip(maps, seeds)]
        objective = np.array([r[0] for r in rows], dtype=np.float64)
        measures = np.array([r[1] for r in rows], dtype=np.float64).reshape(len(rows), len(self.measure_names))
        fields = {name: np.array([r[2][name] for r in rows], dtype=np.float64) for name in self.field_names}
        # The repaired layouts travel back as extras (None for mazes): see record().
        extras = None if self.kind.name == "maze" else [r[3] for r in rows]
        return Evaluation(objective, measures, fields, extras=extras)

    def record(self, folder: Path, generation: int, genomes: Any, evaluation: Evaluation) -> None:
        """Keep the repaired layout of the best candidate seen so far (chosen as the run chooses its best), so that
        ``best/`` shows the layout that was scored. Repairing again is not the same: with a time limit HiGHS can end
        elsewhere (measured: 518 cells changed in ``best/layout.json`` against the 204 of the scored layout)."""
        if evaluation.extras is None:
            return
        top = int(np.argmax(evaluation.objective))
        if self._scored_best is None or evaluation.objective[top] > self._scored_best[0]:
            self._scored_best = (float(evaluation.objective[top]), _genome_key(genomes[top]), evaluation.extras[top])

    def _judge_mazes(self, maps: np.ndarray, seeds: np.ndarray) -> list[tuple]:
        """Objective 1 for a solvable maze, else 0; the agent's mean steps over ``episodes`` episodes (the horizon
        for an unsolvable maze) is the path length. The learned agent plays every solvable maze at once."""
        from structgen.domains.layouts.maze.walkers import diameter, run_episodes

        settings = self.settings
        grown = [self.kind.storage(tiles) for tiles in maps]
        horizon = self.measure_ranges[1][1]
        shortest = [diameter(g) for g in grown]
        success, steps = np.zeros(len(grown)), np.full(len(grown), horizon)
        solvable = [i for i, ends in enumerate(shortest) if ends is not None]
        if settings.agent == "learned" and solvable:
            from structgen.domains.layouts.maze.agent import run_agent

            if self._agent is None:
                from structgen.domains.layouts.maze.training import agent_policy

                self._agent = agent_policy(settings.agent_weights)
            chosen = np.asarray(seeds)[solvable]
            results = run_agent(self._agent, [grown[i] for i in solvable], episodes=settings.episodes, seeds=chosen)
            success[solvable], steps[solvable] = results.reached, results.steps
        elif solvable:
            for i in solvable:
                stats = run_episodes(grown[i], settings.agent, episodes=settings.episodes, seed=int(seeds[i]))
                success[i], steps[i] = stats.success_rate, stats.mean_steps
        rows = []
        for i, maze in enumerate(grown):
            entropy, walls = pattern_entropy(maze, self.kind), float((maze == 1).sum())
            fields = {
                "success_rate": float(success[i]),
                "shortest_path": shortest[i][2] if shortest[i] is not None else -1,
                "walls": walls,
                "entropy": entropy,
            }
            first = walls if settings.measures == "walls" else entropy
            rows.append((1.0 if shortest[i] is not None else 0.0, (first, float(steps[i])), fields, None))
        return rows

    def _judge(self, tiles: np.ndarray, seed: int):
        try:
            result = self._repair(tiles, seed)
        except RepairError:
            low = [lo for lo, _ in self.measure_ranges]
            failed = {name: 1.0 if name == "failed" else 0.0 for name in self.field_names}
            return self.objective_floor, low, failed, None
        hamming, score = similarity(tiles, result.tiles, self.kind)
        first = (
            shelf_components(result.tiles, self.kind)
            if self.kind.name == "warehouse"
            else float(np.isin(result.tiles, self.kind.blocking_tiles()).sum())
        )
        fields = {
            "similarity": score,
            "hamming": hamming,
            "optimal": float(result.optimal),
            "failed": 0.0,
            "highs": float(result.searched),
            "patched": float(result.method == "patch"),
            "timed_out": float(result.timed_out),
        }
        throughput, congested = self._simulate(result.tiles, seed)
        fields.update(throughput=throughput, congested=congested)
        objective = throughput + self.settings.alpha * score
        return objective, (first, pattern_entropy(result.tiles, self.kind)), fields, (result.tiles, result.optimal)

    def _repair(self, tiles: np.ndarray, seed: int):
        return repair(
            tiles,
            self.kind,
            shelves=self.shelves if self.kind.name == "warehouse" else None,
            agents=self.settings.agents if self.kind.name == "manufacturing" else 0,
            time_limit=self.settings.repair_time_limit,
            seed=seed % (2**31),
            threads=self.settings.repair_threads,
            node_limit=self.settings.repair_node_limit or None,
            greedy_beyond=None if self.settings.repair_greedy_beyond < 0 else self.settings.repair_greedy_beyond,
            bounded=self.settings.repair_search == "bounded",
        )

    def write_artifacts(self, genome, folder: Path) -> list[Path]:
        """The genome's layout: ``layout.json`` and ``layout.png``; warehouse and manufacturing layouts are repaired
        first (a run's best: the repaired layout it was scored on; any other genome: repaired with seed 0 and the
        run's repair settings; a layout HiGHS cannot repair keeps only ``unrepaired.json``), the picture showing the
        grown and repaired maps side by side."""
        from structgen.domains.layouts.show import draw

        tiles = self.grow(np.asarray(genome)[None])[0]
        name = "layout" if self.kind.name == "maze" else "unrepaired"
        grown = self.kind.grid(tiles, name=name, kind=self.kind.name, iterations=self.iterations)
        if self.kind.name == "maze":
            written = [grown.save(folder / "layout.json")]
            return written + [draw([grown], self.kind, folder / "layout.png", titles=["grown"])]
        written = [grown.save(folder / "unrepaired.json")]
        scored = self._scored_best
        if scored is not None and scored[1] == _genome_key(genome):
            if scored[2] is None:  # the repair failed when it was scored
                return written
            repaired_tiles, optimal = scored[2]
        else:
            try:
                result = self._repair(tiles, 0)
            except RepairError:
                return written
            repaired_tiles, optimal = result.tiles, result.optimal
        hamming, score = similarity(tiles, repaired_tiles, self.kind)
        repaired = self.kind.grid(
            repaired_tiles, name="layout", kind=self.kind.name, hamming=hamming, sim_score=score, optimal=optimal
        )
        written.append(repaired.save(folder / "layout.json"))
        titles = ["grown by the NCA", f"repaired ({hamming} cells changed)"]
        return written + [draw([grown, repaired], self.kind, folder / "layout.png", titles=titles)]

    def _simulate(self, tiles: np.ndarray, seed: int) -> tuple[float, float]:
        """Mean throughput over the simulations, and the share of them that congested."""
        from structgen.domains.layouts.warehouse.simulator import evaluate_layout

        settings = self.settings
        if settings.simulations == 0:
            return 0.0, 0.0
        try:
            runs = evaluate_layout(
                tiles,
                settings.agents,
                settings.simulations,
                settings.simulation_steps,
                seed=seed,
                kind=self.kind,
                uneven=settings.uneven,
                planner=settings.planner,
            )
        except InputError:  # the simulator refuses the layout (too little floor for the robots): it cannot work
            return 0.0, 1.0
        # Training averages every run, congested ones included, as the original's objective does.
        return float(runs.throughputs.mean()), float(runs.congested.mean())


def _genome_key(genome: Any) -> bytes:
    return np.asarray(genome, dtype=np.float64).tobytes()
