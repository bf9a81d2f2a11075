"""Find the tallest structures a local NCA can grow that stand, and teach them to it.

Evolution in weight space stops at four or five levels (benchmarks/structures.md, "Tall structures"): the weights that
grow a tall, sparse tower are a narrow target. This module searches the designs instead and then trains the network on the
winner with :func:`.teach.teach`.

The designs are :func:`.samples.by_level_rules`: one rule per level from a top vertex, the lowest 0 to 2
levels tied to their side neighbours. Every vertex of a level does the same, the regularity a shared local rule can
express. The search:

1. **Beam, by static load.** From the top down, every kept design is made one level taller in every way; those whose
   levels an NCA can tell apart are ranked by their largest static joint load (:func:`physics.statics.bounding_loads`,
   milliseconds each), and the ``beam`` best go on to the next height.
2. **Transient, per height.** Of each height the ``candidates`` best that an NCA can grow whole are simulated for the
   faithful preset's first 0.3 s with joints that hold (:func:`physics.check_transient`), when such towers carry
   most; the lowest peak is that height's design.
3. **Refinement.** Static load misses designs that carry less in the transient, so every design that differs from the
   tallest in two levels' rules is ranked the same way and the ``candidates`` best simulated (``refine``). While the
   refined design still carries more than the break force, the next height down is refined too, so a search asked
   for more levels than can stand ends with the tallest design that holds.
4. **Teaching.** Each height's design is taught to the paper's 52-60-26 network; the weights are grown and checked
   against the design.

:func:`find_tallest` runs it all, in a run folder when given one (``structgen tall``). The folder is a run folder like
an evolution run's (:class:`evolution.RunFolder`: ``config.toml`` with every setting, the physics included,
``manifest.json``, the lock, atomic writes), with ``checkpoint.json`` written after each height and each refinement:
``structgen resume DIR`` (or the same ``structgen tall`` command) goes on where it stopped, and the same folder
with more ``levels`` goes on to the taller heights. The simulations run on the project's worker pool
(:class:`evolution.pool.WorkerPool`), so a worker that dies costs one design, which then counts as unable to stand.
"""

from __future__ import annotations

import csv
import functools
import io
import itertools
import json
import logging
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from evolution import RunFolder, RunFolderError
from evolution.files import MiB, atomic_write, read_json
from evolution.pool import Lost, WorkerPool
from physics import PhysicsConfig, check_transient
from physics.statics import bounding_loads
from structgen.config import ConfigError, build, flatten, to_table
from structgen.domains.structures.samples import LEVEL_RULES, by_level_rules, by_level_rules_one_taller
from structgen.domains.structures.tall_settings import MAX_LEVELS, TallSettings
from structgen.domains.structures.teach import TeachError, TeachResult, growth_config, growth_schedule, local_rules, teach
from structgen.errors import InputError
from structgen.structure import Structure

__all__ = [
    "RUN_KIND",
    "TallDesign",
    "TallResult",
    "TallSettings",
    "describe_search",
    "find_tallest",
    "is_search_folder",
    "refine",
    "resume_search",
    "search_summary",
    "teachable",
]

log = logging.getLogger(__name__)

#: Seconds of the preset simulated per candidate: the tallest designs carry their largest loads in them.
TRANSIENT_WINDOW = 0.3
#: What a tall search's manifest calls its kind of run (``structgen resume`` finds the domain's code by it).
RUN_KIND = "tall"
DOMAIN = "structures-v0"
CHECKPOINT_FILE = "checkpoint.json"
TABLE_FILE = "designs.csv"
# The files of a search folder written by structgen 0.2, converted when the folder is next opened.
_OLD_SETTINGS, _OLD_CHECKPOINT = "settings.json", "search.json"


