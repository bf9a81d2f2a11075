"""The patch repair: a valid layout that keeps what a growth got right, in milliseconds and without a solver.

The paper repairs every grown layout with the fewest changes (a MILP), so that what the NCA grew, and with it the
archive's measures, survives the repair. HiGHS does that in about a second for layouts near valid but can spend its
whole minute on layouts far from it; the row repair (:func:`~structgen.domains.layouts.repair.greedy_repair`)
answers those at once but throws the growth's pattern away, so every far layout lands in the same few archive cells
(measured on the even run: 38 cells in 2,000 evaluations). This repair changes cells only where a rule asks (shelves
below stand for manufacturing's stations too):

1. a surplus (a warehouse's shelf count; more stations than leave room for the robots) is removed: first shelves off
   the row repair's rows (what is kept of a dense growth then stands in rows, not in a maze that jams), and among
   those first the ones boxed in by others, then those with no endpoint, then the thickest blocks;
2. every pocket of floor the workstations cannot reach gets the shortest way out, through as few shelves as possible
   (one breadth-first search over all pockets at once);
3. a deficit (the shelf count; one station of each kind) is made up on floor cells whose filling cannot cut any
   floor off (the free cells around them stay joined: a local test that needs no search), first beside endpoints
   already there, then on the row repair's rows, then anywhere;
4. each shelf without an endpoint gets one on a free neighbour (a boxed-in one is removed and step 3 replaces it),
   and endpoints beside no shelf become floor.

The steps repeat until the layout is valid (twice, nearly always). Candidates at each step are taken in a spread
order over the map, not from its top, and everything is deterministic. The answer is not the fewest changes; the
router (:func:`~structgen.domains.layouts.repair.repair`'s ``greedy_beyond``) takes whichever of this and the row
repair changes fewer cells.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from structgen.domains.layouts.kinds import WAREHOUSE, LayoutKind
from structgen.domains.layouts.measures import neighbour_count, violations

__all__ = ["PATCH_ROUNDS", "patch_repair"]

#: How many times the steps may repeat before the repair gives up (the layouts of random NCAs and of a training run
#: are valid after two; a step that undoes another's work would otherwise loop).
PATCH_ROUNDS = 8

_FOUR = ndimage.generate_binary_structure(2, 1)
#: The eight cells around a cell, in order around it, so that consecutive ones are 4-neighbours of each other.
_RING = ((-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1))
_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


@dataclass
class _Rules:
    """What the steps need to know of a layout kind, for one map."""

    floor: int
    blocking: list[int]  # shelves, or the three kinds of station
    endpoints: list[int]  # tiles that serve as endpoints ("s", the source, is one for manufacturing)
    endpoint: int  # the tile new endpoints get
    area: np.ndarray  # cells the repair may change
    fixed: np.ndarray  # cells that block and are never changed (workstations), where reachability starts
    addable: np.ndarray  # cells a new shelf or station may take
    row_pattern: np.ndarray  # preferred cells for new shelves, after those beside endpoints
    most: int  # at most this many blocking cells
    wanted: list[tuple[int, int]]  # (tile, at least this many), made up in this order


def patch_repair(
    tiles: np.ndarray,
    kind: LayoutKind = WAREHOUSE,
    *,
    shelves: int | None = None,
    agents: int = 0,
    row_offset: int = 0,
    aisle_every: int = 11,
) -> np.ndarray | None:
    """A valid layout that changes ``tiles`` only where a rule asks (module doc), or None where the steps do not
    settle within :data:`PATCH_ROUNDS` rounds. Warehouses take ``shelves`` (exactly that many); manufacturing floors
    ``agents`` (at least that many cells free of stations) and keep one station of each kind. ``row_offset`` and
    ``aisle_every`` give the row pattern preferred for shelves added where the growth has no endpoints (rows
    ``r % 3 == row_offset``, no shelf in every ``aisle_every``-th column of the storage area)."""
    tiles = np.asarray(tiles)
    rules = _rules_for(tiles, kind, shelves, agents, row_offset, aisle_every)
    if rules is None:
        return None
    result = tiles.astype(np.int64)
    check = {"shelves": shelves, "fixed": tiles} if kind.name == "warehouse" else {"agents": agents}
    for _ in range(PATCH_ROUNDS):
        _remove_surplus(result, rules)
        _open_pockets(result, rules)
        _add_blocking(result, rules)
        _give_endpoints(result, rules)
        if not violations(result, kind, **check):
            return result.astype(tiles.dtype)
    return None


def _rules_for(tiles, kind: LayoutKind, shelves, agents: int, row_offset: int, aisle_every: int) -> _Rules | None:
    code = kind.vocabulary.index
    rows, cols = tiles.shape
    area = np.zeros(tiles.shape, dtype=bool)
    if kind.name == "warehouse":
        if shelves is None:
            raise ValueError("a warehouse patch needs the shelf count")
        area[:, WAREHOUSE.border : -WAREHOUSE.border] = True
        fixed = np.isin(tiles, [code("w"), code("r"), code("s")])
        if not fixed.any():
            return None
        blocking, endpoints, most = [code("@")], [code("e")], shelves
        wanted = [(code("@"), shelves)]
    elif kind.name == "manufacturing":
        area[:] = True
        fixed = np.zeros(tiles.shape, dtype=bool)
        blocking, endpoints, most = [code(c) for c in "012"], [code("e"), code("s")], tiles.size - agents
        wanted = [(code(c), 1) for c in "012"]
    else:
        raise ValueError(f"{kind.name} layouts have no patch repair")
    # Cells beside a workstation stay floor: the workstations reach the map through them.
    addable = area & ~(neighbour_count(fixed) > 0)
    columns = np.flatnonzero(area.any(axis=0))
    row_pattern = np.zeros(tiles.shape, dtype=bool)
    row_pattern[[r for r in range(rows) if r % 3 == row_offset]] = True
    row_pattern[:, columns[np.arange(len(columns)) % aisle_every == aisle_every - 1]] = False
    row_pattern &= area
    return _Rules(code("."), blocking, endpoints, code("e"), area, fixed, addable, row_pattern, most, wanted)


def _spread_order(cells: np.ndarray) -> np.ndarray:
    """``cells`` (row-major) reordered so that any first k of them are spread over the map (a golden-ratio
    sequence over their positions), deterministically."""
    if len(cells) == 0:
        return cells
    return cells[np.argsort((np.arange(len(cells)) * _GOLDEN) % 1.0, kind="stable")]


def _remove_surplus(result, rules: _Rules) -> None:
    is_blocking = np.isin(result, rules.blocking)
    surplus = int(is_blocking.sum()) - rules.most
    if surplus <= 0:
        return
    free_next = neighbour_count(rules.area & ~is_blocking)
    endpoint_next = neighbour_count(np.isin(result, rules.endpoints))
    blocking_next = neighbour_count(is_blocking)
    # Lower rank goes first: cells off the row pattern (what is kept of a dense growth then stands in rows, not in
    # a maze that jams: measured), and among those boxed in, then without an endpoint, then the thickest blocks.
    lonely_rank = np.where(free_next == 0, 0, np.where(endpoint_next == 0, 1, 2))
    rank = rules.row_pattern * 32 + lonely_rank * 8 + (4 - blocking_next)
    candidates = np.argwhere(is_blocking & rules.area)
    ranks = rank[tuple(candidates.T)]
    removed = 0
    for level in np.unique(ranks):
        for r, c in _spread_order(candidates[ranks == level]):
            if removed == surplus:
                return
            result[r, c] = rules.floor
            removed += 1


def _open_pockets(result, rules: _Rules) -> None:
    """Give every floor cell the workstations cannot reach a way out through the fewest shelves, all pockets in one
    0-1 breadth-first search from the reached floor."""
    is_blocking = np.isin(result, rules.blocking)
    passable = ~is_blocking & ~rules.fixed
    if rules.fixed.any():  # warehouses: the floor the first workstation opens onto
        roots = [cell for cell in _neighbours(*np.argwhere(rules.fixed)[0], result.shape) if passable[cell]]
    else:  # manufacturing: the first free cell, as the validity check starts
        roots = [tuple(np.argwhere(passable)[0])] if passable.any() else []
    if not roots:
        return
    reached = _flood(passable, roots)
    pockets = passable & ~reached
    if not pockets.any():
        return
    distance = np.full(result.shape, np.iinfo(np.int32).max, dtype=np.int64)
    previous = np.full(result.shape + (2,), -1, dtype=np.int64)
    queue = deque()
    for r, c in np.argwhere(reached):
        distance[r, c] = 0
        queue.append((r, c))
    while queue:
        r, c = queue.popleft()
        for nr, nc in _neighbours(r, c, result.shape):
            if rules.fixed[nr, nc] or (is_blocking[nr, nc] and not rules.area[nr, nc]):
                continue
            step = 1 if is_blocking[nr, nc] else 0
            if distance[r, c] + step < distance[nr, nc]:
                distance[nr, nc] = distance[r, c] + step
                previous[nr, nc] = (r, c)
                (queue.appendleft if step == 0 else queue.append)((nr, nc))
    labels, count = ndimage.label(pockets, structure=_FOUR)
    for label in range(1, count + 1):
        cells = np.argwhere(labels == label)
        r, c = cells[np.argmin(distance[tuple(cells.T)])]
        while previous[r, c, 0] >= 0:
            if is_blocking[r, c]:
                result[r, c] = rules.floor
            r, c = previous[r, c]


def _neighbours(r: int, c: int, shape: tuple[int, int]) -> list[tuple[int, int]]:
    """The 4-neighbours of (r, c) inside a map of ``shape``."""
    return [
        (r + dr, c + dc) for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)) if 0 <= r + dr < shape[0] and 0 <= c + dc < shape[1]
    ]


def _flood(passable: np.ndarray, roots: list) -> np.ndarray:
    labels, _ = ndimage.label(passable, structure=_FOUR)
    keep = {labels[root] for root in roots}
    return np.isin(labels, list(keep))


def _keeps_floor_joined(free: np.ndarray, r: int, c: int) -> bool:
    """Whether blocking (r, c) leaves its free 4-neighbours joined through the ring of cells around it (so blocking
    it cuts no floor off anywhere), and it keeps at least one free 4-neighbour for an endpoint."""
    rows, cols = free.shape
    ring = [0 <= r + dr < rows and 0 <= c + dc < cols and bool(free[r + dr, c + dc]) for dr, dc in _RING]
    if not any(ring[1::2]):
        return False
    if all(ring):
        return True
    # Count the runs of free cells around the ring that hold a 4-neighbour (odd positions): at most one may.
    first_blocked = ring.index(False)
    runs_with_neighbour, in_run, has_neighbour = 0, False, False
    for step in range(1, 9):
        i = (first_blocked + step) % 8
        if ring[i]:
            if not in_run:
                in_run, has_neighbour = True, False
            has_neighbour |= i % 2 == 1
        elif in_run:
            runs_with_neighbour += has_neighbour
            in_run = False
    if in_run:
        runs_with_neighbour += has_neighbour
    return runs_with_neighbour <= 1


def _add_blocking(result, rules: _Rules) -> None:
    """Make up each wanted tile's count on floor cells whose filling cuts no floor off: first beside endpoints, then
    on the row pattern, then anywhere, spread over the map."""
    free = ~np.isin(result, rules.blocking) & ~rules.fixed
    for tile, least in rules.wanted:
        missing = min(least - int((result == tile).sum()), rules.most - int((~free & ~rules.fixed).sum()))
        if missing <= 0:
            continue
        candidates = np.argwhere(rules.addable & (result == rules.floor))
        beside_endpoint = (neighbour_count(np.isin(result, rules.endpoints)) > 0)[tuple(candidates.T)]
        rank = np.where(beside_endpoint, 0, np.where(rules.row_pattern[tuple(candidates.T)], 1, 2))
        for level in range(3):
            for r, c in _spread_order(candidates[rank == level]):
                if missing == 0:
                    break
                if _keeps_floor_joined(free, r, c):
                    result[r, c] = tile
                    free[r, c] = False
                    missing -= 1


def _give_endpoints(result, rules: _Rules) -> None:
    is_blocking = np.isin(result, rules.blocking)
    lonely = np.argwhere(is_blocking & (neighbour_count(np.isin(result, rules.endpoints)) == 0))
    blocking_next = neighbour_count(is_blocking)  # changes only where a boxed-in shelf is removed below
    for r, c in lonely:
        if any(result[cell] in rules.endpoints for cell in _neighbours(r, c, result.shape)):
            continue  # an endpoint given to a neighbouring shelf serves this one too
        spots = [cell for cell in _neighbours(r, c, result.shape) if rules.area[cell] and result[cell] == rules.floor]
        if not spots:
            result[r, c] = rules.floor  # boxed in: the next round's steps put a shelf elsewhere
            blocking_next = neighbour_count(np.isin(result, rules.blocking))
            continue
        # The spot beside the most shelves serves the most of them.
        result[max(spots, key=lambda spot: blocking_next[spot])] = rules.endpoint
    orphans = np.isin(result, rules.endpoints) & (neighbour_count(np.isin(result, rules.blocking)) == 0) & rules.area
    result[orphans] = rules.floor
