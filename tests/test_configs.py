"""The example configurations in configs/ stay valid."""

from __future__ import annotations

from pathlib import Path

import pytest

from structgen.experiment import load_experiment

CONFIGS = sorted((Path(__file__).resolve().parents[1] / "configs").glob("*.toml"))


def test_there_are_examples():
    assert len(CONFIGS) >= 3


@pytest.mark.parametrize("path", CONFIGS, ids=[p.name for p in CONFIGS])
def test_example_configuration_loads(path):
    experiment = load_experiment(path)
    assert experiment.run.generations >= 1
