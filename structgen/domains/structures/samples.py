"""Reference structures: the calibration shapes of the paper's physics, and random lattice growth for test sets.

The calibration shapes pin the physics model (tests/physics): with unit masses and a 52.5 N break force, a
:func:`column` of 3 vertices stands, a column of 4 breaks, a column of 4 :func:`braced` at its first level stands, and
a :func:`flat_edge` stands.

:func:`random_growth` makes varied structures of a chosen size, which random NCAs do not (they grow either a lone
seed or a blob that fills their growth box); benchmarks use it to measure the physics on realistic small and
medium structures.
"""

from __future__ import annotations

import random
from collections.abc import Iterable, Iterator

import numpy as np

from structgen.lattice import OFFSETS, are_neighbours
from structgen.structure import Structure

__all__ = [
    "IN_DEGREE_CLASSES",
    "Box",
    "LEVEL_RULES",
    "WALL_RULES",
    "braced",
    "by_level_rules",
    "by_level_rules_one_taller",
    "cantilever",
    "column",
    "describe_level_rules",
    "five_level_pyramid",
    "flat_edge",
    "in_degree_class",
    "level_rule_moves",
    "on_mat",
    "parse_level_rules",
    "random_growth",
    "six_level_rule_design",
    "sparse_pyramid",
    "star_on_five_legs",
    "tiled_by_level_rules",
]


def column(n: int) -> Structure:
    """``n`` vertices stacked straight up from the ground, each joined to the next."""
    return Structure([[0, 0, z] for z in range(n)], [[z, z + 1] for z in range(n - 1)], {"sample": f"column({n})"})


def star_on_five_legs() -> Structure:
    """A one-step star grown by random generation-0 weights (seed 0): a vertex one level up on five diagonal legs,
    with three arms. It stands in PyBullet under both presets, while statics loads one leg 12% past the break force
    (the load can take several paths; the simulation's contacts share it more evenly). The near miss that the
    statics+bullet screen's margin exists for."""
    vertices = [[-1, -1, -1], [-1, -1, 1], [-1, 0, -1], [-1, 0, 1], [-1, 1, -1], [-1, 1, 1], [0, 0, 0], [0, 1, -1]]
    vertices += [[1, 0, -1], [1, 0, 0]]
    edges = [[k, 6] for k in range(6)] + [[6, 7], [6, 8], [6, 9]]
    return Structure(vertices, edges, {"sample": "star_on_five_legs()"})


def braced(n: int = 4) -> Structure:
    """A column of ``n`` vertices held at its first level by four diagonal struts from ground vertices."""
    if n < 2:
        raise ValueError(f"a braced column needs at least 2 vertices, got {n}")
    base = column(n)
    feet = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]]
    vertices = [*base.vertices.tolist(), *feet]
    edges = [*base.edges.tolist(), *[[1, n + k] for k in range(4)]]
    return Structure(vertices, edges, {"sample": f"braced({n})"})


def cantilever(arm: int, n: int = 2) -> Structure:
    """A braced column of ``n`` vertices with a horizontal arm of ``arm`` vertices sticking out from its top."""
    base = braced(max(n, 2))
    vertices = base.vertices.tolist()
    edges = base.edges.tolist()
    top = max(n, 2) - 1
    previous = top
    for k in range(1, arm + 1):
        vertices.append([k, 0, top])
        edges.append([previous, len(vertices) - 1])
        previous = len(vertices) - 1
    return Structure(vertices, edges, {"sample": f"cantilever({arm}, {n})"})


#: The rules :func:`by_level_rules` takes, one per level. Each letter adds down-neighbours that every vertex of the level
#: reaches: V straight down, S the four side diagonals, C the four corner diagonals, O outwards (away from the vertical
#: axis through the top, corners included), o outwards along the sides only. A vertex on the axis has no outward
#: direction.
LEVEL_RULES = ("V", "S", "VS", "O", "VO", "SO", "VSO", "C", "VC", "SC", "VSC", "o", "Vo", "So")
#: The rules that differ within a wall one cell thick (``by_level_rules(..., wall=True)``): the others repeat them.
WALL_RULES = ("V", "S", "VS", "O", "VO")


