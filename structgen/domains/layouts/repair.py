"""Repair: the fewest tile changes that make a grown layout valid, as a mixed-integer program solved by HiGHS.

The model follows the original's (research notes 1.4), written from its description:

- one tile per cell; binary ``x[t, i]`` for each tile ``t`` the cell may take;
- warehouse: the exact shelf count; the workstation columns fixed (so only the storage area has variables); every
  shelf next to an endpoint and every endpoint next to a shelf; every floor, endpoint and workstation cell reached by
  a single-commodity flow from one workstation, which cannot leave a shelf or another workstation;
- manufacturing: at least one station of each kind, at most ``cells - agents`` stations, every station next to an
  endpoint and the other way round, one endpoint chosen as the flow's source (written back as an endpoint), stations
  blocking the flow. Unlike the original, one "station" channel stands for the three kinds (a witness per kind
  keeps "one of each"), and new stations take the kinds in turn: the optimum is the same number of changes, and
  HiGHS proves it on the original's 33x36 map in about a second instead of stopping at 159 changes after a minute;
- objective: the number of changed cells (the original weighs each change 40, which moves no optimum).

Before the full search of a warehouse map (by default from :data:`ROUNDING_MIN_CELLS` to
:data:`GREEDY_FIRST_CELLS` cells, with at least :data:`ROUNDING_MIN_SECONDS`), the linear relaxation is solved
and the tiles it leaves whole are held while HiGHS solves the much smaller rest: on the original's harder 33x36
maps that finds the optimum in seconds, where HiGHS's own search spent most of the original's minute in cut rounds
before finding it. At large sizes (more than :data:`GREEDY_FIRST_CELLS` cells, by default) a cheap greedy repair
runs first and, if better, is given to HiGHS as its starting solution, so a valid answer exists whatever the time
limit. A layout that the rules cannot satisfy raises :class:`RepairError`; a repair never returns an invalid
layout (every result is checked by the
independent :func:`~structgen.domains.layouts.measures.violations`).
"""

from __future__ import annotations

import dataclasses
import functools
import logging
import time
from dataclasses import dataclass

import numpy as np
from scipy import ndimage, sparse

from structgen.budget import check_memory
from structgen.domains.layouts.kinds import MANUFACTURING, REPAIR_TIME_LIMIT, WAREHOUSE, LayoutKind
from structgen.domains.layouts.measures import broken_cells, neighbour_count, violations
from structgen.domains.layouts.patch import patch_repair
from structgen.errors import InputError

log = logging.getLogger(__name__)

__all__ = [
    "BOUNDED_OPTIONS",
    "GREEDY_AISLE_EVERY",
    "GREEDY_FIRST_CELLS",
    "LOCAL_MAX_SHARE",
    "LOCAL_RADIUS",
    "ROUNDING_MIN_CELLS",
    "REPAIR_GREEDY_BEYOND",
    "ROUNDING_MIN_SECONDS",
    "RepairError",
    "RepairResult",
    "cheap_repair",
    "distance_from_valid",
    "greedy_repair",
    "repair",
]

#: Above this many cells the greedy repair runs first and seeds the MILP.
GREEDY_FIRST_CELLS = 4000
#: Training's default ``greedy_beyond`` (:func:`repair`): HiGHS proved the fewest changes in 0.4 to 1.1 s on the
#: paper's grown 33x36 maps and valid maps with cells changed at random, up to 89 cells from valid; layouts with no
#: shelves, 240 from valid, held it for the whole minute without an answer (measured, docs/layouts.md).
REPAIR_GREEDY_BEYOND = 100
#: The greedy repair leaves every this-many-th column of the storage area free of shelves (where there is room), an
#: aisle across the shelf rows: blocks of ten shelves, as in the paper's human-designed layouts.
GREEDY_AISLE_EVERY = 11
#: A local repair frees the cells within this many steps of a cell that breaks a rule (and the cells that can make
#: up a wrong shelf count) and holds every other cell as it is.
LOCAL_RADIUS = 2
#: ... and is tried only when what it frees is at most this share of the storage area: a map broken all over is the
#: full problem again (measured: the paper's unrepaired 101x102 maps would free 85 and 100 %, and with 53 % freed
#: nothing was found in 110 s; a tiled map frees 28 %).
LOCAL_MAX_SHARE = 0.4
#: Share of the time left that the local repair may use before the full search takes over.
LOCAL_SHARE = 0.5
#: HiGHS's options in a bounded repair (:func:`repair`'s ``bounded``): no sub-MIP heuristics. Neither the time nor
#: the node limit bounds what they do at the root: on a 33x36 manufacturing floor 66 cells from valid (one of the
#: 11 of 2,500 training layouts that reached the minute), they ran sub-MIPs ten deep for 522 s before the first
#: branching, and with RENS and RINS alone switched off the others still held it for the minute. Without any, the
#: root took 8.5 s there; on 22 near-valid warehouse layouts every answer was the same as with them (measured,
#: docs/layouts.md).
BOUNDED_OPTIONS = {
    "mip_heuristic_effort": 0.0,
    "mip_heuristic_run_rens": False,
    "mip_heuristic_run_rins": False,
    "mip_heuristic_run_feasibility_jump": False,
    "mip_heuristic_run_root_reduced_cost": False,
}


class RepairError(InputError):
    """The layout cannot be repaired under the rules (or no valid layout was found in time)."""


