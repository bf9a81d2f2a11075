"""The Amorphous Fortress's text formats: our own small worlds and (where the reference data is on the machine) every
file the original ships read, and write back to equivalent files."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from structgen.domains.fortress.formats import (
    format_entity,
    format_fortress,
    parse_entity,
    parse_fortress,
    read_entity_file,
    read_fortress_file,
)
from structgen.errors import InputError
from tests import reference
from tests.fortress import own_worlds

DATA = reference.folder("amorphous-fortress")
ENTITY_FILES = sorted((DATA / "ENT").glob("*.txt"))
FORTRESS_FILES = sorted((DATA / "FORTS").glob("*.txt")) + sorted((DATA / "QD_EXP" / "SAVED_FORTS").glob("*.txt"))
OWN = {"gem_keeper.txt": own_worlds.GEM_KEEPER, "garden.txt": own_worlds.GARDEN, "numbered.txt": own_worlds.NUMBERED_FROM_ONE}
needs_data = reference.needs("amorphous-fortress")


@needs_data
def test_the_reference_files_are_there():
    # where the data is, all of it is: otherwise the round trips below would test less than they say
    assert len(ENTITY_FILES) == 11 and len(FORTRESS_FILES) == 15, DATA


def entity_round_trip(entity) -> None:
    again = parse_entity(format_entity(entity))
    assert (again.char, again.nodes, list(again.edges.items())) == (entity.char, entity.nodes, list(entity.edges.items()))
    assert entity.nodes[0] and entity.edges


@needs_data
@pytest.mark.parametrize("path", ENTITY_FILES, ids=lambda p: p.name)
def test_entity_files_round_trip(path):
    entity_round_trip(read_entity_file(path))


def test_our_entity_file_round_trips(tmp_path):
    path = tmp_path / "lone.txt"
    path.write_text(own_worlds.LONE_CLASS)
    entity_round_trip(read_entity_file(path))


@pytest.mark.parametrize("name", sorted(OWN))
def test_our_fortress_files_round_trip(name, tmp_path):
    path = tmp_path / name
    path.write_text(OWN[name])
    fortress_round_trip(path, tmp_path / "again")


@needs_data
@pytest.mark.parametrize("path", FORTRESS_FILES, ids=lambda p: p.name)
def test_fortress_files_round_trip(path, tmp_path):
    fortress_round_trip(path, tmp_path)


def fortress_round_trip(path: Path, folder: Path) -> None:
    fortress = read_fortress_file(path)
    folder.mkdir(exist_ok=True)
    written = folder / path.name
    written.write_text(format_fortress(fortress))
    again = read_fortress_file(written)
    assert list(again.classes) == list(fortress.classes)
    for char, entity in fortress.classes.items():
        assert again.classes[char].nodes == entity.nodes
        assert list(again.classes[char].edges.items()) == list(entity.edges.items())
    assert again.initial == fortress.initial and again.placed_by == fortress.placed_by
    assert again.blocks == fortress.blocks
    assert fortress.initial, "every shipped fortress places entities"
    if "SAVED_FORTS" in str(path):
        assert len(fortress.classes) == 15 and fortress.placed_by == "pos"


def test_a_map_places_entities_row_by_row_with_x_the_column(tmp_path):
    path = tmp_path / "gem_keeper.txt"
    path.write_text(own_worlds.GEM_KEEPER)
    fortress = read_fortress_file(path)
    assert list(fortress.classes) == ["k", "g"] and fortress.placed_by == "fort"
    assert fortress.classes["k"].edge_list() == [(0, 1, "nextTo", ["g"]), (1, 0, "none", [])]
    assert fortress.initial == [("k", 2, 1), ("g", 5, 3), ("g", 3, 4), ("k", 7, 5)]


@needs_data
def test_lock_and_key_reads_as_the_original_reads_it():
    fortress = read_fortress_file(DATA / "FORTS" / "LOCK_N_KEY.txt")
    assert list(fortress.classes) == ["o", "O", "X", "?", ">"]
    assert fortress.classes["o"].nodes == ["move_wall X", "chase ?", "transform O"]
    assert fortress.classes["o"].edge_list() == [(0, 1, "within", ["?", "3"]), (1, 2, "touch", ["?"])]
    # placed from the map, row by row, x the column
    assert fortress.placed_by == "fort"
    assert fortress.initial[:3] == [(">", 2, 1), ("X", 4, 1), ("X", 4, 2)]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("A\n-- NODES --\n0: fly\n-- EDGES --\n", "node 0: unknown action 'fly'"),
        ("A\n-- NODES --\n0: take\n-- EDGES --\n", "take takes 1 class character"),
        ("A\n-- NODES --\n0: idle\n-- EDGES --\n0-3: none\n", "edge '0-3': expected src-dst with node indices below 1"),
        ("A\n-- NODES --\nzero: idle\n-- EDGES --\n", "node line 'zero: idle'"),
        ("A\n-- NODES --\n0: idle\n-- EDGES --\n0-0: within B\n", "within takes 2 argument"),
        ("A\n-- NODES --\n0: idle\n-- EDGES --\n0-0: step 0\n", "step needs a count of at least 1"),
        ("A\n-- NODES --\n0: idle\n", "needs '-- NODES --' and '-- EDGES --'"),
    ],
)
def test_bad_entities_are_refused_with_the_place_named(text, message):
    with pytest.raises(InputError, match=message):
        parse_entity(text, "my.txt")


def test_positions_of_undefined_classes_are_refused():
    text = "A\n-- NODES --\n0: idle\n-- EDGES --\n0-0: none\n\n-- INIT ENT POS --\nZ-[1, 1]\n"
    with pytest.raises(InputError, match="undefined classes 'Z'"):
        parse_fortress(text, "f.txt")


def test_nodes_are_numbered_by_order_as_the_original_numbers_them():
    # a class that writes its only node as "1: push b" and an edge 1-1 that can never fire
    player = parse_fortress(own_worlds.NUMBERED_FROM_ONE, "numbered.txt").classes["p"]
    assert player.nodes == ["push b"] and player.edges == {"1-1": "none"}
    assert format_entity(player).splitlines()[2] == "0: push b"


@needs_data
def test_the_originals_node_numbering_quirk_reads_the_same():
    # DRUNK_SOKOBAN_2's player is written as "1: push *" with an edge 1-1
    player = read_fortress_file(DATA / "FORTS" / "DRUNK_SOKOBAN_2.txt").classes["@"]
    assert player.nodes == ["push *"] and player.edges == {"1-1": "none"}


WORLD = "A\n-- NODES --\n0: idle\n1: move\n-- EDGES --\n0-1: {edge}\n\n-- INIT ENT POS --\n{position}\n"


@pytest.mark.parametrize(
    ("edge", "position", "message"),
    [
        ("step ²", "A-[2, 2]", "expected a whole number, got '²'"),  # a digit to str.isdigit, not to int()
        ("within A ٣", "A-[2, 2]", "expected a whole number, got '٣'"),
        ("step 4294967296", "A-[2, 2]", "4294967296 is more than 1,000,000,000"),  # would wrap to 0 in 32 bits
        ("within A 99999999999999999999999", "A-[2, 2]", "is more than 1,000,000,000"),
        ("step 3", "A-[20, 2]", "A-[20, 2]': off the 15x8 map"),
        ("step 3", "A-[2, -1]", "off the 15x8 map"),
        ("step 3", "A-[١, 2]", "expected 'c-[x, y]'"),
    ],
)
def test_numbers_and_positions_the_engine_cannot_hold_are_refused(edge, position, message):
    with pytest.raises(InputError, match=re.escape(message)):
        parse_fortress(WORLD.format(edge=edge, position=position), "w.txt")


def test_a_file_without_classes_or_with_too_many_is_refused():
    with pytest.raises(InputError, match="defines no entity class"):
        parse_fortress("\n\n-- INIT ENT POS --\nA-[2, 2]\n", "empty.txt")
    with pytest.raises(InputError, match="defines no entity class"):
        parse_fortress("", "empty.txt")
    many = "\n\n".join(f"{chr(0x4E00 + k)}\n-- NODES --\n0: idle\n-- EDGES --\n0-0: none" for k in range(10_001))
    with pytest.raises(InputError, match="defines 10,001 classes, more than 10,000"):
        parse_fortress(many, "many.txt")


def test_a_map_block_larger_than_the_map_is_refused():
    big = "A\n-- NODES --\n0: idle\n-- EDGES --\n0-0: none\n\n-- INIT FORT --\n" + "\n".join(["#" + "A" * 30 + "#"] * 20)
    with pytest.raises(InputError, match="its map block is larger than the 15x8 map"):
        parse_fortress(big, "big.txt")
