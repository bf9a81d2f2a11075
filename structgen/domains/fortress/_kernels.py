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


@nb.njit
def _closest(b, i, c, cls, ex, ey, alive, count):
    """The original's closestEnt: the live entity of class c nearest (Manhattan) to entity i, not i itself, the
    earliest created on ties; -1 if none."""
    best, best_d = -1, 1 << 30
    for j in range(count):
        if j != i and alive[b, j] and cls[b, j] == c:
            d = abs(ex[b, j] - ex[b, i]) + abs(ey[b, j] - ey[b, i])
            if d < best_d:
                best, best_d = j, d
    return best


@nb.njit(inline="always")
def _another_of(total, c, k):
    """Whether an entity of class c lives besides the asking one (of class k); an undefined class (-1) has none."""
    return c >= 0 and total[c] > (c == k)


@nb.njit
def _first_at(b, x, y, ex, ey, alive, count):
    """The original's entAtPos: the earliest created live entity on tile (x, y), or -1."""
    for j in range(count):
        if alive[b, j] and ex[b, j] == x and ey[b, j] == y:
            return j
    return -1


@nb.njit(inline="always")
def _count(grid, total, occupied, stale, c, x, y, delta):
    grid[c, x, y] += delta
    stale[c] = True
    total[c] += delta
    occupied[x, y] += delta


@nb.njit
def _near_counted(b, i, c, x, y, reach, orthogonal, cls, alive, grid, total, prefix, stale, width, height):
    """Whether another live entity of class c is within Chebyshev distance ``reach`` of entity i, at (x, y)
    (``orthogonal``: exactly one tile away north, south, east or west), from the per-class tile counts."""
    if c < 0:
        return False
    own = 1 if (alive[b, i] and cls[b, i] == c) else 0
    if total[c] - own <= 0:
        return False
    if orthogonal:
        found = 0
        if x + 1 < width:
            found += grid[c, x + 1, y]
        if x >= 1:
            found += grid[c, x - 1, y]
        if y + 1 < height:
            found += grid[c, x, y + 1]
        if y >= 1:
            found += grid[c, x, y - 1]
        return found > 0
    x0, x1 = max(x - reach, 0), min(x + reach, width - 1)
    y0, y1 = max(y - reach, 0), min(y + reach, height - 1)
    if x0 == 0 and y0 == 0 and x1 == width - 1 and y1 == height - 1:
        return True  # the box is the whole map, and another c is somewhere on it
    if reach <= 1:
        found = -own
        for u in range(x0, x1 + 1):
            for v in range(y0, y1 + 1):
                found += grid[c, u, v]
        return found > 0
    # Larger boxes from the class's prefix sums, rebuilt only when its entities have changed since.
    if stale[c]:
        for u in range(width):
            for v in range(height):
                prefix[c, u + 1, v + 1] = grid[c, u, v] + prefix[c, u, v + 1] + prefix[c, u + 1, v] - prefix[c, u, v]
        stale[c] = False
    found = prefix[c, x1 + 1, y1 + 1] - prefix[c, x0, y1 + 1] - prefix[c, x1 + 1, y0] + prefix[c, x0, y0] - own
    return found > 0


