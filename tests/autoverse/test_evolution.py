"""Autoverse through the generic run machinery: the original's (40 + 40) loop in miniature, its growing search
budget, playtraces in the run folder, a run killed with SIGKILL that resumes to the same result; behaviour cloning,
the Gymnasium environments and PPO on what a run leaves."""

from __future__ import annotations

import json
import re

import gymnasium
import numpy as np
import pytest
import torch

from structgen.domains.autoverse.clone import CloneSettings, clone_run, collect_playtraces, split, transitions
from structgen.domains.autoverse.engine import Observation
from structgen.domains.autoverse.game import game_key, random_game
from structgen.domains.autoverse.problem import AutoverseProblem, AutoverseSettings
from structgen.errors import InputError
from tests.helpers import cli, kill_during_evolve, outcome

TINY = """\
[run]
generations = 4
seed = 3
workers = 0

[problem]
name = "autoverse-v0"
budget = 12
budget_step = 12

[optimizer]
name = "ga"
population = 12
parents = 6
initial = 6
"""


def test_budget_grows_after_a_generation_whose_best_passes_half_of_it():
    problem = AutoverseProblem(AutoverseSettings(budget=200, budget_step=200))
    assert problem.next_schedule({"budget": 200}, 100.0) == {"budget": 200}
    assert problem.next_schedule({"budget": 200}, 101.0) == {"budget": 400}
    games = problem.prepare([random_game(np.random.default_rng(0))], {"budget": 400})
    assert games[0]["budget"] == 400


def test_map_only_mutation_keeps_rules_and_rewards():
    rng = np.random.default_rng(2)
    game = random_game(rng)
    as_run = AutoverseProblem(AutoverseSettings(mutation="map_only")).mutate(game, rng)
    assert np.array_equal(as_run["rules"], game["rules"]) and np.array_equal(as_run["rewards"], game["rewards"])
    assert not np.array_equal(as_run["map"], game["map"]) and np.array_equal(as_run["map"][0], game["map"][0])
    described = AutoverseProblem().mutate(game, np.random.default_rng(5))
    rules = described["rules"]
    # the rotations stay rotations of one pattern
    assert all(np.array_equal(rules[:, k], np.rot90(rules[:, 0], k, axes=(-2, -1))) for k in range(4))


@pytest.mark.slow
def test_a_killed_autoverse_run_resumes_to_the_same_result(tmp_path, capsys):
    config = tmp_path / "autoverse.toml"
    config.write_text(TINY)
    code, out, err = cli(capsys, "evolve", config, "--run-dir", tmp_path / "whole")
    assert code == 0, err
    whole = tmp_path / "whole"
    rows = [json.loads(line) for line in (whole / "metrics.jsonl").read_text().splitlines()]
    assert [r["evaluations"] for r in rows] == [6, 12, 18, 24]
    budgets = [r["schedule_budget"] for r in rows]
    assert budgets[0] == 12 and all(b in (a, a + 12) for a, b in zip(budgets, budgets[1:]))
    traces = sorted((whole / "playtraces").glob("gen-*.npz"))
    assert len(traces) == 4
    assert (whole / "best" / "game.png").read_bytes()[:4] == b"\x89PNG"

    run = tmp_path / "killed"
    kill_during_evolve(config, run, 2, limit=300)
    code, out, err = cli(capsys, "resume", run)
    assert code == 0, err
    assert outcome(run) == outcome(whole)
    for mine, theirs in zip(sorted((run / "playtraces").glob("*.npz")), traces):
        a, b = np.load(mine), np.load(theirs)
        assert all(np.array_equal(a[k], b[k]) for k in a.files)

    # every distinct game once, with the best trace found for it; traces replay to their recorded returns
    entries = collect_playtraces(whole, min_fitness=0)
    assert len({game_key(e) for e in entries}) == len(entries)
    views, flats, actions = transitions(entries, Observation(window=5))
    assert len(actions) == sum(len(e["actions"]) for e in entries)
    assert views.shape[1:] == (5, 31, 31) and int(views[:, :, :13].sum()) == 0  # outside the 5x5 window
    parts = split(entries)
    assert sum(len(p) for p in parts.values()) == len(entries)

    report = clone_run(whole, CloneSettings(steps=3, batch_size=8, eval_steps=30, min_fitness=0), tmp_path / "bc", progress=False)
    assert report["transitions"] == sum(len(e["actions"]) for e in parts["train"])
    assert (tmp_path / "bc" / "policy.pt").is_file() and json.loads((tmp_path / "bc" / "report.json").read_text())


