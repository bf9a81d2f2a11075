"""A domain from another package, installed with pip, works through every generic command and passes the domain
contract without a line of structgen changed (examples/dice-domain)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.helpers import findings

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "dice-domain"

# One worker for the whole file under pytest -n (make test uses --dist loadgroup): the example installs once, and two
# workers building it at the same time in one source folder broke each other's build.
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("plugin")]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The example installed as pip installs any package, into a folder of its own (the test's environment stays
    as it was)."""
    target = tmp_path_factory.mktemp("site")
    # A copy, so that the build's leftovers (build/, egg-info) land in a scratch folder and not in the repository.
    source = shutil.copytree(EXAMPLE, tmp_path_factory.mktemp("source") / EXAMPLE.name)
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--target",
            str(target),
            str(source),
        ],
        check=True,
        capture_output=True,
    )
    assert (target / "dice_domain.py").exists()
    return target


def structgen(site: Path, *argv: object, cwd: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(site)}
    return subprocess.run(
        [sys.executable, "-m", "structgen", *map(str, argv)], cwd=cwd, env=env, capture_output=True, text=True, check=False
    )


def test_the_installed_domain_is_listed(site, tmp_path):
    done = structgen(site, "list", "domains", "--json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "dice-v0" in [row["id"] for row in json.loads(done.stdout)]


def test_it_evolves_resumes_and_exports_through_the_generic_commands(site, tmp_path):
    done = structgen(site, "evolve", "--domain", "dice-v0", "--run-dir", "run", "--generations", 2, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert 'name = "dice-v0"' in (tmp_path / "run" / "config.toml").read_text()
    assert structgen(site, "resume", "run", "--generations", 4, cwd=tmp_path).returncode == 0
    straight = structgen(site, "evolve", "--domain", "dice-v0", "--run-dir", "straight", "--generations", 4, cwd=tmp_path)
    assert straight.returncode == 0

    def metrics(run: str) -> list[dict]:
        return findings(tmp_path / run / "metrics.jsonl")

    assert len(metrics("run")) == 4 and metrics("run") == metrics("straight")
    done = structgen(site, "export", "run", "die.json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    faces = json.loads((tmp_path / "die.json").read_text())["faces"]
    assert faces == json.loads((tmp_path / "run" / "best" / "genome.json").read_text())


def test_a_run_of_its_dataclass_genomes_killed_midway_resumes_to_the_run_that_never_stopped(site, tmp_path):
    # Its genomes are Die dataclasses: the checkpoint holds them, and only the problem's genome_types let it load.
    env = {**os.environ, "PYTHONPATH": str(site)}
    argv = [sys.executable, "-m", "structgen", "evolve", "--domain", "dice-v0", "--run-dir", "killed", "--generations", "100000"]
    process = subprocess.Popen(argv, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    metrics = tmp_path / "killed" / "metrics.jsonl"
    deadline = time.monotonic() + 120
    while not (metrics.exists() and len(metrics.read_text().splitlines()) >= 5) and time.monotonic() < deadline:
        time.sleep(0.02)
    process.send_signal(signal.SIGKILL)
    process.wait()
    reached = len(metrics.read_text().splitlines())
    assert 5 <= reached < 100000
    total = str(reached + 10)
    assert structgen(site, "resume", "killed", "--generations", total, cwd=tmp_path).returncode == 0
    straight = structgen(site, "evolve", "--domain", "dice-v0", "--run-dir", "straight", "--generations", total, cwd=tmp_path)
    assert straight.returncode == 0

    def outcome(run: str) -> tuple[list, str]:
        return findings(tmp_path / run / "metrics.jsonl"), (tmp_path / run / "best" / "genome.json").read_text()

    assert len(outcome("killed")[0]) == int(total) and outcome("killed") == outcome("straight")


def test_its_own_verbs_and_quality_diversity_work(site, tmp_path):
    done = structgen(site, "dice", "roll", "--faces", "2,4", "--times", 5, cwd=tmp_path)
    assert done.returncode == 0 and set(done.stdout.split()) <= {"2", "4"} and len(done.stdout.split()) == 5
    # A plugin's declared verb gets what the built-in ones have: its docstring as help, examples, checked ranges.
    helped = structgen(site, "dice", "roll", "--help", cwd=tmp_path).stdout
    assert "Roll a die with the given faces" in helped and "how many rolls (default 10)" in helped
    assert "examples:\n  structgen dice roll --faces 1,1,2,3,5,8 --times 5" in helped
    refused = structgen(site, "dice", "roll", "--times", 0, cwd=tmp_path)
    assert refused.returncode == 2 and "--times: expected a whole number from 1 to 1,000,000, got 0" in refused.stderr
    done = structgen(
        site,
        "dice",
        "evolve",
        "--optimizer",
        "map_elites",
        "--set",
        "cells=[6,6]",
        "--run-dir",
        "qd",
        "--generations",
        2,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    index = (tmp_path / "qd" / "archive.csv").read_text().splitlines()[1].split(",")[0]
    done = structgen(site, "dice", "export", "qd", "elite.json", "--elite", f"index:{index}", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    done = structgen(site, "export", "qd", "elite.txt", cwd=tmp_path)
    assert done.returncode == 2 and "a die is written as .json" in done.stderr


def test_it_passes_the_domain_contract(site):
    env = {**os.environ, "PYTHONPATH": str(site)}
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/test_domain_contract.py", "-k", "dice-v0"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout[-3000:]
    assert "1 passed" in done.stdout  # the contract's one test per domain, which runs every check, ran for the plugin


def test_a_broken_plugin_is_reported_and_left_out(tmp_path):
    site = tmp_path / "site"
    info = site / "broken_domain-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-domain\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[structgen.domains]\nbroken = no_such_module:DOMAIN\n")
    done = structgen(site, "list", "domains", cwd=tmp_path)
    assert done.returncode == 0 and "structures-v0" in done.stdout
    assert "domain plugin broken = no_such_module:DOMAIN not loaded: ModuleNotFoundError" in done.stderr
