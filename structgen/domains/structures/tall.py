"""Find the tallest structures a local NCA can grow that stand, and teach them to it.

Evolution in weight space stops at four or five levels (benchmarks/README.md, "Tall"): the weights that grow a tall,
sparse tower are a narrow target. This module searches the designs instead and then trains the network on the
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

:func:`find_tallest` runs it all, in a run folder when given one (``structgen tall``): the search writes a checkpoint
after each height, so an interrupted search resumes where it stopped, and every output is written atomically.
"""

from __future__ import annotations

import csv
import functools
import io
import itertools
import json
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from physics import PhysicsConfig, check_transient
from physics.statics import bounding_loads
from structgen.domains.structures.samples import LEVEL_RULES, by_level_rules, by_level_rules_one_taller
from structgen.domains.structures.teach import TeachError, TeachResult, growth_config, growth_schedule, local_rules, teach
from structgen.errors import InputError
from structgen.structure import Structure

__all__ = [
    "TallDesign",
    "TallResult",
    "TallSettings",
    "describe_search",
    "find_tallest",
    "is_search_folder",
    "refine",
    "search_summary",
    "teachable",
]

#: The faithful preset: the loads of the search and the break force they are held to.
PHYSICS = PhysicsConfig()
#: Seconds of the faithful preset simulated per candidate: the tallest designs carry their largest loads in it.
TRANSIENT_WINDOW = 0.3

SETTINGS_FILE = "settings.json"
CHECKPOINT_FILE = "search.json"
TABLE_FILE = "designs.csv"


@dataclass(frozen=True)
class TallSettings:
    """What the search explores; the same settings give the same designs on any number of workers.

    Attributes:
        levels: the tallest design to look for, in vertices (a level is one lattice layer).
        beam: designs of each height kept to grow the next.
        candidates: designs of each height (and of the refinement) simulated.
        max_vertices: the largest design tried.
        refine: whether to try every change of two levels' rules of the tallest design (and of lower ones while none
            above holds in the transient).
    """

    levels: int = 8
    beam: int = 30
    candidates: int = 12
    max_vertices: int = 700
    refine: bool = True

    def __post_init__(self) -> None:
        for name, smallest in (("levels", 2), ("beam", 1), ("candidates", 1), ("max_vertices", 2)):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or value < smallest:
                raise InputError(f"{name} must be a whole number of at least {smallest}, got {value!r}")
        if not isinstance(self.refine, bool):
            raise InputError(f"refine must be true or false, got {self.refine!r}")


@dataclass(frozen=True)
class TallDesign:
    """One height's chosen design: its rules (top level first), tied levels and loads in newtons."""

    rules: tuple[str, ...]
    tied: int
    static_load: float
    peak: float

    @property
    def levels(self) -> int:
        return len(self.rules) + 1

    @functools.cached_property
    def structure(self) -> Structure:
        design = by_level_rules(self.rules, self.tied)
        assert design is not None, "a chosen design reaches the ground"
        return design

    @property
    def holds(self) -> bool:
        """Whether no joint carries more than the break force in the transient, so none breaks there."""
        return self.peak <= PHYSICS.break_force

    def to_json(self) -> dict[str, Any]:
        # JSON has no infinity: a static solve without an answer (inf) is stored as null.
        load = self.static_load if np.isfinite(self.static_load) else None
        return {"rules": list(self.rules), "tied": self.tied, "static_load": load, "peak": self.peak}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> TallDesign:
        load = np.inf if data["static_load"] is None else float(data["static_load"])
        return cls(tuple(data["rules"]), int(data["tied"]), load, float(data["peak"]))


@dataclass
class TallResult:
    """The designs found, per height, and what teaching made of them.

    Attributes:
        designs: each height's design, by number of levels.
        taught: each height's taught network (its weights, growth settings and grown structure).
        teach_seconds: how long each teaching took.
        search_seconds: time spent searching in this call (a resumed search counts only its own part).
    """

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
        return max((levels for levels, design in self.designs.items() if design.holds), default=None)


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


def largest_static_load(design: Structure, physics: PhysicsConfig = PHYSICS) -> float:
    """The largest joint load of the static analysis (inf where it has no answer: a piece that cannot stand)."""
    return float(np.nan_to_num(np.max(bounding_loads(design, physics)), nan=np.inf))


