"""structgen report: one self-contained HTML page for a run, a file, or runs compared; and the page in a real headless
browser (Debian's Chromium through playwright), where the 3D view and the heatmap must draw and a click on an archive
cell must show its elite."""

from __future__ import annotations

import base64
import io
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from structgen import domains
from tests.helpers import cli, tiny_config

#: Set where the browser test must run (CI installs Chromium): a missing browser then fails instead of skipping.
REQUIRE_BROWSER = "STRUCTGEN_REQUIRE_BROWSER"


@pytest.fixture(scope="module")
def qd_run(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("report")
    from structgen.cli import main

    assert main(["evolve", str(tiny_config(folder, "map_elites")), "--run-dir", str(folder / "run")]) == 0
    return folder / "run"


def numbers(value) -> np.ndarray:
    """An array as a figure holds it: a list, or Plotly's typed array (``{"dtype", "bdata"[, "shape"]}``)."""
    if isinstance(value, dict):
        array = np.frombuffer(base64.b64decode(value["bdata"]), dtype=np.dtype(value["dtype"]))
        return array.reshape([int(n) for n in str(value["shape"]).split(",")]) if "shape" in value else array
    return np.asarray(value, dtype=float)


def views_of(page: str) -> list[dict]:
    return json.loads(re.search(r'id="views-data">(.*?)</script>', page, re.S).group(1).replace("<\\/", "</"))


def test_a_run_report_is_one_page_that_needs_nothing_else(qd_run, tmp_path, capsys):
    output = tmp_path / "report.html"
    code, out, _ = cli(capsys, "report", qd_run, "-o", output)
    assert code == 0 and out.startswith(f"{output}: ")
    page = output.read_text()
    # Nothing is fetched when it is opened: no script, style or picture from elsewhere.
    assert not re.search(r'<(script|link|img)[^>]+(src|href)="(https?:)?//', page)
    assert 'id="progress-data"' in page and 'id="archive-data"' in page
    archive = (qd_run / "archive.csv").read_text().splitlines()
    views = views_of(page)
    assert len(views) == len(archive)  # the best, then every elite (header line: one fewer elite than lines)
    assert views[0]["name"] == "best" and all("lines3d" in view for view in views)
    lines = views[0]["lines3d"]  # compact: the page draws it when shown
    points, pairs, loads = (numbers(lines[key]) for key in ("points", "pairs", "values"))
    assert len(points) % 3 == 0 and len(pairs) == 2 * len(loads) and pairs.max() < len(points) // 3
    assert len(loads) and (loads <= 255).all()  # shares of the break force in 254ths (255: no static answer)
    styles = json.loads(re.search(r'id="styles-data">(.*?)</script>', page, re.S).group(1))
    assert len(styles) == 1 and {view["lines3d"]["style"] for view in views} == {0}  # one style, written once
    assert "static analysis" in views[0]["verdict"] and "statics: score Q" in views[0]["fields"]


def test_a_structure_file_and_a_check_result_get_their_own_page(tmp_path, capsys):
    structure = tmp_path / "tower.json"
    assert cli(capsys, "grow", "--seed", 2, "--max-vertices", 12, "-o", structure)[0] == 0
    code, out, _ = cli(capsys, "evaluate", structure, "--statics", "--json")
    checked = tmp_path / "checked.json"
    checked.write_text(out)
    for source, extra in ((structure, None), (checked, "check: integrity")):
        output = tmp_path / f"{source.stem}.html"
        assert cli(capsys, "report", source, "-o", output)[0] == 0
        (view,) = views_of(output.read_text())
        assert "lines3d" in view
        assert extra is None or extra in view["fields"]


@pytest.mark.parametrize("spec", [s for s in domains.specs() if s.command_hooks()], ids=lambda spec: spec.id)
def test_every_domain_draws_its_elites_as_figures_plotly_accepts(spec):
    import plotly.graph_objects as go

    from structgen.config import build

    problem = spec.make(build(spec.settings_type(), spec.test_settings, "problem"))
    try:
        genome = problem.initial_genomes(1, np.random.default_rng(0))[0]
        view = spec.command_hooks().report_view(problem, genome)
    finally:
        problem.close()
    if view is None:  # a domain may draw nothing: its elites show their numbers
        return
    if "lines3d" in view:  # Plotly's own check of every property: the compact view's traces and layout
        style = view["lines3d"]["style"]
        go.Figure([style["lines"], style["markers"]], style["layout"])
    else:
        go.Figure(view["figure"])
    json.dumps(view.get("fields", {}))


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["report", "{tmp}", "-o", "{tmp}/r.html"], "no run folder"),
        (["report", "{tmp}/missing", "-o", "{tmp}/r.html"], "no such file"),
        (["report", "{run}", "-o", "{tmp}/r.txt"], "HTML"),
        (["report", "{tmp}/notes.txt", "-o", "{tmp}/r.html"], "notes.txt"),
    ],
)
def test_bad_input_gets_one_line_and_leaves_no_page(qd_run, tmp_path, capsys, argv, fragment):
    (tmp_path / "notes.txt").write_text("not a structure")
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{run}", str(qd_run)) for a in argv]
    code, out, err = cli(capsys, *argv)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and fragment in err
    assert not (tmp_path / "r.html").exists() and not (tmp_path / "r.txt").exists()


