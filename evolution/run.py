"""Runs as folders: the loop that asks, evaluates and tells, and everything it leaves behind.

A run folder holds:

- ``config.toml``: the resolved configuration (written by the caller; ``resume`` reads only this).
- ``manifest.json``: library versions, start time, command line.
- ``checkpoint.pkl``: the optimiser and loop state after the last checkpointed generation, written atomically
  (temporary file, then rename) and only between generations. Pickle is only for resuming.
- ``metrics.jsonl``: one JSON object per generation; on resume it is cut back to the checkpoint.
- ``archive.csv`` (+ ``archive_solutions.npy`` for flat genomes): the quality-diversity archive, one row per elite.
- ``best/``: the best genome (``genome.npy`` or ``genome.json``), its scores (``best.json``), and whatever the
  problem writes to show it (a structure, a mesh, a picture).
- ``objective.png`` and, for quality diversity, ``archive.png``: plots.

Determinism: all randomness lives in the optimiser (pickled) or is derived from ``(seed, generation)``, and
evaluation is a pure function of genome and seed, so a run interrupted at any point and resumed from its checkpoint
ends exactly like one that never stopped.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import pickle
import shutil
import signal
import sys
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from evolution.evaluators import Evaluator
from evolution.optimizers import Optimizer
from evolution.problem import Evaluation, Problem

__all__ = [
    "Best",
    "RunFolder",
    "RunFolderError",
    "RunSettings",
    "RunState",
    "advance",
    "graceful_interrupt",
    "library_versions",
]

log = logging.getLogger(__name__)
CHECKPOINT_SCHEMA = 1


class RunFolderError(Exception):
    """A run folder cannot be created, read or resumed; the message says which and why."""


@dataclass(frozen=True)
class RunSettings:
    """How long and where a run goes.

    Attributes:
        generations: generations to run in total (``resume --generations`` can raise it).
        seed: the run's seed; the same seed and configuration give the same run.
        checkpoint_every: write a checkpoint (and the best candidate, and the archive) every this many generations;
            the last generation and an interrupted one are always checkpointed.
        workers: local evaluation processes; 0 evaluates in the main process.
        cluster: address of a Dask scheduler; when set, evaluation goes there instead of local processes.
        plot_every: redraw the plots every this many generations (and always at the end).
    """

    generations: int = 20
    seed: int = 0
    checkpoint_every: int = 1
    workers: int = 2
    cluster: str = ""
    plot_every: int = 10

    def __post_init__(self) -> None:
        for name in ("generations", "checkpoint_every", "plot_every"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                raise ValueError(f"run {name} must be a positive integer, got {value!r}")
        if not isinstance(self.workers, int) or isinstance(self.workers, bool) or self.workers < 0:
            raise ValueError(f"run workers must be 0 or a positive integer, got {self.workers!r}")
        if not isinstance(self.seed, int) or isinstance(self.seed, bool) or self.seed < 0:
            raise ValueError(f"run seed must be a non-negative integer, got {self.seed!r}")


@dataclass
class Best:
    """The best candidate seen so far."""

    genome: Any
    objective: float
    measures: list[float]
    fields: dict[str, float]
    generation: int


@dataclass
class RunState:
    """Everything a checkpoint holds."""

    optimizer: Optimizer
    generation: int = 0  # generations completed
    evaluations: int = 0
    elapsed: float = 0.0  # wall seconds spent in generations, over all sessions
    best: Best | None = None
    best_written: int = -1  # generation of the best candidate last written to best/
    extra: dict[str, Any] = field(default_factory=dict)


def library_versions(names: list[str]) -> dict[str, str | None]:
    """Installed versions of the given distributions (None where missing)."""
    versions: dict[str, str | None] = {"python": sys.version.split()[0]}
    for name in names:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def _atomic_write(path: Path, data: bytes | str) -> None:
    # structgen keeps its own copy of this helper: `import structgen` must not load evolution, and evolution must
    # not import structgen.
    payload = data.encode("utf-8") if isinstance(data, str) else data
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:12]}.tmp")
    try:
        with open(tmp, "xb") as handle:
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


class RunFolder:
    """The files of one run."""

    CONFIG, MANIFEST, CHECKPOINT, METRICS = "config.toml", "manifest.json", "checkpoint.pkl", "metrics.jsonl"
    ARCHIVE, SOLUTIONS, BEST = "archive.csv", "archive_solutions.npy", "best"
    OBJECTIVE_PLOT, ARCHIVE_PLOT = "objective.png", "archive.png"

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)

    def __truediv__(self, name: str) -> Path:
        return self.path / name

    # -- life cycle -----------------------------------------------------------------------------------------------------
    @classmethod
    def create(cls, path: str | os.PathLike, config_text: str, manifest: dict[str, Any], *, overwrite: bool = False) -> RunFolder:
        """Make a new run folder. An existing folder is an error, unless ``overwrite`` and it is an empty folder or
        a run folder (anything else is never deleted)."""
        folder = cls(path)
        if folder.path.exists():
            if not folder.path.is_dir():
                raise RunFolderError(f"{folder.path}: exists and is not a folder")
            contents = list(folder.path.iterdir())
            if contents:
                if not overwrite:
                    raise RunFolderError(f"{folder.path}: already exists; choose another --run-dir or pass --overwrite")
                if not (folder / cls.CONFIG).exists():
                    raise RunFolderError(f"{folder.path}: exists and is not a run folder; refusing to overwrite it")
                shutil.rmtree(folder.path)
        folder.path.mkdir(parents=True, exist_ok=True)
        folder.write_config(config_text)
        _atomic_write(folder / cls.MANIFEST, json.dumps(manifest, indent=2) + "\n")
        return folder

    @classmethod
    def open(cls, path: str | os.PathLike) -> RunFolder:
        """An existing run folder (it must hold a config.toml)."""
        folder = cls(path)
        if not folder.path.is_dir():
            raise RunFolderError(f"{folder.path}: no such run folder")
        if not (folder / cls.CONFIG).is_file():
            raise RunFolderError(f"{folder.path}: not a run folder (no {cls.CONFIG})")
        return folder

    def config_text(self) -> str:
        return (self / self.CONFIG).read_text()

    def write_config(self, config_text: str) -> None:
        """Replace the configuration (atomically): a resume that runs longer than configured records it here."""
        _atomic_write(self / self.CONFIG, config_text)

    def manifest(self) -> dict[str, Any]:
        try:
            return json.loads((self / self.MANIFEST).read_text())
        except (OSError, json.JSONDecodeError):
            return {}

    # -- checkpoint -----------------------------------------------------------------------------------------------------
    def save_checkpoint(self, state: RunState) -> None:
        _atomic_write(self / self.CHECKPOINT, pickle.dumps({"schema": CHECKPOINT_SCHEMA, "state": state}))

    def load_checkpoint(self) -> RunState:
        path = self / self.CHECKPOINT
        if not path.is_file():
            raise RunFolderError(f"{self.path}: no checkpoint yet (the run stopped before its first generation ended)")
        try:
            data = pickle.loads(path.read_bytes())
        except Exception as err:  # a checkpoint from another version, or a damaged file
            raise RunFolderError(f"{path}: cannot read the checkpoint ({type(err).__name__}: {err})") from None
        if not isinstance(data, dict) or data.get("schema") != CHECKPOINT_SCHEMA:
            raise RunFolderError(f"{path}: checkpoint format is not supported by this version")
        return data["state"]

    # -- metrics --------------------------------------------------------------------------------------------------------
    def append_metrics(self, row: dict[str, Any]) -> None:
        with open(self / self.METRICS, "a") as handle:
            handle.write(json.dumps(row) + "\n")
            handle.flush()
            os.fsync(handle.fileno())

    def metrics(self) -> list[dict[str, Any]]:
        path = self / self.METRICS
        if not path.exists():
            return []
        rows = []
        for line in path.read_text().splitlines():
            try:
                rows.append(json.loads(line))
            except json.JSONDecodeError:  # a line cut short by a kill
                break
        return rows

    def truncate_metrics(self, generation: int) -> None:
        """Keep the rows up to ``generation``: those after the checkpoint will be recomputed."""
        rows = [row for row in self.metrics() if row["generation"] <= generation]
        _atomic_write(self / self.METRICS, "".join(json.dumps(row) + "\n" for row in rows))

    # -- results --------------------------------------------------------------------------------------------------------
    def write_best(self, best: Best, problem: Problem) -> None:
        folder = self / self.BEST
        folder.mkdir(exist_ok=True)
        if problem.flat:
            buffer = _npy_bytes(np.asarray(best.genome, dtype=np.float64))
            _atomic_write(folder / "genome.npy", buffer)
        else:
            _atomic_write(folder / "genome.json", json.dumps(problem.genome_to_json(best.genome)) + "\n")
        summary = {
            "generation": best.generation,
            "objective": best.objective,
            "measures": dict(zip(problem.measure_names, best.measures)),
            "fields": best.fields,
        }
        _atomic_write(folder / "best.json", json.dumps(summary, indent=2) + "\n")
        problem.write_artifacts(best.genome, folder)

    def write_archive(self, archive: Any, problem: Problem) -> None:
        """``archive.csv`` (index, objective, measures, threshold, fields; sorted by cell index) and, for flat
        genomes, ``archive_solutions.npy`` with the genome of each row in the same order."""
        data = archive.data()
        order = np.argsort(data["index"], kind="stable")
        header = ["index", "objective", *problem.measure_names, "threshold", *problem.field_names]
        columns = [data["index"][order], data["objective"][order]]
        columns += [data["measures"][order, k] for k in range(len(problem.measure_names))]
        columns += [data["threshold"][order], *[data[name][order] for name in problem.field_names]]
        lines = [",".join(header + ([] if problem.flat else ["genome"]))]
        solutions = data["solution"][order]
        for r in range(len(order)):
            cells = [repr(int(columns[0][r]))] + [repr(float(c[r])) for c in columns[1:]]
            if not problem.flat:
                cells.append('"' + json.dumps(problem.genome_to_json(solutions[r])).replace('"', '""') + '"')
            lines.append(",".join(cells))
        _atomic_write(self / self.ARCHIVE, "\n".join(lines) + "\n")
        if problem.flat:
            _atomic_write(self / self.SOLUTIONS, _npy_bytes(np.asarray(solutions, dtype=np.float64)))

    def archive_genome(self, index: int, problem: Problem) -> Any:
        """The genome of the archive elite in cell ``index`` (the ``index`` column of archive.csv)."""
        path = self / self.ARCHIVE
        if not path.is_file():
            raise RunFolderError(f"{self.path}: this run has no archive (only quality-diversity runs keep one)")
        import csv

        with open(path, newline="") as handle:
            rows = list(csv.DictReader(handle))
        positions = [r for r, row in enumerate(rows) if int(row["index"]) == index]
        if not positions:
            known = ", ".join(row["index"] for row in rows[:10])
            raise RunFolderError(f"{path}: no elite in cell {index} (cells held: {known}{', ...' if len(rows) > 10 else ''})")
        if problem.flat:
            return np.load(self / self.SOLUTIONS, allow_pickle=False)[positions[0]]
        return json.loads(rows[positions[0]]["genome"])

    def best_genome(self, problem: Problem) -> Any:
        folder = self / self.BEST
        if problem.flat and (folder / "genome.npy").is_file():
            return np.load(folder / "genome.npy", allow_pickle=False)
        if (folder / "genome.json").is_file():
            return json.loads((folder / "genome.json").read_text())
        raise RunFolderError(f"{self.path}: no best candidate yet")


def _npy_bytes(array: np.ndarray) -> bytes:
    import io

    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=False)
    return buffer.getvalue()


@contextlib.contextmanager
def graceful_interrupt() -> Iterator[Callable[[], bool]]:
    """Within the block, the first Ctrl-C only raises a flag (the loop finishes the generation, checkpoints and
    stops); a second one interrupts at once. Yields a function telling whether a stop was requested."""
    requested = {"stop": False}
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum: int, frame: Any) -> None:
        if requested["stop"]:
            raise KeyboardInterrupt
        requested["stop"] = True
        log.warning("interrupted: finishing this generation, then checkpointing (Ctrl-C again to abort)")

    try:
        signal.signal(signal.SIGINT, handler)
    except ValueError:  # not the main thread: no signal handling, the caller's own stop function still works
        previous = None
    try:
        yield lambda: requested["stop"]
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _metrics_row(state: RunState, evaluation: Evaluation, optimizer: Optimizer, problem: Problem) -> dict[str, Any]:
    best = state.best
    row: dict[str, Any] = {
        "generation": state.generation,
        "evaluations": state.evaluations,
        "best_objective": best.objective,
        "generation_best_objective": float(evaluation.objective.max()),
        "mean_objective": float(evaluation.objective.mean()),
    }
    row.update({f"best_{name}": value for name, value in zip(problem.measure_names, best.measures)})
    row.update({f"best_{name}": value for name, value in best.fields.items()})
    row.update({f"generation_max_{name}": float(values.max()) for name, values in evaluation.fields.items()})
    if optimizer.archive is not None:
        stats = optimizer.archive.stats
        row.update(
            {
                "qd_score": float(stats.qd_score),
                "coverage": float(stats.coverage),
                "num_elites": int(stats.num_elites),
            }
        )
    row["wall_s"] = round(state.elapsed, 3)
    return row


def advance(
    folder: RunFolder,
    problem: Problem,
    state: RunState,
    settings: RunSettings,
    evaluator: Evaluator,
    *,
    until: int | None = None,
    stop_requested: Callable[[], bool] = lambda: False,
    progress: bool = True,
    on_generation: Callable[[dict[str, Any]], None] | None = None,
) -> RunState:
    """Run generations until ``until`` (default ``settings.generations``) or a stop request, checkpointing as set.

    Returns the state after the last completed generation, which is also the last checkpoint.
    """
    from evolution.plots import write_plots

    until = settings.generations if until is None else until
    optimizer = state.optimizer
    optimizer.attach(problem)
    bar = _progress_bar(state.generation, until) if progress else None
    try:
        while state.generation < until:
            started = time.perf_counter()
            genomes = optimizer.ask()
            seeds = np.random.SeedSequence([settings.seed, state.generation]).generate_state(len(genomes))
            evaluation = evaluator.evaluate(problem, genomes, seeds)
            if len(evaluation) != len(genomes):
                raise RuntimeError(f"{problem.name} returned {len(evaluation)} results for {len(genomes)} genomes")
            optimizer.tell(evaluation.objective, evaluation.measures, **evaluation.fields)
            state.generation += 1
            state.evaluations += len(genomes)
            top = int(np.argmax(evaluation.objective))  # the first of equals: deterministic
            if state.best is None or evaluation.objective[top] > state.best.objective:
                row = evaluation.row(top)
                genome = genomes[top]
                state.best = Best(
                    genome=np.array(genome, copy=True) if problem.flat else genome,
                    objective=row["objective"],
                    measures=row["measures"],
                    fields={name: row[name] for name in evaluation.fields},
                    generation=state.generation,
                )
            state.elapsed += time.perf_counter() - started
            metrics = _metrics_row(state, evaluation, optimizer, problem)
            folder.append_metrics(metrics)
            stopping = stop_requested()
            last = state.generation >= until or stopping
            if state.generation % settings.checkpoint_every == 0 or last:
                _checkpoint(folder, problem, state)
            if state.generation % settings.plot_every == 0 or last:
                write_plots(folder, problem, optimizer.archive)
            _report(bar, metrics, until)
            if on_generation is not None:
                on_generation(metrics)
            if stopping:
                break
    finally:
        if bar is not None:
            bar.close()
    return state


def _checkpoint(folder: RunFolder, problem: Problem, state: RunState) -> None:
    # Results first, checkpoint last: a kill in between leaves an older checkpoint whose resume rewrites the same
    # results, never a checkpoint that claims results that were not written.
    if state.best is not None and state.best.generation != state.best_written:
        folder.write_best(state.best, problem)
        state.best_written = state.best.generation
    if state.optimizer.archive is not None:
        folder.write_archive(state.optimizer.archive, problem)
    folder.save_checkpoint(state)


def _progress_bar(start: int, total: int) -> Any:
    if not sys.stderr.isatty():
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=start, desc="evolve", unit="gen", file=sys.stderr, dynamic_ncols=True)


def _report(bar: Any, metrics: dict[str, Any], until: int) -> None:
    details = {k[5:]: v for k, v in metrics.items() if k.startswith("best_") and k != "best_objective"}
    summary = ", ".join(f"{k} {v:.3g}" for k, v in list(details.items())[:4] if isinstance(v, (int, float)) and math.isfinite(v))
    if bar is not None:
        bar.set_postfix_str(f"best {metrics['best_objective']:.4g} ({summary})", refresh=False)
        bar.update(1)
    else:
        log.info(
            "generation %d/%d: best %.4g (%s), this generation mean %.4g, %d evaluations, %.1f s",
            metrics["generation"],
            until,
            metrics["best_objective"],
            summary,
            metrics["mean_objective"],
            metrics["evaluations"],
            metrics["wall_s"],
        )
