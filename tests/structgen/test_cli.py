"""The structgen command line: results on stdout, one-line errors with exit code 2, nothing written on bad input."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import trimesh

from structgen import LocalNCA, NCAConfig, Structure
from structgen.cli import main
from structgen.nca import save_weights

GOOD = '{"vertices": [[0, 0, 0], [0, 0, 1], [1, 0, 1]], "edges": [[0, 1], [1, 2]]}'


@pytest.fixture
def good_file(tmp_path: Path) -> Path:
    path = tmp_path / "good.json"
    path.write_text(GOOD)
    return path


def run(capsys, *argv: str) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as usage:  # refused as the options are read: argparse's exit, with the same code 2
        code = usage.code
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(err: str, *fragments: str) -> None:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    # "structgen: error:" for bad input found at work, "structgen VERB: error:" for an option refused as it is read
    assert lines[0].startswith("structgen") and ": error: " in lines[0] and "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0]


# -- grow ---------------------------------------------------------------------------------------------------------------
def test_grow_from_a_seed_writes_the_random_ncas_structure(tmp_path, capsys):
    code, out, _ = run(capsys, "grow", "--seed", 3, "--iterations", 3, "-o", tmp_path / "s.json")
    assert code == 0
    grown = Structure.load(tmp_path / "s.json")
    expected = LocalNCA.random(3, NCAConfig(iterations=3)).grow()
    assert (grown.vertices.tolist(), grown.edges.tolist()) == (expected.vertices.tolist(), expected.edges.tolist())
    assert grown.metadata["random_seed"] == 3 and grown.metadata["growth"]["iterations"] == 3
    assert out.startswith(f"{tmp_path / 's.json'}: {grown.n_vertices} vertices")


def test_grow_from_saved_weights_and_straight_to_a_mesh(tmp_path, capsys):
    weights = save_weights(tmp_path / "w.npy", LocalNCA.random(9).get_weights())
    code, _, _ = run(capsys, "grow", "--weights", weights, "--cutoff", 0.55, "-o", tmp_path / "s.glb")
    assert code == 0
    scene = trimesh.load(tmp_path / "s.glb")
    expected = LocalNCA.random(9, NCAConfig(cutoff=0.55)).grow()
    assert scene.metadata["n_vertices"] == expected.n_vertices


def test_grow_draws_every_step_as_frames_and_a_gif(tmp_path, capsys):
    from PIL import Image

    from structgen.nca import grow_steps

    code, _, err = run(
        capsys,
        "grow",
        "--seed",
        3,
        "--iterations",
        3,
        "-o",
        tmp_path / "s.json",
        "--frames",
        tmp_path / "f",
        "--gif",
        tmp_path / "g.gif",
    )
    assert code == 0, err
    steps = len(grow_steps(LocalNCA.random(3, NCAConfig(iterations=3)).get_weights(), NCAConfig(iterations=3)))
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == [f"step_{k:03d}.png" for k in range(steps)]
    with Image.open(tmp_path / "g.gif") as gif:
        assert gif.n_frames == steps
    grown = Structure.load(tmp_path / "s.json")
    assert grown.vertices.tolist() == LocalNCA.random(3, NCAConfig(iterations=3)).grow().vertices.tolist()
    with pytest.raises(SystemExit) as exit_info:
        main(["grow", "--seed", "3", "-o", str(tmp_path / "t.json"), "--gif", str(tmp_path / "g.png")])
    assert exit_info.value.code == 2 and "give a name ending in .gif" in capsys.readouterr().err
    assert not (tmp_path / "t.json").exists()


def test_grow_is_deterministic(tmp_path, capsys):
    run(capsys, "grow", "--seed", 5, "-o", tmp_path / "a.json")
    run(capsys, "grow", "--seed", 5, "-o", tmp_path / "b.json")
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()


@pytest.mark.parametrize(
    "argv, fragments",
    [
        (["--weights", "{tmp}/missing.npy"], ["missing.npy", "no such file"]),
        (["--weights", "{tmp}/short.json"], ["short.json", "holds 2 weights"]),
        (["--cutoff", "1.5"], ["--cutoff", "strictly between 0 and 1", "1.5"]),  # refused as the options are read
        (["--iterations", "-2"], ["--iterations", "from 0", "-2"]),
    ],
)
def test_grow_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, argv, fragments):
    (tmp_path / "short.json").write_text("[0.5, 0.25]")
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    try:
        code, out, err = run(capsys, "grow", *argv, "-o", tmp_path / "out.json")
    except SystemExit as usage:
        code, (out, err) = usage.code, capsys.readouterr()
    assert code == 2 and out == ""
    assert_one_line_error(err, *fragments)
    assert not (tmp_path / "out.json").exists()


def test_grow_seed_and_weights_together_is_a_usage_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["grow", "--seed", "1", "--weights", "w.npy", "-o", str(tmp_path / "x.json")])
    assert exit_info.value.code == 2
    assert "not allowed with" in capsys.readouterr().err


# -- export -------------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".glb", ".obj", ".stl", ".ply", ".json"])
def test_export_by_suffix(tmp_path, capsys, good_file, suffix):
    out_path = tmp_path / f"out{suffix}"
    code, out, _ = run(capsys, "export", good_file, out_path)
    assert code == 0 and out_path.exists() and "3 vertices, 2 edges" in out
    if suffix != ".json":
        assert len(trimesh.load(out_path, force="mesh").faces) == len(Structure.load(good_file).to_mesh().faces)


def test_export_with_dash_o_and_dimensions(tmp_path, capsys, good_file):
    code, _, _ = run(capsys, "export", good_file, "-o", tmp_path / "thin.stl", "--cylinder-radius", 0.02)
    assert code == 0
    thick = Structure.load(good_file).to_mesh()
    thin = trimesh.load(tmp_path / "thin.stl")
    assert thin.volume < thick.volume


def test_export_lighter_mesh_for_big_structures(tmp_path, capsys, good_file):
    code, _, _ = run(capsys, "export", good_file, tmp_path / "light.glb", "--sphere-subdivisions", 0, "--cylinder-sections", 6)
    assert code == 0
    light = trimesh.load(tmp_path / "light.glb", force="mesh")
    assert len(light.faces) == len(Structure.load(good_file).to_mesh(sphere_subdivisions=0, cylinder_sections=6).faces)
    assert len(light.faces) < len(Structure.load(good_file).to_mesh().faces) / 4


def test_export_refuses_an_impossible_mesh_resolution(tmp_path, capsys, good_file):
    code, _, err = run(capsys, "export", good_file, tmp_path / "o.glb", "--cylinder-sections", 2)  # refused as read
    assert code == 2
    assert_one_line_error(err, "--cylinder-sections", "a whole number from 3 to 128, got 2")
    assert sorted(os.listdir(tmp_path)) == ["good.json"]


@pytest.mark.parametrize(
    "content, fragments",
    [
        ('{"vertices": [[0, 0, 0], [0, 0, 2]], "edges": [[0, 1]]}', ["bad.json", "edges[0]", "not lattice neighbours"]),
        ('{"vertices": [[0, 0, 0.5]], "edges": []}', ["bad.json", "vertices[0]", "not an integer"]),
        ("{ nope", ["bad.json", "not valid JSON"]),
        ('{"vertices": [[0, 0, 0]], "edges": [], "extra": 1}', ["bad.json", "unknown field 'extra'"]),
    ],
)
def test_export_of_a_broken_file_exits_2_and_keeps_the_old_output(tmp_path, capsys, content, fragments):
    (tmp_path / "bad.json").write_text(content)
    target = tmp_path / "out.glb"
    target.write_bytes(b"previous output")
    code, out, err = run(capsys, "export", tmp_path / "bad.json", target)
    assert code == 2 and out == ""
    assert_one_line_error(err, *fragments)
    assert target.read_bytes() == b"previous output"
    assert sorted(os.listdir(tmp_path)) == ["bad.json", "out.glb"]


@pytest.mark.parametrize(
    "argv, fragments",
    [
        (["{tmp}/absent.json", "{tmp}/o.stl"], ["absent.json", "no such file"]),
        (["{good}", "{tmp}/o.fbx"], ["o.fbx", "unknown export format"]),
        (["{good}"], ["needs an output file"]),
        (["{good}", "{tmp}/o.json", "--sphere-radius", "0.2"], ["only apply to mesh formats"]),
        (["{tmp}", "{tmp}/o.stl"], ["not a run folder (no config.toml)"]),
    ],
)
def test_export_usage_problems_exit_2(tmp_path, capsys, good_file, argv, fragments):
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{good}", str(good_file)) for a in argv]
    code, _, err = run(capsys, "export", *argv)
    assert code == 2
    assert_one_line_error(err, *fragments)
    assert sorted(os.listdir(tmp_path)) == ["good.json"]


# -- info ---------------------------------------------------------------------------------------------------------------
def test_info_json(capsys, good_file):
    code, out, _ = run(capsys, "info", good_file, "--json")
    assert code == 0
    data = json.loads(out)
    assert data["vertices"] == 3 and data["edges"] == 2 and data["height"] == 1 and data["components"] == 1
    assert data["bounds"] == {"min": [0, 0, 0], "max": [1, 0, 1]}


def test_info_table(capsys, good_file):
    code, out, _ = run(capsys, "info", good_file)
    assert code == 0
    table = dict(line.split(None, 1) for line in out.strip().splitlines() if not line.startswith("max"))
    assert table["vertices"] == "3" and table["edges"] == "2" and table["height"] == "1" and table["components"] == "1"


def test_info_of_a_missing_file(tmp_path, capsys):
    code, out, err = run(capsys, "info", tmp_path / "nope.json")
    assert code == 2 and out == ""
    assert_one_line_error(err, "nope.json", "no such file")


@pytest.mark.parametrize("where", ["before", "after"])
def test_verbose_before_or_after_the_command_shows_the_traceback(tmp_path, capsys, where):
    flag, command = ["-v"], ["info", str(tmp_path / "nope.json")]
    code, _, err = run(capsys, *(flag + command if where == "before" else command + flag))
    assert code == 2 and "Traceback" in err
    assert err.splitlines()[0] == f"structgen: error: {tmp_path / 'nope.json'}: no such file"


# -- the installed entry point --------------------------------------------------------------------------------------------
def test_console_script_and_help_for_every_subcommand(tmp_path):
    script = Path(sys.executable).with_name("structgen")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "structgen"]
    for sub in ([], ["grow"], ["export"], ["info"], ["evaluate"], ["show"]):
        done = subprocess.run([*command, *sub, "--help"], capture_output=True, text=True, check=False)
        assert done.returncode == 0 and "usage: structgen" in done.stdout
    done = subprocess.run([*command, "info", str(tmp_path / "x.json")], capture_output=True, text=True, check=False)
    assert done.returncode == 2 and "Traceback" not in done.stderr and done.stdout == ""


# -- check and render -----------------------------------------------------------------------------------------------------
COLUMN_4 = '{"vertices": [[0, 0, 0], [0, 0, 1], [0, 0, 2], [0, 0, 3]], "edges": [[0, 1], [1, 2], [2, 3]]}'
SQUARE = '{"vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], "edges": [[0, 1], [0, 2], [1, 3], [2, 3]]}'


@pytest.fixture
def square(tmp_path: Path) -> Path:
    path = tmp_path / "square.json"
    path.write_text(SQUARE)
    return path


@pytest.fixture
def column_4(tmp_path: Path) -> Path:
    path = tmp_path / "column4.json"
    path.write_text(COLUMN_4)
    return path


def test_check_json_reports_the_required_fields(capsys, square):
    code, out, err = run(capsys, "evaluate", square, "--preset", "fast", "--json")
    assert code == 0 and err == ""
    report = json.loads(out)
    for key in ("integrity", "height", "complexity", "score", "broken_joints", "settled"):
        assert key in report
    assert report["integrity"] == 1.0 and report["complexity"] == 4 and report["preset"] == "fast"
    assert report["broken_joints"] == [] and report["settled"] is True
    assert report["score"] == pytest.approx(1 + report["height"] + 4)


def test_check_of_a_breaking_structure_exits_0_unless_strict(capsys, column_4):
    code, out, _ = run(capsys, "evaluate", column_4, "--preset", "fast")
    assert code == 0 and "breaks" in out and "broken      joint 0 (edge 0, vertex 0)" in out
    code, _, _ = run(capsys, "evaluate", column_4, "--preset", "fast", "--strict")
    assert code == 1


def test_check_strict_passes_a_standing_structure(capsys, square):
    code, out, _ = run(capsys, "evaluate", square, "--preset", "fast", "--strict")
    assert code == 0 and "stands" in out


@pytest.mark.parametrize("key", ["break_force", "physics.break_force"])
def test_check_set_overrides_a_physics_setting(capsys, column_4, key):
    code, out, _ = run(capsys, "evaluate", column_4, "--preset", "fast", "--set", f"{key}=70", "--json")
    assert code == 0
    report = json.loads(out)
    assert report["integrity"] == 1.0 and report["config"]["break_force"] == 70.0 and report["preset"] is None
    assert report["config"]["timestep"] == 1 / 120  # on top of the fast preset


@pytest.mark.parametrize(
    "setting, fragments",
    [
        ("bogus=1", ["unknown setting 'physics.bogus'", "timestep"]),
        ("timestep=abc", ["physics.timestep = 'abc'", "expected a number"]),
        ("solver_iterations=2.5", ["physics.solver_iterations", "expected an integer"]),
        ("timestep=-1", ["timestep must be a positive number"]),
        ("nonsense", ["expected key=value"]),
    ],
)
def test_check_bad_settings_exit_2_naming_the_key(capsys, column_4, setting, fragments):
    code, out, err = run(capsys, "evaluate", column_4, "--set", setting)
    assert code == 2 and out == ""
    assert_one_line_error(err, *fragments)


def test_check_refuses_structures_over_the_size_cap(capsys, column_4):
    code, _, err = run(capsys, "evaluate", column_4, "--set", "max_joints=4")
    assert code == 2
    assert_one_line_error(err, "column4.json", "more than max_joints = 4", "check --statics", "--set max_joints=N")


def test_check_of_a_broken_file(tmp_path, capsys):
    (tmp_path / "bad.json").write_text('{"vertices": [[0, 0, 0], [0, 0, 0]], "edges": []}')
    code, _, err = run(capsys, "evaluate", tmp_path / "bad.json")
    assert code == 2
    assert_one_line_error(err, "bad.json", "vertices[1] duplicates vertices[0]")


def test_render_writes_a_png_before_and_after(tmp_path, capsys, column_4):
    code, out, _ = run(capsys, "show", column_4, "-o", tmp_path / "c.png", "--preset", "fast", "--dpi", 40)
    assert code == 0 and "breaks" in out
    data = (tmp_path / "c.png").read_bytes()
    assert data.startswith(b"\x89PNG\r\n\x1a\n") and len(data) > 1000


def test_render_refuses_other_formats_and_writes_nothing(tmp_path, capsys, column_4):
    code, _, err = run(capsys, "show", column_4, "-o", tmp_path / "c.jpg")
    assert code == 2
    assert_one_line_error(err, "c.jpg", "PNG")
    assert not (tmp_path / "c.jpg").exists()


def test_check_statics_predicts_without_simulating(capsys, column_4, square):
    code, out, _ = run(capsys, "evaluate", column_4, "--statics", "--json")
    report = json.loads(out)
    assert code == 0 and report["method"] == "statics" and report["integrity"] == 0.0 and report["steps"] == 2
    code, out, _ = run(capsys, "evaluate", square, "--statics")
    assert code == 0 and "static frame solve" in out and "stands" in out


def test_check_transient_rates_the_first_moments(capsys, column_4, square):
    code, out, _ = run(capsys, "evaluate", column_4, "--transient", "0.3", "--json", "--strict")
    report = json.loads(out)
    assert code == 1 and report["method"] == "transient" and report["sim_time"] == pytest.approx(0.3)
    assert report["peak_force"] > 52.5 and report["integrity"] == pytest.approx(52.5 / report["peak_force"])
    code, out, _ = run(capsys, "evaluate", square, "--transient", "0.3", "--strict")
    assert code == 0 and "holds in the first 0.3 s" in out and "peak force" in out
    for options, message in [
        (("--transient", "0.3", "--statics"), "not allowed with argument --transient"),
        (("--transient", "-1"), "--transient: expected a number above 0, at most 3600, got -1"),
    ]:
        with pytest.raises(SystemExit) as exit_info:
            main(["evaluate", str(square), *options])
        assert exit_info.value.code == 2 and message in capsys.readouterr().err


def test_render_statics_writes_a_png(tmp_path, capsys, column_4):
    code, out, _ = run(capsys, "show", column_4, "--statics", "-o", tmp_path / "c.png", "--dpi", 40)
    assert code == 0 and "breaks" in out and (tmp_path / "c.png").read_bytes().startswith(b"\x89PNG")


def test_check_pictures_explain_their_colours():
    from physics import PhysicsConfig, check_statics
    from structgen.domains.structures.render import check_figure

    def labels(figure):
        legend = [text.get_text() for text in figure.legends[0].get_texts()]
        return legend, [axes.get_ylabel() for axes in figure.axes if axes.name != "3d"]

    config = PhysicsConfig.preset("fast")
    small = check_figure(check_statics(([[0, 0, 0], [0, 0, 1]], [[0, 1]]), config))
    assert labels(small) == (["edge, joints intact", "edge with a broken joint", "vertex"], [])
    # A flat 11x11 grid has 220 edges; 15x15 has 420, past the size drawn in height colours.
    cells = [[x, y, 0] for x in range(15) for y in range(15)]
    grid = [[i, i + 1] for i in range(225) if i % 15 < 14] + [[i, i + 15] for i in range(210)]
    large = check_figure(check_statics((cells, grid), config))
    assert "stands: the static analysis finds no joint over the break force" in large.get_suptitle()
    assert labels(large) == (["edge with a broken joint"], ["height of an intact edge or vertex"])


# -- the command line as a whole ------------------------------------------------------------------------------------------
def all_parsers(parser=None, path=()):
    """Every parser of the command line, with the words that reach it."""
    import argparse

    from structgen.cli import build_parser

    parser = parser or build_parser()
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from all_parsers(sub, (*path, name))


def test_every_verb_has_help_and_every_option_says_what_it_does(capsys):
    import argparse

    paths = [path for path, _ in all_parsers()]
    for expected in [("list",), ("evolve",), ("export",), ("structures", "grow"), ("grow",), ("ones", "evolve")]:
        assert expected in paths
    for path, parser in all_parsers():
        with pytest.raises(SystemExit) as done:
            main([*path, "--help"])
        assert done.value.code == 0 and "usage: structgen" in capsys.readouterr().out
        for action in parser._actions:
            if not isinstance(action, (argparse._HelpAction, argparse._SubParsersAction, argparse._VersionAction)):
                assert action.help, f"structgen {' '.join(path)}: {action.option_strings or action.dest} has no help"


@pytest.mark.parametrize(
    "old, new",
    [
        (["check"], "evaluate"),
        (["structures", "render"], "show"),
        (["maze", "generate"], "grow"),
        (["maze", "train-agent"], "train"),
        (["fortress", "run"], "evaluate"),
        (["autoverse", "search"], "evaluate"),
    ],
)
def test_a_verbs_old_name_still_answers_for_a_release_and_names_the_new_one(capsys, old, new):
    from structgen.registry.commands import RENAMED_VERBS_GO_IN

    with pytest.raises(SystemExit) as done:
        main([*old, "--help"])  # the same parser: its usage names the new verb
    assert done.value.code == 0 and f" {new} [-h]" in capsys.readouterr().out
    import argparse

    from structgen.registry.commands import renamed_verb_note

    parser = dict(all_parsers())[tuple(old)]  # what parsing the old name gives, without the verb's own arguments
    args = argparse.Namespace(**parser._defaults, command=old[0], verb=old[-1])
    note = renamed_verb_note(args, (args.command, args.verb))
    assert note == f"'{old[-1]}' is now '{new}'; the old name goes in structgen {RENAMED_VERBS_GO_IN}"


def test_a_verb_typed_by_its_new_name_says_nothing_of_renames(capsys, column_4):
    code, _, err = run(capsys, "evaluate", column_4, "--statics")
    assert code == 0 and "is now" not in err
    code, _, err = run(capsys, "check", column_4, "--statics")
    assert code == 0 and "'check' is now 'evaluate'" in err


def test_the_shared_concepts_take_one_verb_in_every_domain():
    import argparse

    from structgen.registry.commands import SHARED_VERBS

    verbs = {}  # group -> its verbs' names (an alias is listed beside its verb, not as a verb of its own)
    for path, parser in all_parsers():
        for action in parser._actions:
            if len(path) == 1 and isinstance(action, argparse._SubParsersAction):
                verbs[path[0]] = {entry.dest for entry in action._choices_actions}
    for group, names in verbs.items():
        assert not names & {"check", "render", "generate", "train-agent", "search", "run"}, (group, names)
    assert {"grow", "evaluate", "show", "info"} <= verbs["structures"] and {"grow", "show", "info", "train"} <= verbs["maze"]
    assert {"evaluate", "show", "info"} <= verbs["fortress"] and {"evaluate", "show", "train"} <= verbs["autoverse"]
    assert set(SHARED_VERBS) == {"grow", "evaluate", "show", "info", "train", "experiment", "figure"}


def test_list_domains_and_optimizers(capsys):
    code, out, _ = run(capsys, "list", "domains")
    lines = out.splitlines()
    assert code == 0 and lines[0].startswith("structures-v0 ") and any(line.startswith("ones-v0 ") for line in lines)
    code, out, _ = run(capsys, "list", "domains", "--json")
    rows = {row["id"]: row for row in json.loads(out)}
    assert rows["structures-v0"]["group"] == "structures" and rows["structures-v0"]["aliases"] == ["structures"]
    code, out, _ = run(capsys, "list", "optimizers", "--json")
    rows = {row["name"]: row for row in json.loads(out)}
    assert list(rows) == ["ga", "cma_es", "map_elites", "cma_mae", "random"]
    assert rows["ga"]["settings"]["population"] == 100 and rows["cma_mae"]["settings"]["cells"] == [16, 16]
    assert rows["random"]["settings"] == {"population": 100, "initial": 0, "cells": []}


def test_grow_takes_settings_by_set_as_every_command_does(tmp_path, capsys):
    code, _, err = run(capsys, "grow", "--seed", 3, "--set", "nca.iterations=2", "--set", "cutoff=0.6", "-o", tmp_path / "a.json")
    assert code == 0, err
    growth = Structure.load(tmp_path / "a.json").metadata["growth"]
    assert growth["iterations"] == 2 and growth["cutoff"] == 0.6
    code, _, _ = run(capsys, "grow", "--seed", 3, "--set", "iterations=9", "--iterations", 2, "-o", tmp_path / "b.json")
    assert code == 0 and Structure.load(tmp_path / "b.json").metadata["growth"]["iterations"] == 2  # the option wins
    code, _, err = run(capsys, "grow", "--set", "sphere_radius=0.2", "-o", tmp_path / "c.json")
    assert code == 2 and "mesh options (dimensions, --solid, --stress) only apply to mesh formats" in err


def test_a_reader_that_closes_the_pipe_early_ends_the_command_quietly(tmp_path):
    import subprocess
    import sys

    process = subprocess.Popen(
        [sys.executable, "-m", "structgen", "fortress", "replay", "--random", "1", "--steps", "300", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        cwd=tmp_path,
    )
    assert process.stdout.read(10)  # `| head -c 10`: more than the pipe holds is still to come
    process.stdout.close()
    err = process.stderr.read().decode()
    assert process.wait(timeout=120) == 141 and "Error" not in err and "Traceback" not in err, err


def test_every_verb_shows_examples_that_the_command_line_takes_for_that_verb(tmp_path, monkeypatch):
    import argparse
    import shlex

    from structgen.cli import build_parser

    monkeypatch.chdir(tmp_path)  # examples name files here; parsing them writes nothing
    for path, parser in all_parsers():
        if any(isinstance(action, argparse._SubParsersAction) for action in parser._actions):
            continue
        epilog = parser.epilog or ""
        assert epilog.startswith("examples:"), f"structgen {' '.join(path)} --help shows no examples"
        assert "\n  structgen " in parser.format_help(), path  # kept one to a line
        for line in epilog.splitlines()[1:]:
            words = shlex.split(line)
            assert words[0] == "structgen", line
            try:
                args = build_parser().parse_args(words[1:])
            except SystemExit:
                pytest.fail(f"structgen {' '.join(path)}: its example {line!r} does not parse")
            assert args.handler is parser._defaults["handler"], f"{line!r} reaches another verb than {path}"