def test_gymnasium_environments():
    import structgen.domains.autoverse.gym_env as gym_env

    env = gymnasium.make(gym_env.ENV_ID)
    observation, _ = env.reset(seed=1)
    assert env.observation_space.contains(observation)
    steps = 0
    truncated = False
    while not truncated:
        observation, reward, terminated, truncated, _ = env.step(env.action_space.sample())
        steps += 1
    assert steps == 101 and not terminated
    games = [random_game(np.random.default_rng(i)) for i in range(3)]
    vector = gym_env.AutoverseVectorEnv(3, games)
    observation, _ = vector.reset()
    assert observation["view"].shape == (3, 5, 31, 31)
    for _ in range(101):
        observation, reward, terminated, truncated, info = vector.step(np.zeros(3, dtype=np.int64))
    assert truncated.all() and "final_obs" in info
    # after the restart the observation is the initial one again
    first, _ = gym_env.AutoverseVectorEnv(3, games).reset()
    assert np.array_equal(observation["view"], first["view"])


def test_ppo_runs_and_reports_returns():
    from structgen.domains.autoverse.ppo import PPOSettings, train_ppo

    games = [random_game(np.random.default_rng(i)) for i in range(2)]
    policy, history = train_ppo(games, PPOSettings(envs=4, steps=101, updates=2, epochs=1, minibatches=2, hidden=8))
    assert len(history) == 2 and all(np.isfinite(history))
    logits, value = policy(torch.zeros(1, 5, 31, 31), torch.zeros(1, 1811))
    assert logits.shape == (1, 5) and value.shape == (1,)


def _playtraces(games: list, **changes) -> dict:
    arrays = {
        "rules": np.stack([g["rules"] for g in games]),
        "rewards": np.stack([g["rewards"] for g in games]),
        "map": np.stack([g["map"] for g in games]),
        "actions": np.full((len(games), 101), 2, dtype=np.int8),
        "fitness": np.full(len(games), 5.0),
        "best_return": np.full(len(games), 3.0),
    }
    arrays.update(changes)
    return {name: value for name, value in arrays.items() if value is not None}


def _bad_maps(games):
    maps = np.stack([g["map"] for g in games])
    maps[0, 2, 0, 0] = 7
    return maps


def _bad_rules(games):
    rules = np.stack([g["rules"] for g in games])
    rules[0, 0, 0, 1, 2, 0, 0] = 5
    return rules


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda games: {"fitness": None}, "not a playtrace file (it lacks fitness)"),
        (lambda games: {"fitness": np.full(len(games) + 1, 5.0)}, "hold different numbers of games"),
        (lambda games: {"map": _bad_maps(games)}, "game 0.map: values must be in (0, 1), got [7]"),
        (lambda games: {"rules": _bad_rules(games)}, "game 0.rules: values must be in (-1, 0, 1), got [5]"),
        (lambda games: {"rewards": np.full((len(games), 5), 100, dtype=np.int8)}, "game 0.rewards: values must be in"),
        (lambda games: {"actions": np.full((len(games), 101), 9, dtype=np.int8)}, "actions must be a table of -1"),
        (lambda games: {"fitness": np.full(len(games), np.nan)}, "fitness and best_return must be finite"),
        (lambda games: {"fitness": np.array([{"x": 1}] * len(games), dtype=object)}, "not a playtrace file"),
    ],
)
def test_a_tampered_playtrace_file_is_refused_naming_it(tmp_path, capsys, change, message):
    games = [random_game(np.random.default_rng(seed)) for seed in range(3)]
    (tmp_path / "run" / "playtraces").mkdir(parents=True)
    path = tmp_path / "run" / "playtraces" / "gen-000001.npz"
    np.savez(path, **_playtraces(games, **change(games)))
    with pytest.raises(InputError, match=re.escape(message)):
        collect_playtraces(tmp_path / "run", min_fitness=0)
    code, out, err = cli(capsys, "autoverse", "clone", tmp_path / "run", "-o", tmp_path / "bc", "--steps", 1)
    assert code == 2 and "gen-000001.npz" in err and not (tmp_path / "bc").exists()


def test_a_fifo_among_the_playtraces_is_refused_at_once_not_waited_on(tmp_path, capsys):
    import os

    (tmp_path / "run" / "playtraces").mkdir(parents=True)
    os.mkfifo(tmp_path / "run" / "playtraces" / "gen-000001.npz")
    code, out, err = cli(capsys, "autoverse", "clone", tmp_path / "run", "-o", tmp_path / "bc", "--steps", 1)
    assert code == 2 and "gen-000001.npz" in err and "FIFO" in err
