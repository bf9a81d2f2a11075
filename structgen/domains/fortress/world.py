"""Random worlds and the original's mutation operators, with one seeded numpy generator for every choice.

A world is a :class:`.formats.FortressFile`: its classes (finite-state machines) and its initial entities. The
operators follow the original's code (``entities.py`` makeTree/connectOrphanNodes, ``fortress.py`` makeCharacters,
``evo_utils.py`` mutate_ind); the one quirk that changes results, ``connectOrphanNodes`` giving *every* node a new
incoming edge each time it runs, is :attr:`Variation.orphan_edges`. The original mixes Python's ``random``, numpy's
global generator and seeded generators; here one generator makes every choice, so a run is reproducible and resumes.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from structgen.domains.fortress.engine import HEIGHT, WIDTH, placements
from structgen.domains.fortress.formats import EntityClass, FortressFile

__all__ = [
    "CHARACTERS",
    "Variation",
    "fsm_size_entropy",
    "mutate_world",
    "node_types",
    "random_class",
    "random_world",
    "world_size",
]

#: The 15 classes of the QD experiments.
CHARACTERS = tuple("@$&+;!><XO*^MDS")
_NO_ARGUMENT = ("idle", "move", "die", "clone")
_WITH_ARGUMENT = ("take", "chase", "push", "add", "transform", "move_wall")
_CONDITIONS = ("none", "touch", "step", "within", "nextTo")


@lru_cache(maxsize=8)
def node_types(chars: tuple[str, ...] = CHARACTERS) -> tuple[str, ...]:
    """Every node a class may hold, once each (94 for 15 classes), in the original's order."""
    return _NO_ARGUMENT + tuple(f"{action} {c}" for action in _WITH_ARGUMENT for c in chars)


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


def _pick(rng: np.random.Generator, items):
    return items[int(rng.integers(len(items)))]


def new_condition(rng: np.random.Generator, chars: tuple[str, ...], variation: Variation) -> str:
    name = _pick(rng, _CONDITIONS)
    if name in ("touch", "nextTo"):
        return f"{name} {_pick(rng, chars)}"
    if name == "step":
        return f"step {int(rng.integers(variation.step_range[0], variation.step_range[1] + 1))}"
    if name == "within":
        char = _pick(rng, chars)
        return f"within {char} {int(rng.integers(variation.prox_range[0], variation.prox_range[1] + 1))}"
    return "none"


def _sorted_edges(edges: dict[str, str]) -> dict[str, str]:
    # The original sorts keys as strings: "10-2" comes before "2-0".
    return dict(sorted(edges.items()))


def connect_orphans(entity: EntityClass, rng, chars, variation: Variation) -> None:
    """The original's repair after building or deleting edges, then its sort of the edges."""
    if len(entity.nodes) > 1:
        reached = {dst for src, dst, *_ in entity.edge_list() if src != dst}
        for node in range(len(entity.nodes)):
            if variation.orphan_edges == "every_node" or node not in reached:
                others = [n for n in range(len(entity.nodes)) if n != node]
                entity.edges[f"{_pick(rng, others)}-{node}"] = new_condition(rng, chars, variation)
                reached.add(node)
    entity.edges = _sorted_edges(entity.edges)


def random_class(char: str, extra_nodes: int, rng, chars=CHARACTERS, variation: Variation = Variation()) -> EntityClass:
    """A class as the original's makeTree builds it: ``idle`` and ``extra_nodes`` distinct random node types, twice
    as many random edges (later ones overwrite earlier ones with the same ends), then the orphan repair."""
    available = [t for t in node_types(tuple(chars)) if t != "idle"]
    nodes = ["idle"]
    for _ in range(extra_nodes):
        nodes.append(available.pop(int(rng.integers(len(available)))))
    entity = EntityClass(char, nodes, {})
    for _ in range(2 * extra_nodes):
        a, b = int(rng.integers(extra_nodes + 1)), int(rng.integers(extra_nodes + 1))
        entity.edges[f"{a}-{b}"] = new_condition(rng, chars, variation)
    if extra_nodes > 0:
        connect_orphans(entity, rng, chars, variation)
    return entity


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
    return float(-(share * np.log(share)).sum() / np.log(base))


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
    rng: np.random.Generator,
    chars: tuple[str, ...] = CHARACTERS,
    variation: Variation = Variation(),
    *,
    start: str = "n_nodes",
    entropy_bins: int = 100,
) -> FortressFile:
    """A random world as the original's QD runs draw one: class sizes by ``start`` ("n_nodes": a total number of
    nodes uniform over its range; "entropy": a spread of class sizes uniform over entropy bins), the classes in a
    random order, then 1 to ``max_initial`` entities of random classes on random floor tiles (a placement on a tile
    already taken is dropped)."""
    per_class = len(node_types(tuple(chars)))
    if start == "n_nodes":
        sizes = _sizes_by_total(rng, len(chars), per_class)
    elif start == "entropy":
        sizes = _sizes_by_entropy(rng, len(chars), per_class, entropy_bins)
    else:
        raise ValueError(f"start must be 'n_nodes' or 'entropy', got {start!r}")
    order = list(chars)
    rng.shuffle(order)
    classes = {c: random_class(c, sizes[i], rng, chars, variation) for i, c in enumerate(order)}
    count = int(rng.integers(1, variation.max_initial + 1))
    drawn = []
    for _ in range(count):
        x, y = int(rng.integers(1, WIDTH - 1)), int(rng.integers(1, HEIGHT - 1))
        drawn.append((_pick(rng, order), x, y))
    # Only the placements that succeed are kept, as the original records its initial entities after placing them.
    return FortressFile(classes=classes, initial=placements(drawn), placed_by="pos")