def transient_peak(design: Structure) -> float:
    """The largest joint force in the faithful preset's first :data:`TRANSIENT_WINDOW` seconds, joints unbreakable.
    The tallest designs pass the default caps; the window is short, so they are let in."""
    physics = PHYSICS.replace(**PHYSICS.room_for(design.n_vertices, design.n_edges))
    return check_transient(design, physics, window=TRANSIENT_WINDOW).peak_force


def _whole_static_load(candidate: tuple[tuple[str, ...], int], max_vertices: int) -> float:
    design = by_level_rules(*candidate)
    if design is None or design.n_vertices > max_vertices or not teachable(design, whole=True):
        return np.inf
    return largest_static_load(design)


Mapper = Callable[[Callable[[Any], Any], Sequence[Any]], list[Any]]


def _one_height(
    kept: list[tuple[tuple[str, ...], int]], settings: TallSettings, simulate: Mapper
) -> tuple[list[tuple[tuple[str, ...], int]], TallDesign | None]:
    """The beam one level taller, and that height's design (None when no design of it can be grown whole)."""
    scored = []
    for rules, tied, design in by_level_rules_one_taller([rules for rules, _ in kept], settings.max_vertices):
        if teachable(design, whole=False):
            scored.append((largest_static_load(design), rules, tied, design))
    scored.sort(key=lambda row: row[0])  # stable: ties keep the order the designs were made in
    kept = list(dict.fromkeys((row[1], row[2]) for row in scored))[: settings.beam]
    whole = list(itertools.islice((row for row in scored if teachable(row[3], whole=True)), settings.candidates))
    if not whole:
        return kept, None
    peaks = simulate(transient_peak, [row[3] for row in whole])
    k = int(np.argmin(peaks))
    load, rules, tied, _ = whole[k]
    return kept, TallDesign(rules, tied, load, float(peaks[k]))


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
    loads = simulate(functools.partial(_whole_static_load, max_vertices=settings.max_vertices), ordered)
    ranked = [(load, variant) for load, variant in sorted(zip(loads, ordered)) if np.isfinite(load)][: settings.candidates]
    peaks = simulate(transient_peak, [by_level_rules(*variant) for _, variant in ranked])
    if peaks and min(peaks) < found.peak:
        k = int(np.argmin(peaks))
        load, (new_rules, tied) = ranked[k]
        return TallDesign(new_rules, tied, float(load), float(peaks[k]))
    return found


# --- the run folder ---------------------------------------------------------------------------------------------


def _write_json(path: Path, data: Any) -> None:
    from evolution.files import atomic_write

    atomic_write(path, json.dumps(data, indent=2) + "\n")


def _read_json(path: Path) -> Any:
    from evolution.files import MiB, read_json

    return read_json(path, 16 * MiB)


def _open_folder(run_dir: Path, settings: TallSettings) -> dict[str, Any]:
    """Start or reopen a run folder; the saved search so far ({} for a new one). A search with the same settings
    resumes, and one with more ``levels`` goes on from where it stopped (keeping its heights, refinements included). A
    folder that holds anything else, or a search with other settings, is refused, so nothing in it is overwritten."""
    settings_path = run_dir / SETTINGS_FILE
    if run_dir.exists() and not run_dir.is_dir():
        raise InputError(f"{run_dir}: is a file, expected a run folder")
    if settings_path.exists():
        saved = _read_json(settings_path)
        if not isinstance(saved, dict):
            raise InputError(f"{settings_path}: expected an object of settings")
        for field in fields(TallSettings):
            before, now = saved.get(field.name), getattr(settings, field.name)
            taller = field.name == "levels" and isinstance(before, int) and now > before
            if before != now and not taller:
                raise InputError(
                    f"{settings_path}: this folder holds a search with {field.name} = {before!r}, not {now!r}; give the "
                    "same settings to resume it (or more levels to go on), or another folder"
                )
        checkpoint = run_dir / CHECKPOINT_FILE
        state = _read_json(checkpoint) if checkpoint.exists() else {}
        if saved["levels"] != settings.levels:
            _write_json(settings_path, asdict(settings))
        return state
    if run_dir.is_dir() and any(run_dir.iterdir()):
        raise InputError(f"{run_dir}: is not empty and holds no tall search ({SETTINGS_FILE}); choose another folder")
    _write_json(settings_path, asdict(settings))
    return {}


