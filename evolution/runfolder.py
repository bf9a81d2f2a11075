"""The run-folder format: which files a run leaves, how each is written and read back.

A run folder holds:

- ``config.toml``: the resolved configuration (written by the caller; ``resume`` reads only this).
- ``manifest.json``: library versions, start time, command line.
- ``checkpoint.pkl``: the loop's :class:`RunState` after the last checkpointed generation, written atomically
  (temporary file, then rename) and only between generations. Pickle is only for resuming, and loading one runs
  nothing it contains (:mod:`evolution.checkpoint`).
- ``metrics.jsonl``: one JSON object per generation; on resume it is cut back to the checkpoint.
- ``archive.csv``: the quality-diversity archive, one row per elite, numbers only (``pandas.read_csv`` reads it as
  it is). The genome of each row, in the same order, is in ``archive_solutions.npy`` for flat genomes and in
  ``archive_genomes.jsonl`` (one JSON value per line) for any other kind, unless the problem keeps a genome store.
- a genome store, for problems that keep one (:meth:`Problem.open_genome_store`; the fortress's ``genomes/``):
  every genome written once, as arrays, when a checkpoint first holds it; ``checkpoint.pkl`` and
  ``archive_genome_keys.npy`` (one key per row of archive.csv) refer to genomes by key.
- ``best/``: the best genome (``genome.npy`` or ``genome.json``), its scores (``best.json``), and whatever the
  problem writes to show it (a structure, a mesh, a picture).
- ``objective.png`` and, for quality diversity, ``archive.png`` and ``qd.png`` (QD score and coverage over
  generations): plots (see :mod:`evolution.plots`).

Every file is replaced atomically, so a kill at any moment leaves either the old file or the new one.
"""

from __future__ import annotations

import contextlib
import csv
import fcntl
import io
import json
import os
import pickle
import re
import shutil
import sys
from collections.abc import Collection, Iterator
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from evolution import checkpoint
from evolution.files import (
    GiB,
    InputFileError,
    MiB,
    atomic_write,
    parse_json,
    path_error,
    read_bytes,
    read_json,
    read_npy,
    read_text,
)
from evolution.optimizers import Optimizer
from evolution.problem import GenomeStore, Problem

__all__ = [
    "CHECKPOINT_SCHEMA",
    "Archive",
    "Best",
    "RunFolder",
    "RunFolderError",
    "RunState",
    "atomic_write",
    "library_versions",
    "load_archive",
]

CHECKPOINT_SCHEMA = 1
#: The key and value in manifest.json that mark a folder as a run folder; --overwrite deletes nothing else.
MARK, MARK_VALUE = "run_folder", "evolution run folder, format 1"
# What atomic_write's temporary files look like (evolution.files).
_LEFTOVER = re.compile(r"\..+\.[0-9a-f]{12}\.tmp")
# Far above what any run writes; they turn a damaged or substituted file into a clear error.
_MAX_TEXT, _MAX_TABLE, _MAX_STATE = 16 * MiB, 4 * GiB, 16 * GiB


class RunFolderError(Exception):
    """A run folder cannot be created, read or resumed; the message says which and why."""


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
    """Everything a checkpoint holds: the optimiser (with its random generators) and the loop's counters."""

    optimizer: Optimizer
    generation: int = 0  # generations completed
    evaluations: int = 0
    elapsed: float = 0.0  # wall seconds spent in generations, over all sessions
    best: Best | None = None
    best_written: int = -1  # generation of the best candidate last written to best/
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Archive:
    """A quality-diversity archive read back from a run folder: one row per elite, sorted by cell.

    ``columns`` maps every column of ``archive.csv`` to an array (``index`` and the ``cell_*`` columns whole
    numbers, the rest floats); ``measure_names`` are the measures in order; ``genomes`` holds each row's genome (an
    ``(N, n_params)`` array for flat genomes, a list otherwise), or is None when no problem was given to decode them.
    """

    columns: dict[str, np.ndarray]
    measure_names: tuple[str, ...]
    genomes: Any = None

    def __len__(self) -> int:
        return len(self.columns["index"])

    @property
    def objective(self) -> np.ndarray:
        return self.columns["objective"]

    @property
    def measures(self) -> np.ndarray:
        """``(N, k)`` measure values, one column per measure."""
        return np.stack([self.columns[name] for name in self.measure_names], axis=1).reshape(len(self), -1)

    @property
    def cells(self) -> np.ndarray:
        """``(N, k)`` whole-number cell coordinates, one column per measure."""
        return np.stack([self.columns[f"cell_{name}"] for name in self.measure_names], axis=1).reshape(len(self), -1)

    def best(self) -> int:
        """The row of the elite with the highest objective."""
        if not len(self):
            raise ValueError("the archive is empty")
        return int(np.argmax(self.objective))

    def row(self, position: int) -> dict[str, float | int]:
        """Every column's value in row ``position`` as plain numbers."""
        return {name: values[position].item() for name, values in self.columns.items()}