def _harmonic(rng, top: int) -> int:
    """k in 1..top with probability proportional to 1/k (the original's node mutation counts)."""
    weights = 1.0 / np.arange(1, top + 1)
    return int(rng.choice(top, p=weights / weights.sum())) + 1


def _remove_node(entity: EntityClass, index: int) -> None:
    """Delete a node, the edges touching it, and renumber the rest (the original's killOrphanEdges)."""
    del entity.nodes[index]
    edges = {}
    for key, condition in entity.edges.items():
        src, dst = (int(v) for v in key.split("-"))
        if index in (src, dst):
            continue
        edges[f"{src - (src > index)}-{dst - (dst > index)}"] = condition
    entity.edges = edges


def _mutate_edges(world: FortressFile, rng, chars, variation: Variation) -> None:
    kind = int(rng.integers(3))
    entity = world.classes[_pick(rng, list(world.classes))]
    if kind == 0 and len(entity.edges) > 1:
        del entity.edges[_pick(rng, list(entity.edges))]
        connect_orphans(entity, rng, chars, variation)
    elif kind == 1:
        a, b = int(rng.integers(len(entity.nodes))), int(rng.integers(len(entity.nodes)))
        entity.edges[f"{a}-{b}"] = new_condition(rng, chars, variation)
    elif kind == 2 and entity.edges:
        entity.edges[_pick(rng, list(entity.edges))] = new_condition(rng, chars, variation)


def _mutate_nodes(world: FortressFile, rng, chars, variation: Variation) -> None:
    kind = int(rng.integers(3))
    entity = world.classes[_pick(rng, list(world.classes))]
    held = set(entity.nodes)
    available = [t for t in node_types(tuple(chars)) if t not in held]
    if kind == 0 and len(entity.nodes) > 1:
        for _ in range(_harmonic(rng, len(entity.nodes) - 1)):
            _remove_node(entity, int(rng.integers(len(entity.nodes))))
    elif kind == 1 and available:
        for _ in range(_harmonic(rng, len(available))):
            entity.nodes.append(available.pop(int(rng.integers(len(available)))))
            new = len(entity.nodes) - 1
            source = _pick(rng, [n for n in range(len(entity.nodes)) if n != new])
            entity.edges[f"{source}-{new}"] = new_condition(rng, chars, variation)
            entity.edges = _sorted_edges(entity.edges)
    elif kind == 2:
        for _ in range(_harmonic(rng, len(entity.nodes))):
            if available:
                index = int(rng.integers(len(entity.nodes)))
                old = entity.nodes[index]
                entity.nodes[index] = available.pop(int(rng.integers(len(available))))
                available.append(old)
            else:
                i, j = int(rng.integers(len(entity.nodes))), int(rng.integers(len(entity.nodes)))
                entity.nodes[i], entity.nodes[j] = entity.nodes[j], entity.nodes[i]


def _mutate_entities(world: FortressFile, rng, chars) -> None:
    if int(rng.integers(2)) == 0:
        if world.initial:
            del world.initial[int(rng.integers(len(world.initial)))]
    else:
        x, y = int(rng.integers(1, WIDTH - 1)), int(rng.integers(1, HEIGHT - 1))
        world.initial.append((_pick(rng, chars), x, y))


def mutate_world(world: FortressFile, rng: np.random.Generator, variation: Variation = Variation()) -> FortressFile:
    """A mutated copy: edge mutations while a coin comes up, at most one node mutation, then initial-entity
    mutations while a coin comes up (an added entity on a taken tile stays in the list and is dropped when placed,
    as in the original)."""
    world = copy.deepcopy(world)
    world.blocks, world.placed_by = [], "pos"
    chars = tuple(world.classes)
    edge_coin, node_coin, instance_coin = rng.random(3)
    while edge_coin < variation.edge_coin:
        _mutate_edges(world, rng, chars, variation)
        edge_coin = rng.random()
    if node_coin < variation.node_coin:
        _mutate_nodes(world, rng, chars, variation)
    while instance_coin < variation.instance_coin:
        _mutate_entities(world, rng, chars)
        instance_coin = rng.random()
    return world


def world_size(world: FortressFile) -> tuple[int, int]:
    """Total nodes and total edges over the world's classes."""
    return sum(len(e.nodes) for e in world.classes.values()), sum(len(e.edges) for e in world.classes.values())


def fsm_size_entropy(world: FortressFile) -> float:
    """The original's entropy measure: class sizes binned into as many bins as there are classes (over 1 to the
    number of node types), the entropy of how many bins are used how often, in base 'number of classes'."""
    n_classes = len(world.classes)
    per_class = len(node_types(tuple(world.classes)))
    if n_classes < 2:
        return 0.0
    bins = [int((len(e.nodes) - 1 - 1) / (per_class - 1) * (n_classes - 1)) for e in world.classes.values()]
    _, counts = np.unique(bins, return_counts=True)
    return _entropy(counts, n_classes)
