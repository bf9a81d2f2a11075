"""The local NCA: weight layout, each growth rule on hand-made networks, batched growth against the oracle."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from structgen import LocalNCA, NCAConfig, Structure, grow, grow_population, random_weights
from structgen.lattice import offset_index
from structgen.nca import grow_steps, load_weights, n_params, save_weights

from .reference_nca import reference_grow

UP, DOWN = int(offset_index(np.array([0, 0, 1]))), int(offset_index(np.array([0, 0, -1])))
EAST, NORTH = int(offset_index(np.array([1, 0, 0]))), int(offset_index(np.array([0, 1, 0])))
CONNECTIONS = slice(26, 52)  # inputs 26..51 are the connection flags


def network(hidden: int = 2, *, w1=None, b1=None, w2=None, b2=None) -> np.ndarray:
    """Flat weights of a hand-made 52-hidden-26 network; unspecified parts are zero."""
    parts = [
        np.zeros((52, hidden)) if w1 is None else w1,
        np.zeros(hidden) if b1 is None else b1,
        np.zeros((hidden, 26)) if w2 is None else w2,
        np.full(26, -1.0) if b2 is None else b2,
    ]
    return np.concatenate([np.asarray(p, dtype=float).ravel() for p in parts])


def constant_wishes(*directions: int) -> np.ndarray:
    """A network that wishes for the same neighbours whatever it sees."""
    b2 = np.full(26, -1.0)
    b2[list(directions)] = 1.0
    return network(b2=b2)


def column(n: int) -> Structure:
    return Structure([[0, 0, z] for z in range(n)], [[z, z + 1] for z in range(n - 1)])


def geometry(s: Structure) -> tuple[list, list]:
    return s.vertices.tolist(), s.edges.tolist()


def config(**changes) -> NCAConfig:
    return NCAConfig(hidden=2, **changes)


# -- weights ------------------------------------------------------------------------------------------------------------
def test_paper_network_has_4766_parameters_in_documented_order():
    assert n_params() == 52 * 60 + 60 + 60 * 26 + 26 == 4766
    flat = np.arange(4766, dtype=float)
    w1, b1, w2, b2 = LocalNCA(flat).layers()
    assert w1.shape == (52, 60) and w1[0, 1] == 1 and w1[1, 0] == 60
    assert b1[0] == 3120 and w2.shape == (60, 26) and w2[0, 0] == 3180 and b2[-1] == 4765


def test_weights_get_set_round_trip_and_copy():
    nca = LocalNCA.random(seed=4)
    weights = nca.get_weights()
    weights[0] += 1.0  # editing the copy must not touch the NCA
    assert nca.get_weights()[0] != weights[0]
    other = LocalNCA()
    other.set_weights(nca.get_weights())
    assert np.array_equal(other.get_weights(), nca.get_weights())
    assert other.grow() == nca.grow()


@pytest.mark.parametrize(
    "bad, message",
    [(np.zeros(10), "expected 4766 weights"), (np.full(4766, np.nan), "finite"), (np.zeros((2, 4766)), "one flat vector")],
)
def test_bad_weights_are_rejected(bad, message):
    with pytest.raises(ValueError, match=message):
        LocalNCA().set_weights(bad)


def test_random_nca_is_reproducible_from_its_seed():
    assert np.array_equal(LocalNCA.random(7).get_weights(), LocalNCA.random(7).get_weights())
    assert not np.array_equal(LocalNCA.random(7).get_weights(), LocalNCA.random(8).get_weights())
    assert LocalNCA.random(7).grow() == LocalNCA.random(7).grow()
    assert np.abs(random_weights(3, 0)).max() <= 0.25


@pytest.mark.parametrize("suffix", [".npy", ".json"])
def test_weights_files_round_trip_exactly(tmp_path, suffix):
    weights = random_weights(1, 11)[0]
    path = save_weights(tmp_path / f"w{suffix}", weights)
    assert np.array_equal(load_weights(path), weights)


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("short.json", "[1, 2, 3]", "holds 3 weights"),
        ("text.json", '{"w": []}', "'weights' list"),
        ("strings.json", '["a"]', "flat list of numbers"),
        ("broken.json", "[1, 2", "not valid JSON"),
        ("weights.txt", "1 2 3", "unknown weights format"),
    ],
)
def test_bad_weights_files_name_the_file_and_problem(tmp_path, name, content, message):
    path = tmp_path / name
    path.write_text(content)
    with pytest.raises(ValueError, match=message) as err:
        load_weights(path)
    assert name in str(err.value)


@pytest.mark.parametrize(
    "field, value",
    [
        ("cutoff", 0.0),
        ("cutoff", 1.0),
        ("iterations", -1),
        ("hidden", 0),
        ("max_vertices", 0),
        ("max_extent", 0),
        ("build_down", 1),
    ],
)
def test_config_rejects_bad_values_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        NCAConfig(**{field: value})


# -- growth rules on hand-made networks ---------------------------------------------------------------------------------
def test_network_that_never_fires_leaves_the_lone_seed():
    assert geometry(grow(network(), config(iterations=5))) == ([[0, 0, 0]], [])


@pytest.mark.parametrize("steps", [0, 1, 2, 5])
def test_growth_is_synchronous_one_layer_per_step(steps):
    # Each vertex wishes only "up": if new vertices could act in the step that made them, the column would race ahead.
    assert geometry(grow(constant_wishes(UP), config(iterations=steps))) == geometry(column(steps + 1))


def test_edge_wanted_by_one_end_only_is_kept():
    # In the column only the lower end of each edge wishes for it; the edges must all survive.
    structure = grow(constant_wishes(UP), config(iterations=4))
    assert structure.n_edges == 4


def test_new_vertex_wished_by_several_joins_all_and_unwished_neighbours_stay_apart():
    structure = grow(constant_wishes(EAST, NORTH), config(iterations=3))
    cells = {tuple(v) for v in structure.vertices.tolist()}
    assert cells == {(i, j, 0) for i in range(4) for j in range(4) if i + j <= 3}
    ends = {frozenset(map(tuple, structure.vertices[e].tolist())) for e in structure.edges}
    # (1, 1, 0) was wished for by both (1, 0, 0) and (0, 1, 0) in the same step.
    assert frozenset({(1, 0, 0), (1, 1, 0)}) in ends and frozenset({(0, 1, 0), (1, 1, 0)}) in ends
    # Only axis steps were ever wished: neighbours on a diagonal are never joined.
    assert all(np.abs(structure.vertices[a] - structure.vertices[b]).sum() == 1 for a, b in structure.edges)
    assert structure.n_edges == 12


def lonely_climber(hidden: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Hidden unit 0 is 1 when the vertex has no edges; output UP fires iff unit 0 or unit 1 is on."""
    w1, b1, w2, b2 = np.zeros((52, hidden)), np.zeros(hidden), np.zeros((hidden, 26)), np.full(26, -1.0)
    w1[CONNECTIONS, 0] = -1.0
    b1[0] = 1.0
    w2[:, UP] = 2.0
    return w1, b1, w2, b2


