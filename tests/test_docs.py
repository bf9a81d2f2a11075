"""Every example in the docs runs as written: the README, CONTRIBUTING.md, the guide's pages under docs/ and the
benchmark pages.

Each page runs in a scratch folder of its own that sees the repository's configs/, docs/ and examples/, its blocks in
the order a reader meets them, exactly as written: every `structgen` line of a ``bash`` block (through the same entry
point as the console script) and every ``python`` block (in one namespace per page; a block that uses another's
names says that it continues it). A command whose comment says ``exits N`` must exit with N; every other one with 0.
``console`` blocks are shown, not run: the docs put there what takes minutes (saying how long) or installs a package
(tests/test_plugins.py runs the plugin's). Every ``toml`` block is a configuration that loads as written.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from structgen.cli import main
from structgen.config import flatten
from structgen.runs.experiment import load_experiment

ROOT = Path(__file__).resolve().parents[1]
PAGES = [
    ROOT / "README.md",
    ROOT / "CONTRIBUTING.md",
    *sorted((ROOT / "docs").rglob("*.md")),
    *sorted((ROOT / "benchmarks").glob("*.md")),
]
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", flags=re.S | re.M)

pytestmark = pytest.mark.slow


def name(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


def blocks(page: Path, *languages: str) -> list[tuple[str, str]]:
    """``(language, text)`` of the page's fenced blocks in those languages, in order."""
    return [(language, text) for language, text in BLOCK.findall(page.read_text()) if language in languages]


def commands(text: str) -> list[tuple[list[str], int]]:
    """``(argv, expected exit code)`` for every structgen command of a bash block."""
    found = []
    for line in text.splitlines():
        if not line.startswith("structgen "):
            continue
        command, _, comment = line.partition("  #")
        expected = re.search(r"\bexits (\d)", comment)
        found.append((shlex.split(command)[1:], int(expected.group(1)) if expected else 0))
    return found


RUNNABLE = [
    page for page in PAGES if any(commands(text) or language == "python" for language, text in blocks(page, "bash", "python"))
]


def test_the_pages_have_examples_of_each_kind():
    assert {name(page) for page in RUNNABLE} >= {"README.md", "docs/runs.md", "docs/structures.md", "docs/layouts.md"}
    assert sum(len(commands(text)) for page in PAGES for _, text in blocks(page, "bash")) >= 60
    assert sum(len(blocks(page, "python")) for page in PAGES) >= 8 and any(blocks(page, "toml") for page in PAGES)


@pytest.mark.parametrize("page", RUNNABLE, ids=name)
def test_every_example_of_the_page_runs_in_order(page, tmp_path, monkeypatch, capsys):
    for folder in ("configs", "docs", "examples"):
        (tmp_path / folder).symlink_to(ROOT / folder)
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "docs_example"}
    for n, (language, text) in enumerate(blocks(page, "bash", "python"), start=1):
        where = f"{name(page)}, block {n}"
        if language == "python":
            exec(compile(text, f"{where} (python)", "exec"), namespace)
            continue
        for argv, expected in commands(text):
            out, err = io.StringIO(), io.StringIO()
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                code = main(argv)
            assert code == expected, f"{where}: structgen {shlex.join(argv)} exited {code}:\n{err.getvalue()[-2000:]}"


def test_every_toml_block_is_a_configuration_taken_as_written(tmp_path):
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    configurations = [text for page in PAGES for _, text in blocks(page, "toml") if "[project" not in text]
    assert configurations
    for n, text in enumerate(configurations):
        path = tmp_path / f"block{n}.toml"
        path.write_text(text)
        resolved = flatten(load_experiment(path).to_mapping())
        for key, value in flatten(tomllib.loads(text)).items():
            assert resolved[key] == value, key


def test_the_layer_picture_is_drawn_from_the_code():
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "docs"))
    try:
        import hooks
    finally:
        sys.path.pop(0)
    from tests.layering import GRAPH

    svg = hooks.layers_svg()
    for name in GRAPH:  # every folder of the code has its box, named as the picture names it
        group = hooks._group(name)
        assert (group.removeprefix("domains/") or "domains/__init__") in svg, group
    assert "layouts/ (" in svg and "#cc0000" not in svg.lower()  # no arrow up


def test_a_broken_link_fails_the_docs_build(tmp_path):
    # `make docs`'s own command, on a copy of the pages: as they are it builds; with one broken link it must fail
    # (mkdocs' --quiet once hid the very warnings that --strict counts).
    makefile = (ROOT / "Makefile").read_text().splitlines()
    recipe = makefile[makefile.index("docs: install") + 1].strip()
    words = shlex.split(recipe.replace("$(BIN)/mkdocs", "MKDOCS"))
    env = dict(word.split("=", 1) for word in words if "=" in word and not word.startswith("-"))
    command = [sys.executable, "-m", "mkdocs", *(w for w in words[words.index("MKDOCS") + 1 :])]
    command[command.index("--site-dir") + 1] = str(tmp_path / "site")
    docs = tmp_path / "docs"
    shutil.copytree(ROOT / "docs", docs)
    config = tmp_path / "mkdocs.yml"
    config.write_text(f"INHERIT: {ROOT / 'mkdocs.yml'}\ndocs_dir: {docs}\nhooks:\n  - {ROOT / 'docs' / 'hooks.py'}\n")

    def build() -> subprocess.CompletedProcess:
        run_env = {**os.environ, **env}
        return subprocess.run([*command, "-f", str(config)], capture_output=True, text=True, cwd=ROOT, env=run_env, timeout=600)

    assert build().returncode == 0, build().stderr
    page = docs / "runs.md"
    page.write_text(page.read_text() + "\nSee [a page that is gone](no-such-page.md).\n")
    broken = build()
    assert broken.returncode != 0 and "no-such-page.md" in broken.stderr