#: Archive indices and cells are whole numbers from 0 to this (pyribs' archives index cells with 32-bit integers).
_MAX_INDEX = 2**31 - 1


def _cell_number(text: Any) -> int | None:
    """An archive index or cell as archive.csv writes it (None if it is not one): read only when short, as Python
    itself refuses to read 5,000 digits as a number."""
    if not isinstance(text, str) or len(text) > 12 or not text.strip().isdigit():
        return None
    value = int(text)
    return value if value <= _MAX_INDEX else None


def _not_a_cell(path: Any, line: int, name: str, text: Any) -> InputFileError:
    shown = text if not isinstance(text, str) or len(text) <= 40 else f"{text[:20]}... ({len(text):,} characters)"
    return InputFileError(f"{path}, line {line}: {name} = {shown!r} is not a whole number from 0 to {_MAX_INDEX:,}")


def load_archive(run_dir: str | os.PathLike, problem: Problem | None = None) -> Archive:
    """The archive of the run in ``run_dir`` (a quality-diversity run); with ``problem``, each elite's genome too."""
    return RunFolder.open(run_dir).load_archive(problem)


def library_versions(names: list[str]) -> dict[str, str | None]:
    """Installed versions of the given distributions (None where missing), and Python's."""
    versions: dict[str, str | None] = {"python": sys.version.split()[0]}
    for name in names:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def _same_file(descriptor: int, path: Path) -> bool:
    try:
        return os.fstat(descriptor).st_ino == os.stat(path, follow_symlinks=False).st_ino
    except FileNotFoundError:
        return False


def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array, allow_pickle=False)
    return buffer.getvalue()


@dataclass
class _StoredGenomes:
    """The archive's genomes as keys into the run's genome store (``archive_genome_keys.npy``)."""

    store: GenomeStore
    keys: np.ndarray

    def __len__(self) -> int:
        return len(self.keys)

    def load(self, positions: Any) -> list[Any]:
        return self.store.load([int(self.keys[p]) for p in positions])


class _StorePickler(pickle.Pickler):
    """Pickles a run state with the genomes of a genome store replaced by their keys."""

    def __init__(self, file: io.BytesIO, store: GenomeStore) -> None:
        super().__init__(file)
        self.store = store
        self.kind = getattr(store, "genome_type", None)

    def persistent_id(self, obj: Any) -> Any:
        if self.kind is not None and type(obj) is self.kind:
            return ("genome", int(self.store.keys([obj])[0]))
        return None


