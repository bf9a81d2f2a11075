"""Random worlds and the original's mutation operators on array genomes (:mod:`.genome`), with one seeded numpy
generator for every choice.

The operators follow the original's code (``entities.py`` makeTree/connectOrphanNodes, ``fortress.py`` makeCharacters,
``evo_utils.py`` mutate_ind), with a machine's edges kept as its dict would keep them: setting an edge that exists
changes its condition in place, a new one goes to the end, and the repairs sort them as strings (``"10-2"`` before
``"2-0"``). The one quirk that changes results, ``connectOrphanNodes`` giving *every* node a new incoming edge each
time it runs, is :attr:`Variation.orphan_edges`. The original mixes Python's ``random``, numpy's global generator
and seeded generators; here one generator makes every choice, in compiled code (:mod:`._mutation`) that draws what
numpy code would, so a run is reproducible and resumes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from structgen.domains.fortress import _mutation
from structgen.domains.fortress.engine import HEIGHT, WIDTH, placements
from structgen.domains.fortress.genome import (
    CHARACTERS,
    ClassArrays,
    Genome,
    edge_order_rank,
    node_types,
)

__all__ = [
    "CHARACTERS",
    "Variation",
    "connect_orphans",
    "fsm_size_entropy",
    "mutate_world",
    "mutate_worlds",
    "node_types",
    "random_class",
    "random_classes",
    "random_world",
    "remove_node",
    "world_size",
]


@dataclass(frozen=True)
class Variation:
    """How random worlds are drawn and mutated (the original's configuration).

    Attributes:
        orphan_edges: "every_node" (the original: each repair gives every node one more incoming edge) or
            "orphans_only" (what its name says: only nodes no other node leads to get one).
        step_range, prox_range: bounds of ``step k`` and ``within c r`` (both [1, 10]).
        edge_coin, node_coin, instance_coin: mutation coins (0.5 each); edge and instance mutations repeat while
            their coin comes up, the node mutation happens at most once.
        max_initial: the most initial entities of a random world (30: a quarter of the 15 x 8 map).
    """

    orphan_edges: str = "every_node"
    step_range: tuple[int, int] = (1, 10)
    prox_range: tuple[int, int] = (1, 10)
    edge_coin: float = 0.5
    node_coin: float = 0.5
    instance_coin: float = 0.5
    max_initial: int = 30

    def __post_init__(self) -> None:
        if self.orphan_edges not in ("every_node", "orphans_only"):
            raise ValueError(f"orphan_edges must be 'every_node' or 'orphans_only', got {self.orphan_edges!r}")
        for name in ("step_range", "prox_range"):
            low, high = getattr(self, name)
            if not 1 <= low <= high:
                raise ValueError(f"{name} must be [low, high] with 1 <= low <= high, got {[low, high]}")
        for name in ("edge_coin", "node_coin", "instance_coin"):
            if not 0 <= getattr(self, name) < 1:
                raise ValueError(f"{name} must be in [0, 1), got {getattr(self, name)!r}")


def _ranges(variation: Variation) -> tuple[int, int, int, int]:
    return (*variation.step_range, *variation.prox_range)


def _settings(variation: Variation) -> np.ndarray:
    """The variation as :func:`._mutation.mutate` reads it."""
    orphans_only = float(variation.orphan_edges == "orphans_only")
    coins = (variation.edge_coin, variation.node_coin, variation.instance_coin)
    return np.array([orphans_only, *coins, *_ranges(variation)], dtype=np.float64)


@lru_cache(maxsize=1)
def _harmonic_cdf() -> np.ndarray:
    """``cdf[top, :top]``: the table ``rng.choice(top, p=weights)`` searches for weights proportional to 1/k, built
    as numpy builds it (the original's node mutation counts)."""
    n_types = len(node_types(CHARACTERS))
    table = np.ones((n_types + 1, n_types), dtype=np.float64)
    for top in range(1, n_types + 1):
        weights = 1.0 / np.arange(1, top + 1)
        cdf = (weights / weights.sum()).cumsum()
        table[top, :top] = cdf / cdf[-1]
    return table


def set_edges(edges: np.ndarray, src: np.ndarray, dst: np.ndarray, conditions: np.ndarray) -> np.ndarray:
    """The edges after ``edges["src-dst"] = condition`` for each new edge in order (their keys distinct)."""
    rows = np.column_stack([src, dst, conditions]).astype(np.int64).reshape(-1, 5)
    owner = np.zeros(len(edges), dtype=np.int64)
    return _mutation.assign(owner, edges.astype(np.int64), np.zeros(len(rows), dtype=np.int64), rows)[1].astype(np.int16)


def connect_orphans(n_nodes: int, edges: np.ndarray, rng: np.random.Generator, variation: Variation) -> np.ndarray:
    """The original's repair after building or deleting edges, then its sort of the edges: every node (or, with
    ``orphans_only``, every node nothing else leads to) gets an incoming edge from another node."""
    owner = np.zeros(len(edges), dtype=np.int64)
    repaired = _mutation.repair(
        owner, edges.astype(np.int64).reshape(-1, 5), np.array([n_nodes], dtype=np.int64), rng,
        variation.orphan_edges == "orphans_only", *_ranges(variation), edge_order_rank(),
    )  # fmt: skip
    return repaired[1].astype(np.int16)


def random_classes(
    chars: np.ndarray, extra_nodes: np.ndarray, rng: np.random.Generator, variation: Variation = Variation()
) -> tuple[ClassArrays, ...]:
    """Classes as the original's makeTree builds them (all drawn at once): ``idle`` and ``extra_nodes[k]`` distinct
    random node types, twice as many random edges (a later one overwrites an earlier one with the same ends), then
    the orphan repair."""
    nodes, node_off, edges, edge_off = _mutation.random_classes(
        rng, np.asarray(extra_nodes, dtype=np.int64), len(node_types(CHARACTERS)), variation.orphan_edges == "orphans_only",
        *_ranges(variation), edge_order_rank(),
    )  # fmt: skip
    return tuple(
        ClassArrays(int(c), nodes[node_off[k] : node_off[k + 1]], edges[edge_off[k] : edge_off[k + 1]])
        for k, c in enumerate(chars)
    )


def random_class(char: int, extra_nodes: int, rng: np.random.Generator, variation: Variation = Variation()) -> ClassArrays:
    """One class as :func:`random_classes` draws them."""
    return random_classes(np.array([char]), np.array([extra_nodes]), rng, variation)[0]


def _sizes_by_total(rng, n_classes: int, per_class: int) -> list[int]:
    """The original's 'n_nodes' start: a total drawn uniformly, split multinomially, each class capped (overflow
    moved to classes with room, in order)."""
    total = int(rng.integers(0, per_class * n_classes - n_classes))
    sizes = rng.multinomial(total, [1 / n_classes] * n_classes)
    cap = per_class - 1
    for k in np.flatnonzero(sizes > cap):
        over = sizes[k] - cap
        sizes[k] = cap
        for j in np.flatnonzero(sizes < cap):
            room = cap - sizes[j]
            moved = min(room, over)
            sizes[j] += moved
            over -= moved
            if over == 0:
                break
    return [int(s) for s in sizes]


def _entropy(counts: np.ndarray, base: int) -> float:
    """Shannon entropy of a histogram, in base ``base`` (the number of classes, as the original's measure)."""
    share = counts[counts > 0] / counts.sum()
    return max(0.0, float(-(share * np.log(share)).sum() / np.log(base)))  # one bin: 0, not -0


@lru_cache(maxsize=4)
def _entropy_table(n_classes: int, n_bins: int) -> dict[int, list[tuple[int, ...]]]:
    """Every way to spread ``n_classes`` classes over as many size bins (as counts, sorted), grouped by the binned
    entropy of that spread: the original's gen_entropy_dict."""

    def partitions(parts: int, total: int, smallest: int = 0):
        if parts == 1:
            if total >= smallest:
                yield (total,)
            return
        for first in range(smallest, total // parts + 1):
            for rest in partitions(parts - 1, total - first, first):
                yield (first, *rest)

    table: dict[int, list[tuple[int, ...]]] = {}
    for spread in partitions(n_classes, n_classes):
        value = _entropy(np.asarray(spread), n_classes)
        table.setdefault(int(value * (n_bins - 1)), []).append(spread)
    return table


def _pick(rng: np.random.Generator, items):
    return items[int(rng.integers(len(items)))]


def _sizes_by_entropy(rng, n_classes: int, per_class: int, n_bins: int) -> list[int]:
    """The original's 'entropy' start: a random entropy bin, a spread of classes over size bins in it, then sizes
    drawn within each class's size bin."""
    table = _entropy_table(n_classes, n_bins)
    spreads = table[_pick(rng, sorted(table))]
    spread = np.array(_pick(rng, spreads))
    rng.shuffle(spread)
    bounds = np.linspace(0, per_class, n_classes + 1).astype(int)
    sizes = []
    size_bin = int(np.flatnonzero(spread > 0)[0])
    for _ in range(n_classes):
        drawn = int(rng.integers(bounds[size_bin], max(bounds[size_bin + 1], bounds[size_bin] + 1)))
        sizes.append(min(max(drawn, 1), per_class - 1))
        spread[size_bin] -= 1
        while size_bin < n_classes and spread[size_bin] == 0:
            size_bin += 1
        if size_bin == n_classes:
            break
    return sizes + [0] * (n_classes - len(sizes))


def random_world(
    rng: np.random.Generator, variation: Variation = Variation(), *, start: str = "n_nodes", entropy_bins: int = 100
) -> Genome:
    """A random world as the original's QD runs draw one: class sizes by ``start`` ("n_nodes": a total number of
    nodes uniform over its range; "entropy": a spread of class sizes uniform over entropy bins), the classes in a
    random order, then 1 to ``max_initial`` entities of random classes on random floor tiles (a placement on a tile
    already taken is dropped)."""
    n_classes, per_class = len(CHARACTERS), len(node_types(CHARACTERS))
    if start == "n_nodes":
        sizes = _sizes_by_total(rng, n_classes, per_class)
    elif start == "entropy":
        sizes = _sizes_by_entropy(rng, n_classes, per_class, entropy_bins)
    else:
        raise ValueError(f"start must be 'n_nodes' or 'entropy', got {start!r}")
    order = rng.permutation(n_classes)
    classes = random_classes(order, np.array(sizes), rng, variation)
    count = int(rng.integers(1, variation.max_initial + 1))
    drawn = np.stack(
        [
            order[rng.integers(n_classes, size=count)],
            rng.integers(1, WIDTH - 1, size=count),
            rng.integers(1, HEIGHT - 1, size=count),
        ],
        axis=1,
    )
    # Only the placements that succeed are kept, as the original records its initial entities after placing them.
    return Genome(classes, np.array(placements(drawn.tolist()), dtype=np.int16).reshape(-1, 3))


def remove_node(nodes: np.ndarray, edges: np.ndarray, index: int) -> tuple[np.ndarray, np.ndarray]:
    """Delete a node, the edges touching it, and renumber the rest (the original's killOrphanEdges)."""
    kept_nodes, kept_edges = _mutation.remove_node(nodes.astype(np.int64), edges.astype(np.int64).reshape(-1, 5), index)
    return kept_nodes.astype(nodes.dtype), kept_edges.astype(edges.dtype)


def mutate_world(world: Genome, rng: np.random.Generator, variation: Variation = Variation()) -> Genome:
    """A mutated world (the parent is left as it was; unchanged classes are shared), the original's operators:

    - edge mutations while a coin comes up, each on a random class: delete a random edge (then the orphan repair),
      set a random edge ``src-dst`` to a random condition, or give a random edge a new condition;
    - at most one node mutation on a random class: delete k random nodes with their edges, add k new node types
      each wired in from a node before it (then the edges are sorted), or replace k nodes by types the class lacks
      (swap two of its nodes when it has them all), k drawn with weights 1/k;
    - initial-entity mutations while a coin comes up: delete a random one, or add one of a random class on a random
      floor tile (on a taken tile it stays in the list and is dropped when placed, as in the original).

    Compiled (:func:`._mutation.mutate`), with the same draws as numpy code."""
    return mutate_worlds([world], rng, variation)[0]


def mutate_worlds(worlds: list[Genome], rng: np.random.Generator, variation: Variation = Variation()) -> list[Genome]:
    """:func:`mutate_world` on each world in turn, in one compiled call (the same draws and mutants)."""
    if not worlds:
        return []
    if any(not world.classes for world in worlds):
        raise ValueError("a world needs at least one class to be mutated")
    classes = [c for world in worlds for c in world.classes]
    counts = [len(world.classes) for world in worlds]
    initial = [world.initial for world in worlds]
    nodes, node_off, edges, edge_off, changed, out_initial, initial_off, touched = _mutation.mutate_many(
        rng,
        np.concatenate([c.nodes for c in classes]).astype(np.int64),
        np.concatenate([[0], np.cumsum([len(c.nodes) for c in classes], dtype=np.int64)]),
        np.concatenate([c.edges for c in classes]).astype(np.int64),
        np.concatenate([[0], np.cumsum([len(c.edges) for c in classes], dtype=np.int64)]),
        np.concatenate([[0], np.cumsum(counts, dtype=np.int64)]),
        np.array([c.char for c in classes], dtype=np.int64),
        np.concatenate(initial).astype(np.int64).reshape(-1, 3),
        np.concatenate([[0], np.cumsum([len(i) for i in initial], dtype=np.int64)]),
        _settings(variation), len(node_types(CHARACTERS)), edge_order_rank(), _harmonic_cdf(), WIDTH, HEIGHT,
    )  # fmt: skip
    mutants, k = [], 0
    for w, world in enumerate(worlds):
        first = k
        k += len(world.classes)
        if not changed[first:k].any() and not touched[w]:
            mutants.append(world)
            continue
        replaced = tuple(
            ClassArrays(c.char, nodes[node_off[i] : node_off[i + 1]], edges[edge_off[i] : edge_off[i + 1]]) if changed[i] else c
            for i, c in enumerate(world.classes, start=first)
        )
        mutants.append(Genome(replaced, out_initial[initial_off[w] : initial_off[w + 1]] if touched[w] else world.initial))
    return mutants


def world_size(world: Genome) -> tuple[int, int]:
    """Total nodes and total edges over the world's classes."""
    return world.size()


def fsm_size_entropy(world: Genome) -> float:
    """The original's entropy measure: class sizes binned into as many bins as there are classes (over 1 to the
    number of node types), the entropy of how many bins are used how often, in base 'number of classes'."""
    n_classes = len(world.classes)
    per_class = len(node_types(CHARACTERS))
    if n_classes < 2:
        return 0.0
    sizes = np.array([len(c.nodes) for c in world.classes])
    bins = np.trunc((sizes - 2) / (per_class - 1) * (n_classes - 1)).astype(np.int64)
    _, counts = np.unique(bins, return_counts=True)
    return _entropy(counts, n_classes)


def compile_kernels() -> None:
    """Compile every numba function of the domain (or load it from numba's cache in ``__pycache__``) by drawing,
    mutating and simulating one small world: the first use after an install otherwise spends about a minute here.
    ``make install`` calls it."""
    from structgen.domains.fortress.engine import simulate

    rng = np.random.default_rng(0)
    world = random_world(rng, start="entropy")
    mutants = mutate_worlds([world, world], rng)
    connect_orphans(3, np.zeros((0, 5), dtype=np.int16), rng, Variation())
    simulate([world, *mutants], [0], 2)
