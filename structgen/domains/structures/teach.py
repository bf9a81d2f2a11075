"""Teach the local NCA to grow a given structure: turn a design into network weights that grow it exactly.

Evolution searches the NCA's weights for structures that score well; this module goes the other way. Given a target
structure and the vertex to grow it from, it plans how growth would reach the target one step at a time, reads off
what every vertex sees and must do at each step, and fits the paper's network (52 inputs, one hidden ReLU layer, 26
outputs) to do exactly that, with a margin so the float32 growth code reproduces it. The weights then grow the target
with :func:`structgen.nca.grow` like any evolved NCA.

The schedule (:func:`growth_schedule`) adds the vertices at graph distance ``t`` from the seed at step ``t``, joined to
the vertices already there; an edge between two vertices that appear in the same step follows one step later, since a
new vertex cannot wish for another one born beside it. The NCA's rule is local and shared, so a schedule can be taught
only if no two vertices (at any steps) see the same neighbourhood while having to do different things
(:func:`local_rules` finds the first such pair and says where). Wishes towards cells outside the growth box are
dropped by growth, so they are free: that is how growth stops at the box's edge without a rule of its own.

A design is teachable when its levels look different from close by; :func:`.tall.find_tallest` searches
level-by-level designs (:func:`.samples.by_level_rules`) for tall ones that are, and teaches them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from structgen.errors import InputError
from structgen.lattice import OFFSETS
from structgen.nca import INIT_SCALE, NCAConfig, _split, grow, grow_population
from structgen.nca_config import N_OUTPUTS, n_params
from structgen.structure import Structure

__all__ = ["TeachError", "TeachResult", "growth_config", "growth_schedule", "local_rules", "teach"]

Cell = tuple[int, int, int]
State = tuple[frozenset[Cell], frozenset[frozenset[Cell]]]
_OFFSETS = [tuple(int(c) for c in row) for row in OFFSETS.tolist()]


class TeachError(InputError):
    """The target cannot be taught to the local NCA: it is not connected, its seed is ambiguous, two vertices would
    need different rules for the same neighbourhood, or the network is too small to hold the rules."""


@dataclass(frozen=True)
class TeachResult:
    """What :func:`teach` made.

    Attributes:
        weights: the flat weight vector (as :func:`structgen.nca.grow` takes it).
        config: the NCA settings to grow it with (growth box and steps fitted to the target).
        grown: the structure the weights grow, the target moved so that its seed is at the origin.
        steps: growth steps from the seed to the finished target (``config.iterations``).
        n_rules: distinct neighbourhoods the network had to learn.
        margin: the smallest distance of any taught output from the firing threshold, in logits.
        fit_steps: optimiser steps the fit took.
    """

    weights: np.ndarray
    config: NCAConfig
    grown: Structure
    steps: int
    n_rules: int
    margin: float
    fit_steps: int


def _cells(points: np.ndarray) -> list[Cell]:
    return [(int(x), int(y), int(z)) for x, y, z in points.tolist()]


def seed_index(structure: Structure, seed_vertex: int | str = "top") -> int:
    """The index of the vertex to grow from: ``"top"`` (the single highest vertex) or an index."""
    if seed_vertex == "top":
        z = structure.vertices[:, 2]
        tops = np.flatnonzero(z == z.max())
        if len(tops) != 1:
            raise TeachError(
                f"the target has {len(tops)} vertices at its top level, so 'top' names no single seed; choose one by "
                f"index (seed_vertex=..., --seed-vertex INDEX), e.g. {int(tops[0])}"
            )
        return int(tops[0])
    if isinstance(seed_vertex, bool) or not isinstance(seed_vertex, (int, np.integer)):
        raise TeachError(f"seed_vertex must be 'top' or a vertex index, got {seed_vertex!r}")
    if not 0 <= seed_vertex < structure.n_vertices:
        raise TeachError(f"seed_vertex {seed_vertex} is not a vertex of the target (it has {structure.n_vertices})")
    return int(seed_vertex)


def growth_schedule(target: Structure, seed_vertex: int | str = "top") -> list[State]:
    """The states growth passes through from the seed alone to ``target``, in cells relative to the seed.

    State ``t`` holds the vertices within graph distance ``t`` of the seed and the target's edges among them, except
    those joining two vertices of distance exactly ``t`` (they come at step ``t + 1``). The last state is the target.
    """
    seed = seed_index(target, seed_vertex)
    if target.n_components != 1:
        raise TeachError(f"growth from one seed makes a connected structure; the target has {target.n_components} pieces")
    cells = _cells(target.vertices - target.vertices[seed])
    neighbours: list[list[int]] = [[] for _ in cells]
    for i, j in target.edges.tolist():
        neighbours[i].append(j)
        neighbours[j].append(i)
    distance = [-1] * len(cells)
    distance[seed] = 0
    frontier = [seed]
    while frontier:
        following = []
        for i in frontier:
            for j in neighbours[i]:
                if distance[j] < 0:
                    distance[j] = distance[i] + 1
                    following.append(j)
        frontier = following
    depth = max(distance)
    states: list[State] = []
    for t in range(depth + 2):
        vertices = frozenset(cells[i] for i in range(len(cells)) if distance[i] <= t)
        edges = frozenset(
            frozenset((cells[i], cells[j]))
            for i, j in target.edges.tolist()
            if max(distance[i], distance[j]) <= t and min(distance[i], distance[j]) < t
        )
        states.append((vertices, edges))
    if len(states) > 1 and states[-1] == states[-2]:
        states.pop()  # no edge joins two vertices of the last distance: the target is reached a step earlier
    return states


def growth_config(states: Sequence[State], *, hidden: int = 60, cutoff: float = 0.5) -> NCAConfig:
    """The NCA settings that grow through ``states``: the smallest growth box around the seed that holds the last
    state, and one iteration per step."""
    extent = max(1, max(max(abs(c) for c in cell) for cell in states[-1][0]))
    return NCAConfig(
        hidden=hidden,
        iterations=len(states) - 1,
        cutoff=cutoff,
        max_extent=extent,
        max_vertices=max(NCAConfig().max_vertices, len(states[-1][0])),
    )


def _within(cell: Cell, box: np.ndarray) -> bool:
    return all(low <= c <= high for c, (low, high) in zip(cell, box.tolist()))


def _in_box(cell: Cell, config: NCAConfig, box: np.ndarray | None = None) -> bool:
    if box is not None and not _within(cell, box):
        return False
    return max(abs(c) for c in cell) <= config.max_extent and (config.build_down or cell[2] >= 0)


def _target_box(box: object, states: Sequence[State]) -> np.ndarray | None:
    """``box`` as growth takes it (offsets from the seed), checked to hold the target."""
    if box is None:
        return None
    array = np.asarray(box)
    if array.shape != (3, 2) or not np.issubdtype(array.dtype, np.integer) or (array[:, 0] > 0).any() or (array[:, 1] < 0).any():
        raise TeachError(f"box must be whole-number [low, high] offsets from the seed per axis, holding the seed; got {box!r}")
    outside = [cell for cell in sorted(states[-1][0]) if not _within(cell, array)]
    if outside:
        raise TeachError(f"the target reaches {outside[0]} (from its seed), outside the growth box {array.tolist()}")
    return array.astype(np.int64)


def local_rules(
    states: Sequence[State], config: NCAConfig, *, fixed_point: bool = True, box: np.ndarray | None = None
) -> dict[tuple[bool, ...], tuple[bool, ...]]:
    """What the NCA must do: for every neighbourhood a vertex sees on the way through ``states`` (52 input flags),
    the 26 wishes it must make (``box``: a growth box within the cube, as :func:`.nca.grow_population` takes one).

    Each step ``t`` to ``t + 1`` is taught; with ``fixed_point`` also that the last state stays as it is, so growing
    longer changes nothing. A wish towards a cell outside the growth box is dropped by growth, so it is free: where
    another vertex with the same neighbourhood needs it (an upper level that keeps growing, say), it is made and
    dropped; otherwise it is not made. Raises :class:`TeachError` naming two vertices that see the same and must
    differ.
    """
    rules: dict[tuple[bool, ...], tuple[tuple[bool, ...], tuple[bool, ...], int, Cell]] = {}
    pairs = list(zip(states[:-1], states[1:], range(len(states) - 1)))
    if fixed_point:
        pairs.append((states[-1], states[-1], len(states) - 1))
    for (vertices, edges), (_, next_edges), step in pairs:
        for cell in sorted(vertices):
            around = [(cell[0] + dx, cell[1] + dy, cell[2] + dz) for dx, dy, dz in _OFFSETS]
            seen = tuple([other in vertices for other in around] + [frozenset((cell, other)) in edges for other in around])
            wish = tuple(frozenset((cell, other)) in next_edges for other in around)
            matters = tuple(_in_box(other, config, box) for other in around)
            if seen in rules:
                known, known_matters, known_step, known_cell = rules[seen]
                clash = [k for k in range(N_OUTPUTS) if matters[k] and known_matters[k] and wish[k] != known[k]]
                if clash:
                    k = clash[0]
                    raise TeachError(
                        f"no local rule grows this target: the vertex at {known_cell} (step {known_step}) and the one "
                        f"at {cell} (step {step}) see the same neighbourhood, but only "
                        f"{known_cell if known[k] else cell} must reach towards {_OFFSETS[k]}"
                    )
                wish = tuple(w if m else kw for w, kw, m in zip(wish, known, matters))
                matters = tuple(a or b for a, b in zip(matters, known_matters))
            rules[seen] = (wish, matters, step, cell)
    return {seen: wish for seen, (wish, _, _, _) in rules.items()}


def _fit(rules: dict, config: NCAConfig, margin: float, seed: int, max_steps: int) -> tuple[np.ndarray, float, int]:
    """Adam on a hinge loss until every taught output clears the threshold by ``margin`` (float64 throughout)."""
    inputs = torch.tensor([list(seen) for seen in rules], dtype=torch.float64)
    sign = torch.tensor([list(wish) for wish in rules.values()], dtype=torch.float64) * 2 - 1
    threshold = math.log(config.cutoff / (1 - config.cutoff))
    generator = torch.Generator().manual_seed(seed)
    # One flat vector in the layout growth reads (structgen.nca._split), so the result needs no repacking.
    flat = ((torch.rand(n_params(config), dtype=torch.float64, generator=generator) * 2 - 1) * INIT_SCALE).requires_grad_()
    optimiser = torch.optim.Adam([flat], lr=0.01)

    def clearance() -> torch.Tensor:
        w1, b1, w2, b2 = _split(flat, config.hidden)
        return sign * (torch.relu(inputs @ w1 + b1) @ w2 + b2 - threshold)

    steps = 0
    while steps < max_steps:
        loss = torch.relu(margin - clearance()).sum()
        if loss.item() == 0:
            break
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        steps += 1
    with torch.no_grad():
        worst = float(clearance().min())
    return flat.detach().numpy(), worst, steps


def teach(
    target: Structure,
    *,
    seed_vertex: int | str = "top",
    hidden: int = 60,
    cutoff: float = 0.5,
    margin: float = 1.0,
    seed: int = 0,
    max_steps: int = 20_000,
    box: object = None,
) -> TeachResult:
    """Weights for the local NCA that grow ``target`` from ``seed_vertex`` and then stay put.

    The growth box is the smallest that holds the target around the seed, and growth needs as many steps as the
    target's farthest vertex is from the seed (one more for edges between the farthest vertices); both are in the
    result's ``config`` (:func:`growth_config`). Raises :class:`TeachError` when no local rule grows the target (see
    :func:`local_rules`) or the network cannot hold the rules within ``max_steps`` (a larger ``hidden`` helps).

    ``box`` (``[[x_low, x_high], [y_low, y_high], [z_low, z_high]]`` offsets from the seed, as
    :func:`structgen.nca.grow_population` takes it) teaches growth within that box rather than the cube: a target
    that fills a box wider than it is tall can then stop at the box's floor and sides alike, since wishes beyond any
    wall are dropped.
    """
    if not (isinstance(margin, (int, float)) and math.isfinite(margin) and margin > 0):
        raise TeachError(f"margin must be a positive number of logits, got {margin!r}")
    states = growth_schedule(target, seed_vertex)
    config = growth_config(states, hidden=hidden, cutoff=cutoff)
    growth_box = _target_box(box, states)
    rules = local_rules(states, config, box=growth_box)
    weights, worst, fit_steps = _fit(rules, config, margin, seed, max_steps)
    if worst < margin * 0.5:
        raise TeachError(
            f"a {hidden}-unit hidden layer did not learn the {len(rules)} rules in {max_steps} steps (an output sits "
            f"{worst:.3g} logits from its threshold); try a larger hidden layer"
        )
    grown = grow(weights, config) if growth_box is None else grow_population(weights[None], config, growth_box)[0]
    vertices, edges = states[-1]
    got = _cells(grown.vertices)
    if set(got) != vertices or {frozenset((got[i], got[j])) for i, j in grown.edges.tolist()} != edges:
        raise AssertionError("the taught weights do not grow the target; every rule cleared its margin, so this is a bug")
    return TeachResult(weights, config, grown, len(states) - 1, len(rules), worst, fit_steps)