@dataclass(frozen=True)
class RepairResult:
    """A repaired layout and how it was found.

    Attributes:
        tiles: the whole repaired map.
        hamming: cells changed.
        optimal: whether HiGHS proved no repair changes fewer cells.
        gap: relative MIP gap at the end (0 when optimal; infinite when no bound is known, as when the greedy
            repair stood in for HiGHS).
        seconds: wall time of the whole repair.
        method: ``"rounded relaxation"`` (optimal without the full search), ``"milp"``, ``"milp from rounded
            relaxation"``, ``"milp from greedy"`` or ``"milp from patch"`` (the full search from that start), or
            ``"greedy"`` or ``"patch"``: the row repair's or the patch repair's layout
            (:func:`~structgen.domains.layouts.patch.patch_repair`), answering for ``greedy_beyond`` or where the
            MILP found nothing, or nothing better, in time (random NCAs' 33x36 layouts, nearly all shelves, can
            leave HiGHS without a layout after 60 s).
        status: HiGHS's model status, in its words.
        searched: whether HiGHS ran (False: ``greedy_beyond`` answered without it).
        timed_out: whether a HiGHS solve stopped at its time limit, so that the answer may differ on another
            machine or another run.
    """

    tiles: np.ndarray
    hamming: int
    optimal: bool
    gap: float
    seconds: float
    method: str
    status: str
    searched: bool = True
    timed_out: bool = False

    @property
    def gap_text(self) -> str:
        """The gap in words: ``"gap 0.9%"``, or ``"no bound known"`` where the gap is infinite."""
        return f"gap {self.gap:.1%}" if np.isfinite(self.gap) else "no bound known"


def _grid_edges(rows: int, cols: int) -> np.ndarray:
    """Directed 4-neighbour edges (from, to) between flat cell indices."""
    index = np.arange(rows * cols).reshape(rows, cols)
    pairs = [
        np.stack([index[:, :-1].ravel(), index[:, 1:].ravel()], 1),
        np.stack([index[:-1, :].ravel(), index[1:, :].ravel()], 1),
    ]
    undirected = np.concatenate(pairs)
    return np.concatenate([undirected, undirected[:, ::-1]])


class _Model:
    """Columns and rows of a MILP gathered as arrays, then handed to HiGHS in one piece."""

    def __init__(self) -> None:
        self.lower: list[np.ndarray] = []
        self.upper: list[np.ndarray] = []
        self.integer: list[np.ndarray] = []
        self.n_cols = 0
        self.rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []  # (row ids, col ids, values)
        self.row_lower: list[np.ndarray] = []
        self.row_upper: list[np.ndarray] = []
        self.n_rows = 0
        # Whether any solve so far stopped at its time limit: then the answer depends on the machine's speed.
        self.timed_out = False
        self.cost: np.ndarray | None = None
        self.changes_offset = 0.0  # changed cells = cost @ values + changes_offset
        self.tile_columns: np.ndarray | None = None  # (tiles, storage cells) column numbers, warehouses only
        self.storage: np.ndarray | None = None  # the cells those columns belong to

    def columns(self, count: int, lower: float, upper: float, integer: bool) -> np.ndarray:
        ids = np.arange(self.n_cols, self.n_cols + count)
        self.n_cols += count
        self.lower.append(np.full(count, lower, dtype=np.float64))
        self.upper.append(np.full(count, upper, dtype=np.float64))
        self.integer.append(np.full(count, 1 if integer else 0, dtype=np.int32))
        return ids

    def constraints(self, count: int, row: np.ndarray, col: np.ndarray, value, lower, upper) -> None:
        """``count`` rows; entries ``(row[k], col[k], value[k])`` with rows numbered from 0 within this call."""
        self.rows.append((np.asarray(row) + self.n_rows, np.asarray(col), np.broadcast_to(value, np.shape(row))))
        self.row_lower.append(np.broadcast_to(np.asarray(lower, dtype=np.float64), (count,)))
        self.row_upper.append(np.broadcast_to(np.asarray(upper, dtype=np.float64), (count,)))
        self.n_rows += count

    def solve(
        self,
        time_limit: float,
        seed: int,
        threads: int,
        start: np.ndarray | None = None,
        node_limit: int | None = None,
        *,
        relax: bool = False,
        fix: np.ndarray | None = None,
        fixed_values: np.ndarray | None = None,
        target: float | None = None,
        bounded: bool = False,
    ) -> _Solution:
        """Solve the model (``relax``: its linear relaxation) with the columns in ``fix`` held at ``fixed_values``,
        stopping at the first layout whose objective is at most ``target`` when that is given; ``bounded``: without
        HiGHS's sub-MIP heuristics (see :data:`BOUNDED_OPTIONS`)."""
        import highspy

        inf = highspy.kHighsInf
        lp = highspy.HighsLp()
        lp.num_col_, lp.num_row_ = self.n_cols, self.n_rows
        lp.col_cost_ = self.cost
        lower, upper = np.concatenate(self.lower), np.concatenate(self.upper)
        if fix is not None:
            lower[fix] = upper[fix] = fixed_values[fix]
        lp.col_lower_, lp.col_upper_ = lower, upper
        lp.row_lower_ = np.where(np.isinf(np.concatenate(self.row_lower)), -inf, np.concatenate(self.row_lower))
        lp.row_upper_ = np.where(np.isinf(np.concatenate(self.row_upper)), inf, np.concatenate(self.row_upper))
        row = np.concatenate([r for r, _, _ in self.rows])
        col = np.concatenate([c for _, c, _ in self.rows])
        value = np.concatenate([np.asarray(v, dtype=np.float64) for _, _, v in self.rows])
        matrix = sparse.csc_matrix((value, (row, col)), shape=(self.n_rows, self.n_cols))
        lp.a_matrix_.format_ = highspy.MatrixFormat.kColwise
        lp.a_matrix_.start_ = matrix.indptr
        lp.a_matrix_.index_ = matrix.indices
        lp.a_matrix_.value_ = matrix.data
        if not relax:
            lp.integrality_ = [highspy.HighsVarType(int(i)) for i in self.integer_columns()]
        h = highspy.Highs()
        h.setOptionValue("output_flag", False)
        h.setOptionValue("time_limit", float(time_limit))
        h.setOptionValue("random_seed", int(seed))
        h.setOptionValue("threads", int(threads))
        h.setOptionValue("mip_rel_gap", 0.0)
        if node_limit is not None:  # unlike the time limit, a node limit stops at the same answer on every machine
            h.setOptionValue("mip_max_nodes", int(node_limit))
        if target is not None:
            h.setOptionValue("objective_target", float(target))
        for option, value in BOUNDED_OPTIONS.items() if bounded else ():
            h.setOptionValue(option, value)
        h.passModel(lp)
        if start is not None:
            solution = highspy.HighsSolution()
            solution.col_value = list(map(float, start))
            solution.value_valid = True
            h.setSolution(solution)
        h.run()
        status = h.getModelStatus()
        self.timed_out |= status == highspy.HighsModelStatus.kTimeLimit
        info = h.getInfo()
        values = np.asarray(h.getSolution().col_value) if info.primal_solution_status == 2 else None
        return _Solution(
            values,
            h.modelStatusToString(status),
            status == highspy.HighsModelStatus.kOptimal,
            float(info.mip_gap) if not relax else 0.0,
            float(info.objective_function_value) if values is not None else np.inf,
        )

    def integer_columns(self) -> np.ndarray:
        return np.concatenate(self.integer).astype(bool)