def _checkpoint(
    run_dir: Path | None,
    done: int,
    kept: list[tuple[tuple[str, ...], int]],
    designs: dict[int, TallDesign],
    refined: list[int],
    *,
    complete: bool = False,
) -> None:
    """Write what :func:`_restore` reads back; ``complete`` once every output is written (``structgen info``)."""
    if run_dir is not None:
        state = {
            "levels_done": done,
            "kept": [[list(rules), tied] for rules, tied in kept],
            "designs": {str(levels): design.to_json() for levels, design in designs.items()},
            "refined": refined,
            "complete": complete,
        }
        _write_json(run_dir / CHECKPOINT_FILE, state)


def _restore(state: Any, where: Path) -> tuple[int, list, dict[int, TallDesign], list[int]]:
    """From a checkpoint: the levels searched, the beam, each height's design and the heights refined."""
    if not isinstance(state, dict):
        raise InputError(f"{where / CHECKPOINT_FILE}: not a tall search checkpoint (expected an object)")
    try:
        done = int(state.get("levels_done", 1))
        kept = [(tuple(rules), int(tied)) for rules, tied in state.get("kept", [[[], 0]])]
        designs = {int(levels): TallDesign.from_json(row) for levels, row in state.get("designs", {}).items()}
        refined = [int(levels) for levels in state.get("refined", [])]
    except (TypeError, ValueError, KeyError, AttributeError) as err:
        raise InputError(f"{where / CHECKPOINT_FILE}: not a tall search checkpoint ({err})") from None
    return done, kept, designs, refined


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
        taught = result.taught[levels]
        writer.writerow(
            [
                levels,
                " ".join(design.rules),
                design.tied,
                design.structure.n_vertices,
                design.structure.n_edges,
                f"{design.static_load:.2f}",
                f"{design.peak:.2f}",
                "yes" if design.holds else "no",
                taught.n_rules,
                f"tall_{levels}.npy",
            ]
        )
    return buffer.getvalue()


def _write_outputs(run_dir: Path, result: TallResult) -> None:
    from evolution.files import atomic_write
    from structgen.domains.structures.render import render_structure
    from structgen.nca import save_weights

    for levels, taught in result.taught.items():
        save_weights(run_dir / f"tall_{levels}.npy", taught.weights)
        taught.grown.save(run_dir / f"tall_{levels}.json")
    atomic_write(run_dir / TABLE_FILE, _table_text(result))
    levels = result.tallest_holding or result.tallest
    grown = result.taught[levels].grown
    holds = "that hold in the transient" if result.designs[levels].holds else "that break in the transient"
    render_structure(
        grown,
        run_dir / "tallest.png",
        title=f"{levels} levels grown by a taught NCA, {holds}: {grown.n_vertices} vertices, {grown.n_edges} edges",
    )


