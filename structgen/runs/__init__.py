"""Evolution runs from a checked configuration: start one, resume one, and take elites out of one.

These are the functions behind ``structgen evolve``, ``structgen resume`` and ``structgen export RUN_DIR``, for any
registered domain; scripts can call them directly::

    from structgen.runs.experiment import load_experiment
    from structgen.runs import evolve, resume

    folder, state = evolve(load_experiment("my.toml", overrides=["run.generations=50"]), "runs/mine")
    folder, state = resume("runs/mine", generations=80)

Each builds the problem once and the optimiser once (a resumed run's optimiser comes from its checkpoint).

:func:`load_run` opens a finished or running run for a look: its settings, metrics, best genome, archive and its
problem; :func:`run_summary` is what ``structgen info RUN_DIR`` prints.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import logging
import os
import sys
from collections.abc import Callable, Iterable
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from evolution import Archive, Problem, RunFolder, RunFolderError, RunState, advance, library_versions, make_evaluator
from evolution.files import MAX_WEIGHTS_BYTES, InputFileError, atomic_write, read_bytes
from evolution.optimizers import START_WORDS
from structgen import __version__, registry
from structgen.config import ConfigError, flatten
from structgen.runs.experiment import Experiment, load_experiment

__all__ = [
    "Run",
    "default_run_dir",
    "elite_genome",
    "evolve",
    "load_run",
    "manifest",
    "open_run",
    "other_run_kind",
    "read_best",
    "resume",
    "check_numbers",
    "run_summary",
    "summary_of",
]

log = logging.getLogger(__name__)
#: Libraries every run's manifest records; a domain adds its own (DomainSpec.libraries).
LIBRARIES = ("numpy", "scipy", "ribs", "cma", "matplotlib", "distributed")


def default_run_dir(experiment: Experiment) -> Path:
    """``runs/<domain group>-<optimizer>-s<seed>-<date>-<time>`` under the current folder, with ``-2``, ``-3``...
    added if a run started in the same second already has that name."""
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    name = f"{experiment.spec.group_name}-{experiment.optimizer_name}-s{experiment.run.seed}-{stamp}"
    path, n = Path("runs") / name, 1
    while path.exists():
        n += 1
        path = Path("runs") / f"{name}-{n}"
    return path


def _start_file(experiment: Experiment) -> tuple[str, bytes] | None:
    """(name of its copy in the run folder, contents) of the genome file the optimiser starts from, if it names one
    (``optimizer.x0``): the run keeps its own copy, so its start is known after the file moves or changes."""
    x0 = getattr(experiment.optimizer_settings, "x0", None)
    if not isinstance(x0, str) or x0 in START_WORDS:
        return None
    return "x0" + Path(x0).suffix.lower(), read_bytes(x0, MAX_WEIGHTS_BYTES)


def manifest(domain: str, libraries: Iterable[str], **extra: Any) -> dict[str, Any]:
    """What every run folder's ``manifest.json`` records: structgen's version, the domain, when and how the run was
    started, and the versions of the engine's libraries and of ``libraries``; ``extra`` adds to it (a search's
    ``run_kind``)."""
    return {
        "schema": 1,
        "structgen": __version__,
        "domain": domain,
        "created": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
        "argv": sys.argv,
        "versions": library_versions(list(dict.fromkeys([*LIBRARIES, *libraries]))),
        **extra,
    }


def _manifest(experiment: Experiment, start: tuple[str, bytes] | None) -> dict[str, Any]:
    extra = {}
    if start is not None:
        extra["x0"] = {
            "source": experiment.optimizer_settings.x0,
            "copy": start[0],
            "sha256": hashlib.sha256(start[1]).hexdigest(),
        }
    return manifest(experiment.domain, experiment.spec.libraries, **extra)


#: What one local worker process may hold: the interpreter, torch and a domain's problem (30 to 450 MiB measured).
WORKER_BYTES = 300 << 20


def check_workers(workers: int, cluster: str = "") -> None:
    """Refuse more local worker processes than this machine's available memory holds, before any starts."""
    if cluster or workers <= 0 or not hasattr(os, "sysconf"):
        return
    try:
        available = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError):  # not reported on this system
        return
    if workers * WORKER_BYTES > available:
        raise ConfigError(
            f"run.workers = {workers}: that many worker processes need about {workers * WORKER_BYTES >> 20:,} MiB, and "
            f"this machine has {available >> 20:,} MiB available; use fewer workers"
        )


