"""Run folders written by structgen 0.1.0, before the domain registry, still resume, to exactly the results that
version gave when it ran straight through (tests/fixtures/runs_0.1.0/README.md says how they were made)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from evolution import RunFolder
from structgen.cli import main
from structgen.runs import open_run
from tests.helpers import findings

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "runs_0.1.0"
RUNS = ["structures_ga", "structures_cma_mae", "ones_map_elites"]


@pytest.fixture
def old_run(tmp_path, request) -> Path:
    run = tmp_path / request.param
    shutil.copytree(FIXTURES / request.param, run)
    return run


@pytest.mark.parametrize("old_run", RUNS, indirect=True)
def test_an_old_run_resumes_to_what_it_would_have_become(old_run, capsys):
    assert main(["resume", str(old_run), "--generations", "4"]) == 0, capsys.readouterr().err
    expected, found = findings(FIXTURES / f"{old_run.name}.expected_metrics.jsonl"), findings(old_run / "metrics.jsonl")
    # Columns added since (fields, generation means) come on top; every column that version wrote is the same.
    assert [{k: row[k] for k in want} for row, want in zip(found, expected)] == expected and len(found) == len(expected)
    assert 'name = "' in (old_run / "config.toml").read_text()


@pytest.mark.parametrize("old_run", ["structures_cma_mae"], indirect=True)
def test_an_old_runs_elites_export_without_resuming(old_run, tmp_path, capsys):
    index = (old_run / "archive.csv").read_text().splitlines()[1].split(",")[0]
    assert main(["export", str(old_run), str(tmp_path / "elite.json"), "--elite", f"index:{index}"]) == 0
    assert json.loads((tmp_path / "elite.json").read_text())["metadata"]["elite"] == f"index:{index}"
    assert main(["export", str(old_run), str(tmp_path / "best.glb")]) == 0


@pytest.mark.parametrize("old_run", ["ones_map_elites"], indirect=True)
def test_an_old_archive_of_object_genomes_reads_from_its_csv_column(old_run):
    folder, experiment = open_run(old_run)
    assert experiment.domain == "ones-v0"
    problem = experiment.make_problem()
    rows = (old_run / "archive.csv").read_text().splitlines()
    assert rows[0].endswith(",genome")
    index = int(rows[1].split(",")[0])
    genome = folder.archive_genome(index, problem)
    assert isinstance(genome, tuple) and len(genome) == 16
    ones = float(rows[1].split(",")[rows[0].split(",").index("ones")])
    assert np.sum(genome) == ones == problem.evaluate([genome], np.zeros(1)).objective[0]
    assert isinstance(RunFolder(old_run).best_genome(problem), tuple)
