"""The Amorphous Fortress's text formats: entity classes (finite-state machines) and fortress files.

An entity block::

    B
    -- NODES --
    0: idle
    1: take L
    -- EDGES --
    0-1: touch L
    1-0: none

names its class by one character (entity files may write ``B``; fortress and elite files write ``B:``), lists its
action nodes by index, and its edges ``src-dst: condition [char] [int]`` in the order in which edges of one priority
are tried. A fortress file is entity blocks separated by blank lines, then an ``-- INIT ENT POS --`` block (one
``c-[x, y]`` per line, x the column) and/or an ``-- INIT FORT --`` block (the ASCII map, ``#`` wall, ``.`` floor,
any class character an entity there); as in the original, the first of them that places entities decides the
initial population, and the rest are kept only to be written back. Saved elites add a ``-- FORT @ STEPS N --`` map.

Reading is strict: an unknown action or condition, a node index out of range or a malformed position is an
:class:`InputError` naming the file, the line and the text.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from structgen.errors import InputError

__all__ = [
    "ACTIONS",
    "CONDITIONS",
    "EntityClass",
    "FortressFile",
    "format_entity",
    "format_fortress",
    "parse_entity",
    "parse_fortress",
    "read_entity_file",
    "read_fortress_file",
]

#: Actions and how many arguments each takes (a class character).
ACTIONS = {
    "idle": 0,
    "move": 0,
    "die": 0,
    "clone": 0,
    "take": 1,
    "chase": 1,
    "push": 1,
    "add": 1,
    "transform": 1,
    "move_wall": 1,
}
#: Conditions with their priority (higher is tried first) and their arguments.
CONDITIONS = {
    "touch": (4, ("char",)),
    "nextTo": (3, ("char",)),
    "within": (2, ("char", "int")),
    "step": (1, ("int",)),
    "none": (0, ()),
}
# At most 9 digits: longer numbers are off the map anyway, and Python refuses to read one of over 4,300 digits.
_POSITION = re.compile(r"^(.)-\[(-?[0-9]{1,9}), (-?[0-9]{1,9})\]$")
#: The largest number a condition may hold (``within c r``, ``step k``): the engine stores them in 32 bits.
MAX_NUMBER = 10**9
#: The most classes a world may define (class numbers are stored in 16 bits).
MAX_CLASSES = 10_000
# The map every world lives on (engine.WIDTH x engine.HEIGHT): initial entities must be placed on it.
_MAP_WIDTH, _MAP_HEIGHT = 15, 8


def _whole(text: str) -> bool:
    """Whether ``text`` is a whole number written in ASCII digits (``str.isdigit`` also takes "²" and other scripts)."""
    return text.isascii() and text.isdigit()


@dataclass
class EntityClass:
    """One class: its character, its action nodes (``"take L"``) and its edges, ``"src-dst" -> "touch L"`` in file
    order (the order edges of one priority are tried in)."""

    char: str
    nodes: list[str]
    edges: dict[str, str] = field(default_factory=dict)

    def edge_list(self) -> list[tuple[int, int, str, list[str]]]:
        """``(src, dst, condition, arguments)`` in file order."""
        found = []
        for key, condition in self.edges.items():
            src, dst = key.split("-")
            name, *arguments = condition.split(" ")
            found.append((int(src), int(dst), name, arguments))
        return found


@dataclass
class FortressFile:
    """A fortress definition.

    Attributes:
        classes: the entity classes by character, in file order.
        initial: ``(char, x, y)`` of each initial entity in the order it is placed (x the column, y the row).
        placed_by: "pos" or "fort": the kind of block the initial entities come from (None when there are none).
        blocks: the position and map blocks in file order, as ``(kind, lines)`` with the header line first; kept so
            that a file is written back with the same blocks in the same order.
    """

    classes: dict[str, EntityClass]
    initial: list[tuple[str, int, int]] = field(default_factory=list)
    placed_by: str | None = None
    blocks: list[tuple[str, list[str]]] = field(default_factory=list)


def _check_entity(entity: EntityClass, where: str) -> None:
    for index, node in enumerate(entity.nodes):
        name, *arguments = node.split(" ")
        if name not in ACTIONS:
            raise InputError(f"{where}: node {index}: unknown action {name!r} (known: {', '.join(ACTIONS)})")
        if len(arguments) != ACTIONS[name] or any(len(a) != 1 for a in arguments):
            raise InputError(f"{where}: node {index}: {node!r}: {name} takes {ACTIONS[name]} class character(s)")
    for key, condition in entity.edges.items():
        match = re.fullmatch(r"([0-9]{1,9})-([0-9]{1,9})", key)
        # An edge from a node the class does not have can never fire; the original keeps such edges (a shipped file
        # has one), so they are kept. One that could fire must lead to a node that exists.
        if not match or (int(match[1]) < len(entity.nodes) and int(match[2]) >= len(entity.nodes)):
            raise InputError(f"{where}: edge {key!r}: expected src-dst with node indices below {len(entity.nodes)}")
        name, *arguments = condition.split(" ")
        if name not in CONDITIONS:
            raise InputError(f"{where}: edge {key}: unknown condition {name!r} (known: {', '.join(CONDITIONS)})")
        kinds = CONDITIONS[name][1]
        if len(arguments) != len(kinds):
            raise InputError(f"{where}: edge {key}: {condition!r}: {name} takes {len(kinds)} argument(s)")
        for kind, argument in zip(kinds, arguments):
            if (kind == "char" and len(argument) != 1) or (kind == "int" and not _whole(argument)):
                wanted = "a class character" if kind == "char" else "a whole number"
                raise InputError(f"{where}: edge {key}: {condition!r}: expected {wanted}, got {argument!r}")
            # Compared by length first: Python will not turn 4,300 digits or more into a number.
            if kind == "int" and (len(argument) > len(str(MAX_NUMBER)) or int(argument) > MAX_NUMBER):
                raise InputError(f"{where}: edge {key}: {condition!r}: {argument[:20]} is more than {MAX_NUMBER:,}")
        if name == "step" and int(arguments[0]) < 1:
            raise InputError(f"{where}: edge {key}: {condition!r}: step needs a count of at least 1")


def parse_entity(text: str, where: str = "entity", *, char_at_end: bool = False) -> EntityClass:
    """One entity block. Its class character is the first character of its first line (the original's string
    reader), or the last with ``char_at_end`` (its entity-file reader)."""
    lines = [line.strip() for line in text.split("\n") if line.strip()]
    if not lines:
        raise InputError(f"{where}: empty entity block")
    try:
        nodes_at, edges_at = lines.index("-- NODES --"), lines.index("-- EDGES --")
    except ValueError:
        raise InputError(f"{where}: an entity block needs '-- NODES --' and '-- EDGES --' lines") from None
    if nodes_at != 1 or edges_at < nodes_at:
        raise InputError(f"{where}: expected the class character, then '-- NODES --', then '-- EDGES --'")
    char = lines[0][-1] if char_at_end else lines[0][0]
    nodes = []
    for number, line in enumerate(lines[nodes_at + 1 : edges_at]):
        # The original numbers nodes by their order and ignores the number written (a shipped file starts at 1).
        index, sep, node = line.partition(": ")
        if not sep or not _whole(index):
            raise InputError(f"{where}: node line {line!r}: expected '{number}: action'")
        nodes.append(node)
    edges: dict[str, str] = {}
    for line in lines[edges_at + 1 :]:
        key, sep, condition = line.partition(": ")
        if not sep:
            raise InputError(f"{where}: edge line {line!r}: expected 'src-dst: condition'")
        edges[key] = condition
    entity = EntityClass(char, nodes, edges)
    _check_entity(entity, f"{where} (class {char!r})")
    return entity


def format_entity(entity: EntityClass, *, colon: bool = False) -> str:
    """The block as the original prints it (``colon``: ``B:`` as its elite files write the header)."""
    lines = [entity.char + (":" if colon else ""), "-- NODES --"]
    lines += [f"{i}: {node}" for i, node in enumerate(entity.nodes)]
    lines.append("-- EDGES --")
    lines += [f"{key}: {condition}" for key, condition in entity.edges.items()]
    return "\n".join(lines) + "\n"


def _positions(block: list[str], where: str) -> list[tuple[str, int, int]]:
    found = []
    for line in block[1:]:
        match = _POSITION.match(line.strip())
        if not match:
            raise InputError(f"{where}: position line {line!r}: expected 'c-[x, y]'")
        x, y = int(match[2]), int(match[3])
        if not (0 <= x < _MAP_WIDTH and 0 <= y < _MAP_HEIGHT):
            raise InputError(f"{where}: position line {line!r}: off the {_MAP_WIDTH}x{_MAP_HEIGHT} map")
        found.append((match[1], x, y))
    return found


def _from_map(block: list[str], classes: dict[str, EntityClass], where: str) -> list[tuple[str, int, int]]:
    rows = block[1:]
    if len(rows) > _MAP_HEIGHT or any(len(line.strip()) > _MAP_WIDTH for line in rows):
        raise InputError(f"{where}: its map block is larger than the {_MAP_WIDTH}x{_MAP_HEIGHT} map")
    found = []
    for row, line in enumerate(rows):
        for col, char in enumerate(line.strip()):
            if char not in "#." and char in classes:
                found.append((char, col, row))
    return found


def parse_fortress(text: str, where: str = "fortress") -> FortressFile:
    """A fortress definition (entity blocks, then position and map blocks)."""
    fortress = FortressFile(classes={})
    for chunk in text.split("\n\n"):
        block = [line.rstrip() for line in chunk.strip().split("\n")]
        if block == [""]:
            continue
        header = block[0].strip()
        if "-- INIT ENT POS --" in chunk:
            placed, kind = _positions(block, where), "pos"
        elif "FORT" in header and header.startswith("--"):
            placed, kind = _from_map(block, fortress.classes, where), "fort"
        else:
            entity = parse_entity(chunk, where)
            fortress.classes[entity.char] = entity
            continue
        fortress.blocks.append((kind, block))
        if not fortress.initial and placed:
            fortress.initial, fortress.placed_by = placed, kind
    if not fortress.classes:
        raise InputError(f"{where}: defines no entity class (a fortress file starts with entity blocks)")
    if len(fortress.classes) > MAX_CLASSES:
        raise InputError(f"{where}: defines {len(fortress.classes):,} classes, more than {MAX_CLASSES:,}")
    unknown = sorted({char for char, _, _ in fortress.initial} - set(fortress.classes))
    if unknown:
        raise InputError(f"{where}: initial entities of undefined classes {', '.join(map(repr, unknown))}")
    return fortress


def format_fortress(fortress: FortressFile) -> str:
    """The file: entity blocks (``X:`` headers, as the original's elite files), then the position and map blocks in
    the order read. A fortress with initial entities and no such block gets an ``-- INIT ENT POS --`` block."""
    parts = [format_entity(entity, colon=True) for entity in fortress.classes.values()]
    blocks = fortress.blocks
    if fortress.initial and not blocks:
        blocks = [("pos", ["-- INIT ENT POS --", *(f"{c}-[{x}, {y}]" for c, x, y in fortress.initial)])]
    parts += ["\n".join(lines) + "\n" for _, lines in blocks]
    return "\n".join(parts)


def read_entity_file(path: str | Path) -> EntityClass:
    """An entity file (``ENT/*.txt``): the class character is the last of its first line."""
    from evolution.files import read_text

    return parse_entity(read_text(path, 1 << 20, what="an entity file"), str(path), char_at_end=True)


def read_fortress_file(path: str | Path) -> FortressFile:
    from evolution.files import read_text

    return parse_fortress(read_text(path, 4 << 20, what="a fortress file"), str(path))
