"""The results index (docs/results/README.md) and the check that re-derives its numbers (benchmarks/results_check.py)."""

from __future__ import annotations

import importlib.util
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
INDEX = ROOT / "docs" / "results" / "README.md"


def _results_check():
    spec = importlib.util.spec_from_file_location("results_check", ROOT / "benchmarks" / "results_check.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_every_check_stands_for_a_claim_of_the_index_and_the_index_names_it():
    checks = _results_check().CHECKS
    anchors = set(re.findall(r'<a id="([a-z0-9-]+)"></a>', INDEX.read_text()))
    text = INDEX.read_text()
    for check in checks:
        # A check belongs to a claim: its anchor, or the claim's entry naming it as its check.
        assert check.id in anchors or f"`{check.id}`" in text, f"{check.id} is not in docs/results/README.md"
    named = set(re.findall(r"\*\*Check\*\* `([a-z0-9-]+)`", text))
    assert named <= {c.id for c in checks}, f"the index names checks that do not exist: {named - {c.id for c in checks}}"
    assert all(c.tolerance >= 0 and c.scale for c in checks)


def test_a_number_moved_beyond_its_tolerance_fails_its_check():
    module = _results_check()
    check = module.Check("x", "a stated scale", lambda work: 0.0, expected=6.673, tolerance=0.05)
    assert module.verdict(check, 6.70) and module.verdict(check, 6.623)
    assert not module.verdict(check, 6.60) and not module.verdict(check, 6.75)
    assert not module.verdict(check, math.nan)  # a claim that no longer comes out at all has moved too
    exact = module.Check("y", "a stated scale", lambda work: 0.0, expected=100.0, tolerance=0.0)
    assert module.verdict(exact, 100.0) and not module.verdict(exact, 180.0)


def test_no_committed_file_names_a_machine_path():
    try:
        listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("not a git checkout: the committed files cannot be listed")
    machine = re.compile(rb"""(^|["'`( ])/(work|home|root|Users|mnt)/""", re.MULTILINE)
    found = []
    for name in listed.decode().split("\0"):
        path = ROOT / name
        if not name or not path.is_file() or path.stat().st_size > 4_000_000:
            continue
        data = path.read_bytes()
        if b"\0" in data[:4096]:
            continue  # a binary file (weights, pictures)
        found += [f"{name}: {m.group(0).decode(errors='replace').strip()}" for m in machine.finditer(data)]
    assert not found, "committed files name machine paths:\n" + "\n".join(found[:20])


def test_fortress_tables_say_whether_map_elites_beats_random_search_run_for_run():
    from structgen.domains.fortress.experiment import baseline_markdown

    def report(scores: list[float], best: float) -> dict:
        rows = [{"name": f"run seed-{k}", "qd_score": s, "best": best} for k, s in enumerate(scores)]
        rows += [{"name": "merged (3 runs)", "qd_score": sum(scores), "best": best}]
        return {"measures": "entities_nodes", "rows": rows}

    text = baseline_markdown(report([1700.0, 1750.0, 1800.0], 0.94), report([900.0, 1000.0, 1100.0], 0.60))
    assert "#### entities_nodes: does MAP-Elites learn? Against random search at the same evaluations" in text
    assert "- as evolved, QD score of one run: MAP-Elites 1,750.00 ± 28.87 against random search 1,000.00 ± 57.74" in text
    assert "MAP-Elites learns by the three-standard-error rule" in text
    level = baseline_markdown(report([1000.0, 1100.0, 900.0], 0.6), report([950.0, 1050.0, 1000.0], 0.6))
    assert "learns" not in level.replace("not shown to learn", "")


def test_the_learning_verdicts_come_from_the_committed_tables():
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "learning_verdicts.py")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "#### cutoff: does the GA learn? Against random search at the same spawns and judge" in done.stdout


