"""Windowed Priority-Based Search with RHCR's start-cell rules: the planner the paper's simulator uses.

Every replanning round is one windowed MAPF problem: paths for all agents whose collisions count only in the first
``window`` steps (Li et al., "Lifelong Multi-Agent Path Finding in Large-Scale Warehouses", AAAI 2021), solved by
Priority-Based Search (Ma et al., "Searching with Consistent Prioritization for Multi-Agent Path Finding", AAAI
2019) as RHCR runs it in the paper's configuration (its option ``prioritize_start`` on). The behaviour that option
and RHCR's handling of a failed round add is described nowhere in the papers; it was given to us in plain words
(research notes 2.0) and is written here in our own design. Each rule has a bit in ``rules`` so that it can be
switched off to measure what it does:

- **the root** plans the agents one by one in index order, each alone apart from rule 1;
- **rule 1, own starts** (:data:`OWN_STARTS`): whenever an agent is planned, every other agent that already has a
  path owns its start cell from step 0 until the step at which that path first leaves it, and the planned agent
  keeps out of owned cells at those steps. In a fixed-length window a path that never leaves its start cell owns it
  for the whole window (RHCR's paths run on to the goal past the window, so such a path leaves after it);
- **rule 2, hold the start** (:data:`HOLD_START`): an agent that finds no path searches again allowed to stand on
  its start cell as long as it likes, whatever is reserved there, so a search never fails;
- **rule 3, the waiting agent stays** (:data:`WAITING_STAYS`): when two paths collide on a cell where one agent has
  waited since step 0, the other agent is planned again, whatever the priorities say. Otherwise the lower agent of
  the two in the partial order moves, and a collision between agents with no order stays for the search to branch
  on;
- **rule 4, a cap on replanning** (``replan_cap``): making a child consistent (planning its lower agent, then every
  agent that rule 3 or the order makes the one to move) fails the child after more than ``replan_cap`` times as
  many low-level searches as there are agents;
- **rule 5, search order** (:data:`SEARCH_ORDER`): the earliest collision is expanded, but one between a *dead
  pair* (agents that earlier in the round gave no feasible child in either order) goes first; of the two children
  the one with the smaller sum of costs is explored first, ties going to the one with fewer collisions. Depth
  first. Without it ties go to the child whose upper agent comes first in the round's order;
- **rule 6, a failed round still moves**: when the node budget runs out (it stands in for RHCR's 60 s so that runs
  repeat exactly), the search returns the node whose paths stay collision-free for the longest prefix (ties: the
  lower cost), which the simulator carries out with :func:`wait_out`.

A node is one child planned. The low-level search is the space-time A* of :mod:`._mapf` (``_search``): goals in
sequence, costs exact inside the window and estimated by distance beyond it. Which agents stand on a cell at a step
is kept in linked lists (one per step and cell), so the collisions of a new path are found without scanning every
agent. Everything is plain arrays so that numba compiles it.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from structgen.domains.layouts.warehouse._mapf import _heap_pop, _heap_push, _search, search_scratch

#: Rule 1: agents own their start cells while they wait there.
OWN_STARTS = 1
#: Rule 2: an agent's search never fails because of its start cell.
HOLD_START = 2
#: Rule 3: in a collision on the start cell of an agent that has waited there since step 0, the other agent moves.
WAITING_STAYS = 4
#: Rule 5: dead pairs first; the cheaper child first, ties to fewer collisions.
SEARCH_ORDER = 8
ALL_RULES = OWN_STARTS | HOLD_START | WAITING_STAYS | SEARCH_ORDER
#: Without a replanning cap, a child still fails after this many low-level searches per agent, so that a cycle of
#: agents moving each other out of the way ends.
_LAST_RESORT_CAP = 50

# Slots of the counters array that the helpers share: the undo log's length, the sum of costs, the search stamp, the
# walk stamp, and the marks of the agents above and below the agent planned last.
_UNDO, _TOTAL, _STAMP, _MARK, _ABOVE, _BELOW = 0, 1, 2, 3, 4, 5


@nb.njit(cache=True)
def _leave(path, start):
    """The first step at which ``path`` is off ``start``; ``len(path)`` if it never leaves within the window."""
    for t in range(1, len(path)):
        if path[t] != start:
            return t
    return len(path)


@nb.njit(cache=True)
def _index_add(x, path, index, cells):
    head, after, before, _ = index
    width = len(path)
    for t in range(width):
        node = x * width + t
        slot = t * cells + path[t]
        first = head[slot]
        after[node] = first
        before[node] = -1
        if first >= 0:
            before[first] = node
        head[slot] = node


@nb.njit(cache=True)
def _index_remove(x, path, index, cells):
    head, after, before, _ = index
    width = len(path)
    for t in range(width):
        node = x * width + t
        prev, nxt = before[node], after[node]
        if prev >= 0:
            after[prev] = nxt
        else:
            head[t * cells + path[t]] = nxt
        if nxt >= 0:
            before[nxt] = prev


@nb.njit(cache=True)
def _tally(x, path, paths, index, cells, tallies, sign):
    """Add ``sign`` to the tallies (``collisions_at[t]``, and ``of_agent[a]`` for both agents) for every collision
    of agent ``x`` on ``path`` with another agent in the index at step ``t`` (each counted once per pair and step,
    whichever of the two is tallied)."""
    head, after, _, _ = index
    collisions_at, of_agent = tallies
    width = len(path)
    for t in range(1, width):
        v = path[t]
        node = head[t * cells + v]
        while node >= 0:
            y = node // width
            if y != x:
                collisions_at[t] += sign
                of_agent[x] += sign
                of_agent[y] += sign
            node = after[node]
        u = path[t - 1]
        if u != v:
            node = head[(t - 1) * cells + v]
            while node >= 0:
                y = node // width
                if y != x and paths[y, t] == u:
                    collisions_at[t] += sign
                    of_agent[x] += sign
                    of_agent[y] += sign
                node = after[node]


@nb.njit(cache=True)
def _collision_at(t, paths, index, cells, of_agent):
    """A pair of agents that collide at step ``t`` (one is known to exist); only agents with collisions are looked
    at."""
    head, after, _, _ = index
    n_agents, width = paths.shape
    for a in range(n_agents):
        if of_agent[a] == 0:
            continue
        v = paths[a, t]
        node = head[t * cells + v]
        while node >= 0:
            y = node // width
            if y != a:
                return a, y
            node = after[node]
        u = paths[a, t - 1]
        if u != v:
            node = head[(t - 1) * cells + v]
            while node >= 0:
                y = node // width
                if y != a and paths[y, t] == u:
                    return a, y
                node = after[node]
    return -1, -1


@nb.njit(cache=True)
def _pair_collision(paths, a, b):
    """The first step at which agents ``a`` and ``b`` collide (same cell, or swapping cells), or -1."""
    for t in range(1, paths.shape[1]):
        if paths[a, t] == paths[b, t]:
            return t
        if paths[a, t] == paths[b, t - 1] and paths[b, t] == paths[a, t - 1] and paths[a, t] != paths[a, t - 1]:
            return t
    return -1


@nb.njit(cache=True)
def _dead_pair_first(a, b, paths, dead_a, dead_b, n_dead):
    """Rule 5: the pair whose collision is expanded. The earliest collision's pair ``(a, b)``, unless the paths of
    a dead pair (``dead_a[i]``, ``dead_b[i]`` for ``i < n_dead``) collide: then the dead pair that collides first."""
    first = paths.shape[1]
    for i in range(n_dead):
        t = _pair_collision(paths, dead_a[i], dead_b[i])
        if 0 <= t < first:
            a, b, first = dead_a[i], dead_b[i], t
    return a, b


@nb.njit(cache=True)
def _second_first(feasible, costs, collisions, rules):
    """Rule 5: whether the second of two children is explored first: it alone is feasible, or both are and it costs
    less, or (with :data:`SEARCH_ORDER`) costs the same with fewer collisions."""
    if not feasible[1]:
        return False
    if not feasible[0] or costs[1] < costs[0]:
        return True
    return bool(rules & SEARCH_ORDER) and costs[1] == costs[0] and collisions[1] < collisions[0]


@nb.njit(cache=True)
def _collect(start, heads, nexts, ends, mark, stamp, queue):
    """Every agent reachable from ``start`` along the edge lists ``heads``/``nexts``/``ends`` (``start`` included)
    into ``queue``; marks them with ``stamp``. Returns how many."""
    mark[start] = stamp
    queue[0] = start
    head, tail = 0, 1
    while head < tail:
        x = queue[head]
        head += 1
        e = heads[x]
        while e >= 0:
            y = ends[e]
            if mark[y] != stamp:
                mark[y] = stamp
                queue[tail] = y
                tail += 1
            e = nexts[e]
    return tail


@nb.njit(cache=True)
def _reaches(x, y, heads, nexts, ends, mark, stamp, queue, level):
    """Whether ``y`` is below ``x`` along the downward edge lists: a walk that stops as soon as it finds ``y`` and
    never enters an agent at ``y``'s level or beyond (nothing there can lead to it)."""
    mark[x] = stamp
    queue[0] = x
    head, tail = 0, 1
    while head < tail:
        z = queue[head]
        head += 1
        e = heads[z]
        while e >= 0:
            w = ends[e]
            if w == y:
                return True
            if mark[w] != stamp and level[w] < level[y]:
                mark[w] = stamp
                queue[tail] = w
                tail += 1
            e = nexts[e]
    return False


