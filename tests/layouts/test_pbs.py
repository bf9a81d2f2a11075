"""The ``pbs`` planner's rules (RHCR's start-cell rules, its replanning cap, search order and failed-round repair),
each on a small hand-drawn map where it decides the outcome. The moves of whole simulations are checked by the
plain checker in test_simulator.py."""

from __future__ import annotations

import numpy as np
import pytest

from structgen.domains.layouts.kinds import WAREHOUSE
from structgen.domains.layouts.warehouse import _mapf, _pbs
from structgen.domains.layouts.warehouse.simulator import distance_tables, simulate
from tests.layouts.test_simulator import check_moves, small_warehouse

WINDOW = 10


def first_collision(paths: np.ndarray) -> int:
    """The first step at which two of ``paths`` share a cell or swap cells, or -1 (plain code, no index)."""
    for t in range(1, paths.shape[1]):
        if len(set(paths[:, t].tolist())) < len(paths):
            return t
        moves = {(int(u), int(v)) for u, v in zip(paths[:, t - 1], paths[:, t]) if u != v}
        if any((v, u) in moves for u, v in moves):
            return t
    return -1


def plan_round(rows, starts, goals, *, task=None, rules=_pbs.ALL_RULES, cap=5, budget=1000, order=None):
    """One planning round on the map drawn in ``rows`` ('.' floor, '@' wall); ``starts`` and ``goals`` as
    ``(row, col)``. ``task``: an agent standing on its start for a task of that many more steps, as ``(agent,
    steps)``. Returns pbs_window's ``(paths, nodes, gave_up, failed children)`` with paths as ``(row, col)``
    pairs."""
    passable = np.array([[c != "@" for c in row] for row in rows])
    cols = passable.shape[1]
    neighbours = _mapf.grid_neighbours(passable)
    flat = lambda cell: cell[0] * cols + cell[1]  # noqa: E731
    positions = np.array([flat(s) for s in starts], dtype=np.int32)
    goal_cells = np.array([[flat(g)] for g in goals], dtype=np.int32)
    targets = np.unique(goal_cells).astype(np.int32)
    target_of = np.full(passable.size, -1, dtype=np.int32)
    target_of[targets] = np.arange(len(targets), dtype=np.int32)
    waits = np.zeros_like(goal_cells)
    pinned = np.zeros(len(starts), dtype=np.bool_)
    if task is not None:
        agent, steps = task
        goal_cells[agent, 0], waits[agent, 0], pinned[agent] = positions[agent], steps, True
        targets = np.unique(goal_cells).astype(np.int32)
        target_of[:] = -1
        target_of[targets] = np.arange(len(targets), dtype=np.int32)
    order = np.arange(len(starts), dtype=np.int64) if order is None else np.asarray(order, dtype=np.int64)
    paths, nodes, gave_up, failed = _pbs.pbs_window(
        positions, goal_cells, waits, np.ones(len(starts), dtype=np.int64), pinned, target_of,
        distance_tables(neighbours, targets), neighbours, WINDOW, order, budget, -1, rules, cap,
    )  # fmt: skip
    return paths, nodes, gave_up, failed


CORRIDOR = ["....."]  # cells (0, 0) .. (0, 4), one wide


def without(*bits: int) -> int:
    return _pbs.ALL_RULES & ~sum(bits)


