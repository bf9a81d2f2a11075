"""The paper's experiments and figures from the command line, on a tiny configuration: runs per seed side by side,
the Table 3 summary beside the paper's numbers, a finished experiment kept as it is, and every figure drawn; the
rule presets each paper's words give."""

from __future__ import annotations

import json

import numpy as np
import pytest

from structgen.domains.fortress.engine import RULES, Rules, simulate
from structgen.domains.fortress.experiment import PAPER_TABLE
from structgen.domains.fortress.world import random_world
from tests.fortress.test_evolution import TINY
from tests.helpers import cli


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    folder = tmp_path_factory.mktemp("experiment")
    config = folder / "tiny.toml"
    config.write_text(TINY)
    return folder, config


@pytest.mark.slow
def test_an_experiment_runs_its_seeds_and_writes_the_table_beside_the_papers(experiment, capsys):
    folder, config = experiment
    out = folder / "exp1"
    arguments = ["fortress", "experiment", "entities_nodes", out, "--config", config, "--seeds", "1", "2"]
    code, printed, err = cli(capsys, *arguments, "--generations", "4")
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["seed-1", "seed-2", "table.json", "table.md"]
    table = json.loads((out / "table.json").read_text())
    assert table["paper"] == [list(row) for row in PAPER_TABLE["entities_nodes"]] and table["run_seeds"] == [1, 2]
    names = [row["name"] for row in table["rows"]]
    assert names[:3] == ["run seed-1", "run seed-2", "merged (2 runs)"] and len(names) == 9
    lines = (out / "table.md").read_text().splitlines()
    assert len(lines) == 5 and "2,235" in lines[2] and lines[4].startswith("| new seeds, longer episodes | 75 |")
    assert printed == (out / "table.md").read_text()
    # Finished runs are kept: the same command again writes the same table.
    before = (out / "seed-1" / "metrics.jsonl").read_text()
    code, again, err = cli(capsys, *arguments, "--generations", "4")
    assert code == 0, err
    assert again == printed and (out / "seed-1" / "metrics.jsonl").read_text() == before


@pytest.mark.slow
def test_every_figure_is_drawn_from_run_folders(experiment, capsys):
    folder, config = experiment
    run = folder / "run"
    assert cli(capsys, "evolve", config, "--run-dir", run)[0] == 0
    for kind, extra in (("archive", []), ("archive", ["--colour", "entropy"]), ("archive", ["--colour", "nodes"])):
        output = folder / f"{kind}-{len(extra)}.png"
        code, out, err = cli(capsys, "fortress", "figure", kind, run, run, "-o", output, *extra)
        assert code == 0, err
        assert output.read_bytes()[:4] == b"\x89PNG"
    for kind in ("robustness", "populations"):
        output = folder / f"{kind}.png"
        code, out, err = cli(capsys, "fortress", "figure", kind, run, "-o", output, "--longer", "2")
        assert code == 0, err
        assert output.read_bytes()[:4] == b"\x89PNG"
    code, out, err = cli(capsys, "fortress", "figure", "robustness", run, run, "-o", folder / "two.png")
    assert code != 0 and "one RUN_DIR" in err


def test_the_rule_presets_follow_each_papers_words():
    assert RULES["code"] == Rules()
    assert RULES["af-paper"].next_to == "orthogonal" and RULES["af-paper"].inactivity_limit == 20
    assert RULES["af-paper"].population_cap == 15 * 8 and RULES["af-paper"].take_reach is None
    assert RULES["qd-paper"] == Rules(next_to="orthogonal", wall_blocks="any")
    with pytest.raises(ValueError, match="population_cap"):
        Rules(population_cap=157)


def test_a_lower_population_cap_stops_a_growing_world_sooner():
    rng = np.random.default_rng(7)
    worlds = [random_world(rng) for _ in range(20)]
    code = simulate(worlds, [0, 1], 100)
    capped = simulate(worlds, [0, 1], 100, Rules(population_cap=40))
    stopped = capped.cause == 3  # overpopulated: more than the cap alive before a tick
    assert stopped.any() and (capped.entities[stopped] > 40).all() and (capped.ticks <= code.ticks).all()


def test_the_rules_option_reaches_the_simulation(tmp_path, capsys):
    code, out, err = cli(capsys, "fortress", "evaluate", "--random", "4", "--steps", "30", "--rules", "qd-paper", "--json")
    assert code == 0, err
    code, again, err = cli(capsys, "fortress", "evaluate", "--random", "4", "--steps", "30", "--paper-rules", "--json")
    assert code == 0, err
    assert json.loads(out)["ticks"] <= 30 and json.loads(again)["ticks"] <= 30
