"""Run configurations: a TOML file (or a domain's main job) plus ``--set`` overrides, checked before any work.

A configuration has three tables::

    [run]                 # evolution.RunSettings: generations, seed, checkpoint_every, workers, cluster, plot_every
    [problem]             # name = a registered domain ("structures-v0" if absent), then that domain's settings
    [optimizer]           # name = "ga" (if absent), "cma_es", "map_elites" or "cma_mae", then its settings

Unknown tables or keys, values of the wrong type, and unknown domain or optimiser names fail with a message that
names the key. Loading builds nothing: :meth:`Experiment.make_problem` and :meth:`Experiment.make_optimizer` do, once,
when a command needs them. The resolved configuration (every setting spelled out) is what a run folder's
``config.toml`` holds, and ``structgen resume`` reads nothing else.
"""

from __future__ import annotations

import copy
import os
import sys
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import Any

from evolution import DEFAULT_OPTIMIZER, OPTIMIZERS, Optimizer, Problem, RunSettings, make_optimizer
from evolution.files import InputFileError, MiB, read_text
from structgen import registry
from structgen.config import ConfigError, build, parse_assignment, resolve_key, set_path, setting_paths, to_table

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["Experiment", "load_experiment", "main_job_tables", "parse_toml"]

TABLES = ("run", "problem", "optimizer")


@dataclass(frozen=True)
class Experiment:
    """A checked run configuration: run settings, a domain and its settings, an optimiser and its settings."""

    run: RunSettings
    domain: str
    problem_settings: Any
    optimizer_name: str
    optimizer_settings: Any

    @property
    def spec(self) -> registry.DomainSpec:
        return registry.spec(self.domain)

    def make_problem(self) -> Problem:
        """The domain's problem with these settings (close it when done)."""
        return self.spec.make(self.problem_settings)

    def make_optimizer(self, problem: Problem) -> Optimizer:
        """The optimiser, seeded with the run's seed; a combination that cannot work is a ConfigError, and archives
        beyond the memory budget are refused before they are allocated."""
        cells = getattr(self.optimizer_settings, "cells", None)
        if cells is not None:
            from evolution.qd import archive_bytes
            from structgen.budget import check_memory

            archives = 2 if getattr(self.optimizer_settings, "result_archive", False) else 1
            shape = " x ".join(f"{int(c):,}" for c in cells)
            check_memory(archive_bytes(problem, tuple(cells), archives), f"optimizer cells = [{shape}] for {problem.name}")
        try:
            return make_optimizer(self.optimizer_name, problem, self.optimizer_settings, self.run.seed)
        except ValueError as err:
            raise ConfigError(str(err)) from None

    def to_mapping(self) -> dict[str, Any]:
        """The resolved configuration as nested tables."""
        return {
            "run": to_table(self.run),
            "problem": {"name": self.domain, **to_table(self.problem_settings)},
            "optimizer": {"name": self.optimizer_name, **to_table(self.optimizer_settings)},
        }

    def to_toml(self) -> str:
        import tomli_w

        header = "# Resolved configuration of this run: every setting, as used. `structgen resume` reads this file.\n"
        return header + tomli_w.dumps(self.to_mapping())

    def with_run(self, **changes: Any) -> Experiment:
        try:
            run = RunSettings(**{**asdict(self.run), **changes})
        except ValueError as err:
            raise ConfigError(str(err)) from None
        return Experiment(run, self.domain, self.problem_settings, self.optimizer_name, self.optimizer_settings)


def _cpus() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


def main_job_tables(domain: str) -> dict[str, Any]:
    """The tables of a domain's main job, before its per-optimiser sizes (which follow the optimiser chosen)."""
    job = registry.spec(domain).main_job
    return {
        "run": {"workers": min(_cpus(), 8), **copy.deepcopy(dict(job.run))},
        "problem": {"name": registry.spec(domain).id, **copy.deepcopy(dict(job.problem))},
        "optimizer": {"name": job.optimizer},
    }


#: Configuration files larger than this are refused before they are read.
MAX_CONFIG_BYTES = 16 * MiB


