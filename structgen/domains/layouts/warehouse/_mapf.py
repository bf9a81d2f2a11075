"""Compiled kernels of the multi-robot simulator: distance tables and windowed prioritized planning.

Cells are flat indices ``row * cols + col``; ``neighbours[cell]`` lists the four passable neighbours (-1 where there
is none). Everything here is plain arrays so that numba compiles it to machine code; the task model and the
simulation loop live in :mod:`structgen.domains.layouts.warehouse.simulator`.
"""

from __future__ import annotations

import numba as nb
import numpy as np

#: Distance to a cell that cannot be reached.
UNREACHABLE = 30000


@nb.njit(cache=True)
def grid_neighbours(passable: np.ndarray) -> np.ndarray:
    rows, cols = passable.shape
    out = -np.ones((rows * cols, 4), dtype=np.int32)
    for r in range(rows):
        for c in range(cols):
            if not passable[r, c]:
                continue
            here = r * cols + c
            if r > 0 and passable[r - 1, c]:
                out[here, 0] = here - cols
            if c + 1 < cols and passable[r, c + 1]:
                out[here, 1] = here + 1
            if r + 1 < rows and passable[r + 1, c]:
                out[here, 2] = here + cols
            if c > 0 and passable[r, c - 1]:
                out[here, 3] = here - 1
    return out


@nb.njit(cache=True)
def distance_tables(neighbours: np.ndarray, targets: np.ndarray, table: np.ndarray, unreachable: int) -> np.ndarray:
    """Fill ``table[i, cell]`` (given full of ``unreachable``) with the moves from ``cell`` to ``targets[i]``
    (breadth-first; moves are symmetric). Every distance must stay below ``unreachable``: the caller picks a table
    type for which it does (:func:`structgen.domains.layouts.warehouse.simulator.distance_tables`)."""
    n = neighbours.shape[0]
    queue = np.empty(n, dtype=np.int32)
    for i in range(len(targets)):
        row = table[i]
        row[targets[i]] = 0
        queue[0] = targets[i]
        head, tail = 0, 1
        while head < tail:
            cell = queue[head]
            head += 1
            for d in range(4):
                nxt = neighbours[cell, d]
                if nxt >= 0 and row[nxt] == unreachable:
                    row[nxt] = row[cell] + 1
                    queue[tail] = nxt
                    tail += 1
    return table


@nb.njit(cache=True)
def _heap_push(keys, states, size, key, state):
    i = size
    keys[i] = key
    states[i] = state
    while i > 0:
        parent = (i - 1) >> 1
        if keys[parent] <= keys[i]:
            break
        keys[parent], keys[i] = keys[i], keys[parent]
        states[parent], states[i] = states[i], states[parent]
        i = parent
    return size + 1


@nb.njit(cache=True)
def _heap_pop(keys, states, size):
    state = states[0]
    size -= 1
    keys[0] = keys[size]
    states[0] = states[size]
    i = 0
    while True:
        left = 2 * i + 1
        if left >= size:
            break
        child = left
        if left + 1 < size and keys[left + 1] < keys[left]:
            child = left + 1
        if keys[i] <= keys[child]:
            break
        keys[child], keys[i] = keys[i], keys[child]
        states[child], states[i] = states[i], states[child]
        i = child
    return state, size


@nb.njit(cache=True)
def _taken(occupied, lookup, t, cell, agent):
    """Whether a reserved path stands on ``cell`` at step ``t``: in ``occupied``, or with ``lookup`` (module notes of
    :func:`_search`) whether a marked agent other than ``agent`` does."""
    if lookup is None:
        return occupied[t, cell] != -1
    head, after, agent_of, mark, stamp, paths, cells = lookup
    node = head[t * cells + cell]
    while node >= 0:
        y = agent_of[node]
        if mark[y] == stamp and y != agent:
            return True
        node = after[node]
    return False


@nb.njit(cache=True)
def _swaps(occupied, lookup, t, nxt, cell, agent):
    """Whether a reserved path goes from ``nxt`` at step ``t`` to ``cell`` at ``t + 1`` (a move from ``cell`` to
    ``nxt`` would swap with it). In ``occupied``, -2 marks a cell where several reserved paths meet (they may collide
    among themselves), and then any of them may swap."""
    if lookup is None:
        before, after = occupied[t, nxt], occupied[t + 1, cell]
        return before != -1 and after != -1 and (before == after or before == -2 or after == -2)
    head, nexts, agent_of, mark, stamp, paths, cells = lookup
    node = head[t * cells + nxt]
    while node >= 0:
        y = agent_of[node]
        if mark[y] == stamp and y != agent and paths[y, t + 1] == cell:
            return True
        node = nexts[node]
    return False


