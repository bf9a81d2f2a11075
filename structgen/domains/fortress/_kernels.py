"""The fortress tick compiled with numba: one simulation per parallel iteration, its entities updated one at a time.

The semantics are the original's (see :mod:`.engine`): entities act in creation order with live reads, each draws at
most one number from its simulation's random stream, newborns wait for the next tick. Everything is plain arrays so
that numba can compile it; :mod:`.engine` builds them from fortress files and reads the results back.

Random numbers: the original draws ``rng.choice`` of 4 directions (or of the 2 directions a chase needs) from a numpy
``Generator`` (PCG64). Such a choice takes one 32-bit output ``u`` of the generator and returns ``(u * n) >> 32``
(no rejection is ever needed for n = 2 or 4), and a choice among one direction takes nothing. So each simulation is
handed the 32-bit outputs of ``default_rng(seed)`` in order and draws from them exactly as numpy would. Simulations
with the same seed share one array of outputs (each keeps its own count of those it used).
"""

from __future__ import annotations

import numba as nb
import numpy as np

# Action codes (node types) and condition codes; a condition's code is its priority.
IDLE, MOVE, DIE, CLONE, TAKE, CHASE, PUSH, ADD, TRANSFORM, MOVE_WALL = range(10)
NONE, STEP, WITHIN, NEXT_TO, TOUCH = range(5)
# A simulation's own counters, kept in a private array while it runs (threads writing neighbouring entries of the
# shared arrays on every update would keep stealing each other's cache line).
USED, UPDATES, LAST_EVENT = range(3)
# End causes.
RUNNING, STEPS, EXTINCT, OVERPOPULATED, INACTIVE = range(5)

# The original's direction list, [[0,1],[0,-1],[1,0],[-1,0]] as (dx, dy).
_DX = np.array([0, 0, 1, -1], dtype=np.int64)
_DY = np.array([1, -1, 0, 0], dtype=np.int64)


@nb.njit(inline="always")
def _draw(draws, row, mine, n):
    u = np.uint64(draws[row, mine[USED]])
    mine[USED] += 1
    return np.int64((u * np.uint64(n)) >> np.uint64(32))


@nb.njit(inline="always")
def _valid(x, y, width, height):
    # The fortress is floor inside a one-tile wall border.
    return 1 <= x <= width - 2 and 1 <= y <= height - 2


@nb.njit(inline="always")
def _closest(i, c, ex, ey, alive, members, n_members):
    """The original's closestEnt: the live entity of class c nearest (Manhattan) to entity i, not i itself, the
    earliest created on ties; -1 if none. Only class c's entities are looked at (``members[c]``, in creation order)."""
    best, best_d = -1, 1 << 30
    x, y = ex[i], ey[i]
    for m in range(n_members[c]):
        j = members[c, m]
        if j != i and alive[j]:
            d = abs(ex[j] - x) + abs(ey[j] - y)
            if d < best_d:
                if d == 0:
                    return j  # nothing is nearer, and later ones lose ties
                best, best_d = j, d
    return best


@nb.njit(inline="always")
def _another_of(total, c, k):
    """Whether an entity of class c lives besides the asking one (of class k); an undefined class (-1) has none."""
    return c >= 0 and total[c] > (c == k)


@nb.njit(inline="always")
def _first_at(x, y, ex, ey, alive, count):
    """The original's entAtPos: the earliest created live entity on tile (x, y), or -1."""
    for j in range(count):
        if alive[j] and ex[j] == x and ey[j] == y:
            return j
    return -1


@nb.njit(inline="always")
def _count(grid, rows, total, occupied, c, x, y, delta):
    grid[c, x, y] += delta
    total[c] += delta
    occupied[x, y] += delta
    # rows[c, y]: a bit for each column of row y that holds a c.
    if grid[c, x, y] == 0:
        rows[c, y] &= ~(1 << x)
    else:
        rows[c, y] |= 1 << x


