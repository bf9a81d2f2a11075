"""The compiled fortress engine held to the plain reference (tests/fortress/reference_fortress.py) step for step, on
every shipped fortress file and on random and mutated worlds; the settings that depart from the original's code; its
refusals."""

from __future__ import annotations

import numpy as np
import pytest

from structgen.domains.fortress.engine import CAUSES, POPULATION_CAP, Rules, simulate
from structgen.domains.fortress.formats import parse_fortress, read_fortress_file
from structgen.domains.fortress.world import mutate_world, random_world
from structgen.errors import InputError
from tests import reference
from tests.fortress.reference_fortress import ReferenceFortress

DATA = reference.folder("amorphous-fortress")
SHIPPED = sorted((DATA / "FORTS").glob("*.txt")) + sorted((DATA / "QD_EXP" / "SAVED_FORTS").glob("*.txt"))
needs_data = reference.needs("amorphous-fortress")


def assert_matches_reference(worlds, seeds, steps):
    outcome = simulate(worlds, seeds, steps, record=True)
    for w, world in enumerate(worlds):
        for s, seed in enumerate(seeds):
            reference = ReferenceFortress(world, seed)
            states = reference.run(steps)
            got = outcome.traces[w][s].entities
            first = next((t for t, (a, b) in enumerate(zip(states, got)) if a != b), None)
            assert len(states) == len(got) and first is None, f"world {w} seed {seed}: first differs at tick {first}"
            assert outcome.visit_sets(w, s, worlds) == reference.visits
            assert outcome.fitness[w, s] == pytest.approx(reference.fitness())
            assert outcome.ticks[w, s] == reference.ticks


@needs_data
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_every_shipped_fortress_runs_as_the_reference_does(path):
    assert_matches_reference([read_fortress_file(path)], [0, 7], 100)