@dataclass(frozen=True)
class TallDesign:
    """One height's chosen design: its rules (top level first), tied levels and loads in newtons."""

    rules: tuple[str, ...]
    tied: int
    static_load: float
    peak: float
    extent: int | None = None  # the search's footprint limit (TallSettings.extent), not saved with the design

    @property
    def levels(self) -> int:
        return len(self.rules) + 1

    @functools.cached_property
    def structure(self) -> Structure:
        design = by_level_rules(self.rules, self.tied, self.extent)
        assert design is not None, "a chosen design reaches the ground"
        return design

    def holds(self, physics: PhysicsConfig) -> bool:
        """Whether no joint carries more than the break force in the transient, so none breaks there."""
        return self.peak <= physics.break_force

    def to_json(self) -> dict[str, Any]:
        # JSON has no infinity: a load without an answer (inf) is stored as null.
        return {
            "rules": list(self.rules),
            "tied": self.tied,
            "static_load": _finite(self.static_load),
            "peak": _finite(self.peak),
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TallDesign:
        return cls(tuple(data["rules"]), int(data["tied"]), _number(data["static_load"]), _number(data["peak"]))


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _number(value: Any) -> float:
    return math.inf if value is None else float(value)


@dataclass
class TallResult:
    """The designs found, per height, and what teaching made of them.

    Attributes:
        settings: what was searched, the physics included.
        designs: each height's design, by number of levels.
        taught: each height's taught network (its weights, growth settings and grown structure).
        teach_seconds: how long each teaching took.
        search_seconds: time spent searching in this call (a resumed search counts only its own part).
    """

    settings: TallSettings
    designs: dict[int, TallDesign]
    taught: dict[int, TeachResult]
    teach_seconds: dict[int, float]
    search_seconds: float

    @property
    def tallest(self) -> int:
        """The most levels of any design found."""
        return max(self.designs)

    @property
    def tallest_holding(self) -> int | None:
        """The most levels of a design that holds in the transient (None when none does)."""
        physics = self.settings.physics
        return max((levels for levels, design in self.designs.items() if design.holds(physics)), default=None)


def teachable(design: Structure, *, whole: bool) -> bool:
    """Whether a local rule can grow ``design`` from its top vertex. With ``whole=False`` the lowest level's own
    actions are left out, since they change when a level is added below it."""
    states = growth_schedule(design)
    try:
        if whole:
            local_rules(states, growth_config(states))
        else:  # state t holds the levels down to t, so the lowest level first acts in the step after state `height`
            local_rules(states[: design.height + 1], growth_config(states), fixed_point=False)
    except TeachError:
        return False
    return True


def largest_static_load(design: Structure, physics: PhysicsConfig | None = None) -> float:
    """The largest joint load of the static analysis (inf where it has no answer: a piece that cannot stand)."""
    return float(np.nan_to_num(np.max(bounding_loads(design, physics or PhysicsConfig())), nan=np.inf))


def transient_peak(design: Structure, physics: PhysicsConfig | None = None, window: float = TRANSIENT_WINDOW) -> float:
    """The largest joint force in the first ``window`` seconds of ``physics`` (default: the faithful preset), joints
    unbreakable, on ``design`` listed as an NCA grows it (:meth:`.Structure.in_growth_order`). The tallest designs
    pass the default caps; the window is short, so they are let in."""
    physics = physics or PhysicsConfig()
    physics = physics.replace(**physics.room_for(design.n_vertices, design.n_edges))
    # Judged as an NCA would grow it, since the body order moves PyBullet's joint forces by a few newtons.
    return check_transient(design.in_growth_order(), physics, window=window).peak_force


def _whole_static_load(
    candidate: tuple[tuple[str, ...], int], max_vertices: int, physics: PhysicsConfig, extent: int | None = None
) -> float:
    design = by_level_rules(*candidate, extent)
    if design is None or design.n_vertices > max_vertices or not teachable(design, whole=True):
        return np.inf
    return largest_static_load(design, physics)


#: Runs a function over items, in order (in the worker pool, or in this process in tests).
Mapper = Callable[[Callable[[Any], Any], Sequence[Any]], list[Any]]


def _one_height(
    kept: list[tuple[tuple[str, ...], int]], settings: TallSettings, simulate: Mapper
) -> tuple[list[tuple[tuple[str, ...], int]], TallDesign | None]:
    """The beam one level taller, and that height's design (None when no design of it can be grown whole)."""
    scored = []
    prefixes = [rules for rules, _ in kept]
    for rules, tied, design in by_level_rules_one_taller(prefixes, settings.max_vertices, settings.extent):
        if teachable(design, whole=False):
            scored.append((largest_static_load(design, settings.physics), rules, tied, design))
    scored.sort(key=lambda row: row[0])  # stable: ties keep the order the designs were made in
    kept = list(dict.fromkeys((row[1], row[2]) for row in scored))[: settings.beam]
    whole = list(itertools.islice((row for row in scored if teachable(row[3], whole=True)), settings.candidates))
    if not whole:
        return kept, None
    peaks = simulate(functools.partial(transient_peak, physics=settings.physics), [row[3] for row in whole])
    k = int(np.argmin(peaks))
    load, rules, tied, _ = whole[k]
    return kept, TallDesign(rules, tied, load, float(peaks[k]), settings.extent)


def refine(found: TallDesign, settings: TallSettings, simulate: Mapper) -> TallDesign:
    """The design with the lowest transient peak among ``found`` and the ``settings.candidates`` best by static
    load of those differing from it in two levels' rules that an NCA can grow whole."""
    rules = found.rules
    variants = {
        (tuple(rule_a if k == i else rule_b if k == j else rule for k, rule in enumerate(rules)), found.tied)
        for i, j in itertools.combinations(range(len(rules)), 2)
        for rule_a in LEVEL_RULES
        for rule_b in LEVEL_RULES
    } - {(rules, found.tied)}
    ordered = sorted(variants)
    static = functools.partial(
        _whole_static_load, max_vertices=settings.max_vertices, physics=settings.physics, extent=settings.extent
    )
    loads = simulate(static, ordered)
    ranked = [(load, variant) for load, variant in sorted(zip(loads, ordered)) if np.isfinite(load)][: settings.candidates]
    designs = [by_level_rules(*v, settings.extent) for _, v in ranked]
    peaks = simulate(functools.partial(transient_peak, physics=settings.physics), designs)
    if peaks and min(peaks) < found.peak:
        k = int(np.argmin(peaks))
        load, (new_rules, tied) = ranked[k]
        return TallDesign(new_rules, tied, float(load), float(peaks[k]), settings.extent)
    return found


# --- the run folder ---------------------------------------------------------------------------------------------


def _config_text(settings: TallSettings, workers: int) -> str:
    import tomli_w

    header = (
        "# Settings of this tall search (structgen tall): every setting, as used. `structgen resume` reads this file;\n"
        "# [run] workers only decides where the simulations run, never what they find.\n"
    )
    return header + tomli_w.dumps({"run": {"workers": workers}, "search": to_table(settings)})


def _read_config(folder: RunFolder) -> tuple[TallSettings, int]:
    """The search settings and the number of workers a search folder's ``config.toml`` holds."""
    from structgen.runs.experiment import parse_toml

    where = folder / RunFolder.CONFIG
    tables = parse_toml(folder.config_text(), where)
    unknown = sorted(set(tables) - {"run", "search"})
    if unknown:
        raise ConfigError(f"{where}: unknown table [{unknown[0]}]; a tall search's configuration has [run] and [search]")
    run, search = tables.get("run", {}), tables.get("search", {})
    workers = run.get("workers", 2) if isinstance(run, dict) else None
    whole = isinstance(workers, int) and not isinstance(workers, bool) and workers >= 0
    if not isinstance(run, dict) or set(run) - {"workers"} or not whole:
        raise ConfigError(f"{where}: [run] holds only workers, a whole number of processes (0 for this one), got {run!r}")
    if not isinstance(search, dict):
        raise ConfigError(f"{where}: [search] must be a table")
    try:
        return build(TallSettings, search, "search"), workers
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}", err.key) from None