def test_rule_1_a_robot_planned_later_keeps_off_the_start_cell_of_one_waiting_there():
    # Robot 0 stands on (0, 2) for a task that fills the window; robot 1 must pass through that cell to reach (0, 4).
    paths, nodes, gave_up, _ = plan_round(CORRIDOR, [(0, 2), (0, 0)], [(0, 2), (0, 4)], task=(0, WINDOW))
    # Planned after robot 0 at the root, robot 1 waits for it: no collision, no search beyond the root.
    assert nodes == 0 and not gave_up and first_collision(paths) == -1
    assert (paths[0] == 2).all() and 2 not in paths[1].tolist()
    # Switched off, the root's paths collide and the search has to branch.
    off = plan_round(CORRIDOR, [(0, 2), (0, 0)], [(0, 2), (0, 4)], task=(0, WINDOW), rules=without(_pbs.OWN_STARTS))
    assert off[1] > 0 and first_collision(off[0]) == -1
    # A start cell is protected only against robots planned after its robot: in index order the other way round,
    # the root's paths collide even with the rule.
    swapped = plan_round(CORRIDOR, [(0, 0), (0, 2)], [(0, 4), (0, 2)], task=(1, WINDOW))
    assert swapped[1] > 0


def test_rule_1_the_low_level_search_honours_owned_cells_only_until_their_robot_leaves():
    passable = np.ones((1, 5), dtype=bool)
    neighbours = _mapf.grid_neighbours(passable)
    targets = np.array([4], dtype=np.int32)
    target_of = np.full(5, -1, dtype=np.int32)
    target_of[4] = 0
    dist = distance_tables(neighbours, targets)
    scratch = _mapf.search_scratch(5, WINDOW, 1)
    occupied = -np.ones((WINDOW + 1, 5), dtype=np.int32)
    owner = np.array([-1, -1, 1, -1, -1], dtype=np.int64)  # robot 1 starts on cell 2
    for leave in (0, 4, WINDOW + 1):
        path = np.empty(WINDOW + 1, dtype=np.int32)
        cost = _mapf._search(0, np.array([4], dtype=np.int32), np.zeros(1, dtype=np.int32), 1, False, target_of, dist,
                             neighbours, occupied, WINDOW, *scratch[:2], leave + 1, *scratch[2:], path, 0, owner,
                             np.array([0, leave], dtype=np.int64), False)  # fmt: skip
        if leave == WINDOW + 1:  # owned for the whole window: it waits in front of it
            assert cost >= 0 and 2 not in path.tolist() and path[-1] == 1
        else:  # on cell 2 only once robot 1 has left it, and as early as that allows
            assert cost >= 0 and 2 not in path[:leave].tolist() and path[max(leave, 2)] == 2


def test_rule_2_a_robot_boxed_in_may_always_keep_waiting_on_its_start_cell():
    passable = np.ones((1, 5), dtype=bool)
    neighbours = _mapf.grid_neighbours(passable)
    target_of = np.full(5, -1, dtype=np.int32)
    target_of[4] = 0
    dist = distance_tables(neighbours, np.array([4], dtype=np.int32))
    scratch = _mapf.search_scratch(5, WINDOW, 1)
    occupied = -np.ones((WINDOW + 1, 5), dtype=np.int32)
    occupied[1:, 1] = occupied[1:, 3] = 7  # both neighbours taken from step 1 on
    occupied[3, 2] = 8  # and its own cell at step 3
    results = []
    for relaxed in (False, True):
        path = np.full(WINDOW + 1, -1, dtype=np.int32)
        cost = _mapf._search(2, np.array([4], dtype=np.int32), np.zeros(1, dtype=np.int32), 1, False, target_of, dist,
                             neighbours, occupied, WINDOW, *scratch[:2], 10 + relaxed, *scratch[2:], path, 0,
                             -np.ones(5, dtype=np.int64), np.zeros(1, dtype=np.int64), relaxed)  # fmt: skip
        results.append((cost, path.tolist()))
    assert results[0][0] == -1
    assert results[1][0] >= 0 and results[1][1] == [2] * (WINDOW + 1)


ROUND_3 = (CORRIDOR, [(0, 0), (0, 2)], [(0, 4), (0, 2)])  # robot 1 on its task at (0, 2), robot 0 to pass it