def _advance(folder: RunFolder, experiment: Experiment, problem: Problem, state: RunState, **options: Any) -> RunState:
    timeout = experiment.run.evaluation_timeout or None
    with make_evaluator(experiment.run.workers, experiment.run.cluster, timeout) as evaluator:
        return advance(folder, problem, state, experiment.run, evaluator, **options)


def evolve(
    experiment: Experiment,
    run_dir: str | Path | None = None,
    *,
    overwrite: bool = False,
    progress: bool = True,
    stop_requested: Callable[[], bool] = lambda: False,
) -> tuple[RunFolder, RunState]:
    """Start a run in a new folder (default :func:`default_run_dir`) and carry it to ``experiment.run.generations``
    or until ``stop_requested()`` (checked after each generation, which is then checkpointed).

    A problem and optimiser that cannot work together fail (ConfigError) before the folder is made. A run that fails
    before any generation has ended leaves nothing behind (a folder the user made stays, empty); one that fails later
    keeps its folder, which ``resume`` continues (from the beginning if no checkpoint was written yet)."""
    check_workers(experiment.run.workers, experiment.run.cluster)
    problem = experiment.make_problem()
    try:
        optimizer = experiment.make_optimizer(problem)
        path = Path(run_dir or default_run_dir(experiment))
        made_here = not path.exists()
        start = _start_file(experiment)
        folder = RunFolder.create(path, experiment.to_toml(), _manifest(experiment, start), overwrite=overwrite)
        if start is not None:
            atomic_write(folder / start[0], start[1])
        state = _fresh_state(experiment, optimizer)
        try:
            with folder.locked():
                state = _advance(folder, experiment, problem, state, progress=progress, stop_requested=stop_requested)
        except BaseException:
            if not folder.has_checkpoint() and not _any_generation_ended(folder):
                folder.remove(keep_folder=not made_here)
            raise
        return folder, state
    finally:
        problem.close()


def _fresh_state(experiment: Experiment, optimizer: Any) -> RunState:
    return RunState(optimizer=optimizer, extra={"config": experiment.to_mapping()})


def _any_generation_ended(folder: RunFolder) -> bool:
    try:
        return bool(folder.metrics())
    except (InputFileError, RunFolderError):  # damaged rows: something ended
        return True


def other_run_kind(run_dir: str | Path) -> tuple[str, str] | None:
    """``(domain, kind)`` of a run folder that a domain wrote for a run of its own kind (a search, whose manifest
    names its ``run_kind``); None for an evolution run."""
    folder = RunFolder.open(run_dir)
    kind = folder.manifest().get("run_kind")
    if kind is None:
        return None
    domain = folder.manifest().get("domain")
    if not isinstance(kind, str) or not isinstance(domain, str):
        raise RunFolderError(f"{folder / RunFolder.MANIFEST}: run_kind {kind!r} of domain {domain!r} is not a run kind")
    return domain, kind


def describe_folder(run_dir: str | Path) -> tuple[dict[str, Any], str]:
    """``structgen info`` on a run folder of any domain: an evolution run's summary, or, for a run of a domain's own
    kind (its manifest names a ``run_kind``), what that domain says of it. A summary for ``--json`` and the text."""
    other = other_run_kind(run_dir)
    if other is not None:
        hooks = registry.spec(other[0]).command_hooks()
        if hooks is None:
            raise RunFolderError(f"{run_dir}: a {other[1]!r} run of the {other[0]} domain, which has no commands")
        return hooks.describe_run(other[1], Path(run_dir))
    summary = run_summary(run_dir)
    return summary, describe_run(summary)


def open_run(run_dir: str | Path) -> tuple[RunFolder, Experiment]:
    """An evolution run's folder and its configuration, checked (nothing is built)."""
    other = other_run_kind(run_dir)
    if other is not None:
        raise RunFolderError(
            f"{run_dir}: a {other[1]} run of the {other[0]} domain, not an evolution run (structgen info {run_dir} "
            "says what it holds)"
        )
    folder = RunFolder.open(run_dir)
    try:
        experiment = load_experiment(folder / RunFolder.CONFIG)
    except ConfigError as err:
        raise RunFolderError(str(err)) from None
    return folder, experiment