def _manifest(settings: TallSettings) -> dict[str, Any]:
    from structgen.runs import manifest

    return manifest(DOMAIN, ("numpy", "scipy", "torch", "pybullet"), run_kind=RUN_KIND)


def is_search_folder(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a folder a tall search wrote (``structgen info`` tells it from an evolution run)."""
    folder = RunFolder(path)
    if _is_old_folder(folder):
        return True
    return (folder / RunFolder.CONFIG).is_file() and folder.manifest().get("run_kind") == RUN_KIND


def _is_old_folder(folder: RunFolder) -> bool:
    """Whether ``folder`` is a search folder of structgen 0.2 (``settings.json``, no ``config.toml``)."""
    return (folder / _OLD_SETTINGS).is_file() and not (folder / RunFolder.CONFIG).exists()


def _old_settings(folder: RunFolder) -> TallSettings:
    """The settings of a search folder of structgen 0.2 (``settings.json``), read and checked, nothing changed."""
    saved = read_json(folder / _OLD_SETTINGS, 16 * MiB)
    if not isinstance(saved, dict):
        raise InputError(f"{folder / _OLD_SETTINGS}: expected an object of settings, got {type(saved).__name__}")
    try:
        return build(TallSettings, saved, "settings")
    except ConfigError as err:
        raise InputError(f"{folder / _OLD_SETTINGS}: {err}") from None


def _convert_old_folder(folder: RunFolder) -> None:
    """Turn a search folder of structgen 0.2 (settings.json, search.json) into a run folder, keeping its progress;
    with the folder's lock held, once the command is known to go ahead."""
    settings = _old_settings(folder)
    folder.write_config(_config_text(settings, 2))
    atomic_write(folder / RunFolder.MANIFEST, json.dumps(_marked(_manifest(settings)), indent=2) + "\n")
    if (folder / _OLD_CHECKPOINT).is_file():
        os.replace(folder / _OLD_CHECKPOINT, folder / CHECKPOINT_FILE)
    (folder / _OLD_SETTINGS).unlink()
    log.info("%s: converted from the tall search folder of structgen 0.2", folder.path)


def _marked(manifest: dict[str, Any]) -> dict[str, Any]:
    from evolution.runfolder import MARK, MARK_VALUE

    return {**manifest, MARK: MARK_VALUE}


def _open_folder(path: Path, settings: TallSettings, workers: int, overwrite: bool) -> tuple[RunFolder, bool]:
    """A new run folder for the search, or the one a search with the same settings started (it resumes; with more
    ``levels`` it goes on), and whether it is a folder of structgen 0.2 to convert. A folder that holds anything
    else, or a search with other settings, is refused, and nothing in it is changed: an existing folder is only
    read here (the caller converts it and records the settings with its lock held)."""
    folder = RunFolder(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{path}: is a file, expected a run folder")
    old = _is_old_folder(folder)
    if not old and (not is_search_folder(path) or overwrite):
        if (folder / RunFolder.CONFIG).is_file() and not overwrite:
            raise InputError(f"{path}: holds a run that is not a tall search; choose another folder")
        return RunFolder.create(path, _config_text(settings, workers), _manifest(settings), overwrite=overwrite), False
    saved = _old_settings(folder) if old else _read_config(folder)[0]
    where = folder / (_OLD_SETTINGS if old else RunFolder.CONFIG)
    before, now = flatten(to_table(saved)), flatten(to_table(settings))
    for key in sorted(before.keys() | now.keys()):
        taller = key == "levels" and now.get(key, 0) > before.get(key, 0)
        if before.get(key) != now.get(key) and not taller:
            raise InputError(
                f"{where}: this folder holds a search with search.{key} = {before.get(key)!r}, not "
                f"{now.get(key)!r}; give the same settings to resume it (or more levels to go on), or another folder"
            )
    return folder, old


def _checkpoint(
    folder: RunFolder | None,
    done: int,
    kept: list[tuple[tuple[str, ...], int]],
    designs: dict[int, TallDesign],
    refined: list[int],
    *,
    complete: bool = False,
) -> None:
    """Write what :func:`_restore` reads back; ``complete`` once every output is written (``structgen info``)."""
    if folder is not None:
        state = {
            "levels_done": done,
            "kept": [[list(rules), tied] for rules, tied in kept],
            "designs": {str(levels): design.to_json() for levels, design in designs.items()},
            "refined": refined,
            "complete": complete,
        }
        atomic_write(folder / CHECKPOINT_FILE, json.dumps(state, indent=2) + "\n")


def _checkpoint_path(folder: RunFolder, old: bool = False) -> Path:
    """Where the search's checkpoint is; ``old``: in a folder of structgen 0.2 not yet converted."""
    return folder / (_OLD_CHECKPOINT if old else CHECKPOINT_FILE)


def _saved_state(folder: RunFolder, old: bool = False) -> Any:
    """The checkpoint's content ({} before the first)."""
    path = _checkpoint_path(folder, old)
    return read_json(path, 16 * MiB) if path.exists() or path.is_symlink() else {}


def _whole(value: Any, low: int, high: int, field: str, where: Path) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise InputError(f"{where}: {field} is {value!r}; expected a whole number from {low} to {high}")
    return value


def _rules(value: Any, field: str, where: Path) -> tuple[str, ...]:
    if not isinstance(value, list) or len(value) >= MAX_LEVELS or not all(rule in LEVEL_RULES for rule in value):
        raise InputError(
            f"{where}: {field} is not a design's rules (a list of at most {MAX_LEVELS - 1} of {', '.join(LEVEL_RULES)})"
        )
    return tuple(value)


def _load(value: Any, field: str, where: Path) -> float:
    if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 <= value < math.inf):
        raise InputError(f"{where}: {field} is {value!r}; expected a load in newtons, 0 or more (null: none)")
    return _number(value)


def _restore(state: Any, path: Path, settings: TallSettings) -> tuple[int, list, dict[int, TallDesign], list[int]]:
    """From a checkpoint (read from ``path``): the levels searched, the beam, each height's design and the heights
    refined. Every field is checked for what a search writes (whole numbers, rules it knows, a height per design no
    taller than the levels searched, no more levels than ``settings`` search); anything else is an error naming the
    field."""
    if not isinstance(state, dict):
        raise InputError(f"{path}: not a tall search checkpoint (expected an object)")
    done = _whole(state.get("levels_done", 1), 1, settings.levels, "levels_done", path)
    kept_rows = state.get("kept", [[[], 0]])
    if not isinstance(kept_rows, list):
        raise InputError(f"{path}: kept is {type(kept_rows).__name__}; expected a list of [rules, tied] pairs")
    kept = []
    for number, row in enumerate(kept_rows):
        if not isinstance(row, list) or len(row) != 2:
            raise InputError(f"{path}: kept[{number}] is not a [rules, tied] pair")
        kept.append((_rules(row[0], f"kept[{number}] rules", path), _whole(row[1], 0, 2, f"kept[{number}] tied", path)))
    rows = state.get("designs", {})
    if not isinstance(rows, dict):
        raise InputError(f"{path}: designs is {type(rows).__name__}; expected an object of designs by height")
    designs = {}
    for key, row in rows.items():
        # ASCII digits, and few: int() refuses 4,300 digits and reads "²" as no number at all.
        if not (key.isascii() and key.isdigit() and len(key) <= 3) or not isinstance(row, dict):
            raise InputError(f"{path}: designs[{key!r}] is not a design under its height")
        levels = _whole(int(key), 2, done, f"designs[{key!r}]'s height", path)
        rules = _rules(row.get("rules"), f"designs[{key!r}].rules", path)
        if len(rules) + 1 != levels:
            raise InputError(f"{path}: designs[{key!r}] has {len(rules) + 1} levels of rules, not {levels}")
        tied = _whole(row.get("tied"), 0, 2, f"designs[{key!r}].tied", path)
        designs[levels] = TallDesign(
            rules, tied, _load(row.get("static_load"), f"designs[{key!r}].static_load", path),
            _load(row.get("peak"), f"designs[{key!r}].peak", path), settings.extent,
        )  # fmt: skip
    refined_rows = state.get("refined", [])
    if not isinstance(refined_rows, list) or not all(isinstance(r, int) and r in designs for r in refined_rows):
        raise InputError(f"{path}: refined is {refined_rows!r}; expected heights of its designs")
    if not isinstance(state.get("complete", False), bool):
        raise InputError(f"{path}: complete is {state.get('complete')!r}; expected true or false")
    return done, kept, designs, list(refined_rows)


def _table_text(result: TallResult) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        [
            "levels",
            "rules",
            "tied_levels",
            "vertices",
            "edges",
            "static_load_n",
            "transient_peak_n",
            "holds_in_transient",
            "rules_taught",
            "weights",
        ]
    )
    for levels, design in sorted(result.designs.items()):
        writer.writerow(
            [
                levels,
                " ".join(design.rules),
                design.tied,
                design.structure.n_vertices,
                design.structure.n_edges,
                f"{design.static_load:.2f}",
                f"{design.peak:.2f}",
                "yes" if design.holds(result.settings.physics) else "no",
                result.taught[levels].n_rules,
                f"tall_{levels}.npy",
            ]
        )
    return buffer.getvalue()


