"""The README's examples run as written: every `structgen` command of its bash blocks, every python block, every
toml block.

Commands run in order, in one scratch folder that sees the repository's configs/, docs/ and examples/, through the
same entry point as the console script. Two changes keep the suite short, and nothing else is changed: evolution runs
stop after one generation (``--generations 1 --workers 0`` appended; a resume with ``--generations`` continues to 2),
and an ``--elite index:I`` whose cell the short run did not fill takes a cell it did fill. A command whose comment
says ``exits N`` must exit with N; every other one with 0. ``console`` blocks are not run (the plugin's commands are
run by tests/test_plugins.py).
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
import sys
from pathlib import Path

import pytest

from structgen.cli import main
from structgen.experiment import load_experiment

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()

# One worker for the whole file under pytest -n (make test uses --dist loadgroup): the commands run once, not twice.
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("readme")]


def blocks(language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", README, flags=re.S | re.M)


def commands() -> list[tuple[list[str], int]]:
    """``(argv, expected exit code)`` for every structgen command in the bash blocks."""
    found = []
    for block in blocks("bash"):
        for line in block.splitlines():
            if not line.startswith("structgen "):
                continue
            command, _, comment = line.partition("  #")
            expected = re.search(r"\bexits (\d)", comment)
            found.append((shlex.split(command)[1:], int(expected.group(1)) if expected else 0))
    return found


def shortened(argv: list[str], scratch: Path) -> list[str]:
    """The command with its evolution cut short and its archive cell taken from the run at hand."""
    argv = list(argv)
    verb = argv[1] if argv[0] not in ("evolve", "resume", "export", "grow") and len(argv) > 1 else argv[0]
    if verb == "evolve" and "--print-config" not in argv:
        argv += ["--generations", "1", "--workers", "0"]
    if verb == "resume" and "--generations" in argv:
        argv[argv.index("--generations") + 1] = "2"
    if "--elite" in argv and argv[argv.index("--elite") + 1].startswith("index:"):
        run = scratch / (argv[argv.index("--run") + 1] if "--run" in argv else argv[1])
        cells = [line.split(",")[0] for line in (run / "archive.csv").read_text().splitlines()[1:]]
        cell = argv[argv.index("--elite") + 1].split(":")[1]
        if cell not in cells:
            argv[argv.index("--elite") + 1] = f"index:{cells[0]}"
    return argv


@pytest.fixture(scope="module")
def scratch(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("readme")
    for name in ("configs", "docs", "examples"):
        (folder / name).symlink_to(ROOT / name)
    return folder


def test_the_readme_has_examples_of_each_kind():
    assert len(commands()) >= 30 and len(blocks("python")) >= 4 and blocks("toml")


@pytest.fixture(scope="module")
def ran_commands(scratch) -> list[tuple[list[str], int, int, str]]:
    """Every command run once, in order, in the scratch folder: ``(argv, expected code, code, stderr)`` each. A
    fixture, not a test, because the python blocks need what the commands made, and a test run split over several
    processes (pytest -n) may give the two tests to different ones."""
    results = []
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(scratch)
        for argv, expected in commands():
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(shortened(argv, scratch))
            results.append((argv, expected, code, err.getvalue()))
    return results


def test_every_command_runs_as_written(ran_commands):
    for argv, expected, code, err in ran_commands:
        assert code == expected, f"structgen {shlex.join(argv)} exited {code}:\n{err[-2000:]}"


def test_every_python_block_runs(ran_commands, scratch, monkeypatch, capsys):
    monkeypatch.chdir(scratch)
    namespace: dict = {"__name__": "readme_example"}
    for n, block in enumerate(blocks("python")):
        exec(compile(block, f"README.md python block {n + 1}", "exec"), namespace)
    out = capsys.readouterr().out
    assert "runs/ones" in str(namespace["folder"].path) and namespace["state"].generation == 5
    assert namespace["small"].n_vertices <= 64 and (scratch / "tower.glb").exists()
    assert (scratch / "runs" / "words" / "best" / "genome.json").exists() and out


def test_every_toml_block_is_a_configuration_taken_as_written(tmp_path):
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    def leaves(table: dict, prefix: str = "") -> dict:
        out = {}
        for key, value in table.items():
            out.update(leaves(value, f"{prefix}{key}.") if isinstance(value, dict) else {prefix + key: value})
        return out

    configurations = [block for block in blocks("toml") if "[project" not in block]  # not a package's pyproject
    assert configurations
    for n, block in enumerate(configurations):
        path = tmp_path / f"block{n}.toml"
        path.write_text(block)
        resolved = leaves(load_experiment(path).to_mapping())
        for key, value in leaves(tomllib.loads(block)).items():
            assert resolved[key] == value, key
