"""Measures of a layout as the original code computes them, and an independent validity check of repaired layouts.

- :func:`shelf_components`: 4-connected groups of shelves (stations, for manufacturing).
- :func:`pattern_entropy`: entropy of the 2x2 tile patterns, base (number of patterns), in [0, 1]; for warehouses
  over the storage area only (81 patterns of ``.@e``), for manufacturing over the whole map (625 of ``.012e``).
- :func:`similarity`: the share of cells the repair left alone (manufacturing: stations weigh 5).
- :func:`violations`: what makes a layout invalid, found by counting and breadth-first search, not by the MILP, so the
  tests can check the repair with it.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy import ndimage

from structgen.domains.layouts.kinds import WAREHOUSE, LayoutKind

__all__ = ["pattern_entropy", "shelf_components", "similarity", "violations"]

_FOUR = ndimage.generate_binary_structure(2, 1)


def shelf_components(tiles: np.ndarray, kind: LayoutKind = WAREHOUSE) -> int:
    """Number of 4-connected groups of shelves (warehouse) or stations (manufacturing)."""
    blocking = kind.blocking_tiles()
    _, count = ndimage.label(np.isin(tiles, blocking), structure=_FOUR)
    return int(count)


def pattern_entropy(tiles: np.ndarray, kind: LayoutKind = WAREHOUSE) -> float:
    """Entropy of the distribution of 2x2 tile patterns over the NCA's tiles, in base (number of patterns).

    The original counts every pattern of its alphabet, zeros included, and normalises by ``log(len(alphabet)**4)``;
    a pattern holding a tile outside the alphabet (a workstation) cannot occur in the area it measures."""
    area = kind.storage(tiles) if kind.name == "warehouse" else np.asarray(tiles)
    n = kind.nca_tiles
    area = np.asarray(area, dtype=np.int64)
    if area.max(initial=0) >= n:
        raise ValueError(f"pattern entropy counts tiles {kind.vocabulary[:n]!r} only; the area holds others")
    codes = ((area[:-1, :-1] * n + area[:-1, 1:]) * n + area[1:, :-1]) * n + area[1:, 1:]
    counts = np.bincount(codes.ravel(), minlength=n**4).astype(np.float64)
    total = counts.sum()
    if total == 0:
        return 0.0
    p = counts[counts > 0] / total
    return max(0.0, float(-(p * np.log(p)).sum() / np.log(n**4)))


def similarity(unrepaired: np.ndarray, repaired: np.ndarray, kind: LayoutKind = WAREHOUSE) -> tuple[int, float]:
    """(Hamming distance, similarity score) between a layout and its repair, over the whole map.

    Warehouse: ``1 - Hamming / cells``. Manufacturing: matching cells count 5 where the unrepaired tile is a station
    and 1 elsewhere, divided by ``5 * cells``, as the original's ``sw=5`` runs."""
    unrepaired, repaired = np.asarray(unrepaired), np.asarray(repaired)
    if unrepaired.shape != repaired.shape:
        raise ValueError(f"layouts differ in shape: {unrepaired.shape} and {repaired.shape}")
    same = unrepaired == repaired
    hamming = int((~same).sum())
    if kind.name == "manufacturing":
        weight = np.where(np.isin(unrepaired, kind.blocking_tiles()), 5.0, 1.0)
        return hamming, float((weight * same).sum() / (5.0 * same.size))
    return hamming, 1.0 - hamming / same.size


def neighbour_count(mask: np.ndarray) -> np.ndarray:
    """How many of each cell's four neighbours are in ``mask``."""
    m = mask.astype(np.int16)
    count = np.zeros_like(m)
    count[1:] += m[:-1]
    count[:-1] += m[1:]
    count[:, 1:] += m[:, :-1]
    count[:, :-1] += m[:, 1:]
    return count


def _reached(passable: np.ndarray, starts: list[tuple[int, int]]) -> np.ndarray:
    """Which cells are reached from ``starts``: passable ones through passable cells, others by being next to one."""
    rows, cols = passable.shape
    seen = np.zeros_like(passable)
    for start in starts:
        seen[start] = True
    queue = deque(starts)
    while queue:
        r, c = queue.popleft()
        for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= nr < rows and 0 <= nc < cols and passable[nr, nc] and not seen[nr, nc]:
                seen[nr, nc] = True
                queue.append((nr, nc))
    touched = seen | (neighbour_count(seen) > 0)
    return np.where(passable, seen, touched)