def _write_outputs(folder: RunFolder, result: TallResult) -> None:
    from structgen.domains.structures.render import render_structure
    from structgen.nca import save_weights

    for levels, taught in result.taught.items():
        save_weights(folder / f"tall_{levels}.npy", taught.weights)
        taught.grown.save(folder / f"tall_{levels}.json")
    atomic_write(folder / TABLE_FILE, _table_text(result))
    levels = result.tallest_holding or result.tallest
    grown = result.taught[levels].grown
    holds = "hold" if result.designs[levels].holds(result.settings.physics) else "break"
    render_structure(
        grown,
        folder / "tallest.png",
        title=f"{levels} levels grown by a taught NCA, that {holds} in the transient: {grown.n_vertices} vertices, "
        f"{grown.n_edges} edges",
    )


def search_summary(run_dir: str | os.PathLike) -> dict[str, Any]:
    """What a tall search folder holds, from its files: its settings, how far it got and each height's design."""
    folder = RunFolder(run_dir)
    if not is_search_folder(folder.path):
        raise RunFolderError(f"{folder.path}: not a tall search folder")
    old = _is_old_folder(folder)
    settings = _old_settings(folder) if old else _read_config(folder)[0]
    state = _saved_state(folder, old)
    done, _, designs, refined = _restore(state, _checkpoint_path(folder, old), settings)
    rows = [
        {
            **design.to_json(),
            "levels": levels,
            "vertices": design.structure.n_vertices,
            "edges": design.structure.n_edges,
            "holds_in_transient": design.holds(settings.physics),
        }
        for levels, design in sorted(designs.items())
    ]
    return {
        "run_dir": str(folder.path),
        "kind": "tall search",
        "settings": to_table(settings),
        "levels_searched": done,
        "refined": sorted(refined),
        "finished": bool(state.get("complete")),
        "designs": rows,
    }


