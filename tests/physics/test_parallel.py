"""check_many and CheckPool: worker processes, input order, and failures that stay with their structure."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

from physics import CheckPool, InputError, PhysicsConfig, check_many, check_stability
from structgen.domains.structures.samples import braced, cantilever, column, flat_edge, random_growth

FAST = PhysicsConfig.preset("fast")


def same(a, b) -> bool:
    return (
        a.broken_joints == b.broken_joints
        and np.array_equal(a.final_positions, b.final_positions)
        and (a.integrity, a.height, a.score, a.steps, a.settled) == (b.integrity, b.height, b.score, b.steps, b.settled)
    )


def test_results_come_back_in_input_order_and_match_single_checks():
    structures = [column(4), flat_edge(), braced(4), column(2), cantilever(2), column(3)]
    reports = check_many(structures, FAST, workers=2)
    assert len(reports) == len(structures)
    for structure, report in zip(structures, reports):
        assert same(report, check_stability(structure, FAST))
    assert [r.intact for r in reports] == [False, True, True, True, False, True]


def test_in_process_mode_gives_the_same_reports():
    structures = [random_growth(8, seed, upward=0.1) for seed in range(3)]
    assert all(same(a, b) for a, b in zip(check_many(structures, FAST, workers=0), check_many(structures, FAST, workers=2)))


def test_a_pool_is_reused_across_batches():
    with CheckPool(2) as pool:
        first = pool.check([column(3), column(4)], FAST)
        pids = pool.pids
        second = pool.check([column(3)], FAST)
        assert pool.pids == pids  # the same workers served both batches
    assert first[0].intact and not first[1].intact and second[0].intact
    assert pool.pids == []


def test_a_structure_over_the_size_cap_fails_alone():
    capped = FAST.replace(max_joints=8)
    reports = check_many([column(3), column(6), column(2)], capped, workers=2)
    assert reports[0].intact and reports[2].intact
    assert reports[1].error is not None and "max_joints" in reports[1].error
    assert reports[1].integrity == 0.0 and reports[1].score == 0.0


def test_unreadable_input_is_refused_before_any_work():
    with pytest.raises(InputError, match="cannot read a structure"):
        check_many([column(3), 42], FAST, workers=1)


def test_a_worker_that_dies_fails_only_its_structure():
    long_job = FAST.replace(horizon=200.0, early_stop=False)  # seconds of work for braced(4): time to kill it
    with CheckPool(2) as pool:
        pool.check([flat_edge(), flat_edge()], FAST)  # start both workers first
        victim = pool.pids[0]
        result: list = []
        lone = ([[0, 0, 0]], [])  # no joints: cheap however long the horizon
        runner = threading.Thread(target=lambda: result.extend(pool.check([braced(4), lone, lone], long_job)))
        runner.start()
        time.sleep(0.3)
        os.kill(victim, signal.SIGKILL)
        runner.join(timeout=60)
        assert not runner.is_alive()
        assert victim not in pool.pids  # replaced
    killed, *others = result
    assert killed.error == "the worker died (exit code -9)" and killed.integrity == 0.0
    assert all(r.error is None and r.intact for r in others)


def test_a_structure_that_takes_too_long_times_out_alone():
    # 60 simulated seconds: several seconds of work for 40 vertices, about a tenth of a second for a lone vertex.
    slow = FAST.replace(horizon=60.0, early_stop=False)
    reports = check_many([random_growth(40, 1, extra_edges=0.6), ([[0, 0, 0]], [])], slow, workers=2, timeout=1.0)
    assert reports[0].error == "timed out after 1 s" and reports[0].score == 0.0
    assert reports[1].error is None and reports[1].intact


def test_empty_batch():
    assert check_many([], FAST) == []
