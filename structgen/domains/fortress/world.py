"""Random worlds and the original's mutation operators on array genomes (:mod:`.genome`), with one seeded numpy
generator for every choice.

The operators follow the original's code (``entities.py`` makeTree/connectOrphanNodes, ``fortress.py`` makeCharacters,
``evo_utils.py`` mutate_ind), with a machine's edges kept as its dict would keep them: setting an edge that exists
changes its condition in place, a new one goes to the end, and the repairs sort them as strings (``"10-2"`` before
``"2-0"``). The one quirk that changes results, ``connectOrphanNodes`` giving *every* node a new incoming edge each
time it runs, is :attr:`Variation.orphan_edges`. The original mixes Python's ``random``, numpy's global generator
and seeded generators; here one generator makes every choice (many at a time, as arrays), so a run is reproducible
and resumes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from structgen.domains.fortress.engine import HEIGHT, WIDTH, placements
from structgen.domains.fortress.genome import (
    CHARACTERS,
    COND,
    CONDITION_NAMES,
    DST,
    SRC,
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
    "node_types",
    "random_class",
    "random_classes",
    "random_world",
    "remove_node",
    "world_size",
]

_STEP, _WITHIN = CONDITION_NAMES.index("step"), CONDITION_NAMES.index("within")
_TAKES_CLASS = np.isin(CONDITION_NAMES, ("touch", "nextTo", "within"))
_KEYS = 128


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


def new_conditions(rng: np.random.Generator, count: int, variation: Variation) -> np.ndarray:
    """``(count, 3)``: random conditions as (condition, class argument, number), each condition equally likely, its
    class uniform over the 15 and its number uniform over its range."""
    cond = rng.integers(len(CONDITION_NAMES), size=count)
    char = rng.integers(len(CHARACTERS), size=count)
    step = rng.integers(variation.step_range[0], variation.step_range[1] + 1, size=count)
    prox = rng.integers(variation.prox_range[0], variation.prox_range[1] + 1, size=count)
    char = np.where(_TAKES_CLASS[cond], char, -1)
    number = np.where(cond == _STEP, step, np.where(cond == _WITHIN, prox, 0))
    return np.stack([cond, char, number], axis=1).astype(np.int16)


def _assign(old_keys: np.ndarray, edges: np.ndarray, new_keys: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Dict assignment of ``rows`` (full edge rows) under distinct ``new_keys`` into ``edges`` keyed ``old_keys``: an
    edge that exists keeps its place and takes the new condition, the others are appended in order. Also returns
    which of the new keys were there already."""
    sorter = np.argsort(old_keys, kind="stable")
    at = np.searchsorted(old_keys[sorter], new_keys)
    found = at < len(old_keys)
    found[found] = old_keys[sorter[at[found]]] == new_keys[found]
    result = edges.copy()
    result[sorter[at[found]], COND:] = rows[found, COND:]
    return np.concatenate([result, rows[~found]]).astype(np.int16), found


def _edge_rows(src: np.ndarray, dst: np.ndarray, conditions: np.ndarray) -> np.ndarray:
    return np.concatenate([np.stack([src, dst], axis=1), conditions], axis=1).astype(np.int16)


def set_edges(edges: np.ndarray, src: np.ndarray, dst: np.ndarray, conditions: np.ndarray) -> np.ndarray:
    """The edges after ``edges["src-dst"] = condition`` for each new edge in order (their keys distinct)."""
    old = edges[:, SRC].astype(np.int64) * _KEYS + edges[:, DST]
    new = np.asarray(src, dtype=np.int64) * _KEYS + np.asarray(dst, dtype=np.int64)
    return _assign(old, edges, new, _edge_rows(src, dst, conditions))[0]


def _sorted_edges(edges: np.ndarray) -> np.ndarray:
    # The original sorts keys as strings: "10-2" comes before "2-0".
    return edges[np.argsort(edge_order_rank()[edges[:, SRC], edges[:, DST]], kind="stable")]


