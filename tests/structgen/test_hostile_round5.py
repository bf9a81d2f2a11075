"""Hardening round 5 (issue 87): a report page runs no script that came from its inputs, no command replaces one of
its inputs with its output, every refusal comes before the work, and the newer files' readers go through the file
gate (one line naming the file and the field, exit 2)."""

from __future__ import annotations

import csv
import json
import os
import re
import shutil
from pathlib import Path

import pytest

from tests.helpers import cli, tiny_config
from tests.structgen.test_hostile_inputs import refused
from tests.structgen.test_report import chromium

#: Markup that would run if a page parsed it: an inline handler, a script element, and Plotly's own link markup (its
#: ``popup`` becomes an onclick), each setting ``window.__pwned`` when it runs.
PAYLOADS = (
    '<img src=x onerror="window.__pwned=1">',
    "<script>window.__pwned=2</script>",
    '<a href="https://example.org" popup="\');window.__pwned=3;(\'">link</a>',
)
HOSTILE = " ".join(PAYLOADS)


@pytest.fixture(scope="module")
def qd_run(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("round5")
    from structgen.cli import main

    assert main(["evolve", str(tiny_config(folder, "map_elites")), "--run-dir", str(folder / "run")]) == 0
    return folder / "run"


def _copy_run(source: Path, target: Path) -> Path:
    shutil.copytree(source, target)
    (target / ".lock").unlink(missing_ok=True)
    return target


def _hostile_best(run: Path) -> None:
    best = run / "best" / "best.json"
    data = json.loads(best.read_text())
    data["measures"][HOSTILE] = 1.0
    data["fields"][HOSTILE] = 2.0
    best.write_text(json.dumps(data))


def _hostile_archive_column(run: Path) -> None:
    path = run / "archive.csv"
    rows = list(csv.reader(path.read_text().splitlines()))
    rows[0][rows[0].index("complexity")] = HOSTILE
    with open(path, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)


def _pages(qd_run: Path, tmp_path: Path, capsys) -> dict[str, Path]:
    """A page of each kind, each built from a hostile source."""
    structure = tmp_path / "tower.json"
    assert cli(capsys, "grow", "--seed", 2, "--max-vertices", 12, "-o", structure)[0] == 0
    checked = json.loads(cli(capsys, "evaluate", structure, "--statics", "--json")[1])
    checked.update(method=HOSTILE, integrity=HOSTILE)
    (tmp_path / "checked.json").write_text(json.dumps(checked))
    best = _copy_run(qd_run, tmp_path / "best")
    _hostile_best(best)
    archive = _copy_run(qd_run, tmp_path / "archive")
    _hostile_archive_column(archive)
    named = _copy_run(qd_run, tmp_path / "<img src=x onerror=window.__pwned=4>")
    sources = {"evaluate --json": tmp_path / "checked.json", "best.json": best, "archive.csv": archive, "folder name": named}
    pages = {}
    for label, source in sources.items():
        page = tmp_path / f"{len(pages)}.html"
        code, _, err = cli(capsys, "report", source, "-o", page)
        assert code == 0, err
        pages[label] = page
    compared = tmp_path / "compared.html"
    assert cli(capsys, "compare", best, named, "-o", tmp_path / "c.png", "--html", compared)[0] == 0
    pages["compare"] = compared
    return pages


def test_a_page_states_a_policy_that_lets_only_its_own_scripts_run(qd_run, tmp_path, capsys):
    from structgen.runs.report import content_security_policy

    page = _pages(qd_run, tmp_path, capsys)["best.json"].read_text()
    policy = re.search(r'<meta http-equiv="Content-Security-Policy" content="([^"]+)">', page).group(1)
    assert "default-src 'none'" in policy and "'unsafe-inline'" not in policy.split("script-src")[1].split(";")[0]
    scripts = [body for attributes, body in re.findall(r"<script([^>]*)>(.*?)</script>", page, re.S) if "json" not in attributes]
    assert len(scripts) == 2 and content_security_policy(*scripts) == policy  # Plotly's and the page's own, by hash
    # What came from the file is text in the page: no payload survives as markup anywhere.
    for payload in PAYLOADS:
        assert payload not in page and payload.replace('"', '\\"') not in page


@pytest.mark.slow
def test_no_script_from_a_file_runs_when_the_page_is_opened_or_clicked(qd_run, tmp_path, capsys):
    """Each page opened in Chromium, as written and with its policy taken out (so that the escaping alone is what
    is tested): nothing from the files ran, and the hostile names show as the text they are."""
    executable = chromium()
    from playwright.sync_api import sync_playwright

    pages = _pages(qd_run, tmp_path, capsys)
    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=executable, args=["--no-sandbox", "--use-gl=swiftshader"])
        try:
            for label, path in pages.items():
                bare = path.with_name(f"bare-{path.name}")
                bare.write_text(re.sub(r'<meta http-equiv="Content-Security-Policy"[^>]*>', "", path.read_text()))
                for shown in (path, bare):
                    page = browser.new_page(viewport={"width": 1200, "height": 900})
                    blocked: list[str] = []
                    page.on("console", lambda message, into=blocked: into.append(message.text))
                    page.goto(shown.as_uri())
                    page.wait_for_selector("div.figure .main-svg, div.figure canvas", timeout=60_000)
                    if label == "archive.csv":  # the hostile column is an elite's field: show every elite in turn
                        page.evaluate("() => { for (let i = 0; i < VIEWS.length; i++) showElite(i); }")
                    page.wait_for_timeout(300)
                    assert page.evaluate("() => window.__pwned") is None, (label, shown.name)
                    assert page.locator("#elite-fields img, #elite-fields script, .main-svg a[onclick]").count() == 0
                    if label in ("evaluate --json", "best.json", "archive.csv"):
                        assert PAYLOADS[0] in page.inner_text("#elite-fields"), label  # shown as text
                    # The page as written draws without a single violation of its own policy.
                    assert shown is bare or not [m for m in blocked if "Content Security Policy" in m], blocked
                    page.close()
        finally:
            browser.close()


