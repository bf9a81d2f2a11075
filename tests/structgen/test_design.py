"""Designs to a spec: a library of NCAs and the boxes they meet specs in, looked up and grown in milliseconds."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from physics.statics import check_statics
from structgen import Structure
from structgen.cli import main
from structgen.domains.structures import samples
from structgen.domains.structures.design import (
    DEFAULT_LIBRARY,
    FAMILIES,
    DesignLibrary,
    Spec,
    UnmeetableSpec,
    _Found,
    _grow_answer,
    _judge,
    above_ground,
    add_taught,
    build_library,
    design,
    dimensions,
    load_library,
    on_a_mat,
    screened,
    spec_box,
    tallest_possible,
    taught_boxed,
    taught_clipped,
    taught_on_mats,
    taught_tilings,
    with_mat_flags,
)
from structgen.nca import load_weights

DOCS = Path(__file__).resolve().parents[2] / "docs"
# Specs the taught eight-level tower meets when grown in their boxes (the seed on its top level).
SPECS = [(3, 3, 4), (3, 5, 6), (5, 5, 6), (5, 7, 6), (7, 7, 6)]


@pytest.fixture(scope="module")
def library() -> DesignLibrary:
    """The taught seven- and eight-level towers as a library's two NCAs, with every answer they give for SPECS (two
    seed places each)."""
    weights = np.stack([load_weights(DOCS / name) for name in ("tall_grown_8.npy", "tall_grown_7.npy")])
    weights = weights.astype(np.float32).astype(np.float64)
    tries = np.array([(n, w, d, h, x, y) for n in (0, 1) for w, d, h in SPECS for x in {(w - 1) // 2, w // 2 - 1 if w > 2 else 0}
                      for y in {(d - 1) // 2, d // 2 + (1 if d > 4 else 0)}])  # fmt: skip
    found = _Found()
    _judge(weights, [0, 1], ["down", "down"], tries, found)
    return DesignLibrary(["down", "down"], weights.astype(np.float32), np.array(found.rows, np.int32),
                         np.array(found.peaks, np.float32), {"name": "test library"})  # fmt: skip


def test_a_design_meets_its_spec_exactly_and_stands(library):
    met = {tuple(row[1:4]) for row in library.answers.tolist()}
    assert len(met) >= 4  # the tower answers most of SPECS
    for width, depth, height in sorted(met):
        structure = design(Spec(width, depth, height), 0, library)
        assert dimensions(structure) == (width, depth, height)
        assert check_statics(structure).stands
        assert structure.metadata["design"]["spec"] == {"width": width, "depth": depth, "height": height, "max_members": None}


def test_width_over_depth_is_the_answer_turned_a_quarter(library):
    width, depth, height = next(tuple(row[1:4]) for row in library.answers.tolist() if row[1] < row[2])
    turned = design(Spec(depth, width, height), 0, library)
    straight = design(Spec(width, depth, height), 0, library)
    assert dimensions(turned) == (depth, width, height) and turned.metadata["design"]["turned"] is True
    assert sorted(map(tuple, turned.vertices[:, [1, 0, 2]] * [1, -1, 1])) == sorted(map(tuple, straight.vertices))


def test_seeds_pick_different_answers_where_there_are_several(library):
    counts = {}
    for row in library.answers.tolist():
        counts[tuple(row[1:4])] = counts.get(tuple(row[1:4]), 0) + 1
    spec = Spec(*max(counts, key=counts.get))
    assert counts[(spec.width, spec.depth, spec.height)] >= 2
    designs = {(d.vertices.tobytes(), d.edges.tobytes()) for d in (design(spec, seed, library) for seed in range(8))}
    assert len(designs) >= 2
    assert design(spec, 3, library) == design(spec, 3, library)  # the same seed, the same design


def test_an_unmeetable_spec_names_the_nearest_that_can_be_met(library):
    nearest = r"meets footprint 7x7, height 8; the nearest that can be met: footprint 7x7, height 6"
    with pytest.raises(UnmeetableSpec, match=nearest):
        design(Spec(7, 7, 8), 0, library)
    smallest = int(library.answers[:, 6].min())
    with pytest.raises(UnmeetableSpec, match="at most 1 members"):
        design(Spec(7, 7, 6, max_members=1), 0, library)
    width, depth, height = (int(v) for v in library.answers[library.answers[:, 6].argmin(), 1:4])
    assert design(Spec(width, depth, height, max_members=smallest), 0, library).n_edges <= smallest


def test_a_spec_taller_than_equilibrium_allows_on_its_footprint_says_so(library):
    from structgen.domains.structures.samples import column

    # A column shares its load perfectly, so the bound is exact there: three levels stand, four break.
    assert tallest_possible(1, 1) == 3
    assert check_statics(column(3)).stands and not check_statics(column(4)).stands
    assert tallest_possible(2, 2) < tallest_possible(2, 5) < tallest_possible(5, 5)  # more room, more members
    # Nothing the shipped library meets is taller than the bound allows (it would be wrong if anything were).
    assert all(height <= tallest_possible(width, depth) for width, depth, height in load_library().specs())
    # Loading members only along their axes, or no more evenly than a ratio over the even share, can only lower it;
    # a column has no diagonals to lose.
    for width, depth in ((1, 1), (2, 5), (5, 5), (11, 11)):
        heights = [tallest_possible(width, depth, axial=True, sharing=ratio) for ratio in (1.0, 1.25, 1.5, 2.0)]
        assert heights == sorted(heights, reverse=True) and heights[0] <= tallest_possible(width, depth)
    assert tallest_possible(1, 1, axial=True) == 3 and tallest_possible(11, 11, axial=True) < tallest_possible(11, 11)
    with pytest.raises(ValueError, match="sharing must be a number from 1"):
        tallest_possible(5, 5, sharing=0.9)
    with pytest.raises(UnmeetableSpec, match=r"no structure on a 1x1 footprint stands over 3 levels"):
        design(Spec(1, 1, 5), 0, library)
    with pytest.raises(UnmeetableSpec) as refused:
        design(Spec(7, 7, 8), 0, library)  # equilibrium allows it: the library's gap, no such remark
    assert "no structure" not in str(refused.value)


def test_specs_out_of_range_are_refused():
    for bad in ({"width": 0, "depth": 3, "height": 2}, {"width": 3, "depth": 3, "height": True},
                {"width": 3, "depth": 3, "height": 2, "max_members": -1}):  # fmt: skip
        with pytest.raises(ValueError, match="spec"):
            Spec(**bad)


def test_a_library_saves_and_loads_back(library, tmp_path):
    path = library.save(tmp_path / "lib.npz")
    loaded = load_library(path)
    assert loaded.families == library.families and loaded.info == library.info
    np.testing.assert_array_equal(loaded.answers, library.answers)
    np.testing.assert_array_equal(loaded.weights, library.weights.astype(np.float64))
    assert design(Spec(5, 5, 6), 1, loaded) == design(Spec(5, 5, 6), 1, library)
    assert loaded.on_mat is None  # a library built before the flags: design grows answers in seed order alone
    flagged = load_library(with_mat_flags(library).save(tmp_path / "flagged.npz"))
    np.testing.assert_array_equal(flagged.on_mat, np.zeros(len(library.answers), dtype=bool))  # towers, no mats
    from structgen.errors import InputError

    np.savez(tmp_path / "short.npz", **{**np.load(tmp_path / "flagged.npz"), "on_mat": np.zeros(3, dtype=bool)})
    with pytest.raises(InputError, match=r"on_mat of shape \(3,\) is not one flag"):
        load_library(tmp_path / "short.npz")

    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError, match="not a .npz archive"):
        load_library(tmp_path / "bad.npz")
    with pytest.raises(InputError, match="no design library there"):
        load_library(tmp_path / "missing.npz")


def test_building_a_small_library_is_reproducible_and_its_answers_hold():
    starts = {"down": [load_weights(DOCS / "tall_grown_8.npy")], "up": []}
    first = build_library(12, 1, specs_each=6, keep=2, starts=starts, max_side=4, max_levels=3)
    again = build_library(12, 1, specs_each=6, keep=2, starts=starts, max_side=4, max_levels=3)
    np.testing.assert_array_equal(first.answers, again.answers)
    np.testing.assert_array_equal(first.weights, again.weights)
    assert len(first.answers) >= 3 and set(first.families) <= set(FAMILIES)
    assert (first.answers[:, 1] <= first.answers[:, 2]).all() and first.answers[:, 1:4].max() <= 4
    # On so small a grid every step has work left: a design searched in its own box, an answer set on a mat.
    assert first.info["boxed_ncas"] >= 1 and first.info["mat_ncas"] >= 1 and len(first.specs()) >= 28  # of 30
    np.testing.assert_array_equal(first.on_mat, again.on_mat)
    for row in range(0, len(first.answers), max(1, len(first.answers) // 8)):  # flagged as grown
        assert first.on_mat[row] == on_a_mat(_grow_answer(first, first.answers[row]))
    for row in first.answers[:: max(1, len(first.answers) // 6)]:
        width, depth, height = (int(v) for v in row[1:4])
        structure = design(Spec(width, depth, height), 0, first)
        assert dimensions(structure) == (width, depth, height) and check_statics(structure).stands


def test_design_on_the_command_line(library, tmp_path, capsys):
    path = library.save(tmp_path / "lib.npz")
    out = tmp_path / "tower.json"
    assert main(["design", "--footprint", "5x5", "--height", "6", "--library", str(path), "-o", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["dimensions"] == [5, 5, 6] and summary["stands"] and summary["peak_load_share"] <= 1.0
    assert summary["on_mat"] is False and summary["above_ground"] == list(above_ground(Structure.load(out)))
    assert dimensions(Structure.load(out)) == (5, 5, 6)
    assert main(["design", "--footprint", "7x7", "--height", "8", "--library", str(path), "-o", str(tmp_path / "no.json")]) == 2
    assert "the nearest that can be met: footprint 7x7, height 6" in capsys.readouterr().err
    assert not (tmp_path / "no.json").exists()
    with pytest.raises(SystemExit) as usage:
        main(["design", "--footprint", "5by5", "--height", "3", "-o", str(tmp_path / "x.json")])
    assert usage.value.code == 2 and "give the footprint as WxD" in capsys.readouterr().err


def test_the_shipped_library_answers_specs_across_the_documented_range():
    library = load_library()
    met = library.specs()
    assert DEFAULT_LIBRARY.exists() and len(met) >= 403  # of the 528 specs with width at most depth
    wide_and_low = [(9, 9, 3), (11, 11, 3), (8, 11, 5), (1, 11, 4)]  # wider than a pyramid of their height: tilings
    assert set(wide_and_low) <= met
    assert {(2, 8, 6), (2, 9, 6), (9, 11, 7)} <= met  # narrower than a pyramid of their height: the narrow designs
    assert {(3, 3, 6), (4, 11, 6), (8, 10, 7)} <= met  # their rules per in-degree class
    assert {(2, 2, 5), (4, 4, 6), (6, 8, 7)} <= met  # designs searched in the spec's own box
    assert {(1, 9, 5), (3, 6, 6), (11, 11, 6), (6, 10, 7)} <= met  # smaller footprints' answers on a floor mat
    # Which answers stand on a mat is known without growing them, and a spec with answers that fill it gets those.
    for row in np.random.default_rng(5).choice(len(library.answers), 20, replace=False):
        assert library.on_mat[row] == on_a_mat(_grow_answer(library, library.answers[row]))
    assert not any(design(Spec(5, 5, 6), seed, library).metadata["design"]["on_mat"] for seed in range(5))
    assert design(Spec(11, 11, 6), 0, library).metadata["design"]["on_mat"]  # met by towers on mats alone
    assert all(height <= 7 for width, _, height in met if width <= 6)
    for width, depth, height in wide_and_low[:2]:
        structure = design(Spec(width, depth, height), 3, library)
        assert dimensions(structure) == (width, depth, height) and check_statics(structure).stands
    rng = np.random.default_rng(7)
    for width, depth, height in [sorted(met)[i] for i in rng.choice(len(met), 12, replace=False)]:
        structure = design(Spec(width, depth, height), int(rng.integers(100)), library)
        assert dimensions(structure) == (width, depth, height) and check_statics(structure).stands


@pytest.mark.slow
def test_the_shipped_librarys_heavily_loaded_answers_hold_in_pybullets_first_moments():
    from structgen.domains.structures.tall import transient_peak

    library = load_library()
    assert library.info["screen_above_share"] == 0.7  # built with the transient screen as its last step
    heavy = np.flatnonzero((library.peaks > 0.7) & (library.answers[:, 3] >= 4) & (library.answers[:, 7] <= 120))
    for row in np.random.default_rng(3).choice(heavy, 4, replace=False):
        structure = _grow_answer(library, library.answers[row])
        assert transient_peak(structure) <= 52.5, library.answers[row]


def test_tilings_meet_footprints_wider_than_a_pyramid_of_their_height(library):
    tilings = taught_tilings(max_side=7, max_levels=3, per_height=1)
    assert [height for height, _ in tilings] == [2, 3, 2, 3]  # pyramids side by side, then walls end to end
    spec = Spec(7, 7, 3)  # one design three levels tall spreads to 5 cells at most
    assert not len(library.candidates(spec)[0])
    tiled = add_taught(library, tilings, specs=np.array([(7, 7, 3), (3, 7, 2), (1, 7, 3)]))
    assert tiled.specs() >= library.specs() | {(7, 7, 3), (3, 7, 2), (1, 7, 3)}
    assert len(tiled.families) == len(library.families) + 4 and tiled.info["tiling_ncas"] == 4
    for seed in (0, 1):
        structure = design(spec, seed, tiled)
        assert dimensions(structure) == (7, 7, 3) and check_statics(structure).stands
        assert structure.metadata["design"]["nca"] >= len(library.families)  # a tiling's answer


@pytest.mark.slow
def test_designs_cut_to_a_narrow_box_meet_specs_taller_than_a_pyramid_of_their_width(library):
    from structgen.domains.structures.samples import by_level_rules
    from structgen.domains.structures.tall import transient_peak

    # Three cells wide, a pyramid is two levels tall; one rule per level cut a cell from the axis holds at five.
    taught = taught_clipped(max_side=3, max_levels=6, per_height=1, lowest=5, by_class_from=None)
    assert {height for height, _ in taught} == {5}
    spec = Spec(3, 3, 5)
    assert not len(library.candidates(spec)[0])
    clipped = add_taught(library, taught, specs=np.array([(3, 3, 5)]), kind="clipped")
    assert (3, 3, 5) in clipped.specs() and clipped.info["clipped_ncas"] == len(taught)
    structure = design(spec, 0, clipped)
    assert dimensions(structure) == (3, 3, 5) and check_statics(structure).stands
    assert add_taught(library, [], kind="clipped") is library  # nothing taught, nothing added
    # At six levels the lightest such design stands by the static analysis, but PyBullet's first moments break it:
    # it is left out.
    six = by_level_rules(("V", "S", "C", "SC", "SC"), 1, 1)
    assert dimensions(six) == (3, 3, 6) and check_statics(six).stands
    assert transient_peak(six) > 52.5


@pytest.mark.slow
def test_a_rule_per_in_degree_class_holds_six_levels_in_a_3x3_box_where_one_rule_per_level_breaks(library):
    from structgen.domains.structures.tall import transient_peak

    taught = taught_clipped(max_side=3, max_levels=6, lowest=6, one_rule=False)
    assert taught and {height for height, _ in taught} == {6}
    assert taught_clipped(max_side=3, max_levels=6, lowest=6, by_class_from=None) == []  # one rule a level: none
    clipped = add_taught(library, taught, specs=np.array([(3, 3, 6)]), kind="clipped")
    assert (3, 3, 6) in clipped.specs() and (3, 3, 6) not in library.specs()
    for seed in range(3):
        structure = design(Spec(3, 3, 6), seed, clipped)
        assert dimensions(structure) == (3, 3, 6) and transient_peak(structure) <= 52.5


@pytest.mark.slow
def test_the_transient_screen_drops_answers_that_break_in_pybullet_and_keeps_the_rest(library):
    from structgen.domains.structures.samples import by_level_rules
    from structgen.domains.structures.tall import transient_peak
    from structgen.domains.structures.teach import teach

    # A 3x3 frame of six levels that the static analysis lets stand and PyBullet breaks in its first moments.
    six = by_level_rules(("V", "S", "C", "SC", "SC"), 1, 1)
    weak = add_taught(library, [(6, teach(six).weights)], specs=np.array([(3, 3, 6)]), kind="clipped")
    assert (3, 3, 6) in weak.specs()
    kept = screened(weak)
    assert (3, 3, 6) not in kept.specs() and kept.info["screen_answers_dropped"] >= 1
    assert kept.families == weak.families[: len(kept.families)]  # the NCA left without answers is gone
    assert kept.answers[:, 0].max() < len(kept.families) == len(kept.weights)
    safe = weak.peaks <= 0.7  # loaded lightly by the static analysis: not simulated, all kept
    assert safe.any() and (~safe).sum() == kept.info["screen_simulated"]
    np.testing.assert_array_equal(kept.answers[kept.peaks <= 0.7][:, 1:], weak.answers[safe][:, 1:])
    assert len(kept.answers) > safe.sum()  # some simulated answers hold
    for row in kept.answers[kept.peaks > 0.7]:  # each kept answer, renumbered, still grows its spec, and holds
        structure = _grow_answer(kept, row)
        assert dimensions(structure) == tuple(int(v) for v in row[1:4]) and transient_peak(structure) <= 52.5
    in_workers = screened(weak, workers=2)
    np.testing.assert_array_equal(in_workers.answers, kept.answers)
    assert screened(weak, above_share=1.0).answers.shape == weak.answers.shape  # none simulated, none dropped
    # Extended by one NCA, only its answers are simulated; the library's own were screened before.
    added = weak.answers[:, 0] >= len(library.families)
    only_new = screened(weak, from_nca=len(library.families))
    assert only_new.info["screen_added_simulated"] == int((added & ~safe).sum()) < kept.info["screen_simulated"]
    assert "screen_simulated" not in only_new.info  # weak was not screened before: nothing to keep
    assert (3, 3, 6) not in only_new.specs()
    np.testing.assert_array_equal(only_new.answers[only_new.answers[:, 0] < len(library.families)], weak.answers[~added])


@pytest.mark.slow
def test_a_rule_per_in_degree_class_carries_what_one_rule_per_level_cannot_in_a_narrow_box():
    import random

    from structgen.domains.structures.design import _lightest_by_class
    from structgen.domains.structures.samples import by_level_rules
    from structgen.domains.structures.tall import largest_static_load

    # A one-rule seven-level design in a 3x3 box carries 73 N at its worst joint; a rule per in-degree class lets the
    # vertices where loads meet send more down, and the descent over those rules takes off a quarter of it.
    rules, tied = ("V", "C", "SC", "S", "SC", "SC"), 1
    start = by_level_rules(rules, tied, 1)
    assert dimensions(start) == (3, 3, 7) and not check_statics(start).stands
    found = _lightest_by_class(rules, tied, 1, 3, random.Random(0))
    assert found is not None and dimensions(found) == (3, 3, 7)
    assert largest_static_load(found) < 0.8 * largest_static_load(start)
    assert _lightest_by_class(rules, tied, 1, 3, random.Random(0)).edges.tolist() == found.edges.tolist()  # repeats


@pytest.mark.slow
def test_designs_searched_in_a_specs_own_box_meet_an_even_footprint_no_square_cut_reaches(library):
    from structgen.domains.structures.samples import by_level_rules
    from structgen.domains.structures.tall import transient_peak

    assert spec_box(2, 2) == (0, 1, 0, 1) and spec_box(3, 4) == (-1, 1, -1, 2) and spec_box(1, 1) == (0, 0, 0, 0)
    assert dimensions(by_level_rules(("S",) * 4, 0, spec_box(2, 5))) == (2, 5, 5)
    # Two by two cells and five levels tall: the seed at a corner of the top, a design grown in that box holds.
    taught = taught_boxed([(2, 2, 5)])
    assert [height for height, _ in taught] == [5]
    boxed = add_taught(library, taught, specs=np.array([(2, 2, 5)]), kind="boxed")
    assert (2, 2, 5) in boxed.specs() and (2, 2, 5) not in library.specs() and boxed.info["boxed_ncas"] == 1
    structure = design(Spec(2, 2, 5), 0, boxed)
    assert dimensions(structure) == (2, 2, 5) and transient_peak(structure) <= 52.5
    with pytest.raises(ValueError, match="width at most depth"):
        taught_boxed([(3, 2, 4)])


def test_a_footprint_searched_in_its_own_box_stops_at_the_first_height_nothing_holds(monkeypatch):
    import structgen.domains.structures.design as design_module

    heights = []
    descent = design_module._lightest_by_class

    def counted(rules, *args, **kwargs):
        heights.append(len(rules) + 1)
        return descent(rules, *args, **kwargs)

    monkeypatch.setattr(design_module, "_lightest_by_class", counted)
    # Two cells long and one wide: nothing the search finds of four levels holds there, so five is not searched.
    assert taught_boxed([(1, 2, 4), (1, 2, 5)]) == []
    assert heights and set(heights) == {4}


def test_an_answer_set_on_a_mat_meets_a_wider_footprint_and_the_mat_stops_at_any_box_walls(library, tmp_path, capsys):
    from structgen.domains.structures.tall import transient_peak

    # The tower's top four levels stand on 3 x 3 cells; nothing in the library is 5 x 7 or 4 x 5 at four levels.
    assert (3, 3, 4) in library.specs() and not {(5, 7, 4), (4, 5, 4)} & library.specs()
    taught = taught_on_mats(library, [(4, 5, 4), (5, 7, 4)])
    assert [height for height, _ in taught] == [4]  # one answer chosen for both, taught once on the larger mat
    matted = add_taught(library, taught, specs=np.array([(4, 5, 4), (5, 7, 4), (4, 4, 4)]), kind="mat")
    assert {(4, 5, 4), (5, 7, 4), (4, 4, 4)} <= matted.specs() and matted.info["mat_ncas"] == 1
    for spec in (Spec(4, 5, 4), Spec(7, 5, 4)):  # in a smaller box than it was taught in, the walls stop the mat
        structure = design(spec, 0, matted)
        assert dimensions(structure) == (spec.width, spec.depth, 4) and transient_peak(structure) <= 52.5
        floor = {tuple(v[:2]) for v in (structure.vertices - structure.vertices.min(axis=0)).tolist() if v[2] == 0}
        assert len(floor) == spec.width * spec.depth  # every ground cell
        assert structure.metadata["design"]["above_ground"] == [3, 3]  # the tower, turned or not
    # Seven cells of floor are more than the 3 x 3 tower's members can reach: the user is told it stands on a mat.
    path = matted.save(tmp_path / "mats.npz")
    assert main(["design", "--footprint", "7x5", "--height", "4", "--library", str(path), "-o", str(tmp_path / "m.json")]) == 0
    assert "a 3x3 tower on a floor mat filling the footprint" in capsys.readouterr().out
    refused = ["design", "--footprint", "7x5", "--height", "4", "--library", str(path), "--no-mat", "-o"]
    assert main([*refused, str(tmp_path / "n.json")]) == 2 and not (tmp_path / "n.json").exists()
    assert "are towers on a floor mat, which were refused" in capsys.readouterr().err
    # A flagged library extended and screened keeps its flags, the new answers flagged as grown.
    flagged = add_taught(with_mat_flags(library), taught, specs=np.array([(4, 5, 4), (5, 7, 4), (4, 4, 4)]), kind="mat")
    np.testing.assert_array_equal(flagged.on_mat, with_mat_flags(matted).on_mat)
    assert flagged.on_mat.any() and not flagged.on_mat.all()
    kept = screened(flagged, from_nca=len(library.families), step="mat")
    np.testing.assert_array_equal(kept.on_mat, with_mat_flags(kept).on_mat)
    with pytest.raises(ValueError, match="width at most depth"):
        taught_on_mats(library, [(5, 4, 4)])


def test_a_tower_on_a_mat_is_told_from_a_frame_that_fills_its_footprint():
    pyramid = samples.sparse_pyramid(4)  # every ground vertex reached from the level above
    assert not on_a_mat(pyramid) and dimensions(pyramid) == (7, 7, 4) and above_ground(pyramid) == (5, 5)
    assert on_a_mat(samples.on_mat(pyramid, 9, 7)) and above_ground(samples.on_mat(pyramid, 9, 7)) == above_ground(pyramid)
    width, depth, _ = dimensions(pyramid)
    # A mat of the pyramid's own footprint lies within a cell of the levels above: nothing tells it from a tied foot.
    assert not on_a_mat(samples.on_mat(pyramid, width, depth))
    flat = samples.on_mat(samples.column(1), 3, 3)
    assert not on_a_mat(flat) and above_ground(flat) is None
    assert on_a_mat(samples.on_mat(samples.column(3), 1, 4, at=(0, 0)))  # a post at one end of a one-cell-wide wall