def violations(
    tiles: np.ndarray,
    kind: LayoutKind,
    *,
    shelves: int | None = None,
    fixed: np.ndarray | None = None,
    agents: int = 0,
) -> list[str]:
    """Every rule the layout breaks, in words; empty if it is valid.

    Warehouse: the shelf count (when given), the fixed workstation columns (``fixed``: the whole map they come from),
    every shelf next to an endpoint and every endpoint next to a shelf, and every floor, endpoint and workstation cell
    reachable from a workstation through floor and endpoints. Manufacturing: at least one station of each kind, at
    least ``agents`` non-station cells, every station next to an endpoint and every endpoint next to a station, every
    non-station cell connected.
    """
    tiles = np.asarray(tiles)
    found: list[str] = []
    code = kind.vocabulary.index
    shelf, starts, lonely_shelf, lonely_endpoint, unreached = _cell_rules(tiles, kind)
    if kind.name == "warehouse":
        if shelves is not None and int(shelf.sum()) != shelves:
            found.append(f"{int(shelf.sum())} shelves, expected {shelves}")
        if fixed is not None:
            border = np.ones(tiles.shape, dtype=bool)
            border[:, WAREHOUSE.border : -WAREHOUSE.border] = False
            changed = int((border & (np.asarray(fixed) != tiles)).sum())
            if changed:
                found.append(f"{changed} cells of the fixed workstation columns changed")
    else:
        for n in range(3):
            if not (tiles == code(str(n))).any():
                found.append(f"no station of kind {n}")
        free = int((~shelf).sum())
        if free < agents:
            found.append(f"{free} cells free of stations, fewer than {agents} agents")
    if lonely_shelf.any():
        found.append(
            f"{int(lonely_shelf.sum())} {'shelves' if kind.name == 'warehouse' else 'stations'} with no endpoint next to them"
        )
    if lonely_endpoint.any():
        found.append(
            f"{int(lonely_endpoint.sum())} endpoints with no {'shelf' if kind.name == 'warehouse' else 'station'} next to them"
        )
    if len(starts) == 0:
        found.append("nowhere to start: no workstation" if kind.name == "warehouse" else "no free cell")
    elif unreached.any():
        found.append(f"{int(unreached.sum())} cells not connected to the rest")
    return found


def broken_cells(tiles: np.ndarray, kind: LayoutKind = WAREHOUSE) -> np.ndarray:
    """The cells that break a rule of their own (a shelf or station with no endpoint beside it, an endpoint with
    none beside it, a cell the workstations' floor does not reach), as a boolean map: where a repair that keeps the
    rest of a layout must make its changes. Counts (the shelf count, one station of each kind) are not cells'."""
    _, _, lonely_shelf, lonely_endpoint, unreached = _cell_rules(np.asarray(tiles), kind)
    return lonely_shelf | lonely_endpoint | unreached


def _cell_rules(tiles: np.ndarray, kind: LayoutKind):
    """``(shelves or stations, cells reachability starts from, shelves with no endpoint beside them, endpoints with
    no shelf beside them, cells that must be reached and are not)``: the rules :func:`violations` words and
    :func:`broken_cells` maps. Warehouse reachability starts at the first workstation, whose flow leaves into every
    free neighbour, and passes floor and endpoints; manufacturing's starts at its first free cell."""
    code = kind.vocabulary.index
    if kind.name == "warehouse":
        shelf, endpoint = tiles == code("@"), tiles == code("e")
        station = np.isin(tiles, [code("w"), code("r"), code("s")])
        passable, starts = ~shelf & ~station, np.argwhere(station)
    elif kind.name == "manufacturing":
        shelf, endpoint = np.isin(tiles, [code(c) for c in "012"]), np.isin(tiles, [code("e"), code("s")])
        passable = ~shelf
        starts = np.argwhere(passable)
    else:
        raise ValueError(f"no validity rules for {kind.name} layouts")
    targets = ~shelf
    lonely_shelf = shelf & (neighbour_count(endpoint) == 0)
    lonely_endpoint = endpoint & (neighbour_count(shelf) == 0)
    if len(starts) == 0:
        return shelf, starts, lonely_shelf, lonely_endpoint, np.zeros_like(shelf)
    start = tuple(int(i) for i in starts[0])
    if kind.name == "warehouse":
        rows, cols = shelf.shape
        free_next = [
            (start[0] + dr, start[1] + dc)
            for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1))
            if 0 <= start[0] + dr < rows and 0 <= start[1] + dc < cols and passable[start[0] + dr, start[1] + dc]
        ]
        unreached = targets.copy() if not free_next else targets & ~_reached(passable, free_next)
    else:
        unreached = targets & ~_reached(passable, [start])
    return shelf, starts, lonely_shelf, lonely_endpoint, unreached