def test_rule_2_and_3_a_robot_waiting_on_its_start_stays_and_the_mover_plans_again():
    # Robot 1 stands on (0, 2) for a task that fills the window; robot 0, planned first at the root, runs into it
    # there. In the child where robot 0 goes first, robot 1 can only hold its start (rule 2) and robot 0 plans again
    # whatever the order says (rule 3): both children are feasible.
    paths, nodes, gave_up, failed = plan_round(*ROUND_3, task=(1, WINDOW))
    assert not gave_up and failed == 0 and nodes == 2 and first_collision(paths) == -1
    assert (paths[1] == 2).all() and 2 not in paths[0].tolist()
    # Without rule 3 the lower robot would have to leave a cell it cannot leave: that child fails.
    paths, _, gave_up, failed = plan_round(*ROUND_3, task=(1, WINDOW), rules=without(_pbs.WAITING_STAYS))
    assert failed == 1 and not gave_up and first_collision(paths) == -1
    # Without rule 2 its search fails outright: that child fails too.
    assert plan_round(*ROUND_3, task=(1, WINDOW), rules=without(_pbs.HOLD_START))[3] == 1


def test_rule_4_a_child_that_needs_too_many_searches_fails():
    # The child above takes three low-level searches (robot 1 twice: plain, then holding its start; robot 0 once).
    assert plan_round(*ROUND_3, task=(1, WINDOW), cap=2)[3] == 0  # at most 2 x 2 robots = 4 searches
    paths, _, gave_up, failed = plan_round(*ROUND_3, task=(1, WINDOW), cap=1)  # at most 2
    assert failed == 1 and not gave_up and first_collision(paths) == -1  # the other child still solves it


def test_rule_5_a_dead_pair_is_expanded_first_and_ties_go_to_fewer_collisions():
    paths = np.array(
        [
            [0, 1, 2, 3],  # 0 and 1 collide at step 1
            [5, 1, 5, 5],
            [10, 11, 12, 13],  # 2 and 3 collide at step 3
            [20, 21, 22, 13],
            [30, 31, 32, 33],  # 4 and 5 never collide
            [40, 41, 42, 43],
        ],
        dtype=np.int32,
    )
    none = np.empty(0, dtype=np.int64)
    assert _pbs._dead_pair_first(0, 1, paths, none, none, 0) == (0, 1)
    dead_a, dead_b = np.array([4, 2], dtype=np.int64), np.array([5, 3], dtype=np.int64)
    assert _pbs._dead_pair_first(0, 1, paths, dead_a, dead_b, 2) == (2, 3)  # later, but a dead pair
    assert _pbs._dead_pair_first(0, 1, paths, dead_a, dead_b, 1) == (0, 1)  # a dead pair that no longer collides
    both = np.array([True, True])
    cheaper, tied = np.array([7, 5]), np.array([5, 5])
    assert _pbs._second_first(both, cheaper, np.array([0, 9]), _pbs.ALL_RULES)
    assert _pbs._second_first(both, tied, np.array([3, 1]), _pbs.ALL_RULES)
    assert not _pbs._second_first(both, tied, np.array([3, 1]), without(_pbs.SEARCH_ORDER))
    assert not _pbs._second_first(both, tied, np.array([1, 3]), _pbs.ALL_RULES)
    assert _pbs._second_first(np.array([False, True]), np.array([1, 9]), np.array([0, 0]), _pbs.ALL_RULES)
    assert not _pbs._second_first(np.array([True, False]), np.array([9, 1]), np.array([0, 0]), _pbs.ALL_RULES)