@pytest.mark.parametrize(
    "steps, expected",
    [(1, column(2)), (2, Structure([[0, 0, 0]], [])), (3, column(2)), (4, Structure([[0, 0, 0]], []))],
)
def test_edges_nobody_wants_go_and_vertices_left_without_edges_are_pruned(steps, expected):
    # Alone -> wish up; once joined, nobody wishes: the edge goes, the top vertex is pruned, the seed stays.
    w1, b1, w2, b2 = lonely_climber()
    assert geometry(grow(network(w1=w1, b1=b1, w2=w2, b2=b2), config(iterations=steps))) == geometry(expected)


def test_inputs_are_occupancy_flags_then_connection_flags_in_neighbour_order():
    # Unit 1 reads one input: "a vertex below me" (occupancy) or "joined to a vertex below me" (connection).
    w1, b1, w2, b2 = lonely_climber()
    w1[DOWN, 1] = 1.0
    by_occupancy = grow(network(w1=w1, b1=b1, w2=w2, b2=b2), config(iterations=3))
    assert geometry(by_occupancy) == geometry(column(4))

    w1, b1, w2, b2 = lonely_climber()
    w1[26 + DOWN, 1] = 1.0
    by_connection = grow(network(w1=w1, b1=b1, w2=w2, b2=b2), config(iterations=3))
    # Step 2 cuts the seed loose; in step 3 the seed rejoins (0,0,1), which no longer has an edge below and lets go
    # of (0,0,2), which does and grows (0,0,3).
    assert geometry(by_connection) == ([[0, 0, 0], [0, 0, 1], [0, 0, 2], [0, 0, 3]], [[0, 1], [2, 3]])