def _reach(rule: str, x: int, y: int) -> set[tuple[int, int]]:
    sx, sy = int(np.sign(x)), int(np.sign(y))
    steps: set[tuple[int, int]] = set()
    if "V" in rule:
        steps.add((0, 0))
    if "S" in rule:
        steps |= {(1, 0), (-1, 0), (0, 1), (0, -1)}
    if "C" in rule:
        steps |= {(1, 1), (1, -1), (-1, 1), (-1, -1)}
    if "O" in rule:
        steps |= {(sx, 0), (0, sy), (sx, sy)} - {(0, 0)}
    if "o" in rule:
        steps |= {(sx, 0), (0, sy)} - {(0, 0)}
    return steps


def _ties(
    cells: set[tuple[int, int]], z: int, offsets: tuple[tuple[int, int], ...]
) -> list[tuple[tuple[int, int, int], tuple[int, int, int]]]:
    """Edges at height ``z`` between each of ``cells`` and the ones at ``offsets`` from it (each pair once when the
    offsets hold no two opposite directions)."""
    return [((x, y, z), (x + dx, y + dy, z)) for x, y in sorted(cells) for dx, dy in offsets if (x + dx, y + dy) in cells]


def _from_cell_pairs(edges: list[tuple[tuple[int, int, int], tuple[int, int, int]]], metadata: dict) -> Structure:
    """The structure whose edges join these pairs of lattice cells, vertices numbered in order of first appearance."""
    index: dict[tuple[int, int, int], int] = {}
    for pair in edges:
        for point in pair:
            index.setdefault(point, len(index))
    return Structure(list(index), [[index[a], index[b]] for a, b in edges], metadata)


