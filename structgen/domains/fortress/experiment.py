"""The paper's two experiments end to end: ten MAP-Elites runs, one per seed, then Table 3 from their archives.

``structgen fortress experiment entities_nodes OUT`` runs ``configs/fortress_paper.toml`` (or ``--config``) under
seeds 20 to 29 (the original's sweep), each in its own run folder ``OUT/seed-<S>``, several at a time on local cores
or on a Dask cluster; a run folder that exists is resumed or, when finished, kept. Then every run's archive is
re-evaluated as the paper's Table 3 does (:func:`.robustness.reevaluate`: as evolved, on 5 new seeds, on new seeds
with 5 times longer episodes; each run re-binned, the runs merged best-per-cell) and the table is written beside
the paper's numbers: ``OUT/table.json`` (every row) and ``OUT/table.md``.

A run is a separate ``structgen evolve`` / ``structgen resume`` process, so runs in parallel share nothing but the
disk, a killed experiment resumes run by run, and a Dask worker needs only the package and the output folder.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from evolution.files import atomic_write
from structgen.commands import EXIT_BAD_INPUT
from structgen.errors import InputError

__all__ = ["PAPER_TABLE", "run_experiment", "run_seed", "table_markdown"]

# The QD paper's Table 3 (10 runs merged): best score, QD score and archive size, as evolved (100 ticks), on new
# seeds (100 ticks) and on new seeds with 500-tick episodes.
PAPER_TABLE = {
    "entities_nodes": [(0.941, 2235, 9986), (0.941, 2197, 9975), (0.941, 2086, 9962)],
    "entities_entropy": [(0.958, 2156, 6974), (0.958, 2005, 6951), (0.958, 2011, 6950)],
}
PASSES = ("as evolved", "new seeds", "new seeds, longer episodes")
#: A Dask scheduler's address: an optional scheme, a host and a port.
_ADDRESS = re.compile(r"(?:[a-z][a-z0-9+.-]*://)?[A-Za-z0-9._\-\[\]:]+:[0-9]{1,5}")


def _finished(run_dir: Path) -> bool:
    """Whether the run reached its configured generations (its last metrics row says so)."""
    from structgen.runs import open_run

    try:
        folder, experiment = open_run(run_dir)
        rows = folder.metrics()
    except Exception:
        return False
    return bool(rows) and rows[-1]["generation"] >= experiment.run.generations and folder.has_checkpoint()


def run_seed(config: str, measures: str, seed: int, run_dir: str, threads: int, generations: int | None = None) -> str:
    """One run of the experiment in its own process (``threads`` numba threads): started, resumed, or left alone
    when it has finished. Returns the run folder. Runs anywhere the package is installed (a Dask worker too)."""
    path = Path(run_dir)
    if _finished(path):
        return run_dir
    command = [sys.executable, "-m", "structgen"]
    if (path / "config.toml").is_file():
        command += ["resume", run_dir]
    else:
        command += ["evolve", config, "--seed", str(seed), "--run-dir", run_dir, "--set", f"problem.measures={measures}"]
        if generations is not None:
            command += ["--generations", str(generations)]
    environment = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
    done = subprocess.run(command, env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if done.returncode != 0:
        last = done.stderr.strip().splitlines()[-1] if done.stderr.strip() else f"exit {done.returncode}"
        # The run's own verdict travels on: bad input there (exit 2) is bad input here.
        kind = InputError if done.returncode == EXIT_BAD_INPUT else RuntimeError
        raise kind(f"seed {seed} ({run_dir}): {last}")
    return run_dir


def _expected_run(config: str | Path, measures: str, seed: int, generations: int | None) -> Any:
    """The configuration ``run_seed`` starts a seed's run with, checked (its errors name the file)."""
    from structgen.config import ConfigError
    from structgen.experiment import load_experiment

    changes: dict[str, Any] = {"seed": seed}
    if generations is not None:
        changes["generations"] = generations
    try:
        return load_experiment(config, overrides=[f"problem.measures={measures}"], run_changes=changes)
    except ConfigError as err:
        raise InputError(str(err)) from None


def _check_seed_folder(run_dir: Path, expected: Any) -> None:
    """Refuse a ``seed-S`` folder that is not this experiment's run for that seed: its results would be merged into
    the table as if they were (settings that only say where or how long a run goes may differ, but not its
    generations)."""
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
    free = set(EDITABLE) - {"run.generations"}
    differ = sorted(key for key in before.keys() | now.keys() if key not in free and before.get(key) != now.get(key))
    if differ:
        listing = "; ".join(f"{key} {before.get(key)!r} (wanted {now.get(key)!r})" for key in differ[:5])
        raise InputError(
            f"{run_dir / 'config.toml'}: a run with other settings than this experiment's for its seed: {listing}; "
            "move it away or choose another OUT_DIR"
        )


