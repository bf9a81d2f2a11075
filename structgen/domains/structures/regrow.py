"""Growth that repairs itself: cut members out of a structure an NCA grew and let the same NCA grow on
(:func:`structgen.nca.grow_on`); how much of the original comes back, and whether what regrew stands."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from structgen.nca_config import NCAConfig
from structgen.structure import Structure

__all__ = ["CUTS", "Regrowth", "damage", "member_keys", "regrow"]

#: How members are cut: ``mid``, those nearest the structure's middle height (one cut through it); ``random``, drawn
#: at random anywhere.
CUTS = ("mid", "random")


def member_keys(structure: Structure) -> list[tuple[tuple[int, ...], tuple[int, ...]]]:
    """Each member, in order, as the pair of its ends' lattice points (smaller first): comparable across
    structures."""
    points = [tuple(int(c) for c in v) for v in structure.vertices]
    return [tuple(sorted((points[a], points[b]))) for a, b in structure.edges]  # type: ignore[misc]


def damage(structure: Structure, share: float, cut: str = "mid", seed: int = 0) -> Structure:
    """``structure`` with ``share`` of its members removed (rounded to the nearest count, at least one): by ``cut``
    (:data:`CUTS`); vertices left with no member go too, but the seed (the vertex at the origin) stays."""
    if cut not in CUTS:
        raise ValueError(f"cut must be one of {', '.join(CUTS)}, got {cut!r}")
    from structgen.nca import check_seed  # (growth loads torch; the command line names the cuts without it)

    if not 0 < share <= 1:
        raise ValueError(f"damage must be a share above 0 and at most 1, got {share!r}")
    check_seed(structure)
    edges, vertices = structure.edges, structure.vertices
    count = min(len(edges), max(1, round(share * len(edges))))
    if cut == "mid":
        heights = vertices[edges].mean(axis=1)[:, 2]
        middle = (vertices[:, 2].min() + vertices[:, 2].max()) / 2
        # Nearest the middle first; ties broken by the edge's order, so the cut is the same every time.
        removed = np.lexsort((np.arange(len(edges)), np.abs(heights - middle)))[:count]
    else:
        removed = np.random.default_rng(seed).choice(len(edges), size=count, replace=False)
    kept = np.setdiff1d(np.arange(len(edges)), removed)
    used = np.zeros(len(vertices), dtype=bool)
    used[edges[kept].reshape(-1)] = True
    used |= (vertices == 0).all(axis=1)
    renumber = np.cumsum(used) - 1
    return Structure(vertices[used], renumber[edges[kept]])


@dataclass(frozen=True)
class Regrowth:
    """What :func:`regrow` found: the three structures, the share of the original's members that regrew
    (``restored``), how many members grew that the original lacks (``extra``), and the static analysis's verdict
    on the regrown structure (``stands``)."""

    original: Structure
    damaged: Structure
    regrown: Structure
    restored: float
    extra: int
    stands: bool


def regrow(
    weights: Any, structure: Structure, config: NCAConfig, share: float, cut: str = "mid", seed: int = 0, physics: Any = None
) -> Regrowth:
    """Damage ``structure`` (:func:`damage`), let ``weights`` grow on from what is left, and compare."""
    from physics import PhysicsConfig
    from physics.statics import check_statics
    from structgen.nca import grow_on

    damaged = damage(structure, share, cut, seed)
    regrown = grow_on(weights, damaged, config)
    original, back = set(member_keys(structure)), set(member_keys(regrown))
    restored = len(original & back) / len(original) if original else 1.0
    stands = check_statics(regrown, physics or PhysicsConfig.preset("faithful")).stands
    return Regrowth(structure, damaged, regrown, restored, len(back - original), stands)
