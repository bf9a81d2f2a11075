"""Faults on a real Dask cluster, started as the docs say (``dask scheduler`` and ``dask worker`` processes of their
own): a worker killed during a run changes nothing in its results, and a scheduler that goes away stops the run with
one clear error, after which ``structgen resume`` on a new cluster finishes it exactly as an undisturbed run."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import time
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.helpers import OPTIMIZER_SETTINGS, TINY, outcome, structgen_command, wait_for_lines

pytest.importorskip("distributed")
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("cluster")]

GENERATIONS = 16


def _dask(*words: str, log: Path) -> subprocess.Popen:
    dask = Path(sys.executable).with_name("dask")
    command = [str(dask)] if dask.exists() else [sys.executable, "-m", "dask"]
    return subprocess.Popen([*command, *words], stdout=subprocess.DEVNULL, stderr=open(log, "w"))


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@contextmanager
def cluster(folder: Path, workers: int = 2):
    """A scheduler and ``workers`` one-thread workers, each its own process; yields (address, processes)."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    processes = [_dask("scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard", log=folder / "scheduler.log")]
    from distributed import Client

    try:
        for number in range(workers):
            processes.append(
                _dask("worker", address, "--nthreads", "1", "--no-dashboard", "--no-nanny", log=folder / f"worker-{number}.log")
            )
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(workers, timeout=60)
        yield address, processes
    finally:
        for process in processes:
            process.kill()
            process.wait()


def _config(folder: Path) -> Path:
    path = folder / "ga.toml"
    text = TINY.format(optimizer="ga", optimizer_settings=OPTIMIZER_SETTINGS["ga"])
    path.write_text(text.replace("generations = 4", f"generations = {GENERATIONS}"))
    return path


@pytest.fixture(scope="module")
def undisturbed(tmp_path_factory) -> Path:
    from structgen.cli import main

    folder = tmp_path_factory.mktemp("undisturbed")
    assert main(["evolve", str(_config(folder)), "--run-dir", str(folder / "run")]) == 0
    return folder / "run"


def _evolve(config: Path, run: Path, address: str) -> subprocess.Popen:
    command = [*structgen_command(), "evolve", str(config), "--run-dir", str(run), "--cluster", address]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_a_worker_killed_during_a_run_changes_nothing(undisturbed, tmp_path):
    config, run = _config(tmp_path), tmp_path / "run"
    with cluster(tmp_path) as (address, processes):
        process = _evolve(config, run, address)
        wait_for_lines(run / "metrics.jsonl", 2, process)
        processes[1].send_signal(signal.SIGKILL)  # a worker, its tasks in hand: Dask gives them to the other
        _, err = process.communicate(timeout=240)
        assert process.returncode == 0, err
        assert processes[1].poll() is not None and len((run / "metrics.jsonl").read_text().splitlines()) == GENERATIONS
    assert outcome(run) == outcome(undisturbed)


def test_a_scheduler_that_goes_away_stops_the_run_and_resume_finishes_it(undisturbed, tmp_path):
    config, run = _config(tmp_path), tmp_path / "run"
    with cluster(tmp_path) as (address, processes):
        process = _evolve(config, run, address)
        wait_for_lines(run / "metrics.jsonl", 2, process)
        processes[0].send_signal(signal.SIGKILL)
        started = time.monotonic()
        _, err = process.communicate(timeout=240)
    assert process.returncode == 1 and time.monotonic() - started < 120
    last = err.strip().splitlines()[-1]
    assert last.startswith("structgen: error: EvaluationError: lost the Dask scheduler at") and "resume RUN_DIR --cluster" in last
    # Our error is one line, not a traceback; distributed's own logger may still report its background sender
    # failing as the scheduler dies (timing-dependent), which names only distributed's and tornado's frames.
    ours = [line for line in err.splitlines() if line.strip().startswith('File "') and "distributed" not in line
            and "tornado" not in line and "asyncio" not in line]  # fmt: skip
    assert not ours, "\n".join(ours)
    done = len((run / "metrics.jsonl").read_text().splitlines())
    assert 2 <= done < GENERATIONS
    with cluster(tmp_path) as (address, _):
        resumed = subprocess.run([*structgen_command(), "resume", str(run), "--cluster", address], capture_output=True, text=True)
    assert resumed.returncode == 0, resumed.stderr
    assert outcome(run) == outcome(undisturbed)