@nb.njit(inline="always")
def _move(grid, rows, total, occupied, c, j, x, y, nx, ny, ex, ey):
    """Entity j of class c steps from (x, y) to (nx, ny)."""
    _count(grid, rows, total, occupied, c, x, y, -1)
    _count(grid, rows, total, occupied, c, nx, ny, 1)
    ex[j], ey[j] = nx, ny


@nb.njit(inline="always")
def _spawn(c, x, y, cls, ex, ey, node, age, alive, slots, members, n_members):
    k = slots[0]
    cls[k], ex[k], ey[k], node[k], age[k], alive[k] = c, x, y, 0, 0, True
    slots[0] = k + 1
    members[c, n_members[c]] = k
    n_members[c] += 1


@nb.njit(inline="always")
def _list_members(cls, count, members, n_members):
    """Each class's entities in creation order (slots 0..count-1)."""
    n_members[:] = 0
    for j in range(count):
        c = cls[j]
        members[c, n_members[c]] = j
        n_members[c] += 1


@nb.njit
def _simulate(
    until,
    w,
    node_act,
    node_arg,
    node_vid,
    edge_start,
    edge_stop,
    edge_cond,
    edge_arg,
    edge_int,
    edge_dst,
    edge_vid,
    draws,
    row,
    mine,
    cls,
    ex,
    ey,
    node,
    age,
    alive,
    slots,
    clock,
    visited,
    width,
    height,
    cap,
    inactivity_limit,
    orthogonal_next_to,
    take_reach,
    wall_any,
):
    """One simulation until it stops or reaches tick ``until``, on its own copies of its state (1-D arrays;
    ``slots``, ``clock`` = [tick, cause] and ``mine`` = [used, updates, last event] are one-element counters)."""
    n_classes = node_act.shape[1]
    # Live entities per class and tile, per class, and per tile, and each class's entities in creation order:
    # conditions and targets read these instead of scanning every entity.
    grid = np.zeros((n_classes, width, height), dtype=np.int32)
    rows = np.zeros((n_classes, height), dtype=np.int32)
    total = np.zeros(n_classes, dtype=np.int32)
    occupied = np.zeros((width, height), dtype=np.int32)
    members = np.empty((n_classes, cls.shape[0]), dtype=np.int32)
    n_members = np.zeros(n_classes, dtype=np.int32)
    for j in range(slots[0]):
        if alive[j]:
            _count(grid, rows, total, occupied, cls[j], ex[j], ey[j], 1)
    _list_members(cls, slots[0], members, n_members)
    while clock[1] == RUNNING:
        # The original checks these before each tick, in this order. Between ticks the slots hold only the
        # living (the dead are dropped at the end of each tick, and placement makes no gaps).
        live = slots[0]
        if live == 0:
            clock[1] = EXTINCT
            break
        if inactivity_limit > 0 and clock[0] - mine[LAST_EVENT] > inactivity_limit:
            clock[1] = INACTIVE
            break
        if live > cap:
            clock[1] = OVERPOPULATED
            break
        if clock[0] >= until:
            break
        clock[0] += 1
        t = clock[0]
        # Entities alive at the start of the tick act in creation order; newborns get later slots and wait.
        n_start = slots[0]
        died = False
        for i in range(n_start):
            if not alive[i]:
                continue
            k = cls[i]
            mine[UPDATES] += 1
            age[i] += 1
            here = node[i]
            act = node_act[w, k, here]
            arg = node_arg[w, k, here]
            x, y = ex[i], ey[i]
            if act == MOVE:
                d = _draw(draws, row, mine, 4)
                nx, ny = x + _DX[d], y + _DY[d]
                if _valid(nx, ny, width, height):
                    _move(grid, rows, total, occupied, k, i, x, y, nx, ny, ex, ey)
                    mine[LAST_EVENT] = t
            elif act == DIE:
                alive[i] = False
                died = True
                _count(grid, rows, total, occupied, k, x, y, -1)
                mine[LAST_EVENT] = t
            elif act == CLONE or act == ADD:
                d = _draw(draws, row, mine, 4)
                nx, ny = x + _DX[d], y + _DY[d]
                placed = _valid(nx, ny, width, height) and occupied[nx, ny] == 0
                if placed:
                    born = k if act == CLONE else arg
                    _spawn(born, nx, ny, cls, ex, ey, node, age, alive, slots, members, n_members)
                    _count(grid, rows, total, occupied, born, nx, ny, 1)
                if placed or act == CLONE:  # the original logs a failed clone, not a failed add
                    mine[LAST_EVENT] = t
            elif act == TAKE:
                j = _closest(i, arg, ex, ey, alive, members, n_members) if _another_of(total, arg, k) else -1
                if j >= 0 and (take_reach < 0 or max(abs(ex[j] - x), abs(ey[j] - y)) <= take_reach):
                    alive[j] = False
                    died = True
                    _count(grid, rows, total, occupied, arg, ex[j], ey[j], -1)
                    mine[LAST_EVENT] = t
            elif act == CHASE:
                j = _closest(i, arg, ex, ey, alive, members, n_members) if _another_of(total, arg, k) else -1
                if j >= 0:
                    tx, ty = ex[j], ey[j]
                    sx = 1 if tx > x else (-1 if tx < x else 0)
                    sy = 1 if ty > y else (-1 if ty < y else 0)
                    if sx != 0 or sy != 0:
                        # The original chooses among the needed directions, east/west first; a choice among
                        # one draws nothing.
                        if sx != 0 and sy != 0:
                            if _draw(draws, row, mine, 2) == 0:
                                sy = 0
                            else:
                                sx = 0
                        if _valid(x + sx, y + sy, width, height):
                            _move(grid, rows, total, occupied, k, i, x, y, x + sx, y + sy, ex, ey)
                            mine[LAST_EVENT] = t
            elif act == PUSH:
                j = _closest(i, arg, ex, ey, alive, members, n_members) if _another_of(total, arg, k) else -1
                if j >= 0:
                    d = _draw(draws, row, mine, 4)
                    nx, ny = x + _DX[d], y + _DY[d]
                    if nx == ex[j] and ny == ey[j]:
                        if _valid(nx + _DX[d], ny + _DY[d], width, height):
                            _move(grid, rows, total, occupied, k, i, x, y, nx, ny, ex, ey)
                            _move(grid, rows, total, occupied, arg, j, nx, ny, nx + _DX[d], ny + _DY[d], ex, ey)
                            mine[LAST_EVENT] = t
                    elif _valid(nx, ny, width, height):
                        _move(grid, rows, total, occupied, k, i, x, y, nx, ny, ex, ey)
                        mine[LAST_EVENT] = t
            elif act == TRANSFORM:
                _spawn(arg, x, y, cls, ex, ey, node, age, alive, slots, members, n_members)
                _count(grid, rows, total, occupied, arg, x, y, 1)
                alive[i] = False
                died = True
                _count(grid, rows, total, occupied, k, x, y, -1)
                mine[LAST_EVENT] = t
            elif act == MOVE_WALL:
                d = _draw(draws, row, mine, 4)
                nx, ny = x + _DX[d], y + _DY[d]
                if _valid(nx, ny, width, height):
                    if arg < 0 or grid[arg, nx, ny] == 0:
                        blocked = False
                    elif wall_any:
                        blocked = True
                    else:
                        j = _first_at(nx, ny, ex, ey, alive, slots[0])
                        blocked = j >= 0 and cls[j] == arg
                    if not blocked:
                        _count(grid, rows, total, occupied, k, x, y, -1)
                        _count(grid, rows, total, occupied, k, nx, ny, 1)
                        ex[i], ey[i] = nx, ny
                    mine[LAST_EVENT] = t  # moving and being blocked are both logged
            # Then the first edge out of the node (priority, then file order) whose condition holds is taken;
            # this runs even for an entity that has just died, with its last position.
            moved = -1
            for e in range(edge_start[w, k, here], edge_stop[w, k, here]):
                cond = edge_cond[e]
                if cond == NONE:
                    ok = True
                elif cond == STEP:
                    ok = age[i] % edge_int[e] == 0
                else:
                    # Another live c within reach of the entity: touch 0, nextTo 1 (or the four orthogonal
                    # neighbours), within its range. Written out here rather than in a helper: numba counts
                    # references to every array a helper is handed, atomically, on each call (the kernel's
                    # hottest line spent most of its time on them).
                    c = edge_arg[e]
                    ok = False
                    if c >= 0:
                        px, py = ex[i], ey[i]
                        own = 1 if (alive[i] and cls[i] == c) else 0
                        if total[c] > own:
                            if cond == NEXT_TO and orthogonal_next_to:
                                ok = (
                                    (px + 1 < width and grid[c, px + 1, py] > 0)
                                    or (px >= 1 and grid[c, px - 1, py] > 0)
                                    or (py + 1 < height and grid[c, px, py + 1] > 0)
                                    or (py >= 1 and grid[c, px, py - 1] > 0)
                                )
                            elif grid[c, px, py] > own:
                                ok = True
                            elif cond != TOUCH:
                                reach = 1 if cond == NEXT_TO else edge_int[e]
                                x0, x1 = max(px - reach, 0), min(px + reach, width - 1)
                                y0, y1 = max(py - reach, 0), min(py + reach, height - 1)
                                # Columns x0..x1 as bits; the own tile was looked at above.
                                columns = ((1 << (x1 + 1)) - 1) ^ ((1 << x0) - 1)
                                for v in range(y0, y1 + 1):
                                    if rows[c, v] & (columns if v != py else columns & ~(1 << px)):
                                        ok = True
                                        break
                if ok:
                    node[i] = edge_dst[e]
                    moved = e
                    break
            visited[node_vid[w, k] + node[i]] = 1
            if moved >= 0:
                visited[edge_vid[moved]] = 1
        # Drop the dead, keeping creation order (a tick without deaths leaves the slots and class lists as they are:
        # newborns were appended to both).
        if died:
            kept = 0
            for j in range(slots[0]):
                if alive[j]:
                    if kept != j:
                        cls[kept], ex[kept], ey[kept] = cls[j], ex[j], ey[j]
                        node[kept], age[kept], alive[kept] = node[j], age[j], True
                    kept += 1
            for j in range(kept, slots[0]):
                alive[j] = False
            slots[0] = kept
            _list_members(cls, kept, members, n_members)