def resume(
    run_dir: str | Path,
    *,
    generations: int | None = None,
    workers: int | None = None,
    cluster: str | None = None,
    progress: bool = True,
    stop_requested: Callable[[], bool] = lambda: False,
) -> tuple[RunFolder, RunState]:
    """Continue a run from its last checkpoint up to ``generations`` in total (default: its configured number).

    The metrics of generations after the checkpoint are dropped and recomputed; the result is the same as if the
    run had never stopped. A run killed before its first checkpoint starts again from the beginning (same seed, same
    result). ``workers`` and ``cluster`` change only where evaluation happens, not its results.
    """
    folder, experiment = open_run(run_dir)
    with folder.locked():
        for leftover in folder.remove_temporary_files():
            log.info("removed %s, left by a write that was cut short", leftover)
        # The problem first: it says which genome classes its checkpoint may hold.
        problem = experiment.make_problem()
        try:
            if folder.has_checkpoint():
                state = folder.load_checkpoint(problem.genome_types, problem)
            else:
                # Killed before its first checkpoint: the run starts again, and ends as if it had never stopped.
                rows = folder.metrics()
                log.warning(
                    "%s: no checkpoint was written (%d generation%s recorded after none): starting again from the beginning",
                    folder.path,
                    len(rows),
                    "" if len(rows) == 1 else "s",
                )
                state = _fresh_state(experiment, experiment.make_optimizer(problem))
            _warn_on_new_versions(folder)
            experiment, edited = _reconcile(folder, experiment, state)
            if generations is not None:
                if generations < state.generation:
                    raise ConfigError(f"--generations {generations} is fewer than the {state.generation} already run")
                if generations != experiment.run.generations:
                    experiment = experiment.with_run(generations=generations)
                    state.extra["config"] = experiment.to_mapping()
                    edited = True
            recorded = experiment
            runtime = {k: v for k, v in (("workers", workers), ("cluster", cluster)) if v is not None}
            if runtime:
                experiment = experiment.with_run(**runtime)
            check_workers(experiment.run.workers, experiment.run.cluster)
            folder.truncate_metrics(state.generation)  # reads every row first: a damaged file refuses here
            if edited:  # only once nothing can refuse: a refused resume leaves config.toml as it was
                folder.write_config(recorded.to_toml())
            if state.generation >= experiment.run.generations:
                log.info("%s: already at generation %d of %d", folder.path, state.generation, experiment.run.generations)
                return folder, state
            log.info("%s: resuming after generation %d of %d", folder.path, state.generation, experiment.run.generations)
            state = _advance(folder, experiment, problem, state, progress=progress, stop_requested=stop_requested)
        finally:
            problem.close()
        return folder, state


#: Settings of a run that may change between sessions: they decide how long and where it runs, not its results.
EDITABLE = (
    "run.generations",
    "run.workers",
    "run.cluster",
    "run.checkpoint_every",
    "run.checkpoint_seconds",
    "run.plot_every",
    "run.evaluation_timeout",
)


def _reconcile(folder: RunFolder, experiment: Experiment, state: RunState) -> tuple[Experiment, bool]:
    """The configuration to resume with: config.toml, if it differs from what the run recorded only in settings
    that cannot change results (applied, and recorded in the state), and whether it was edited (the caller writes it
    back normalised once nothing can refuse); otherwise an error naming each changed setting."""
    current = experiment.to_mapping()
    recorded = state.extra.get("config")
    if recorded is None:  # a checkpoint from before runs recorded their configuration: the file is all there is
        state.extra["config"] = current
        return experiment, False
    before, after = flatten(recorded), flatten(current)
    # Settings only one side knows were added or removed by another version of structgen, not by an edit.
    changed = sorted(key for key in before.keys() & after.keys() if before[key] != after[key])
    fixed = [key for key in changed if key not in EDITABLE]
    if fixed:
        listing = "; ".join(f"{key} {before[key]!r} -> {after[key]!r}" for key in fixed)
        raise RunFolderError(
            f"{folder / RunFolder.CONFIG}: edited since the run began, in settings a run cannot change: {listing}. "
            f"Undo the edit to resume, or start a new run from it: structgen evolve {folder / RunFolder.CONFIG} "
            "--run-dir NEW"
        )
    if changed:
        if experiment.run.generations < state.generation:
            raise ConfigError(
                f"{folder / RunFolder.CONFIG}: run.generations = {experiment.run.generations} is fewer than the "
                f"{state.generation} already run"
            )
        log.info(
            "%s: applying edits: %s",
            folder / RunFolder.CONFIG,
            ", ".join(f"{key} {before[key]!r} -> {after[key]!r}" for key in changed),
        )
        state.extra["config"] = current
    return experiment, bool(changed)