def test_no_build_down_rule_drops_wishes_below_the_seed():
    down_and_east = constant_wishes(DOWN, EAST)
    free = grow(down_and_east, config(iterations=3))
    assert free.vertices[:, 2].min() == -3
    ruled = grow(down_and_east, config(iterations=3, build_down=False))
    assert geometry(ruled) == ([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]], [[0, 1], [1, 2], [2, 3]])


def test_cutoff_decides_which_outputs_fire():
    b2 = np.full(26, -1.0)
    b2[UP] = math.log(0.55 / 0.45)  # sigmoid = 0.55
    weights = network(b2=b2)
    assert grow(weights, config(iterations=2, cutoff=0.5)).n_vertices == 3
    assert grow(weights, config(iterations=2, cutoff=0.6)).n_vertices == 1


def test_outputs_too_close_to_the_cutoff_for_float32_are_decided_exactly():
    # z = (1 + 1e-9) - 1 = 1e-9 > 0 fires in exact arithmetic; float32 rounds the bias to 1 and would say 0.
    w1, b1, w2, b2 = np.zeros((52, 2)), np.array([1.0, 0.0]), np.zeros((2, 26)), np.full(26, -1.0)
    w2[0, UP] = -1.0
    b2[UP] = 1.0 + 1e-9
    assert geometry(grow(network(w1=w1, b1=b1, w2=w2, b2=b2), config(iterations=3))) == geometry(column(4))
    b2[UP] = 1.0 - 1e-9
    assert grow(network(w1=w1, b1=b1, w2=w2, b2=b2), config(iterations=3)).n_vertices == 1


def test_max_extent_drops_wishes_beyond_the_box_and_says_so():
    capped = grow(constant_wishes(UP), config(iterations=5, max_extent=2))
    assert geometry(capped) == geometry(column(3))
    assert capped.metadata["growth"]["hit_max_extent"] is True
    within = grow(constant_wishes(UP), config(iterations=2, max_extent=2))
    assert within.metadata["growth"]["hit_max_extent"] is False


def test_a_box_keeps_growth_inside_it_and_a_cube_box_is_max_extent():
    weights = random_weights(40, seed=5, config=config(iterations=4))
    boxes = np.array([[[-1, 2], [0, 1], [-3, 0]], [[-4, 4], [-4, 4], [-4, 4]]] * 20)
    boxed = grow_population(weights, config(iterations=4), boxes)
    for w, box, structure in zip(weights, boxes, boxed):
        assert (structure.vertices >= box[:, 0]).all() and (structure.vertices <= box[:, 1]).all()
        assert structure.metadata["growth"]["box"] == box.tolist()
        # One by one, the same; a box as large as the growth box is no box.
        assert geometry(grow(w, config(iterations=4), box=box)) == geometry(structure)
        if box[0, 0] == -4:
            assert geometry(structure) == geometry(grow(w, config(iterations=4, max_extent=4)))
    assert len({s.n_vertices for s in boxed[0::2]}) > 3  # varied, not all lone seeds
    column_in_box = grow(constant_wishes(UP), config(iterations=5), box=[[0, 0], [0, 0], [0, 2]])
    assert geometry(column_in_box) == geometry(column(3)) and column_in_box.metadata["growth"]["hit_max_extent"]