@nb.njit(cache=True)
def _set_path(x, path, cost, paths, costs, leave, positions, index, tallies, counters, log):
    """Give agent ``x`` a new path of ``cost``, its old one logged for :func:`_undo_to`; returns the log (it grows
    when full)."""
    undo_agent, undo_cost, undo_path = log
    n_undo = counters[_UNDO]
    if n_undo == len(undo_agent):
        log = _grown(undo_agent, undo_cost, undo_path)
        undo_agent, undo_cost, undo_path = log
    cells = index[0].shape[0] // paths.shape[1]
    undo_agent[n_undo], undo_cost[n_undo] = x, costs[x]
    undo_path[n_undo] = paths[x]
    _replace(x, path, paths, index, cells, tallies)
    counters[_TOTAL] += cost - costs[x]
    costs[x] = cost
    leave[x] = _leave(paths[x], positions[x])
    counters[_UNDO] = n_undo + 1
    return log


@nb.njit(cache=True)
def _undo_to(keep, paths, costs, leave, positions, index, tallies, counters, log):
    undo_agent, undo_cost, undo_path = log
    cells = index[0].shape[0] // paths.shape[1]
    while counters[_UNDO] > keep:
        n_undo = counters[_UNDO] - 1
        x = undo_agent[n_undo]
        _replace(x, undo_path[n_undo], paths, index, cells, tallies)
        counters[_TOTAL] += undo_cost[n_undo] - costs[x]
        costs[x] = undo_cost[n_undo]
        leave[x] = _leave(paths[x], positions[x])
        counters[_UNDO] = n_undo