def _repair(
    owner: np.ndarray, edges: np.ndarray, n_nodes: np.ndarray, rng: np.random.Generator, variation: Variation
) -> tuple[np.ndarray, np.ndarray]:
    """connectOrphanNodes on several classes at once: ``edges[i]`` belongs to class ``owner[i]`` of ``n_nodes``
    nodes; returns the repaired edges of every class, grouped by class and sorted as the original sorts them."""
    classes = np.flatnonzero(n_nodes > 1)
    target_owner = np.repeat(classes, n_nodes[classes])
    targets = np.arange(len(target_owner)) - np.repeat(np.cumsum(n_nodes[classes]) - n_nodes[classes], n_nodes[classes])
    if variation.orphan_edges == "orphans_only":
        moving = edges[:, SRC] != edges[:, DST]
        reached = owner[moving].astype(np.int64) * _KEYS + edges[moving, DST]
        keep = ~np.isin(target_owner * _KEYS + targets, reached)
        target_owner, targets = target_owner[keep], targets[keep]
    # A source among the class's other nodes, uniformly.
    sources = (rng.random(len(targets)) * (n_nodes[target_owner] - 1)).astype(np.int64)
    sources += sources >= targets
    span = _KEYS * _KEYS
    old = owner.astype(np.int64) * span + edges[:, SRC].astype(np.int64) * _KEYS + edges[:, DST]
    new = target_owner * span + sources * _KEYS + targets
    edges, found = _assign(old, edges, new, _edge_rows(sources, targets, new_conditions(rng, len(targets), variation)))
    owner = np.concatenate([owner, target_owner[~found]])
    order = np.lexsort((edge_order_rank()[edges[:, SRC], edges[:, DST]], owner))
    return owner[order], edges[order]


def connect_orphans(n_nodes: int, edges: np.ndarray, rng: np.random.Generator, variation: Variation) -> np.ndarray:
    """The original's repair after building or deleting edges, then its sort of the edges."""
    return _repair(np.zeros(len(edges), dtype=np.int64), edges, np.array([n_nodes]), rng, variation)[1]