@dataclass(frozen=True)
class _Solution:
    values: np.ndarray | None  # None: HiGHS found no feasible point
    status: str
    optimal: bool
    gap: float
    objective: float


#: Memory a repair takes per cell of the map (model and solver), measured at 33x36 and 101x102 with room to spare.
REPAIR_BYTES_PER_CELL = 24 << 10


def repair(
    tiles: np.ndarray,
    kind: LayoutKind = WAREHOUSE,
    *,
    shelves: int | None = None,
    agents: int = 0,
    time_limit: float = REPAIR_TIME_LIMIT,
    seed: int = 0,
    threads: int = 1,
    greedy_first: bool | None = None,
    node_limit: int | None = None,
    round_relaxation: bool | None = None,
    good_enough: int | None = None,
    local_first: bool | None = None,
    greedy_beyond: int | None = None,
    bounded: bool = False,
) -> RepairResult:
    """Repair a whole map (for warehouses, with its workstation columns).

    Args:
        tiles: the map as tile numbers of ``kind``.
        shelves: the exact shelf count (warehouse; required there).
        agents: manufacturing only: the number of cells that must stay free of stations.
        time_limit: seconds for the whole repair (building the model and the greedy start count against it); the best
            layout found by then is returned (with ``optimal`` False). HiGHS is given 5% less (at most 5 s less),
            since one of its presolve steps can overrun its limit by a second or two on a 101x102 map.
        seed: HiGHS's random seed.
        threads: HiGHS's threads.
        greedy_first: run the cheap repairs first (the row repair and the patch repair) and start
            HiGHS from the one with fewer changes; None: above :data:`GREEDY_FIRST_CELLS`.
        node_limit: stop HiGHS after this many branch-and-bound nodes. A repair stopped by the time limit depends
            on the machine's speed; one stopped by a node limit does not. HiGHS has no such limit for its work
            before the first branching, where layouts far from valid can keep it for the whole time limit, so
            only a repair that ends before its time limit is sure to repeat.
        round_relaxation: first solve the linear relaxation and the smaller MILP left by holding the tiles it
            decided (see :func:`_round_the_relaxation`); that answer ends the repair when it meets the relaxation's
            bound and starts HiGHS's full search otherwise. None: for warehouses from :data:`ROUNDING_MIN_CELLS`
            to :data:`GREEDY_FIRST_CELLS` cells given at least :data:`ROUNDING_MIN_SECONDS`, where it was
            measured to help.
        good_enough: end the repair at the first valid layout that changes at most this many cells, proven optimal
            or not (``optimal`` says which). None: search for the fewest changes until the time limit.
        local_first: (warehouses) first try a local repair: the cells that break a rule, those within
            :data:`LOCAL_RADIUS` steps of them, and (when the shelf count is wrong) the cells that can take or give
            up a shelf are solved for, every other cell held as it is; its answer, the fewest changes within that
            region, ends the repair (``method`` "local", not proven optimal). A map whose region is more than
            :data:`LOCAL_MAX_SHARE` of the storage area, or whose region has no answer, goes on to the usual search.
            None: for warehouses above :data:`GREEDY_FIRST_CELLS` cells, where the full search keeps little of a
            large layout's pattern (a tiled 101x102 warehouse: 255 changes in 14 s locally, as many as the
            original's CPLEX made, against 5,528 from the full search in 120 s).
        greedy_beyond: answer a layout more than this many cells from valid (:func:`distance_from_valid`) without
            HiGHS: with the row repair (``method`` "greedy") or the patch repair
            (:func:`~structgen.domains.layouts.patch.patch_repair`, ``method`` "patch", which keeps the growth's
            pattern), whichever changes fewer cells; a row answer that changes no more cells than the shelf count
            must change is the fewest changes and ends any repair (``method`` "greedy", optimal).
            HiGHS spends its whole time limit on layouts far from valid (random NCAs' 33x36 layouts with no shelves:
            a minute, then the greedy answer anyway), and on a layout with no shelf or station at all however near
            it counts (a manufacturing floor of floor cells only), so those take the cheap way too: a training run
            repeats exactly and costs little only if they never reach it. None: every layout goes to HiGHS.
        bounded: a repair whose answer depends on counts, never on the clock: HiGHS without its sub-MIP heuristics
            (:data:`BOUNDED_OPTIONS`), stopped after ``node_limit`` nodes (None: after the root); the time limit is
            then only a safety net (``timed_out`` says if it was reached). An answer HiGHS could not prove the
            fewest changes is compared with the cheap repairs' (:func:`cheap_repair`), the fewer changes kept.
            Training's default (``repair_search = "bounded"``), so that a run repeats exactly.

    Raises:
        RepairError: no valid layout exists under the rules, or neither HiGHS within the time limit nor the greedy
            repair found one.
    """
    began = time.perf_counter()
    tiles = np.asarray(tiles).astype(np.int64)
    if kind.name == "warehouse":
        if shelves is None:
            raise ValueError("a warehouse repair needs the shelf count")
        build = _warehouse_model
    elif kind.name == "manufacturing":
        build = _manufacturing_model
    else:
        raise ValueError(f"{kind.name} layouts have no repair")
    if not time_limit > 0:
        raise ValueError(f"time_limit must be positive, got {time_limit!r}")
    if good_enough is not None and not (isinstance(good_enough, (int, np.integer)) and good_enough >= 0):
        raise ValueError(f"good_enough must be a whole number of changed cells, 0 or more, got {good_enough!r}")
    # About 30 nonzeros a cell, and HiGHS's work on them: 210 MiB for a 101x102 map, measured (beside Python's own).
    check_memory(tiles.size * REPAIR_BYTES_PER_CELL, f"the repair of a {tiles.shape[0]}x{tiles.shape[1]} map", "a smaller map")
    if bounded and node_limit is None:
        node_limit = 1
    log.info("repairing a %dx%d %s layout with HiGHS, at most %g s", *tiles.shape, kind.name, time_limit)
    # The cheap repairs' answer, made at most once: the routing, the greedy start and the fallbacks below share it.
    cheap = functools.cache(lambda: cheap_repair(tiles, kind, shelves=shelves, agents=agents))
    if greedy_beyond is not None:
        routed = _greedy_route(tiles, kind, shelves, agents, greedy_beyond, began, cheap)
        if routed is not None:
            return routed
    model, decode, encode = build(tiles, shelves=shelves, agents=agents)
    # HiGHS checks its clock between steps, and at 101x102 one presolve step can run 1 to 2.5 s past its limit
    # (measured): keep a margin so that a repair of two minutes ends within its limit.
    deadline = began + time_limit - min(0.05 * time_limit, 5.0)

    def seconds_left(share: float = 1.0) -> float:
        return max(share * (deadline - time.perf_counter()), 0.01)

    solution = None
    method = "local"
    if local_first if local_first is not None else kind.name == "warehouse" and tiles.size > GREEDY_FIRST_CELLS:
        if kind.name != "warehouse":
            raise ValueError("the local repair is for warehouses")
        solution = _repair_locally(
            model, encode, tiles, kind, shelves, seconds_left(LOCAL_SHARE), seed, threads, node_limit, bounded
        )
    greedy, greedy_method = None, ""
    if solution is None and (greedy_first if greedy_first is not None else tiles.size > GREEDY_FIRST_CELLS):
        greedy, greedy_method = cheap()
        if greedy is None:
            raise RepairError(f"the greedy repair cannot place the {kind.name} layout's shelves")
    start = None if greedy is None else encode(greedy)
    if solution is None:
        method = "milp" if greedy is None else f"milp from {greedy_method}"
    if round_relaxation is None:
        round_relaxation = (
            kind.name == "warehouse"
            and ROUNDING_MIN_CELLS <= tiles.size <= GREEDY_FIRST_CELLS
            and time_limit >= ROUNDING_MIN_SECONDS
        )
    # good_enough as an objective value; changes are whole, so half a change of slack is safe from rounding.
    target = None if good_enough is None else good_enough - model.changes_offset + 0.5
    rounded = None
    if round_relaxation and solution is None:
        rounded = _round_the_relaxation(model, seconds_left, seed, threads, node_limit, bounded)
    if rounded is not None:
        if rounded.optimal or (target is not None and rounded.objective <= target):  # none changes fewer, or need to
            solution, method = rounded, "rounded relaxation"
        elif start is None or rounded.objective < float(model.cost @ start):
            start, method = rounded.values, "milp from rounded relaxation"
    if solution is None:
        solution = model.solve(seconds_left(), seed, threads, start, node_limit, target=target, bounded=bounded)
    if solution.values is None:
        if greedy is not None:
            result, method = greedy, greedy_method
        elif solution.status == "Infeasible":
            raise RepairError(f"no {kind.name} layout of this size satisfies the rules ({_rules(kind, shelves, agents)})")
        else:  # HiGHS ran out of time without a layout: a cheap repair still gives a valid one
            result, method = cheap()
            if result is None:
                raise RepairError(
                    f"the repair found no valid layout within {time_limit:g} s ({solution.status}); allow more time"
                ) from None
    else:
        result = decode(solution.values)
        if bounded and not solution.optimal:  # stopped on a count: a cheap repair may have done better
            other, other_method = cheap()
            if other is not None and (other != tiles).sum() < (result != tiles).sum():
                result, method = other, other_method
    broken = violations(result, kind, shelves=shelves, fixed=tiles if kind.name == "warehouse" else None, agents=agents)
    if broken:  # the model and the checker disagree: never hand out an invalid layout
        raise RepairError(f"the repaired {kind.name} layout is invalid: {'; '.join(broken)}")
    hamming = int((result != tiles).sum())
    optimal = solution.optimal
    return RepairResult(
        result.astype(np.uint8),
        hamming,
        optimal,
        0.0 if optimal else solution.gap,
        time.perf_counter() - began,
        method,
        solution.status,
        timed_out=model.timed_out,
    )


