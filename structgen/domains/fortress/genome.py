"""Worlds as arrays: the genome MAP-Elites evolves, cheap to copy, mutate, compile and store.

A fortress file (:class:`.formats.FortressFile`) keeps a class's machine as text (``"chase X"``, ``"3-7": "within
X 4"``), which is what people read and write; evolution touches one class of a world at a time and simulates ten
worlds a generation, where parsing and copying text cost more than the simulations. A :class:`Genome` holds the
same world as small integer arrays over the 15 classes of the QD experiments (:data:`CHARACTERS`):

- a class (:class:`ClassArrays`) is its character's number, its nodes as numbers into :func:`node_types` (94 of
  them: ``idle, move, die, clone``, then ``take, chase, push, add, transform, move_wall`` of each class), and its
  edges in file order as rows ``(src, dst, condition, class argument, number)``; the condition is its priority
  (0 none, 1 step, 2 within, 3 nextTo, 4 touch), absent arguments are -1 and 0;
- classes are immutable and shared between a world and its mutants: a mutant replaces the classes it changes, so a
  copy costs 15 references; the engine lays the arrays of a generation's worlds out for its kernel in one compiled
  pass (:func:`.engine.compile_worlds`);
- :meth:`Genome.to_file` and :meth:`Genome.from_file` convert to and from the text form, edge order and all.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from structgen.domains.fortress.formats import CONDITIONS, EntityClass, FortressFile
from structgen.errors import InputError

__all__ = ["CHARACTERS", "CONDITION_NAMES", "TYPE_ACTION", "TYPE_CHAR", "ClassArrays", "Genome", "edge_order_rank", "node_types"]

#: The 15 classes of the QD experiments.
CHARACTERS = tuple("@$&+;!><XO*^MDS")
NO_ARGUMENT = ("idle", "move", "die", "clone")
WITH_ARGUMENT = ("take", "chase", "push", "add", "transform", "move_wall")
#: Condition names by their code, which is their priority (the engine's codes).
CONDITION_NAMES = tuple(sorted(CONDITIONS, key=lambda name: CONDITIONS[name][0]))
# Edge columns.
SRC, DST, COND, CHAR, NUMBER = range(5)
_CHAR_INDEX = {c: k for k, c in enumerate(CHARACTERS)}


@lru_cache(maxsize=8)
def node_types(chars: tuple[str, ...] = CHARACTERS) -> tuple[str, ...]:
    """Every node a class may hold, once each (94 for 15 classes), in the original's order."""
    return NO_ARGUMENT + tuple(f"{action} {c}" for action in WITH_ARGUMENT for c in chars)


_TYPE_INDEX = {name: t for t, name in enumerate(node_types(CHARACTERS))}
_ACTION_CODES = {name: code for code, name in enumerate(("idle", "move", "die", "clone", *WITH_ARGUMENT))}
#: For each node type: the engine's action code and the class it names (-1 for none).
TYPE_ACTION = np.array(
    [_ACTION_CODES[name.partition(" ")[0]] for name in node_types(CHARACTERS)],
    dtype=np.int8,
)
TYPE_CHAR = np.array([-1] * len(NO_ARGUMENT) + [c for _ in WITH_ARGUMENT for c in range(len(CHARACTERS))], dtype=np.int16)
# Node indices stay below this (94 types, each at most once), so an edge's (src, dst) is one number src * _KEYS + dst.
_KEYS = 128


@lru_cache(maxsize=1)
def edge_order_rank() -> np.ndarray:
    """``rank[src, dst]``: where the key ``"src-dst"`` falls in string order (``"10-2"`` before ``"2-0"``), the
    order the original sorts a machine's edges in."""
    keys = [f"{a}-{b}" for a in range(_KEYS) for b in range(_KEYS)]
    rank = np.empty(len(keys), dtype=np.int32)
    rank[sorted(range(len(keys)), key=keys.__getitem__)] = np.arange(len(keys), dtype=np.int32)
    return rank.reshape(_KEYS, _KEYS)