def test_compare_writes_the_curves_of_several_runs_as_a_page(qd_run, tmp_path, capsys):
    page = tmp_path / "compare.html"
    code, _, err = cli(capsys, "compare", qd_run, qd_run, "-o", tmp_path / "c.png", "--html", page)
    assert code == 0, err
    figure = json.loads(re.search(r'id="progress-data">(.*?)</script>', page.read_text(), re.S).group(1))
    assert {trace["name"] for trace in figure["data"]} == {"run", "run'"}  # two folders of one name told apart


# -- in a browser ---------------------------------------------------------------------------------------------------------
def chromium() -> str:
    """The Chromium to drive, or a skip (a failure where the browser test is required) saying what is missing."""
    found = os.environ.get("STRUCTGEN_CHROMIUM") or next(
        (path for name in ("chromium", "chromium-browser", "google-chrome") if (path := shutil.which(name))), None
    )
    missing = None if found else "no Chromium on this machine (Debian: apt-get install chromium)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        missing = "playwright is not installed (make install puts it in the test tools)"
    if missing:
        (pytest.fail if os.environ.get(REQUIRE_BROWSER) else pytest.skip)(f"the browser test needs a browser: {missing}")
    return found


def test_the_report_draws_in_a_browser_and_a_click_shows_an_elite(qd_run, tmp_path, capsys):
    executable = chromium()
    from PIL import Image
    from playwright.sync_api import sync_playwright

    output = tmp_path / "report.html"
    assert cli(capsys, "report", qd_run, "-o", output)[0] == 0
    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path=executable, args=["--no-sandbox", "--use-gl=swiftshader"])
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.on("console", lambda message: errors.append(message.text) if message.type == "error" else None)
            page.goto(output.as_uri())
            page.wait_for_selector("#elite-view .gl-container canvas", timeout=60_000)  # the 3D view drew
            page.wait_for_selector("#archive .heatmaplayer image, #archive .hm", timeout=60_000)  # the heatmap drew
            assert page.inner_text("#elite-title") == "Elite: best"
            shot = Image.open(io.BytesIO(page.locator("#elite").screenshot())).convert("L")
            assert shot.getextrema()[1] - shot.getextrema()[0] > 50  # not a blank panel
            # Click the centre of a filled cell (not the best's view, 0), where Plotly's own axes put it on the screen.
            heatmap = json.loads(re.search(r'id="archive-data">(.*?)</script>', output.read_text(), re.S).group(1))
            custom = numbers(heatmap["data"][0]["customdata"])
            row, col = np.argwhere(custom > 0)[0]
            x, y = page.evaluate(
                """([row, col]) => {
                  const plot = document.getElementById("archive"), layout = plot._fullLayout;
                  const box = plot.getBoundingClientRect();
                  return [box.left + layout._size.l + layout.xaxis.d2p(col), box.top + layout._size.t + layout.yaxis.d2p(row)];
                }""",
                [int(row), int(col)],
            )
            cell = int(custom[row, col])
            page.mouse.click(x, y)
            page.wait_for_function("() => document.getElementById('elite-title').textContent !== 'Elite: best'")
            shown = views_of(output.read_text())[cell]["name"]
            assert page.inner_text("#elite-title") == f"Elite: {shown}"
            assert errors == []
        finally:
            browser.close()