def _warn_on_new_versions(folder: RunFolder) -> None:
    recorded = folder.manifest().get("versions", {})
    current = library_versions([name for name in recorded if name != "python"])
    changed = [f"{name} {recorded[name]} -> {current.get(name)}" for name in recorded if recorded[name] != current.get(name)]
    if changed:
        log.warning("library versions differ from when this run started (%s); results may differ", ", ".join(changed))


def elite_genome(folder: RunFolder, problem: Problem, elite: str) -> Any:
    """The genome named by ``elite``: ``"best"`` (best seen) or ``"index:I"`` (the archive's elite in cell I)."""
    if elite == "best":
        return folder.best_genome(problem)
    kind, _, value = elite.partition(":")
    # Cell indices are whole numbers of at most ten digits (pyribs counts cells in 32 bits): a longer one names no
    # cell, and Python refuses to read 5,000 digits as a number.
    if kind != "index" or not value.lstrip("-").isdigit() or len(value) > 11:
        shown = elite if len(elite) <= 40 else f"{elite[:30]}... ({len(elite):,} characters)"
        raise ConfigError(f"--elite {shown!r}: use 'best' or 'index:I' with I a cell index from archive.csv")
    genome = folder.archive_genome(int(value), problem)
    return np.asarray(genome) if problem.flat else genome


class Run:
    """A run folder opened for a look (nothing is resumed or written). The problem is built on first use (it may
    load torch or a physics engine); ``close()`` or a ``with`` block releases it.

    >>> run = load_run("runs/structures")                                # doctest: +SKIP
    >>> archive, genome = run.archive(), run.best_genome()               # doctest: +SKIP
    """

    def __init__(self, run_dir: str | Path) -> None:
        self.folder, self.experiment = open_run(run_dir)

    @property
    def path(self) -> Path:
        return self.folder.path

    @cached_property
    def problem(self) -> Problem:
        return self.experiment.make_problem()

    def metrics(self) -> list[dict[str, Any]]:
        """One dict per finished generation (``metrics.jsonl``)."""
        return self.folder.metrics()

    def best_genome(self) -> Any:
        return elite_genome(self.folder, self.problem, "best")

    def archive(self, genomes: bool = True) -> Archive:
        """The quality-diversity archive (``archive.csv``), with each elite's genome unless ``genomes`` is False."""
        return self.folder.load_archive(self.problem if genomes else None)

    def best_nca(self) -> Any:
        """Deprecated (goes in structgen 0.4): ``run.problem.nca(run.best_genome())`` in the structures domain."""
        import warnings

        warnings.warn(
            "Run.best_nca() is deprecated: use run.problem.nca(run.best_genome()) (structures runs)",
            DeprecationWarning,
            stacklevel=2,
        )
        nca = getattr(self.problem, "nca", None)
        if nca is None:
            raise RunFolderError(f"{self.path}: a run of the {self.experiment.domain} domain has no NCA of the structures kind")
        return nca(self.best_genome())

    def close(self) -> None:
        problem = self.__dict__.pop("problem", None)
        if problem is not None:
            problem.close()

    def __enter__(self) -> Run:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def load_run(run_dir: str | Path) -> Run:
    """Open the run in ``run_dir`` for a look: ``run.metrics()``, ``run.best_genome()``, ``run.archive()``,
    and ``run.problem`` (the domain's problem, whose own methods decode a genome: ``run.problem.nca(genome)`` in the
    structures domain). A folder that is not a run is a :class:`~evolution.RunFolderError`."""
    return Run(run_dir)


def run_summary(run_dir: str | Path) -> dict[str, Any]:
    """What a run is and how far it got, from its files alone (no problem is built): settings, progress, the best
    candidate and, for quality diversity, the archive's size, coverage and QD score."""
    folder, experiment = open_run(run_dir)
    return summary_of(folder, experiment, folder.metrics())


