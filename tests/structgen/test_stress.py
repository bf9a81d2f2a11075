"""Where a structure is stressed: members' static load shares, their colours in pictures and meshes, and --stress."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest
import trimesh

from physics import PhysicsConfig
from physics.statics import check_statics_with_loads
from structgen import Structure
from structgen.cli import main
from structgen.domains.structures.stress import (
    LOAD_SCALE,
    NO_ANSWER,
    OVERLOADED,
    level_shares,
    load_colours,
    member_load_shares,
    member_peak_shares,
)


def leaning_frame() -> Structure:
    """Three posts, braces to a hub and an apex: members along seven axes, loaded unevenly, standing."""
    vertices = [[0, 0, 0], [0, 0, 1], [2, 0, 0], [2, 0, 1], [1, 2, 0], [1, 2, 1], [1, 1, 1], [1, 0, 2]]
    edges = [[0, 1], [2, 3], [4, 5], [1, 6], [3, 6], [5, 6], [1, 7], [3, 7], [0, 6]]
    return Structure(vertices, edges)


def _rgb(colour: str) -> list[int]:
    return [int(colour[i : i + 2], 16) for i in (1, 3, 5)]


def test_a_members_share_is_its_more_loaded_joint_over_the_break_force():
    structure, config = leaning_frame(), PhysicsConfig()
    report, shares = member_load_shares(structure, config)
    _, loads = check_statics_with_loads(structure, config)
    assert shares.shape == (structure.n_edges,) and report.method == "statics"
    np.testing.assert_allclose(shares, np.fmax(loads[0::2], loads[1::2]) / config.break_force)
    assert report.stands and np.isfinite(shares).all() and (shares > 0).all()
    # A brace to the apex (edge 6) carries less than the post it stands on (edge 0).
    assert shares[6] < shares[0]
    weaker = PhysicsConfig(break_force=config.break_force / 4)
    np.testing.assert_allclose(member_load_shares(structure, weaker)[1], 4 * shares)


def test_load_colours_follow_the_scale_and_mark_overload_and_no_answer():
    colours = load_colours(np.array([0.0, 0.5, 1.0, 0.25, 1.5, np.nan]))
    assert colours.dtype == np.uint8 and colours.shape == (6, 4) and (colours[:, 3] == 255).all()
    for row, (_, colour) in zip(colours[:3], LOAD_SCALE):
        assert row[:3].tolist() == _rgb(colour)
    between = (np.array(_rgb(LOAD_SCALE[0][1])) + np.array(_rgb(LOAD_SCALE[1][1]))) / 2
    np.testing.assert_allclose(colours[3, :3], between, atol=1)
    assert colours[4, :3].tolist() == _rgb(OVERLOADED) and colours[5, :3].tolist() == _rgb(NO_ANSWER)


def _glb_document(path) -> dict:
    raw = path.read_bytes()
    (length,) = struct.unpack("<I", raw[12:16])
    return json.loads(raw[20 : 20 + length])


def _linear_to_byte(value: float) -> int:
    srgb = value * 12.92 if value <= 0.0031308 else 1.055 * value ** (1 / 2.4) - 0.055
    return round(srgb * 255)


def test_a_stressed_glb_colours_every_cylinder_as_its_own_member(tmp_path):
    structure = leaning_frame()
    _, shares = member_load_shares(structure)
    colours = load_colours(shares)
    path = structure.export(tmp_path / "s.glb", edge_colors=colours, colour_key={"meaning": "test"})
    document = _glb_document(path)
    nodes, meshes, materials = document["nodes"], document["meshes"], document["materials"]
    (edges_group,) = [node for node in nodes if node.get("name") == "edges"]
    placed = {}
    for child in edges_group["children"]:
        node = nodes[child]
        factor = materials[meshes[node["mesh"]]["primitives"][0]["material"]]["pbrMetallicRoughness"]["baseColorFactor"]
        placed[tuple(np.round(node["translation"], 4))] = [_linear_to_byte(c) for c in factor[:3]]
    # Where each edge's cylinder goes (y-up, lowest spheres on the ground) and the colour it must have there.
    centres = structure.vertices.astype(float)
    centres[:, 2] += 0.25
    middles = (centres[structure.edges[:, 0]] + centres[structure.edges[:, 1]]) / 2
    for middle, colour in zip(middles, colours):
        at = tuple(np.round([middle[0], middle[2], -middle[1]], 4))
        assert placed[at] == colour[:3].tolist()
    assert len(placed) == structure.n_edges
    # Colours are materials, geometry is not written again: one cylinder per axis, whatever the colours.
    steps = structure.vertices[structure.edges[:, 1]] - structure.vertices[structure.edges[:, 0]]
    axes = {tuple(step * (1 if step[np.flatnonzero(step)[0]] > 0 else -1)) for step in steps}
    assert len({meshes[nodes[c]["mesh"]]["primitives"][0]["indices"] for c in edges_group["children"]}) == len(axes) == 7
    assert document["scenes"][0]["extras"]["edge_colours"] == {"meaning": "test"}


@pytest.mark.parametrize("suffix", [".ply", ".obj"])
def test_a_stressed_ply_or_obj_colours_each_cylinders_faces(tmp_path, suffix):
    structure = leaning_frame()
    colours = load_colours(member_load_shares(structure)[1])
    mesh = trimesh.load(structure.export(tmp_path / f"s{suffix}", edge_colors=colours), force="mesh", process=False)
    face_colours = mesh.visual.face_colors  # OBJ keeps them as vertex colours, each part its own vertices
    centres = structure.vertices.astype(float)
    centres[:, 2] += 0.25
    start, end = centres[structure.edges[:, 0]], centres[structure.edges[:, 1]]
    sphere_faces = structure.n_vertices * len(trimesh.creation.icosphere(subdivisions=2).faces)
    middles = mesh.vertices[mesh.faces[sphere_faces:]].mean(axis=1)
    # Each cylinder face lies within a cylinder radius of its own member's line segment, and far from the others'.
    along = np.clip(np.einsum("fei,ei->fe", middles[:, None] - start, end - start) / ((end - start) ** 2).sum(1), 0, 1)
    distance = np.linalg.norm(middles[:, None] - (start + along[..., None] * (end - start)), axis=2)
    owner = distance.argmin(axis=1)
    assert (distance.min(axis=1) <= 0.08 + 1e-6).all()
    np.testing.assert_allclose(face_colours[sphere_faces:, :3], colours[owner, :3], atol=1)


def test_bad_edge_colours_are_refused(tmp_path):
    from structgen import StructureError

    structure = leaning_frame()
    with pytest.raises(StructureError, match=r"\(9, 4\) RGBA bytes"):
        structure.export(tmp_path / "s.glb", edge_colors=np.zeros((3, 4), np.uint8))
    with pytest.raises(StructureError, match="STL holds no colours"):
        structure.export(tmp_path / "s.stl", edge_colors=np.zeros((9, 4), np.uint8))
    assert not list(tmp_path.iterdir())


def test_stress_on_the_command_line(tmp_path, capsys):
    source = tmp_path / "frame.json"
    leaning_frame().save(source)
    assert main(["show", str(source), "-o", str(tmp_path / "stress.png"), "--statics", "--stress"]) == 0
    assert (tmp_path / "stress.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["export", str(source), str(tmp_path / "frame.glb"), "--stress"]) == 0
    key = _glb_document(tmp_path / "frame.glb")["scenes"][0]["extras"]["edge_colours"]
    assert key["peak_share"] == pytest.approx(float(member_load_shares(leaning_frame())[1].max()))
    assert key["members_over_break_force"] == 0 and key["scale"] == [list(stop) for stop in LOAD_SCALE]
    capsys.readouterr()
    for out, extra, message in (("frame.stl", [], "STL holds no colours"), ("solid.glb", ["--solid"], "one colour"),
                                ("frame2.json", [], "only apply to mesh formats")):  # fmt: skip
        assert main(["export", str(source), str(tmp_path / out), "--stress", *extra]) == 2
        assert message in capsys.readouterr().err
        assert not (tmp_path / out).exists()


def _arm(length: int) -> Structure:
    """A tripod's apex with an arm of ``length`` members sticking out sideways."""
    vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]] + [[x, 0, 1] for x in range(1, length + 1)]
    edges = [[0, 3], [1, 3], [2, 3], [3, 4]] + [[v, v + 1] for v in range(4, len(vertices) - 1)]
    return Structure(vertices, edges)


