"""The run loop: ask, evaluate, tell, record; checkpoint between generations; stop cleanly on Ctrl-C.

What a run leaves behind, and how each file is written, is :mod:`evolution.runfolder`.

Determinism: all randomness lives in the optimiser (pickled) or is derived from ``(seed, generation)``, and
evaluation is a pure function of genome and seed, so a run interrupted at any point and resumed from its checkpoint
ends exactly like one that never stopped.
"""

from __future__ import annotations

import contextlib
import logging
import math
import signal
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from evolution.evaluators import Evaluator
from evolution.optimizers import Optimizer
from evolution.plots import write_plots
from evolution.problem import Evaluation, Problem

# Best and RunState are defined with the format they are saved in; they are named here too because checkpoints
# written by structgen 0.1 refer to them as evolution.run.Best and evolution.run.RunState.
from evolution.runfolder import Best, RunFolder, RunFolderError, RunState, library_versions

__all__ = [
    "Best",
    "RunFolder",
    "RUN_CONDITIONS",
    "comparable_metrics",
    "RunFolderError",
    "RunSettings",
    "RunState",
    "advance",
    "graceful_interrupt",
    "library_versions",
]

log = logging.getLogger(__name__)

#: Fields of a metrics row that say how a generation ran (its wall time, its local evaluation processes), not what it
#: found: runs of the same seed and configuration agree on everything else.
RUN_CONDITIONS = ("wall_s", "workers")


def comparable_metrics(rows: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Metrics rows without the :data:`RUN_CONDITIONS`: what two runs of one seed and configuration must agree on."""
    return [{k: v for k, v in row.items() if k not in RUN_CONDITIONS} for row in rows]


@dataclass(frozen=True)
class RunSettings:
    """How long and where a run goes.

    Attributes:
        generations: generations to run in total (``resume --generations`` can raise it).
        seed: the run's seed; the same seed and configuration give the same run.
        checkpoint_every: write a checkpoint (and the best candidate, and the archive) every this many generations;
            the last generation and an interrupted one are always checkpointed.
        checkpoint_seconds: also write one at the end of a generation when this many seconds of the run have passed
            since the last (0: only by ``checkpoint_every``), so a crash loses minutes, not hours, of a run whose
            generations are long or whose ``checkpoint_every`` is large; at least nine times as long as the last
            checkpoint took, so that checkpoints of a large run cost at most about a tenth of it.
        workers: local evaluation processes; 0 evaluates in the main process.
        cluster: address of a Dask scheduler; when set, evaluation goes there instead of local processes.
        plot_every: redraw the plots every this many generations (and always at the end).
        evaluation_timeout: seconds one candidate may take in a worker process before the worker is taken for hung
            and replaced (its candidates are tried once more, then scored as failed); 0 for no limit.
    """

    generations: int = 20
    seed: int = 0
    checkpoint_every: int = 1
    checkpoint_seconds: float = 60.0
    workers: int = 2
    cluster: str = ""
    plot_every: int = 10
    evaluation_timeout: float = 600.0

    def __post_init__(self) -> None:
        def whole(name: str, low: int, high: int) -> None:
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
                raise ValueError(f"run {name} must be a whole number from {low:,} to {high:,}, got {value!r}")

        for name in ("generations", "checkpoint_every", "plot_every"):
            whole(name, 1, 10**9)
        whole("workers", 0, 1024)
        whole("seed", 0, 2**63 - 1)
        for name in ("evaluation_timeout", "checkpoint_seconds"):
            seconds = getattr(self, name)
            if not isinstance(seconds, (int, float)) or isinstance(seconds, bool) or not 0 <= seconds < math.inf:
                raise ValueError(f"run {name} must be a number of seconds, 0 for no limit, got {seconds!r}")


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
    row.update({f"generation_mean_{name}": float(np.mean(evaluation.fields[name])) for name in problem.mean_fields})
    if optimizer.archive is not None:
        stats = optimizer.archive.stats
        row.update(
            {
                "qd_score": float(stats.qd_score),
                "coverage": float(stats.coverage),
                "num_elites": int(stats.num_elites),
            }
        )
    failed = int(evaluation.failed.sum())
    if failed:  # candidates that could not be evaluated at all (see PoolEvaluator); absent when there are none
        row["failed_evaluations"] = failed
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
    until = settings.generations if until is None else until
    optimizer = state.optimizer
    optimizer.attach(problem)
    bar = _progress_bar(state.generation, until) if progress else None
    last_checkpoint = time.monotonic()  # a session starts from a checkpoint (or from nothing to lose)
    # A checkpoint on the clock waits at least nine times as long as the last one took, so writing large run
    # folders never takes more than about a tenth of a run.
    wait = settings.checkpoint_seconds
    try:
        while state.generation < until:
            started = time.perf_counter()
            schedule = state.extra.get("schedule")
            if schedule is None:
                schedule = problem.initial_schedule()
            genomes = problem.prepare(optimizer.ask(), schedule)
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
            if schedule:
                state.extra["schedule"] = problem.next_schedule(schedule, state.best.objective)
            problem.record(folder.path, state.generation, genomes, evaluation)
            state.elapsed += time.perf_counter() - started
            metrics = _metrics_row(state, evaluation, optimizer, problem)
            metrics.update({f"schedule_{name}": value for name, value in schedule.items()})
            if not settings.cluster:  # cost per structure needs the cores a generation ran on (resumes may differ)
                metrics["workers"] = settings.workers
            folder.append_metrics(metrics)
            stopping = stop_requested()
            last = state.generation >= until or stopping
            overdue = settings.checkpoint_seconds > 0 and time.monotonic() - last_checkpoint >= wait
            if state.generation % settings.checkpoint_every == 0 or last or overdue:
                began = time.monotonic()
                _checkpoint(folder, problem, state)
                last_checkpoint = time.monotonic()
                wait = max(settings.checkpoint_seconds, 9 * (last_checkpoint - began))
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
    folder.save_checkpoint(state, problem)


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