def check_numbers(source: str | Path, rows: list[dict[str, Any]], names: tuple[str, ...], *, lines: bool = True) -> None:
    """Every row holds these keys (where present) as finite numbers, or an InputFileError names the file, the row
    and the key: a damaged or edited file is refused, not formatted into a traceback."""
    import math

    for number, row in enumerate(rows, start=1):
        for name in names:
            value = row.get(name, 0)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                where = f"{source}, line {number}" if lines else str(source)
                raise InputFileError(f"{where}: {name} = {value!r} is not a finite number")


def read_best(path: str | Path) -> dict[str, Any]:
    """A ``best.json`` (a run's best candidate, or one kept at a spawn), checked: a JSON object whose objective and
    generation are finite numbers and whose measures and fields are objects of them; anything else is an
    InputFileError naming the file and the field."""
    from evolution.files import read_json

    best = read_json(path, 1 << 24)
    if not isinstance(best, dict):
        raise InputFileError(f"{path}: not a best candidate's summary (a JSON object), but {type(best).__name__}")
    check_numbers(path, [best], ("objective", "generation"), lines=False)
    for key in ("measures", "fields"):
        values = best.get(key) or {}
        if not isinstance(values, dict):
            raise InputFileError(f"{path}: {key} must be an object of numbers")
        check_numbers(f"{path}, {key}", [values], tuple(values), lines=False)
    return best


def summary_of(folder: RunFolder, experiment: Experiment, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """:func:`run_summary` of a run already opened, with its metrics already read."""
    manifest = folder.manifest()
    numbers = ("generation", "evaluations", "best_objective", "wall_s", "qd_score", "coverage", "num_elites")
    check_numbers(folder / RunFolder.METRICS, rows, numbers)
    last = rows[-1] if rows else {}
    summary: dict[str, Any] = {
        "run": str(folder.path),
        "domain": experiment.domain,
        "optimizer": experiment.optimizer_name,
        "seed": experiment.run.seed,
        "generations": last.get("generation", 0),
        "generations_configured": experiment.run.generations,
        "evaluations": last.get("evaluations", 0),
        "wall_s": last.get("wall_s"),
        "created": manifest.get("created"),
        "structgen": manifest.get("structgen"),
    }
    best_file = folder / RunFolder.BEST / "best.json"
    if best_file.is_file():
        best = read_best(best_file)
        summary["best"] = {key: best.get(key) for key in ("objective", "generation", "measures", "fields")}
    if "qd_score" in last:
        summary["archive"] = {"elites": last.get("num_elites"), "coverage": last["coverage"], "qd_score": last["qd_score"]}
    summary["files"] = sorted(p.name + ("/" if p.is_dir() else "") for p in folder.path.iterdir() if not p.name.startswith("."))
    return summary


def describe_run(summary: dict[str, Any]) -> str:
    """:func:`run_summary` as aligned lines of text."""
    done, planned = summary["generations"], summary["generations_configured"]
    wall = summary.get("wall_s")
    rows = [
        ("run", summary["run"]),
        ("domain", summary["domain"]),
        ("optimizer", f"{summary['optimizer']}, seed {summary['seed']}"),
        (
            "progress",
            f"{done} of {planned} generations, {summary['evaluations']:,} evaluations"
            + (f", {wall:.1f} s" if isinstance(wall, (int, float)) else "")
            + ("" if done >= planned else " (resume to go on)"),
        ),
        ("created", f"{summary.get('created') or '?'} by structgen {summary.get('structgen') or '?'}"),
    ]
    best = summary.get("best")
    if best:
        rows.append(("best", f"objective {best['objective']:g} (generation {best['generation']})"))
        measures = best.get("measures") or {}
        if measures:
            rows.append(("  measures", ", ".join(f"{k} {v:g}" for k, v in measures.items())))
        fields = best.get("fields") or {}
        if fields:
            rows.append(("  fields", ", ".join(f"{k} {v:g}" for k, v in fields.items())))
    archive = summary.get("archive")
    if archive:
        rows.append(
            ("archive", f"{archive['elites']:,} elites, coverage {archive['coverage']:.1%}, QD score {archive['qd_score']:.4g}")
        )
    rows.append(("files", ", ".join(summary["files"])))
    return "\n".join(f"{name:<11} {value}" for name, value in rows)