def test_overloaded_members_and_pieces_that_tip_get_their_own_colours():
    """An arm of two members overloads the tripod's joints; one of three reaches past the feet, and the whole tips
    over: no static answer at all."""
    _, shares = member_load_shares(_arm(2))
    assert np.isfinite(shares).all() and shares.max() > 1.0
    assert (load_colours(shares)[shares > 1.0, :3] == _rgb(OVERLOADED)).all()
    _, shares = member_load_shares(_arm(3))
    assert np.isnan(shares).all() and (load_colours(shares)[:, :3] == _rgb(NO_ANSWER)).all()


# -- how evenly each pair of levels shares what lies above (level_shares) ---------------------------------------------------
def test_a_column_shares_perfectly_at_every_level():
    from physics.statics import joint_forces
    from structgen.domains.structures.samples import column

    tower = column(4)
    rows = level_shares(tower, joint_forces(tower))
    assert [(row.level, row.members, row.bodies_above) for row in rows] == [(0, 1, 5), (1, 1, 3), (2, 1, 1)]
    np.testing.assert_allclose([row.even for row in rows], [6 * 9.81, 4 * 9.81, 2 * 9.81])
    np.testing.assert_allclose([row.ratio for row in rows], 1.0)
    # A level whose lower joints all broke (NaN in a simulation's last step) has no peak, said as NaN.
    broken = joint_forces(tower)
    broken[0] = np.nan
    assert np.isnan(level_shares(tower, broken)[0].peak) and level_shares(tower, broken)[1].peak == rows[1].peak