# -- no input replaced by the output --------------------------------------------------------------------------------------
def _files(tmp_path: Path) -> dict[str, Path]:
    structure = tmp_path / "seven.json"
    from structgen.cli import main

    assert main(["grow", "--seed", "2", "--max-vertices", "12", "-o", str(structure)]) == 0
    # The refusal comes before anything is read: the weights' contents do not matter.
    weights, generator = tmp_path / "w.json", tmp_path / "g.json"
    weights.write_text("[0.5]")
    generator.write_text("[0.25]")
    shutil.copy(structure, tmp_path / "tower.html")  # a structure file under another suffix
    return {"structure": structure, "weights": weights, "generator": generator, "html": tmp_path / "tower.html"}


SAME_FILE = [
    pytest.param(["report", "{html}", "-o", "{html}"], "html", id="report onto its structure"),
    pytest.param(["warehouse", "grow", "--weights", "{generator}", "-o", "{generator}"], "generator", id="grow onto weights"),
    pytest.param(["regrow", "{structure}", "--weights", "{weights}", "-o", "{weights}"], "weights", id="regrow onto its weights"),
    pytest.param(["regrow", "{structure}", "--weights", "{weights}", "-o", "{structure}"], "structure", id="regrow onto input"),
    pytest.param(["export", "{structure}", "{structure}"], "structure", id="export onto its source"),
]


@pytest.mark.parametrize("how", ["path", "hard link", "symbolic link", "other spelling"])
@pytest.mark.parametrize("argv, victim", SAME_FILE)
def test_an_output_that_is_an_input_is_refused_before_any_work(tmp_path, capsys, argv, victim, how):
    files = _files(tmp_path)
    capsys.readouterr()  # what growing the inputs printed
    before = {name: path.read_bytes() for name, path in files.items()}
    target = files[victim]
    if how == "hard link":
        target = tmp_path / f"hard{target.suffix}"
        os.link(files[victim], target)
    elif how == "symbolic link":
        target = tmp_path / f"link{target.suffix}"
        target.symlink_to(files[victim])
    elif how == "other spelling":
        (tmp_path / "sub").mkdir()
        target = tmp_path / "sub" / ".." / files[victim].name
    words = [w.replace(f"{{{victim}}}", str(target)) if i == len(argv) - 1 else w for i, w in enumerate(argv)]
    words = [re.sub(r"\{(\w+)\}", lambda m: str(files[m.group(1)]), w) for w in words]
    refused(capsys, *words, fragments=("an input of this command",))
    assert {name: path.read_bytes() for name, path in files.items()} == before


def test_an_output_replacing_a_file_of_the_run_it_reads_is_refused(qd_run, tmp_path, capsys):
    run = _copy_run(qd_run, tmp_path / "run")
    best = (run / "best" / "best.json").read_bytes()
    refused(capsys, "export", run, run / "best" / "best.json", fragments=("which this command reads",))
    refused(capsys, "report", run, "-o", run / "metrics.jsonl", fragments=("which this command reads",))
    assert (run / "best" / "best.json").read_bytes() == best
    # A new file beside the run's own replaces nothing: that is allowed.
    assert cli(capsys, "export", run, run / "best.obj")[0] == 0


def test_two_outputs_of_one_name_are_refused(tmp_path, capsys):
    files = _files(tmp_path)
    capsys.readouterr()  # what growing the inputs printed
    out = tmp_path / "out.png"
    refused(capsys, "regrow", files["structure"], "--weights", files["weights"], "-o", out, "--picture", out,
            fragments=("two outputs",))  # fmt: skip
    assert not out.exists()


def test_overwrite_never_replaces_a_folder_that_holds_an_input(qd_run, tmp_path, capsys):
    run = _copy_run(qd_run, tmp_path / "run")
    config = run / "config.toml"
    before = config.read_bytes()
    refused(capsys, "evolve", config, "--run-dir", run, "--overwrite", fragments=("an input of this command",))
    assert config.read_bytes() == before