class ClassArrays:
    """One class's machine as arrays (see the module's description); never changed once made."""

    __slots__ = ("char", "nodes", "edges", "__weakref__")

    def __init__(self, char: int, nodes: np.ndarray, edges: np.ndarray) -> None:
        self.char = int(char)
        self.nodes = np.asarray(nodes, dtype=np.int8).reshape(-1)
        self.edges = np.asarray(edges, dtype=np.int16).reshape(-1, 5)
        self.nodes.flags.writeable = False
        self.edges.flags.writeable = False

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, ClassArrays)
            and self.char == other.char
            and np.array_equal(self.nodes, other.nodes)
            and np.array_equal(self.edges, other.edges)
        )

    def __getstate__(self) -> dict:
        return {"char": self.char, "nodes": self.nodes, "edges": self.edges}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["char"], state["nodes"], state["edges"])

    # -- text ----------------------------------------------------------------------------------------------------------
    def to_entity(self) -> EntityClass:
        types = node_types(CHARACTERS)
        edges = {}
        for src, dst, cond, char, number in self.edges.tolist():
            name = CONDITION_NAMES[cond]
            arguments = [CHARACTERS[char]] if char >= 0 else []
            if name in ("step", "within"):
                arguments.append(str(number))
            edges[f"{src}-{dst}"] = " ".join([name, *arguments])
        return EntityClass(CHARACTERS[self.char], [types[t] for t in self.nodes.tolist()], edges)

    @classmethod
    def from_entity(cls, entity: EntityClass, where: str = "world") -> ClassArrays:
        if entity.char not in _CHAR_INDEX:
            raise InputError(f"{where}: class {entity.char!r} is not one of the QD classes {''.join(CHARACTERS)}")
        try:
            nodes = [_TYPE_INDEX[node] for node in entity.nodes]
        except KeyError as missing:
            raise InputError(f"{where}: class {entity.char!r}: node {missing} is not a QD node type") from None
        if len(set(nodes)) != len(nodes):
            raise InputError(f"{where}: class {entity.char!r} holds a node type twice (a QD class holds each once)")
        rows = []
        for src, dst, name, arguments in entity.edge_list():
            if max(src, dst) >= _KEYS:
                raise InputError(f"{where}: class {entity.char!r}: edge {src}-{dst} names a node beyond {_KEYS - 1}")
            char, number = -1, 0
            for argument in arguments:
                if argument.isascii() and argument.isdigit():
                    number = int(argument)
                    if number > np.iinfo(np.int16).max:
                        raise InputError(f"{where}: class {entity.char!r}: edge {src}-{dst}: {number} is too large")
                elif argument in _CHAR_INDEX:
                    char = _CHAR_INDEX[argument]
                else:
                    raise InputError(f"{where}: class {entity.char!r}: edge {src}-{dst} names class {argument!r}")
            rows.append((src, dst, CONDITIONS[name][0], char, number))
        return cls(_CHAR_INDEX[entity.char], np.array(nodes), np.array(rows, dtype=np.int16).reshape(-1, 5))


class Genome:
    """A world: its classes in the world's order and its initial entities ``(class number, x, y)`` in the order
    they are placed (one on a tile already taken is dropped when placed)."""

    __slots__ = ("classes", "initial", "__weakref__")

    def __init__(self, classes: tuple[ClassArrays, ...], initial: np.ndarray) -> None:
        self.classes = tuple(classes)
        self.initial = np.asarray(initial, dtype=np.int16).reshape(-1, 3)
        self.initial.flags.writeable = False

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, Genome)
            and len(self.classes) == len(other.classes)
            and all(a == b for a, b in zip(self.classes, other.classes))
            and np.array_equal(self.initial, other.initial)
        )

    def __getstate__(self) -> dict:
        return {"classes": self.classes, "initial": self.initial}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["classes"], state["initial"])

    def replace(self, position: int, entity: ClassArrays) -> Genome:
        classes = list(self.classes)
        classes[position] = entity
        return Genome(tuple(classes), self.initial)

    @property
    def chars(self) -> list[str]:
        return [CHARACTERS[c.char] for c in self.classes]

    def size(self) -> tuple[int, int]:
        """Total nodes and total edges."""
        return sum(len(c.nodes) for c in self.classes), sum(len(c.edges) for c in self.classes)

    def to_file(self) -> FortressFile:
        classes = {CHARACTERS[c.char]: c.to_entity() for c in self.classes}
        initial = [(CHARACTERS[c], x, y) for c, x, y in self.initial.tolist()]
        return FortressFile(classes=classes, initial=initial, placed_by="pos" if initial else None)

    @classmethod
    def from_file(cls, world: FortressFile, where: str = "world") -> Genome:
        classes = tuple(ClassArrays.from_entity(entity, where) for entity in world.classes.values())
        for c, *_ in world.initial:
            if c not in _CHAR_INDEX:
                raise InputError(f"{where}: initial entity of class {c!r}, not one of the QD classes")
        initial = np.array([(_CHAR_INDEX[c], x, y) for c, x, y in world.initial], dtype=np.int16).reshape(-1, 3)
        return cls(classes, initial)