def test_the_even_share_counts_slopes_and_bodies_whichever_way_the_edges_run():
    from physics.statics import joint_forces

    apex_on_four_legs = [[1, 1, 1], [0, 0, 0], [2, 0, 0], [0, 2, 0], [2, 2, 0]]
    down, mixed = [[0, 1], [0, 2], [0, 3], [0, 4]], [[1, 0], [0, 2], [3, 0], [0, 4]]
    rows = [
        level_shares(Structure(apex_on_four_legs, edges), joint_forces(Structure(apex_on_four_legs, edges)))
        for edges in (down, mixed)
    ]
    assert rows[0] == rows[1] and len(rows[0]) == 1
    (legs,) = rows[0]
    # The apex and the legs stand on the legs' feet: 5 bodies over four corner diagonals' cosines (1/sqrt 3 each).
    assert legs.members == 4 and legs.bodies_above == 1 and legs.even == pytest.approx(9.81 * 5 / (4 / np.sqrt(3)))
    # Each foot joint holds up a quarter of the apex and its whole leg: the force can be no less than that.
    assert legs.peak >= 9.81 * 1.25 - 1e-9 and legs.ratio < 1  # the fixed joints pass part of it by bending


def test_level_shares_refuse_forces_that_do_not_fit_the_structure():
    with pytest.raises(ValueError, match="two forces an edge"):
        level_shares(leaning_frame(), np.ones(3))


# -- where a simulation loads it (member_peak_shares, show --peaks) --------------------------------------------------------
def test_a_members_peak_share_is_its_more_loaded_joints_simulated_peak():
    from physics import check_statics, check_transient
    from structgen.domains.structures.samples import column

    report = check_transient(column(3), PhysicsConfig.preset("fast"), window=0.2)
    shares = member_peak_shares(report)
    assert shares.shape == (2,) and shares.max() == pytest.approx(report.peak_force / 52.5)
    # The lower member holds up more than the upper one, and each peaks past its static load (the transient).
    assert shares[0] > shares[1] > 2 * 9.81 / 52.5
    with pytest.raises(ValueError, match="statics report has no simulated joint forces"):
        member_peak_shares(check_statics(column(3)))
    from structgen.domains.structures.render import check_figure

    figure = check_figure(report, shares, "largest force in the simulation")
    labels = [axes.get_ylabel() for axes in figure.axes]
    assert "largest force in the simulation / break force (52.5 N); peak " + f"{shares.max():.0%}" in labels


def test_peaks_on_the_command_line(tmp_path, capsys):
    source = tmp_path / "frame.json"
    leaning_frame().save(source)
    assert main(["show", str(source), "-o", str(tmp_path / "peaks.png"), "--transient", "0.1", "--peaks"]) == 0
    assert (tmp_path / "peaks.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    capsys.readouterr()
    for extra in (["--statics"], ["--stress"]):
        assert main(["show", str(source), "-o", str(tmp_path / "no.png"), "--peaks", *extra]) == 2
        assert "--peaks colours members by a simulation's forces" in capsys.readouterr().err
    assert not (tmp_path / "no.png").exists()