@nb.njit(cache=True)
def _replace(x, path, paths, index, cells, tallies):
    """Agent ``x``'s path becomes ``path``, in the index and the collision tallies too."""
    _tally(x, paths[x], paths, index, cells, tallies, -1)
    _index_remove(x, paths[x], index, cells)
    paths[x] = path
    _index_add(x, paths[x], index, cells)
    _tally(x, paths[x], paths, index, cells, tallies, 1)


@nb.njit(cache=True)
def _grown(undo_agent, undo_cost, undo_path):
    size = 2 * len(undo_agent)
    agent = np.empty(size, dtype=undo_agent.dtype)
    cost = np.empty(size, dtype=undo_cost.dtype)
    path = np.empty((size, undo_path.shape[1]), dtype=undo_path.dtype)
    agent[: len(undo_agent)] = undo_agent
    cost[: len(undo_cost)] = undo_cost
    path[: len(undo_path)] = undo_path
    return agent, cost, path


@nb.njit(cache=True)
def _push_edge(hi, lo, n_edges, graph, level, stack, stacked):
    """Add "``hi`` before ``lo``" to the order, raising the levels below ``lo`` so that every edge still goes from
    a lower level to a higher one. Levels are never lowered when edges go: they stay consistent, only less tight."""
    edge_hi, edge_lo, next_up, next_down, head_up, head_down = graph
    e = n_edges
    edge_hi[e], edge_lo[e] = hi, lo
    next_up[e], head_up[lo] = head_up[lo], e
    next_down[e], head_down[hi] = head_down[hi], e
    if level[lo] <= level[hi]:
        level[lo] = level[hi] + 1
        stack[0] = lo
        stacked[lo] = True
        size = 1
        while size > 0:  # an agent is on the stack at most once, so it holds at most every agent
            size -= 1
            x = stack[size]
            stacked[x] = False
            f = head_down[x]
            while f >= 0:
                y = edge_lo[f]
                if level[y] <= level[x]:
                    level[y] = level[x] + 1
                    if not stacked[y]:
                        stacked[y] = True
                        stack[size] = y
                        size += 1
                f = next_down[f]
    return n_edges + 1


