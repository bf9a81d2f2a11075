"""A lifelong multi-robot simulation that scores a warehouse or manufacturing layout by its throughput.

The task models follow the paper's simulator (research notes 1.7): agents start on distinct non-shelf cells and
move to a 4-neighbour cell or wait each step, without rotation; shelves and stations block, everything else is
traversable. Warehouse: each agent gets a random endpoint first, then goals alternate between a workstation (drawn
by weight) and an endpoint. Manufacturing: goals are endpoints next to a station, visiting station kinds 0, 1, 2,
0, ... in turn (an endpoint beside two stations of a kind is twice as likely); a task is done after standing on its
endpoint 2, 5 or 10 steps by kind, and standing there for a task does not count towards congestion.
Every ``replan`` steps all agents plan collision-free paths for the next ``window`` steps (rolling-horizon planning)
and the first ``replan`` steps are carried out. Throughput is the number of goals reached divided by the number of
steps asked for. When more than half of the agents stood still over a whole replanning interval, the run is
congested and stops there (throughput keeps the full horizon as its denominator, as in the original).

Planner ``"pbs"``: windowed Priority-Based Search, the original's planner, written from its papers and from a
plain-words account of RHCR's start-cell rules and failure repair (:mod:`._pbs`; each rule can be switched off with
``pbs_off``).

Planner ``"pp"`` (the default, for speed): windowed prioritized planning (space-time A* against a reservation
table; agents that reached a goal longest ago plan first; an agent that finds no path moves to the front and
planning restarts; after a budget of restarts, one per 40 agents and at least five, such agents wait in place). The
priority rule and the restart budget were chosen against the original's recorded throughputs (benchmarks/layouts.md):
with more restarts at 200 agents the human layout no longer congests, as it does there.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from evolution.pool import Lost, WorkerPool
from structgen.budget import check_memory
from structgen.domains.layouts.kinds import MANUFACTURING, WAREHOUSE, LayoutKind
from structgen.errors import InputError

__all__ = [
    "PBS_RULES",
    "PLANNERS",
    "LayoutEvaluation",
    "SimulationResult",
    "compile_kernels",
    "evaluate_layout",
    "simulate",
]

PLANNERS = ("pp", "pbs", "pibt")
#: The ``pbs`` planner's rules that ``pbs_off`` can switch off, by name (module notes of :mod:`._pbs`): rule 1, own
#: starts; rule 2, hold the start; rule 3, the waiting robot stays; rule 5, dead pairs first and ties to fewer
#: collisions. Rule 4 is ``replan_cap`` and rule 6 ``fallback="repair"``.
PBS_RULES = ("own_starts", "hold_start", "waiting_stays", "search_order")
FALLBACKS = ("repair", "pp")
#: Steps a manufacturing task takes at a station of each kind (the original's ``station_wait_times``).
STATION_WAITS = (2, 5, 10)
#: Goals queued ahead per agent at most (the queue is filled until its route is longer than the goal horizon).
MAX_GOALS = 8


@dataclass(frozen=True)
class SimulationResult:
    """One simulation: ``throughput`` = goals reached / ``steps``; ``congested`` says the run stopped early (at
    ``stopped_at``) because more than half of the agents stood still over a replanning interval; ``restarts``
    and ``held`` count planning rounds started again and agents made to wait because they found no path;
    ``positions`` (every agent's cell at every step) and ``finished`` (one row ``step, agent, cell`` per task
    finished) are the trace when asked for. Planner ``pbs`` also counts its search: ``nodes`` planned, rounds it
    gave up on (``fallbacks``) and ``failed_children``, the children it could not make consistent."""

    throughput: float
    tasks: int
    steps: int
    agents: int
    congested: bool
    stopped_at: int
    seconds: float
    planner: str
    restarts: int
    held: int
    positions: np.ndarray | None = None
    finished: np.ndarray | None = None
    nodes: int = 0
    fallbacks: int = 0
    failed_children: int = 0


class _WarehouseTasks:
    """Goals alternate between a workstation (by weight) and an endpoint; no task waits. The draws themselves are
    :func:`._steps.queue_goals`'s; this holds its tables."""

    #: The planner's default restart budget: one per this many agents (see ``simulate``'s ``restarts``).
    agents_per_restart = 40

    def __init__(self, tiles: np.ndarray, kind: LayoutKind, uneven: bool, rng: np.random.Generator) -> None:
        code = kind.vocabulary.index
        self.workstations = np.flatnonzero(tiles.ravel() == code("w"))
        self.endpoints = np.flatnonzero(tiles.ravel() == code("e"))
        if len(self.workstations) == 0 or len(self.endpoints) == 0:
            raise InputError("a warehouse simulation needs workstations and endpoints")
        weights = np.ones(len(self.workstations))
        if uneven:  # the paper's uneven setting: the left column's workstations are five times likelier
            weights[self.workstations % tiles.shape[1] < tiles.shape[1] // 2] = 5.0
        weights /= weights.sum()
        # Generator.choice(p=...) draws one uniform and bisects this same cumulative table: drawing the uniform and
        # bisecting gives the same goals.
        self.cumulative = np.cumsum(weights)
        self.cumulative /= self.cumulative[-1]
        self.targets = np.concatenate([self.workstations, self.endpoints]).astype(np.int32)
        self.beside, self.beside_start = np.zeros(0, dtype=np.int64), np.zeros(1, dtype=np.int64)
        self.rng = rng

    def first(self, positions: np.ndarray) -> tuple[np.ndarray, int]:
        # 1 where the goal after the first endpoint is a workstation (robots starting on one go to an endpoint).
        self.toggle = (~np.isin(positions, self.workstations)).astype(np.int64)
        return self.rng.choice(self.endpoints, len(positions)), 0


class _ManufacturingTasks:
    """Goals visit endpoints beside stations of kind 0, 1, 2, 0, ...; each task waits by its station's kind. The
    same endpoint may serve two kinds in a row: the original allows it, and so does this."""

    agents_per_restart = 4

    def __init__(self, tiles: np.ndarray, kind: LayoutKind, rng: np.random.Generator) -> None:
        from structgen.domains.layouts.measures import neighbour_count  # loads scipy: not at command start-up

        endpoint = (tiles == kind.vocabulary.index("e")).ravel()
        beside: list[np.ndarray] = []  # per station kind: endpoints, once per adjacent station of the kind
        for station, name in enumerate("012"):
            touching = np.where(endpoint, neighbour_count(tiles == kind.vocabulary.index(name)).ravel(), 0)
            found = np.repeat(np.arange(len(touching)), touching)
            if len(found) == 0:
                raise InputError(f"a manufacturing simulation needs an endpoint beside a station of kind {station}")
            beside.append(found)
        self.first_goals = beside[0]
        self.beside = np.concatenate(beside).astype(np.int64)
        self.beside_start = np.cumsum([0] + [len(b) for b in beside]).astype(np.int64)
        self.targets = np.unique(self.beside).astype(np.int32)
        self.workstations = self.endpoints = np.zeros(0, dtype=np.int64)
        self.cumulative = np.zeros(0)
        self.rng = rng

    def first(self, positions: np.ndarray) -> tuple[np.ndarray, int]:
        self.toggle = np.zeros(len(positions), dtype=np.int64)  # the kind of station each robot heads for
        return self.rng.choice(self.first_goals, len(positions)), STATION_WAITS[0]


#: Bytes a simulation holds per map cell besides the distance tables, with the paper's window of 10 (``pbs``: the
#: occupancy table, its index by step and cell, the search's cell numbering; ``pp``: the occupancy table and the
#: search's; ``pibt``: one step's; all: the neighbour table and the free cells). Measured on a 4096 x 4096 map with
#: one robot: ``pbs`` 250, ``pp`` 64 (peak memory above what loading the map took, over its cells).
PLANNER_BYTES_PER_CELL = {"pbs": 260, "pp": 90, "pibt": 60}


def distance_tables(neighbours: np.ndarray, targets: np.ndarray, other_bytes: int = 0) -> np.ndarray:
    """``table[i, cell]``: moves from ``cell`` to ``targets[i]``. Distances fit 16 bits on any map with fewer free
    cells than :data:`._mapf.UNREACHABLE` (no path is longer than the free cells); larger maps take 32 bits. Refused
    beyond the memory budget (with ``other_bytes``, what the planner will hold beside them) before anything is
    allocated."""
    from structgen.domains.layouts.warehouse import _mapf

    cells = neighbours.shape[0]
    free = int((neighbours >= 0).any(axis=1).sum()) + 1
    kind, unreachable = (np.int16, _mapf.UNREACHABLE) if free < _mapf.UNREACHABLE else (np.int32, np.iinfo(np.int32).max)
    check_memory(
        len(targets) * cells * np.dtype(kind).itemsize + other_bytes,
        f"the simulator's distance tables ({len(targets):,} goals x {cells:,} cells) and planning tables",
        "use a smaller map or one with fewer goals",
    )
    table = np.full((len(targets), cells), unreachable, dtype=kind)
    return _mapf.distance_tables(neighbours, targets, table, unreachable)


def simulate(
    tiles: np.ndarray,
    agents: int,
    steps: int = 1000,
    *,
    kind: LayoutKind = WAREHOUSE,
    seed: int = 0,
    planner: str = "pp",
    uneven: bool = False,
    window: int = 10,
    replan: int = 5,
    restarts: int | None = None,
    priority: str = "waiting",
    trace: bool = False,
    node_budget: int | None = None,
    dead_ends: int | None = None,
    fallback: str = "repair",
    goal_horizon: int | None = None,
    pbs_off: tuple[str, ...] = (),
    replan_cap: int = 5,
) -> SimulationResult:
    """Simulate ``agents`` robots on a whole warehouse map for ``steps`` steps and return the throughput.

    Args:
        tiles: the whole map as tile numbers of ``kind`` (warehouse: shelves block, goals are workstations ``w`` and
            endpoints ``e``; manufacturing: stations block, goals are the endpoints beside them).
        seed: draws the start cells, the goals and the tie-breaks between equal priorities.
        uneven: the left half's workstations are five times likelier goals than the right half's (warehouse).
        window, replan: plan ``window`` steps ahead every ``replan`` steps (the paper's 10 and 5).
        restarts: how many times a round of planning starts again with a failing agent first; None: at least 5, and
            one per 40 agents in a warehouse, one per 4 in manufacturing. (Five at 200 agents reproduces where the
            original congests in a warehouse; with fixed five, 1,000 agents at 101x102 congested in two runs of five,
            agents held in place blocking others in a cascade. In manufacturing every robot first heads for the
            kind-0 stations; with five restarts the human layout jammed there in all runs, where RHCR scores 5.92.)
        priority: ``"waiting"`` (agents that reached a goal longest ago plan first; the calibrated default) or
            ``"random"`` (a fresh random order each round).
        node_budget: the ``pbs`` planner gives up on a round after planning this many nodes (children), in place of
            RHCR's 60 s a call so that runs repeat exactly. None: 10 per agent, at least 1,000.
        dead_ends: ``pbs`` also gives up after this many nodes with no feasible child (None: no such limit).
        fallback: what ``pbs`` does with a round it gave up on: ``"repair"`` (RHCR's) carries out the node whose
            paths stay collision-free longest, robots whose next cell is taken waiting, in a random order each step;
            ``"pp"`` plans the round again by prioritized planning (as planner ``pp``).
        pbs_off: names from :data:`PBS_RULES` to switch off (to measure what each rule does; all on is RHCR's
            behaviour with the paper's ``prioritize_start``).
        replan_cap: ``pbs`` fails a child after more than this many low-level searches per robot while making its
            paths consistent (RHCR's five); 0: no cap (a last-resort cap of 50 still ends cycles).
        goal_horizon: goals are queued for each robot until the Manhattan route through them, task waits included,
            is longer than this. None: the planning window (10) for ``pbs``, which brought it within 1 % of RHCR on
            the 33x36 warehouses (against 1.3-2.5 % with 5), and the replanning period (5) for ``pp`` and ``pibt``,
            whose calibration used it.
        trace: keep every agent's cell at every step (``result.positions``, ``(steps + 1, agents)`` flat cells) and
            the tasks finished (``result.finished``).
    """
    from structgen.domains.layouts.warehouse import _mapf, _pbs, _steps

    if planner not in PLANNERS:
        raise InputError(f"unknown planner {planner!r}; choose from {', '.join(PLANNERS)}")
    if priority not in ("waiting", "random"):
        raise InputError(f"unknown priority {priority!r}; choose 'waiting' or 'random'")
    if not 1 <= replan <= window:
        raise InputError(f"replan ({replan}) must be between 1 and window ({window})")
    began = time.perf_counter()
    tiles = np.asarray(tiles)
    rows, cols = tiles.shape
    passable = ~np.isin(tiles, kind.blocking_tiles())
    free = np.flatnonzero(passable.ravel())
    if not 0 < agents <= len(free):
        raise InputError(f"{agents} agents do not fit on {len(free)} free cells")
    rng = np.random.default_rng(seed)
    if kind.name == MANUFACTURING.name:
        tasks_of, task_model = _ManufacturingTasks(tiles, kind, rng), _steps.MANUFACTURING_TASKS
    else:
        tasks_of, task_model = _WarehouseTasks(tiles, kind, uneven, rng), _steps.WAREHOUSE_TASKS
    if restarts is None:
        restarts = max(5, agents // tasks_of.agents_per_restart)
    if node_budget is None:
        node_budget = max(1000, 10 * agents)
    if goal_horizon is None:
        goal_horizon = window if planner == "pbs" else replan
    if not isinstance(goal_horizon, int) or goal_horizon < 0:
        raise InputError(f"goal_horizon must be a non-negative integer, got {goal_horizon!r}")
    if not isinstance(node_budget, int) or node_budget < 1:
        raise InputError(f"node_budget must be a positive integer, got {node_budget!r}")
    if dead_ends is not None and (not isinstance(dead_ends, int) or dead_ends < 0):
        raise InputError(f"dead_ends must be a non-negative integer or None, got {dead_ends!r}")
    if fallback not in FALLBACKS:
        raise InputError(f"unknown fallback {fallback!r}; choose from {', '.join(FALLBACKS)}")
    unknown = [name for name in pbs_off if name not in PBS_RULES]
    if unknown or isinstance(pbs_off, str):
        raise InputError(f"pbs_off: unknown rule {unknown or pbs_off!r}; choose from {', '.join(PBS_RULES)}")
    if not isinstance(replan_cap, int) or replan_cap < 0:
        raise InputError(f"replan_cap must be a non-negative integer, got {replan_cap!r}")
    # Each name in PBS_RULES is that of the rule's bit in _pbs, lower case (tests/layouts/test_pbs.py holds them).
    rule_bits = _pbs.ALL_RULES & ~sum(getattr(_pbs, name.upper()) for name in set(pbs_off))
    planning = int(PLANNER_BYTES_PER_CELL[planner] * rows * cols * max(1.0, (window + 1) / 11))
    check_memory(planning, f"the {planner} planner's tables on a {rows} x {cols} map", "use a smaller map")
    neighbours = _mapf.grid_neighbours(passable)
    targets = tasks_of.targets
    target_of = np.full(rows * cols, -1, dtype=np.int32)
    target_of[targets] = np.arange(len(targets), dtype=np.int32)
    dist = distance_tables(neighbours, targets, planning)

    positions = rng.permutation(free)[:agents].astype(np.int32)
    goals = np.zeros((agents, MAX_GOALS), dtype=np.int32)
    waits = np.zeros((agents, MAX_GOALS), dtype=np.int32)
    n_goals = np.ones(agents, dtype=np.int64)
    goals[:, 0], waits[:, 0] = tasks_of.first(positions)
    served = np.full(agents, -1, dtype=np.int64)  # steps stood on the first goal (-1: not on it)

    tasks = restarts_used = held_total = nodes_total = fallbacks = failed_total = 0
    trail = [positions.copy()] if trace else None
    finished: list[np.ndarray] = []
    finished_now = np.zeros((agents * replan, 3), dtype=np.int64)
    last_done = np.zeros(agents, dtype=np.int64)
    station_waits = np.array(STATION_WAITS, dtype=np.int64)
    congested = False
    t = 0
    while t < steps:
        _steps.queue_goals(
            positions, goals, waits, n_goals, goal_horizon, cols, rng, task_model, tasks_of.toggle,
            tasks_of.workstations, tasks_of.cumulative, tasks_of.endpoints, tasks_of.beside, tasks_of.beside_start,
            station_waits,
        )  # fmt: skip
        order = rng.permutation(agents)
        if priority == "waiting":  # longest since its last goal first; ties in random order
            order = order[np.argsort(last_done[order], kind="stable")]
        order = order.astype(np.int64)
        if planner in ("pp", "pbs"):
            # An agent part-way through a task finishes it first, with the steps it has left.
            pinned = served > 0
            left = waits.copy()
            left[pinned, 0] -= served[pinned].astype(np.int32)
            used = held = 0
            if planner == "pp":
                paths, used, held = _mapf.plan_window(
                    positions, goals, left, n_goals, pinned, target_of, dist, neighbours, window, order, restarts
                )
            else:
                paths, nodes, gave_up, failed = _pbs.pbs_window(
                    positions, goals, left, n_goals, pinned, target_of, dist, neighbours, window, order, node_budget,
                    -1 if dead_ends is None else dead_ends, rule_bits, replan_cap,
                )  # fmt: skip
                if gave_up and fallback == "pp":
                    paths, used, held = _mapf.plan_window(
                        positions, goals, left, n_goals, pinned, target_of, dist, neighbours, window, order, restarts
                    )
                elif gave_up:
                    orders = np.argsort(rng.random((window, agents)), axis=1)
                    paths = _pbs.wait_out(paths, positions, window, orders, rows * cols)
                nodes_total += nodes
                failed_total += failed
                fallbacks += int(gave_up)
        else:  # PIBT decides one step at a time: its "plan" is the interval itself
            waited = (t - last_done).astype(np.int64)
            paths = _mapf.pibt_window(
                positions, goals, waits, n_goals, served, target_of, dist, neighbours, replan, waited, int(rng.integers(2**31))
            )
            used = held = 0
        restarts_used += used
        held_total += held
        todo = min(replan, steps - t)
        done, still = _steps.carry_out(paths, goals, waits, n_goals, served, last_done, t, todo, replan, finished_now)
        tasks += done
        if trail is not None:
            trail.extend(paths[:, 1 : todo + 1].T.copy())
            finished.append(finished_now[:done].copy())
        positions = paths[:, todo].copy()
        t += todo
        if todo == replan and still > agents // 2:
            congested = True
            break
    return SimulationResult(
        throughput=tasks / steps,
        tasks=tasks,
        steps=steps,
        agents=agents,
        congested=congested,
        stopped_at=t,
        seconds=time.perf_counter() - began,
        planner=planner,
        restarts=restarts_used,
        held=held_total,
        positions=None if trail is None else np.stack(trail),
        finished=None if trail is None else np.concatenate(finished or [np.zeros((0, 3), dtype=np.int64)]),
        nodes=nodes_total,
        fallbacks=fallbacks,
        failed_children=failed_total,
    )


@dataclass(frozen=True)
class LayoutEvaluation:
    """Many simulations of one layout, summed up as the paper's tables are: ``success_rate`` is the share of runs
    that did not congest, and ``mean``/``standard_error`` are the throughput of those runs alone (None when none
    succeeded: the tables' "N/A"). ``throughputs`` and ``congested`` hold every run, in seed order."""

    simulations: int
    successes: int
    success_rate: float
    mean: float | None
    standard_error: float | None
    throughputs: np.ndarray
    congested: np.ndarray
    seconds: float


def evaluate_layout(
    tiles: np.ndarray,
    agents: int,
    simulations: int = 50,
    steps: int = 5000,
    *,
    seed: int = 0,
    progress: bool = False,
    workers: int = 0,
    **options,
) -> LayoutEvaluation:
    """Run ``simulations`` simulations of ``steps`` steps (seeds drawn from ``seed``, as training's are) and sum
    them up as :class:`LayoutEvaluation`; ``options`` go to :func:`simulate` (``kind``, ``planner``, ``uneven``,
    ...). ``progress`` shows a bar on the terminal. ``workers`` processes share the runs (0: this process); each
    run depends on its seed alone, so the result is the same with any number."""
    if not isinstance(simulations, int) or simulations < 1:
        raise InputError(f"simulations must be a positive integer, got {simulations!r}")
    if not isinstance(workers, int) or workers < 0:
        raise InputError(f"workers must be a whole number, 0 or more, got {workers!r}")
    began = time.perf_counter()
    seeds = [int(s) for s in np.random.SeedSequence(seed).generate_state(simulations)]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=simulations, desc="simulations", unit="run", leave=False)
    job = functools.partial(_throughput_of_run, np.asarray(tiles), agents, steps, options)
    with WorkerPool(min(workers, simulations)) as pool:
        runs = pool.map(job, seeds, done=None if bar is None else lambda _: bar.update())
    if bar is not None:
        bar.close()
    lost = [f"seed {s}: {run.reason}" for s, run in zip(seeds, runs) if isinstance(run, Lost)]
    if lost:
        raise RuntimeError(f"{len(lost)} simulation(s) lost with their worker: {'; '.join(lost)}")
    throughputs = np.array([throughput for throughput, _ in runs])
    congested = np.array([jammed for _, jammed in runs])
    good = throughputs[~congested]
    mean = float(good.mean()) if len(good) else None
    error = float(good.std(ddof=1) / np.sqrt(len(good))) if len(good) > 1 else (0.0 if len(good) else None)
    return LayoutEvaluation(
        simulations=simulations,
        successes=len(good),
        success_rate=len(good) / simulations,
        mean=mean,
        standard_error=error,
        throughputs=throughputs,
        congested=congested,
        seconds=time.perf_counter() - began,
    )


def _throughput_of_run(tiles: np.ndarray, agents: int, steps: int, options: dict, seed: int) -> tuple[float, bool]:
    run = simulate(tiles, agents, steps, seed=seed, **options)
    return run.throughput, run.congested


def compile_kernels() -> None:
    """Compile the planners' numba functions (or load them from numba's cache in ``__pycache__``) by running each
    planner for a few steps on a small warehouse: a first simulation after an install otherwise spends most of a
    minute compiling. ``make install`` calls it (see :func:`structgen.registry.compile_kernels`)."""
    storage = np.zeros((9, 12), dtype=np.uint8)
    shelf, endpoint = WAREHOUSE.vocabulary.index("@"), WAREHOUSE.vocabulary.index("e")
    for row in (2, 6):
        storage[row, 1:11] = shelf
        storage[row - 1 : row + 2 : 2, 1:11] = endpoint
    for planner in PLANNERS:
        simulate(WAREHOUSE.complete(storage), 4, 20, planner=planner)
