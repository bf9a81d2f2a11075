"""check_stability: the paper's calibration, the joint forces, the score, determinism, robustness and quietness.

Tests run the real simulator on tiny structures for a few simulated seconds. Structures come from structgen's sample
shapes or as plain arrays: physics accepts anything that offers vertices and edges.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics import InputError, PhysicsConfig, check_stability, check_transient
from physics._quiet import import_pybullet, silenced
from structgen.domains.structures.samples import braced, cantilever, column, flat_edge

FAST = PhysicsConfig.preset("fast")
# The faithful protocol with a short horizon: every break in the calibration set happens within the first second.
FAITHFUL_SHORT = PhysicsConfig.preset("faithful", horizon=3.0)
PRESETS = pytest.mark.parametrize("config", [FAST, FAITHFUL_SHORT], ids=["fast", "faithful-3s"])
G = 9.81


# -- calibration (the paper's: what must stand and what must fall at 52.5 N) -----------------------------------------------
@PRESETS
@pytest.mark.parametrize(
    "structure, stands",
    [
        (column(3), True),
        (column(4), False),
        (braced(4), True),
        (flat_edge(), True),
        (cantilever(1), True),
        (cantilever(2), False),
    ],
    ids=["column3", "column4", "braced4", "flat-edge", "cantilever1", "cantilever2"],
)
def test_calibration_structures_stand_or_fall_as_in_the_paper(config, structure, stands):
    report = check_stability(structure, config)
    assert report.intact is stands
    assert (report.integrity == 1.0) is stands
    if not stands:
        assert report.integrity < 1.0 and report.broken_joints


@pytest.mark.slow
def test_calibration_holds_over_the_full_faithful_30_seconds():
    for structure, stands in [(column(3), True), (column(4), False), (braced(4), True)]:
        report = check_stability(structure, PhysicsConfig())
        assert report.sim_time == pytest.approx(30.0) and report.intact is stands


@PRESETS
def test_static_joint_forces_of_a_column_are_exact(config):
    # Unbreakable joints: each joint carries the weight of everything above it (a cylinder and a sphere per level).
    report = check_stability(column(4), config.replace(break_force=math.inf, horizon=2.0, early_stop=False))
    expected = np.array([6, 5, 4, 3, 2, 1]) * G
    np.testing.assert_allclose(report.joint_forces, expected, atol=0.05)
    assert expected[0] < report.peak_force < 1.1 * expected[0]  # the spawn transient adds a few per cent


def test_column_of_four_breaks_at_its_bottom_joint_first():
    report = check_stability(column(4), FAST)
    first = min(report.broken_joints, key=lambda b: b.time)
    assert (first.joint, first.edge, first.vertex) == (0, 0, 0)
    assert first.force > 52.5 and first.time < 0.1


# -- the first moments alone (check_transient) -------------------------------------------------------------------------------
@PRESETS
@pytest.mark.parametrize(
    "structure, holds",
    [(column(3), True), (column(4), False), (braced(4), True), (cantilever(2), False)],
    ids=["column3", "column4", "braced4", "cantilever2"],
)
def test_the_transient_check_rates_the_peak_and_agrees_with_breakable_joints(config, structure, holds):
    report = check_transient(structure, config, window=0.3)
    held = check_stability(structure, config.replace(break_force=math.inf, horizon=0.3))
    assert report.method == "transient" and report.config == config and report.sim_time == pytest.approx(0.3)
    assert report.peak_force == held.peak_force and not report.broken_joints
    assert report.integrity == min(1.0, 52.5 / report.peak_force)
    assert report.score == pytest.approx(report.integrity * (1 + report.height + report.complexity))
    # Breakable joints take the same steps until one breaks: they break something in the window exactly when the
    # peak is over the limit.
    assert report.intact is holds is check_stability(structure, config.replace(horizon=0.3)).intact
    assert report.verdict().startswith("holds in the first 0.3 s" if holds else "breaks in the first 0.3 s")
    assert f"{report.peak_force:.1f} N" in report.verdict()


@PRESETS
def test_each_joint_keeps_its_own_peak(config):
    # Unbreakable joints over the first moments: the largest any joint carried is the report's peak, every joint's
    # own peak is at least what it carried in the last step, and a column's bottom joint peaks above its static load
    # while its top joint, holding only the top sphere, stays near it.
    report = check_transient(column(4), config, window=0.3)
    peaks = report.peak_forces
    assert peaks.shape == (report.n_joints,) and peaks.max() == report.peak_force
    assert np.all(peaks >= report.joint_forces - 1e-9)
    assert peaks[0] > 6 * G and peaks[-1] < 1.5 * G
    assert report.to_dict()["peak_forces"] == peaks.tolist()


def test_a_bad_transient_window_is_refused():
    with pytest.raises(ValueError, match="window must be a positive number of seconds, got 0"):
        check_transient(column(2), FAST, window=0)


# -- the report -------------------------------------------------------------------------------------------------------------
def test_score_is_the_papers_formula():
    report = check_stability(braced(4), FAST)
    assert report.complexity == 8 and report.height == pytest.approx(3.0, abs=0.01)
    assert report.score == pytest.approx(report.integrity + (report.height + report.complexity) * report.integrity)
    weighted = check_stability(braced(4), FAST.replace(height_weight=2.0, complexity_weight=0.5))
    assert weighted.score == pytest.approx(1 + 2 * weighted.height + 0.5 * 8)


def test_broken_structure_scores_by_integrity():
    report = check_stability(column(4), FAST)
    assert report.integrity == pytest.approx(1 - len(report.broken_joints) / report.n_joints)
    expected = report.integrity * (1 + report.height + report.complexity)
    assert report.score == pytest.approx(expected)


def test_mean_height_option():
    report = check_stability(column(3), FAST.replace(height_mode="mean"))
    assert report.height == pytest.approx(1.0, abs=0.01)  # heights 0, 1, 2 above the lowest


def test_report_contents_are_consistent():
    report = check_stability(cantilever(2), FAST)
    assert report.n_joints == 2 * len(report.edges) and len(report.joint_forces) == report.n_joints
    assert report.initial_positions.shape == report.final_positions.shape == (report.complexity, 3)
    assert report.initial_positions[:, 2].min() == pytest.approx(FAST.sphere_radius)  # resting on the ground
    assert report.final_edge_ends.shape == (len(report.edges), 2, 3)
    for joint in report.broken_joints:
        assert joint.edge == joint.joint // 2 and joint.vertex == report.edges[joint.edge, joint.joint % 2]
        assert 0 < joint.time <= report.sim_time and np.isnan(report.joint_forces[joint.joint])
    assert report.steps == round(report.sim_time / FAST.timestep)
    assert report.wall_time > 0 and report.cpu_time > 0
    data = report.to_dict()
    for key in ("integrity", "height", "complexity", "score", "broken_joints", "settled", "final_positions"):
        assert key in data


def test_torque_limit_is_an_option():
    assert check_stability(cantilever(1), FAST).intact
    assert not check_stability(cantilever(1), FAST.replace(break_torque=1.0)).intact


# -- stopping -----------------------------------------------------------------------------------------------------------
def test_fast_preset_stops_once_settled():
    report = check_stability(column(3), FAST)
    assert report.settled and report.sim_time < 1.0


def test_without_early_stop_the_horizon_is_simulated():
    report = check_stability(flat_edge(), FAST.replace(early_stop=False, horizon=2.0))
    assert report.settled and report.sim_time == pytest.approx(2.0)


def test_collapsed_debris_hits_the_cap_when_it_keeps_moving():
    report = check_stability(column(4), FAST)
    assert report.sim_time == pytest.approx(FAST.horizon) or report.settled


# -- determinism ------------------------------------------------------------------------------------------------------------
def without_timing(report) -> dict:
    data = report.to_dict()
    del data["wall_time"], data["cpu_time"]
    return data


def test_same_input_gives_the_same_report_bit_for_bit():
    first = check_stability(cantilever(2), FAST)
    check_stability(column(5), FAST)  # something else in between, in the same client
    second = check_stability(cantilever(2), FAST)
    assert without_timing(first) == without_timing(second)
    assert np.array_equal(first.final_positions, second.final_positions)


def test_an_emptied_world_gives_what_a_fresh_world_gives(monkeypatch):
    # The client's world is emptied, not reset, between structures (it keeps the solver's buffers); a structure that
    # breaks must still come out bit for bit as in a world that never held anything, whatever came before it.
    from physics import bullet

    fresh = bullet._Client()
    monkeypatch.setattr(bullet, "_client", fresh)
    try:
        first = check_stability(cantilever(2), FAST)
        assert first.broken_joints
        check_stability(braced(5), FAST)
        shapes_after_braced = dict(fresh.shapes)
        again = check_stability(cantilever(2), FAST)
        assert without_timing(first) == without_timing(again)
        assert np.array_equal(first.final_positions, again.final_positions)
        # Shapes are made once per size: nothing piles up from one structure to the next.
        assert fresh.shapes == shapes_after_braced and len(fresh.shapes) <= 5  # ground, sphere, three rod lengths
        structure = cantilever(2)
        assert fresh.pb.getNumBodies(physicsClientId=fresh.id) == 1 + structure.n_vertices + structure.n_edges
    finally:
        fresh.pb.disconnect(physicsClientId=fresh.id)


# -- inputs -----------------------------------------------------------------------------------------------------------------
def test_plain_arrays_mappings_and_pairs_are_accepted():
    vertices, edges = np.array([[0, 0, 0], [0, 0, 1], [0, 0, 2]]), np.array([[0, 1], [1, 2]])
    by_pair = check_stability((vertices, edges), FAST)
    by_mapping = check_stability({"vertices": vertices.tolist(), "edges": edges.tolist()}, FAST)
    by_object = check_stability(column(3), FAST)
    assert without_timing(by_pair) == without_timing(by_mapping) == without_timing(by_object)


def test_lone_vertex_and_floating_structures_are_placed_on_the_ground():
    lone = check_stability(([[4, 4, 9]], []), FAST)
    assert lone.intact and lone.integrity == 1.0 and lone.score == 2.0  # Q = 1 + (0 + 1) * 1
    high = check_stability(([[0, 0, 7], [0, 0, 8]], [[0, 1]]), FAST)
    assert high.initial_positions[:, 2].min() == pytest.approx(0.25) and high.intact


@pytest.mark.parametrize(
    "structure, message",
    [
        (([[0, 0]], []), "shape"),
        (([[0, 0, 0]], [[0, 1]]), "out of range"),
        (([[0, 0, 0], [0, 0, 1]], [[1, 1]]), "itself"),
        (([[0, 0, np.nan]], []), "not finite"),
        (([[0, 0, 0], [0, 0, 0.4]], [[0, 1]]), "too short"),
        ("column", "cannot read a structure"),
        ({"vertices": [[0, 0, 0]]}, "'edges'"),
    ],
)
def test_malformed_input_raises_input_error(structure, message):
    with pytest.raises(InputError, match=message):
        check_stability(structure, FAST)


def test_size_caps_refuse_before_simulating():
    with pytest.raises(InputError, match="more than max_joints = 4"):
        check_stability(column(4), FAST.replace(max_joints=4))
    with pytest.raises(InputError, match="more than max_vertices = 3"):
        check_stability(column(4), FAST.replace(max_vertices=3))


@pytest.mark.parametrize(
    "field, value",
    [("timestep", 0.0), ("solver_iterations", 0), ("break_force", -1.0), ("height_mode", "top"), ("sphere_radius", 0.6)],
)
def test_bad_settings_name_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        FAST.replace(**{field: value})


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(ValueError, match="faithful, fast"):
        PhysicsConfig.preset("turbo")


# -- robustness ---------------------------------------------------------------------------------------------------------------
def test_runaway_simulation_is_reported_as_exploded_not_raised():
    report = check_stability(column(3), FAST.replace(gravity=1e6))
    assert report.exploded and report.integrity == 0.0 and report.score == 0.0 and not report.intact


# -- quiet --------------------------------------------------------------------------------------------------------------------
def test_checks_print_nothing(capfd):
    check_stability(column(3), FAST)
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_c_level_output_of_pybullet_is_silenced(capfd):
    pybullet = import_pybullet()
    client = pybullet.connect(pybullet.DIRECT)
    try:
        capfd.readouterr()
        with silenced(), pytest.raises(pybullet.error):
            pybullet.loadURDF("no-such-file.urdf", physicsClientId=client)  # warns on C stdout, then raises
        print("after", flush=True)
        out, _ = capfd.readouterr()
        assert out == "after\n"
        with pytest.raises(pybullet.error):
            pybullet.loadURDF("no-such-file.urdf", physicsClientId=client)
        assert "no-such-file.urdf" in capfd.readouterr().out  # the warning is real, and only silenced above
    finally:
        pybullet.disconnect(client)


def test_a_configuration_stepped_as_another_preset_keeps_its_physical_model():
    changed = PhysicsConfig.preset("fast", break_force=60.0, sphere_mass=2.0)
    faithful = changed.stepped_as("faithful")
    assert faithful == PhysicsConfig(break_force=60.0, sphere_mass=2.0)
    assert faithful.stepped_as("fast") == changed
    with pytest.raises(ValueError, match="unknown physics preset 'slow'"):
        changed.stepped_as("slow")
