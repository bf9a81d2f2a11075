"""The tall search (``structgen tall``): each height's design is one an NCA grows exactly; the run folder holds what
the command says and resumes an interrupted search to the same answer; folders it does not own are left alone."""

from __future__ import annotations

import csv
import json
from dataclasses import replace

import numpy as np
import pytest

import structgen.domains.structures.tall as tall
from evolution import RunFolderError
from physics import PhysicsConfig
from structgen import NCAConfig, Structure, grow
from structgen.cli import main
from structgen.domains.structures.tall import TallDesign, TallSettings, find_tallest, refine
from structgen.errors import InputError
from structgen.nca import load_weights

# Small enough to run in seconds; three levels still go through every stage (beam, transient, refinement, teaching).
SMALL = TallSettings(levels=3, beam=3, candidates=2, max_vertices=100)
SMALL_OPTIONS = ["--levels", "3", "--beam", "3", "--candidates", "2", "--max-vertices", "100", "--workers", "0"]
BREAK_FORCE = PhysicsConfig().break_force


def shape(structure: Structure) -> tuple[set, set]:
    """Vertex cells and edges relative to the top vertex, so a design and its grown copy compare equal."""
    points = structure.vertices - structure.vertices[np.argmax(structure.vertices[:, 2])]
    cells = [tuple(int(c) for c in p) for p in points.tolist()]
    return set(cells), {frozenset((cells[i], cells[j])) for i, j in structure.edges.tolist()}


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    run_dir = tmp_path_factory.mktemp("tall") / "run"
    return run_dir, find_tallest(SMALL, run_dir, workers=0)


def test_every_height_is_a_design_the_taught_weights_grow_exactly(small_run):
    run_dir, result = small_run
    assert sorted(result.designs) == [2, 3] and result.tallest == 3
    for levels, design in result.designs.items():
        assert design.structure.height == levels - 1
        assert design.peak < BREAK_FORCE  # these small towers hold in the transient
        taught = result.taught[levels]
        grown = grow(load_weights(run_dir / f"tall_{levels}.npy"), NCAConfig(max_extent=levels - 1, iterations=30))
        assert grown.metadata["growth"]["reached_fixed_point"]
        assert shape(grown) == shape(design.structure) == shape(taught.grown)
        assert shape(Structure.load(run_dir / f"tall_{levels}.json")) == shape(design.structure)


def test_the_peak_the_search_reports_is_that_of_the_structure_the_taught_weights_grow(small_run):
    # PyBullet's forces depend on the order bodies are made in, and the search builds designs level by level.
    run_dir, result = small_run
    for levels, design in result.designs.items():
        grown = grow(load_weights(run_dir / f"tall_{levels}.npy"), NCAConfig(max_extent=levels - 1, iterations=30))
        assert design.peak == pytest.approx(tall.transient_peak(grown), rel=1e-6)


def test_the_table_has_a_row_per_height_matching_the_designs(small_run):
    run_dir, result = small_run
    rows = list(csv.DictReader((run_dir / "designs.csv").open()))
    assert [int(row["levels"]) for row in rows] == [2, 3]
    for row in rows:
        design = result.designs[int(row["levels"])]
        assert row["rules"] == " ".join(design.rules) and int(row["tied_levels"]) == design.tied
        assert int(row["vertices"]) == design.structure.n_vertices and int(row["edges"]) == design.structure.n_edges
        assert float(row["transient_peak_n"]) == pytest.approx(design.peak, abs=0.01)
    assert (run_dir / "tallest.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_same_settings_give_the_same_designs_with_any_number_of_workers(small_run):
    _, result = small_run
    assert find_tallest(SMALL, workers=2).designs == result.designs


def test_an_interrupted_search_resumes_after_its_last_height_to_the_same_answer(small_run, tmp_path, monkeypatch):
    _, uninterrupted = small_run
    one_height = tall._one_height
    calls = []

    def stop_at_the_third_level(kept, settings, simulate):
        calls.append(len(calls))
        if len(calls) == 2:
            raise KeyboardInterrupt
        return one_height(kept, settings, simulate)

    monkeypatch.setattr(tall, "_one_height", stop_at_the_third_level)
    run_dir = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt):
        find_tallest(SMALL, run_dir, workers=0)
    assert json.loads((run_dir / "checkpoint.json").read_text())["levels_done"] == 2
    assert not (run_dir / "designs.csv").exists()
    lines = []
    resumed = find_tallest(SMALL, run_dir, workers=0, log=lines.append)
    assert len(calls) == 3  # only the third level was searched again
    assert lines[0] == f"{run_dir}: resuming after 2 of 3 levels (1 heights found so far)"
    assert resumed.designs == uninterrupted.designs