def test_rule_6_a_round_out_of_nodes_returns_the_node_collision_free_for_longest():
    # A crowded round of the small warehouse: the more nodes the search may plan, the longer the returned plan stays
    # collision-free (the search visits the same nodes first), until it is collision-free throughout.
    blocked = np.isin(small_warehouse(), WAREHOUSE.blocking_tiles())
    rows = ["".join("@" if b else "." for b in row) for row in blocked]
    open_cells = [tuple(cell) for cell in np.argwhere(~blocked).tolist()]
    picks = np.random.default_rng(1).choice(len(open_cells), 2 * 50, replace=False)
    starts, goals = [open_cells[i] for i in picks[:50]], [open_cells[i] for i in picks[50:]]
    reached = []
    for budget in (0, 1, 2, 4, 8, 16, 64, 4096):
        paths, nodes, gave_up, _ = plan_round(rows, starts, goals, budget=budget)
        assert nodes <= budget + 1
        reached.append(WINDOW + 1 if not gave_up else first_collision(paths))
    assert reached == sorted(reached) and reached[0] < reached[-1] == WINDOW + 1


def test_rule_6_a_failed_plan_is_carried_out_with_waiting_in_each_steps_order():
    # Cells are plain numbers here. Agents 0 and 1 want cell 1 at the first step and 1 comes first in that step's
    # order; agent 2 follows agent 0, so it waits as well; agents 4 and 5 would swap, so neither moves.
    plan = np.array([[0, 1, 3, 3], [2, 1, 4, 4], [5, 0, 6, 6], [7, 7, 7, 7], [10, 11, 11, 11], [11, 10, 10, 10]], dtype=np.int32)
    orders = np.array([[1, 0, 2, 3, 4, 5], [0, 1, 2, 3, 4, 5], [5, 4, 3, 2, 1, 0]])
    out = _pbs.wait_out(plan, plan[:, 0].copy(), 3, orders, 12)
    assert first_collision(out) == -1
    for agent in range(6):  # each walks its own plan, maybe late: its cells are a prefix of the plan, repeats aside
        walked = [c for i, c in enumerate(out[agent].tolist()) if i == 0 or c != out[agent, i - 1]]
        planned = [c for i, c in enumerate(plan[agent].tolist()) if i == 0 or c != plan[agent, i - 1]]
        assert walked == planned[: len(walked)]
    assert out[0].tolist() == [0, 0, 1, 3] and out[1].tolist() == [2, 1, 4, 4] and out[2].tolist() == [5, 5, 0, 6]
    assert (out[4] == 10).all() and (out[5] == 11).all()
    # With agent 0 first at the first step, it takes cell 1 and agent 1 waits instead.
    orders[0] = [0, 1, 2, 3, 4, 5]
    out = _pbs.wait_out(plan, plan[:, 0].copy(), 3, orders, 12)
    assert out[0].tolist() == [0, 1, 3, 3] and out[1].tolist() == [2, 2, 1, 4]


@pytest.mark.parametrize("off", ["own_starts", "hold_start", "waiting_stays", "search_order"])
def test_each_rule_can_be_switched_off_and_moves_stay_legal(off):
    tiles = small_warehouse()
    result = simulate(tiles, 40, 60, seed=2, trace=True, planner="pbs", pbs_off=(off,))
    check_moves(tiles, result.positions)
    assert result.tasks > 0


def test_each_rule_name_switches_off_its_own_bit():
    from structgen.domains.layouts.warehouse.simulator import PBS_RULES

    bits = [getattr(_pbs, name.upper()) for name in PBS_RULES]
    assert sorted(bits) == [1, 2, 4, 8] and sum(bits) == _pbs.ALL_RULES


def test_unknown_rules_and_fallbacks_are_clear_errors():
    from structgen.errors import InputError

    with pytest.raises(InputError, match="pbs_off: unknown rule \\['hold'\\]; choose from own_starts"):
        simulate(small_warehouse(), 4, 10, planner="pbs", pbs_off=("hold",))
    with pytest.raises(InputError, match="unknown fallback 'wait'; choose from repair, pp"):
        simulate(small_warehouse(), 4, 10, planner="pbs", fallback="wait")
    with pytest.raises(InputError, match="replan_cap must be a non-negative integer, got -1"):
        simulate(small_warehouse(), 4, 10, planner="pbs", replan_cap=-1)