@nb.njit(cache=True)
def _search(
    start,
    goals,
    waits,
    n_goals,
    pinned,
    target_of,
    dist,
    neighbours,
    occupied,
    window,
    seen,
    parent,
    stamp,
    heap_keys,
    heap_states,
    cell_ids,
    path,
    agent=-1,
    owner=None,
    leave=None,
    relaxed=False,
    lookup=None,
):
    """Space-time A* for one agent over ``window`` steps, avoiding the cells and swaps ``occupied`` reserves
    (``occupied[t, cell]``: the agent there at step ``t``, -1 for none, -2 for several). With ``lookup`` =
    ``(head, after, agent_of, mark, stamp, paths, cells)`` the reserved paths are instead those of the agents whose
    ``mark`` is ``stamp``, found through an index of every path by step and cell (``head[t * cells + cell]`` starts a
    list of nodes ``agent * (window + 1) + t`` linked by ``after``, ``agent_of[node]`` its agent): the ``pbs``
    planner reserves the paths of the agents above the one planned, often hundreds, and copying them into a table for
    every search cost more than the search.

    A state is (cell, time, goals reached). Its cost is the time of finishing the last goal: exact within the window,
    and the remaining distance and task waits (ignoring other agents) beyond it, as in rolling-horizon planning.
    A goal with ``waits[k] > 0`` (a manufacturing task) is finished by standing on it that many steps, one move in
    the search; ``pinned`` agents are in the middle of such a task and may only finish it. Writes the best path into
    ``path`` (``window + 1`` cells) and returns its cost (the estimated time at which the last goal is finished), or
    -1 if no path exists.

    Start cells (the ``pbs`` planner's rules, :mod:`._pbs`): with ``owner`` given (``owner[cell]``: the agent whose
    start cell it is, or -1), the cell of another agent ``o`` is closed at every step before ``leave[o]``, the step
    at which ``o``'s own path first leaves it. ``relaxed`` lets ``agent`` stand on its start cell as long as it likes
    whatever is reserved there (and never come back to it once it left, so that standing there always means waiting
    there since step 0): such a search always finds a path.

    States are numbered by the cells the search meets, in the order it meets them (``cell_ids``, from
    :func:`search_scratch`), not by their place on the map: no more than ``2w² + 2w + 1`` cells lie within ``w``
    moves, so the arrays one search touches stay small and in cache whatever the map's size."""
    levels = n_goals + 1
    met, local_of, cell_of = cell_ids[0], cell_ids[1], cell_ids[2]
    # rest[k]: moves and waits from goal k-1 to the end of the last goal, along the goal sequence.
    rest = np.zeros(levels + 1, dtype=np.int64)
    for k in range(n_goals - 1, 0, -1):
        rest[k] = rest[k + 1] + dist[target_of[goals[k]], goals[k - 1]] + waits[k]
    size = 0
    met[start] = stamp
    local_of[start] = 0
    cell_of[0] = start
    count = 1
    first = 0
    seen[first] = stamp
    parent[first] = -1
    h0 = 0 if n_goals == 0 else dist[target_of[goals[0]], start] + waits[0] + rest[1]
    size = _heap_push(heap_keys, heap_states, size, h0 * (window + 2) + window, first)
    slab = reachable_cells(window) * levels  # states per time step
    while size > 0:
        key = heap_keys[0]
        state, size = _heap_pop(heap_keys, heap_states, size)
        t = state // slab
        here_id = (state % slab) // levels
        cell = cell_of[here_id]
        k = state % levels
        if t == window:
            # Walk back; a task move spans several steps on one cell.
            s, high = state, window
            while s >= 0:
                here = cell_of[(s % slab) // levels]
                for back in range(s // slab, high + 1):
                    path[back] = here
                high = s // slab - 1
                s = parent[s]
            return key // (window + 2)
        if k < n_goals and cell == goals[k] and waits[k] > 0:
            end = min(t + waits[k], window)
            free = True
            for u in range(t + 1, end + 1):
                if not (relaxed and cell == start) and _taken(occupied, lookup, u, cell, agent):
                    free = False
                    break
            child = end * slab + here_id * levels + k + 1
            if free and seen[child] != stamp:
                seen[child] = stamp
                parent[child] = state
                h = 0 if k + 1 == n_goals else dist[target_of[goals[k + 1]], cell] + waits[k + 1] + rest[k + 2]
                cost = t + waits[k] + h  # a task cut by the window still counts its whole wait
                size = _heap_push(heap_keys, heap_states, size, cost * (window + 2) + window - end, child)
        if pinned and t == 0:
            continue
        for d in range(5):
            nxt = cell if d == 4 else neighbours[cell, d]
            if nxt < 0:
                continue
            if relaxed and nxt == start:
                if d != 4:
                    continue  # back onto the start cell after leaving it: not waiting there any more
            elif _taken(occupied, lookup, t + 1, nxt, agent):
                continue
            elif owner is not None:
                starter = owner[nxt]
                if starter >= 0 and starter != agent and leave[starter] > t + 1:
                    continue  # another agent still waits on its start cell
            if nxt != cell and _swaps(occupied, lookup, t, nxt, cell, agent):
                continue
            nk = k + 1 if k < n_goals and nxt == goals[k] and waits[k] == 0 else k
            if met[nxt] != stamp:
                met[nxt] = stamp
                local_of[nxt] = count
                cell_of[count] = nxt
                count += 1
            child = (t + 1) * slab + local_of[nxt] * levels + nk
            if seen[child] == stamp:
                continue
            seen[child] = stamp
            parent[child] = state
            h = 0 if nk == n_goals else dist[target_of[goals[nk]], nxt] + waits[nk] + rest[nk + 1]
            size = _heap_push(heap_keys, heap_states, size, (t + 1 + h) * (window + 2) + window - (t + 1), child)
    return -1


@nb.njit(cache=True)
def reachable_cells(window):
    """How many cells lie within ``window`` moves of a cell (a diamond), the most one search can meet."""
    return 2 * window * window + 2 * window + 1


@nb.njit(cache=True)
def search_scratch(cells, window, max_goals):
    """The working arrays :func:`_search` needs on a map of ``cells`` cells: one entry per (step, cell met, goals
    reached) state, and ``cell_ids`` (which cells a search met, under which number). ``seen`` and ``cell_ids[0]``
    are stamped, so that one set serves every search of a round."""
    states = (window + 1) * reachable_cells(window) * (max_goals + 1)
    return (
        np.zeros(states, dtype=np.int32),
        np.empty(states, dtype=np.int64),
        np.empty(states, dtype=np.int64),
        np.empty(states, dtype=np.int64),
        np.zeros((3, max(cells, reachable_cells(window))), dtype=np.int64),
    )


@nb.njit(cache=True)
def plan_window(positions, goals, waits, n_goals, pinned, target_of, dist, neighbours, window, order, restarts):
    """Collision-free paths for all agents over ``window`` steps by prioritized planning (``waits`` and ``pinned``
    as in :func:`_search`).

    Agents plan in ``order``, each around the paths of those before it. An agent that finds no path moves to the
    front and planning starts again (up to ``restarts`` times); after that, agents that still fail stay where they
    are for the whole window and the others plan around them, which always ends with a valid plan.
    Returns ``(paths, restarts used, agents held in place)``."""
    n_agents = len(positions)
    n = neighbours.shape[0]
    seen, parent, heap_keys, heap_states, cell_ids = search_scratch(n, window, goals.shape[1])
    occupied = np.empty((window + 1, n), dtype=np.int32)
    paths = np.empty((n_agents, window + 1), dtype=np.int32)
    path = np.empty(window + 1, dtype=np.int32)
    held = np.zeros(n_agents, dtype=np.bool_)
    order = order.copy()
    stamp = 0
    used = 0
    while True:
        occupied[:] = -1
        for a in range(n_agents):
            if held[a]:
                paths[a, :] = positions[a]
                occupied[:, positions[a]] = a
        failed = -1
        for i in range(n_agents):
            a = order[i]
            if held[a]:
                continue
            stamp += 1
            cost = _search(
                positions[a],
                goals[a],
                waits[a],
                n_goals[a],
                pinned[a],
                target_of,
                dist,
                neighbours,
                occupied,
                window,
                seen,
                parent,
                stamp,
                heap_keys,
                heap_states,
                cell_ids,
                path,
            )
            if cost < 0:
                failed = i
                break
            for t in range(window + 1):
                paths[a, t] = path[t]
                occupied[t, path[t]] = a
        if failed < 0:
            return paths, used, int(held.sum())
        a = order[failed]
        if used < restarts:
            for j in range(failed, 0, -1):
                order[j] = order[j - 1]
            order[0] = a
        else:
            held[a] = True
        used += 1


@nb.njit(cache=True)
def _rank_moves(a, depth, position, goal_cell, target_of, dist, neighbours, noise, moves, n_moves):
    """Agent ``a``'s possible next cells (its four neighbours and its own), nearest to its goal first."""
    here = position[a]
    keys = np.empty(5, dtype=np.float64)
    cells = np.empty(5, dtype=np.int64)
    count = 0
    for d in range(5):
        cell = here if d == 4 else neighbours[here, d]
        if cell < 0:
            continue
        cells[count] = cell
        keys[count] = (UNREACHABLE if goal_cell[a] < 0 else dist[target_of[goal_cell[a]], cell]) + noise[a, d]
        count += 1
    ranked = np.argsort(keys[:count])
    for i in range(count):
        moves[depth, i] = cells[ranked[i]]
    n_moves[depth] = count


@nb.njit(cache=True)
def _pibt(root, position, next_position, occupant, reserved, goal_cell, target_of, dist, neighbours, noise, frames):
    """Choose the next cell of ``root`` and of every agent it pushes (priority inheritance).

    An agent takes the best free cell; if another undecided agent stands there, that one chooses first and may not
    take the pusher's cell; if it cannot move away, the pusher tries its next cell. An agent with no cell left stays.
    Written with an explicit stack instead of recursion: numba cannot cache recursive functions."""
    agent, parent, tried, moves, n_moves = frames
    depth = 0
    agent[0], parent[0], tried[0] = root, -1, 0
    _rank_moves(root, 0, position, goal_cell, target_of, dist, neighbours, noise, moves, n_moves)
    returning, result = False, False
    while depth >= 0:
        a, pusher = agent[depth], parent[depth]
        if returning:
            returning = False
            if result:  # the pushed agent moved away: keep this agent's choice
                result = next_position[a] != position[a] or pusher < 0
                depth -= 1
                returning = True
                continue
            next_position[a] = -1  # the pushed agent stays on that cell (holding it): try the next one
        pushed = False
        while tried[depth] < n_moves[depth]:
            cell = moves[depth, tried[depth]]
            tried[depth] += 1
            if reserved[cell] >= 0 or (pusher >= 0 and cell == position[pusher]):
                continue  # taken, or a swap with the pusher
            reserved[cell] = a
            next_position[a] = cell
            other = occupant[cell]
            if other >= 0 and other != a and next_position[other] < 0:
                depth += 1
                agent[depth], parent[depth], tried[depth] = other, a, 0
                _rank_moves(other, depth, position, goal_cell, target_of, dist, neighbours, noise, moves, n_moves)
                pushed = True
                break
            result = cell != position[a] or pusher < 0
            depth -= 1
            returning = True
            pushed = True
            break
        if not pushed:  # nowhere to go: stay
            here = position[a]
            next_position[a] = here
            reserved[here] = a
            result = False
            depth -= 1
            returning = True


@nb.njit(cache=True)
def pibt_window(positions, goals, waits, n_goals, served, target_of, dist, neighbours, steps, waited, seed):
    """``steps`` steps of PIBT (one step of look-ahead, priority to agents that waited longest for a goal).
    A goal with ``waits[k] > 0`` is finished after standing on it that many steps; ``served`` counts the steps each
    agent already stood on its first goal (-1: not on it). Returns ``paths`` like :func:`plan_window`:
    ``(agents, steps + 1)`` cells."""
    np.random.seed(seed)
    n_agents = len(positions)
    n = neighbours.shape[0]
    paths = np.empty((n_agents, steps + 1), dtype=np.int32)
    position = positions.astype(np.int64)
    reached = np.zeros(n_agents, dtype=np.int64)
    serve = served.astype(np.int64)
    age = waited.astype(np.float64)
    occupant = -np.ones(n, dtype=np.int64)
    reserved = -np.ones(n, dtype=np.int64)
    next_position = -np.ones(n_agents, dtype=np.int64)
    goal_cell = np.empty(n_agents, dtype=np.int64)
    frames = (
        np.empty(n_agents + 1, dtype=np.int64),
        np.empty(n_agents + 1, dtype=np.int64),
        np.empty(n_agents + 1, dtype=np.int64),
        np.empty((n_agents + 1, 5), dtype=np.int64),
        np.empty(n_agents + 1, dtype=np.int64),
    )
    paths[:, 0] = positions
    for t in range(1, steps + 1):
        for a in range(n_agents):
            occupant[position[a]] = a
            goal_cell[a] = goals[a, reached[a]] if reached[a] < n_goals[a] else -1
        noise = np.random.random((n_agents, 5)) * 0.5
        order = np.argsort(-(age + np.random.random(n_agents) * 0.5))
        for i in range(n_agents):
            a = order[i]
            if next_position[a] < 0:
                _pibt(a, position, next_position, occupant, reserved, goal_cell, target_of, dist, neighbours, noise, frames)
        for a in range(n_agents):
            occupant[position[a]] = -1
            reserved[next_position[a]] = -1
            stayed = position[a] == next_position[a]
            position[a] = next_position[a]
            next_position[a] = -1
            paths[a, t] = position[a]
            age[a] += 1.0
            if goal_cell[a] < 0 or position[a] != goal_cell[a]:
                serve[a] = -1
                continue
            serve[a] = serve[a] + 1 if stayed and serve[a] >= 0 else 0
            if serve[a] >= waits[a, reached[a]]:
                reached[a] += 1
                age[a] = 0.0
                serve[a] = 0 if reached[a] < n_goals[a] and goals[a, reached[a]] == position[a] else -1
    return paths
