"""Run configurations: a TOML file (or the built-in main job) plus ``--set`` overrides, checked before any work.

A configuration has three tables::

    [run]                 # evolution.RunSettings: generations, seed, checkpoint_every, workers, cluster, plot_every
    [problem]             # name = "structures" (default), "sphere" or "ones", then that problem's settings
    [optimizer]           # name = "ga" (default), "cma_es", "map_elites" or "cma_mae", then its settings

Unknown tables or keys, values of the wrong type, and unknown problem or optimizer names fail with a message that
names the key. The resolved configuration (every setting spelled out) is what a run folder's ``config.toml`` holds,
and ``structgen resume`` reads nothing else.
"""

from __future__ import annotations

import copy
import os
import sys
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

from evolution import OPTIMIZERS, Problem, RunSettings
from evolution.toys import Ones, OnesSettings, Sphere, SphereSettings
from structgen.config import ConfigError, build, parse_assignment
from structgen.domains import structures

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["MAIN_JOB", "PROBLEMS", "Experiment", "ProblemEntry", "load_experiment"]


@dataclass(frozen=True)
class ProblemEntry:
    """A problem by name: how to read its settings from a table, write them back, and build it."""

    read: Callable[[dict[str, Any], str], Any]
    write: Callable[[Any], dict[str, Any]]
    make: Callable[[Any], Problem]
    summary: str


def _plain(settings_type: type) -> tuple[Callable[[dict[str, Any], str], Any], Callable[[Any], dict[str, Any]]]:
    return (lambda table, where: build(settings_type, table, where)), asdict


def _read_structures(table: dict[str, Any], where: str) -> structures.StructuresSettings:
    unknown = sorted(set(table) - {"init_scale", "evaluator", "nca", "physics"})
    if unknown:
        raise ConfigError(
            f"unknown setting '{where}.{unknown[0]}'; {where} has: init_scale, evaluator, nca (table), physics (table)"
        )
    return structures.settings_from_table(table, where)


PROBLEMS: dict[str, ProblemEntry] = {
    "structures": ProblemEntry(
        _read_structures, structures.settings_to_table, structures.StableStructures, "NCA-grown structures judged by physics"
    ),
    "sphere": ProblemEntry(*_plain(SphereSettings), Sphere, "continuous toy problem (no physics)"),
    "ones": ProblemEntry(*_plain(OnesSettings), Ones, "discrete toy problem with its own mutation (no physics)"),
}


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


# The README's main job: the paper's setup (local NCA, cutoff 0.5, five steps, building down allowed, the elitist
# GA keeping a fifth of the population) scaled to finish in a few minutes on two cores: a population of 40, a vertex
# cap of 64, the fast physics preset.
MAIN_JOB: dict[str, Any] = {
    "run": {"generations": 30, "seed": 0, "checkpoint_every": 1, "workers": min(_cpus(), 8)},
    "problem": {"name": "structures"},
    "optimizer": {"name": "ga"},
}
# Sizes for each optimiser in the main job, so that switching with --optimizer keeps a comparable budget.
MAIN_JOB_OPTIMIZERS: dict[str, dict[str, Any]] = {
    "ga": {"population": 40, "parents": 8},
    "cma_es": {"population": 40},
    "map_elites": {"batch_size": 40, "cells": [11, 32]},
    "cma_mae": {"emitters": 4, "batch_size": 10, "cells": [11, 32]},
}


@dataclass(frozen=True)
class Experiment:
    """A checked run configuration."""

    run: RunSettings
    problem_name: str
    problem_settings: Any
    optimizer_name: str
    optimizer_settings: Any

    def make_problem(self) -> Problem:
        return PROBLEMS[self.problem_name].make(self.problem_settings)

    def to_mapping(self) -> dict[str, Any]:
        """The resolved configuration as nested tables."""
        optimizer = {name: list(v) if isinstance(v, tuple) else v for name, v in asdict(self.optimizer_settings).items()}
        return {
            "run": asdict(self.run),
            "problem": {"name": self.problem_name, **PROBLEMS[self.problem_name].write(self.problem_settings)},
            "optimizer": {"name": self.optimizer_name, **optimizer},
        }

    def to_toml(self) -> str:
        import tomli_w

        header = "# Resolved configuration of this run: every setting, as used. `structgen resume` reads this file.\n"
        return header + tomli_w.dumps(_toml_safe(self.to_mapping()))

    def with_run(self, **changes: Any) -> Experiment:
        try:
            return Experiment(RunSettings(**{**asdict(self.run), **changes}), *self._rest())
        except ValueError as err:
            raise ConfigError(str(err)) from None

    def _rest(self) -> tuple[Any, ...]:
        return self.problem_name, self.problem_settings, self.optimizer_name, self.optimizer_settings