def test_a_search_asked_for_more_levels_goes_on_from_its_folder_to_the_answer_of_a_new_search(small_run, tmp_path, monkeypatch):
    _, fresh = small_run
    run_dir = tmp_path / "run"
    find_tallest(TallSettings(levels=2, beam=3, candidates=2, max_vertices=100), run_dir, workers=0)
    refine = tall.refine

    def stop(*args):
        raise KeyboardInterrupt

    monkeypatch.setattr(tall, "refine", stop)
    with pytest.raises(KeyboardInterrupt):  # stopped after the new height, before its refinement
        find_tallest(SMALL, run_dir, workers=0)
    saved = json.loads((run_dir / "checkpoint.json").read_text())
    assert saved["levels_done"] == 3 and saved["refined"] == [2] and not saved["complete"]
    monkeypatch.setattr(tall, "refine", refine)
    lines = []
    taller = find_tallest(SMALL, run_dir, workers=0, log=lines.append)
    assert lines[0] == f"{run_dir}: resuming after 3 of 3 levels (2 heights found so far)"
    assert [line.split(" (")[0] for line in lines[1:]] == ["refined the 3-level design"]  # the 2-level one is kept
    assert taller.designs == fresh.designs
    assert "levels = 3\n" in (run_dir / "config.toml").read_text()
    with pytest.raises(InputError, match="holds a search with search.levels = 3, not 2; give the same settings to resume it"):
        find_tallest(TallSettings(levels=2, beam=3, candidates=2, max_vertices=100), run_dir, workers=0)


def test_refinement_keeps_the_lowest_peak_of_the_design_and_its_two_level_changes():
    found = TallDesign(("S", "SC"), 1, static_load=0.0, peak=np.inf)  # any variant that grows beats an infinite peak
    better = refine(found, SMALL, lambda function, items: [function(item) for item in items])
    assert better.peak < np.inf and better.rules != found.rules and better.tied == 1
    assert refine(better, SMALL, lambda function, items: [function(item) for item in items]).peak <= better.peak


def test_when_the_tallest_breaks_even_refined_the_next_height_down_is_refined_and_named_the_tallest_that_holds(
    small_run, tmp_path, monkeypatch
):
    _, result = small_run
    # a break force between the two small heights' peaks: three levels cannot hold, two can
    between = (result.designs[2].peak + result.designs[3].peak) / 2
    run_dir = tmp_path / "run"
    lines = []
    weaker = find_tallest(replace(SMALL, physics=PhysicsConfig(break_force=between)), run_dir, workers=0, log=lines.append)
    assert weaker.designs == result.designs  # the loads do not depend on the break force
    assert weaker.tallest == 3 and weaker.tallest_holding == 2
    assert [line.split(" (")[0] for line in lines if line.startswith("refined")] == [
        "refined the 3-level design",
        "refined the 2-level design",
    ]
    assert json.loads((run_dir / "checkpoint.json").read_text())["refined"] == [3, 2]
    rows = {row["levels"]: row["holds_in_transient"] for row in csv.DictReader((run_dir / "designs.csv").open())}
    assert rows == {"2": "yes", "3": "no"}


