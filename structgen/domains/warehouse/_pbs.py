"""Windowed Priority-Based Search: the planner the paper's simulator uses, written from its two papers.

Every replanning round is one windowed MAPF problem: paths for all agents whose collisions count only in the first
``window`` steps (Li et al., "Lifelong Multi-Agent Path Finding in Large-Scale Warehouses", AAAI 2021). It is
solved by Priority-Based Search (Ma et al., "Searching with Consistent Prioritization for Multi-Agent Path
Finding", AAAI 2019):

- the root gives every agent the best path of its own, ignoring the others;
- a node with a collision between agents ``a`` and ``b`` has two children, one in which ``a`` goes before ``b``
  and one the other way round. A child adds that pair to the partial order it inherits, then plans the lower agent
  again, and after it, in topological order, every agent below it whose path now runs into an agent above it; each
  plans against the paths of all agents above it. A child in which some agent has no path is dropped;
- the search goes depth first, into the child with the smaller sum of path costs first (ties: the child whose upper
  agent comes first in the round's order); the other child waits on a stack for backtracking;
- it ends at the first node without collisions.

A node is one child planned. When the search runs out of nodes (its budget stands in for the original's time limit,
so that runs repeat exactly) or of children, it gives up and returns the paths of the node it stopped at, which may
collide. The caller then plans the round by prioritized planning (the simulator's default), or carries those paths
out step by step with waiting (:func:`wait_out`): an agent whose next cell is taken, or who would swap with another,
waits and takes the rest of its path one step later (the first agent in the round's order keeps a contested cell).
That always gives collision-free moves, but congested more often.

The low-level search is the space-time A* of :mod:`._mapf` (``_search``): goals in sequence, costs exact inside
the window and estimated by distance beyond it. Everything is plain arrays so that numba compiles it.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from structgen.domains.warehouse._mapf import _search, search_scratch


@nb.njit(cache=True)
def _first_collision(paths, window, who, when, stamp):
    """The earliest collision among ``paths`` as ``(a, b, time)``, or ``(-1, -1, -1)``: two agents on one cell, or
    two swapping cells, at the same step. ``who``/``when`` are ``(2, cells)`` scratch tables; ``stamp`` must grow by
    more than ``window`` between calls."""
    n_agents = paths.shape[0]
    for t in range(window + 1):
        layer = t & 1
        mark = stamp + t
        for a in range(n_agents):
            cell = paths[a, t]
            if when[layer, cell] == mark:
                return who[layer, cell], a, t
            when[layer, cell] = mark
            who[layer, cell] = a
        if t == 0:
            continue
        before = 1 - layer
        for a in range(n_agents):
            u, v = paths[a, t - 1], paths[a, t]
            if u != v and when[before, v] == mark - 1:
                b = who[before, v]
                if b != a and paths[b, t] == u:
                    return b, a, t
    return -1, -1, -1


@nb.njit(cache=True)
def _runs_into(path, occupied, window):
    """Whether ``path`` shares a cell with, or swaps with, a path written into ``occupied``."""
    for t in range(1, window + 1):
        v = path[t]
        if occupied[t, v] >= 0:
            return True
        u = path[t - 1]
        if u != v:
            other = occupied[t - 1, v]
            if other >= 0 and occupied[t, u] == other:
                return True
    return False


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
def pbs_window(
    positions, goals, waits, n_goals, pinned, target_of, dist, neighbours, window, order, node_budget, dead_end_budget
):
    """Collision-free paths for all agents over ``window`` steps by Priority-Based Search (``waits`` and ``pinned``
    as in :func:`._mapf._search`; ``order`` breaks ties between children). Returns ``(paths, nodes, gave_up)``:
    ``(agents, window + 1)`` cells, the nodes planned, and whether the search gave up (the paths are then the
    unfinished plan, which may collide: module notes)."""
    n_agents = len(positions)
    n = neighbours.shape[0]
    seen, parent, heap_keys, heap_states = search_scratch(n, window, goals.shape[1])
    occupied = -np.ones((window + 1, n), dtype=np.int32)
    path = np.empty(window + 1, dtype=np.int32)
    who = np.zeros((2, n), dtype=np.int64)
    when = np.full((2, n), -1, dtype=np.int64)
    rank = np.empty(n_agents, dtype=np.int64)
    for i in range(n_agents):
        rank[order[i]] = i

    paths = np.empty((n_agents, window + 1), dtype=np.int32)
    costs = np.zeros(n_agents, dtype=np.int64)
    stamp = 0
    total = 0
    for a in range(n_agents):
        stamp += 1
        cost = _search(positions[a], goals[a], waits[a], n_goals[a], pinned[a], target_of, dist, neighbours, occupied,
                       window, seen, parent, stamp, heap_keys, heap_states, path)  # fmt: skip
        if cost < 0:  # cannot even move alone (a task it cannot finish in place): stay
            path[:] = positions[a]
            cost = 0
        paths[a] = path
        costs[a] = cost
        total += cost

    # The partial order: edge e says edge_hi[e] goes before edge_lo[e]. Edges are added and removed last in, first
    # out (depth-first search), so each agent's lists are stacks with their newest edge at the head.
    capacity = node_budget + 2
    edge_hi = np.empty(capacity, dtype=np.int64)
    edge_lo = np.empty(capacity, dtype=np.int64)
    next_up = np.empty(capacity, dtype=np.int64)  # next edge into the same lower agent
    next_down = np.empty(capacity, dtype=np.int64)  # next edge out of the same upper agent
    head_up = -np.ones(n_agents, dtype=np.int64)
    head_down = -np.ones(n_agents, dtype=np.int64)
    n_edges = 0
    # Undo log of replaced paths, so that backtracking restores a node.
    undo_cap = 4 * n_agents + 16
    undo_agent = np.empty(undo_cap, dtype=np.int64)
    undo_cost = np.empty(undo_cap, dtype=np.int64)
    undo_path = np.empty((undo_cap, window + 1), dtype=np.int32)
    n_undo = 0
    # Children left for backtracking: the node to return to (undo and edge marks) and the pair to add.
    alt_undo = np.empty(capacity, dtype=np.int64)
    alt_edges = np.empty(capacity, dtype=np.int64)
    alt_hi = np.empty(capacity, dtype=np.int64)
    alt_lo = np.empty(capacity, dtype=np.int64)
    n_alt = 0
    mark = np.zeros(n_agents, dtype=np.int64)  # stamps for graph walks
    mark_stamp = 0
    queue = np.empty(n_agents, dtype=np.int64)
    above = np.empty(n_agents, dtype=np.int64)
    topo = np.empty(n_agents, dtype=np.int64)
    indegree = np.zeros(n_agents, dtype=np.int64)
    collision_stamp = 0
    nodes = 0
    dead_ends = 0
    kept_agent = np.empty(n_agents, dtype=np.int64)
    kept_cost = np.empty(n_agents, dtype=np.int64)
    kept_path = np.empty((n_agents, window + 1), dtype=np.int32)
    n_kept = 0

    while True:
        collision_stamp += window + 2
        a, b, _ = _first_collision(paths, window, who, when, collision_stamp)
        if a < 0:
            return paths, nodes, False
        if nodes >= node_budget:
            break
        # Agents already ordered can still collide when a path above was written over another in ``occupied``:
        # then only the existing order is a child (adding the other would make a cycle).
        mark_stamp += 1
        _collect(a, head_down, next_down, edge_lo, mark, mark_stamp, queue)
        a_above_b = mark[b] == mark_stamp
        b_above_a = False
        if not a_above_b:
            mark_stamp += 1
            _collect(b, head_down, next_down, edge_lo, mark, mark_stamp, queue)
            b_above_a = mark[a] == mark_stamp
        # Children as (upper, lower); the first in the round's order goes first on ties.
        first_hi, first_lo = (a, b) if rank[a] <= rank[b] else (b, a)
        if a_above_b:
            first_hi, first_lo = a, b
        elif b_above_a:
            first_hi, first_lo = b, a
        only_one = a_above_b or b_above_a
        base_undo, base_edges = n_undo, n_edges

        results = np.zeros(2, dtype=np.bool_)
        child_cost = np.zeros(2, dtype=np.int64)
        for child in range(1 if only_one else 2):
            hi, lo = (first_hi, first_lo) if child == 0 else (first_lo, first_hi)
            if child == 1:  # back to the parent
                n_undo, total = _undo_to(base_undo, n_undo, undo_agent, undo_cost, undo_path, paths, costs, total)
                n_edges = _pop_edges_to(base_edges, n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down)
            nodes += 1
            if not only_one:
                n_edges = _push_edge(hi, lo, n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down)
            ok, n_undo, total, stamp, mark_stamp, undo_agent, undo_cost, undo_path = _replan_below(
                lo, paths, costs, total, positions, goals, waits, n_goals, pinned, target_of, dist, neighbours,
                occupied, window, seen, parent, stamp, heap_keys, heap_states, path, head_up, next_up, edge_hi,
                head_down, next_down, edge_lo, mark, mark_stamp, queue, above, topo, indegree,
                n_undo, undo_agent, undo_cost, undo_path,
            )  # fmt: skip
            results[child] = ok
            child_cost[child] = total
            if child == 0 and ok and not only_one:
                # Keep the first child's new paths: if it wins, they go back in without planning them again.
                n_kept = n_undo - base_undo
                for i in range(n_kept):
                    x = undo_agent[base_undo + i]
                    kept_agent[i], kept_cost[i] = x, costs[x]
                    kept_path[i] = paths[x]
        second_wins = not only_one and results[1] and (not results[0] or child_cost[1] < child_cost[0])
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
                n_undo, total = _undo_to(base_undo, n_undo, undo_agent, undo_cost, undo_path, paths, costs, total)
                n_edges = _pop_edges_to(base_edges, n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down)
                n_edges = _push_edge(first_hi, first_lo, n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down)
                for i in range(n_kept):
                    n_undo, total, undo_agent, undo_cost, undo_path = _set_path(
                        kept_agent[i], kept_path[i], kept_cost[i], paths, costs, total, n_undo, undo_agent, undo_cost,
                        undo_path,
                    )  # fmt: skip
            continue
        # Neither child works: return to the newest child left on the stack.
        dead_ends += 1
        resumed = False
        while n_alt > 0 and nodes < node_budget and dead_ends <= dead_end_budget:
            n_alt -= 1
            n_undo, total = _undo_to(alt_undo[n_alt], n_undo, undo_agent, undo_cost, undo_path, paths, costs, total)
            n_edges = _pop_edges_to(alt_edges[n_alt], n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down)
            n_edges = _push_edge(alt_hi[n_alt], alt_lo[n_alt], n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down)
            nodes += 1
            ok, n_undo, total, stamp, mark_stamp, undo_agent, undo_cost, undo_path = _replan_below(
                alt_lo[n_alt], paths, costs, total, positions, goals, waits, n_goals, pinned, target_of, dist,
                neighbours, occupied, window, seen, parent, stamp, heap_keys, heap_states, path, head_up, next_up,
                edge_hi, head_down, next_down, edge_lo, mark, mark_stamp, queue, above, topo, indegree,
                n_undo, undo_agent, undo_cost, undo_path,
            )  # fmt: skip
            if ok:
                resumed = True
                break
        if not resumed:
            break
    return paths, nodes, True


@nb.njit(cache=True)
def _push_edge(hi, lo, n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down):
    e = n_edges
    edge_hi[e], edge_lo[e] = hi, lo
    next_up[e], head_up[lo] = head_up[lo], e
    next_down[e], head_down[hi] = head_down[hi], e
    return n_edges + 1


@nb.njit(cache=True)
def _pop_edges_to(keep, n_edges, edge_hi, edge_lo, next_up, next_down, head_up, head_down):
    while n_edges > keep:
        n_edges -= 1
        head_up[edge_lo[n_edges]] = next_up[n_edges]
        head_down[edge_hi[n_edges]] = next_down[n_edges]
    return n_edges


@nb.njit(cache=True)
def _undo_to(keep, n_undo, undo_agent, undo_cost, undo_path, paths, costs, total):
    while n_undo > keep:
        n_undo -= 1
        x = undo_agent[n_undo]
        total += undo_cost[n_undo] - costs[x]
        costs[x] = undo_cost[n_undo]
        paths[x] = undo_path[n_undo]
    return n_undo, total


@nb.njit(cache=True)
def _replan_below(
    lo, paths, costs, total, positions, goals, waits, n_goals, pinned, target_of, dist, neighbours, occupied, window,
    seen, parent, stamp, heap_keys, heap_states, path, head_up, next_up, edge_hi, head_down, next_down, edge_lo, mark,
    mark_stamp, queue, above, topo, indegree, n_undo, undo_agent, undo_cost, undo_path,
):  # fmt: skip
    """Plan ``lo`` again against every agent above it, then, in topological order, every agent below ``lo`` whose
    path runs into one above it. Returns ``(ok, ...state)``; ``ok`` is False as soon as one agent has no path."""
    mark_stamp += 1
    below_stamp = mark_stamp
    count = _collect(lo, head_down, next_down, edge_lo, mark, below_stamp, queue)
    # Kahn's algorithm within the agents below ``lo``: count each one's upper agents in that set.
    for i in range(count):
        indegree[queue[i]] = 0
    for i in range(count):
        x = queue[i]
        e = head_up[x]
        while e >= 0:
            if mark[edge_hi[e]] == below_stamp:
                indegree[x] += 1
            e = next_up[e]
    # ``topo`` is filled as a queue, starting from ``lo`` (nothing above it is below it).
    topo[0] = lo
    head, tail = 0, 1
    ok = True
    while head < tail:
        x = topo[head]
        head += 1
        # Everything above x goes into the reservation table.
        mark_stamp += 1
        n_above = _collect(x, head_up, next_up, edge_hi, mark, mark_stamp, above)
        for i in range(1, n_above):
            y = above[i]
            for t in range(window + 1):
                occupied[t, paths[y, t]] = y
        if x == lo or _runs_into(paths[x], occupied, window):
            stamp += 1
            cost = _search(positions[x], goals[x], waits[x], n_goals[x], pinned[x], target_of, dist, neighbours,
                           occupied, window, seen, parent, stamp, heap_keys, heap_states, path)  # fmt: skip
            if cost >= 0:
                n_undo, total, undo_agent, undo_cost, undo_path = _set_path(
                    x, path, cost, paths, costs, total, n_undo, undo_agent, undo_cost, undo_path
                )
            else:
                ok = False
        for i in range(1, n_above):
            y = above[i]
            for t in range(window + 1):
                occupied[t, paths[y, t]] = -1
        if not ok:
            break
        # x is placed: its lower agents (all below lo too) have one upper agent fewer left to place.
        e = head_down[x]
        while e >= 0:
            y = edge_lo[e]
            indegree[y] -= 1
            if indegree[y] == 0:
                topo[tail] = y
                tail += 1
            e = next_down[e]
    return ok, n_undo, total, stamp, mark_stamp, undo_agent, undo_cost, undo_path


@nb.njit(cache=True)
def _set_path(x, path, cost, paths, costs, total, n_undo, undo_agent, undo_cost, undo_path):
    """Give agent ``x`` a new path of ``cost``, its old one logged for :func:`_undo_to`; returns
    ``(n_undo, total, undo_agent, undo_cost, undo_path)`` (the log grows when full)."""
    if n_undo == len(undo_agent):
        undo_agent, undo_cost, undo_path = _grown(undo_agent, undo_cost, undo_path)
    undo_agent[n_undo], undo_cost[n_undo] = x, costs[x]
    undo_path[n_undo] = paths[x]
    paths[x] = path
    total += cost - costs[x]
    costs[x] = cost
    return n_undo + 1, total, undo_agent, undo_cost, undo_path


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
def wait_out(plan, positions, window, order, cells):
    """``plan`` (which may collide) carried out step by step with waiting, ``order`` keeping contested cells: see
    the module notes. ``cells``: how many cells the map has."""
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
