"""Which way to go on, read from an agent's own map: the first step of a shortest path over the floor it has seen to
the goal (once seen and reachable) or else to the nearest unexplored floor (floor seen beside a cell not yet seen).

This is the summary of the whole map that the maze agent's 9 x 9 and 27 x 27 patches lack: in a large maze the
unexplored floor is often far beyond both, and an agent that only counts its visits walks back and forth in what
it has already seen (issue 58: a third of the floor walked, half the steps on cells stood on twenty times). It is
the scripted explorer's plan (:class:`.walkers.Explorer`), made from the same map the network reads, for a batch of
agents at once. A breadth-first search from each agent stops at the first unexplored floor it meets, usually a few
cells away, so a step costs microseconds even on a 66 x 66 maze.
"""

from __future__ import annotations

import numba
import numpy as np

from structgen.domains.layouts.maze.walkers import _STEPS

__all__ = ["WAY_FEATURES", "first_steps"]

#: The features :func:`first_steps` gives the network: the way relative to the agent's facing (ahead, right,
#: behind, left; all zero where there is nowhere to go), the path's length as log(1 + steps) / 8, and whether the
#: path leads to the goal.
WAY_FEATURES = 6
_ROW_STEP = np.array([row for row, _ in _STEPS], dtype=np.int64)
_COLUMN_STEP = np.array([column for _, column in _STEPS], dtype=np.int64)
#: The channels of the agent's map (:class:`.agent.PathMemory`) the search reads: seen as wall, seen as floor.
WALL, FLOOR = 0, 1


@numba.njit(cache=True)
def _search(maps, goal, rows, columns, side, way, length, to_goal, visited, first, queue):  # pragma: no cover
    for agent in range(maps.shape[0]):
        start = rows[agent] * side + columns[agent]
        visited[start] = True
        head, tail = 0, 1
        queue[0] = start
        first[start] = -1
        distance_of = 0
        frontier_way, frontier_length = -1, -1
        way[agent], length[agent], to_goal[agent] = -1, -1, False
        target = goal[agent]
        level_end = 1
        while head < tail:
            if head == level_end:
                distance_of += 1
                level_end = tail
            cell = queue[head]
            head += 1
            row, column = cell // side, cell % side
            if cell == target:
                way[agent], length[agent], to_goal[agent] = first[cell], distance_of, True
                break
            if cell != start and frontier_way < 0:
                for d in range(4):
                    n = ((row + _ROW_STEP[d]) % side) * side + (column + _COLUMN_STEP[d]) % side
                    if maps[agent, FLOOR, n] < 0.5 and maps[agent, WALL, n] < 0.5:
                        frontier_way, frontier_length = first[cell], distance_of
                        break
                if frontier_way >= 0 and target < 0:
                    break
            for d in range(4):
                n = ((row + _ROW_STEP[d]) % side) * side + (column + _COLUMN_STEP[d]) % side
                if not visited[n] and maps[agent, FLOOR, n] > 0.5:
                    visited[n] = True
                    first[n] = d if cell == start else first[cell]
                    queue[tail] = n
                    tail += 1
        if way[agent] < 0 and frontier_way >= 0:
            way[agent], length[agent] = frontier_way, frontier_length
        for k in range(tail):  # clear only what this search marked: the map may be a hundred times larger
            visited[queue[k]] = False


def first_steps(maps: np.ndarray, goal: np.ndarray, position: np.ndarray, side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each agent: the direction of its first step (0-3 as :data:`.walkers._STEPS`, -1: nowhere to go), the
    path's length in moves, and whether it leads to the goal.

    ``maps`` are the agents' ``(agents, channels, side * side)`` maps, channels as :class:`.agent.PathMemory`'s
    (:data:`WALL` and :data:`FLOOR` above 0.5: seen as wall, as floor; a cell seen as neither is unexplored), read
    in place when contiguous (the agent's own, so that a step copies none of it); ``goal`` the goal's cell on each
    map or -1, ``position`` each agent's ``(row, column)`` on its map (taken modulo ``side``: the maps are tori)."""
    count = maps.shape[0]
    way = np.empty(count, dtype=np.int64)
    length = np.empty(count, dtype=np.int64)
    to_goal = np.empty(count, dtype=np.bool_)
    cells = side * side
    position = np.asarray(position, dtype=np.int64) % side
    _search(
        np.ascontiguousarray(maps),
        np.asarray(goal, dtype=np.int64),
        np.ascontiguousarray(position[:, 0]),
        np.ascontiguousarray(position[:, 1]),
        side,
        way,
        length,
        to_goal,
        np.zeros(cells, dtype=np.bool_),
        np.zeros(cells, dtype=np.int64),
        np.zeros(cells, dtype=np.int64),
    )
    return way, length, to_goal


def compile_kernels() -> None:
    """Compile the search (or load it from numba's cache) on a 3 x 3 map."""
    maps = np.zeros((1, 2, 9), dtype=np.float32)
    maps[0, FLOOR, 4] = maps[0, FLOOR, 5] = 1.0
    first_steps(maps, np.array([-1]), np.array([[1, 1]]), 3)