def distance_from_valid(tiles: np.ndarray, kind: LayoutKind = WAREHOUSE, *, shelves: int | None = None) -> int:
    """How far a layout is from valid, in cells: the shelves (warehouse, with ``shelves``) too many or too few plus
    the cells that break a rule of their own (:func:`~structgen.domains.layouts.measures.broken_cells`). The first
    term is a lower bound on any repair's changes; the second says how much of the layout needs rearranging."""
    tiles = np.asarray(tiles)
    return int(broken_cells(tiles, kind).sum()) + _shelves_off(tiles, kind, shelves)


def _shelves_off(tiles: np.ndarray, kind: LayoutKind, shelves: int | None) -> int:
    """Shelves too many or too few (warehouse, with a shelf count): every repair changes at least this many cells."""
    if kind.name != "warehouse" or shelves is None:
        return 0
    return abs(int((tiles == kind.vocabulary.index("@")).sum()) - shelves)


def _greedy_route(tiles, kind, shelves, agents, beyond: int, began: float, cheapest) -> RepairResult | None:
    """:func:`repair`'s answer without HiGHS (see its ``greedy_beyond``), or None where HiGHS should search;
    ``cheapest()`` gives :func:`cheap_repair`'s ``(layout, method)`` for ``tiles``."""
    if not (isinstance(beyond, (int, np.integer)) and beyond >= 0):
        raise ValueError(f"greedy_beyond must be a whole number of cells, 0 or more, got {beyond!r}")
    cheap, method = cheapest()
    if cheap is None:
        return None
    hamming = int((cheap != tiles).sum())
    optimal = hamming <= _shelves_off(tiles, kind, shelves)
    # A layout with no shelf or station at all gives HiGHS nothing to keep, and it stalls before branching (an
    # all-floor 33x36 manufacturing floor, 0 cells from valid by the measure: the whole time limit, no answer of its
    # own; measured with and without node limits), so it takes the cheap way however near it counts.
    keeps_something = bool(np.isin(tiles, kind.blocking_tiles()).any())
    if not optimal and keeps_something and distance_from_valid(tiles, kind, shelves=shelves) <= beyond:
        return None
    broken = violations(cheap, kind, shelves=shelves, fixed=tiles if kind.name == "warehouse" else None, agents=agents)
    if broken:  # as for HiGHS's answers: never hand out an invalid layout
        raise RepairError(f"the {method} {kind.name} layout is invalid: {'; '.join(broken)}")
    status = "optimal: as many changes as the shelf count needs" if optimal else "far from valid: not searched"
    gap = 0.0 if optimal else float("inf")
    seconds = time.perf_counter() - began
    return RepairResult(cheap.astype(np.uint8), hamming, optimal, gap, seconds, method, status, searched=False)