@nb.njit(parallel=True, cache=True)
def run(
    until,  # ticks to reach (the episode length)
    world,  # (B,) the world each simulation runs
    node_act,  # (W, K, N) action code of each node
    node_arg,  # (W, K, N) its class argument (-1: none or undefined)
    node_vid,  # (W, K) where the class's nodes start in a simulation's visit flags
    edge_start,  # (W, K, N) first edge tried from a node, an index into the edge arrays
    edge_stop,  # (W, K, N) one past its last
    edge_cond,  # (E,) condition code
    edge_arg,  # (E,) class argument (-1: none or undefined)
    edge_int,  # (E,) step count or range
    edge_dst,  # (E,) node it leads to
    edge_vid,  # (E,) its visit flag
    draws,  # (R, D) uint32 outputs of each random stream's generator, in order
    stream,  # (B,) the stream each simulation draws from
    used,  # (B,) how many it has used
    cls,  # (B, S) entity state in creation order: class
    ex,  # (B, S) column
    ey,  # (B, S) row
    node,  # (B, S) current node
    age,  # (B, S) ticks lived (the original's cur_step)
    alive,  # (B, S)
    slots,  # (B,) slots in use
    tick,  # (B,) ticks run
    cause,  # (B,) RUNNING or why the simulation stopped
    last_event,  # (B,) tick of the last logged event (for the inactivity stop)
    visited,  # (B, V) visit flags of nodes and edges
    updates,  # (B,) entity updates made
    width,
    height,
    cap,  # the population cap (stop when above it)
    inactivity_limit,  # 0: no inactivity stop (the original's, which never fires)
    orthogonal_next_to,
    take_reach,  # -1: anywhere on the map (the original); r: within Chebyshev distance r
    wall_any,  # move_wall blocked by any entity of the class on the tile (the original: only the first there)
):
    for b in nb.prange(world.shape[0]):
        # Each simulation runs on private copies of its rows: threads writing neighbouring entries of the shared
        # arrays on every update would keep stealing each other's cache lines.
        own_cls, own_ex, own_ey = cls[b].copy(), ex[b].copy(), ey[b].copy()
        own_node, own_age, own_alive, own_visited = node[b].copy(), age[b].copy(), alive[b].copy(), visited[b].copy()
        own_slots = np.array([slots[b]])
        clock = np.array([tick[b], cause[b]])
        mine = np.array([used[b], updates[b], last_event[b]])
        _simulate(
            until, world[b], node_act, node_arg, node_vid, edge_start, edge_stop, edge_cond, edge_arg, edge_int,
            edge_dst, edge_vid, draws, stream[b], mine, own_cls, own_ex, own_ey, own_node, own_age, own_alive,
            own_slots, clock, own_visited, width, height, cap, inactivity_limit, orthogonal_next_to, take_reach,
            wall_any,
        )  # fmt: skip
        cls[b], ex[b], ey[b], node[b], age[b], alive[b] = own_cls, own_ex, own_ey, own_node, own_age, own_alive
        visited[b] = own_visited
        slots[b], tick[b], cause[b] = own_slots[0], clock[0], clock[1]
        used[b], updates[b], last_event[b] = mine[USED], mine[UPDATES], mine[LAST_EVENT]


