"""Every command builds its problem once and its optimiser at most once (a resumed run's comes from its checkpoint):
a domain's problem may start simulators or load models, and building it twice costs start-up time for nothing."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import pytest

import structgen.runs.experiment
from structgen.cli import main

CONFIG = """\
[run]
generations = 2
workers = 0
[problem.nca]
hidden = 8
max_vertices = 16
[optimizer]
name = "map_elites"
batch_size = 4
cells = [4, 4]
"""


@pytest.fixture
def builds(monkeypatch) -> Counter:
    counts: Counter = Counter()
    make_problem = structgen.runs.experiment.Experiment.make_problem
    make_optimizer = structgen.runs.experiment.make_optimizer

    def counted_problem(self):
        counts["problem"] += 1
        return make_problem(self)

    def counted_optimizer(*args, **kwargs):
        counts["optimizer"] += 1
        return make_optimizer(*args, **kwargs)

    monkeypatch.setattr(structgen.runs.experiment.Experiment, "make_problem", counted_problem)
    monkeypatch.setattr(structgen.runs.experiment, "make_optimizer", counted_optimizer)
    return counts


def run(builds: Counter, *argv: object) -> dict[str, int]:
    builds.clear()
    assert main([str(a) for a in argv]) == 0
    return dict(builds)


def test_each_command_builds_once(tmp_path: Path, builds: Counter):
    config = tmp_path / "c.toml"
    config.write_text(CONFIG)
    run_dir = tmp_path / "run"
    assert run(builds, "evolve", config, "--run-dir", run_dir) == {"problem": 1, "optimizer": 1}
    assert run(builds, "resume", run_dir, "--generations", 3) == {"problem": 1}
    assert run(builds, "export", run_dir, tmp_path / "best.json") == {"problem": 1}
    index = (run_dir / "archive.csv").read_text().splitlines()[1].split(",")[0]
    assert run(builds, "export", run_dir, tmp_path / "elite.json", "--elite", f"index:{index}") == {"problem": 1}
    assert run(builds, "grow", "--run", run_dir, "-o", tmp_path / "grown.json") == {"problem": 1}
    assert run(builds, "evolve", config, "--print-config") == {}