def cheap_repair(
    tiles: np.ndarray, kind: LayoutKind = WAREHOUSE, *, shelves: int | None = None, agents: int = 0
) -> tuple[np.ndarray | None, str]:
    """The router's answer without HiGHS: the row repair's layout (:func:`greedy_repair`, method ``"greedy"``) or
    the patch repair's (:func:`~structgen.domains.layouts.patch.patch_repair`, ``"patch"``, which keeps the
    growth's pattern where the rows replace it), whichever changes fewer cells (ties to the rows, which carry robots
    well); ``(None, "")`` where neither finds a layout. The paper's repair takes the fewest changes; so does this,
    between the two. Deterministic, milliseconds at 33x36."""
    try:
        rows = greedy_repair(tiles, kind, shelves=shelves, agents=agents)
    except RepairError:
        rows = None
    patched = patch_repair(tiles, kind, shelves=shelves, agents=agents, row_offset=_row_offset(rows, kind))
    if patched is not None and (rows is None or (patched != tiles).sum() < (rows != tiles).sum()):
        return patched, "patch"
    return rows, "greedy" if rows is not None else ""


def _row_offset(rows: np.ndarray | None, kind: LayoutKind) -> int:
    """Which rows (``r % 3``) the row repair chose for its shelves: the patch repair adds on the same ones."""
    if rows is None:
        return 0
    shelf_rows = np.flatnonzero(np.isin(rows, kind.blocking_tiles()).any(axis=1))
    return int(shelf_rows[0] % 3) if len(shelf_rows) else 0


#: Share of the time left that the linear relaxation, and then the rounding's smaller MILP, may use.
ROUNDING_SHARE = 0.25
#: Where :func:`repair` rounds the relaxation by default: warehouses of at least this many cells (and at most
#: :data:`GREEDY_FIRST_CELLS`) given at least this many seconds. Below 1,000 cells (9x16) the full search proves the
#: optimum in seconds and the rounding only added its own 1 to 3 s; under 30 s the relaxation's 0.6 to 3 s at 33x36
#: leave too little for the search; above 4,000 cells the relaxation alone outlasted its share of two minutes; and
#: on the original's manufacturing maps the full search did as well without it (all measured, benchmarks/layouts.md).
ROUNDING_MIN_CELLS = 1000
ROUNDING_MIN_SECONDS = 30.0
#: Branch-and-bound nodes the rounding's smaller MILP may use: its answers came from the root on the maps measured,
#: and a rounding that needs a long search is better left to the full one.
ROUNDING_NODES = 100


def _round_the_relaxation(
    model: _Model, seconds_left, seed: int, threads: int, node_limit: int | None, bounded: bool = False
) -> _Solution | None:
    """A layout from the linear relaxation: hold each tile variable the relaxation left whole, solve for the rest.

    On the original's harder 33x36 maps the relaxation's bound is already the optimum or close to it, while HiGHS's
    own search spent 40 to 50 s in cut rounds at the root before its heuristics found that layout (measured). Fixing
    the variables the relaxation decided leaves a MILP with a fourth to a sixth of the tile variables free (on those
    maps), which HiGHS solves in seconds; when its answer meets the bound it is optimal, and otherwise it starts the
    full search. None when either step found nothing in its share of the time.
    """
    relaxed = model.solve(seconds_left(ROUNDING_SHARE), seed, threads, relax=True, bounded=bounded)
    if relaxed.values is None or not relaxed.optimal:
        return None
    integer = model.integer_columns()
    decided = integer & (np.abs(relaxed.values - np.round(relaxed.values)) <= 1e-6)
    nodes = ROUNDING_NODES if node_limit is None else min(node_limit, ROUNDING_NODES)
    rounded = model.solve(
        seconds_left(ROUNDING_SHARE),
        seed,
        threads,
        node_limit=nodes,
        fix=decided,
        fixed_values=np.round(relaxed.values),
        bounded=bounded,
    )
    if rounded.values is None:
        return None
    # Where only integer variables cost anything, and in whole units (changed cells), no layout beats the
    # relaxation's bound rounded up.
    whole = np.array_equal(model.cost, np.round(model.cost)) and not model.cost[~integer].any()
    bound = np.ceil(relaxed.objective - 1e-6) if whole else relaxed.objective
    optimal = bool(rounded.objective <= bound + 1e-6)
    gap = 0.0 if optimal else (rounded.objective - bound) / max(abs(rounded.objective), 1.0)  # HiGHS's definition
    return dataclasses.replace(rounded, optimal=optimal, gap=gap)