def random_classes(
    chars: np.ndarray, extra_nodes: np.ndarray, rng: np.random.Generator, variation: Variation = Variation()
) -> tuple[ClassArrays, ...]:
    """Classes as the original's makeTree builds them (all drawn at once): ``idle`` and ``extra_nodes[k]`` distinct
    random node types, twice as many random edges (a later one overwrites an earlier one with the same ends), then
    the orphan repair."""
    extra = np.asarray(extra_nodes, dtype=np.int64)
    n_types = len(node_types(CHARACTERS))
    # Distinct types for each class: the first ones of a random order of the 93 beyond idle.
    shuffled = 1 + np.argsort(rng.random((len(extra), n_types - 1)), axis=1)
    owner = np.repeat(np.arange(len(extra)), 2 * extra)
    ends = (rng.random((len(owner), 2)) * (extra[owner] + 1)[:, None]).astype(np.int64)
    conditions = new_conditions(rng, len(owner), variation)
    keys = owner * _KEYS * _KEYS + ends[:, 0] * _KEYS + ends[:, 1]
    # The last edge written under each key wins (the repair's sort settles the order).
    last = len(keys) - 1 - np.unique(keys[::-1], return_index=True)[1]
    owner, edges = _repair(owner[last], _edge_rows(ends[last, 0], ends[last, 1], conditions[last]), extra + 1, rng, variation)
    bounds = np.searchsorted(owner, np.arange(len(extra) + 1))
    return tuple(
        ClassArrays(int(c), np.concatenate([[0], shuffled[k, : extra[k]]]), edges[bounds[k] : bounds[k + 1]])
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


def _harmonic(rng, top: int) -> int:
    """k in 1..top with probability proportional to 1/k (the original's node mutation counts)."""
    weights = 1.0 / np.arange(1, top + 1)
    return int(rng.choice(top, p=weights / weights.sum())) + 1


def remove_node(nodes: np.ndarray, edges: np.ndarray, index: int) -> tuple[np.ndarray, np.ndarray]:
    """Delete a node, the edges touching it, and renumber the rest (the original's killOrphanEdges)."""
    keep = (edges[:, SRC] != index) & (edges[:, DST] != index)
    edges = edges[keep].copy()
    edges[:, SRC] -= edges[:, SRC] > index
    edges[:, DST] -= edges[:, DST] > index
    return np.delete(nodes, index), edges


def _mutate_edges(world: Genome, rng, variation: Variation) -> Genome:
    kind = int(rng.integers(3))
    position = int(rng.integers(len(world.classes)))
    entity = world.classes[position]
    nodes, edges = entity.nodes, entity.edges
    if kind == 0 and len(edges) > 1:
        edges = connect_orphans(len(nodes), np.delete(edges, int(rng.integers(len(edges))), axis=0), rng, variation)
    elif kind == 1:
        ends = rng.integers(len(nodes), size=2)
        edges = set_edges(edges, ends[:1], ends[1:], new_conditions(rng, 1, variation))
    elif kind == 2 and len(edges):
        edges = edges.copy()
        edges[int(rng.integers(len(edges))), COND:] = new_conditions(rng, 1, variation)[0]
    else:
        return world
    return world.replace(position, ClassArrays(entity.char, nodes, edges))


def _mutate_nodes(world: Genome, rng, variation: Variation) -> Genome:
    kind = int(rng.integers(3))
    position = int(rng.integers(len(world.classes)))
    entity = world.classes[position]
    nodes, edges = entity.nodes.copy(), entity.edges
    available = np.setdiff1d(np.arange(len(node_types(CHARACTERS))), nodes).tolist()
    if kind == 0 and len(nodes) > 1:
        for _ in range(_harmonic(rng, len(nodes) - 1)):
            nodes, edges = remove_node(nodes, edges, int(rng.integers(len(nodes))))
    elif kind == 1 and available:
        count = _harmonic(rng, len(available))
        added = [available.pop(int(rng.integers(len(available)))) for _ in range(count)]
        new = np.arange(len(nodes), len(nodes) + count)
        # Each new node is wired in from a node before it (the nodes there already, or one added earlier).
        sources = (rng.random(count) * new).astype(np.int64)
        nodes = np.concatenate([nodes, np.array(added, dtype=np.int8)])
        edges = _sorted_edges(set_edges(edges, sources, new, new_conditions(rng, count, variation)))
    elif kind == 2:
        for _ in range(_harmonic(rng, len(nodes))):
            if available:
                index = int(rng.integers(len(nodes)))
                old = int(nodes[index])
                nodes[index] = available.pop(int(rng.integers(len(available))))
                available.append(old)
            else:
                i, j = rng.integers(len(nodes), size=2)
                nodes[[i, j]] = nodes[[j, i]]
    else:
        return world
    return world.replace(position, ClassArrays(entity.char, nodes, edges))


def _mutate_entities(world: Genome, rng) -> Genome:
    initial = world.initial
    if int(rng.integers(2)) == 0:
        if len(initial):
            initial = np.delete(initial, int(rng.integers(len(initial))), axis=0)
    else:
        char = world.classes[int(rng.integers(len(world.classes)))].char
        x, y = int(rng.integers(1, WIDTH - 1)), int(rng.integers(1, HEIGHT - 1))
        initial = np.concatenate([initial, np.array([[char, x, y]], dtype=np.int16)])
    return Genome(world.classes, initial)


def mutate_world(world: Genome, rng: np.random.Generator, variation: Variation = Variation()) -> Genome:
    """A mutated world (the parent is left as it was; unchanged classes are shared): edge mutations while a coin
    comes up, at most one node mutation, then initial-entity mutations while a coin comes up (an added entity on a
    taken tile stays in the list and is dropped when placed, as in the original)."""
    edge_coin, node_coin, instance_coin = rng.random(3)
    while edge_coin < variation.edge_coin:
        world = _mutate_edges(world, rng, variation)
        edge_coin = rng.random()
    if node_coin < variation.node_coin:
        world = _mutate_nodes(world, rng, variation)
    while instance_coin < variation.instance_coin:
        world = _mutate_entities(world, rng)
        instance_coin = rng.random()
    return world


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