def describe_search(summary: dict[str, Any]) -> str:
    """:func:`search_summary` as lines to read."""
    settings = summary["settings"]
    status = "finished" if summary["finished"] else f"searched up to {summary['levels_searched']} levels, unfinished"
    break_force = settings["physics"]["break_force"] if "break_force" in settings["physics"] else PhysicsConfig().break_force
    lines = [
        f"{summary['run_dir']}: a tall search (structgen tall), {status}",
        f"settings    levels {settings.get('levels')}, beam {settings.get('beam')}, candidates "
        f"{settings.get('candidates')}, max_vertices {settings.get('max_vertices')}, refine {settings.get('refine')}, "
        f"joints break above {break_force:g} N",
    ]
    for row in summary["designs"]:
        load, peak = _number(row["static_load"]), _number(row["peak"])
        lines.append(
            f"{row['levels']} levels    {' '.join(row['rules'])} (tied {row['tied']}): {row['vertices']} vertices, "
            f"{row['edges']} edges, static {load:.1f} N, transient peak {peak:.1f} N"
            + ("" if row["holds_in_transient"] else f" (over the {break_force:g} N break force)")
        )
    holding = [row["levels"] for row in summary["designs"] if row["holds_in_transient"]]
    if summary["finished"] and holding:
        lines.append(f"tallest     {Path(summary['run_dir']) / f'tall_{max(holding)}.npy'} grows {max(holding)} levels that hold")
    return "\n".join(lines)