def _repair_locally(
    model: _Model, encode, tiles: np.ndarray, kind: LayoutKind, shelves: int, seconds, seed, threads, node_limit, bounded
):
    """The fewest changes within the region around the cells that break a rule, every other cell held (see
    :func:`repair`'s ``local_first``); None when the region is too large or holds no answer."""
    code = kind.vocabulary.index
    storage = model.storage
    region = ndimage.binary_dilation(broken_cells(tiles, kind), iterations=LOCAL_RADIUS)
    shelf = tiles == code("@")
    missing = shelves - int(shelf.sum())
    if missing > 0:  # floor beside an endpoint can take a shelf and keep that endpoint's rule
        region |= (tiles == code(".")) & (neighbour_count(tiles == code("e")) > 0)
    elif missing < 0:  # shelves on the edge of a block can go
        region |= shelf & (neighbour_count(~shelf) > 0)
    region &= storage
    if region.sum() > LOCAL_MAX_SHARE * storage.sum():
        log.info("local repair skipped: it would free %d of %d cells", int(region.sum()), int(storage.sum()))
        return None
    fix = np.zeros(model.n_cols, dtype=bool)
    fix[model.tile_columns[:, ~region[storage]].ravel()] = True
    found = model.solve(seconds, seed, threads, None, node_limit, fix=fix, fixed_values=encode(tiles), bounded=bounded)
    if found.values is None:
        log.info("local repair found nothing (%s); the full search goes on", found.status)
        return None
    # The fewest changes within the region (or the best found in its time), not proven the fewest overall.
    return dataclasses.replace(found, optimal=False, gap=float("inf"))


def _rules(kind: LayoutKind, shelves: int | None, agents: int) -> str:
    if kind.name == "warehouse":
        return f"{shelves} shelves, each next to an endpoint, all floor connected"
    return f"at least one station of each kind, {agents} cells free, all floor connected"


def _warehouse_model(tiles: np.ndarray, *, shelves: int | None, agents: int):
    rows, cols = tiles.shape
    code = WAREHOUSE.vocabulary.index
    border = WAREHOUSE.border
    storage = np.zeros((rows, cols), dtype=bool)
    storage[:, border:-border] = True
    grown = tiles[storage]
    if np.isin(grown, [code("."), code("@"), code("e")], invert=True).any():
        raise RepairError("the storage area holds tiles other than floor, shelf and endpoint")
    n_cells = rows * cols
    cell_var = -np.ones(n_cells, dtype=np.int64)  # storage cell -> its position among the storage cells
    cell_var[storage.ravel()] = np.arange(int(storage.sum()))
    n_storage = int(storage.sum())
    if shelves > n_storage or shelves < 0:
        raise RepairError(f"{shelves} shelves do not fit in a storage area of {n_storage} cells")
    station = np.isin(tiles, [code("w"), code("r"), code("s")]).ravel() & ~storage.ravel()
    stations = np.flatnonzero(station)
    if len(stations) == 0:
        raise RepairError("the map has no workstation for the flow to start from")
    source = int(stations[0])

    model = _Model()
    x = model.columns(3 * n_storage, 0, 1, True).reshape(3, n_storage)  # floor, shelf, endpoint per storage cell
    all_edges = _grid_edges(rows, cols)
    # No flow leaves a workstation other than the source, and none needs to enter the source.
    keep = ~(station[all_edges[:, 0]] & (all_edges[:, 0] != source)) & (all_edges[:, 1] != source)
    edges = all_edges[keep]
    big = float(n_cells)
    flow = model.columns(len(edges), 0, big, False)

    # One tile per storage cell.
    k = np.arange(n_storage)
    model.constraints(n_storage, np.repeat(k, 3), x.T.ravel(), 1.0, 1.0, 1.0)
    # The exact shelf count.
    model.constraints(1, np.zeros(n_storage, dtype=np.int64), x[1], 1.0, shelves, shelves)
    # Adjacency: sum of neighbouring endpoints >= shelf here; sum of neighbouring shelves >= endpoint here.
    both = (cell_var[all_edges[:, 0]] >= 0) & (cell_var[all_edges[:, 1]] >= 0)
    here, there = cell_var[all_edges[both, 0]], cell_var[all_edges[both, 1]]
    for mine, theirs in ((1, 2), (2, 1)):
        model.constraints(
            n_storage,
            np.concatenate([here, k]),
            np.concatenate([x[theirs][there], x[mine][k]]),
            np.concatenate([np.ones(len(here)), -np.ones(n_storage)]),
            0.0,
            np.inf,
        )
    # Capacity: nothing flows out of a shelf.
    out_of_storage = np.flatnonzero(cell_var[edges[:, 0]] >= 0)
    m = len(out_of_storage)
    model.constraints(
        m,
        np.concatenate([np.arange(m), np.arange(m)]),
        np.concatenate([flow[out_of_storage], x[1][cell_var[edges[out_of_storage, 0]]]]),
        np.concatenate([np.ones(m), np.full(m, big)]),
        -np.inf,
        big,
    )
    # Conservation at every cell but the source: inflow - outflow (+ shelf) = 1 (storage) or 1 (border floor and
    # workstations); a shelf takes no unit.
    nodes = np.array([i for i in range(n_cells) if i != source])
    node_row = -np.ones(n_cells, dtype=np.int64)
    node_row[nodes] = np.arange(len(nodes))
    into, out = node_row[edges[:, 1]], node_row[edges[:, 0]]
    r = [into[into >= 0], out[out >= 0]]
    c = [flow[into >= 0], flow[out >= 0]]
    v = [np.ones(int((into >= 0).sum())), -np.ones(int((out >= 0).sum()))]
    in_storage = nodes[cell_var[nodes] >= 0]
    r.append(node_row[in_storage])
    c.append(x[1][cell_var[in_storage]])
    v.append(np.ones(len(in_storage)))
    model.constraints(len(nodes), np.concatenate(r), np.concatenate(c), np.concatenate(v), 1.0, 1.0)

    # Objective: cells whose tile changes, i.e. minus the agreeing x (the constant is left out).
    cost = np.zeros(model.n_cols)
    storage_tiles = tiles.ravel()[storage.ravel()]
    channel = np.select([storage_tiles == code("."), storage_tiles == code("@")], [0, 1], 2)
    cost[x[channel, k]] = -1.0
    model.cost, model.changes_offset = cost, float(len(storage_tiles))
    # Where each storage cell's three tile columns are, for repairs that hold some cells (_repair_locally).
    model.tile_columns, model.storage = x, storage
    channels = np.array([code("."), code("@"), code("e")])

    def decode(values: np.ndarray) -> np.ndarray:
        chosen = values[x].reshape(3, n_storage).argmax(axis=0)
        out_tiles = tiles.copy()
        out_tiles[storage] = channels[chosen]
        return out_tiles

    def encode(layout: np.ndarray) -> np.ndarray:
        values = np.zeros(model.n_cols)
        grown_tiles = layout[storage]
        values[x[np.select([grown_tiles == code("."), grown_tiles == code("@")], [0, 1], 2), k]] = 1.0
        values[flow] = _flow_for(layout.ravel(), edges, source, ~np.isin(layout.ravel(), [code("@")]), station)
        return values

    return model, decode, encode


