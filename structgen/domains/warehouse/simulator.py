"""A lifelong multi-robot warehouse simulation that scores a layout by its throughput.

The task model follows the paper's simulator (research notes 1.7): agents start on distinct non-shelf cells; each
gets a random endpoint first, then goals alternate between a workstation (drawn by weight) and an endpoint; agents
move to a 4-neighbour cell or wait each step, without rotation; shelves block, everything else is traversable.
Every ``replan`` steps all agents plan collision-free paths for the next ``window`` steps (rolling-horizon planning)
and the first ``replan`` steps are carried out. Throughput is the number of goals reached divided by the number of
steps asked for. When more than half of the agents stood still over a whole replanning interval, the run is
congested and stops there (throughput keeps the full horizon as its denominator, as in the original).

Planner ``"pp"``: windowed prioritized planning (space-time A* against a reservation table; agents that reached a
goal longest ago plan first; an agent that finds no path moves to the front and planning restarts; after a budget
of restarts, one per 40 agents and at least five, such agents wait in place). It stands in for the original's PBS,
whose licence keeps it out of this project. The priority rule and the restart budget were chosen against the
original's recorded throughputs (benchmarks/README.md): with more restarts at 200 agents the human layout no longer
congests, as it does there.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from structgen.domains.warehouse.layouts import WAREHOUSE, LayoutKind
from structgen.errors import InputError

__all__ = ["PLANNERS", "SimulationResult", "simulate"]

PLANNERS = ("pp", "pibt")
#: Goals queued ahead per agent at most (the queue is filled until it is longer than one replanning interval).
MAX_GOALS = 8


@dataclass(frozen=True)
class SimulationResult:
    """One simulation: ``throughput`` = goals reached / ``steps``; ``congested`` says the run stopped early (at
    ``stopped_at``) because more than half of the agents stood still over a replanning interval; ``restarts``
    and ``held`` count planning rounds started again and agents made to wait because they found no path;
    ``positions`` is the trace when asked for."""

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


def _workstation_weights(cells: np.ndarray, cols: int, uneven: bool) -> np.ndarray:
    weights = np.ones(len(cells))
    if uneven:  # the paper's uneven setting: the left column's workstations are five times likelier
        weights[cells % cols < cols // 2] = 5.0
    return weights / weights.sum()


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
) -> SimulationResult:
    """Simulate ``agents`` robots on a whole warehouse map for ``steps`` steps and return the throughput.

    Args:
        tiles: the whole map as tile numbers of ``kind`` (shelves block; workstations ``w``, endpoints ``e``).
        seed: draws the start cells, the goals and the tie-breaks between equal priorities.
        uneven: the left half's workstations are five times likelier goals than the right half's.
        window, replan: plan ``window`` steps ahead every ``replan`` steps (the paper's 10 and 5).
        restarts: how many times a round of planning starts again with a failing agent first; None: one per 40
            agents, at least 5. (Five at 200 agents reproduces where the original congests; with fixed five, 1,000
            agents at 101x102 congested in two runs of five, agents held in place blocking others in a cascade.)
        priority: ``"waiting"`` (agents that reached a goal longest ago plan first; the calibrated default) or
            ``"random"`` (a fresh random order each round).
        trace: keep every agent's cell at every step (``result.positions``, ``(steps + 1, agents)`` flat cells).
    """
    from structgen.domains.warehouse import _mapf

    if planner not in PLANNERS:
        raise InputError(f"unknown planner {planner!r}; choose from {', '.join(PLANNERS)}")
    if priority not in ("waiting", "random"):
        raise InputError(f"unknown priority {priority!r}; choose 'waiting' or 'random'")
    if not 1 <= replan <= window:
        raise InputError(f"replan ({replan}) must be between 1 and window ({window})")
    if restarts is None:
        restarts = max(5, agents // 40)
    began = time.perf_counter()
    tiles = np.asarray(tiles)
    rows, cols = tiles.shape
    code = kind.vocabulary.index
    passable = ~np.isin(tiles, kind.blocking_tiles())
    free = np.flatnonzero(passable.ravel())
    if not 0 < agents <= len(free):
        raise InputError(f"{agents} agents do not fit on {len(free)} free cells")
    workstations = np.flatnonzero(tiles.ravel() == code("w"))
    endpoints = np.flatnonzero(tiles.ravel() == code("e"))
    if len(workstations) == 0 or len(endpoints) == 0:
        raise InputError("a warehouse simulation needs workstations and endpoints")
    weights = _workstation_weights(workstations, cols, uneven)
    neighbours = _mapf.grid_neighbours(passable)
    targets = np.concatenate([workstations, endpoints]).astype(np.int32)
    target_of = np.full(rows * cols, -1, dtype=np.int32)
    target_of[targets] = np.arange(len(targets), dtype=np.int32)
    dist = _mapf.distance_tables(neighbours, targets)

    rng = np.random.default_rng(seed)
    positions = rng.permutation(free)[:agents].astype(np.int32)
    wants_workstation = ~np.isin(positions, workstations)  # the kind of goal after the first endpoint
    goals = np.zeros((agents, MAX_GOALS), dtype=np.int32)
    n_goals = np.ones(agents, dtype=np.int64)
    goals[:, 0] = rng.choice(endpoints, agents)

    def next_goal(agent: int, last: int) -> int:
        while True:
            if wants_workstation[agent]:
                goal = int(rng.choice(workstations, p=weights))
            else:
                goal = int(rng.choice(endpoints))
            if goal != last:
                wants_workstation[agent] = ~wants_workstation[agent]
                return goal

    def manhattan(a: int, b: int) -> int:
        return abs(a // cols - b // cols) + abs(a % cols - b % cols)

    tasks = restarts_used = held_total = 0
    trail = [positions.copy()] if trace else None
    last_done = np.zeros(agents, dtype=np.int64)
    congested = False
    t = 0
    while t < steps:
        # Queue goals until the route through them is longer than one replanning interval (the original's rule).
        for a in range(agents):
            last, length = int(positions[a]), 0
            for k in range(n_goals[a]):
                length += manhattan(last, int(goals[a, k]))
                last = int(goals[a, k])
            while length <= replan and n_goals[a] < MAX_GOALS:
                goal = next_goal(a, last)
                goals[a, n_goals[a]] = goal
                n_goals[a] += 1
                length += manhattan(last, goal)
                last = goal
        order = rng.permutation(agents)
        if priority == "waiting":  # longest since its last goal first; ties in random order
            order = order[np.argsort(last_done[order], kind="stable")]
        order = order.astype(np.int64)
        if planner == "pp":
            paths, used, held = _mapf.plan_window(positions, goals, n_goals, target_of, dist, neighbours, window, order, restarts)
        else:  # PIBT decides one step at a time: its "plan" is the interval itself
            waited = (t - last_done).astype(np.int64)
            paths = _mapf.pibt_window(
                positions, goals, n_goals, target_of, dist, neighbours, replan, waited, int(rng.integers(2**31))
            )
            used = held = 0
        restarts_used += used
        held_total += held
        todo = min(replan, steps - t)
        for step in range(1, todo + 1):
            here = paths[:, step]
            done = (here == goals[:, 0]) & (n_goals > 0)
            for a in np.flatnonzero(done):
                last_done[a] = t + step
                goals[a, :-1] = goals[a, 1:]
                n_goals[a] -= 1
            tasks += int(done.sum())
            if trail is not None:
                trail.append(here.copy())
        still = (paths[:, :replan] == paths[:, :1]).all(axis=1)
        positions = paths[:, todo].copy()
        t += todo
        if todo == replan and int(still.sum()) > agents // 2:
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
    )
