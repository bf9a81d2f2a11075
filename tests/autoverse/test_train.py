"""``structgen autoverse train``: cloning then PPO on a run's games, checkpoints that resume exactly, games drawn at
random per episode, regret-driven evolution, and a normalisation that a cascading game cannot blow up."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from structgen.domains.autoverse.clone import Policy, evaluate_policy, normalisation
from structgen.domains.autoverse.engine import Engine, Mechanics, Observation
from structgen.domains.autoverse.game import game_from_json, random_game
from structgen.domains.autoverse.ppo import GamePool
from structgen.domains.autoverse.train import TrainSettings, evolve_pool, regret_scores, train
from tests.autoverse.test_evolution import TINY
from tests.helpers import cli

SMALL = TrainSettings(
    clone_steps=10,
    clone_batch=16,
    updates=4,
    envs=4,
    steps=101,
    epochs=1,
    minibatches=2,
    hidden=8,
    evaluate_every=2,
    eval_steps=101,
    checkpoint_every=2,
    evolve_every=2,
    min_fitness=0.0,
)


@pytest.fixture(scope="module")
def evolved(tmp_path_factory) -> Path:
    """A tiny Autoverse run (4 generations of 6 games) whose playtraces the player learns from."""
    from structgen.cli import main

    folder = tmp_path_factory.mktemp("autoverse")
    config = folder / "tiny.toml"
    config.write_text(TINY)
    assert main(["evolve", str(config), "--run-dir", str(folder / "run")]) == 0
    return folder / "run"


def _weights(folder: Path) -> dict[str, torch.Tensor]:
    return torch.load(folder / "policy.pt", weights_only=True)["policy"]


def _rows(folder: Path) -> list[dict]:
    rows = [json.loads(line) for line in (folder / "history.jsonl").read_text().splitlines()]
    return [{k: v for k, v in row.items() if k != "seconds"} for row in rows]


@pytest.mark.slow
def test_training_clones_then_trains_and_a_stopped_training_resumes_to_the_same_policy(evolved, tmp_path):
    whole = train(evolved, tmp_path / "whole", SMALL, progress=False)
    assert [row["update"] for row in whole] == [0, 1, 2, 3, 4]
    assert all(name in whole[0] for name in ("train", "val", "test"))  # the cloned policy, evaluated
    assert "pool_regret" in whole[2] and "pool_regret" in whole[4] and "pool_regret" not in whole[1]
    for name in ("learning.png", "evolution.png", "cloned.pt", "checkpoint.pt", "policy.pt"):
        assert (tmp_path / "whole" / name).is_file()

    train(evolved, tmp_path / "parts", replace(SMALL, updates=2), progress=False)
    train(evolved, tmp_path / "parts", SMALL, progress=False)  # more updates: goes on from the checkpoint
    mine, theirs = _weights(tmp_path / "parts"), _weights(tmp_path / "whole")
    assert all(torch.equal(mine[key], theirs[key]) for key in theirs)
    assert _rows(tmp_path / "parts") == _rows(tmp_path / "whole")

    # another setting is refused, naming it, and the folder is left as it was
    before = (tmp_path / "whole" / "config.toml").read_text()
    with pytest.raises(Exception, match="train.hidden = 8"):
        train(evolved, tmp_path / "whole", replace(SMALL, hidden=9), progress=False)
    assert (tmp_path / "whole" / "config.toml").read_text() == before


def test_the_command_line_trains_resumes_and_refuses_bad_settings(evolved, tmp_path, capsys):
    out = tmp_path / "player"
    options = ["--clone-steps", "5", "--clone-batch", "8", "--updates", "1", "--envs", "2", "--epochs", "1"]
    options += ["--minibatches", "1", "--hidden", "4", "--eval-steps", "101", "--min-fitness", "0"]
    code, printed, err = cli(capsys, "autoverse", "train", evolved, "-o", out, *options)
    assert code == 0, err
    assert "1 PPO updates" in printed and (out / "learning.png").is_file()
    code, printed, err = cli(capsys, "info", out)
    assert code == 0 and "1 of 1 PPO updates" in printed, err
    code, printed, err = cli(capsys, "resume", out, "--generations", "2")
    assert code == 0 and "2 PPO updates" in printed, err
    with pytest.raises(SystemExit) as refused:  # as the options are read
        cli(capsys, "autoverse", "train", evolved, "-o", tmp_path / "bad", "--evolve-mutation", "everything")
    err = capsys.readouterr().err
    assert refused.value.code == 2 and "--evolve-mutation" in err and "everything" in err and "rules_and_map" in err
    assert not (tmp_path / "bad").exists()


def test_each_episode_plays_a_game_drawn_from_the_pool():
    games = [random_game(np.random.default_rng(seed)) for seed in range(6)]
    pool = GamePool(games, 3, Observation(), "cpu", torch.Generator().manual_seed(0))
    played = [set(pool.state.game.tolist())]
    for _ in range(5 * 101):
        _, _, done = pool.step(torch.zeros(3, dtype=torch.int64))
        if bool(done.any()):
            played.append(set(pool.state.game.tolist()))
    seen = set().union(*played)
    assert len(played) == 6 and len(seen) >= 4  # one environment index is not tied to one game


def test_regret_evolution_keeps_the_games_whose_returns_the_agent_mispredicts_most():
    rng = np.random.default_rng(3)
    games = [random_game(rng) for _ in range(6)]
    torch.manual_seed(0)
    policy = Policy(hidden=8)
    settings = replace(SMALL, evolve_mutation="map_only")
    kept, scores = evolve_pool(policy, games, settings, 6, np.random.default_rng(1), seed=7)
    assert len(kept) == 6 and list(scores) == sorted(scores, reverse=True)
    children = [g for g in kept if not any(g is parent for parent in games)]
    assert all(any(np.array_equal(child["rules"], parent["rules"]) for parent in games) for child in children)  # map_only
    # the scores are the regret of the kept games, as scored alone
    alone = regret_scores(policy, kept, Observation(), SMALL.gamma, seed=7)
    assert alone.shape == (6,) and np.all(alone >= 0)


def test_a_game_whose_rules_cascade_does_not_blow_up_the_normalised_return():
    """From the main job's run: no constant action earns anything, but once force is placed its rules fire hundreds
    of times a step. The original's normalisation keeps scale 1 there (issue 43: one such game made a validation
    mean -6,974); ours also measures one episode of random play."""
    path = Path(__file__).parent / "data" / "cascade_game.json"
    game = game_from_json(json.loads(path.read_text()), str(path))
    engine = Engine([game], mechanics=Mechanics())
    _, original_scale = normalisation(engine, original=True)
    _, scale = normalisation(engine)
    assert float(original_scale[0]) == 1.0 and float(scale[0]) < 1e-3
    torch.manual_seed(0)
    policy = Policy(hidden=8).eval()
    played = evaluate_policy(policy, [game], Observation(), 303, seed=0)
    assert abs(float(played[0])) < 10


def test_the_original_preset_is_the_original_trainers_settings():
    from structgen.domains.autoverse.train_settings import PRESETS

    original = TrainSettings(**PRESETS["original"])
    ppo = original  # PPO takes the training's settings as they are
    assert (ppo.envs, ppo.steps, ppo.epochs, ppo.minibatches, ppo.learning_rate, ppo.hidden) == (100, 200, 10, 4, 1e-5, 256)
    assert (ppo.gamma, ppo.gae_lambda, ppo.clip, ppo.entropy, ppo.value_coef, ppo.max_grad_norm) == (
        0.99,
        0.95,
        0.2,
        0.01,
        0.5,
        0.5,
    )
    assert (original.clone_steps, original.clone_batch, original.clone_learning_rate) == (100_000, 4096, 1e-4)
    with pytest.raises(ValueError, match="train observation padding must be 'wrap' or 'zeros', got 'mirror'"):
        TrainSettings(padding="mirror")


def _tampered_cases(folder: Path) -> dict:
    saved = torch.load(folder / "checkpoint.pt", weights_only=True)
    nan = {k: torch.full_like(v, float("nan")) if v.is_floating_point() else v for k, v in saved["policy"].items()}
    empty_pool = {k: v[:0] for k, v in saved["pool"].items()}
    return {
        "no_update": ("checkpoint.pt", {k: v for k, v in saved.items() if k != "update"}, "'update'"),
        "map_cells_7": (
            "checkpoint.pt",
            {**saved, "pool": {**saved["pool"], "map": torch.full_like(saved["pool"]["map"], 7)}},
            "map: values must be in",
        ),
        "rule_entries_9": (
            "checkpoint.pt",
            {**saved, "pool": {**saved["pool"], "rules": torch.full_like(saved["pool"]["rules"], 9)}},
            "rules: values must be in",
        ),
        "maps_cut_to_8x8": (
            "checkpoint.pt",
            {**saved, "pool": {**saved["pool"], "map": saved["pool"]["map"][..., :8, :8]}},
            "pool maps have shape",
        ),
        "no_pool": ("checkpoint.pt", {k: v for k, v in saved.items() if k != "pool"}, "pool"),
        "empty_pool": ("checkpoint.pt", {**saved, "pool": empty_pool}, "pool"),
        "nan_policy": ("checkpoint.pt", {**saved, "policy": nan}, "NaN"),
        "a_maze_checkpoint": ("checkpoint.pt", {"update": 1, "policy": saved["policy"], "mazes": {}}, "optimiser"),
        "cloned_without_policy": ("cloned.pt", {"evaluation": {}}, "'policy'"),
        "cloned_of_another_shape": ("cloned.pt", {"policy": {k: v[:1] for k, v in saved["policy"].items()}}, "shape"),
    }


@pytest.mark.parametrize(
    "case",
    ["no_update", "no_pool", "empty_pool", "nan_policy", "a_maze_checkpoint", "cloned_without_policy", "cloned_of_another_shape",
     "map_cells_7", "rule_entries_9", "maps_cut_to_8x8"],
)  # fmt: skip
def test_a_tampered_training_folder_is_refused_naming_the_field_and_left_as_it_was(evolved, tmp_path_factory, tmp_path, case):
    import shutil

    from structgen.errors import InputError

    made = tmp_path_factory.getbasetemp() / "player-two-updates"
    if not made.exists():
        train(evolved, made, replace(SMALL, updates=2, evolve_every=0), progress=False)
    folder = tmp_path / "copy"
    shutil.copytree(made, folder, ignore=shutil.ignore_patterns(".lock"))
    name, state, fragment = _tampered_cases(made)[case]
    torch.save(state, folder / name)
    before = {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}
    with pytest.raises(InputError, match=fragment) as refused:
        train(evolved, folder, replace(SMALL, updates=3, evolve_every=0), progress=False)
    assert name in str(refused.value) and "\n" not in str(refused.value)
    assert {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()} == before
