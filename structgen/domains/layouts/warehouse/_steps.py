"""Compiled kernels of the simulator's bookkeeping: queueing each robot's next goals and carrying out a planned
interval (tasks finished, robots standing still).

They do what :func:`structgen.domains.layouts.warehouse.simulator.simulate` did in NumPy, one robot at a time and in the same
order, drawing from the same ``numpy.random.Generator`` (numba draws the same numbers from it as NumPy does), so a
simulation's result is the same to the last step. In Python this work cost a third of a 200-robot simulation with
the ``pp`` planner, most of it per finished task (measured, benchmarks/layouts.md).
"""

from __future__ import annotations

import numba as nb
import numpy as np

#: Task models, as :func:`queue_goals` takes them.
WAREHOUSE_TASKS, MANUFACTURING_TASKS = 0, 1


@nb.njit(cache=True)
def _next_goal(a, last, rng, model, toggle, workstations, cumulative, endpoints, beside, beside_start, station_waits):
    """Robot ``a``'s goal after ``last`` and its wait. Warehouse: a workstation (by weight) and an endpoint in turn,
    never ``last`` again; manufacturing: an endpoint beside a station of the next kind (``toggle`` holds the kind)."""
    if model == WAREHOUSE_TASKS:
        while True:
            if toggle[a] == 1:
                goal = workstations[np.searchsorted(cumulative, rng.random(), side="right")]
            else:
                goal = endpoints[rng.integers(0, len(endpoints))]
            if goal != last:
                toggle[a] = 1 - toggle[a]
                return goal, 0
    station = (toggle[a] + 1) % len(station_waits)
    toggle[a] = station
    low, high = beside_start[station], beside_start[station + 1]
    return beside[low + rng.integers(0, high - low)], station_waits[station]


@nb.njit(cache=True)
def queue_goals(positions, goals, waits, n_goals, horizon, cols, rng, model, toggle, workstations, cumulative, endpoints,
                beside, beside_start, station_waits):  # fmt: skip
    """Queue goals for every robot, in index order, until the Manhattan route through them (task waits included)
    is longer than ``horizon`` or the queue is full."""
    agents, max_goals = goals.shape
    for a in range(agents):
        if n_goals[a] >= max_goals:
            continue
        length = 0
        here = positions[a]
        for k in range(n_goals[a]):
            goal = goals[a, k]
            length += abs(goal // cols - here // cols) + abs(goal % cols - here % cols) + waits[a, k]
            here = goal
        last = here
        while length <= horizon and n_goals[a] < max_goals:
            goal, wait = _next_goal(
                a, last, rng, model, toggle, workstations, cumulative, endpoints, beside, beside_start, station_waits
            )
            goals[a, n_goals[a]] = goal
            waits[a, n_goals[a]] = wait
            n_goals[a] += 1
            length += abs(goal // cols - last // cols) + abs(goal % cols - last % cols) + wait
            last = goal


@nb.njit(cache=True)
def carry_out(paths, goals, waits, n_goals, served, last_done, t, todo, replan, finished):
    """Carry out the first ``todo`` steps of ``paths``: robots standing on their first goal serve its wait, and a
    finished task leaves the queue. ``served`` counts the steps stood on the first goal (-1: not on it).
    ``finished`` receives a row ``step, robot, cell`` per task finished. Returns the tasks finished and the robots
    that stood still for the first ``replan`` steps without working on a task."""
    agents, max_goals = goals.shape
    working = np.zeros(agents, dtype=np.bool_)
    tasks = 0
    for step in range(1, todo + 1):
        for a in range(agents):
            here = paths[a, step]
            on_goal = n_goals[a] > 0 and here == goals[a, 0]
            if not on_goal:
                served[a] = -1
                continue
            if here == paths[a, step - 1] and served[a] >= 0:
                served[a] += 1
                working[a] = True
            else:
                served[a] = 0
            if served[a] >= waits[a, 0]:
                last_done[a] = t + step
                for k in range(max_goals - 1):
                    goals[a, k] = goals[a, k + 1]
                    waits[a, k] = waits[a, k + 1]
                n_goals[a] -= 1
                served[a] = 0 if n_goals[a] > 0 and goals[a, 0] == here else -1
                finished[tasks, 0] = t + step
                finished[tasks, 1] = a
                finished[tasks, 2] = here
                tasks += 1
    still = 0
    for a in range(agents):
        if working[a]:
            continue
        moved = False
        for step in range(1, replan):
            if paths[a, step] != paths[a, 0]:
                moved = True
                break
        if not moved:
            still += 1
    return tasks, still