@nb.njit(cache=True)
def _pop_edges_to(keep, n_edges, graph):
    edge_hi, edge_lo, next_up, next_down, head_up, head_down = graph
    while n_edges > keep:
        n_edges -= 1
        head_up[edge_lo[n_edges]] = next_up[n_edges]
        head_down[edge_hi[n_edges]] = next_down[n_edges]
    return n_edges


@nb.njit(cache=True)
def _plan(x, problem, scratch, paths, leave, index, graph, walk, counters, window, rules):
    """Agent ``x`` planned against every agent above it (and, rule 1, the start cells others own), into the
    scratch path. Returns ``(cost, low-level searches made)``; cost -1 when there is no path."""
    positions, goals, waits, n_goals, pinned, target_of, dist, neighbours, owner, no_leave = problem
    seen, parent, heap_keys, heap_states, cell_ids, path, occupied = scratch
    edge_hi, _, next_up, _, head_up, _ = graph
    mark, queue, above, _ = walk
    counters[_MARK] += 1
    counters[_ABOVE] = counters[_MARK]
    counters[_BELOW] = 0
    _collect(x, head_up, next_up, edge_hi, mark, counters[_MARK], above)
    lookup = (index[0], index[1], index[3], mark, counters[_ABOVE], paths, len(owner))
    owned = leave if rules & OWN_STARTS else no_leave
    counters[_STAMP] += 1
    cost = _search(positions[x], goals[x], waits[x], n_goals[x], pinned[x], target_of, dist, neighbours, occupied,
                   window, seen, parent, counters[_STAMP], heap_keys, heap_states, cell_ids, path, x, owner, owned, False,
                   lookup)  # fmt: skip
    searches = 1
    if cost < 0 and rules & HOLD_START:
        counters[_STAMP] += 1
        cost = _search(positions[x], goals[x], waits[x], n_goals[x], pinned[x], target_of, dist, neighbours, occupied,
                       window, seen, parent, counters[_STAMP], heap_keys, heap_states, cell_ids, path, x, owner, owned, True,
                       lookup)  # fmt: skip
        searches = 2
    return cost, searches


@nb.njit(cache=True)
def _mover(x, y, t, cell, positions, leave, level, graph, walk, counters, rules):
    """Which of two colliding agents must be planned again (rule 3, then the partial order), or -1 for neither.
    ``x`` was planned just now, so the agents above it carry the mark of that planning (``counters[_ABOVE]``);
    the agents below it are marked once, when first asked for (``counters[_BELOW]``, 0 until then). ``cell`` is
    where they collide at step ``t`` (-1 for a swap, where neither waits)."""
    if rules & WAITING_STAYS and cell >= 0:
        if cell == positions[y] and leave[y] > t:
            return x
        if cell == positions[x] and leave[x] > t:
            return y
    mark, queue, _, below = walk
    # Every edge goes to a higher level, so only the agent on the lower level can be above the other.
    if level[y] < level[x]:
        return x if mark[y] == counters[_ABOVE] else -1
    if level[x] < level[y]:
        if counters[_BELOW] == 0:
            _, edge_lo, _, next_down, _, head_down = graph
            counters[_MARK] += 1
            counters[_BELOW] = counters[_MARK]
            _collect(x, head_down, next_down, edge_lo, below, counters[_BELOW], queue)
        return y if below[y] == counters[_BELOW] else -1
    return -1


