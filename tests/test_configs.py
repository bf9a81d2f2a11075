"""The example configurations in configs/ stay valid: they load, their problem and optimiser work together, and what
a run would record reads back to the same configuration."""

from __future__ import annotations

from pathlib import Path

import pytest

from structgen.runs.experiment import load_experiment

CONFIGS = sorted((Path(__file__).resolve().parents[1] / "configs").glob("*.toml"))


def test_there_are_examples():
    assert len(CONFIGS) >= 3


@pytest.mark.parametrize("path", CONFIGS, ids=[p.name for p in CONFIGS])
def test_example_configuration_builds_and_round_trips(path, tmp_path):
    experiment = load_experiment(path)
    problem = experiment.make_problem()
    try:
        optimizer = experiment.make_optimizer(problem)
        assert len(optimizer.ask()) >= 1
    finally:
        problem.close()
    resolved = tmp_path / "config.toml"
    resolved.write_text(experiment.to_toml())
    assert load_experiment(resolved) == experiment