def test_a_folder_it_does_not_own_or_another_search_is_refused_and_left_as_it_was(small_run, tmp_path):
    run_dir, _ = small_run
    before = {path.name: path.read_bytes() for path in run_dir.iterdir()}
    with pytest.raises(InputError, match=r"config.toml: this folder holds a search with search.beam = 3, not 4"):
        find_tallest(TallSettings(levels=3, beam=4, candidates=2, max_vertices=100), run_dir, workers=0)
    with pytest.raises(InputError, match=r"search.physics.break_force = 52.5, not 60.0"):
        find_tallest(replace(SMALL, physics=PhysicsConfig(break_force=60.0)), run_dir, workers=0)
    assert {path.name: path.read_bytes() for path in run_dir.iterdir()} == before
    (tmp_path / "notes.txt").write_text("mine")
    with pytest.raises(RunFolderError, match="already exists"):
        find_tallest(SMALL, tmp_path, workers=0)
    with pytest.raises(RunFolderError, match="not a run folder"):
        find_tallest(SMALL, tmp_path, workers=0, overwrite=True)
    assert [path.name for path in tmp_path.iterdir()] == ["notes.txt"]
    with pytest.raises(InputError, match="is a file, expected a run folder"):
        find_tallest(SMALL, tmp_path / "notes.txt", workers=0)


def test_a_second_writer_is_refused_while_a_search_holds_its_folder(small_run):
    from evolution import RunFolder

    run_dir, _ = small_run
    with RunFolder(run_dir).locked():
        with pytest.raises(RunFolderError, match="another process .* is writing this run"):
            find_tallest(SMALL, run_dir, workers=0)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"levels": 1}, "search levels = 1: expected a whole number from 2 to 50"),
        ({"refine": "yes"}, "refine must be true or false"),
        ({"footprint": 4}, "footprint must be odd"),
        ({"footprint": -1}, "search footprint = -1"),
    ],
)
def test_settings_out_of_range_are_refused(changes, message):
    with pytest.raises(InputError, match=message):
        TallSettings(**changes)


def test_a_footprint_keeps_every_design_within_it_and_the_taught_weights_grow_it(tmp_path):
    # Unlimited, the three-level answer reaches two cells from the axis; in a 3x3 footprint everything stays within one.
    narrow = find_tallest(replace(SMALL, footprint=3), tmp_path / "narrow", workers=0)
    assert sorted(narrow.designs) == [2, 3]
    for levels, design in narrow.designs.items():
        assert np.abs(design.structure.vertices[:, :2]).max() <= 1
        assert shape(narrow.taught[levels].grown) == shape(design.structure)
    restored = find_tallest(replace(SMALL, footprint=3), tmp_path / "narrow", workers=0)  # read back from its folder
    assert shape(restored.designs[3].structure) == shape(narrow.designs[3].structure)


def test_the_command_writes_the_run_folder_and_prints_how_to_grow_and_check_the_tallest(tmp_path, capsys):
    run_dir = tmp_path / "run"
    assert main(["tall", "--run-dir", str(run_dir), *SMALL_OPTIONS]) == 0
    out = capsys.readouterr().out
    assert "the tallest that holds: 3 levels" in out and "over the" not in out
    assert f"grow it: structgen grow --weights {run_dir / 'tall_3.npy'} --max-extent 2 --iterations 3 -o tall.json" in out
    assert f"structgen evaluate {run_dir / 'tall_3.json'}\n" in out  # within the default limits: nothing to --set
    grown_file = tmp_path / "tall.json"
    assert (
        main(["grow", "--weights", str(run_dir / "tall_3.npy"), "--max-extent", "2", "--iterations", "3", "-o", str(grown_file)])
        == 0
    )
    assert shape(Structure.load(grown_file)) == shape(Structure.load(run_dir / "tall_3.json"))
    # another search in the same folder: exit 2, the reason on stderr
    assert main(["tall", "--run-dir", str(run_dir), *SMALL_OPTIONS[:-2], "--no-refine"]) == 2
    assert "this folder holds a search with search.refine = True, not False" in capsys.readouterr().err
    # the generic verbs know it for what it is
    assert main(["resume", str(run_dir), "--workers", "0"]) == 0
    assert "the tallest that holds: 3 levels" in capsys.readouterr().out
    assert main(["resume", str(run_dir), "--generations", "5"]) == 2
    assert "a tall search has no generations" in capsys.readouterr().err
    assert main(["export", str(run_dir), str(tmp_path / "x.glb")]) == 2
    assert "a tall run of the structures-v0 domain, not an evolution run" in capsys.readouterr().err