@nb.njit(cache=True)
def _settle(lo, limit, problem, scratch, paths, costs, leave, index, tallies, graph, walk, heap, queued, level,
            counters, log, window, rules):  # fmt: skip
    """Make a child consistent: plan ``lo``, then every agent that one of the new paths' collisions makes the one to
    move (:func:`_mover`), highest in the order first (so that an agent is planned after the agents above it that
    move too). Returns ``(ok, log)``; not ok once an agent has no path or more than ``limit`` low-level searches
    were made."""
    positions = problem[0]
    path = scratch[5]
    head, after, _, _ = index
    heap_keys, heap_agents = heap
    n_agents, width = paths.shape
    cells = head.shape[0] // width
    size = _heap_push(heap_keys, heap_agents, 0, level[lo] * n_agents + lo, lo)
    queued[lo] = True
    searches = 0
    ok = True
    while size > 0:
        x, size = _heap_pop(heap_keys, heap_agents, size)
        queued[x] = False
        cost, made = _plan(x, problem, scratch, paths, leave, index, graph, walk, counters, window, rules)
        searches += made
        if cost < 0 or searches > limit:
            ok = False
            break
        log = _set_path(x, path, cost, paths, costs, leave, positions, index, tallies, counters, log)
        for t in range(1, width):
            v = paths[x, t]
            u = paths[x, t - 1]
            for swap in range(2):
                if swap == 1 and u == v:
                    break
                node = head[t * cells + v] if swap == 0 else head[(t - 1) * cells + v]
                while node >= 0:
                    y = node // width
                    node = after[node]
                    if y == x or (swap == 1 and paths[y, t] != u):
                        continue
                    m = _mover(x, y, t, v if swap == 0 else -1, positions, leave, level, graph, walk, counters, rules)
                    if m == x:  # planned just now against everything it must avoid: planning again changes nothing
                        ok = False
                        break
                    if m >= 0 and not queued[m]:
                        size = _heap_push(heap_keys, heap_agents, size, level[m] * n_agents + m, m)
                        queued[m] = True
                if not ok:
                    break
            if not ok:
                break
        if not ok:
            break
    for i in range(size):
        queued[heap_agents[i]] = False
    return ok, log


