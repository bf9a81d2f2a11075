"""Random worlds and the original's mutation operators: sizes in the measures' ranges, the orphan-edge quirk,
node deletion renumbering edges, reproducibility, and the entropy measure."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from structgen.domains.fortress.formats import EntityClass, FortressFile, format_fortress, parse_fortress
from structgen.domains.fortress.world import (
    CHARACTERS,
    Variation,
    _remove_node,
    connect_orphans,
    fsm_size_entropy,
    mutate_world,
    node_types,
    random_class,
    random_world,
    world_size,
)


def test_there_are_94_node_types_and_1410_nodes_at_most():
    types = node_types(CHARACTERS)
    assert len(types) == 94 == len(set(types))
    assert types[:4] == ("idle", "move", "die", "clone") and "move_wall S" in types


@pytest.mark.parametrize("start", ["n_nodes", "entropy"])
def test_random_worlds_stay_inside_the_measure_ranges(start):
    rng = np.random.default_rng(0)
    for _ in range(20):
        world = random_world(rng, start=start)
        nodes, _ = world_size(world)
        assert sorted(world.classes) == sorted(CHARACTERS)
        assert 15 <= nodes <= 1410
        assert all(1 <= len(e.nodes) <= 94 and e.nodes[0] == "idle" for e in world.classes.values())
        assert all(len(set(e.nodes)) == len(e.nodes) for e in world.classes.values())
        assert 1 <= len(world.initial) <= 30
        assert len({(x, y) for _, x, y in world.initial}) == len(world.initial)
        assert all(1 <= x <= 13 and 1 <= y <= 6 for _, x, y in world.initial)
        assert 0 <= fsm_size_entropy(world) <= 1
        assert parse_fortress(format_fortress(world)).classes == world.classes


def test_entropy_starts_spread_over_entropy_and_size_starts_do_not():
    rng = np.random.default_rng(1)
    by_entropy = [fsm_size_entropy(random_world(rng, start="entropy")) for _ in range(40)]
    by_size = [fsm_size_entropy(random_world(rng, start="n_nodes")) for _ in range(40)]
    assert np.std(by_entropy) > np.std(by_size)


def test_the_orphan_repair_adds_an_edge_to_every_node_as_the_original_does():
    edges = {"0-1": "none", "1-2": "none", "2-0": "none"}
    every = EntityClass("A", ["idle", "move", "die"], dict(edges))
    connect_orphans(every, np.random.default_rng(0), CHARACTERS, Variation())
    # each node gets a new incoming edge from another node (some may overwrite the ones there)
    assert all(any(k.endswith(f"-{n}") and k != f"{n}-{n}" for k in every.edges) for n in range(3))
    assert every.edges != edges
    fixed = EntityClass("A", ["idle", "move", "die"], dict(edges))
    connect_orphans(fixed, np.random.default_rng(0), CHARACTERS, Variation(orphan_edges="orphans_only"))
    assert fixed.edges == edges  # nobody was an orphan
    assert list(every.edges) == sorted(every.edges)  # sorted as strings, as the original


def test_random_class_has_its_nodes_and_twice_as_many_edges_at_most_before_repair():
    entity = random_class("A", 10, np.random.default_rng(3))
    assert len(entity.nodes) == 11
    assert 11 <= len(entity.edges) <= 20 + 11
    assert list(entity.edges) == sorted(entity.edges)
    assert random_class("A", 0, np.random.default_rng(3)).edges == {}


def test_removing_a_node_drops_its_edges_and_renumbers_the_rest():
    entity = EntityClass("A", ["idle", "move", "die", "clone"], {"0-1": "none", "1-2": "step 2", "3-0": "touch A", "2-3": "none"})
    _remove_node(entity, 1)
    assert entity.nodes == ["idle", "die", "clone"]
    assert entity.edges == {"2-0": "touch A", "1-2": "none"}


def test_mutation_copies_is_reproducible_and_changes_something():
    rng = np.random.default_rng(4)
    world = random_world(rng)
    before = copy.deepcopy(world)
    first = [mutate_world(world, np.random.default_rng(s)) for s in range(30)]
    again = [mutate_world(world, np.random.default_rng(s)) for s in range(30)]
    assert world == before
    assert [format_fortress(a) for a in first] == [format_fortress(b) for b in again]
    changed = sum(format_fortress(m) != format_fortress(world) for m in first)
    assert changed >= 20  # the three coins all fail one time in eight
    for mutant in first:
        for entity in mutant.classes.values():
            assert len(entity.nodes) >= 1 and len(set(entity.nodes)) == len(entity.nodes)
            for src, dst, *_ in entity.edge_list():
                assert src < len(entity.nodes) and dst < len(entity.nodes)


def test_fsm_size_entropy_follows_the_original_binning():
    def world_of(sizes):
        classes = {c: EntityClass(c, node_types(CHARACTERS)[:n], {}) for c, n in zip(CHARACTERS, sizes)}
        return FortressFile(classes=classes)

    assert fsm_size_entropy(world_of([1] * 15)) == 0.0  # one bin
    # The original bins size - 1 over [1, 94] into 15 bins, so the last bin needs 95 nodes: 14 bins are reachable.
    spread = [2 + int(np.ceil(93 * k / 14)) for k in range(14)] + [2]
    assert len({int((s - 2) / 93 * 14) for s in spread}) == 14 and max(spread) <= 94
    share = np.array([2] + [1] * 13) / 15
    assert fsm_size_entropy(world_of(spread)) == pytest.approx(-(share * np.log(share)).sum() / np.log(15))
    half = [1] * 7 + [94] * 8  # two bins, 7 and 8 classes
    share = np.array([7, 8]) / 15
    assert fsm_size_entropy(world_of(half)) == pytest.approx(-(share * np.log(share)).sum() / np.log(15))