def _pool_mapper(pool: WorkerPool, progress: bool) -> Mapper:
    def simulate(function: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        bar = None
        if progress and sys.stderr.isatty():
            from tqdm import tqdm

            bar = tqdm(total=len(items), leave=False, unit="design", file=sys.stderr, dynamic_ncols=True)
        try:
            results = pool.map(function, items, done=None if bar is None else lambda _: bar.update(1))
        finally:
            if bar is not None:
                bar.close()
        lost = [k for k, result in enumerate(results) if isinstance(result, Lost)]
        for k in lost:  # a design whose worker died counts as one that cannot stand
            log.warning("design %d of %d: %s; it counts as unable to stand", k, len(items), results[k].reason)
        return [math.inf if isinstance(result, Lost) else result for result in results]

    return simulate


def find_tallest(
    settings: TallSettings | None = None,
    run_dir: str | os.PathLike | None = None,
    *,
    workers: int = 2,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
    overwrite: bool = False,
) -> TallResult:
    """Search for the tallest design an NCA can grow with the lowest transient load, teach every height's design,
    and (with ``run_dir``) write it all to a run folder.

    Args:
        settings: what to search (the defaults reach eight levels in about 8 minutes on 2 cores).
        run_dir: a new or empty folder, or one a search with the same settings started (it resumes after the last
            finished height; with more ``levels`` it goes on from there). It receives ``config.toml`` (the settings),
            ``manifest.json``, ``checkpoint.json``, ``designs.csv`` (a row per height), ``tall_<levels>.npy`` (the
            taught weights), ``tall_<levels>.json`` (what they grow) and ``tallest.png`` (the tallest that holds in
            the transient).
        workers: processes for the simulations (0: this process); results do not depend on it.
        progress: a progress bar on a terminal while candidates are simulated.
        log: called with a line per finished stage (``print`` shows the search as it goes).
        overwrite: replace a run folder that holds another search (never a folder that is not a run folder).

    Raises:
        InputError: a run folder that holds something else, or a search with other settings.
        RunFolderError: another process is writing the folder.
    """
    settings = settings or TallSettings()
    if not isinstance(workers, int) or isinstance(workers, bool) or workers < 0:
        raise InputError(f"workers must be a whole number, 0 or more, got {workers!r}")
    if run_dir is None:
        fresh = _restore({}, Path(CHECKPOINT_FILE), settings)
        return _search(settings, None, fresh, workers, progress, log or (lambda line: None))
    folder, old = _open_folder(Path(run_dir), settings, workers, overwrite)
    with folder.locked():
        # The checkpoint is read back before anything is written: a damaged one refuses with the folder unchanged.
        restored = _restore(_saved_state(folder, old), _checkpoint_path(folder, old), settings)
        if old:
            _convert_old_folder(folder)
        if folder.config_text() != _config_text(settings, workers):
            folder.write_config(_config_text(settings, workers))
        folder.remove_temporary_files()
        return _search(settings, folder, restored, workers, progress, log or (lambda line: None))


def resume_search(
    run_dir: str | os.PathLike,
    *,
    workers: int | None = None,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
) -> TallResult:
    """Go on with the search in ``run_dir`` with the settings it was started with (``structgen resume DIR``);
    ``workers`` changes only where the simulations run."""
    folder = RunFolder.open(run_dir)
    if not is_search_folder(folder.path):
        raise RunFolderError(f"{folder.path}: not a tall search folder")
    settings, saved_workers = _read_config(folder)
    return find_tallest(settings, folder.path, workers=saved_workers if workers is None else workers, progress=progress, log=log)


def _search(
    settings: TallSettings,
    folder: RunFolder | None,
    restored: tuple[int, list, dict[int, TallDesign], list[int]],
    workers: int,
    progress: bool,
    say: Callable[[str], None],
) -> TallResult:
    """The search from where ``restored`` (what :func:`_restore` read from the folder's checkpoint) says it stands."""
    done, kept, designs, refined = restored
    _checkpoint(folder, done, kept, designs, refined)  # not complete until this call's outputs are written
    physics = settings.physics
    if done > 1:
        where = folder.path if folder is not None else "the search"
        say(f"{where}: resuming after {done} of {settings.levels} levels ({len(designs)} heights found so far)")
    else:
        say(f"searching designs of 2 to {settings.levels} levels; joints break above {physics.break_force:g} N")
    started = time.perf_counter()
    with WorkerPool(workers) as pool:
        simulate = _pool_mapper(pool, progress)
        for levels in range(done + 1, settings.levels + 1):
            if not kept:  # no design of the last height could be made taller
                break
            clock = time.perf_counter()
            kept, design = _one_height(kept, settings, simulate)
            if design is not None:
                designs[levels] = design
                say(
                    f"{levels} levels: {' '.join(design.rules)} (tied {design.tied}), {design.structure.n_vertices} "
                    f"vertices, static {design.static_load:.1f} N, transient peak {design.peak:.1f} N "
                    f"({time.perf_counter() - clock:.0f} s)"
                )
            else:
                say(f"{levels} levels: no design an NCA can grow whole ({time.perf_counter() - clock:.0f} s)")
            done = levels
            _checkpoint(folder, done, kept, designs, refined)
        if not designs:
            raise InputError(f"no design of 2 to {settings.levels} levels within {settings.max_vertices} vertices can be grown")
        # The tallest design is always refined (a lower peak is more margin); lower ones only while none above holds,
        # so a search past what can stand still ends with the tallest design that does.
        for levels in sorted(designs, reverse=True):
            if settings.refine and levels not in refined:
                clock, before = time.perf_counter(), designs[levels]
                designs[levels] = refine(before, settings, simulate)
                refined.append(levels)
                outcome = (
                    f"peak {before.peak:.1f} N -> {designs[levels].peak:.1f} N"
                    if designs[levels] != before
                    else "none carries less"
                )
                say(
                    f"refined the {levels}-level design (every change of two levels' rules): {outcome} "
                    f"({time.perf_counter() - clock:.0f} s)"
                )
                _checkpoint(folder, done, kept, designs, refined)
            if designs[levels].holds(physics):
                break
    search_seconds = time.perf_counter() - started
    taught, teach_seconds = {}, {}
    for levels, design in sorted(designs.items()):
        clock = time.perf_counter()
        taught[levels] = teach(design.structure)
        teach_seconds[levels] = time.perf_counter() - clock
    result = TallResult(settings, designs, taught, teach_seconds, search_seconds)
    if folder is not None:
        _write_outputs(folder, result)
        _checkpoint(folder, done, kept, designs, refined, complete=True)
    return result