@nb.njit(cache=True)
def pbs_window(
    positions,
    goals,
    waits,
    n_goals,
    pinned,
    target_of,
    dist,
    neighbours,
    window,
    order,
    node_budget,
    dead_end_budget,
    rules,
    replan_cap,
):
    """Collision-free paths for all agents over ``window`` steps by Priority-Based Search with the rules of the
    module notes (``rules``: a sum of their bits; ``replan_cap`` 0 for none; ``dead_end_budget`` -1 for none;
    ``order`` breaks ties between children without rule 5). ``waits`` and ``pinned`` as in :func:`._mapf._search`.
    Returns ``(paths, nodes, gave_up, failed_children)``: ``(agents, window + 1)`` cells, the nodes planned, whether
    the search gave up (the paths are then the node collision-free for longest, which may collide later), and the
    children that could not be made consistent."""
    n_agents = len(positions)
    n = neighbours.shape[0]
    width = window + 1
    seen, parent, heap_keys, heap_states, cell_ids = search_scratch(n, window, goals.shape[1])
    occupied = -np.ones((width, n), dtype=np.int32)
    path = np.empty(width, dtype=np.int32)
    owner = -np.ones(n, dtype=np.int64)
    for a in range(n_agents):
        owner[positions[a]] = a
    leave = np.zeros(n_agents, dtype=np.int64)  # nobody owns a start cell before its path is planned
    problem = (positions, goals, waits, n_goals, pinned, target_of, dist, neighbours, owner, np.zeros(n_agents, dtype=np.int64))
    scratch = (seen, parent, heap_keys, heap_states, cell_ids, path, occupied)
    # Every path by step and cell: lists of nodes (agent * width + step), and each node's agent.
    index = (-np.ones(width * n, dtype=np.int64), np.empty(n_agents * width, dtype=np.int64),
             np.empty(n_agents * width, dtype=np.int64), np.repeat(np.arange(n_agents), width))  # fmt: skip
    counters = np.zeros(6, dtype=np.int64)
    # Collisions at each step and of each agent, kept up to date by _replace.
    tallies = (np.zeros(width, dtype=np.int64), np.zeros(n_agents, dtype=np.int64))
    collisions_at, of_agent = tallies
    rank = np.empty(n_agents, dtype=np.int64)
    for i in range(n_agents):
        rank[order[i]] = i
    limit = replan_cap * n_agents if replan_cap > 0 else _LAST_RESORT_CAP * n_agents

    # The root: each agent in index order, against the start cells of those planned before it (rule 1).
    paths = np.empty((n_agents, width), dtype=np.int32)
    costs = np.zeros(n_agents, dtype=np.int64)
    owned = leave if rules & OWN_STARTS else problem[9]
    for a in range(n_agents):
        counters[_STAMP] += 1
        cost = _search(positions[a], goals[a], waits[a], n_goals[a], pinned[a], target_of, dist, neighbours, occupied,
                       window, seen, parent, counters[_STAMP], heap_keys, heap_states, cell_ids, path, a, owner, owned,
                       False)  # fmt: skip
        if cost < 0 and rules & HOLD_START:
            counters[_STAMP] += 1
            cost = _search(positions[a], goals[a], waits[a], n_goals[a], pinned[a], target_of, dist, neighbours,
                           occupied, window, seen, parent, counters[_STAMP], heap_keys, heap_states, cell_ids, path, a, owner,
                           owned, True)  # fmt: skip
        if cost < 0:  # cannot even move alone (a task it cannot finish in place): stay
            path[:] = positions[a]
            cost = 0
        paths[a] = path
        costs[a] = cost
        counters[_TOTAL] += cost
        leave[a] = _leave(path, positions[a])
        _index_add(a, paths[a], index, n)
        _tally(a, paths[a], paths, index, n, tallies, 1)

    # The partial order: edge e says edge_hi[e] goes before edge_lo[e]. Edges are added and removed last in, first
    # out (depth-first search), so each agent's lists are stacks with their newest edge at the head.
    capacity = node_budget + 2
    graph = (
        np.empty(capacity, dtype=np.int64),  # edge_hi
        np.empty(capacity, dtype=np.int64),  # edge_lo
        np.empty(capacity, dtype=np.int64),  # next edge into the same lower agent
        np.empty(capacity, dtype=np.int64),  # next edge out of the same upper agent
        -np.ones(n_agents, dtype=np.int64),  # newest edge into each agent
        -np.ones(n_agents, dtype=np.int64),  # newest edge out of each agent
    )
    n_edges = 0
    # Undo log of replaced paths, so that backtracking restores a node.
    log = (np.empty(4 * n_agents + 16, dtype=np.int64), np.empty(4 * n_agents + 16, dtype=np.int64),
           np.empty((4 * n_agents + 16, width), dtype=np.int32))  # fmt: skip
    # Children left for backtracking: the node to return to (undo and edge marks) and the pair to add.
    alt_undo = np.empty(capacity, dtype=np.int64)
    alt_edges = np.empty(capacity, dtype=np.int64)
    alt_hi = np.empty(capacity, dtype=np.int64)
    alt_lo = np.empty(capacity, dtype=np.int64)
    n_alt = 0
    dead_a = np.empty(capacity, dtype=np.int64)
    dead_b = np.empty(capacity, dtype=np.int64)
    n_dead = 0
    walk = (np.zeros(n_agents, dtype=np.int64), np.empty(n_agents, dtype=np.int64), np.empty(n_agents, dtype=np.int64),
            np.zeros(n_agents, dtype=np.int64))  # fmt: skip
    heap = (np.empty(n_agents, dtype=np.int64), np.empty(n_agents, dtype=np.int64))
    queued = np.zeros(n_agents, dtype=np.bool_)
    level = np.zeros(n_agents, dtype=np.int64)
    stack = np.empty(n_agents, dtype=np.int64)
    stacked = np.zeros(n_agents, dtype=np.bool_)
    nodes = 0
    failed = 0
    dead_ends = 0
    kept_agent = np.empty(n_agents, dtype=np.int64)
    kept_cost = np.empty(n_agents, dtype=np.int64)
    kept_path = np.empty((n_agents, width), dtype=np.int32)
    n_kept = 0
    best = paths.copy()
    best_time, best_cost = -1, 0
    mark, queue, _, _ = walk
    _, edge_lo, _, next_down, _, head_down = graph

    while True:
        at = 1
        while at < width and collisions_at[at] == 0:
            at += 1
        if at == width:
            return paths, nodes, False, failed
        if at > best_time or (at == best_time and counters[_TOTAL] < best_cost):
            best[:] = paths
            best_time, best_cost = at, counters[_TOTAL]
        if nodes >= node_budget:
            break
        a, b = _collision_at(at, paths, index, n, of_agent)
        if rules & SEARCH_ORDER:
            a, b = _dead_pair_first(a, b, paths, dead_a, dead_b, n_dead)
        # Agents already ordered can still collide (an agent above moved onto a waiting agent's start cell, or rule 3
        # moved an upper agent): then only the existing order is a child (adding the other would make a cycle).
        a_above_b = b_above_a = False
        if level[a] < level[b]:
            counters[_MARK] += 1
            a_above_b = _reaches(a, b, head_down, next_down, edge_lo, mark, counters[_MARK], queue, level)
        elif level[b] < level[a]:
            counters[_MARK] += 1
            b_above_a = _reaches(b, a, head_down, next_down, edge_lo, mark, counters[_MARK], queue, level)
        # Children as (upper, lower); without rule 5 the first in the round's order goes first on ties.
        first_hi, first_lo = (a, b) if rank[a] <= rank[b] else (b, a)
        if a_above_b:
            first_hi, first_lo = a, b
        elif b_above_a:
            first_hi, first_lo = b, a
        only_one = a_above_b or b_above_a
        base_undo, base_edges = counters[_UNDO], n_edges

        results = np.zeros(2, dtype=np.bool_)
        child_cost = np.zeros(2, dtype=np.int64)
        child_collisions = np.zeros(2, dtype=np.int64)
        for child in range(1 if only_one else 2):
            hi, lo = (first_hi, first_lo) if child == 0 else (first_lo, first_hi)
            if child == 1:  # back to the parent
                _undo_to(base_undo, paths, costs, leave, positions, index, tallies, counters, log)
                n_edges = _pop_edges_to(base_edges, n_edges, graph)
            nodes += 1
            if not only_one:
                n_edges = _push_edge(hi, lo, n_edges, graph, level, stack, stacked)
            ok, log = _settle(lo, limit, problem, scratch, paths, costs, leave, index, tallies, graph, walk,
                              heap, queued, level, counters, log, window, rules)  # fmt: skip
            results[child] = ok
            failed += not ok
            child_cost[child] = counters[_TOTAL]
            if ok and not only_one:
                child_collisions[child] = collisions_at.sum()
            if child == 0 and ok and not only_one:
                # Keep the first child's new paths: if it wins, they go back in without planning them again.
                n_kept = counters[_UNDO] - base_undo
                if n_kept > len(kept_agent):
                    kept_agent = np.empty(n_kept, dtype=np.int64)
                    kept_cost = np.empty(n_kept, dtype=np.int64)
                    kept_path = np.empty((n_kept, width), dtype=np.int32)
                for i in range(n_kept):
                    x = log[0][base_undo + i]
                    kept_agent[i], kept_cost[i] = x, costs[x]
                    kept_path[i] = paths[x]
        second_wins = not only_one and _second_first(results, child_cost, child_collisions, rules)
        if second_wins:  # the state holds the second child already
            if results[0]:
                alt_undo[n_alt], alt_edges[n_alt], alt_hi[n_alt], alt_lo[n_alt] = base_undo, base_edges, first_hi, first_lo
                n_alt += 1
            continue
        if results[0]:
            if not only_one:  # back to the first child: its kept paths, logged for undoing as planning would log them
                if results[1]:
                    alt_undo[n_alt], alt_edges[n_alt], alt_hi[n_alt], alt_lo[n_alt] = (
                        base_undo, base_edges, first_lo, first_hi
                    )  # fmt: skip
                    n_alt += 1
                _undo_to(base_undo, paths, costs, leave, positions, index, tallies, counters, log)
                n_edges = _pop_edges_to(base_edges, n_edges, graph)
                n_edges = _push_edge(first_hi, first_lo, n_edges, graph, level, stack, stacked)
                for i in range(n_kept):
                    log = _set_path(kept_agent[i], kept_path[i], kept_cost[i], paths, costs, leave, positions, index,
                                    tallies, counters, log)  # fmt: skip
            continue
        # Neither child works: remember the pair (rule 5) and return to the newest child left on the stack.
        if rules & SEARCH_ORDER:
            dead_a[n_dead], dead_b[n_dead] = a, b
            n_dead += 1
        dead_ends += 1
        resumed = False
        while n_alt > 0 and nodes < node_budget and (dead_end_budget < 0 or dead_ends <= dead_end_budget):
            n_alt -= 1
            _undo_to(alt_undo[n_alt], paths, costs, leave, positions, index, tallies, counters, log)
            n_edges = _pop_edges_to(alt_edges[n_alt], n_edges, graph)
            n_edges = _push_edge(alt_hi[n_alt], alt_lo[n_alt], n_edges, graph, level, stack, stacked)
            nodes += 1
            ok, log = _settle(alt_lo[n_alt], limit, problem, scratch, paths, costs, leave, index, tallies, graph,
                              walk, heap, queued, level, counters, log, window, rules)  # fmt: skip
            failed += not ok
            if ok:
                resumed = True
                break
        if not resumed:
            break
    return best, nodes, True, failed