def test_random_baseline_compares_a_configuration_with_random_search_and_writes_a_table_the_verdicts_read(tmp_path):
    results = tmp_path / "results"
    results.mkdir()
    command = [sys.executable, str(ROOT / "benchmarks" / "random_baseline.py"), str(ROOT / "configs" / "ones_map_elites.toml"),
               "--generations", "3", "--seeds", "0", "1", "--metric", "qd_score", "best_objective",
               "--out", str(tmp_path / "runs"), "--results", str(results / "ones")]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    table = json.loads((results / "ones.json").read_text())
    assert table["kind"] == "optimiser-against-random-search" and table["seeds"] == [0, 1]
    methods = table["metrics"]["qd_score"]["methods"]
    assert list(methods) == ["ones_map_elites.toml's optimiser", "random search"]
    assert all(m["evaluations"] == [60] and len(m["values"]) == 2 for m in methods.values())
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == ["random-s0", "random-s1", "trained-s0", "trained-s1"]
    assert "| random search | 60 |" in (results / "ones.md").read_text()
    verdicts = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "learning_verdicts.py"), "--results", str(results)],
                              capture_output=True, text=True)  # fmt: skip
    assert verdicts.returncode == 0, verdicts.stderr
    assert "- qd_score: ones_map_elites.toml's optimiser" in verdicts.stdout


def test_table2_seeds_judges_each_runs_best_generator_and_keeps_them(tmp_path):
    shipped = np.load(ROOT / "docs" / "layout_runs" / "even_generator.npy")
    for k, name in enumerate(["trained-s0", "trained-s1", "random-s0", "random-s1"]):
        (tmp_path / "runs" / name / "best").mkdir(parents=True)
        np.save(tmp_path / "runs" / name / "best" / "genome.npy", shipped if name.startswith("trained") else shipped * 0.1 * k)
    options = ["--simulations", "1", "--steps", "30", "--workers", "1", "--results", tmp_path / "t2", "--keep", tmp_path / "kept"]
    command = [sys.executable, ROOT / "benchmarks" / "table2_seeds.py", tmp_path / "runs", *options]
    done = subprocess.run(command, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    table = json.loads((tmp_path / "t2.json").read_text())["sizes"]["33x36"]
    trained, random = table["methods"].values()
    assert trained["values"][0] == trained["values"][1] > 0  # the same generator judged alike in both seeds
    assert len(random["values"]) == 2 and isinstance(table["learns"], bool)
    assert np.array_equal(np.load(tmp_path / "kept" / "trained-s1.npy"), shipped)
    assert "| trained (the archive's best) |" in (tmp_path / "t2.md").read_text()
    # The kept generators alone, without the runs, give the same table: what makes a committed row re-derivable.
    again = [sys.executable, ROOT / "benchmarks" / "table2_seeds.py", tmp_path / "kept", *options[:6],
             "--results", tmp_path / "k2"]  # fmt: skip
    done = subprocess.run(again, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    tables = [json.loads((tmp_path / f"{stem}.json").read_text())["sizes"]["33x36"] for stem in ("t2", "k2")]
    values = [{name: method["values"] for name, method in table["methods"].items()} for table in tables]
    assert values[0] == values[1]


def test_a_result_table_is_written_in_both_forms_beside_a_stem_with_a_dot_in_its_name(tmp_path):
    from evolution.files import write_table

    paths = write_table(tmp_path / "tables" / "v1.2", {"learns": True}, "| a |\n")
    assert [p.name for p in paths] == ["v1.2.json", "v1.2.md"]
    assert json.loads(paths[0].read_text()) == {"learns": True} and paths[1].read_text() == "| a |\n"
    assert sorted(p.name for p in (tmp_path / "tables").iterdir()) == ["v1.2.json", "v1.2.md"]  # no temporary left


def test_autoverse_reseed_searches_each_kept_game_under_new_child_orders(tmp_path):
    script = ROOT / "benchmarks" / "autoverse_reseed.py"
    games = ROOT / "docs" / "results" / "autoverse-games"
    command = [sys.executable, script, games, "--budget", "30", "--search-seeds", "1", "2"]
    for stem in ("a", "b"):
        done = subprocess.run([*command, "--results", tmp_path / stem], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    first, again = (json.loads((tmp_path / f"{stem}.json").read_text()) for stem in ("a", "b"))
    assert first["sides"] == again["sides"]  # the same child orders give the same fitness
    ga = first["sides"]["the GA"]
    assert first["run_seeds"] == [0, 1, 2] and all(len(f) == 2 and max(f) <= 30 for f in ga["fitness"].values())
    assert ga["scores"] == [sum(f) / 2 for f in ga["fitness"].values()]
    (tmp_path / "empty").mkdir()
    refused = subprocess.run([sys.executable, script, tmp_path / "empty"], capture_output=True, text=True)
    assert refused.returncode == 2 and "no trained-sS.json" in refused.stderr