def is_search_folder(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a folder a tall search wrote (``structgen info`` tells it from an evolution run)."""
    return (Path(path) / SETTINGS_FILE).is_file()


def search_summary(run_dir: str | os.PathLike) -> dict[str, Any]:
    """What a tall search folder holds, from its files: its settings, how far it got and each height's design."""
    folder = Path(run_dir)
    settings = _read_json(folder / SETTINGS_FILE)
    state = _read_json(folder / CHECKPOINT_FILE) if (folder / CHECKPOINT_FILE).exists() else {}
    done, _, designs, refined = _restore(state, folder)
    rows = [
        {
            **design.to_json(),
            "levels": levels,
            "vertices": design.structure.n_vertices,
            "edges": design.structure.n_edges,
            "holds_in_transient": design.holds,
        }
        for levels, design in sorted(designs.items())
    ]
    return {
        "run_dir": str(folder),
        "kind": "tall search",
        "settings": settings,
        "levels_searched": done,
        "refined": sorted(refined),
        "finished": bool(state.get("complete")),
        "designs": rows,
    }


def describe_search(summary: dict[str, Any]) -> str:
    """:func:`search_summary` as lines to read."""
    settings = summary["settings"]
    status = "finished" if summary["finished"] else f"searched up to {summary['levels_searched']} levels, unfinished"
    lines = [
        f"{summary['run_dir']}: a tall search (structgen tall), {status}",
        f"settings    levels {settings.get('levels')}, beam {settings.get('beam')}, candidates "
        f"{settings.get('candidates')}, max_vertices {settings.get('max_vertices')}, refine {settings.get('refine')}",
    ]
    for row in summary["designs"]:
        lines.append(
            f"{row['levels']} levels    {' '.join(row['rules'])} (tied {row['tied']}): {row['vertices']} vertices, "
            f"{row['edges']} edges, static {row['static_load']:.1f} N, transient peak {row['peak']:.1f} N"
            + ("" if row["holds_in_transient"] else f" (over the {PHYSICS.break_force:g} N break force)")
        )
    holding = [row["levels"] for row in summary["designs"] if row["holds_in_transient"]]
    if summary["finished"] and holding:
        lines.append(f"tallest     {Path(summary['run_dir']) / f'tall_{max(holding)}.npy'} grows {max(holding)} levels that hold")
    return "\n".join(lines)


def _ignore_interrupts() -> None:
    # Ctrl-C reaches every process of the terminal's group; the parent alone stops the search (and ends the pool), so
    # the workers do not each print a traceback.
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _pool_mapper(workers: int, progress: bool) -> tuple[Mapper, Any]:
    pool = None
    if workers > 1:
        from multiprocessing import Pool

        pool = Pool(workers, initializer=_ignore_interrupts)

    def simulate(function: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        results: Iterable[Any] = (
            pool.imap(function, items, chunksize=max(1, len(items) // (8 * workers))) if pool else map(function, items)
        )
        if progress and sys.stderr.isatty():
            from tqdm import tqdm

            results = tqdm(results, total=len(items), leave=False, unit="design", file=sys.stderr, dynamic_ncols=True)
        return list(results)

    return simulate, pool


def find_tallest(
    settings: TallSettings | None = None,
    run_dir: str | os.PathLike | None = None,
    *,
    workers: int = 1,
    progress: bool = False,
    log: Callable[[str], None] | None = None,
) -> TallResult:
    """Search for the tallest design an NCA can grow with the lowest transient load, teach every height's design,
    and (with ``run_dir``) write it all to a run folder.

    Args:
        settings: what to search (the defaults reach eight levels in about 8 minutes on 2 cores).
        run_dir: a new or empty folder, or one a search with the same settings started (it resumes after the last
            finished height). It receives ``settings.json``, ``search.json`` (the checkpoint), ``designs.csv`` (a row
            per height), ``tall_<levels>.npy`` (the taught weights), ``tall_<levels>.json`` (what they grow) and
            ``tallest.png`` (the tallest that holds in the transient).
        workers: processes for the simulations; results do not depend on it.
        progress: a progress bar on a terminal while candidates are simulated.
        log: called with a line per finished stage (``print`` shows the search as it goes).

    Raises:
        InputError: a run folder that holds something else, or a search with other settings.
    """
    settings = settings or TallSettings()
    if not isinstance(workers, int) or workers < 1:
        raise InputError(f"workers must be a whole number of at least 1, got {workers!r}")
    say = log or (lambda line: None)
    folder = Path(run_dir) if run_dir is not None else None
    state = _open_folder(folder, settings) if folder is not None else {}
    done, kept, designs, refined = _restore(state, folder or Path("."))
    _checkpoint(folder, done, kept, designs, refined)  # not complete until this call's outputs are written
    if done > 1:
        say(f"{folder}: resuming after {done} of {settings.levels} levels ({len(designs)} heights found so far)")
    else:
        say(f"searching designs of 2 to {settings.levels} levels; joints break above {PHYSICS.break_force:g} N")
    started = time.perf_counter()
    simulate, pool = _pool_mapper(workers, progress)
    try:
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
            if designs[levels].holds:
                break
    finally:
        if pool is not None:
            pool.terminate()
    search_seconds = time.perf_counter() - started
    taught, teach_seconds = {}, {}
    for levels, design in sorted(designs.items()):
        clock = time.perf_counter()
        taught[levels] = teach(design.structure)
        teach_seconds[levels] = time.perf_counter() - clock
    result = TallResult(designs, taught, teach_seconds, search_seconds)
    if folder is not None:
        _write_outputs(folder, result)
        _checkpoint(folder, done, kept, designs, refined, complete=True)
    return result