def _flow_for(layout: np.ndarray, edges: np.ndarray, source: int, open_: np.ndarray, blocked: np.ndarray) -> np.ndarray:
    """Flow on each edge of a valid layout: a breadth-first tree from the source sending one unit to each cell."""
    n = len(layout)
    adjacency: list[list[int]] = [[] for _ in range(n)]
    for e, a in enumerate(edges[:, 0]):
        adjacency[int(a)].append(e)
    parent_edge = -np.ones(n, dtype=np.int64)
    order = [source]
    seen = np.zeros(n, dtype=bool)
    seen[source] = True
    head = 0
    while head < len(order):
        a = order[head]
        head += 1
        if a != source and (blocked[a] or not open_[a]):
            continue
        for e in adjacency[a]:
            b = int(edges[e, 1])
            if not seen[b] and open_[b]:
                seen[b] = True
                parent_edge[b] = e
                order.append(b)
    flow = np.zeros(len(edges))
    load = np.where(seen, 1.0, 0.0)
    load[source] = 0.0
    for b in reversed(order[1:]):
        e = parent_edge[b]
        flow[e] += load[b]
        load[int(edges[e, 0])] += load[b]
    return flow


def _manufacturing_model(tiles: np.ndarray, *, shelves: int | None, agents: int):
    rows, cols = tiles.shape
    code = MANUFACTURING.vocabulary.index
    if np.isin(tiles, [code(c) for c in ".012e"], invert=True).any():
        raise RepairError("the map holds tiles other than floor, the three stations and endpoints")
    n = rows * cols
    if agents > n - 3:
        raise RepairError(f"{agents} agents leave no room for three stations in {n} cells")
    model = _Model()
    # The three station kinds obey the same rules, so one "station" channel stands for all three; with a channel per
    # kind, HiGHS branched through every equivalent way of labelling new stations and missed the original's optimum
    # within its minute. Kinds enter only through "at least one of each": witness[k, i] marks a station counted as
    # kind k, paid for (one change) where the cell held a station of another kind.
    # Channels: floor, station, endpoint, source endpoint.
    x = model.columns(4 * n, 0, 1, True).reshape(4, n)
    witness = model.columns(3 * n, 0, 1, True).reshape(3, n)
    edges = _grid_edges(rows, cols)
    big = float(n)
    flow = model.columns(len(edges), 0, big, False)
    supply = model.columns(n, 0, big, False)
    k = np.arange(n)
    one_row = np.zeros(n, dtype=np.int64)
    model.constraints(n, np.repeat(k, 4), x.T.ravel(), 1.0, 1.0, 1.0)
    model.constraints(1, one_row, x[3], 1.0, 1.0, 1.0)
    for kind in range(3):
        model.constraints(1, one_row, witness[kind], 1.0, 1.0, np.inf)
    model.constraints(n, np.repeat(k, 3), witness.T.ravel(), 1.0, -np.inf, 1.0)
    for kind in range(3):  # a witness only where there is a station
        model.constraints(
            n,
            np.concatenate([k, k]),
            np.concatenate([witness[kind], x[1]]),
            np.concatenate([np.ones(n), -np.ones(n)]),
            -np.inf,
            0.0,
        )
    model.constraints(1, one_row, x[1], 1.0, 0.0, n - agents)
    here, there = edges[:, 0], edges[:, 1]
    for mine, theirs in (((1,), (2, 3)), ((2, 3), (1,))):
        r = [np.tile(here, len(theirs))] + [k] * len(mine)
        c = [x[t][there] for t in theirs] + [x[t] for t in mine]
        v = [np.ones(len(here) * len(theirs))] + [-np.ones(n)] * len(mine)
        model.constraints(n, np.concatenate(r), np.concatenate(c), np.concatenate(v), 0.0, np.inf)
    # Capacity: nothing flows out of a station; the source's supply only where the source is.
    m = len(edges)
    model.constraints(
        m,
        np.concatenate([np.arange(m), np.arange(m)]),
        np.concatenate([flow, x[1][here]]),
        np.concatenate([np.ones(m), np.full(m, big)]),
        -np.inf,
        big,
    )
    model.constraints(
        n, np.concatenate([k, k]), np.concatenate([supply, x[3]]), np.concatenate([np.ones(n), -np.full(n, big)]), -np.inf, 0.0
    )
    # Conservation: supply + inflow - outflow - (floor + endpoint) = 0.
    model.constraints(
        n,
        np.concatenate([k, there, here, k, k]),
        np.concatenate([supply, flow, flow, x[0], x[2]]),
        np.concatenate([np.ones(n), np.ones(m), -np.ones(m), -np.ones(n), -np.ones(n)]),
        0.0,
        0.0,
    )
    flat = tiles.ravel()
    station_kind = np.select([flat == code(c) for c in "012"], [0, 1, 2], -1)
    channel = np.select([flat == code("."), station_kind >= 0], [0, 1], 2)
    cost = np.zeros(model.n_cols)
    cost[x[channel, k]] = -1.0
    cost[x[3, k[flat == code("e")]]] = -1.0  # an endpoint chosen as the source is not a change
    for kind in range(3):
        cost[witness[kind, (station_kind >= 0) & (station_kind != kind)]] = 1.0
    model.cost, model.changes_offset = cost, float(n)
    station_codes = np.array([code(c) for c in "012"])

    def decode(values: np.ndarray) -> np.ndarray:
        chosen = values[x].reshape(4, n).argmax(axis=0)
        out = np.array([code(c) for c in ".0ee"])[chosen]
        station = chosen == 1
        counted = values[witness].reshape(3, n) > 0.5
        kind_here = np.where(counted.any(0), counted.argmax(0), station_kind)
        new = station & (kind_here < 0)
        # New stations cost one change whatever their kind: they take the kinds in turn, in reading order.
        kind_here[new] = np.arange(int(new.sum())) % 3
        out[station] = station_codes[kind_here[station]]
        return out.reshape(rows, cols)

    def encode(layout: np.ndarray) -> np.ndarray:
        values = np.zeros(model.n_cols)
        flat_layout = layout.ravel()
        is_station = np.isin(flat_layout, station_codes)
        chosen = np.select([flat_layout == code("."), is_station], [0, 1], 2)
        source = int(np.flatnonzero(flat_layout == code("e"))[0])
        chosen[source] = 3
        values[x[chosen, k]] = 1.0
        for kind in range(3):
            values[witness[kind, np.flatnonzero(flat_layout == station_codes[kind])[0]]] = 1.0
        sent = _flow_for(flat_layout, edges, source, ~is_station, is_station)
        values[flow] = sent
        values[supply[source]] = sent[edges[:, 0] == source].sum()
        return values

    return model, decode, encode


