"""Experiments of many seeds: each seed's run in its own ``structgen evolve`` / ``structgen resume`` process.

A run in its own process shares nothing with the others but the disk, so runs go side by side on local cores or on a
Dask cluster, and a killed experiment resumes run by run. Each seed's folder is checked before any run starts: a
folder holding another configuration's run is refused rather than merged into a table.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from structgen.errors import InputError
from structgen.registry.commands import EXIT_BAD_INPUT, EXIT_INTERRUPTED

__all__ = [
    "ADDRESS",
    "RunStopped",
    "check_distinct_seeds",
    "check_seed_folder",
    "expected_run",
    "finished",
    "run_all",
    "run_seed",
]


class RunStopped(KeyboardInterrupt):
    """A seed's run stopped by Ctrl-C (or SIGINT sent to it alone) after checkpointing; the experiment stops as if it
    had been interrupted itself (exit 130), and the same command resumes it."""


#: A Dask scheduler's address: an optional scheme, a host and a port.
ADDRESS = re.compile(r"(?:[a-z][a-z0-9+.-]*://)?[A-Za-z0-9._\-\[\]:]+:[0-9]{1,5}")


def finished(run_dir: Path, generations: int | None = None) -> bool:
    """Whether the run reached ``generations`` (default: its configured generations; its last metrics row says so)."""
    from structgen.runs import open_run

    try:
        folder, experiment = open_run(run_dir)
        rows = folder.metrics()
    except Exception:
        return False
    target = experiment.run.generations if generations is None else generations
    return bool(rows) and rows[-1]["generation"] >= target and folder.has_checkpoint()


def run_seed(
    config: str,
    overrides: Sequence[str],
    seed: int,
    run_dir: str,
    threads: int,
    generations: int | None = None,
    workers: int | None = None,
) -> str:
    """One run of the experiment in its own process (``threads`` numba threads, ``workers`` evaluation processes,
    default the configuration's): started, resumed (to ``generations`` when given), or left alone when it has got
    that far. Returns the run folder. Runs anywhere the package is installed (a Dask worker too).

    ``workers`` is passed as an option, not as a setting among ``overrides``: a resumed run reads only its own
    config.toml, so a setting would be lost there."""
    path = Path(run_dir)
    if finished(path, generations):
        return run_dir
    command = [sys.executable, "-m", "structgen"]
    if (path / "config.toml").is_file():
        command += ["resume", run_dir]
        if generations is not None:
            command += ["--generations", str(generations)]
    else:
        command += ["evolve", config, "--seed", str(seed), "--run-dir", run_dir]
        for assignment in overrides:
            command += ["--set", assignment]
        if generations is not None:
            command += ["--generations", str(generations)]
    if workers is not None:
        command += ["--workers", str(workers)]
    environment = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
    done = subprocess.run(command, env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode in (EXIT_INTERRUPTED, -signal.SIGINT):
        raise RunStopped(f"seed {seed} ({run_dir}) was stopped after its last checkpoint; the same command resumes it")
    if done.returncode != 0:
        last = done.stderr.strip().splitlines()[-1] if done.stderr.strip() else f"exit {done.returncode}"
        # The run's own verdict travels on: bad input there (exit 2) is bad input here.
        kind = InputError if done.returncode == EXIT_BAD_INPUT else RuntimeError
        raise kind(f"seed {seed} ({run_dir}): {last}")
    return run_dir


def check_distinct_seeds(seeds: Sequence[int]) -> None:
    """Each seed once: two runs of one seed would share its folder (and race in it, run side by side)."""
    repeated = sorted({seed for seed in seeds if list(seeds).count(seed) > 1})
    if repeated:
        raise InputError(f"--seeds: seed {', '.join(map(str, repeated))} given twice; each seed runs once")


def expected_run(
    config: str | Path, overrides: Sequence[str], seed: int, generations: int | None, domain: str | None = None
) -> Any:
    """The configuration ``run_seed`` starts a seed's run with, checked (its errors name the file); with ``domain``,
    it must be a configuration of that domain (an experiment's, before its own settings are applied to it)."""
    from structgen.config import ConfigError
    from structgen.runs.experiment import load_experiment

    changes: dict[str, Any] = {"seed": seed}
    if generations is not None:
        changes["generations"] = generations
    try:
        return load_experiment(config, domain=domain, overrides=list(overrides), run_changes=changes)
    except ConfigError as err:
        raise InputError(str(err)) from None


def check_seed_folder(run_dir: Path, expected: Any, *, any_length: bool = False) -> None:
    """Refuse a ``seed-S`` folder that is not this experiment's run for that seed: its results would be merged into
    the table as if they were (settings that only say where or how long a run goes may differ, but not its
    generations, unless ``any_length``: an experiment that runs its seeds in stages)."""
    from evolution import RunFolderError
    from structgen.config import flatten
    from structgen.runs import EDITABLE, open_run

    if not run_dir.exists() and not run_dir.is_symlink():
        return
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: is not a folder; the experiment keeps each seed's run there")
    if not any(run_dir.iterdir()):
        return
    try:
        _, found = open_run(run_dir)
    except (RunFolderError, InputError) as err:
        raise InputError(f"{run_dir}: not this experiment's run ({err})") from None
    before, now = flatten(found.to_mapping()), flatten(expected.to_mapping())
    free = set(EDITABLE) if any_length else set(EDITABLE) - {"run.generations"}
    differ = sorted(key for key in before.keys() | now.keys() if key not in free and before.get(key) != now.get(key))
    if differ:
        listing = "; ".join(f"{key} {before.get(key)!r} (wanted {now.get(key)!r})" for key in differ[:5])
        raise InputError(
            f"{run_dir / 'config.toml'}: a run with other settings than this experiment's for its seed: {listing}; "
            "move it away or choose another OUT_DIR"
        )


def run_all(jobs: Sequence[tuple], parallel: int, cluster: str, report: Callable[[str], None]) -> None:
    if cluster:
        try:
            from distributed import Client, as_completed
        except ImportError:
            raise InputError("--cluster needs the 'distributed' package (pip install distributed)") from None
        try:
            client = Client(cluster, timeout="10s")
        except OSError as err:
            raise InputError(f"--cluster {cluster}: cannot reach a Dask scheduler there ({err})") from None
        from concurrent.futures import CancelledError

        with client:
            futures = [client.submit(run_seed, *job, pure=False) for job in jobs]
            try:
                for future in as_completed(futures):
                    report(future.result())
            except (OSError, TimeoutError, CancelledError) as err:
                # Each seed's run keeps its own checkpoints: what finished stays finished, the rest resumes.
                reason = str(err).splitlines()[0] if str(err) else type(err).__name__
                raise RuntimeError(
                    f"lost the Dask scheduler at {cluster} ({reason}); each seed's run keeps its last checkpoint: the "
                    "same command, with the scheduler running again, goes on from there"
                ) from None
        return
    from concurrent.futures import ThreadPoolExecutor, as_completed

    # Threads only wait on the run processes.
    with ThreadPoolExecutor(max_workers=parallel) as pool:
        for future in as_completed([pool.submit(run_seed, *job) for job in jobs]):
            report(future.result())
