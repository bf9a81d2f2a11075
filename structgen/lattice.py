"""The integer lattice structures live on: the 26-neighbourhood and its fixed ordering.

Every part of structgen that talks about "the k-th neighbour" (the NCA's inputs and outputs, structure validation)
uses the ordering defined here, so it is written down once.

Neighbour ``k`` is the k-th offset ``(dx, dy, dz)`` in ``{-1, 0, 1}^3`` without ``(0, 0, 0)``, in lexicographic
order: ``k = 0`` is ``(-1, -1, -1)``, ``k = 12`` is ``(0, 0, -1)``, ``k = 13`` is ``(0, 0, 1)`` and ``k = 25`` is
``(1, 1, 1)``. The opposite of neighbour ``k`` is ``25 - k``, so the first 13 offsets hold one direction of every
undirected lattice edge.
"""

from __future__ import annotations

import itertools

import numpy as np

#: (26, 3) int64: the neighbour offsets in lexicographic order, origin excluded.
OFFSETS: np.ndarray = np.array([d for d in itertools.product((-1, 0, 1), repeat=3) if d != (0, 0, 0)], dtype=np.int64)
OFFSETS.setflags(write=False)

#: Number of lattice neighbours of a cell.
N_NEIGHBOURS: int = len(OFFSETS)

#: Number of undirected edge directions; offsets ``0 .. N_DIRECTIONS - 1`` are one of each opposite pair.
N_DIRECTIONS: int = N_NEIGHBOURS // 2


def opposite(k: int | np.ndarray) -> int | np.ndarray:
    """Index of the offset pointing the other way (``OFFSETS[opposite(k)] == -OFFSETS[k]``)."""
    return N_NEIGHBOURS - 1 - k


def offset_index(offset: np.ndarray) -> np.ndarray:
    """Neighbour index of each offset in a ``(..., 3)`` array of entries in {-1, 0, 1}, not all zero."""
    offset = np.asarray(offset)
    flat = (offset[..., 0] + 1) * 9 + (offset[..., 1] + 1) * 3 + (offset[..., 2] + 1)
    return np.where(flat > 13, flat - 1, flat)


def are_neighbours(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether integer points ``a`` and ``b`` (``(..., 3)``) are distinct and at most one step apart on every axis."""
    chebyshev = np.abs(np.asarray(a) - np.asarray(b)).max(axis=-1)
    return chebyshev == 1
