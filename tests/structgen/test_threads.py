"""The thread policy: idle OpenMP threads sleep, threads follow the cores this process may use, the user's settings win."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from structgen import threads

PROBE = """
import json, os, structgen, numba, torch
print(json.dumps({"wait": os.environ.get("OMP_WAIT_POLICY"), "numba": numba.config.NUMBA_NUM_THREADS,
                  "torch": torch.get_num_threads()}))
"""


def probe(env_changes: dict[str, str | None], cpus: set[int] | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMP_", "NUMBA_NUM", "MKL_NUM"))}
    env.update({k: v for k, v in env_changes.items() if v is not None})
    pin = (lambda: os.sched_setaffinity(0, cpus)) if cpus else None
    done = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True, preexec_fn=pin)
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_importing_structgen_makes_idle_threads_sleep_unless_the_user_chose():
    assert probe({})["wait"] == "PASSIVE"
    assert probe({"OMP_WAIT_POLICY": "ACTIVE"})["wait"] == "ACTIVE"


def test_one_variable_sets_both_thread_pools():
    seen = probe({"OMP_NUM_THREADS": "1"})
    assert (seen["torch"], seen["numba"]) == (1, 1)
    assert probe({"OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "2"})["numba"] == 2


@pytest.mark.skipif(not hasattr(os, "sched_getaffinity") or len(os.sched_getaffinity(0)) < 2, reason="needs 2 cores")
def test_a_process_pinned_to_one_core_runs_one_thread_in_each_pool():
    seen = probe({}, cpus={min(os.sched_getaffinity(0))})
    assert (seen["torch"], seen["numba"]) == (1, 1)


@pytest.mark.parametrize(
    ("cpu_max", "expected"), [("max 100000\n", None), ("50000 100000\n", 1), ("100000 100000\n", 1), ("garbage\n", None)]
)
def test_a_container_cpu_quota_caps_the_cores(tmp_path, cpu_max, expected):
    (tmp_path / "cpu.max").write_text(cpu_max)
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert threads.usable_cores(tmp_path / "cpu.max") == (affinity if expected is None else min(affinity, expected))
    assert threads.usable_cores(tmp_path / "absent") == affinity


def test_a_quota_below_the_affinity_mask_sets_the_thread_counts(monkeypatch):
    monkeypatch.setattr(threads, "_affinity_cores", lambda: 8)
    environ: dict[str, str] = {}
    threads.apply_thread_policy(environ, cores=3)
    assert environ == {"OMP_WAIT_POLICY": "PASSIVE", "OMP_NUM_THREADS": "3", "NUMBA_NUM_THREADS": "3"}
    environ = {"OMP_NUM_THREADS": "6"}
    threads.apply_thread_policy(environ, cores=3)
    assert environ["OMP_NUM_THREADS"] == environ["NUMBA_NUM_THREADS"] == "6"


def test_a_nested_openmp_thread_list_is_not_handed_to_numba():
    environ = {"OMP_NUM_THREADS": "4,2"}
    threads.apply_thread_policy(environ, cores=1)
    assert "NUMBA_NUM_THREADS" not in environ


def test_faster_of_times_each_way_then_uses_the_cheaper_and_looks_at_the_other_now_and_then():
    choice = threads.FasterOf(("serial", "parallel"), explore_every=10, trials=2)
    cost = {"serial": 2.0, "parallel": 1.0}
    picks = []
    for _ in range(40):
        way = choice.pick()
        picks.append(way)
        choice.record(way, cost[way] * 64 + (100.0 if picks.count(way) == 1 else 0.0), 64)  # a slow first call
    assert picks[:4] == ["serial", "serial", "parallel", "parallel"]  # each warmed up, then counted
    assert choice.cost == pytest.approx({"serial": 2.0, "parallel": 1.0})  # the first calls left out
    later = picks[10:]
    assert later.count("parallel") > 20 and 2 <= later.count("serial") <= 8  # the other way is still tried
    cost["parallel"] = 5.0  # the machine got busy: the parallel way slowed down
    picks = []
    for _ in range(60):
        way = choice.pick()
        picks.append(way)
        choice.record(way, cost[way] * 64, 64)
    assert choice.cost["serial"] < choice.cost["parallel"]
    assert picks[-20:].count("serial") >= 16  # it went over to the serial way


def test_faster_of_refuses_settings_that_never_use_the_best_way():
    with pytest.raises(ValueError, match="more calls between explorations"):
        threads.FasterOf(explore_every=2, trials=2)


def test_one_torch_thread_restores_the_callers_count():
    import torch

    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        with threads.one_torch_thread():
            assert torch.get_num_threads() == 1
        assert torch.get_num_threads() == 2
        with pytest.raises(RuntimeError), threads.one_torch_thread():
            raise RuntimeError("the block failed")
        assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