def on_mat(structure: Structure, width: int, depth: int, at: tuple[int, int] | None = None) -> Structure:
    """``structure`` set on a floor mat that fills a ``width`` x ``depth`` footprint: every ground cell of it a
    vertex, joined to its side neighbours (the structure's own ground vertices among them). The mat lies on the
    ground and carries nothing but itself, so a structure that stands on a smaller footprint gives one of this
    footprint that stands too, nearly always (the mat ties its feet together, which moves their load a little); and
    an NCA taught to grow it spreads the mat to the walls of whatever box it grows in. ``at``: where the
    structure's low corner sits on the mat, in cells (default: the middle, the lower middle where the room left is
    odd). Vertices are cells from the mat's low corner; the structure's own come first, in their order."""
    cells = structure.vertices - structure.vertices.min(axis=0)
    span = cells.max(axis=0) + 1
    if not (_whole(width) and _whole(depth) and width >= span[0] and depth >= span[1]):
        raise ValueError(f"a mat of {width!r} x {depth!r} cells cannot hold a structure {span[0]} x {span[1]} cells wide")
    room = (width - int(span[0]), depth - int(span[1]))
    at = (room[0] // 2, room[1] // 2) if at is None else at
    if not (isinstance(at, (tuple, list)) and len(at) == 2 and all(_whole(v) and 0 <= v <= r for v, r in zip(at, room))):
        raise ValueError(f"at must place the structure on the mat: 0..{room[0]} by 0..{room[1]} cells, got {at!r}")
    cells = cells + [int(at[0]), int(at[1]), 0]
    index = {tuple(c): i for i, c in enumerate(cells.tolist())}
    for x in range(width):
        for y in range(depth):
            index.setdefault((x, y, 0), len(index))
    edges = {tuple(sorted(edge)) for edge in structure.edges.tolist()}
    for x in range(width):
        for y in range(depth):
            edges.update(tuple(sorted((index[(x, y, 0)], index[(x + dx, y + dy, 0)])))
                         for dx, dy in ((1, 0), (0, 1)) if x + dx < width and y + dy < depth)  # fmt: skip
    metadata = {**structure.metadata, "mat": [int(width), int(depth)]}
    return Structure(list(index), sorted(edges), metadata)


def sparse_pyramid(levels: int) -> Structure:
    """A sparse pyramid ``levels`` vertices tall, built by one rule per level from a single top vertex: every vertex
    reaches down along the four side diagonals, and every vertex below the top also outwards (away from the axis,
    corners included); the two lowest levels are braced by edges between neighbouring vertices, and from five levels
    on, the vertices inside the outermost ring two levels up carry nothing down, so their load goes round a hollow
    centre. Five levels is :func:`five_level_pyramid`; taller ones overload their lowest joints (six levels: 53 N by
    statics, load factors applied, over the 52.5 N limit) and are where ``benchmarks/tall_design.py`` starts its
    search for designs that stand.
    """
    if levels < 2:
        raise ValueError(f"a pyramid needs at least 2 levels, got {levels}")
    top = levels - 1
    level, edges = [(0, 0)], []
    for z in range(top, 0, -1):
        below: set[tuple[int, int]] = set()
        reach = max(max(abs(x), abs(y)) for x, y in level)
        for x, y in level:
            if z == 2 and top >= 4 and max(abs(x), abs(y)) < reach - 1:  # the hollow centre
                continue
            for dx, dy in sorted(_reach("SO" if z < top else "S", x, y)):
                below.add((x + dx, y + dy))
                edges.append(((x, y, z), (x + dx, y + dy, z - 1)))
        if z <= 2:  # brace the two lowest levels
            edges += _ties(below, z - 1, ((1, 0), (0, 1), (1, 1), (1, -1)))
        level = sorted(below)
    return _from_cell_pairs(edges, {"sample": f"sparse_pyramid({levels})"})


def five_level_pyramid() -> Structure:
    """:func:`sparse_pyramid` five levels tall (79 vertices, 296 edges): it stands under the faithful preset with no
    joint broken, its largest static joint force 37 N of the 52.5 N limit. Found by a small search over level-by-level
    rules with the static analysis; taller structures need designing vertex by vertex (``benchmarks/tall_design.py``).
    """
    return sparse_pyramid(5).with_metadata(sample="five_level_pyramid()")


#: The classes a level's vertices fall into by how many members reach them from the level above (their in-degree):
#: one, two, three or four, five or more. A vertex sees these members, so a rule that depends on them is local.
IN_DEGREE_CLASSES = ("1", "2", "3-4", "5+")


def in_degree_class(members_from_above: int) -> int:
    """The index in :data:`IN_DEGREE_CLASSES` of a vertex that ``members_from_above`` members reach."""
    return 0 if members_from_above <= 1 else 1 if members_from_above == 2 else 2 if members_from_above <= 4 else 3


LevelRule = str | tuple[str, ...]
#: A growth box as offsets from a design's axis: ``(x_low, x_high, y_low, y_high)``.
Box = tuple[int, int, int, int]


def level_rule_moves(rules: Iterable[LevelRule], tied_levels: int, rng: random.Random) -> list[tuple[list[tuple[str, ...]], int]]:
    """Every design one change from ``rules`` (each level written as one rule per :data:`IN_DEGREE_CLASSES` entry)
    with ``tied_levels`` in the family of :func:`by_level_rules`: one class's rule in one level, or how many of the
    lowest levels are tied (0 to 3); shuffled by ``rng``, so that a first-improvement descent over them does not
    always favour the top level. The step of the per-class searches (``benchmarks/tall_classes.py``,
    :func:`.design.taught_clipped`)."""
    levels = [rule if isinstance(rule, tuple) else (rule,) * len(IN_DEGREE_CLASSES) for rule in rules]
    found = []
    for level, rule in enumerate(levels):
        for k in range(len(IN_DEGREE_CLASSES)):
            for other in LEVEL_RULES:
                if other != rule[k]:
                    changed = list(levels)
                    changed[level] = rule[:k] + (other,) + rule[k + 1 :]
                    found.append((changed, tied_levels))
    found += [(levels, t) for t in range(4) if t != tied_levels]
    rng.shuffle(found)
    return found


def parse_level_rules(text: str) -> tuple[LevelRule, ...]:
    """Rules written as the tall searches print them, top level first: each level one of :data:`LEVEL_RULES`, or one
    per :data:`IN_DEGREE_CLASSES` entry joined by slashes (``"V S o/C/SC/SC"``). Raises ValueError naming the word."""
    rules: list[LevelRule] = []
    for word in text.split():
        parts = tuple(word.split("/"))
        if len(parts) not in (1, len(IN_DEGREE_CLASSES)) or any(part not in LEVEL_RULES for part in parts):
            raise ValueError(
                f"{word!r} is not a level's rule: one of {', '.join(LEVEL_RULES)}, or {len(IN_DEGREE_CLASSES)} joined by /"
            )
        rules.append(word if len(parts) == 1 else parts)
    if not rules:
        raise ValueError("no rules given")
    return tuple(rules)


def describe_level_rules(rules: Iterable[LevelRule]) -> str:
    """``rules`` as :func:`parse_level_rules` reads them; a level whose classes all follow one rule as that rule."""
    return " ".join(rule if isinstance(rule, str) else rule[0] if len(set(rule)) == 1 else "/".join(rule) for rule in rules)


def _check_rule(rule: object) -> bool:
    if isinstance(rule, str):
        return rule in LEVEL_RULES
    return (
        isinstance(rule, (tuple, list))
        and len(rule) == len(IN_DEGREE_CLASSES)
        and all(isinstance(r, str) and r in LEVEL_RULES for r in rule)
    )


def _whole(value: object) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def _extent_bounds(extent: int | Box | None) -> Box | None:
    """``extent`` (None, cells from the axis each way, or a :data:`Box`) as a box, checked."""
    if extent is None:
        return None
    if _whole(extent) and extent >= 0:  # type: ignore[operator]
        return (-int(extent), int(extent), -int(extent), int(extent))  # type: ignore[call-overload]
    if (isinstance(extent, tuple) and len(extent) == 4 and all(_whole(v) for v in extent)
            and extent[0] <= 0 <= extent[1] and extent[2] <= 0 <= extent[3]):  # fmt: skip
        return tuple(int(v) for v in extent)  # type: ignore[return-value]
    raise ValueError(
        "extent must be None, a non-negative integer, or (x_low, x_high, y_low, y_high) whole offsets "
        f"from the axis with each low <= 0 <= high; got {extent!r}"
    )


def by_level_rules(
    rules: tuple[LevelRule, ...] | list[LevelRule],
    tied_levels: int = 0,
    extent: int | Box | None = None,
    *,
    wall: bool = False,
) -> Structure | None:
    """A structure grown down from one top vertex, one rule per level (top first; letters as in :data:`LEVEL_RULES`):
    ``len(rules) + 1`` vertices tall, its lowest ``tied_levels`` levels also joined to their side neighbours. None when
    the rules do not reach the ground (an outward-only rule on the axis reaches nowhere).

    A level's rule is either one of :data:`LEVEL_RULES`, which every vertex of the level follows, or one per
    :data:`IN_DEGREE_CLASSES` entry, so that a vertex many members reach (one the load of several above flows into)
    can send more down than one a single member reaches. Both are the kind of regularity an NCA's shared local rule
    can express (:func:`.tall.teachable` says whether a given design's levels look different enough).
    ``extent`` keeps the footprint within that many cells of the axis, dropping reach beyond it as an NCA's growth
    box does; a :data:`Box` ``(x_low, x_high, y_low, y_high)`` of offsets from the axis cuts it to a box the axis
    need not be the middle of (an even side, a seed off the middle). ``wall`` keeps the design in the plane x = 0,
    one cell thick: each rule's reach across it dropped (S and O reach along the wall only, C nowhere). :mod:`.tall`
    searches the one-rule designs for the tallest an NCA can grow that stands; ``benchmarks/tall_classes.py`` the
    per-class ones.
    """
    if not rules or not all(_check_rule(rule) for rule in rules):
        raise ValueError(
            f"rules must be a non-empty sequence of {', '.join(LEVEL_RULES)}, or of tuples of "
            f"{len(IN_DEGREE_CLASSES)} of them (one per in-degree class); got {list(rules)!r}"
        )
    if not isinstance(tied_levels, int) or isinstance(tied_levels, bool) or tied_levels < 0:
        raise ValueError(f"tied_levels must be a non-negative integer, got {tied_levels!r}")
    bounds = _extent_bounds(extent)
    top = len(rules)
    level: dict[tuple[int, int], int] = {(0, 0): 1}  # cell -> members reaching it from above
    edges = []
    for z, rule in zip(range(top, 0, -1), rules):
        below: dict[tuple[int, int], int] = {}
        for (x, y), reached_by in sorted(level.items()):
            own = rule if isinstance(rule, str) else rule[in_degree_class(reached_by)]
            for dx, dy in sorted(_reach(own, x, y)):
                if wall and dx:
                    continue
                cell = (x + dx, y + dy)
                if bounds is not None and not (bounds[0] <= cell[0] <= bounds[1] and bounds[2] <= cell[1] <= bounds[3]):
                    continue
                below[cell] = below.get(cell, 0) + 1
                edges.append(((x, y, z), (cell[0], cell[1], z - 1)))
        if z <= tied_levels:
            edges += _ties(set(below), z - 1, ((1, 0), (0, 1)))
        level = below
        if not level:
            return None
    described = [rule if isinstance(rule, str) else tuple(rule) for rule in rules]
    extra = (f", extent={extent}" if extent is not None else "") + (", wall=True" if wall else "")
    return _from_cell_pairs(edges, {"sample": f"by_level_rules({described!r}, tied_levels={tied_levels}{extra})"})


def by_level_rules_one_taller(
    prefixes: Iterable[tuple[str, ...]], max_vertices: int, extent: int | Box | None = None, *, wall: bool = False
) -> Iterator[tuple[tuple[str, ...], int, Structure]]:
    """``(rules, tied_levels, design)`` for every :func:`by_level_rules` design one level taller than one of
    ``prefixes`` (each rule of :data:`LEVEL_RULES` added below, with 0, 1 or 2 of the lowest levels tied), in that
    order, each distinct structure once (different rules can give the same one: an axis vertex has no outward
    direction). Designs that do not reach the ground or have more than ``max_vertices`` vertices are left out;
    ``extent`` and ``wall`` (then over :data:`WALL_RULES`) as for :func:`by_level_rules`. The step of the beam
    searches in :mod:`.tall`, :mod:`.design` and ``benchmarks/tall.py``."""
    seen: set[tuple[bytes, bytes]] = set()
    for rules in prefixes:
        for rule in WALL_RULES if wall else LEVEL_RULES:
            for tied in (0, 1, 2):
                design = by_level_rules((*rules, rule), tied, extent, wall=wall)
                if design is None or design.n_vertices > max_vertices:
                    continue
                shape = (design.vertices.tobytes(), design.edges.tobytes())
                if shape not in seen:
                    seen.add(shape)
                    yield (*rules, rule), tied, design


def tiled_by_level_rules(
    rules: tuple[LevelRule, ...] | list[LevelRule], tied_levels: int, extent: int, *, wall: bool = False
) -> Structure | None:
    """:func:`by_level_rules` designs side by side: one top every ``2 r`` cells along x and y (along y only for a
    ``wall``), ``r`` the design's reach from its axis at the ground, so neighbours share the vertices of their outer
    rows; everything within ``extent`` cells of the middle top kept (a growth box's walls). A footprint wider than one
    design's, at the height of one design: each carries only its own weight, and an NCA grows them all from one top
    (down to the shared feet, up the next). None when the design does not reach the ground or reaches no cell beside
    its axis. Its vertices are cells relative to the middle top."""
    one = by_level_rules(rules, tied_levels, wall=wall)
    if one is None:
        return None
    cells = one.vertices - one.vertices[np.argmax(one.vertices[:, 2])]
    reach = int(np.abs(cells[:, :2]).max())
    if reach == 0:
        return None
    period = 2 * reach
    copies = extent // period + 1
    pairs = set()
    for i in range(-copies, copies + 1) if not wall else (0,):
        for j in range(-copies, copies + 1):
            for a, b in one.edges.tolist():
                ends = tuple(sorted(tuple(int(c) for c in cells[k] + (i * period, j * period, 0)) for k in (a, b)))
                if max(abs(c) for end in ends for c in end[:2]) <= extent:
                    pairs.add(ends)
    named = f"tiled_by_level_rules({list(rules)!r}, {tied_levels}, extent={extent}{', wall=True' if wall else ''})"
    return _from_cell_pairs(sorted(pairs), {"sample": named})


def six_level_rule_design() -> Structure:
    """Six vertices tall by one rule per level (153 vertices, 633 edges): straight down from the top, then side and
    corner diagonals, side diagonals, side and outward diagonals, side and corner diagonals, the lowest level tied.
    Its largest static joint load is 35.6 N (load factors applied) and its largest force in the first 0.3 s 37.0 N,
    and it stands under the faithful preset with no joint broken; found by ``benchmarks/tall.py --rules``."""
    design = by_level_rules(("V", "SC", "S", "SO", "SC"), tied_levels=1)
    assert design is not None
    return design.with_metadata(sample="six_level_rule_design()")


def flat_edge() -> Structure:
    """Two vertices side by side on the ground, joined."""
    return Structure([[0, 0, 0], [1, 0, 0]], [[0, 1]], {"sample": "flat_edge"})


def random_growth(n_vertices: int, seed: int, *, extra_edges: float = 0.3, upward: float = 0.2) -> Structure:
    """A random connected structure of ``n_vertices`` grown from a seed on the ground.

    Each new vertex goes to an empty lattice neighbour of a random existing vertex and is joined to it: one of the 9
    cells a layer up with probability ``upward``, otherwise one of the 17 cells in the same layer or below (never
    below the ground). Then every other pair of neighbouring vertices is joined with probability ``extra_edges``.
    Low ``upward`` gives wide, low structures that mostly stand; high ``upward`` gives towers that mostly fall.
    The same arguments give the same structure.
    """
    if n_vertices < 1:
        raise ValueError(f"n_vertices must be at least 1, got {n_vertices}")
    if not 0 <= extra_edges <= 1 or not 0 <= upward <= 1:
        raise ValueError("extra_edges and upward must be in [0, 1]")
    rng = np.random.default_rng(seed)
    cells = [(0, 0, 0)]
    taken = {cells[0]}
    edges = []
    up, other = np.flatnonzero(OFFSETS[:, 2] > 0), np.flatnonzero(OFFSETS[:, 2] <= 0)
    while len(cells) < n_vertices:
        parent_index = int(rng.integers(len(cells)))
        step = OFFSETS[int(rng.choice(up if rng.random() < upward else other))]
        child = tuple(int(c) for c in np.add(cells[parent_index], step))
        if child in taken or child[2] < 0:
            continue
        taken.add(child)
        cells.append(child)
        edges.append((parent_index, len(cells) - 1))
    points = np.array(cells)
    joined = {tuple(sorted(e)) for e in edges}
    i, j = np.triu_indices(len(points), k=1)
    near = are_neighbours(points[i], points[j])
    for a, b in zip(i[near].tolist(), j[near].tolist()):
        if (a, b) not in joined and rng.random() < extra_edges:
            edges.append((a, b))
    sample = f"random_growth({n_vertices}, seed={seed}, extra_edges={extra_edges}, upward={upward})"
    return Structure(points, np.array(edges, dtype=np.int64).reshape(-1, 2), {"sample": sample})
