"""The Structure type: validation with clear messages, JSON files, metrics."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from structgen import Structure, StructureError


def l_shape() -> Structure:
    return Structure([[0, 0, 0], [1, 0, 0], [1, 0, 1], [1, 1, 2]], [[0, 1], [1, 2], [2, 3]])


# -- construction and validation ----------------------------------------------------------------------------------------
def test_valid_structure_keeps_its_data():
    s = l_shape()
    assert s.vertices.dtype == np.int64 and s.vertices.shape == (4, 3)
    assert s.edges.tolist() == [[0, 1], [1, 2], [2, 3]]
    assert s.n_vertices == 4 and s.n_edges == 3


def test_edges_are_stored_smaller_index_first_in_given_order():
    s = Structure([[0, 0, 0], [0, 0, 1], [0, 1, 1]], [[2, 1], [1, 0]])
    assert s.edges.tolist() == [[1, 2], [0, 1]]


def test_integral_floats_are_accepted_as_lattice_coordinates():
    s = Structure([[0.0, 0, 0], [1.0, 1.0, 1.0]], [[0, 1]])
    assert s.vertices.tolist() == [[0, 0, 0], [1, 1, 1]]


def test_all_26_neighbour_directions_are_valid_edges():
    offsets = [[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1) if (x, y, z) != (0, 0, 0)]
    s = Structure([[0, 0, 0], *offsets], [[0, i] for i in range(1, 27)])
    assert s.n_edges == 26


def test_structure_is_immutable():
    s = l_shape()
    with pytest.raises(ValueError):
        s.vertices[0, 0] = 5
    with pytest.raises(ValueError):
        s.edges[0, 0] = 2
    meta = Structure([[0, 0, 0]], [], {"a": 1})
    meta.metadata["a"] = 2
    assert meta.metadata == {"a": 1}


@pytest.mark.parametrize(
    "vertices, edges, message",
    [
        ("not a list", [], "vertices: expected a list of \\[x, y, z\\] triples, got str"),
        ([[0, 0]], [], r"vertices\[0\] = \[0, 0\]: expected 3 integers"),
        ([[0, 0, 0], [0, 0, 0.5]], [], r"vertices\[1\] = \[0, 0, 0.5\]: entry 2 is 0.5, not an integer"),
        ([[0, 0, 0], [0, "1", 0]], [], r"vertices\[1\].*entry 1 is '1' \(str\), not an integer"),
        ([[0, 0, True]], [], r"vertices\[0\].*\(bool\), not an integer"),
        ([[0, 0, None]], [], r"vertices\[0\].*\(NoneType\), not an integer"),
        ([[0, 0, float("nan")]], [], r"vertices\[0\].*not an integer"),
        ([], [], "at least one vertex"),
        ([[0, 0, 0], [0, 0, 1], [0, 0, 0]], [], r"vertices\[2\] duplicates vertices\[0\]: \[0, 0, 0\]"),
        ([[0, 0, 0], [0, 0, 1]], [[0, 2]], r"edges\[0\] = \[0, 2\]: vertex index 2 out of range \(the structure has 2"),
        ([[0, 0, 0], [0, 0, 1]], [[-1, 0]], r"edges\[0\] = \[-1, 0\]: vertex index -1 out of range"),
        ([[0, 0, 0], [0, 0, 1]], [[1, 1]], r"edges\[0\] = \[1, 1\]: joins vertex 1 to itself"),
        ([[0, 0, 0], [0, 0, 2]], [[0, 1]], r"joins \[0, 0, 0\] and \[0, 0, 2\], which are not lattice neighbours"),
        ([[0, 0, 0], [0, 0, 1]], [[0, 1], [1, 0]], r"edges\[1\] repeats edges\[0\]: \[0, 1\]"),
        ([[0, 0, 0], [0, 0, 1]], [[0, 1, 1]], r"edges\[0\] = \[0, 1, 1\]: expected 2 integers"),
        ([[0, 0, 0], [0, 0, 1]], [[0, 0.5]], r"edges\[0\].*not an integer"),
        ([[0, 0, 10**12]], [], r"vertices\[0\].*out of range"),
        (np.zeros((2, 3, 1)), [], r"vertices: expected shape \(n, 3\)"),
        (np.array([[0.0, 0.0, 0.25]]), [], r"vertices\[0\] = \[0.0, 0.0, 0.25\]: entry 2 is 0.25, not an integer"),
        (np.array([["a", "b", "c"]]), [], "expected integers, got an array of dtype"),
    ],
)
def test_bad_structures_raise_a_value_error_naming_the_problem(vertices, edges, message):
    with pytest.raises(StructureError, match=message) as err:
        Structure(vertices, edges)
    assert isinstance(err.value, ValueError)


def test_metadata_must_be_an_object_with_string_keys():
    with pytest.raises(StructureError, match="metadata"):
        Structure([[0, 0, 0]], [], {1: "x"})


# -- metrics ----------------------------------------------------------------------------------------------------------
def test_metrics_of_an_l_shape():
    s = l_shape()
    assert s.height == 2
    assert s.bounds.tolist() == [[0, 0, 0], [1, 1, 2]]
    assert s.degrees().tolist() == [1, 2, 2, 1]
    assert s.n_components == 1


def test_components_count_pieces_and_lone_vertices():
    s = Structure([[0, 0, 0], [0, 0, 1], [5, 5, 5], [5, 5, 6], [9, 9, 9]], [[0, 1], [2, 3]])
    assert s.component_labels().tolist() == [0, 0, 1, 1, 2]
    summary = s.summary()
    assert summary["components"] == 3 and summary["isolated_vertices"] == 1
    assert summary["vertices"] == 5 and summary["edges"] == 2 and summary["height"] == 9
    assert summary["size"] == [9, 9, 9] and summary["max_degree"] == 1


def test_single_vertex_structure_has_zero_height():
    s = Structure([[3, 4, 5]], [])
    assert s.height == 0 and s.n_components == 1 and s.n_edges == 0


def test_equality_compares_geometry_and_metadata():
    assert l_shape() == l_shape()
    assert l_shape() != l_shape().with_metadata(run="x")
    assert l_shape() != Structure([[0, 0, 0]], [])


# -- files ------------------------------------------------------------------------------------------------------------
def test_the_minimal_file_format_always_loads(tmp_path):
    path = tmp_path / "s.json"
    path.write_text('{"vertices": [[0, 0, 0], [0, 0, 1]], "edges": [[0, 1]]}')
    s = Structure.load(path)
    assert s.vertices.tolist() == [[0, 0, 0], [0, 0, 1]] and s.edges.tolist() == [[0, 1]]


def test_save_and_load_round_trip_with_metadata(tmp_path):
    s = l_shape().with_metadata(generator="test", score=1.5, tags=["a"])
    path = s.save(tmp_path / "deep" / "folder" / "s.json")
    assert Structure.load(path) == s
    assert json.loads(path.read_text())["metadata"]["generator"] == "test"


def test_empty_edge_list_round_trips(tmp_path):
    s = Structure([[0, 0, 0]], [])
    assert Structure.load(s.save(tmp_path / "lone.json")) == s


@pytest.mark.parametrize(
    "content, message",
    [
        ('{"vertices": [[0, 0, 0]], "edges": [], "colour": 1}', "unknown field 'colour'"),
        ('{"vertices": [[0, 0, 0]]}', "missing field 'edges'"),
        ('{"edges": []}', "missing field 'vertices'"),
        ("[1, 2]", "expected a JSON object"),
        ('{"vertices": [[0, 0, 0]], "edges": [}', r"not valid JSON \(line 1, column"),
        ('{"vertices": [[0, 0, 0], [0, 0, 3]], "edges": [[0, 1]]}', r"edges\[0\] = \[0, 1\]"),
        ('{"vertices": [[0, 0, 0]], "edges": [], "metadata": []}', "metadata: expected an object"),
    ],
)
def test_bad_files_name_the_file_and_the_problem(tmp_path, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(StructureError, match=message) as err:
        Structure.load(path)
    assert str(err.value).startswith(f"{path}: ")


def test_binary_file_is_rejected_cleanly(tmp_path):
    path = tmp_path / "model.json"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    with pytest.raises(StructureError, match="not a text file"):
        Structure.load(path)


def test_a_file_that_cannot_be_read_is_a_structure_error_naming_it(tmp_path):
    with pytest.raises(StructureError, match="absent.json: no such file"):
        Structure.load(tmp_path / "absent.json")
    with pytest.raises(StructureError, match="is a folder"):
        Structure.load(tmp_path)


def test_save_refuses_non_json_names(tmp_path):
    with pytest.raises(StructureError, match="use export"):
        l_shape().save(tmp_path / "s.glb")
    assert not (tmp_path / "s.glb").exists()


@pytest.mark.parametrize("metadata", [{"when": object()}, {"x": float("nan")}, {"x": [float("inf")]}])
def test_metadata_that_json_cannot_hold_is_refused_when_made(metadata):
    with pytest.raises(StructureError, match="metadata: must be JSON with finite numbers"):
        Structure([[0, 0, 0]], [], metadata)


def test_failed_save_leaves_the_existing_file_untouched(tmp_path, monkeypatch):
    import errno

    path = l_shape().save(tmp_path / "s.json")
    before = path.read_bytes()

    def disk_full(*args):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "replace", disk_full)
    with pytest.raises(OSError, match="No space left"):
        l_shape().with_metadata(note="new").save(path)
    assert path.read_bytes() == before
    assert os.listdir(tmp_path) == ["s.json"]  # no temporary file left behind


def test_in_growth_order_lists_any_ordering_of_a_grown_structure_as_growth_did():
    from structgen.nca import NCAConfig, grow, n_params

    grown = grow(np.random.default_rng(3).normal(0, 0.3, n_params(NCAConfig())), NCAConfig(iterations=6))
    assert grown.n_edges > 10
    rng = np.random.default_rng(0)
    order = rng.permutation(grown.n_vertices)
    rank = np.argsort(order)
    shuffled = Structure(grown.vertices[order], rank[grown.edges][rng.permutation(grown.n_edges)], grown.metadata)
    assert shuffled != grown
    assert shuffled.in_growth_order() == grown
    assert grown.in_growth_order() == grown
