"""The fortress engine: many worlds, each run under many seeds, stepped together by a compiled kernel.

Semantics (the original's code, which differs from its paper's prose in places):

- The fortress is 15 x 8 tiles, floor inside a one-tile wall border (78 floor tiles); any number of entities may share
  a tile. A simulation stops before a tick when no entity is left, or when more than 156 (twice the floor) are, or
  after its number of ticks. The original's inactivity stop never fires (its log check cannot match), so there is
  none unless ``Rules.inactivity_limit`` asks for one.
- Initial entities are placed in order; one whose tile is already taken is dropped (positions are not checked
  against walls, as in the original).
- In a tick, the entities alive at its start act one at a time in creation order; one removed earlier in the tick
  is skipped, newborns act from the next tick, and every read (positions, who is alive) sees the changes already made.
- An entity's update: its age grows by one; it performs the action of its current node; then, of the edges out of
  that node, the first whose condition holds (touch > nextTo > within > step > none, ties in file order) moves it to
  the edge's node. This happens even when the action killed it. Its class's visit flags then record the node it is
  on and the edge it took, if any (so a class's start node counts only once an entity is on it after an update).
- Actions: ``idle``; ``move`` one random step (of [0,1],[0,-1],[1,0],[-1,0]) onto floor, through entities;
  ``move_wall c`` the same unless the first-created entity on the target tile is of class c; ``chase c`` one step
  towards the nearest other c (Manhattan, earliest created on ties), a random one of the needed directions;
  ``push c``: a random direction; if the nearest c is on that tile and the tile beyond is floor, both move,
  otherwise the entity moves if it can; ``take c`` removes the nearest other c anywhere on the map; ``die``;
  ``clone`` / ``add c`` place a new own-class / c entity on a random neighbouring floor tile if no entity is there
  (one try); ``transform c`` places a c on its own tile (occupied or not) and dies.
- Conditions: ``step k`` when the entity's age is a multiple of k; ``touch c`` another c on the same tile; ``within c
  r`` another c at Chebyshev distance at most r (same tile included); ``nextTo c`` is ``within c 1``; ``none``.
- Randomness: each simulation has one numpy ``default_rng(seed)`` stream; move, move_wall, push (when it has a
  target), clone and add each take one choice of 4, a chase that needs two directions one choice of 2, and nothing
  else draws. Every number of a simulation is a function of its world and its seed.

Settings that change these rules (:class:`Rules`) reproduce what the paper describes where the code differs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np

from structgen.budget import check_memory
from structgen.domains.fortress.formats import ACTIONS, CONDITIONS, EntityClass, FortressFile
from structgen.domains.fortress.genome import CHARACTERS, TYPE_ACTION, TYPE_CHAR, Genome
from structgen.errors import InputError

__all__ = [
    "CAUSES",
    "HEIGHT",
    "POPULATION_CAP",
    "RULES",
    "WIDTH",
    "Outcome",
    "Rules",
    "Trace",
    "compile_worlds",
    "placements",
    "simulate",
]

WIDTH, HEIGHT = 15, 8
#: The original's population cap: twice the floor tiles.
POPULATION_CAP = (WIDTH - 2) * (HEIGHT - 2) * 2
#: Why a simulation stopped, by the kernel's code.
CAUSES = ("running", "steps", "extinct", "overpopulated", "inactive")
_ACTION_CODES = {name: code for code, name in enumerate(ACTIONS)}
_CONDITION_CODES = {name: priority for name, (priority, _) in CONDITIONS.items()}
# Entity slots: at most the cap act in a tick, and each adds at most one newborn.
_SLOTS = 2 * POPULATION_CAP + 8


@dataclass(frozen=True)
class Rules:
    """Where the engine may depart from the original's code (the defaults reproduce it).

    Attributes:
        next_to: "chebyshev" (the code: the 8 neighbours and the same tile) or "orthogonal" (the paper: north,
            south, east or west).
        take_reach: None (the code: ``take`` removes the nearest target anywhere on the map) or a Chebyshev distance
            the target must be within.
        wall_blocks: "first" (the code: ``move_wall c`` is blocked only when the first-created entity on the tile is
            a c) or "any" (by any c there).
        inactivity_limit: 0 (the code: its inactivity stop never fires) or stop once this many ticks pass with no
            event the original would log (a move, birth, death, take, push, failed clone or blocked move).
        visit_start_nodes: False (the code: node 0 counts as visited only when an entity is on it after an update)
            or True (every class with an initial entity has visited its start node).
        population_cap: a simulation stops when more entities than this are alive (the code: 156, twice the floor
            tiles; the first paper says the map's w x h, 120); at most 156.

    :data:`RULES` names the rules of the code and of each paper.
    """

    next_to: str = "chebyshev"
    take_reach: int | None = None
    wall_blocks: str = "first"
    inactivity_limit: int = 0
    visit_start_nodes: bool = False
    population_cap: int = POPULATION_CAP

    def __post_init__(self) -> None:
        if self.next_to not in ("chebyshev", "orthogonal"):
            raise ValueError(f"next_to must be 'chebyshev' or 'orthogonal', got {self.next_to!r}")
        if self.take_reach is not None and (not isinstance(self.take_reach, int) or self.take_reach < 0):
            raise ValueError(f"take_reach must be None or a whole number >= 0, got {self.take_reach!r}")
        if self.wall_blocks not in ("first", "any"):
            raise ValueError(f"wall_blocks must be 'first' or 'any', got {self.wall_blocks!r}")
        if not isinstance(self.inactivity_limit, int) or self.inactivity_limit < 0:
            raise ValueError(f"inactivity_limit must be a whole number >= 0, got {self.inactivity_limit!r}")
        if not isinstance(self.visit_start_nodes, bool):
            raise ValueError(f"visit_start_nodes must be true or false, got {self.visit_start_nodes!r}")
        if not isinstance(self.population_cap, int) or not 1 <= self.population_cap <= POPULATION_CAP:
            raise ValueError(f"population_cap must be a whole number from 1 to {POPULATION_CAP}, got {self.population_cap!r}")


#: The rules as the original's code runs them and as each paper describes them (docs/fortress.md quotes the
#: sentence behind every switch): "af-paper" the first paper (Charity et al., ALIFE for Games 2023), "qd-paper" the
#: quality-diversity sequel (Earle et al., ALOE 2023), whose runs these are.
RULES = {
    "code": Rules(),
    "af-paper": Rules(next_to="orthogonal", inactivity_limit=20, population_cap=WIDTH * HEIGHT),
    "qd-paper": Rules(next_to="orthogonal", wall_blocks="any"),
}


@dataclass
class Tables:
    """Worlds as the kernel's arrays (see :func:`._kernels.run`); ``chars[w]`` are world w's classes in order,
    ``n_nodes[w]`` / ``n_edges[w]`` its totals (its visit flags: nodes first, then edges); its initial entities are
    the rows ``initial[initial_start[w]:initial_start[w + 1]]`` of ``(class, x, y)`` in the order they are placed."""

    chars: list[list[str]]
    node_act: np.ndarray
    node_arg: np.ndarray
    node_vid: np.ndarray
    edge_start: np.ndarray
    edge_stop: np.ndarray
    edge_cond: np.ndarray
    edge_arg: np.ndarray
    edge_int: np.ndarray
    edge_dst: np.ndarray
    edge_vid: np.ndarray
    n_nodes: np.ndarray
    n_edges: np.ndarray
    initial: np.ndarray
    initial_start: np.ndarray

    @property
    def visit_width(self) -> int:
        """Visit flags a simulation needs: the largest world's nodes + edges (at least 1)."""
        return max(int((self.n_nodes + self.n_edges).max(initial=0)), 1)


def _lay_out(
    counts: Sequence[int],
    class_nodes: np.ndarray,
    class_edges: np.ndarray,
    node_act: np.ndarray,
    node_arg: np.ndarray,
    edges: np.ndarray,
    renumber: np.ndarray,
    initial: Sequence[np.ndarray],
    chars: list[list[str]],
) -> Tables:
    """The kernel's tables from every world's classes, concatenated in order (see :func:`._kernels.lay_out`):
    ``counts[w]`` classes in world w, their node and edge counts, every node's action code and class argument,
    every edge row (src, dst, condition, class argument, number) in file order; ``renumber[w, a]``: world w's class
    number of argument a; ``initial[w]``: rows (class, x, y) in class numbers."""
    from structgen.domains.fortress import _kernels

    n_worlds = len(counts)
    k_max = max(max(counts, default=1), 1)
    n_max = max(int(class_nodes.max(initial=1)), 1)
    check_memory(n_worlds * k_max * (n_max * 11 + 4) + int(class_edges.sum()) * 48, f"the tables of {n_worlds:,} worlds")
    class_world = np.repeat(np.arange(n_worlds, dtype=np.int64), counts)
    class_slot = np.arange(len(class_world), dtype=np.int64) - np.repeat(np.cumsum(counts) - counts, counts)
    tables = _kernels.lay_out(
        class_world, class_slot, class_nodes.astype(np.int64), class_edges.astype(np.int64), node_act.astype(np.int8),
        node_arg.astype(np.int64), edges.astype(np.int64).reshape(-1, 5), renumber.astype(np.int64), k_max, n_max,
    )  # fmt: skip
    sizes = np.array([len(rows) for rows in initial], dtype=np.int64)
    return Tables(
        chars,
        *tables,
        initial=np.concatenate(initial).astype(np.int64).reshape(-1, 3) if initial else np.zeros((0, 3), dtype=np.int64),
        initial_start=np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
    )


def _compile_class(entity: EntityClass, index: dict[str, int], where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A class of a fortress file as (node action codes, node class arguments, edge rows), class arguments numbered
    in the world's class order (``index``)."""
    act = np.zeros(len(entity.nodes), dtype=np.int8)
    arg = np.full(len(entity.nodes), -1, dtype=np.int64)
    for n, text in enumerate(entity.nodes):
        name, _, argument = text.partition(" ")
        target = index.get(argument, -1) if argument else -1
        if name in ("add", "transform") and target < 0:
            # The original fails with a KeyError the first time such a node acts.
            raise InputError(f"{where}: class {entity.char!r} node {n} ({text!r}) makes a class the world does not define")
        act[n], arg[n] = _ACTION_CODES[name], target
    rows = []
    for src, dst, name, arguments in entity.edge_list():
        target, number = -1, 0
        for argument in arguments:
            if argument.isascii() and argument.isdigit():
                number = int(argument)
            else:
                target = index.get(argument, -1)
        rows.append((src, dst, _CONDITION_CODES[name], target, number))
    return act, arg, np.array(rows, dtype=np.int64).reshape(-1, 5)


def _compile_genomes(worlds: Sequence[Genome]) -> Tables:
    """Array worlds: class arguments are character numbers, renumbered in each world's class order."""
    orders = np.full((len(worlds), len(CHARACTERS)), -1, dtype=np.int64)
    for w, world in enumerate(worlds):
        orders[w, [c.char for c in world.classes]] = np.arange(len(world.classes))
    classes = [c for world in worlds for c in world.classes]
    nodes = np.concatenate([c.nodes for c in classes]) if classes else np.zeros(0, dtype=np.int8)
    return _lay_out(
        [len(world.classes) for world in worlds],
        np.array([len(c.nodes) for c in classes], dtype=np.int64),
        np.array([len(c.edges) for c in classes], dtype=np.int64),
        TYPE_ACTION[nodes],
        TYPE_CHAR[nodes],
        np.concatenate([c.edges for c in classes]) if classes else np.zeros((0, 5), dtype=np.int16),
        orders,
        [np.column_stack([orders[w, world.initial[:, 0]], world.initial[:, 1:]]) for w, world in enumerate(worlds)],
        [world.chars for world in worlds],
    )


def compile_worlds(worlds: Sequence[FortressFile | Genome], where: Sequence[str] | None = None) -> Tables:
    """The kernel's arrays for these worlds (fortress files or array genomes, not mixed). An ``add`` or
    ``transform`` of a class a world does not define is an :class:`InputError` (the original crashes on it);
    conditions and targets naming such a class never hold."""
    if worlds and all(isinstance(w, Genome) for w in worlds):
        return _compile_genomes(worlds)
    worlds = [w.to_file() if isinstance(w, Genome) else w for w in worlds]
    compiled, initial = [], []
    for w, world in enumerate(worlds):
        index = {char: k for k, char in enumerate(world.classes)}
        label = where[w] if where is not None else f"world {w}"
        compiled += [_compile_class(entity, index, label) for entity in world.classes.values()]
        initial.append(np.array([(index[c], x, y) for c, x, y in world.initial], dtype=np.int64).reshape(-1, 3))
    counts = [len(world.classes) for world in worlds]
    # Class arguments are class numbers already.
    same = np.tile(np.arange(max(counts, default=0), dtype=np.int64), (len(worlds), 1))

    def joined(column: int, shape: tuple[int, ...]) -> np.ndarray:
        return np.concatenate([c[column] for c in compiled]) if compiled else np.zeros(shape, dtype=np.int64)

    return _lay_out(
        counts,
        np.array([len(act) for act, _, _ in compiled], dtype=np.int64),
        np.array([len(rows) for _, _, rows in compiled], dtype=np.int64),
        joined(0, (0,)),
        joined(1, (0,)),
        joined(2, (0, 5)),
        same,
        initial,
        [list(world.classes) for world in worlds],
    )


@dataclass
class Trace:
    """One simulation tick by tick: ``entities[t]`` lists ``(char, x, y, node)`` of the live entities after tick t
    (t = 0 is the initial placement), in creation order."""

    world: int
    seed: int
    entities: list[list[tuple[str, int, int, int]]] = field(default_factory=list)

    def populations(self, chars: Sequence[str]) -> np.ndarray:
        """``(ticks + 1, len(chars))``: how many entities of each class there were after each tick."""
        column = {c: i for i, c in enumerate(chars)}
        counts = np.zeros((len(self.entities), len(chars)), dtype=np.int64)
        for t, entities in enumerate(self.entities):
            for char, *_ in entities:
                counts[t, column[char]] += 1
        return counts


@dataclass
class Outcome:
    """Results of every world under every seed; arrays are ``(worlds, seeds)``.

    Attributes:
        ticks: ticks run. updates: entity updates made. cause: why each stopped (an index into :data:`CAUSES`).
        entities: live entities at the end. visited_nodes / visited_edges: distinct nodes and edges visited, summed
            over classes. size: the world's total nodes + edges. fitness: (visited nodes + edges) / size.
        visits: ``(worlds, seeds, V)`` visit flags (nodes of each class in order, then edges of each class in order).
        tables: the compiled worlds. traces: per world, per seed, when recorded.
    """

    ticks: np.ndarray
    updates: np.ndarray
    cause: np.ndarray
    entities: np.ndarray
    visited_nodes: np.ndarray
    visited_edges: np.ndarray
    size: np.ndarray
    fitness: np.ndarray
    visits: np.ndarray
    tables: Tables
    traces: list[list[Trace]] | None = None

    def visit_sets(self, world: int, seed: int, worlds: Sequence[FortressFile | Genome]) -> dict[str, dict[str, set]]:
        """The original's CHAR_VISIT_TREE for one simulation: per class, the node indices and edge keys visited."""
        flags = self.visits[world, seed]
        found: dict[str, dict[str, set]] = {}
        node_at = 0
        chosen = worlds[world]
        entity_classes = list((chosen.to_file() if isinstance(chosen, Genome) else chosen).classes.values())
        edge_at = int(self.tables.n_nodes[world])
        for entity in entity_classes:
            nodes = {n for n in range(len(entity.nodes)) if flags[node_at + n]}
            edges = {key for q, key in enumerate(entity.edges) if flags[edge_at + q]}
            found[entity.char] = {"nodes": nodes, "edges": edges}
            node_at += len(entity.nodes)
            edge_at += len(entity.edges)
        return found


#: About what one recorded entity of one tick costs (a tuple of four numbers in a list).
_RECORDED_ENTITY_BYTES = 120


def memory_needed(worlds: int, seeds: int, steps: int, record: bool = False) -> int:
    """Bytes a simulation of ``worlds`` x ``seeds`` for ``steps`` ticks takes beyond its tables: the random numbers
    every simulation draws from (a 32-bit number per possible entity and tick, for each seed) and, recorded, every
    tick's entities."""
    draws = seeds * max(steps * POPULATION_CAP, 1) * 4
    recorded = worlds * seeds * (steps + 1) * POPULATION_CAP * _RECORDED_ENTITY_BYTES if record else 0
    return draws + recorded


def random_streams(seeds: Sequence[int], draws: int) -> np.ndarray:
    """``(len(seeds), draws)`` uint32: the first outputs of ``numpy.random.default_rng(seed)`` for each seed, the
    numbers the simulations' random choices are made from (read-only: every evaluation of a run uses the same)."""
    return _streams(tuple(int(s) for s in seeds), int(draws))


@lru_cache(maxsize=4)
def _streams(seeds: tuple[int, ...], draws: int) -> np.ndarray:
    found = np.stack([np.random.default_rng(s).integers(0, 1 << 32, size=draws, dtype=np.uint32) for s in seeds])
    found.flags.writeable = False
    return found


def placements(initial: Sequence[tuple]) -> list[tuple]:
    """The initial entities ``(class, x, y)`` that are placed: in order, each unless its tile is already taken (the
    original places them with its clone, which refuses an occupied tile)."""
    taken: set[tuple[int, int]] = set()
    placed = []
    for entity in initial:
        if (entity[1], entity[2]) not in taken:
            taken.add((entity[1], entity[2]))
            placed.append(entity)
    return placed


def _state(tables: Tables, worlds_of: np.ndarray, rules: Rules) -> dict[str, np.ndarray]:
    from structgen.domains.fortress import _kernels

    count = len(worlds_of)
    state = {
        "cls": np.zeros((count, _SLOTS), dtype=np.int16),
        "ex": np.zeros((count, _SLOTS), dtype=np.int64),
        "ey": np.zeros((count, _SLOTS), dtype=np.int64),
        "node": np.zeros((count, _SLOTS), dtype=np.int16),
        "age": np.zeros((count, _SLOTS), dtype=np.int64),
        "alive": np.zeros((count, _SLOTS), dtype=np.bool_),
        "slots": np.zeros(count, dtype=np.int64),
        "tick": np.zeros(count, dtype=np.int64),
        "cause": np.zeros(count, dtype=np.int64),
        "last_event": np.zeros(count, dtype=np.int64),
        "used": np.zeros(count, dtype=np.int64),
        "updates": np.zeros(count, dtype=np.int64),
        "visited": np.zeros((count, tables.visit_width), dtype=np.uint8),
    }
    _kernels.place(
        tables.initial, tables.initial_start, np.asarray(worlds_of, dtype=np.int64), tables.node_vid,
        rules.visit_start_nodes, WIDTH, HEIGHT, state["cls"], state["ex"], state["ey"], state["alive"], state["slots"],
        state["visited"],
    )  # fmt: skip
    return state


def _run(
    tables: Tables, state: dict, worlds_of: np.ndarray, draws: np.ndarray, stream: np.ndarray, until: int, rules: Rules
) -> None:
    import numba

    from structgen.domains.fortress import _kernels

    # Simulations differ a lot in length (one entity or 156), so threads take them one at a time.
    with numba.parallel_chunksize(1):
        _kernels.run(
            until, worlds_of, tables.node_act, tables.node_arg, tables.node_vid, tables.edge_start, tables.edge_stop,
            tables.edge_cond, tables.edge_arg, tables.edge_int, tables.edge_dst, tables.edge_vid, draws, stream,
            state["used"], state["cls"], state["ex"], state["ey"], state["node"], state["age"], state["alive"],
            state["slots"], state["tick"], state["cause"], state["last_event"], state["visited"], state["updates"],
            WIDTH, HEIGHT,
            rules.population_cap, rules.inactivity_limit, rules.next_to == "orthogonal",
            -1 if rules.take_reach is None else rules.take_reach, rules.wall_blocks == "any",
        )  # fmt: skip


def _snapshot(tables: Tables, state: dict, b: int, w: int) -> list[tuple[str, int, int, int]]:
    chars = tables.chars[w]
    return [
        (chars[state["cls"][b, j]], int(state["ex"][b, j]), int(state["ey"][b, j]), int(state["node"][b, j]))
        for j in range(state["slots"][b])
        if state["alive"][b, j]
    ]


def simulate(
    worlds: Sequence[FortressFile | Genome],
    seeds: Sequence[int],
    steps: int = 100,
    rules: Rules = Rules(),
    *,
    record: bool = False,
    chunk: int = 512,
    where: Sequence[str] | None = None,
) -> Outcome:
    """Run every world under every seed for at most ``steps`` ticks (``record``: keep every tick's entities).

    Simulations run ``chunk`` at a time (memory grows with it), each chunk in parallel on numba's threads."""
    if not isinstance(steps, int) or isinstance(steps, bool) or steps < 0:
        raise ValueError(f"steps must be a whole number >= 0, got {steps!r}")
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("simulate needs at least one seed")
    what = f"{steps:,} ticks of {len(worlds):,} worlds x {len(seeds)} seeds" + (", every tick recorded" if record else "")
    check_memory(memory_needed(len(worlds), len(seeds), steps, record), what, "fewer ticks")
    tables = compile_worlds(worlds, where)
    n_worlds, n_seeds = len(worlds), len(seeds)
    # At most the cap act in a tick and each draws at most once.
    draws = random_streams(seeds, max(steps * POPULATION_CAP, 1))
    count = n_worlds * n_seeds
    ticks = np.zeros(count, dtype=np.int64)
    updates = np.zeros(count, dtype=np.int64)
    cause = np.zeros(count, dtype=np.int64)
    entities = np.zeros(count, dtype=np.int64)
    visits = np.zeros((count, tables.visit_width), dtype=np.uint8)
    traces: list[Trace] = []
    for start in range(0, count, chunk):
        rows = np.arange(start, min(start + chunk, count))
        worlds_of = (rows // n_seeds).astype(np.int64)
        stream = (rows % n_seeds).astype(np.int64)
        state = _state(tables, worlds_of, rules)
        if record:
            found = [Trace(int(w), seeds[s], [_snapshot(tables, state, b, int(w))]) for b, (w, s) in
                     enumerate(zip(worlds_of, stream))]  # fmt: skip
            for t in range(1, steps + 1):
                _run(tables, state, worlds_of, draws, stream, t, rules)
                for b, trace in enumerate(found):
                    if state["tick"][b] == t:
                        trace.entities.append(_snapshot(tables, state, b, int(worlds_of[b])))
            traces += found
        else:
            _run(tables, state, worlds_of, draws, stream, steps, rules)
        ticks[rows] = state["tick"]
        updates[rows] = state["updates"]
        # Still running after its last tick: it stopped at the step cap.
        cause[rows] = np.where(state["cause"] == CAUSES.index("running"), CAUSES.index("steps"), state["cause"])
        entities[rows] = state["alive"].sum(axis=1)
        visits[rows] = state["visited"]
    n_nodes = np.repeat(tables.n_nodes, n_seeds)
    n_edges = np.repeat(tables.n_edges, n_seeds)
    # Flags are 0 or 1, nodes first: a row's running count at its last node is its visited nodes.
    counted = visits.cumsum(axis=1, dtype=np.int32)
    visited_nodes = np.where(n_nodes > 0, counted[np.arange(count), np.maximum(n_nodes, 1) - 1], 0)
    visited_edges = counted[:, -1] - visited_nodes
    size = n_nodes + n_edges
    fitness = (visited_nodes + visited_edges) / np.maximum(size, 1)
    shape = (n_worlds, n_seeds)
    return Outcome(
        ticks=ticks.reshape(shape),
        updates=updates.reshape(shape),
        cause=cause.reshape(shape),
        entities=entities.reshape(shape),
        visited_nodes=visited_nodes.reshape(shape),
        visited_edges=visited_edges.reshape(shape),
        size=size.reshape(shape),
        fitness=fitness.reshape(shape),
        visits=visits.reshape(*shape, -1),
        tables=tables,
        traces=[traces[w * n_seeds : (w + 1) * n_seeds] for w in range(n_worlds)] if record else None,
    )


def describe(outcome: Outcome, world: int, seed: int) -> dict[str, Any]:
    """One simulation's numbers as plain data."""
    return {
        "ticks": int(outcome.ticks[world, seed]),
        "stopped": CAUSES[int(outcome.cause[world, seed])],
        "entities": int(outcome.entities[world, seed]),
        "fitness": float(outcome.fitness[world, seed]),
        "visited_nodes": int(outcome.visited_nodes[world, seed]),
        "visited_edges": int(outcome.visited_edges[world, seed]),
    }
