"""Helpers several test files use: the command line in this process, tiny structures runs' configurations, run
folders compared, and a run killed midway in a process of its own."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

from evolution.run import comparable_metrics as comparable
from structgen.cli import main


def cli(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def findings(metrics_file: Path) -> list[dict]:
    """A metrics file's rows, :func:`comparable`."""
    return comparable(json.loads(line) for line in metrics_file.read_text().splitlines())


def outcome(run: Path) -> dict:
    """What must be identical between two runs of the same configuration (everything but timings)."""
    metrics = findings(run / "metrics.jsonl")
    files = {
        name: (run / name).read_bytes()
        for name in ("best/genome.npy", "best/best.json", "best/structure.json", "archive.csv", "archive_solutions.npy")
        if (run / name).exists()
    }
    return {"metrics": metrics, "files": files}


def structgen_command() -> list[str]:
    script = Path(sys.executable).with_name("structgen")
    return [str(script)] if script.exists() else [sys.executable, "-m", "structgen"]


def wait_for_lines(path: Path, count: int, process: subprocess.Popen, limit: float = 120.0) -> None:
    deadline = time.monotonic() + limit
    while time.monotonic() < deadline:
        if path.exists() and len(path.read_text().splitlines()) >= count:
            return
        assert process.poll() is None, process.communicate()
        time.sleep(0.05)
    raise AssertionError(f"{path} never reached {count} lines")


def kill_during_evolve(config: Path, run: Path, generations: int, *options: str, limit: float = 120.0) -> None:
    """Start ``structgen evolve CONFIG --run-dir RUN``, let it finish ``generations`` generations, then SIGKILL it:
    no chance to clean up, whatever it was writing is cut short."""
    process = subprocess.Popen(
        [*structgen_command(), "evolve", str(config), "--run-dir", str(run), *options],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    wait_for_lines(run / "metrics.jsonl", generations, process, limit=limit)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert process.returncode == -signal.SIGKILL


# A structures run of four generations with a 16-vertex cap: seconds, for any optimiser.
TINY = """\
[run]
generations = 4
seed = 3
workers = 0

[problem]
name = "structures"

[problem.nca]
max_vertices = 16

[optimizer]
name = "{optimizer}"
{optimizer_settings}
"""
OPTIMIZER_SETTINGS = {
    "ga": "population = 6\nparents = 2",
    "cma_es": "population = 6",
    "map_elites": "batch_size = 6\ncells = [6, 8]",
    "cma_mae": "emitters = 2\nbatch_size = 3\ncells = [6, 8]",
}


def tiny_config(tmp_path: Path, optimizer: str = "ga") -> Path:
    path = tmp_path / f"{optimizer}.toml"
    path.write_text(TINY.format(optimizer=optimizer, optimizer_settings=OPTIMIZER_SETTINGS[optimizer]))
    return path