def _run_all(jobs: Sequence[tuple], parallel: int, cluster: str, report: Callable[[str], None]) -> None:
    if cluster:
        try:
            from distributed import Client, as_completed
        except ImportError:
            raise InputError("--cluster needs the 'distributed' package (pip install distributed)") from None
        try:
            client = Client(cluster, timeout="10s")
        except OSError as err:
            raise InputError(f"--cluster {cluster}: cannot reach a Dask scheduler there ({err})") from None
        with client:
            futures = [client.submit(run_seed, *job, pure=False) for job in jobs]
            for future in as_completed(futures):
                report(future.result())
        return
    from concurrent.futures import ThreadPoolExecutor, as_completed

    # Threads only wait on the run processes.
    with ThreadPoolExecutor(max_workers=parallel) as pool:
        for future in as_completed([pool.submit(run_seed, *job) for job in jobs]):
            report(future.result())


def run_experiment(
    measures: str,
    out_dir: str | Path,
    *,
    config: str | Path,
    seeds: Sequence[int] = tuple(range(20, 30)),
    parallel: int = 2,
    threads: int = 1,
    cluster: str = "",
    generations: int | None = None,
    longer: int = 5,
    progress: bool = True,
) -> dict[str, Any]:
    """Run (or finish) every seed's run, then write and return the table (see the module's description)."""
    from structgen.domains.fortress.problem import MEASURES
    from structgen.domains.fortress.robustness import open_runs, reevaluate

    if measures not in MEASURES:
        raise InputError(f"measures must be one of {', '.join(MEASURES)}, got {measures!r}")
    if not Path(config).is_file():
        raise InputError(f"{config}: no such configuration file")
    if cluster and not _ADDRESS.fullmatch(cluster):
        raise InputError(f"--cluster {cluster[:60]!r}: not a Dask scheduler's address (tcp://host:port or host:port)")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: is not a folder; OUT_DIR holds the runs and the table")
    # Every seed's folder is checked before any run starts, so that nothing runs for a table that would be refused.
    for seed in seeds:
        _check_seed_folder(out / f"seed-{seed}", _expected_run(config, measures, seed, generations))
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(f"{out}: cannot make this folder ({err.strerror})") from None
    jobs = [(str(config), measures, seed, str(out / f"seed-{seed}"), threads, generations) for seed in seeds]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(jobs), desc=f"{measures} runs", unit="run", file=sys.stderr)
    try:
        _run_all(jobs, parallel, cluster, lambda done: bar.update(1) if bar is not None else None)
    finally:
        if bar is not None:
            bar.close()
    folders, experiment = open_runs([job[3] for job in jobs])
    report = reevaluate(folders, experiment, longer=longer, progress=progress)
    report.update({"measures": measures, "run_seeds": list(seeds), "longer": longer, "paper": PAPER_TABLE[measures]})
    atomic_write(out / "table.json", json.dumps(report, indent=1) + "\n")
    atomic_write(out / "table.md", table_markdown(report))
    return report


def table_markdown(report: dict[str, Any]) -> str:
    """Table 3's half for these measures: the merged archive of the runs (and the runs' spread) beside the paper's."""
    rows = report["rows"]
    merged = [row for row in rows if row["name"].startswith("merged")]
    runs = len(report["run_seeds"])
    singles = [[row for row in rows if row["name"].startswith("run ") and _pass_of(row["name"]) == p] for p in range(len(PASSES))]
    header = f"| {report['measures']} ({runs} runs) | ticks | best | QD score | cells | QD score of one run (min-max) |"
    lines = [header + " paper: best / QD score / cells |", "|---|---:|---:|---:|---:|---:|---:|"]
    ticks = [report["steps"], report["steps"], report["steps"] * report["longer"]]
    for p, name in enumerate(PASSES):
        row = merged[p] if len(merged) > p else (singles[p][0] if singles[p] else None)
        if row is None:
            continue
        steps = ticks[p]
        scores = [r["qd_score"] for r in singles[p]]
        spread = f"{min(scores):,.0f}-{max(scores):,.0f}" if scores else ""
        best, qd, cells = report["paper"][p]
        lines.append(
            f"| {name} | {steps} | {row['best']:.3f} | {row['qd_score']:,.0f} | {row['cells']:,} | {spread} | "
            f"{best:.3f} / {qd:,} / {cells:,} |"
        )
    return "\n".join(lines) + "\n"


def _pass_of(name: str) -> int:
    if ", new seeds, " in name:
        return 2
    if ", new seeds" in name:
        return 1
    return 0
