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
# End causes.
RUNNING, STEPS, EXTINCT, OVERPOPULATED, INACTIVE = range(5)

# The original's direction list, [[0,1],[0,-1],[1,0],[-1,0]] as (dx, dy).
_DX = np.array([0, 0, 1, -1], dtype=np.int64)
_DY = np.array([1, -1, 0, 0], dtype=np.int64)


@nb.njit(inline="always")
def _draw(draws, stream, b, used, n):
    u = np.uint64(draws[stream[b], used[b]])
    used[b] += 1
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


@nb.njit
def _first_at(b, x, y, ex, ey, alive, count):
    """The original's entAtPos: the earliest created live entity on tile (x, y), or -1."""
    for j in range(count):
        if alive[b, j] and ex[b, j] == x and ey[b, j] == y:
            return j
    return -1


@nb.njit
def _near(b, i, c, reach, orthogonal, cls, ex, ey, alive, count):
    """Whether another live entity of class c is within Chebyshev distance ``reach`` of entity i (``orthogonal``:
    exactly one tile away north, south, east or west)."""
    for j in range(count):
        if j != i and alive[b, j] and cls[b, j] == c:
            dx, dy = abs(ex[b, j] - ex[b, i]), abs(ey[b, j] - ey[b, i])
            if orthogonal:
                if dx + dy == 1:
                    return True
            elif dx <= reach and dy <= reach:
                return True
    return False


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
    for b in nb.prange(world.shape[0]):
        w = world[b]
        while cause[b] == RUNNING:
            # The original checks these before each tick, in this order. Between ticks the slots hold only the
            # living (the dead are dropped at the end of each tick, and placement makes no gaps).
            live = slots[b]
            if live == 0:
                cause[b] = EXTINCT
                break
            if inactivity_limit > 0 and tick[b] - last_event[b] > inactivity_limit:
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
                updates[b] += 1
                age[b, i] += 1
                here = node[b, i]
                act = node_act[w, k, here]
                arg = node_arg[w, k, here]
                x, y = ex[b, i], ey[b, i]
                if act == MOVE:
                    d = _draw(draws, stream, b, used, 4)
                    nx, ny = x + _DX[d], y + _DY[d]
                    if _valid(nx, ny, width, height):
                        ex[b, i], ey[b, i] = nx, ny
                        last_event[b] = t
                elif act == DIE:
                    alive[b, i] = False
                    last_event[b] = t
                elif act == CLONE or act == ADD:
                    d = _draw(draws, stream, b, used, 4)
                    nx, ny = x + _DX[d], y + _DY[d]
                    placed = _valid(nx, ny, width, height) and _first_at(b, nx, ny, ex, ey, alive, slots[b]) < 0
                    if placed:
                        _spawn(b, k if act == CLONE else arg, nx, ny, cls, ex, ey, node, age, alive, slots)
                    if placed or act == CLONE:  # the original logs a failed clone, not a failed add
                        last_event[b] = t
                elif act == TAKE:
                    j = _closest(b, i, arg, cls, ex, ey, alive, slots[b])
                    if j >= 0 and (take_reach < 0 or max(abs(ex[b, j] - x), abs(ey[b, j] - y)) <= take_reach):
                        alive[b, j] = False
                        last_event[b] = t
                elif act == CHASE:
                    j = _closest(b, i, arg, cls, ex, ey, alive, slots[b])
                    if j >= 0:
                        tx, ty = ex[b, j], ey[b, j]
                        sx = 1 if tx > x else (-1 if tx < x else 0)
                        sy = 1 if ty > y else (-1 if ty < y else 0)
                        if sx != 0 or sy != 0:
                            # The original chooses among the needed directions, east/west first; a choice among
                            # one draws nothing.
                            if sx != 0 and sy != 0:
                                if _draw(draws, stream, b, used, 2) == 0:
                                    sy = 0
                                else:
                                    sx = 0
                            if _valid(x + sx, y + sy, width, height):
                                ex[b, i], ey[b, i] = x + sx, y + sy
                                last_event[b] = t
                elif act == PUSH:
                    j = _closest(b, i, arg, cls, ex, ey, alive, slots[b])
                    if j >= 0:
                        d = _draw(draws, stream, b, used, 4)
                        nx, ny = x + _DX[d], y + _DY[d]
                        if nx == ex[b, j] and ny == ey[b, j]:
                            if _valid(nx + _DX[d], ny + _DY[d], width, height):
                                ex[b, i], ey[b, i] = nx, ny
                                ex[b, j], ey[b, j] = nx + _DX[d], ny + _DY[d]
                                last_event[b] = t
                        elif _valid(nx, ny, width, height):
                            ex[b, i], ey[b, i] = nx, ny
                            last_event[b] = t
                elif act == TRANSFORM:
                    _spawn(b, arg, x, y, cls, ex, ey, node, age, alive, slots)
                    alive[b, i] = False
                    last_event[b] = t
                elif act == MOVE_WALL:
                    d = _draw(draws, stream, b, used, 4)
                    nx, ny = x + _DX[d], y + _DY[d]
                    if _valid(nx, ny, width, height):
                        if wall_any:
                            blocked = False
                            for j in range(slots[b]):
                                if alive[b, j] and cls[b, j] == arg and ex[b, j] == nx and ey[b, j] == ny:
                                    blocked = True
                                    break
                        else:
                            j = _first_at(b, nx, ny, ex, ey, alive, slots[b])
                            blocked = j >= 0 and cls[b, j] == arg
                        if not blocked:
                            ex[b, i], ey[b, i] = nx, ny
                        last_event[b] = t  # moving and being blocked are both logged
                # Then the first edge out of the node (priority, then file order) whose condition holds is taken;
                # this runs even for an entity that has just died, with its last position.
                moved = -1
                for e in range(edge_start[w, k, here], edge_stop[w, k, here]):
                    cond = edge_cond[e]
                    if cond == NONE:
                        ok = True
                    elif cond == STEP:
                        ok = age[b, i] % edge_int[e] == 0
                    elif cond == TOUCH:
                        ok = _near(b, i, edge_arg[e], 0, False, cls, ex, ey, alive, slots[b])
                    elif cond == NEXT_TO:
                        ok = _near(b, i, edge_arg[e], 1, orthogonal_next_to, cls, ex, ey, alive, slots[b])
                    else:
                        ok = _near(b, i, edge_arg[e], edge_int[e], False, cls, ex, ey, alive, slots[b])
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