@pytest.mark.parametrize("box, message", [([[1, 2], [0, 0], [0, 0]], "hold the seed"), ([[0, 1]], "shaped"),
                                          ([[0.5, 1], [0, 0], [0, 0]], "whole numbers")])  # fmt: skip
def test_a_box_without_the_seed_or_of_the_wrong_shape_is_refused(box, message):
    with pytest.raises(ValueError, match=message):
        grow(constant_wishes(UP), config(iterations=2), box=box)


def test_growth_stops_at_a_fixed_point_and_says_so():
    # The column reaches the top of its box after 2 steps; every later step would change nothing.
    stopped = grow(constant_wishes(UP), config(iterations=10_000, max_extent=2))
    growth = stopped.metadata["growth"]
    assert geometry(stopped) == geometry(column(3))
    assert growth["reached_fixed_point"] is True and growth["iterations_run"] == 2
    assert grow(constant_wishes(UP), config(iterations=2, max_extent=2)).metadata["growth"]["reached_fixed_point"] is False


def test_grow_steps_gives_the_structure_after_every_step_that_changed_something():
    weights = random_weights(1, seed=4, config=NCAConfig(hidden=8))[0]
    nca_config = NCAConfig(hidden=8, iterations=4)
    frames = grow_steps(weights, nca_config)
    assert geometry(frames[0]) == ([[0, 0, 0]], [])
    assert frames[-1] == grow(weights, nca_config)
    for k, frame in enumerate(frames[:-1]):
        assert geometry(frame) == geometry(grow(weights, replace(nca_config, iterations=k)))
    assert len(grow_steps(constant_wishes(UP), config(iterations=50, max_extent=3))) == 4  # seed + 3 steps


@pytest.mark.parametrize("limit, vertices, steps", [(30, 27, 1), (27, 27, 1), (26, 1, 0)])
def test_max_vertices_discards_the_step_that_would_exceed_it_and_stops(limit, vertices, steps):
    everywhere = network(b2=np.ones(26))
    structure = grow(everywhere, config(iterations=3, max_vertices=limit))
    growth = structure.metadata["growth"]
    assert structure.n_vertices == vertices and growth["iterations_run"] == steps
    assert growth["hit_max_vertices"] is True
    if vertices == 27:  # the seed joined to all 26 neighbours, which were not yet there to wish for each other
        assert structure.n_edges == 26


# -- batched growth -----------------------------------------------------------------------------------------------------
CONFIGS = [
    NCAConfig(),
    NCAConfig(cutoff=0.6, build_down=False),
    NCAConfig(iterations=6, max_extent=3, max_vertices=150),
    NCAConfig(hidden=8, iterations=3),
]


@pytest.mark.parametrize("seed, nca_config", list(enumerate(CONFIGS)), ids=["paper", "cutoff0.6-nodown", "caps", "hidden8"])
def test_batched_growth_equals_one_by_one_and_the_reference(seed, nca_config):
    weights = random_weights(12, seed=seed, config=nca_config)
    batched = grow_population(weights, nca_config)
    assert len(batched) == len(weights)
    for w, structure in zip(weights, batched):
        assert grow(w, nca_config) == structure
        assert reference_grow(w, nca_config) == structure
        # The batched engine skips validation; the public constructor must accept its output.
        Structure(structure.vertices, structure.edges)


def test_batched_growth_of_many_random_ncas_equals_one_by_one():
    weights = random_weights(100, seed=123)
    batched = grow_population(weights)
    assert [grow(w) for w in weights] == batched
    assert len({s.n_vertices for s in batched}) > 10  # a varied population, not 100 copies of one case


def test_grown_structures_are_canonical_and_start_at_the_seed():
    structure = LocalNCA.random(5).grow()
    v = structure.vertices.tolist()
    assert v == sorted(v) and [0, 0, 0] in v
    e = structure.edges.tolist()
    assert e == sorted(e) and all(i < j for i, j in e)
