"""The patch repair: a valid warehouse that keeps what a growth got right, in milliseconds and without a solver.

The paper repairs every grown layout with the fewest changes (a MILP), so that what the NCA grew, and with it the
archive's measures, survives the repair. HiGHS does that in about a second for layouts near valid but can spend its
whole minute on layouts far from it; the row repair (:func:`~structgen.domains.warehouse.repair.greedy_repair`)
answers those at once but throws the growth's pattern away, so every far layout lands in the same few archive cells
(measured on the even run: 38 cells in 2,000 evaluations). This repair changes cells only where a rule asks:

1. a shelf surplus is removed, first shelves boxed in by others, then shelves with no endpoint, then those in the
   thickest blocks;
2. every pocket of floor the workstations cannot reach gets the shortest way out, through as few shelves as possible
   (one breadth-first search over all pockets at once);
3. a shelf deficit is made up on floor cells whose filling cannot cut any floor off (the free cells around them stay
   joined: a local test that needs no search), first beside endpoints already there, then on the row pattern of the
   row repair, then anywhere;
4. each shelf without an endpoint gets one on a free neighbour (a boxed-in one is removed and step 3 replaces it),
   and endpoints beside no shelf become floor.

The steps repeat until the layout is valid (twice, nearly always). Candidates at each step are taken in a spread
order over the map, not from its top, and everything is deterministic. The answer is not the fewest changes; the
router (:func:`~structgen.domains.warehouse.repair.repair`'s ``greedy_beyond``) takes whichever of this and the row
repair changes fewer cells.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy import ndimage

from structgen.domains.warehouse.layouts import WAREHOUSE
from structgen.domains.warehouse.measures import neighbour_count, violations

__all__ = ["PATCH_ROUNDS", "patch_repair"]

#: How many times the steps may repeat before the repair gives up (the layouts of random NCAs and of a training run
#: are valid after two; a step that undoes another's work would otherwise loop).
PATCH_ROUNDS = 8

_FOUR = ndimage.generate_binary_structure(2, 1)
#: The eight cells around a cell, in order around it, so that consecutive ones are 4-neighbours of each other.
_RING = ((-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1))
_GOLDEN = (np.sqrt(5.0) - 1.0) / 2.0


def patch_repair(tiles: np.ndarray, *, shelves: int, row_offset: int = 0, aisle_every: int = 11) -> np.ndarray | None:
    """A valid warehouse with ``shelves`` shelves that changes ``tiles`` only where a rule asks (module doc), or None
    where the steps do not settle within :data:`PATCH_ROUNDS` rounds. ``row_offset`` and ``aisle_every`` give the
    row pattern preferred for shelves added where the growth has no endpoints (rows ``r % 3 == row_offset``, no
    shelf in every ``aisle_every``-th column of the storage area)."""
    code = WAREHOUSE.vocabulary.index
    floor, shelf, endpoint = code("."), code("@"), code("e")
    tiles = np.asarray(tiles)
    result = tiles.astype(np.int64)
    area = np.zeros(tiles.shape, dtype=bool)
    area[:, WAREHOUSE.border : -WAREHOUSE.border] = True
    station = np.isin(tiles, [code("w"), code("r"), code("s")])
    if not station.any():
        return None
    # Cells beside a workstation stay floor: the workstations reach the map through them.
    addable = area & ~(neighbour_count(station) > 0)
    rows, cols = tiles.shape
    storage_columns = np.flatnonzero(area.any(axis=0))
    row_pattern = np.zeros(tiles.shape, dtype=bool)
    row_pattern[[r for r in range(rows) if r % 3 == row_offset]] = True
    row_pattern[:, storage_columns[np.arange(len(storage_columns)) % aisle_every == aisle_every - 1]] = False
    row_pattern &= area
    for _ in range(PATCH_ROUNDS):
        _remove_surplus(result, area, row_pattern, shelves, floor, shelf, endpoint)
        _open_pockets(result, area, station, floor, shelf)
        _add_shelves(result, addable, row_pattern, shelves, floor, shelf, endpoint)
        _give_endpoints(result, area, floor, shelf, endpoint)
        if not violations(result, WAREHOUSE, shelves=shelves, fixed=tiles):
            return result.astype(tiles.dtype)
    return None


def _spread_order(cells: np.ndarray) -> np.ndarray:
    """``cells`` (row-major) reordered so that any first k of them are spread over the map (a golden-ratio
    sequence over their positions), deterministically."""
    if len(cells) == 0:
        return cells
    return cells[np.argsort((np.arange(len(cells)) * _GOLDEN) % 1.0, kind="stable")]


def _remove_surplus(result, area, row_pattern, shelves, floor, shelf, endpoint) -> None:
    is_shelf = result == shelf
    surplus = int(is_shelf.sum()) - shelves
    if surplus <= 0:
        return
    free_next = neighbour_count(area & ~is_shelf)
    endpoint_next = neighbour_count(result == endpoint)
    shelf_next = neighbour_count(is_shelf)
    # Lower rank goes first: shelves off the row pattern (what is kept of a dense growth then stands in rows, not in
    # a maze that jams: measured), and among those boxed in, then without an endpoint, then the thickest blocks.
    rank = row_pattern * 32 + np.where(free_next == 0, 0, np.where(endpoint_next == 0, 1, 2)) * 8 + (4 - shelf_next)
    candidates = np.argwhere(is_shelf & area)
    removed = 0
    for level in np.unique(rank[tuple(candidates.T)]):
        for r, c in _spread_order(candidates[rank[tuple(candidates.T)] == level]):
            if removed == surplus:
                return
            result[r, c] = floor
            removed += 1


def _open_pockets(result, area, station, floor, shelf) -> None:
    """Give every floor cell the workstations cannot reach a way out through the fewest shelves, all pockets in one
    0-1 breadth-first search from the reached floor."""
    passable = (result != shelf) & ~station
    start = tuple(np.argwhere(station)[0])
    roots = [cell for cell in _neighbours(*start, result.shape) if passable[cell]]
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
            if station[nr, nc]:
                continue
            if result[nr, nc] == shelf and not area[nr, nc]:
                continue
            step = 1 if result[nr, nc] == shelf else 0
            if distance[r, c] + step < distance[nr, nc]:
                distance[nr, nc] = distance[r, c] + step
                previous[nr, nc] = (r, c)
                (queue.appendleft if step == 0 else queue.append)((nr, nc))
    labels, count = ndimage.label(pockets, structure=_FOUR)
    for label in range(1, count + 1):
        cells = np.argwhere(labels == label)
        r, c = cells[np.argmin(distance[tuple(cells.T)])]
        while previous[r, c, 0] >= 0:
            if result[r, c] == shelf:
                result[r, c] = floor
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


def _add_shelves(result, addable, row_pattern, shelves, floor, shelf, endpoint) -> None:
    missing = shelves - int((result == shelf).sum())
    if missing <= 0:
        return
    free = result != shelf
    free &= ~np.isin(result, [WAREHOUSE.vocabulary.index(t) for t in "wrs"])
    candidates = np.argwhere(addable & (result == floor))
    beside_endpoint = (neighbour_count(result == endpoint) > 0)[tuple(candidates.T)]
    on_pattern = row_pattern[tuple(candidates.T)]
    rank = np.where(beside_endpoint, 0, np.where(on_pattern, 1, 2))
    for level in range(3):
        for r, c in _spread_order(candidates[rank == level]):
            if missing == 0:
                return
            if _keeps_floor_joined(free, r, c):
                result[r, c] = shelf
                free[r, c] = False
                missing -= 1


def _give_endpoints(result, area, floor, shelf, endpoint) -> None:
    is_shelf = result == shelf
    lonely = np.argwhere(is_shelf & (neighbour_count(result == endpoint) == 0))
    for r, c in lonely:
        if any(result[cell] == endpoint for cell in _neighbours(r, c, result.shape)):
            continue  # an endpoint given to a neighbouring shelf serves this one too
        spots = [cell for cell in _neighbours(r, c, result.shape) if area[cell] and result[cell] == floor]
        if not spots:
            result[r, c] = floor  # boxed in: the next round's steps put a shelf elsewhere
            continue
        # The spot beside the most shelves serves the most of them.
        shelf_next = neighbour_count(result == shelf)
        best = max(spots, key=lambda spot: shelf_next[spot])
        result[best] = endpoint
    orphans = (result == endpoint) & (neighbour_count(result == shelf) == 0) & area
    result[orphans] = floor