@needs_data
def test_the_shipped_entity_files_run_together_as_the_reference_does():
    # Every class of ENT/ in one world (duck and poke_trainer are both '@': one world each), two of each placed.
    from structgen.domains.fortress.formats import FortressFile, read_entity_file

    files = sorted((DATA / "ENT").glob("*.txt"))
    worlds = []
    for left_out in ("duck.txt", "poke_trainer.txt"):
        classes = {e.char: e for e in (read_entity_file(f) for f in files if f.name != left_out)}
        initial = [(c, 1 + (2 * k + j) % 13, 1 + (2 * k + j) // 13) for k, c in enumerate(classes) for j in range(2)]
        worlds.append(FortressFile(classes=classes, initial=initial, placed_by="pos"))
    assert_matches_reference(worlds, [0, 1, 2], 100)


def test_random_and_mutated_worlds_run_as_the_reference_does():
    rng = np.random.default_rng(11)
    worlds = [random_world(rng) for _ in range(4)]
    worlds += [mutate_world(w, rng) for w in worlds]
    # The engine runs the array genomes; the reference reads the same worlds as fortress files.
    assert_matches_reference([w.to_file() for w in worlds], [3, 4], 40)


TWO = """\
A
-- NODES --
0: idle
1: move
-- EDGES --
0-1: nextTo B

B
-- NODES --
0: idle
-- EDGES --

-- INIT ENT POS --
A-[3, 3]
B-[4, 4]
"""


def _final(text, rules, steps=1, seed=0):
    outcome = simulate([parse_fortress(text)], [seed], steps, rules, record=True)
    return outcome, outcome.traces[0][0].entities[-1]


def test_next_to_is_chebyshev_in_the_code_and_orthogonal_on_request():
    outcome, _ = _final(TWO, Rules())
    assert outcome.visit_sets(0, 0, [parse_fortress(TWO)])["A"]["edges"] == {"0-1"}  # diagonal counts
    outcome, _ = _final(TWO, Rules(next_to="orthogonal"))
    assert outcome.visit_sets(0, 0, [parse_fortress(TWO)])["A"]["edges"] == set()


TAKER = """\
A
-- NODES --
0: take B
-- EDGES --

B
-- NODES --
0: idle
-- EDGES --

-- INIT ENT POS --
A-[1, 1]
B-[13, 6]
"""


def test_take_reaches_across_the_map_unless_limited():
    _, final = _final(TAKER, Rules())
    assert [e[0] for e in final] == ["A"]
    _, final = _final(TAKER, Rules(take_reach=1))
    assert [e[0] for e in final] == ["A", "B"]


WALL = """\
C
-- NODES --
0: idle
-- EDGES --

B
-- NODES --
0: chase C
-- EDGES --

A
-- NODES --
0: idle
1: move_wall B
-- EDGES --
0-1: step 2

-- INIT ENT POS --
C-[3, 2]
B-[4, 2]
A-[2, 2]
"""


def test_move_wall_is_blocked_only_by_the_first_entity_on_the_tile_unless_any():
    # B chases C onto C's tile (one direction: no draw); A's first move_wall, at tick 3, is the first draw.
    world = parse_fortress(WALL)
    seeds = list(range(16))
    first = simulate([world], seeds, 3, Rules(), record=True).traces[0]
    any_b = simulate([world], seeds, 3, Rules(wall_blocks="any"), record=True).traces[0]
    east = [s for s in seeds if first[s].entities[-1][2][1:3] == (3, 2)]
    assert east, "no seed sent A east"
    for s in seeds:
        assert first[s].entities[-1][1][1:3] == (3, 2)  # B sits on C's tile, C created first
        a_first, a_any = first[s].entities[-1][2], any_b[s].entities[-1][2]
        assert a_any[1:3] == ((2, 2) if s in east else a_first[1:3])


IDLE = """\
A
-- NODES --
0: idle
1: idle
-- EDGES --
0-1: step 5
1-0: step 5

-- INIT ENT POS --
A-[5, 5]
"""


def test_the_inactivity_stop_is_off_as_in_the_original_and_available():
    outcome, _ = _final(IDLE, Rules(), steps=100)
    assert CAUSES[outcome.cause[0, 0]] == "steps" and outcome.ticks[0, 0] == 100
    outcome, _ = _final(IDLE, Rules(inactivity_limit=20), steps=100)
    assert CAUSES[outcome.cause[0, 0]] == "inactive" and outcome.ticks[0, 0] == 21


def test_start_nodes_count_only_after_an_update_unless_asked():
    world = parse_fortress(IDLE)
    outcome = simulate([world], [0], 1, Rules())
    assert outcome.visit_sets(0, 0, [world])["A"]["nodes"] == {0}  # it stays on node 0 after its first update
    outcome = simulate([world], [0], 0, Rules())
    assert outcome.visit_sets(0, 0, [world])["A"]["nodes"] == set()
    outcome = simulate([world], [0], 0, Rules(visit_start_nodes=True))
    assert outcome.visit_sets(0, 0, [world])["A"]["nodes"] == {0}


CLONER = """\
A
-- NODES --
0: clone
-- EDGES --

-- INIT ENT POS --
A-[6, 3]
"""


@needs_data
def test_a_world_that_overpopulates_stops_above_the_cap():
    outcome = simulate([read_fortress_file(DATA / "FORTS" / "overpop.txt")], [0, 1], 200)
    assert (outcome.entities > POPULATION_CAP).all() and (outcome.ticks < 200).all()
    assert [CAUSES[c] for c in outcome.cause[0]] == ["overpopulated", "overpopulated"]


def test_results_depend_on_world_and_seed_only():
    rng = np.random.default_rng(5)
    worlds = [random_world(rng) for _ in range(5)]
    together = simulate(worlds, [0, 1, 2], 50)
    apart = simulate(worlds, [0, 1, 2], 50, chunk=2)
    alone = simulate(worlds[3:4], [1], 50)
    assert np.array_equal(together.fitness, apart.fitness) and np.array_equal(together.visits, apart.visits)
    assert together.fitness[3, 1] == alone.fitness[0, 0] and together.entities[3, 1] == alone.entities[0, 0]
    assert not np.array_equal(together.visits[:, 0], together.visits[:, 1])  # seeds matter


def test_placements_on_a_taken_tile_are_dropped():
    world = parse_fortress(CLONER.replace("A-[6, 3]\n", "A-[6, 3]\nA-[6, 3]\nA-[7, 3]\n"))
    trace = simulate([world], [0], 0, record=True).traces[0][0]
    assert trace.entities[0] == [("A", 6, 3, 0), ("A", 7, 3, 0)]


def test_making_a_class_the_world_lacks_is_refused_with_its_place():
    text = CLONER.replace("0: clone", "0: add Z")
    with pytest.raises(InputError, match=r"mine.txt: class 'A' node 0 \('add Z'\)"):
        simulate([parse_fortress(text)], [0], 5, where=["mine.txt"])
    # Conditions and targets naming it simply never hold.
    quiet = CLONER.replace("0: clone\n-- EDGES --\n", "0: take Z\n1: idle\n-- EDGES --\n0-1: touch Z\n")
    outcome = simulate([parse_fortress(quiet)], [0], 5)
    assert outcome.entities[0, 0] == 1 and outcome.visited_edges[0, 0] == 0


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="steps"):
        simulate([parse_fortress(CLONER)], [0], -1)
    with pytest.raises(ValueError, match="seed"):
        simulate([parse_fortress(CLONER)], [], 5)
    with pytest.raises(ValueError, match="next_to"):
        Rules(next_to="diagonal")
