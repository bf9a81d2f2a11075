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
    library = tmp_path / "library.npz"  # any file will do: it is never read
    library.write_bytes(b"a library")
    files = {"structure": structure, "weights": weights, "generator": generator, "html": tmp_path / "tower.html"}
    return {**files, "library": library}


SAME_FILE = [
    pytest.param(["report", "{html}", "-o", "{html}"], "html", id="report onto its structure"),
    pytest.param(["warehouse", "grow", "--weights", "{generator}", "-o", "{generator}"], "generator", id="grow onto weights"),
    pytest.param(["regrow", "{structure}", "--weights", "{weights}", "-o", "{weights}"], "weights", id="regrow onto its weights"),
    pytest.param(["regrow", "{structure}", "--weights", "{weights}", "-o", "{structure}"], "structure", id="regrow onto input"),
    pytest.param(["export", "{structure}", "{structure}"], "structure", id="export onto its source"),
    # An input option typed as a path (Path("x") == an output's Path("x")) is still told from the output.
    pytest.param(
        ["design", "--footprint", "3x3", "--height", "3", "--library", "{library}", "-o", "{library}"],
        "library",
        id="design onto its library",
    ),
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


# -- refused before any work ----------------------------------------------------------------------------------------------
EXPERIMENT = ("structures", "experiment", "cutoff")


def _results_cases(tmp_path: Path) -> dict[str, Path]:
    (tmp_path / "list.json").write_text("[1, 2]")
    (tmp_path / "garbage.json").write_text("{not json")
    (tmp_path / "folder.json").mkdir()
    (tmp_path / "file").write_text("a file")
    return {
        "a list": tmp_path / "list",
        "garbage": tmp_path / "garbage",
        "a folder": tmp_path / "folder",
        "under a file": tmp_path / "file" / "table",
        "under /proc": Path("/proc/structgen-table"),
    }


@pytest.mark.parametrize("case", ["a list", "garbage", "a folder", "under a file", "under /proc"])
def test_an_experiment_refuses_its_results_file_before_any_run(tmp_path, capsys, case):
    out = tmp_path / "out"
    refused(capsys, *EXPERIMENT, out, "--seeds", "0", "--spawns", "100", "--results", _results_cases(tmp_path)[case])
    assert not out.exists()  # no seed ran, no folder made


def test_an_experiment_refuses_another_domains_configuration_and_duplicate_seeds_before_any_run(tmp_path, capsys):
    out = tmp_path / "out"
    config = Path(__file__).resolve().parents[2] / "configs" / "fortress_paper.toml"
    refused(capsys, *EXPERIMENT, out, "--seeds", "0", "--config", config, fragments=("fortress-v0 domain, not of structures-v0",))
    paper = config.with_name("paper_cutoff.toml")
    refused(capsys, "fortress", "experiment", "entities_nodes", out, "--seeds", "0", "--config", paper,
            fragments=("structures-v0 domain, not of fortress-v0",))  # fmt: skip
    refused(capsys, *EXPERIMENT, out, "--seeds", "0", "0", "--parallel", "2", fragments=("seed 0 given twice",))
    refused(capsys, "fortress", "experiment", "entities_nodes", out, "--seeds", "1", "1", fragments=("given twice",))
    assert not out.exists()


# -- the file gate for the newer files ------------------------------------------------------------------------------------
def _small_library() -> dict:
    """The shipped library cut to its first two NCAs and their answers: every field as the real one holds it."""
    import numpy as np

    from structgen.domains.structures.design import DEFAULT_LIBRARY

    with np.load(DEFAULT_LIBRARY) as shipped:
        arrays = {name: shipped[name] for name in shipped.files}
    mine = arrays["answers"][:, 0] < 2
    return {**arrays, "families": arrays["families"][:2], "weights": arrays["weights"][:2], "answers": arrays["answers"][mine],
            "peaks": arrays["peaks"][mine], "on_mat": arrays["on_mat"][mine]}  # fmt: skip


def _library_cases(tmp_path: Path) -> dict[str, tuple[Path, str]]:
    import io
    import zipfile

    import numpy as np

    base = _small_library()

    def saved(name: str, **changes) -> Path:
        path = tmp_path / f"{name}.npz"
        np.savez(path, **{k: v for k, v in {**base, **changes}.items() if v is not None})
        return path

    answers = base["answers"]
    nca = answers.copy()
    nca[0, 0] = 7
    seed = answers.copy()
    seed[0, 4] = 2**30
    wide = answers.copy()
    wide[0, 1] = 10_000
    nan = base["weights"].copy()
    nan[0, 0] = np.nan
    whole = tmp_path / "whole.npz"
    np.savez(whole, **base)
    data = whole.read_bytes()
    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    (tmp_path / "renamed.npz").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))
    with zipfile.ZipFile(tmp_path / "claims.npz", "w") as archive:  # a header claiming 19 TB of peaks
        for name, value in base.items():
            header = io.BytesIO()
            shape = (5 * 10**12,) if name == "peaks" else value.shape
            np.lib.format.write_array_header_1_0(header, {**np.lib.format.header_data_from_array_1_0(value), "shape": shape})
            archive.writestr(f"{name}.npy", header.getvalue() + value.tobytes())
    with zipfile.ZipFile(tmp_path / "bomb.npz", "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("weights.npy", "w", force_zip64=True) as member:  # 300 MiB of zeros in well under 1 MiB
            header = io.BytesIO()
            np.lib.format.write_array_header_1_0(header, {"descr": "<f4", "fortran_order": False, "shape": (300 << 18,)})
            member.write(header.getvalue())
            for _ in range(300):
                member.write(bytes(1 << 20))
    os.mkfifo(tmp_path / "fifo.npz")
    return {
        "nca out of range": (saved("nca", answers=nca), "nca 7"),
        "seed outside its box": (saved("seed", answers=seed), "x_seed"),
        "a box too wide": (saved("wide", answers=wide), "width 10000"),
        "answers as text": (saved("text", answers=answers.astype(str)), "answers is <U"),
        "info a list": (saved("info", info=np.array("[1, 2]")), "info is not a JSON object"),
        "info garbage": (saved("garbage", info=np.array("{no")), "not valid JSON"),
        "NaN weights": (saved("nan", weights=nan), "NaN"),
        "no answers": (saved("none", answers=None), "no 'answers'"),
        "empty": (tmp_path / "empty.npz", "not a .npz archive"),
        "cut short": (tmp_path / "cut.npz", "not a .npz archive"),
        "renamed": (tmp_path / "renamed.npz", "not a .npz archive"),
        "a header claiming 19 TB": (tmp_path / "claims.npz", "cut short or damaged"),
        "inflates past its limit": (tmp_path / "bomb.npz", "unpacks to more than"),
        "a FIFO": (tmp_path / "fifo.npz", "not a regular file"),
    }


LIBRARY_CASES = [
    "nca out of range", "seed outside its box", "a box too wide", "answers as text", "info a list", "info garbage",
    "NaN weights", "no answers", "empty", "cut short", "renamed", "a header claiming 19 TB", "inflates past its limit",
    "a FIFO",
]  # fmt: skip


@pytest.fixture(scope="module")
def library_cases(tmp_path_factory) -> dict[str, tuple[Path, str]]:
    """Every damaged library, made once (the refusals read them and change nothing)."""
    return _library_cases(tmp_path_factory.mktemp("libraries"))


def test_the_undamaged_small_library_is_read_back_and_designs(library_cases, tmp_path, capsys):
    """The base every damaged case starts from is a sound library: each case below fails by its own damage."""
    whole = library_cases["empty"][0].with_name("whole.npz")
    width, depth, height = (int(v) for v in _small_library()["answers"][0, 1:4])
    out = tmp_path / "out.json"
    spec = ("--footprint", f"{width}x{depth}", "--height", height)
    code, _, err = cli(capsys, "design", *spec, "--library", whole, "-o", out)
    assert code == 0 and out.is_file(), err


@pytest.mark.parametrize("case", LIBRARY_CASES)
def test_a_damaged_design_library_is_refused_in_one_line(library_cases, tmp_path, capsys, case):
    path, fragment = library_cases[case]
    out = tmp_path / "out.json"
    spec = ("--footprint", "3x3", "--height", "3")
    refused(capsys, "design", *spec, "--library", path, "-o", out, fragments=(str(path), fragment))
    assert not out.exists()


@pytest.mark.parametrize(
    "growth, fragment",
    [
        ({"hidden": "eight"}, "hidden"), ({"hidden": 0}, "hidden = 0"), ({"iterations": -1}, "iterations = -1"),
        ({"max_extent": 10**9}, "max_extent"), ({"build_down": [1]}, "build_down"), ([1, 2], "metadata.growth is list"),
    ],
    ids=["hidden a string", "hidden 0", "iterations -1", "max_extent 1e9", "build_down a list", "growth a list"],
)  # fmt: skip
def test_regrow_checks_the_growth_metadata_of_its_file(tmp_path, capsys, growth, fragment):
    import numpy as np

    structure = _files(tmp_path)["structure"]
    data = json.loads(structure.read_text())
    data["metadata"]["growth"] = {**data["metadata"]["growth"], **growth} if isinstance(growth, dict) else growth
    structure.write_text(json.dumps(data))
    np.save(tmp_path / "w.npy", np.zeros(4766))
    capsys.readouterr()
    refused(capsys, "regrow", structure, "--weights", tmp_path / "w.npy", fragments=(str(structure), fragment))


def test_weights_past_what_32_bit_floats_hold_and_a_transient_shorter_than_a_step_are_refused(tmp_path, capsys):
    import numpy as np

    np.save(tmp_path / "huge.npy", np.full(4766, 1e308))
    refused(capsys, "grow", "--weights", tmp_path / "huge.npy", "-o", tmp_path / "o.json", fragments=("32-bit",))
    structure = _files(tmp_path)["structure"]
    capsys.readouterr()
    refused(capsys, "show", structure, "--transient", "1e-300", "-o", tmp_path / "o.png", fragments=("one physics step",))
    assert not (tmp_path / "o.json").exists() and not (tmp_path / "o.png").exists()


def _edit_archive(run: Path, column: str, value: str) -> None:
    path = run / "archive.csv"
    rows = list(csv.reader(path.read_text().splitlines()))
    rows[1][rows[0].index(column)] = value
    with open(path, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)


@pytest.mark.parametrize(
    "column, value, fragment",
    [("index", "1" * 30, "index"), ("cell_height", "-1", "cell_height = '-1'"), ("cell_height", "24000", "outside")],
    ids=["a 30-digit index", "a negative cell", "a cell past the archive"],
)
def test_a_report_refuses_an_archive_whose_cells_are_out_of_range(qd_run, tmp_path, capsys, column, value, fragment):
    run = _copy_run(qd_run, tmp_path / "run")
    _edit_archive(run, column, value)
    refused(capsys, "report", run, "-o", tmp_path / "r.html", fragments=("archive.csv", fragment))
    assert not (tmp_path / "r.html").exists()


def test_a_report_draws_a_structure_too_large_for_the_static_solve_with_its_loads_unknown(tmp_path, capsys):
    structure = tmp_path / "long.json"  # 40,000 vertices in a row: coordinates past what 16 bits hold
    structure.write_text(
        json.dumps({"vertices": [[i, 0, 0] for i in range(40_000)], "edges": [[i, i + 1] for i in range(39_999)]})
    )
    code, _, err = cli(capsys, "report", structure, "-o", tmp_path / "long.html")
    assert code == 0, err
    from tests.structgen.test_report import views_of

    (view,) = views_of((tmp_path / "long.html").read_text())
    assert view["verdict"].startswith("static analysis not run") and view["lines3d"]["points"]["dtype"] == "i4"


@pytest.fixture(scope="module")
def experiment(tmp_path_factory) -> Path:
    """A one-generation cutoff experiment (100 spawns), with a kept spawn folder for its figure."""
    from structgen.cli import main

    out = tmp_path_factory.mktemp("experiment") / "out"
    assert main([*EXPERIMENT, str(out), "--seeds", "0", "--spawns", "100", "--workers", "0", "--json"]) == 0
    shutil.copytree(out / "seed-0" / "best", out / "seed-0-spawns" / "spawn-100")
    return out


def _png_claiming(width: int, height: int) -> bytes:
    import struct
    import zlib

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I", 13) + b"IHDR" + header + struct.pack(">I", zlib.crc32(b"IHDR" + header))


def _damage(out: Path, case: str) -> None:
    kept = out / "seed-0-spawns" / "spawn-100"
    if case == "best.json garbage":
        (kept / "best.json").write_text("{garbage")
    elif case == "best.json a list":
        (kept / "best.json").write_text("[1, 2]")
    elif case == "objective a string":
        best = json.loads((kept / "best.json").read_text())
        (kept / "best.json").write_text(json.dumps({**best, "objective": "high"}))
    elif case == "structure.png not a PNG":
        (kept / "structure.png").write_text("not a picture")
    elif case == "a picture of 20,000 x 20,000":
        (kept / "structure.png").write_bytes(_png_claiming(20_000, 20_000))
    elif case == "a folder seed-x":
        shutil.copytree(out / "seed-0-spawns", out / "seed-x-spawns")
    elif case == "a folder spawn-abc":
        shutil.copytree(kept, kept.with_name("spawn-abc"))


FIGURE_CASES = {
    "best.json garbage": "not valid JSON", "best.json a list": "not a best candidate's summary",
    "objective a string": "objective = 'high'", "structure.png not a PNG": "not a PNG picture",
    "a picture of 20,000 x 20,000": "20,000 x 20,000 pixels", "a folder seed-x": "seed-x-spawns",
    "a folder spawn-abc": "spawn-abc",
}  # fmt: skip


@pytest.mark.parametrize("case", list(FIGURE_CASES))
def test_a_figure_of_a_damaged_experiment_is_refused_naming_the_file(experiment, tmp_path, capsys, case):
    out = tmp_path / "out"
    shutil.copytree(experiment, out)
    _damage(out, case)
    refused(capsys, "structures", "figure", out, "-o", tmp_path / "f.png", fragments=(FIGURE_CASES[case],))
    assert not (tmp_path / "f.png").exists()


@pytest.mark.parametrize("case", ["best.json garbage", "best.json a list", "objective a string", "wall_s a string"])
def test_a_table_of_a_damaged_run_is_refused_naming_the_file(experiment, tmp_path, capsys, case):
    out = tmp_path / "out"
    shutil.copytree(experiment, out)
    best = out / "seed-0" / "best" / "best.json"
    if case == "wall_s a string":
        metrics = out / "seed-0" / "metrics.jsonl"
        rows = [json.loads(line) for line in metrics.read_text().splitlines()]
        rows[-1]["wall_s"] = "long"
        metrics.write_text("".join(json.dumps(row) + "\n" for row in rows))
        fragment = "wall_s = 'long'"
    else:
        shutil.copy(out / "seed-0-spawns" / "spawn-100" / "best.json", best)
        _damage(out, case)
        shutil.copy(out / "seed-0-spawns" / "spawn-100" / "best.json", best)
        fragment = FIGURE_CASES[case]
    table = (out / "table.md").read_bytes()
    refused(capsys, *EXPERIMENT, out, "--seeds", "0", "--spawns", "100", "--table-only", fragments=(fragment,))
    assert (out / "table.md").read_bytes() == table


def test_the_figure_of_the_undamaged_experiment_is_drawn(experiment, tmp_path, capsys):
    code, _, err = cli(capsys, "structures", "figure", experiment, "-o", tmp_path / "f.png")
    assert code == 0 and (tmp_path / "f.png").read_bytes().startswith(b"\x89PNG"), err


@pytest.fixture(scope="module")
def fortress_run(tmp_path_factory) -> Path:
    from structgen.cli import main
    from tests.fortress.test_evolution import TINY as FORTRESS_TINY

    folder = tmp_path_factory.mktemp("fortress")
    (folder / "fortress.toml").write_text(FORTRESS_TINY)
    assert main(["evolve", str(folder / "fortress.toml"), "--run-dir", str(folder / "run")]) == 0
    return folder / "run"


@pytest.mark.parametrize("damage", ["an array missing", "counts that disagree", "a FIFO", "not a zip"])
def test_a_damaged_file_of_a_fortress_runs_world_store_is_refused_naming_it(fortress_run, tmp_path, capsys, damage):
    import numpy as np

    run = _copy_run(fortress_run, tmp_path / "run")
    segment = sorted((run / "genomes").glob("segment-*.npz"))[0]
    with np.load(segment) as data:
        arrays = {name: data[name] for name in data.files}
    segment.unlink()
    if damage == "an array missing":
        np.savez(segment, **{k: v for k, v in arrays.items() if k != "class_nodes"})
    elif damage == "counts that disagree":
        np.savez(segment, **{**arrays, "class_nodes": arrays["class_nodes"] + 1})
    elif damage == "a FIFO":
        os.mkfifo(segment)
    else:
        segment.write_bytes(b"garbage")
    index = (run / "archive.csv").read_text().splitlines()[1].split(",")[0]
    refused(capsys, "export", run, "--elite", f"index:{index}", "-o", tmp_path / "e.txt", fragments=(segment.name,))
    assert not (tmp_path / "e.txt").exists()


@pytest.fixture(scope="module")
def tall_run(tmp_path_factory) -> Path:
    from structgen.cli import main

    run = tmp_path_factory.mktemp("tall") / "run"
    options = ["--levels", "3", "--beam", "3", "--candidates", "2", "--max-vertices", "100", "--workers", "0"]
    assert main(["tall", "--run-dir", str(run), *options]) == 0
    return run


@pytest.mark.parametrize("case", ["settings a list", "settings a string", "rules no search writes", "a design of 300 levels"])
def test_info_refuses_a_damaged_tall_search_of_structgen_0_2(tall_run, tmp_path, capsys, case):
    state = json.loads((tall_run / "checkpoint.json").read_text())
    settings: object = {"levels": 3, "beam": 3, "candidates": 2, "max_vertices": 100, "refine": True}
    if case == "settings a list":
        settings, fragment = [1, 2], "expected an object of settings, got list"
    elif case == "settings a string":
        settings, fragment = "levels", "expected an object of settings, got str"
    elif case == "rules no search writes":
        first = next(iter(state["designs"]))
        state["designs"][first]["rules"] = ["XYZ"] * len(state["designs"][first]["rules"])
        fragment = "is not a design's rules"
    else:
        state["designs"]["300"] = {"rules": ["VSC"] * 299, "tied": 0, "static_load": 1.0, "peak": 1.0}
        fragment = "height is 300"
    old = tmp_path / "old"
    old.mkdir()
    (old / "settings.json").write_text(json.dumps(settings))
    (old / "search.json").write_text(json.dumps({**state, "complete": False}))
    refused(capsys, "info", old, fragments=(fragment,))
