"""Meshes: spheres and cylinders of the physics model's size, and exports that load back in trimesh."""

from __future__ import annotations

import os

import numpy as np
import pytest
import trimesh

from structgen import Structure, StructureError
from structgen.mesh import MeshStyle

SPHERE = trimesh.creation.icosphere(subdivisions=MeshStyle().sphere_subdivisions)


def column(n: int) -> Structure:
    return Structure([[0, 0, z] for z in range(n)], [[z, z + 1] for z in range(n - 1)])


def diagonal() -> Structure:
    return Structure([[0, 0, 0], [1, 1, 1]], [[0, 1]], {"name": "diagonal"})


def test_mesh_has_one_sphere_per_vertex_and_one_cylinder_per_edge():
    style = MeshStyle()
    mesh = column(3).to_mesh()
    # a cylinder: two side rings and two flat caps (their own rings, plus centres)
    cylinder_vertices = 4 * style.cylinder_sections + 2
    assert len(mesh.vertices) == 3 * len(SPHERE.vertices) + 2 * cylinder_vertices
    assert len(mesh.faces) == 3 * len(SPHERE.faces) + 2 * 4 * style.cylinder_sections


def test_default_dimensions_match_the_physics_model_standing_on_the_ground():
    from physics import PhysicsConfig

    bodies, style = PhysicsConfig(), MeshStyle()
    assert (style.sphere_radius, style.cylinder_radius, style.spacing) == (
        bodies.sphere_radius,
        bodies.cylinder_radius,
        bodies.spacing,
    )
    bounds = column(2).to_mesh().bounds
    np.testing.assert_allclose(bounds, [[-0.25, -0.25, 0.0], [0.25, 0.25, 1.5]], atol=1e-9)
    lifted = Structure([[0, 0, -3], [0, 0, -2]], [[0, 1]]).to_mesh().bounds
    np.testing.assert_allclose(lifted, bounds, atol=1e-9)


def test_cylinders_run_between_sphere_surfaces_along_the_edge():
    style = MeshStyle(sphere_radius=0.2, cylinder_radius=0.05, spacing=2.0)
    mesh = diagonal().to_mesh(sphere_radius=0.2, cylinder_radius=0.05, spacing=2.0)
    rod = mesh.vertices[2 * len(trimesh.creation.icosphere(subdivisions=style.sphere_subdivisions).vertices) :]
    rod = rod - [0, 0, 0.2]  # the lowest sphere's centre sits one radius above the ground
    axis = np.ones(3) / np.sqrt(3)
    along = rod @ axis
    across = np.linalg.norm(rod - along[:, None] * axis, axis=1)
    np.testing.assert_allclose([along.min(), along.max()], [0.2, 2 * np.sqrt(3) - 0.2], atol=1e-9)
    on_rim = np.isclose(across, 0.05, atol=1e-9)
    assert on_rim.sum() >= 2 * style.cylinder_sections and np.all(on_rim | np.isclose(across, 0, atol=1e-9))


def test_normals_are_unit_and_point_outwards():
    mesh = diagonal().to_mesh()
    normals = mesh.vertex_normals
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-9)
    # every triangle's winding agrees with its vertices' normals: faces face outwards
    corners = mesh.vertices[mesh.faces]
    winding = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert (np.einsum("fi,fi->f", winding, normals[mesh.faces].sum(axis=1)) > 0).all()


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply"])
def test_z_up_exports_load_back_with_the_same_geometry(tmp_path, suffix):
    structure = column(3)
    path = structure.export(tmp_path / f"column{suffix}")
    loaded = trimesh.load(path, force="mesh", process=False)
    expected = structure.to_mesh()
    assert len(loaded.faces) == len(expected.faces)
    np.testing.assert_allclose(loaded.bounds, expected.bounds, atol=1e-5)


def test_solid_is_one_watertight_shell(tmp_path):
    structure = Structure([[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 1, 2]], [[0, 1], [1, 2], [2, 3], [0, 2]])
    assert trimesh.load(structure.export(tmp_path / "parts.stl")).body_count > 1  # loose spheres and rods
    solid = trimesh.load(structure.export(tmp_path / "solid.stl", solid=True))
    assert solid.is_watertight and solid.is_volume and solid.body_count == 1
    np.testing.assert_allclose(solid.bounds, structure.to_mesh().bounds, atol=0.02)  # its sphere is turned a little
    scene = trimesh.load(structure.export(tmp_path / "solid.glb", solid=True))
    assert scene.metadata["solid"] is True and len(scene.geometry) == 1


def test_glb_shares_one_sphere_and_one_cylinder_per_axis_and_carries_the_metadata(tmp_path):
    structure = Structure([[0, 0, 0], [0, 0, 1], [0, 1, 2], [0, 1, 3]], [[0, 1], [1, 2], [2, 3]], {"run": "r1", "score": 2.5})
    scene = trimesh.load(structure.export(tmp_path / "s.glb"))
    assert len(scene.geometry) == 1 + 2  # a sphere, an upright cylinder, a diagonal one
    assert len(scene.graph.nodes_geometry) == 4 + 3  # one placed copy per vertex and per edge
    z_up = structure.to_mesh().bounds
    y_up = scene.to_geometry().bounds
    # (x, y, z) -> (x, z, -y): height moves to y, depth to -z; the lowest sphere touches the ground y = 0.
    np.testing.assert_allclose(y_up[:, 0], z_up[:, 0], atol=1e-5)
    np.testing.assert_allclose(y_up[:, 1], z_up[:, 2], atol=1e-5)
    np.testing.assert_allclose(y_up[:, 2], -z_up[::-1, 1], atol=1e-5)
    assert y_up[0, 1] == pytest.approx(0.0, abs=1e-6)
    meta = scene.metadata
    assert meta["up_axis"] == "y" and meta["n_vertices"] == 4 and meta["n_edges"] == 3 and meta["height"] == 3
    assert meta["structure_metadata"] == {"run": "r1", "score": 2.5}