@nb.njit(cache=True)
def wait_out(plan, positions, window, orders, cells):
    """``plan`` (which may collide) carried out step by step with waiting (rule 6 of the module notes): at each step
    the agents are taken in that step's row of ``orders``; one whose next cell is claimed for the step by an agent
    before it, or held by an agent that does not move, or whose move would swap two agents, waits, and an agent that
    waits holds its cell, so whoever had claimed that cell waits too, down the chain. An agent that waited takes the
    rest of its path one step later. ``cells``: how many cells the map has."""
    who = np.zeros((2, cells), dtype=np.int64)
    when = np.full((2, cells), -1, dtype=np.int64)
    stamp = 0
    n_agents = plan.shape[0]
    out = np.empty_like(plan)
    out[:, 0] = positions
    step_of = np.zeros(n_agents, dtype=np.int64)  # how far along its plan each agent is
    moving = np.zeros(n_agents, dtype=np.bool_)
    want = np.empty(n_agents, dtype=np.int64)
    for t in range(1, window + 1):
        order = orders[t - 1]
        for a in range(n_agents):
            here = out[a, t - 1]
            want[a] = plan[a, step_of[a] + 1] if step_of[a] < window else here
            moving[a] = want[a] != here
        stamp += 1
        before = stamp  # layer 0: who stands where at t - 1
        for a in range(n_agents):
            who[0, out[a, t - 1]] = a
            when[0, out[a, t - 1]] = before
        changed = True
        while changed:  # each pass that changes something stops one more agent, so this ends
            changed = False
            stamp += 1
            for a in range(n_agents):  # layer 1: cells taken at t; agents staying hold theirs first
                if not moving[a]:
                    who[1, out[a, t - 1]] = a
                    when[1, out[a, t - 1]] = stamp
            for i in range(n_agents):
                a = order[i]
                if not moving[a]:
                    continue
                v = want[a]
                taken = when[1, v] == stamp
                swap = False
                if not taken and when[0, v] == before:
                    b = who[0, v]
                    swap = moving[b] and want[b] == out[a, t - 1]
                if taken or swap:
                    moving[a] = False
                    changed = True
                    continue
                who[1, v] = a
                when[1, v] = stamp
        for a in range(n_agents):
            if moving[a]:
                out[a, t] = want[a]
                step_of[a] += 1
            else:
                out[a, t] = out[a, t - 1]
    return out