def greedy_repair(tiles: np.ndarray, kind: LayoutKind = WAREHOUSE, *, shelves: int | None = None, agents: int = 0) -> np.ndarray:
    """A valid layout close to ``tiles``, fast and without a solver.

    Shelves (stations) may stand only on every third row, so the rows between stay open and connect everything
    (through the workstation columns for warehouses, through a gap kept in every shelf row for manufacturing), and
    not in every :data:`GREEDY_AISLE_EVERY`-th column where there is room without it, so robots can also cross the
    shelf rows. Of the three ways to choose those rows, the one that keeps the most of the layout is taken; shelves
    already there are kept first, then the count is made up; each shelf gets an endpoint, preferably one already
    there. Where only some of the candidates are needed they are taken evenly spread over the map, not from its
    top: a greedy layout packed into the top rows congests (measured on random NCAs' 33x36 layouts: throughput 0.1
    with 200 robots where HiGHS's answer with as many changes reached 6)."""
    tiles = np.asarray(tiles).astype(np.int64)
    best = None
    for offset in range(3):
        try:
            candidate = _greedy_rows(tiles, kind, offset, shelves, agents)
        except RepairError:
            continue
        if best is None or (candidate != tiles).sum() < (best != tiles).sum():
            best = candidate
    if best is None:
        raise RepairError(f"the greedy repair cannot place the {kind.name} layout's shelves")
    return best


def _spread(cells: np.ndarray, count: int) -> np.ndarray:
    """``count`` of ``cells`` (in row-major order) evenly spaced over them; all of them if there are no more."""
    if count >= len(cells):
        return cells
    return cells[(np.arange(count) * len(cells)) // count]


def _greedy_rows(tiles: np.ndarray, kind: LayoutKind, offset: int, shelves: int | None, agents: int) -> np.ndarray:
    code = kind.vocabulary.index
    warehouse = kind.name == "warehouse"
    rows, cols = tiles.shape
    area = np.zeros((rows, cols), dtype=bool)
    if warehouse:
        area[:, WAREHOUSE.border : -WAREHOUSE.border] = True
    else:
        area[:] = True
    shelf_tiles = kind.blocking_tiles()
    allowed = area.copy()
    allowed[[r for r in range(rows) if r % 3 != offset]] = False
    if not warehouse:  # keep the first column of every shelf row open, so the open rows connect
        allowed[:, 0] = False
    is_shelf = np.isin(tiles, shelf_tiles)
    result = tiles.copy()
    result[area] = code(".")
    if warehouse:
        want = shelves
    else:
        want = max(min(int((is_shelf & allowed).sum()), rows * cols - agents), 3)
    area_columns = np.flatnonzero(area.any(axis=0))
    aisles = area_columns[np.arange(len(area_columns)) % GREEDY_AISLE_EVERY == GREEDY_AISLE_EVERY - 1]
    with_aisles = allowed.copy()
    with_aisles[:, aisles] = False
    if int(with_aisles.sum()) >= want:
        allowed = with_aisles
    if int(allowed.sum()) < want:
        raise RepairError("not enough room")
    keep = is_shelf & allowed
    chosen = np.zeros_like(keep)
    chosen[tuple(_spread(np.argwhere(keep), want).T)] = True
    if chosen.sum() < want:  # make up the count, preferring cells next to existing endpoints
        endpoint_near = np.zeros((rows, cols), dtype=np.int16)
        e = tiles == code("e")
        endpoint_near[1:] += e[:-1]
        endpoint_near[:-1] += e[1:]
        free = np.argwhere(allowed & ~chosen)
        preference = endpoint_near[tuple(free.T)]
        for level in np.unique(preference)[::-1]:
            missing = want - int(chosen.sum())
            if missing == 0:
                break
            chosen[tuple(_spread(free[preference == level], missing).T)] = True
    if warehouse:
        result[chosen] = code("@")
    else:
        result[chosen] = np.where(is_shelf[chosen], tiles[chosen], code("0"))
        for c in "012":  # one of each kind at least
            if not (result == code(c)).any():
                spots = np.argwhere(chosen & (result != code(c)))
                counts = [(result == code(k)).sum() for k in "012"]
                spots = [s for s in spots if counts["012".index(kind.vocabulary[result[tuple(s)]])] > 1]
                if not spots:
                    raise RepairError("too few stations")
                result[tuple(spots[0])] = code(c)
    # Endpoints: above or below each shelf, keeping the layout's own where they are next to a shelf.
    shelf_now = np.isin(result, shelf_tiles)
    was_endpoint = tiles == code("e")
    for r, c in np.argwhere(shelf_now):
        near = [(r + d, c) for d in (-1, 1) if 0 <= r + d < rows and area[r + d, c]]
        if not near:
            raise RepairError("a shelf row with no room for endpoints")
        if any(result[p] == code("e") for p in near):
            continue
        pick = next((p for p in near if was_endpoint[p]), near[0])
        result[pick] = code("e")
    return result