def test_a_large_structure_is_a_small_glb(tmp_path):
    from structgen import LocalNCA, NCAConfig

    big = LocalNCA.random(3, NCAConfig(iterations=6, max_vertices=2500)).grow()
    assert big.n_vertices > 1000
    size = big.export(tmp_path / "big.glb").stat().st_size
    assert size < 600 * big.n_vertices  # about 250 bytes a vertex and its edges' share; the old meshes took 11 KB


def test_structure_without_edges_exports(tmp_path):
    scene = trimesh.load(Structure([[0, 0, 0]], []).export(tmp_path / "lone.glb"))
    assert len(scene.geometry) == 1 and len(scene.graph.nodes_geometry) == 1


def test_json_export_is_the_structure_file(tmp_path):
    assert Structure.load(diagonal().export(tmp_path / "d.json")) == diagonal()


def test_unknown_format_is_refused_and_nothing_is_written(tmp_path):
    with pytest.raises(StructureError, match="unknown export format '.fbx'"):
        column(2).export(tmp_path / "c.fbx")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize(
    "dimensions, message",
    [
        ({"sphere_radius": 0.5}, "less than half the spacing"),
        ({"cylinder_radius": -1.0}, "cylinder_radius"),
        ({"spacing": 0}, "spacing"),
    ],
)
def test_bad_dimensions_are_refused(tmp_path, dimensions, message):
    with pytest.raises(StructureError, match=message):
        column(2).export(tmp_path / "c.stl", **dimensions)
    assert not (tmp_path / "c.stl").exists()


def test_export_overwrites_only_on_success(tmp_path):
    path = column(2).export(tmp_path / "c.stl")
    before = path.read_bytes()
    with pytest.raises(StructureError):
        column(3).export(path, sphere_radius=2.0)
    assert path.read_bytes() == before
    column(3).export(path)
    assert path.read_bytes() != before


@pytest.mark.parametrize("solid", [False, True])
def test_glb_follows_the_gltf_container_rules(tmp_path, solid):
    # The Khronos validator is not available to the tests (it needs node); these are the rules it checks that this
    # writer could break: header and chunk lengths, 4-byte alignment, views inside the buffer, exact POSITION
    # bounds, indices inside their mesh, unit normals, and every mesh, accessor and view used.
    import json
    import struct

    structure = Structure([[0, 0, 0], [1, 0, 0], [1, 1, 1], [1, 1, 2]], [[0, 1], [1, 2], [2, 3]])
    data = structure.export(tmp_path / "s.glb", solid=solid).read_bytes()
    magic, version, total = struct.unpack_from("<4sII", data)
    assert (magic, version, total) == (b"glTF", 2, len(data))
    json_length, json_kind = struct.unpack_from("<I4s", data, 12)
    assert json_kind == b"JSON" and json_length % 4 == 0
    document = json.loads(data[20 : 20 + json_length])
    bin_length, bin_kind = struct.unpack_from("<I4s", data, 20 + json_length)
    assert bin_kind == b"BIN\0" and bin_length % 4 == 0 and 28 + json_length + bin_length == len(data)
    binary = data[28 + json_length :]
    assert document["asset"]["version"] == "2.0" and document["buffers"] == [{"byteLength": bin_length}]
    for view in document["bufferViews"]:
        assert view["byteOffset"] % 4 == 0 and view["byteOffset"] + view["byteLength"] <= bin_length
    kinds = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}
    widths = {"SCALAR": 1, "VEC3": 3}

    def read(index: int) -> np.ndarray:
        accessor = document["accessors"][index]
        view = document["bufferViews"][accessor["bufferView"]]
        dtype, width = kinds[accessor["componentType"]], widths[accessor["type"]]
        assert view["byteLength"] == accessor["count"] * width * np.dtype(dtype).itemsize
        raw = binary[view["byteOffset"] : view["byteOffset"] + view["byteLength"]]
        return np.frombuffer(raw, dtype=dtype).reshape(accessor["count"], width)

    used_accessors = set()
    for mesh in document["meshes"]:
        (primitive,) = mesh["primitives"]
        position, normal, indices = primitive["attributes"]["POSITION"], primitive["attributes"]["NORMAL"], primitive["indices"]
        used_accessors |= {position, normal, indices}
        points = read(position)
        assert document["accessors"][position]["min"] == points.min(axis=0).tolist()
        assert document["accessors"][position]["max"] == points.max(axis=0).tolist()
        np.testing.assert_allclose(np.linalg.norm(read(normal), axis=1), 1.0, atol=1e-5)
        triangles = read(indices)
        assert len(triangles) % 3 == 0 and triangles.max() < len(points)
        assert primitive["material"] < len(document["materials"])
    assert used_accessors == set(range(len(document["accessors"])))
    assert {a["bufferView"] for a in document["accessors"]} == set(range(len(document["bufferViews"])))
    placed = {node["mesh"] for node in document["nodes"] if "mesh" in node}
    assert placed == set(range(len(document["meshes"])))