@nb.njit(cache=True)
def lay_out(class_world, class_slot, class_nodes, class_edges, node_act, node_arg, edges, renumber, k_max, n_max):
    """The kernel's padded tables (see :func:`run`) of many worlds at once.

    Classes come grouped by world, in each world's order: ``class_world`` / ``class_slot`` (C,) say which world and
    place; ``class_nodes`` / ``class_edges`` (C,) their node and edge counts. ``node_act`` / ``node_arg`` hold every
    node's action code and class argument, ``edges`` every edge as ``(src, dst, condition, class argument,
    number)`` in file order, both concatenated over the classes. ``renumber[w, a]`` is the world's class number of
    argument ``a`` (-1: the world has no such class; an argument of -1 stays -1).

    Out of each node the edges are tried highest priority first, file order within a priority (a counting sort on
    (source, priority)); an edge from a node the class lacks never fires and is left out, but keeps its visit flag.
    """
    n_worlds = renumber.shape[0]
    n_classes = class_world.shape[0]
    n_nodes = np.zeros(n_worlds, dtype=np.int64)
    n_edges = np.zeros(n_worlds, dtype=np.int64)
    live = 0
    at = 0
    for c in range(n_classes):
        n_nodes[class_world[c]] += class_nodes[c]
        n_edges[class_world[c]] += class_edges[c]
        for q in range(at, at + class_edges[c]):
            if 0 <= edges[q, 0] < class_nodes[c]:
                live += 1
        at += class_edges[c]
    out_act = np.zeros((n_worlds, k_max, n_max), dtype=np.int8)
    out_arg = np.full((n_worlds, k_max, n_max), -1, dtype=np.int16)
    node_vid = np.zeros((n_worlds, k_max), dtype=np.int32)
    edge_start = np.zeros((n_worlds, k_max, n_max), dtype=np.int32)
    edge_stop = np.zeros((n_worlds, k_max, n_max), dtype=np.int32)
    size = max(live, 1)
    edge_cond = np.zeros(size, dtype=np.int8)
    edge_arg = np.full(size, -1, dtype=np.int16)
    edge_int = np.zeros(size, dtype=np.int32)
    edge_dst = np.zeros(size, dtype=np.int16)
    edge_vid = np.zeros(size, dtype=np.int32)
    nodes_seen = np.zeros(n_worlds, dtype=np.int64)
    edges_seen = np.zeros(n_worlds, dtype=np.int64)
    node_at, edge_at, placed = 0, 0, 0
    for c in range(n_classes):
        w, k, nn, ne = class_world[c], class_slot[c], class_nodes[c], class_edges[c]
        node_vid[w, k] = nodes_seen[w]
        for n in range(nn):
            out_act[w, k, n] = node_act[node_at + n]
            a = node_arg[node_at + n]
            out_arg[w, k, n] = renumber[w, a] if a >= 0 else -1
        # Bucket (src, 4 - condition): its first place among this class's tried edges.
        first = np.zeros(nn * 5 + 1, dtype=np.int64)
        for q in range(edge_at, edge_at + ne):
            if 0 <= edges[q, 0] < nn:
                first[edges[q, 0] * 5 + 4 - edges[q, 2] + 1] += 1
        for j in range(nn * 5):
            first[j + 1] += first[j]
        for n in range(nn):
            edge_start[w, k, n] = placed + first[n * 5]
            edge_stop[w, k, n] = placed + first[n * 5 + 5]
        for q in range(edge_at, edge_at + ne):
            src = edges[q, 0]
            if 0 <= src < nn:
                bucket = src * 5 + 4 - edges[q, 2]
                e = placed + first[bucket]
                first[bucket] += 1
                cond = edges[q, 2]
                a = edges[q, 3]
                edge_cond[e] = cond
                edge_arg[e] = renumber[w, a] if a >= 0 else -1
                edge_int[e] = 1 if cond == NEXT_TO else edges[q, 4]
                edge_dst[e] = edges[q, 1]
                edge_vid[e] = n_nodes[w] + edges_seen[w] + q - edge_at
        placed += first[nn * 5]  # the total, never a bucket's start
        nodes_seen[w] += nn
        edges_seen[w] += ne
        node_at += nn
        edge_at += ne
    return out_act, out_arg, node_vid, edge_start, edge_stop, edge_cond, edge_arg, edge_int, edge_dst, edge_vid, n_nodes, n_edges


@nb.njit(cache=True)
def place(initial, initial_start, world, node_vid, visit_start_nodes, width, height, cls, ex, ey, alive, slots, visited):
    """Each simulation's initial entities: its world's ``initial[initial_start[w]:initial_start[w + 1]]`` rows
    ``(class, x, y)`` in order, each unless its tile is already taken (the original places them with its clone,
    which refuses an occupied tile)."""
    n_worlds = initial_start.shape[0] - 1
    kept = np.zeros(initial.shape[0], dtype=np.bool_)
    taken = np.zeros((width, height), dtype=np.bool_)
    for w in range(n_worlds):
        taken[:, :] = False
        for r in range(initial_start[w], initial_start[w + 1]):
            x, y = initial[r, 1], initial[r, 2]
            if not taken[x, y]:
                taken[x, y] = True
                kept[r] = True
    for b in range(world.shape[0]):
        w = world[b]
        s = 0
        for r in range(initial_start[w], initial_start[w + 1]):
            if kept[r]:
                c = initial[r, 0]
                cls[b, s], ex[b, s], ey[b, s], alive[b, s] = c, initial[r, 1], initial[r, 2], True
                if visit_start_nodes:
                    visited[b, node_vid[w, c]] = 1
                s += 1
        slots[b] = s