class RunFolder:
    """The files of one run."""

    CONFIG, MANIFEST, CHECKPOINT, METRICS = "config.toml", "manifest.json", "checkpoint.pkl", "metrics.jsonl"
    ARCHIVE, SOLUTIONS, GENOMES, BEST = "archive.csv", "archive_solutions.npy", "archive_genomes.jsonl", "best"
    GENOME_KEYS = "archive_genome_keys.npy"
    LOCK = ".lock"
    OBJECTIVE_PLOT, ARCHIVE_PLOT, QD_PLOT = "objective.png", "archive.png", "qd.png"

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        # Genome stores opened in this folder, by the problem that opened them (kept with it, so its id stays its).
        self._stores: dict[int, tuple[Problem, GenomeStore | None]] = {}

    def __truediv__(self, name: str) -> Path:
        return self.path / name

    # -- life cycle -----------------------------------------------------------------------------------------------------
    @classmethod
    def create(
        cls,
        path: str | os.PathLike,
        config_text: str,
        manifest: dict[str, Any],
        *,
        overwrite: bool = False,
        keep: Collection[str | os.PathLike] = (),
    ) -> RunFolder:
        """Make a new run folder, marked as one in its manifest.

        An existing folder is an error, unless it is empty, or ``overwrite`` is given and it is a run folder (its
        manifest carries the mark) of the same kind as the new one (the manifests' ``run_kind``: an evolution run
        replaces only an evolution run, a training only a training of its kind) that no process is writing and that
        neither is nor holds a path in ``keep`` (what the command reads from). Anything else is never deleted.
        """
        folder = cls(path)
        try:
            folder._make(config_text, manifest, overwrite, keep)
        except OSError as err:  # the path itself is at fault: a file on the way, a name too long, no permission
            raise RunFolderError(str(path_error(folder.path, err, writing=True))) from None
        return folder

    def _refuse_to_replace(self, manifest: dict[str, Any], keep: Collection[str | os.PathLike]) -> None:
        """Why ``--overwrite`` may not delete this (existing, non-empty) folder for a run described by ``manifest``."""
        if not self.is_marked():
            raise RunFolderError(
                f"{self.path}: exists and is not a run folder (its manifest.json lacks the run-folder mark); "
                "refusing to overwrite it"
            )
        here = self.path.resolve()
        for kept in keep:
            kept_path = Path(kept).resolve()
            if kept_path == here or here in kept_path.parents:
                raise RunFolderError(
                    f"{self.path}: holds {kept}, which this command reads from; refusing to overwrite it (choose "
                    "another output folder)"
                )
        old_kind, new_kind = self.manifest().get("run_kind"), manifest.get("run_kind")
        if old_kind != new_kind:
            old_name, new_name = (("an evolution run" if k is None else f"a {k} run") for k in (old_kind, new_kind))
            raise RunFolderError(
                f"{self / self.MANIFEST}: run_kind {old_kind!r}: this folder holds {old_name}, and --overwrite "
                f"replaces only {new_name}, the kind this command writes; refusing to delete it"
            )

    def _make(self, config_text: str, manifest: dict[str, Any], overwrite: bool, keep: Collection[str | os.PathLike]) -> None:
        if self.path.is_symlink():
            raise RunFolderError(f"{self.path}: is a symbolic link; give the run folder's own path")
        if self.path.exists():
            if not self.path.is_dir():
                raise RunFolderError(f"{self.path}: exists and is not a folder")
            if any(self.path.iterdir()):
                if not overwrite:
                    raise RunFolderError(f"{self.path}: already exists; choose another --run-dir or pass --overwrite")
                self._refuse_to_replace(manifest, keep)
                with self.locked():  # refuses if a run is writing it
                    shutil.rmtree(self.path)
        self.path.mkdir(parents=True, exist_ok=True)
        self.write_config(config_text)
        atomic_write(self / self.MANIFEST, json.dumps({**manifest, MARK: MARK_VALUE}, indent=2) + "\n")

    def is_marked(self) -> bool:
        """Whether the manifest says this is a run folder (or is a manifest of the first format, which had no mark
        but always these four keys)."""
        manifest = self.manifest()
        legacy = (
            manifest.get("schema") == 1 and isinstance(manifest.get("versions"), dict) and {"created", "argv"} <= set(manifest)
        )
        return manifest.get(MARK) == MARK_VALUE or (legacy and (self / self.CONFIG).is_file())

    def remove(self, *, keep_folder: bool = False) -> None:
        """Delete this run folder (it must carry the mark), or with ``keep_folder`` only what is in it (the folder
        was made by someone else, empty, and is left as it was found)."""
        if not self.is_marked():
            raise RunFolderError(f"{self.path}: not a run folder; refusing to delete it")
        if not keep_folder:
            shutil.rmtree(self.path)
            return
        for child in self.path.iterdir():
            if child.is_dir() and not child.is_symlink():
                shutil.rmtree(child)
            else:
                child.unlink()

    @contextlib.contextmanager
    def locked(self) -> Iterator[RunFolder]:
        """Hold the run folder's lock (an OS file lock on ``.lock``) for the block: only one process writes a run
        at a time, and a second gets a RunFolderError saying which process holds it. The lock goes with the
        process, so a killed run never leaves it held; a run that ends removes the file."""
        path = self / self.LOCK
        flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
        while True:
            try:
                descriptor = os.open(path, flags, 0o644)
            except OSError as err:
                raise RunFolderError(f"{path}: cannot open the run's lock ({err.strerror})") from None
            try:
                fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(descriptor, 64, 0).decode("ascii", "replace").strip() or "another process"
                os.close(descriptor)
                raise RunFolderError(
                    f"{self.path}: another process (pid {holder}) is writing this run; wait for it to end or stop it"
                ) from None
            # The lock file goes when its holder is done; one locked just as it went is not the folder's lock any
            # more, and a process that got it must try the new one.
            if _same_file(descriptor, path):
                break
            os.close(descriptor)
        try:
            os.ftruncate(descriptor, 0)
            os.pwrite(descriptor, f"{os.getpid()}\n".encode(), 0)
            yield self
        finally:
            if _same_file(descriptor, path):  # gone already if the block removed the folder
                path.unlink(missing_ok=True)
            os.close(descriptor)  # closing releases the lock

    def remove_temporary_files(self) -> list[Path]:
        """Delete what writes cut short by a kill left behind (``.NAME.XXXXXXXXXXXX.tmp``); call it holding the
        lock. Returns what was removed."""
        removed = []
        for folder in (self.path, self / self.BEST):
            if folder.is_dir() and not folder.is_symlink():
                for leftover in folder.iterdir():
                    if _LEFTOVER.fullmatch(leftover.name) and leftover.is_file() and not leftover.is_symlink():
                        leftover.unlink()
                        removed.append(leftover)
        return removed

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
        return read_text(self / self.CONFIG, _MAX_TEXT, what="TOML")

    def write_config(self, config_text: str) -> None:
        """Replace the configuration (atomically): a resume that runs longer than configured records it here."""
        atomic_write(self / self.CONFIG, config_text)

    def manifest(self) -> dict[str, Any]:
        """The manifest, or an empty one if it is missing or damaged (it only informs)."""
        try:
            manifest = read_json(self / self.MANIFEST, _MAX_TEXT)
        except InputFileError:
            return {}
        return manifest if isinstance(manifest, dict) else {}

    # -- checkpoint -----------------------------------------------------------------------------------------------------
    def genome_store(self, problem: Problem) -> GenomeStore | None:
        """The problem's genome store in this folder (:meth:`Problem.open_genome_store`), opened once."""
        if id(problem) not in self._stores:
            self._stores[id(problem)] = (problem, problem.open_genome_store(self.path))
        return self._stores[id(problem)][1]

    def save_checkpoint(self, state: RunState, problem: Problem | None = None) -> None:
        """Write the state; with a problem that has a genome store, its genomes go to the store (only those not
        there yet) and the checkpoint names them by key."""
        self._sync_metrics()  # a checkpoint never claims generations whose metrics a power cut could still take
        store = self.genome_store(problem) if problem is not None else None
        data = {"schema": CHECKPOINT_SCHEMA, "state": state}
        if store is None:
            atomic_write(self / self.CHECKPOINT, pickle.dumps(data))
            return
        buffer = io.BytesIO()
        _StorePickler(buffer, store).dump(data)
        store.flush()  # the genomes first: a checkpoint never names a key that was not written
        atomic_write(self / self.CHECKPOINT, buffer.getvalue())

    def load_checkpoint(self, genome_types: Collection[type] = (), problem: Problem | None = None) -> RunState:
        """The last checkpoint's state; ``genome_types`` are the problem's (:attr:`Problem.genome_types`), the only
        classes beyond the engine's own that the checkpoint may hold; ``problem``: its genome store, if it has one,
        gives back the genomes the checkpoint names by key."""
        path = self / self.CHECKPOINT
        if not path.exists() and not path.is_symlink():
            raise RunFolderError(f"{self.path}: no checkpoint yet")
        store = self.genome_store(problem) if problem is not None else None
        genomes = None if store is None else (lambda key: store.load([key])[0])
        try:
            data = checkpoint.loads(read_bytes(path, _MAX_STATE), genome_types, genomes)
        except InputFileError:
            raise
        except checkpoint.UnsafeCheckpointError as err:
            raise RunFolderError(f"{path}: refusing to load this checkpoint: {err}") from None
        except Exception as err:  # a checkpoint from another version, or a damaged file
            raise RunFolderError(f"{path}: cannot read the checkpoint ({type(err).__name__}: {err})") from None
        if not isinstance(data, dict) or data.get("schema") != CHECKPOINT_SCHEMA:
            raise RunFolderError(f"{path}: checkpoint format is not supported by this version")
        return data["state"]

    # -- metrics --------------------------------------------------------------------------------------------------------
    def append_metrics(self, row: dict[str, Any]) -> None:
        path = self / self.METRICS
        flags = os.O_WRONLY | os.O_APPEND | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
        try:
            descriptor = os.open(path, flags, 0o644)
        except OSError:
            if path.is_symlink():
                raise RunFolderError(f"{path}: is a symbolic link; refusing to write through it") from None
            raise
        with os.fdopen(descriptor, "a") as handle:
            handle.write(json.dumps(row) + "\n")
        # Not synced to disk here (a sync a generation cost a fortress run about 3 ms of its 40 while other work loaded
        # the machine): save_checkpoint syncs the rows before the checkpoint that covers them, and rows after the last
        # checkpoint are written again by a resume anyway.

    def _sync_metrics(self) -> None:
        try:
            descriptor = os.open(self / self.METRICS, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0))
        except FileNotFoundError:
            return
        try:
            os.fsync(descriptor)
        finally:
            os.close(descriptor)

    def metrics(self) -> list[dict[str, Any]]:
        """One dict per generation. A last line cut short by a kill is left out; damage anywhere else is an error
        naming the line."""
        path = self / self.METRICS
        if not path.exists():
            return []
        text = read_text(path, _MAX_TABLE, what="JSON lines")
        lines = text.split("\n")
        rows = []
        for number, line in enumerate(lines, start=1):
            if not line:
                continue
            try:
                row = parse_json(line, f"{path}, line {number}")
            except InputFileError:
                if number == len(lines):  # the unfinished last line of a killed run
                    break
                raise
            if not isinstance(row, dict) or not isinstance(row.get("generation"), int):
                raise InputFileError(f"{path}, line {number}: not a metrics row (an object with a 'generation')")
            rows.append(row)
        return rows

    def has_checkpoint(self) -> bool:
        path = self / self.CHECKPOINT
        return path.exists() or path.is_symlink()

    def truncate_metrics(self, generation: int) -> None:
        """Keep the rows up to ``generation``: those after the checkpoint will be recomputed."""
        rows = [row for row in self.metrics() if row["generation"] <= generation]
        atomic_write(self / self.METRICS, "".join(json.dumps(row) + "\n" for row in rows))

    # -- the best candidate ---------------------------------------------------------------------------------------------
    def write_best(self, best: Best, problem: Problem) -> None:
        folder = self / self.BEST
        if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
            raise RunFolderError(f"{folder}: is not a folder of this run (a symbolic link or a file); refusing to write there")
        folder.mkdir(exist_ok=True)
        if problem.flat:
            atomic_write(folder / "genome.npy", _npy_bytes(np.asarray(best.genome, dtype=np.float64)))
        else:
            atomic_write(folder / "genome.json", json.dumps(problem.genome_to_json(best.genome)) + "\n")
        summary = {
            "generation": best.generation,
            "objective": best.objective,
            "measures": dict(zip(problem.measure_names, best.measures)),
            "fields": best.fields,
        }
        atomic_write(folder / "best.json", json.dumps(summary, indent=2) + "\n")
        problem.write_artifacts(best.genome, folder)

    def best_genome(self, problem: Problem) -> Any:
        folder = self / self.BEST
        if problem.flat and (folder / "genome.npy").is_file():
            return self._vector(folder / "genome.npy", read_npy(folder / "genome.npy", _MAX_STATE), problem)
        if (folder / "genome.json").is_file():
            return self._from_json(folder / "genome.json", read_json(folder / "genome.json", _MAX_STATE), problem)
        raise RunFolderError(f"{self.path}: no best candidate yet")

    @staticmethod
    def _vector(source: Path, genome: np.ndarray, problem: Problem) -> np.ndarray:
        if genome.shape != (problem.n_params,) or not np.isfinite(genome).all():
            raise InputFileError(f"{source}: expected a genome of {problem.n_params} finite numbers, got shape {genome.shape}")
        return genome.astype(np.float64)

    @staticmethod
    def _from_json(source: str | Path, data: Any, problem: Problem) -> Any:
        try:
            return problem.genome_from_json(data)
        except (TypeError, ValueError, KeyError, IndexError) as err:
            raise InputFileError(f"{source}: not a genome of {problem.name} ({err})") from None

    # -- the quality-diversity archive ----------------------------------------------------------------------------------
    def write_archive(self, archive: Any, problem: Problem) -> None:
        """``archive.csv`` (index, objective, measures, the cell's coordinate along each measure as ``cell_<measure>``,
        threshold, the fields that are not also measures; sorted by cell index) and the genome of each row in the
        same order: ``archive_solutions.npy`` for flat genomes, ``archive_genomes.jsonl`` otherwise.

        The two files are replaced one after the other; a kill in between leaves them from different generations,
        which :meth:`archive_genome` detects (the next checkpoint of a resumed run rewrites both).
        """
        data = archive.data()
        order = np.argsort(data["index"], kind="stable")
        # A field that is also a measure (the structures' height) is written once, as the measure.
        fields = [name for name in problem.field_names if name not in problem.measure_names]
        measures = problem.measure_names
        cells = np.asarray(archive.int_to_grid_index(data["index"][order])).reshape(len(order), -1)
        columns = [("index", data["index"][order], int), ("objective", data["objective"][order], float)]
        columns += [(name, data["measures"][order, k], float) for k, name in enumerate(measures)]
        columns += [(f"cell_{name}", cells[:, k], int) for k, name in enumerate(measures)]
        columns += [("threshold", data["threshold"][order], float), *[(name, data[name][order], float) for name in fields]]
        lines = [",".join(name for name, _, _ in columns)]
        for r in range(len(order)):
            lines.append(",".join(repr(kind(values[r])) for _, values, kind in columns))
        solutions = data["solution"][order]
        store = None if problem.flat else self.genome_store(problem)
        if problem.flat:
            atomic_write(self / self.SOLUTIONS, _npy_bytes(np.asarray(solutions, dtype=np.float64)))
        elif store is not None:
            keys = np.asarray(store.keys(list(solutions)), dtype=np.int64)
            store.flush()
            atomic_write(self / self.GENOME_KEYS, _npy_bytes(keys))
            # A run of an older version, resumed: its JSON lines would now describe an older archive.
            (self / self.GENOMES).unlink(missing_ok=True)
        else:
            text = "".join(json.dumps(problem.genome_to_json(genome)) + "\n" for genome in solutions)
            atomic_write(self / self.GENOMES, text)
        atomic_write(self / self.ARCHIVE, "\n".join(lines) + "\n")

    def archive_rows(self) -> list[dict[str, str]]:
        """The rows of ``archive.csv`` as read (column name -> text), in file order; each names its cell by a
        whole-number ``index``."""
        path = self / self.ARCHIVE
        if not path.is_file():
            raise RunFolderError(f"{self.path}: this run has no archive (only quality-diversity runs keep one)")
        not_an_archive = f"{path}: not an archive (its first line should name the columns index, objective, ...)"
        reader = csv.DictReader(io.StringIO(read_text(path, _MAX_TABLE, what="CSV"), newline=""))
        try:
            if not reader.fieldnames or reader.fieldnames[:2] != ["index", "objective"]:
                raise InputFileError(not_an_archive)
            rows = list(reader)
        except csv.Error as err:  # Python 3.10's reader refuses NUL bytes, which later versions read as text
            raise InputFileError(f"{not_an_archive}: {err}") from None
        for number, row in enumerate(rows, start=2):
            if _cell_number(row.get("index")) is None:
                raise _not_a_cell(path, number, "index", row.get("index"))
        return rows

    def _genome_store(self, rows: list[dict[str, str]], problem: Problem) -> tuple[Path, Any] | None:
        """Where the rows' genomes are and their raw form (an array of vectors, or JSON lines), checked to hold one
        per row; None for an archive of structgen 0.1, which kept object genomes in a CSV column."""
        if rows and "genome" in rows[0]:
            return None
        store = None if problem.flat else self.genome_store(problem)
        if problem.flat:
            source = self / self.SOLUTIONS
            genomes: Any = read_npy(source, _MAX_STATE)
            if genomes.ndim != 2:
                raise InputFileError(f"{source}: expected one genome per row, got shape {genomes.shape}")
        elif store is not None and (self / self.GENOME_KEYS).is_file():
            source = self / self.GENOME_KEYS
            genomes = read_npy(source, _MAX_STATE)
            if genomes.ndim != 1 or genomes.dtype.kind not in "iu":
                raise InputFileError(f"{source}: expected one whole-number key per row, got {genomes.dtype} {genomes.shape}")
            genomes = _StoredGenomes(store, genomes)
        else:
            source = self / self.GENOMES
            genomes = read_text(source, _MAX_STATE, what="JSON lines").splitlines()
        if len(genomes) != len(rows):
            raise RunFolderError(
                f"{source}: holds {len(genomes)} genomes for the {len(rows)} rows of {self.ARCHIVE} (a write was cut "
                "short); resume the run to rewrite both"
            )
        return source, genomes

    def _genome_at(self, rows: list[dict[str, str]], store: tuple[Path, Any] | None, position: int, problem: Problem) -> Any:
        if store is None:
            where = f"{self / self.ARCHIVE}, line {position + 2}"
            return self._from_json(where, parse_json(rows[position]["genome"] or "", where), problem)
        source, genomes = store
        if problem.flat:
            return self._vector(source, genomes[position], problem)
        if isinstance(genomes, _StoredGenomes):
            return genomes.load([position])[0]
        where = f"{source}, line {position + 1}"
        return self._from_json(where, parse_json(genomes[position], where), problem)

    def archive_genome(self, index: int, problem: Problem) -> Any:
        """The genome of the archive elite in cell ``index`` (the ``index`` column of archive.csv)."""
        rows = self.archive_rows()
        cells = [int(row["index"]) for row in rows]
        if index not in cells:
            known = ", ".join(str(cell) for cell in cells[:10])
            raise RunFolderError(
                f"{self / self.ARCHIVE}: no elite in cell {index} (cells held: {known}{', ...' if len(rows) > 10 else ''})"
            )
        position = cells.index(index)
        return self._genome_at(rows, self._genome_store(rows, problem), position, problem)

    def load_archive(self, problem: Problem | None = None) -> Archive:
        """``archive.csv`` as arrays (see :class:`Archive`); with ``problem``, each elite's genome too."""
        rows = self.archive_rows()
        path = self / self.ARCHIVE
        names = list(rows[0]) if rows else read_text(path, _MAX_TABLE, what="CSV").split("\n", 1)[0].split(",")
        measures = tuple(name[len("cell_") :] for name in names if name.startswith("cell_") and name[len("cell_") :] in names)
        columns: dict[str, np.ndarray] = {}
        for name in names:
            if name == "genome":  # an archive of structgen 0.1 kept object genomes in a column
                continue
            whole = name == "index" or name.startswith("cell_")
            if whole:
                values: list[Any] = [_cell_number(row[name]) for row in rows]
                if None in values:
                    at = values.index(None)
                    raise _not_a_cell(path, at + 2, name, rows[at][name])
            else:
                try:
                    values = [float(row[name]) for row in rows]
                except (TypeError, ValueError):
                    raise InputFileError(f"{path}: column {name!r} holds a value that is not a number") from None
            columns[name] = np.array(values, dtype=np.int64 if whole else np.float64)
        genomes = None
        if problem is not None:
            genomes = self.archive_genomes(problem, rows)
            if problem.flat:
                genomes = np.asarray(genomes, dtype=np.float64).reshape(len(rows), problem.n_params)
        return Archive(columns, measures, genomes)

    def archive_genomes(self, problem: Problem, rows: list[dict[str, str]] | None = None) -> list[Any]:
        """The genome of every archive elite, in the order of ``rows`` (default: :meth:`archive_rows`)."""
        rows = self.archive_rows() if rows is None else rows
        store = self._genome_store(rows, problem)
        if store is not None and isinstance(store[1], _StoredGenomes):
            return store[1].load(range(len(rows)))
        return [self._genome_at(rows, store, position, problem) for position in range(len(rows))]