@nb.njit
def _spawn(b, c, x, y, cls, ex, ey, node, age, alive, slots):
    k = slots[b]
    cls[b, k], ex[b, k], ey[b, k], node[b, k], age[b, k], alive[b, k] = c, x, y, 0, 0, True
    slots[b] = k + 1


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
    n_classes = node_act.shape[1]
    for b in nb.prange(world.shape[0]):
        w = world[b]
        # Live entities per class and tile, per class, and per tile: conditions and placements read these instead
        # of scanning every entity.
        grid = np.zeros((n_classes, width, height), dtype=np.int32)
        total = np.zeros(n_classes, dtype=np.int32)
        occupied = np.zeros((width, height), dtype=np.int32)
        prefix = np.zeros((n_classes, width + 1, height + 1), dtype=np.int32)
        stale = np.ones(n_classes, dtype=np.bool_)
        for j in range(slots[b]):
            if alive[b, j]:
                _count(grid, total, occupied, stale, cls[b, j], ex[b, j], ey[b, j], 1)
        row = stream[b]
        mine = np.empty(3, dtype=np.int64)
        mine[USED], mine[UPDATES], mine[LAST_EVENT] = used[b], updates[b], last_event[b]
        while cause[b] == RUNNING:
            # The original checks these before each tick, in this order. Between ticks the slots hold only the
            # living (the dead are dropped at the end of each tick, and placement makes no gaps).
            live = slots[b]
            if live == 0:
                cause[b] = EXTINCT
                break
            if inactivity_limit > 0 and tick[b] - mine[LAST_EVENT] > inactivity_limit:
                cause[b] = INACTIVE
                break
            if live > cap:
                cause[b] = OVERPOPULATED
                break
            if tick[b] >= until:
                break
            tick[b] += 1
            t = tick[b]
            # Entities alive at the start of the tick act in creation order; newborns get later slots and wait.
            n_start = slots[b]
            for i in range(n_start):
                if not alive[b, i]:
                    continue
                k = cls[b, i]
                mine[UPDATES] += 1
                age[b, i] += 1
                here = node[b, i]
                act = node_act[w, k, here]
                arg = node_arg[w, k, here]
                x, y = ex[b, i], ey[b, i]
                if act == MOVE:
                    d = _draw(draws, row, mine, 4)
                    nx, ny = x + _DX[d], y + _DY[d]
                    if _valid(nx, ny, width, height):
                        _count(grid, total, occupied, stale, k, x, y, -1)
                        _count(grid, total, occupied, stale, k, nx, ny, 1)
                        ex[b, i], ey[b, i] = nx, ny
                        mine[LAST_EVENT] = t
                elif act == DIE:
                    alive[b, i] = False
                    _count(grid, total, occupied, stale, k, x, y, -1)
                    mine[LAST_EVENT] = t
                elif act == CLONE or act == ADD:
                    d = _draw(draws, row, mine, 4)
                    nx, ny = x + _DX[d], y + _DY[d]
                    placed = _valid(nx, ny, width, height) and occupied[nx, ny] == 0
                    if placed:
                        born = k if act == CLONE else arg
                        _spawn(b, born, nx, ny, cls, ex, ey, node, age, alive, slots)
                        _count(grid, total, occupied, stale, born, nx, ny, 1)
                    if placed or act == CLONE:  # the original logs a failed clone, not a failed add
                        mine[LAST_EVENT] = t
                elif act == TAKE:
                    j = _closest(b, i, arg, cls, ex, ey, alive, slots[b]) if _another_of(total, arg, k) else -1
                    if j >= 0 and (take_reach < 0 or max(abs(ex[b, j] - x), abs(ey[b, j] - y)) <= take_reach):
                        alive[b, j] = False
                        _count(grid, total, occupied, stale, arg, ex[b, j], ey[b, j], -1)
                        mine[LAST_EVENT] = t
                elif act == CHASE:
                    j = _closest(b, i, arg, cls, ex, ey, alive, slots[b]) if _another_of(total, arg, k) else -1
                    if j >= 0:
                        tx, ty = ex[b, j], ey[b, j]
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
                                _count(grid, total, occupied, stale, k, x, y, -1)
                                _count(grid, total, occupied, stale, k, x + sx, y + sy, 1)
                                ex[b, i], ey[b, i] = x + sx, y + sy
                                mine[LAST_EVENT] = t
                elif act == PUSH:
                    j = _closest(b, i, arg, cls, ex, ey, alive, slots[b]) if _another_of(total, arg, k) else -1
                    if j >= 0:
                        d = _draw(draws, row, mine, 4)
                        nx, ny = x + _DX[d], y + _DY[d]
                        if nx == ex[b, j] and ny == ey[b, j]:
                            if _valid(nx + _DX[d], ny + _DY[d], width, height):
                                _count(grid, total, occupied, stale, k, x, y, -1)
                                _count(grid, total, occupied, stale, k, nx, ny, 1)
                                _count(grid, total, occupied, stale, arg, nx, ny, -1)
                                _count(grid, total, occupied, stale, arg, nx + _DX[d], ny + _DY[d], 1)
                                ex[b, i], ey[b, i] = nx, ny
                                ex[b, j], ey[b, j] = nx + _DX[d], ny + _DY[d]
                                mine[LAST_EVENT] = t
                        elif _valid(nx, ny, width, height):
                            _count(grid, total, occupied, stale, k, x, y, -1)
                            _count(grid, total, occupied, stale, k, nx, ny, 1)
                            ex[b, i], ey[b, i] = nx, ny
                            mine[LAST_EVENT] = t
                elif act == TRANSFORM:
                    _spawn(b, arg, x, y, cls, ex, ey, node, age, alive, slots)
                    _count(grid, total, occupied, stale, arg, x, y, 1)
                    alive[b, i] = False
                    _count(grid, total, occupied, stale, k, x, y, -1)
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
                            j = _first_at(b, nx, ny, ex, ey, alive, slots[b])
                            blocked = j >= 0 and cls[b, j] == arg
                        if not blocked:
                            _count(grid, total, occupied, stale, k, x, y, -1)
                            _count(grid, total, occupied, stale, k, nx, ny, 1)
                            ex[b, i], ey[b, i] = nx, ny
                        mine[LAST_EVENT] = t  # moving and being blocked are both logged
                # Then the first edge out of the node (priority, then file order) whose condition holds is taken;
                # this runs even for an entity that has just died, with its last position.
                moved = -1
                for e in range(edge_start[w, k, here], edge_stop[w, k, here]):
                    cond = edge_cond[e]
                    if cond == NONE:
                        ok = True
                    elif cond == STEP:
                        ok = age[b, i] % edge_int[e] == 0
                    else:
                        reach = 0 if cond == TOUCH else (1 if cond == NEXT_TO else edge_int[e])
                        ok = _near_counted(
                            b, i, edge_arg[e], ex[b, i], ey[b, i], reach, cond == NEXT_TO and orthogonal_next_to,
                            cls, alive, grid, total, prefix, stale, width, height,
                        )  # fmt: skip
                    if ok:
                        node[b, i] = edge_dst[e]
                        moved = e
                        break
                visited[b, node_vid[w, k] + node[b, i]] = 1
                if moved >= 0:
                    visited[b, edge_vid[moved]] = 1
            # Drop the dead, keeping creation order.
            kept = 0
            for j in range(slots[b]):
                if alive[b, j]:
                    if kept != j:
                        cls[b, kept], ex[b, kept], ey[b, kept] = cls[b, j], ex[b, j], ey[b, j]
                        node[b, kept], age[b, kept], alive[b, kept] = node[b, j], age[b, j], True
                    kept += 1
            for j in range(kept, slots[b]):
                alive[b, j] = False
            slots[b] = kept
        used[b], updates[b], last_event[b] = mine[USED], mine[UPDATES], mine[LAST_EVENT]