def _read_file(path: str | os.PathLike) -> dict[str, Any]:
    try:
        text = read_text(path, MAX_CONFIG_BYTES, what="TOML")
    except InputFileError as err:
        raise ConfigError(str(err)) from None
    return parse_toml(text, path)


def parse_toml(text: str, source: str | os.PathLike) -> dict[str, Any]:
    """The tables of a configuration's text; ``source`` names it in the error when it is not TOML."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{source}: not valid TOML ({err})") from None
    except RecursionError:
        raise ConfigError(f"{source}: not valid TOML (nested too deeply)") from None
    except ValueError as err:  # a whole number of more than 4,300 digits
        raise ConfigError(f"{source}: not valid TOML ({err})") from None


def _table(tables: Mapping[str, Any], name: str, source: str) -> dict[str, Any]:
    value = tables.get(name, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{source}{name} must be a table, got {value!r}")
    return dict(value)


def _name(table: dict[str, Any], default: str, where: str) -> str:
    name = table.get("name", default)
    if not isinstance(name, str):
        raise ConfigError(f"{where}.name = {name!r}: expected a string")
    return name


NAMES = ("problem.name", "optimizer.name")


def load_experiment(
    path: str | os.PathLike | None = None,
    *,
    domain: str | None = None,
    overrides: Iterable[str | tuple[str, Any]] = (),
    optimizer: str | None = None,
    run_changes: Mapping[str, Any] | None = None,
) -> Experiment:
    """Read a configuration and check it, building nothing.

    ``path`` is a TOML file; without one, the main job of ``domain`` (default: the default domain). ``domain`` and
    ``optimizer`` set ``problem.name`` and ``optimizer.name``; ``overrides`` are ``--set`` assignments (texts or
    ``(key, value)`` pairs, keys as in :func:`structgen.config.resolve_key`); ``run_changes`` set ``[run]``
    settings (None values are ignored). Raises ConfigError naming the file and key at fault.

    In order: the tables are read (:func:`_source_tables`); the names choose the domain and the optimiser, whose
    settings classes the other keys are resolved against (:func:`_choose`); the assignments are written into the
    tables; the three settings objects are built from them, an error naming where its value came from.
    """
    source = f"{path}: " if path else ""
    assignments = [parse_assignment(item) if isinstance(item, str) else item for item in overrides]
    changes = [(f"run.{key}", value) for key, value in (run_changes or {}).items() if value is not None]
    tables = _source_tables(path, domain or dict(assignments).get("problem.name"), source)
    if path is not None and domain is not None:
        _check_domain(tables, domain, source)
    written_for = _name(_table(tables, "optimizer", source), DEFAULT_OPTIMIZER, "optimizer") if path else None
    names = [(name, value) for name, value in zip(NAMES, (domain, optimizer)) if value is not None]
    spec, optimizer_name = _choose(tables, [*names, *((k, v) for k, v in assignments if k in NAMES)], source)
    settings_type, optimizer_type = spec.settings_type(), OPTIMIZERS[optimizer_name].settings
    paths = [
        *TABLES,
        *NAMES,
        *setting_paths(RunSettings, "run."),
        *setting_paths(settings_type, "problem."),
        *setting_paths(optimizer_type, "optimizer."),
    ]
    given = [(resolve_key(key, paths, TABLES), value) for key, value in assignments if key not in NAMES] + changes
    for key, value in given:
        set_path(tables, key, value)
    tables = {name: _table(tables, name, source) for name in TABLES}  # a --set may have put a value there
    if path is None:  # the main job's size for the chosen optimiser, under whatever was set explicitly
        written_for = spec.main_job.optimizer
        sizes = spec.main_job.optimizers.get(optimizer_name if optimizer_name != "random" else written_for, {})
        tables["optimizer"] = {**copy.deepcopy(dict(sizes)), **tables["optimizer"]}
    for name in ("problem", "optimizer"):
        tables[name].pop("name", None)
    if optimizer_name == "random" and written_for in OPTIMIZERS and written_for != "random":
        set_here = {key.removeprefix("optimizer.") for key, _ in given if key.startswith("optimizer.")}
        tables["optimizer"] = _random_counterpart(tables["optimizer"], written_for, set_here, path)
    try:
        run = build(RunSettings, tables["run"], "run")
        problem_settings = build(settings_type, tables["problem"], "problem")
        optimizer_settings = build(optimizer_type, tables["optimizer"], "optimizer")
    except ConfigError as err:
        raise _attributed(err, path, [key for key, _ in given]) from None
    return Experiment(run, spec.id, problem_settings, optimizer_name, optimizer_settings)


def _random_counterpart(table: dict[str, Any], written_for: str, set_here: set[str], path: Any) -> dict[str, Any]:
    """The ``[optimizer]`` table of random search at the budget of the optimiser the configuration was written for:
    as many evaluations each generation and the same archive cells (``RandomSettings`` via the settings'
    ``random_counterpart``); settings given with ``--set`` for random search itself are kept."""
    theirs = {key: value for key, value in table.items() if key not in set_here}
    try:
        counterpart = build(OPTIMIZERS[written_for].settings, theirs, "optimizer").random_counterpart()
    except ConfigError as err:
        raise _attributed(err, path, []) from None
    ours = {key: list(value) if isinstance(value, tuple) else value for key, value in asdict(counterpart).items()}
    return {**ours, **{key: table[key] for key in set_here if key in table}}


def _source_tables(path: str | os.PathLike | None, domain: str | None, source: str) -> dict[str, Any]:
    """The tables of the configuration file, or of the main job of ``domain`` when there is no file."""
    if path is None:
        try:
            tables = main_job_tables(domain or registry.DEFAULT_DOMAIN)
        except registry.UnknownDomainError as err:
            raise ConfigError(str(err)) from None
    else:
        tables = _read_file(path)
    unknown = sorted(set(tables) - set(TABLES))
    if unknown:
        raise ConfigError(f"{source}unknown table [{unknown[0]}]; a configuration has [run], [problem] and [optimizer]")
    return tables


def _check_domain(tables: dict[str, Any], domain: str, source: str) -> None:
    """A file run as a domain's (``structgen <group> evolve FILE``) must be that domain's configuration."""
    named_in_file = _table(tables, "problem", source).get("name", registry.DEFAULT_DOMAIN)
    try:
        same = registry.spec(str(named_in_file)).id == registry.spec(domain).id
    except registry.UnknownDomainError:
        same = False
    if not same:
        raise ConfigError(f"{source}a configuration of the {named_in_file} domain, not of {domain}")


def _choose(tables: dict[str, Any], names: list[tuple[str, Any]], source: str) -> tuple[registry.DomainSpec, str]:
    """The domain and the optimiser, with the names given (options, then ``--set``) written into ``tables``."""
    for key, value in names:
        set_path(tables, key, value)
    try:
        spec = registry.spec(_name(_table(tables, "problem", source), registry.DEFAULT_DOMAIN, "problem"))
    except registry.UnknownDomainError as err:
        raise ConfigError(f"{source}problem.name: {err}") from None
    optimizer_name = _name(_table(tables, "optimizer", source), DEFAULT_OPTIMIZER, "optimizer")
    if optimizer_name not in OPTIMIZERS:
        raise ConfigError(f"{source}unknown optimizer.name {optimizer_name!r}; choose one of {', '.join(OPTIMIZERS)}")
    return spec, optimizer_name


def _attributed(err: ConfigError, path: str | os.PathLike | None, given: list[str]) -> ConfigError:
    """``err`` saying where the value at fault came from: the file, the command line, or both."""
    key = err.key or ""
    from_command_line = any(g == key or g.startswith(key + ".") or key.startswith(g + ".") for g in given) if key else False
    if from_command_line and (path is None or err.key in given):
        return ConfigError(f"--set {err}" if err.key in given else f"--set: {err}", err.key)
    if path is not None:
        return ConfigError(f"{path}{' with --set' if from_command_line else ''}: {err}", err.key)
    return err
