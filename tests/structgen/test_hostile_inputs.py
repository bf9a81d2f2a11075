"""Every input that once misbehaved (issue 10's list) is refused in one line naming the place, exit code 2, with
nothing written; and the wrong results it listed are right."""

from __future__ import annotations

import io
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from physics import PhysicsConfig, check_stability
from structgen import Structure, StructureError
from structgen.cli import main

GOOD = '{"vertices": [[0, 0, 0], [0, 0, 1]], "edges": [[0, 1]]}'
FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "runs_0.1.0"


def run(capsys, *argv) -> tuple[int, str, str]:
    try:
        code = main([str(a) for a in argv])
    except SystemExit as done:  # argparse's own usage errors
        code = done.code
    out, err = capsys.readouterr()
    return code, out, err


def refused(capsys, *argv, fragments: tuple[str, ...] = ()) -> str:
    code, out, err = run(capsys, *argv)
    assert code == 2, err
    # Runs kept as fixtures were made on Python 3.11; on another version, resuming warns about it first.
    lines = [line for line in err.strip().splitlines() if not line.startswith("WARNING: library versions differ")]
    assert out == "" and len(lines) == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in err, err
    return err


def npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    (tmp_path / "ok.json").write_text(GOOD)
    return tmp_path


def inputs(folder: Path) -> dict[str, tuple[list, tuple[str, ...]]]:
    """Name: (command line, what the message must say)."""
    (folder / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    (folder / "loop1").symlink_to(folder / "loop2")
    (folder / "loop2").symlink_to(folder / "loop1")
    (folder / "empty.npy").write_bytes(b"")
    lying = io.BytesIO()  # a header that claims 8 TB, and the 38 KB of one real weight vector after it
    np.lib.format.write_array_header_1_0(lying, {"descr": "<f8", "fortran_order": False, "shape": (10**12,)})
    (folder / "lying.npy").write_bytes(lying.getvalue() + np.zeros(4766).tobytes())
    os.mkfifo(folder / "fifo.json")
    (folder / "nan.json").write_text('{"vertices": [[0, 0, 0]], "edges": [], "metadata": {"x": NaN}}')
    (folder / "huge.json").write_text(json.dumps({"vertices": [[0, 0, 10**12]], "edges": []}))
    (folder / "bad.toml").write_text("[run]\ngenerations = 'ten'\n")
    return {
        "deep JSON": (["info", folder / "deep.json"], ("deep.json", "nested too deeply")),
        "symlink loop": (["info", folder / "loop1"], ("loop1", "symbolic links")),
        "file as a folder": (["info", folder / "ok.json" / "x.json"], ("x.json", "a part of the path is a file")),
        "output under a file": (["export", folder / "ok.json", folder / "ok.json" / "x.glb"], ("is a file, not a folder",)),
        "output name too long": (["export", folder / "ok.json", folder / ("a" * 300 + ".glb")], ("file name too long",)),
        "dpi 0": (["show", folder / "ok.json", "-o", folder / "x.png", "--dpi", "0"], ("--dpi", "got 0")),
        "seed -1": (["grow", "--seed", "-1", "-o", folder / "g.json"], ("--seed", "got -1")),
        "huge max-vertices": (
            ["grow", "--max-vertices", 10**19, "-o", folder / "g.json"],
            ("--max-vertices", "10,000,000,000,000,000,000"),
        ),
        "empty .npy": (["grow", "--weights", folder / "empty.npy", "-o", folder / "g.json"], ("empty.npy", "not a valid .npy")),
        "lying .npy header": (["grow", "--weights", folder / "lying.npy", "-o", folder / "g.json"], ("lying.npy", "header says")),
        "a FIFO": (["info", folder / "fifo.json"], ("fifo.json", "not a regular file")),
        "/dev/zero": (["info", "/dev/zero"], ("/dev/zero", "not a regular file")),
        "NaN in metadata": (["export", folder / "nan.json", folder / "n.glb"], ("nan.json", "NaN")),
        "coordinate too large": (["info", folder / "huge.json"], ("huge.json", "vertices[0]", "out of range")),
        "tiny timestep": (["evaluate", folder / "ok.json", "--set", "timestep=1e-9"], ("max_steps",)),
        "config error names the file": (
            ["evolve", folder / "bad.toml", "--run-dir", folder / "run"],
            ("bad.toml", "run.generations"),
        ),
        "infinite init scale": (
            ["evolve", "--set", "problem.init_scale=inf", "--run-dir", folder / "run"],
            ("init_scale", "inf"),
        ),
    }


@pytest.mark.parametrize(
    "name",
    [
        "deep JSON",
        "symlink loop",
        "file as a folder",
        "output under a file",
        "output name too long",
        "dpi 0",
        "seed -1",
        "huge max-vertices",
        "empty .npy",
        "lying .npy header",
        "a FIFO",
        "/dev/zero",
        "NaN in metadata",
        "coordinate too large",
        "tiny timestep",
        "config error names the file",
        "infinite init scale",
    ],
)
def test_bad_input_is_refused_in_one_line_and_nothing_is_written(folder, capsys, name):
    argv, fragments = inputs(folder)[name]
    before = sorted(p.name for p in folder.iterdir())
    refused(capsys, *argv, fragments=fragments)
    assert sorted(p.name for p in folder.iterdir()) == before  # no output, no run folder, no temporary file


@pytest.mark.parametrize(
    "damage, fragments",
    [
        ("checkpoint.pkl", ("checkpoint.pkl", "cannot read the checkpoint")),
        ("metrics.jsonl", ("metrics.jsonl, line 1", "not valid JSON")),
        ("best/genome.npy", ("genome.npy", "not a valid .npy")),
        ("archive.csv", ("archive.csv", "not an archive")),
        ("archive_solutions.npy", ("archive_solutions.npy", "holds 1 genomes for the")),
    ],
)
def test_a_damaged_run_folder_names_the_damaged_file(tmp_path, capsys, damage, fragments):
    run = tmp_path / "run"
    shutil.copytree(FIXTURES / "structures_cma_mae", run)
    path = run / damage
    if damage == "archive_solutions.npy":
        path.write_bytes(npy_bytes(np.load(path)[:1]))  # cut to one row: never a genome of zeros
    elif damage == "metrics.jsonl":
        path.write_text("{not json\n" + path.read_text())
    else:
        path.write_bytes(b"\x00garbage" * 3)
    index = (FIXTURES / "structures_cma_mae" / "archive.csv").read_text().splitlines()[2].split(",")[0]
    command = ["resume", run, "--generations", 3]
    if damage in ("best/genome.npy", "archive.csv", "archive_solutions.npy"):
        elite = "best" if damage == "best/genome.npy" else f"index:{index}"
        command = ["export", run, tmp_path / "out.json", "--elite", elite]
    refused(capsys, *command, fragments=fragments)
    assert not (tmp_path / "out.json").exists()


def test_coordinates_out_of_range_are_refused_before_any_conversion():
    for vertices in (
        [[0, 0, 1e300], [1, 0, 0]],
        np.array([[0, 0, 1e300], [1, 0, 0]]),
        np.array([[2**63 + 5, 0, 0]], dtype=np.uint64),
    ):
        with pytest.raises(StructureError, match="out of range"):
            Structure(vertices)
    assert Structure([[0, 0, 2**20]]).height == 0


def test_a_piece_still_falling_when_the_simulation_ends_adds_no_height_and_does_not_stand(tmp_path, capsys):
    floating = {"vertices": [[0, 0, 0], [5, 5, 100]], "edges": []}
    report = check_stability(floating, PhysicsConfig.preset("fast"))
    assert report.falling == 1 and report.height == 0.0 and not report.stands and report.final_speed > 10
    (tmp_path / "f.json").write_text(json.dumps(floating))
    code, out, _ = run(capsys, "evaluate", tmp_path / "f.json", "--preset", "fast", "--strict")
    assert code == 1 and "still falling when the simulation ended: 1 vertex" in out
    resting = check_stability({"vertices": [[0, 0, 0], [0, 0, 1]], "edges": [[0, 1]]}, PhysicsConfig.preset("fast"))
    assert resting.stands and resting.falling == 0 and resting.height == pytest.approx(1.0, abs=1e-3)


def test_exports_and_static_solves_beyond_the_memory_budget_are_refused_before_allocating(tmp_path, capsys, monkeypatch):
    n = 20_000
    line = Structure(
        np.stack([np.arange(n), np.zeros(n, int), np.zeros(n, int)], 1), np.stack([np.arange(n - 1), np.arange(1, n)], 1)
    )
    line.save(tmp_path / "line.json")
    monkeypatch.setenv("STRUCTGEN_MEMORY_MB", "32")
    refused(
        capsys,
        "export",
        tmp_path / "line.json",
        tmp_path / "line.glb",
        fragments=("memory budget of 32 MiB", "STRUCTGEN_MEMORY_MB"),
    )
    refused(
        capsys,
        "evaluate",
        tmp_path / "line.json",
        "--statics",
        "--set",
        "max_memory_mb=8",
        fragments=("max_memory_mb = 8",),
    )
    refused(capsys, "grow", "--iterations", 40, "-o", tmp_path / "g.json", fragments=("growing 1 NCA", "budget of 32 MiB"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["line.json"]


def test_the_memory_budget_defaults_to_4_gib_and_refuses_a_nonsense_setting(monkeypatch):
    from structgen.budget import check_memory, memory_budget_mb
    from structgen.errors import InputError

    monkeypatch.delenv("STRUCTGEN_MEMORY_MB", raising=False)
    assert memory_budget_mb() == 4096
    check_memory(4000 * 2**20, "a mesh")
    with pytest.raises(InputError, match="more than the memory budget of 4,096 MiB"):
        check_memory(5000 * 2**20, "a mesh")
    for text in ("lots", "0", "-5", "inf", "nan"):
        monkeypatch.setenv("STRUCTGEN_MEMORY_MB", text)
        with pytest.raises(InputError, match=f"STRUCTGEN_MEMORY_MB='{text}'"):
            memory_budget_mb()


OUTPUT_VERBS = [
    ["grow", "--seed", "1", "--max-vertices", "8", "-o", "{out}"],
    ["export", "{structure}", "{out}"],
    ["show", "{structure}", "--statics", "-o", "{out}"],
    ["warehouse", "grow", "--size", "6x8", "--iterations", "2", "-o", "{out}"],
    ["fortress", "evaluate", "--random", "1", "--steps", "2", "--save", "{out}"],
]


@pytest.mark.parametrize("argv", OUTPUT_VERBS, ids=lambda argv: " ".join(argv[:2]))
@pytest.mark.parametrize("kind", ["fifo", "device", "folder", "missing folder"])
def test_an_output_path_that_is_not_a_regular_file_is_refused_before_any_work(tmp_path, capsys, argv, kind):
    import os

    structure = tmp_path / "s.json"
    structure.write_text('{"vertices": [[0, 0, 0], [0, 0, 1]], "edges": [[0, 1]]}')
    if kind == "fifo":
        out = tmp_path / "pipe.json"
        os.mkfifo(out)
    elif kind == "device":
        out = Path("/dev/null")  # refused before anything is written: never replaced, even by root
    elif kind == "folder":
        out = tmp_path / "a-folder.json"
        out.mkdir()
    else:
        out = tmp_path / "no" / "such" / "folder" / "out.json"
    before = sorted(p.name for p in tmp_path.iterdir())
    try:
        code = main([part.format(out=out, structure=structure) for part in argv])
    except SystemExit as usage:  # refused by the option's own check, as a usage error
        code = usage.code
    err = capsys.readouterr().err
    assert code == 2, err
    expected = {"fifo": "is a FIFO, not a regular file", "device": "is a device, not a regular file", "folder": "is a folder"}
    assert expected.get(kind, "no such folder") in err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written, no folder made
    assert Path("/dev/null").is_char_device()


@pytest.mark.parametrize(
    ("target", "edit", "message"),
    [
        ("metrics.jsonl", lambda text: text.replace('"evaluations": ', '"evaluations": [1], "x": ', 1), "evaluations = [1]"),
        ("best/best.json", lambda text: text.replace('"objective": ', '"objective": "high", "x": ', 1), "objective = 'high'"),
        ("best/best.json", lambda text: text.replace('"generation": ', '"generation": null, "x": ', 1), "generation = None"),
    ],
)
def test_info_refuses_a_run_whose_numbers_were_tampered_with_naming_the_file(tmp_path, capsys, target, edit, message):
    run = tmp_path / "run"
    assert main(["evolve", "--domain", "ones-v0", "--generations", "2", "--workers", "0", "--run-dir", str(run)]) == 0
    (run / target).write_text(edit((run / target).read_text()))
    capsys.readouterr()
    assert main(["info", str(run)]) == 2
    err = capsys.readouterr().err
    assert target.split("/")[-1] in err and message in err and "Traceback" not in err


def _files(tmp_path: Path) -> None:
    """What the cases below refer to, written into their scratch folder."""
    (tmp_path / "surrogate.json").write_text('{"tiles": ".@ersw", "layout": ["\\ud800....", "....."]}')
    (tmp_path / "structure.json").write_text('{"vertices": [[0, 0, 0]], "edges": [], "metadata": {"\\udc80": 1}}')
    (tmp_path / "big.json").write_text(json.dumps({"tiles": ".@ersw", "layout": ["." * 1000] * 1000}))
    (tmp_path / "deep.toml").write_text("[run]\nseed = " + "9" * 5000 + "\n")
    from structgen.domains.autoverse.game import game_to_json, random_game

    game = game_to_json(random_game(np.random.default_rng(0)))
    (tmp_path / "budget.json").write_text(json.dumps({**game, "budget": "many"}))
    (tmp_path / "rewards.json").write_text(json.dumps({**game, "rewards": [None] * 5}))
    (tmp_path / "old-tall").mkdir()
    (tmp_path / "old-tall" / "settings.json").write_text("[1, 2]")
    (tmp_path / "afile").write_text("not a folder")


HOSTILE = [
    (["warehouse", "measure", "surrogate.json"], "a lone UTF-16 surrogate"),
    (["info", "structure.json"], "a lone UTF-16 surrogate"),
    (["warehouse", "grow", "--device", "bogus", "-o", "g.json"], "expected cpu, cuda, cuda:N or mps"),
    (["warehouse", "grow", "--device", "meta", "-o", "g.json"], "expected cpu, cuda, cuda:N or mps"),
    (["autoverse", "evolve", "--set", "device=bogus", "--print-config"], "problem device = 'bogus'"),
    (["warehouse", "repair", "big.json", "-o", "r.json", "--time-limit", "nan"], "expected a finite number"),
    (["warehouse", "repair", "big.json", "-o", "r.json", "--time-limit", "0"], "expected a number above 0"),
    (["warehouse", "repair", "big.json", "-o", "r.json", "--shelves", "10"], "the repair of a 1000x1000 map needs about"),
    (["evolve", "--set", "seed=" + "[" * 5000 + "]" * 5000, "--print-config"], "nested too deeply"),
    (["evolve", "--set", "seed=" + "9" * 5000, "--print-config"], "a number too long to read"),
    (["evolve", "deep.toml", "--print-config"], "deep.toml: not valid TOML"),
    (["evolve", "--domain", "ones-v0", "--cluster", "not an address", "--run-dir", "c"], "is not a Dask scheduler's address"),
    (["evolve", "--optimizer", "map_elites", "--set", "cells=[100000,100000]", "--run-dir", "c"], "optimizer cells = [100,000"),
    (["evolve", "--domain", "ones-v0", "--workers", "1000", "--run-dir", "c"], "run.workers = 1000: that many worker"),
    (["warehouse", "evolve", "--set", "size=2000x2000", "--run-dir", "c"], "problem size = '2000x2000'"),
    (["autoverse", "play", "budget.json", "--steps", "3"], "budget.json.budget = 'many'"),
    (["autoverse", "play", "rewards.json", "--steps", "3"], "rewards.json.rewards: must hold numbers"),
    (["autoverse", "clone", "c", "-o", "bc", "--lr", "nan"], "argument --lr: expected a finite number"),
    (["autoverse", "clone", "c", "-o", "bc", "--min-fitness", "inf"], "argument --min-fitness: expected a finite number"),
    (["info", "old-tall"], "settings.json: expected an object of settings, got list"),
    (["fortress", "evaluate", "x" * 300], "file name too long"),
]


@pytest.mark.parametrize(("argv", "message"), HOSTILE, ids=[" ".join(argv)[:50] for argv, _ in HOSTILE])
def test_hostile_input_is_refused_in_one_line_with_exit_2_and_nothing_written(tmp_path, monkeypatch, capsys, argv, message):
    _files(tmp_path)
    monkeypatch.chdir(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    try:
        code = main(argv)
    except SystemExit as usage:
        code = usage.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