def _toml_safe(value: Any) -> Any:
    """TOML has no null: leave None out; infinities are written as TOML's inf."""
    if isinstance(value, dict):
        return {k: _toml_safe(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_toml_safe(v) for v in value]
    return value


def _set_path(tables: dict[str, Any], key: str, value: Any) -> None:
    """Put ``value`` at a dotted path like ``problem.nca.cutoff``."""
    *parents, last = key.split(".")
    if not parents:
        raise ConfigError(f"--set {key}: name the table too, e.g. run.{key} or optimizer.{key}")
    node = tables
    for i, part in enumerate(parents):
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ConfigError(f"--set {key}: {'.'.join(parents[: i + 1])} is a value, not a table")
        node = child
    node[last] = value


def _table(tables: Mapping[str, Any], name: str, source: str) -> dict[str, Any]:
    value = tables.get(name, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{source}{name} must be a table, got {value!r}")
    return dict(value)


def load_experiment(
    path: str | os.PathLike | None = None,
    *,
    overrides: Iterable[str] = (),
    optimizer: str | None = None,
    run_changes: Mapping[str, Any] | None = None,
) -> Experiment:
    """Read a configuration (``path``, or the built-in main job if None), apply ``--set`` overrides, an optimiser
    switch and run-setting shortcuts, and check everything. Raises ConfigError naming the file and key at fault."""
    source = f"{path}: " if path else ""
    if path is None:
        tables = copy.deepcopy(MAIN_JOB)
    else:
        try:
            text = open(path, "rb").read().decode("utf-8")
        except UnicodeDecodeError:
            raise ConfigError(f"{path}: not a text file (expected TOML)") from None
        try:
            tables = tomllib.loads(text)
        except tomllib.TOMLDecodeError as err:
            raise ConfigError(f"{path}: not valid TOML ({err})") from None
    if optimizer is not None:
        _set_path(tables, "optimizer.name", optimizer)
    for text in overrides:
        key, value = parse_assignment(text)
        _set_path(tables, key, value)
    for key, value in (run_changes or {}).items():
        if value is not None:
            _set_path(tables, f"run.{key}", value)
    unknown = sorted(set(tables) - {"run", "problem", "optimizer"})
    if unknown:
        raise ConfigError(f"{source}unknown table [{unknown[0]}]; a configuration has [run], [problem] and [optimizer]")
    if path is None:  # the main job's size for the chosen optimiser, under whatever was set explicitly
        chosen = _table(tables, "optimizer", source)
        tables["optimizer"] = {**MAIN_JOB_OPTIMIZERS.get(chosen.get("name", "ga"), {}), **chosen}

    run = build(RunSettings, _table(tables, "run", source), "run")
    problem_table = _table(tables, "problem", source)
    problem_name = problem_table.pop("name", "structures")
    if problem_name not in PROBLEMS:
        raise ConfigError(f"{source}unknown problem.name {problem_name!r}; choose one of {', '.join(PROBLEMS)}")
    problem_settings = PROBLEMS[problem_name].read(problem_table, "problem")
    optimizer_table = _table(tables, "optimizer", source)
    optimizer_name = optimizer_table.pop("name", "ga")
    if optimizer_name not in OPTIMIZERS:
        raise ConfigError(f"{source}unknown optimizer.name {optimizer_name!r}; choose one of {', '.join(OPTIMIZERS)}")
    optimizer_settings = build(OPTIMIZERS[optimizer_name].settings, optimizer_table, "optimizer")
    experiment = Experiment(run, problem_name, problem_settings, optimizer_name, optimizer_settings)
    _check_combination(experiment, source)
    return experiment


def _check_combination(experiment: Experiment, source: str) -> None:
    """Problems and optimisers that cannot work together fail here, before a run folder exists."""
    from evolution import make_optimizer

    problem = experiment.make_problem()
    try:
        make_optimizer(experiment.optimizer_name, problem, experiment.optimizer_settings, seed=0)
    except ValueError as err:
        raise ConfigError(f"{source}{err}") from None
    finally:
        problem.close()