def test_the_physics_is_a_setting_of_the_search_and_of_the_check_it_prints(tmp_path, capsys):
    run_dir = tmp_path / "run"
    options = [*SMALL_OPTIONS, "--set", "physics.break_force=0.5", "--set", "search.refine=false"]
    assert main(["tall", "--run-dir", str(run_dir), *options]) == 1  # nothing holds under half a newton
    out = capsys.readouterr().out
    assert "over the 0.5 N break force: it breaks" in out and "no height holds in the transient" in out
    config = (run_dir / "config.toml").read_text()
    assert "[search.physics]" in config and "break_force = 0.5\n" in config and "refine = false\n" in config
    assert main(["info", str(run_dir)]) == 0
    assert "joints break above 0.5 N" in capsys.readouterr().out
    assert main(["tall", "--run-dir", str(tmp_path / "other"), *SMALL_OPTIONS, "--set", "physics.break_force=60"]) == 0
    assert "structgen evaluate " in (out := capsys.readouterr().out) and "--set break_force=60.0" in out
    assert main(["tall", "--run-dir", str(tmp_path / "bad"), "--set", "physics.break_forse=1"]) == 2
    assert "break_forse" in capsys.readouterr().err and not (tmp_path / "bad").exists()


def test_a_search_folder_of_structgen_0_2_is_read_and_converted_when_resumed(small_run, tmp_path, capsys):
    run_dir, result = small_run
    old = tmp_path / "old"
    old.mkdir()
    (old / "settings.json").write_text(json.dumps({"levels": 3, "beam": 3, "candidates": 2, "max_vertices": 100, "refine": True}))
    state = json.loads((run_dir / "checkpoint.json").read_text())
    (old / "search.json").write_text(json.dumps({**state, "complete": False}))
    assert main(["info", str(old)]) == 0
    assert "a tall search (structgen tall), searched up to 3 levels, unfinished" in capsys.readouterr().out
    assert find_tallest(SMALL, old, workers=0).designs == result.designs
    assert not (old / "settings.json").exists() and (old / "config.toml").is_file() and (old / "checkpoint.json").is_file()
    assert main(["resume", str(old), "--workers", "0"]) == 0


def test_info_on_a_search_folder_lists_each_height_and_says_how_far_it_got(small_run, tmp_path, capsys):
    run_dir, result = small_run
    assert main(["info", str(run_dir)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{run_dir}: a tall search (structgen tall), finished")
    design = result.designs[3]
    assert f"3 levels    {' '.join(design.rules)} (tied {design.tied}): {design.structure.n_vertices} vertices" in out
    assert main(["info", str(run_dir), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [row["levels"] for row in summary["designs"]] == [2, 3] and summary["refined"] == [3] and summary["finished"]
    (tmp_path / "settings.json").write_text(json.dumps({"levels": 3}))
    (tmp_path / "search.json").write_text("[1, 2]")
    assert main(["info", str(tmp_path)]) == 2
    assert "search.json: not a tall search checkpoint" in capsys.readouterr().err


def test_a_checkpoint_holding_a_design_no_search_writes_is_refused_before_it_is_built(small_run, tmp_path, capsys):
    import shutil

    run_dir, _ = small_run
    folder = shutil.copytree(run_dir, tmp_path / "copy")
    state = json.loads((folder / "checkpoint.json").read_text())
    state["designs"]["300"] = {"rules": ["VSC"] * 299, "tied": 0, "static_load": 1.0, "peak": 1.0}
    (folder / "checkpoint.json").write_text(json.dumps(state))
    assert main(["info", str(folder)]) == 2
    assert "designs['300']'s height is 300" in capsys.readouterr().err
    with pytest.raises(InputError, match="search levels = 300: expected a whole number from 2 to 50"):
        TallSettings(levels=300)
