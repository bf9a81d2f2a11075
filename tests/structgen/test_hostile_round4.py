"""Hardening round 4 (issue 55): training folders, weight files and the newer commands refuse bad input in one line
naming the place, exit 2, and change nothing; ``--overwrite`` deletes only a folder of the kind a command writes."""

from __future__ import annotations

import io
import json
import os
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from evolution import RunFolder
from structgen.domains.layouts.maze.training import AgentSettings, save_agent, train_agent
from structgen.errors import InputError
from structgen.runs import manifest
from structgen.runs.training_folder import open_training_folder
from tests.structgen.test_hostile_inputs import FIXTURES, refused, run

TINY = AgentSettings(updates=2, envs=4, steps=8, checkpoint_every=1, evaluate_every=2, hidden=8, buffer=20, size=8)
TINY_OPTIONS = ["--envs", "4", "--steps", "8", "--checkpoint-every", "1", "--evaluate-every", "2", "--hidden", "8"]
TINY_OPTIONS += ["--buffer", "20", "--size", "8"]


@pytest.fixture(scope="module")
def maze_training(tmp_path_factory) -> Path:
    """A finished two-update maze-agent training (checkpoint, history, agent.pt) to copy and tamper with."""
    folder = tmp_path_factory.mktemp("maze") / "run"
    train_agent(folder, TINY, progress=False)
    return folder


def _copy(source: Path, tmp_path: Path) -> Path:
    target = tmp_path / "copy"
    shutil.copytree(source, target)
    os.remove(target / ".lock") if (target / ".lock").exists() else None
    return target


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file() and not p.is_symlink() and p.name != ".lock"}


def _torch_bytes(state) -> bytes:
    buffer = io.BytesIO()
    torch.save(state, buffer)
    return buffer.getvalue()


def _bomb() -> bytes:
    """A zip archive that names itself a torch file and unpacks 300 MiB of zeros (past the 256 MiB limit) from under 1 MiB."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        with archive.open("archive/data/0", "w") as member:
            block = bytes(1 << 20)
            for _ in range(300):
                member.write(block)
    return buffer.getvalue()


class _Payload:
    def __reduce__(self):
        return (print, ("ran",))


def _checkpoint_cases(folder: Path) -> dict:
    """Name: (how to damage the checkpoint or history, what the one-line error must say)."""
    saved = torch.load(folder / "checkpoint.pt", weights_only=True)

    def changed(**fields):
        return lambda path: path.write_bytes(_torch_bytes({**saved, **fields}))

    def without(key):
        return lambda path: path.write_bytes(_torch_bytes({k: v for k, v in saved.items() if k != key}))

    nan_policy = {k: v.clone() for k, v in saved["policy"].items()}
    next(iter(nan_policy.values())).fill_(float("nan"))
    wrong_maps = {**saved["memory"], "maps": saved["memory"]["maps"][:1]}
    return {
        "update_beyond_the_training": (changed(update=10**12), ("checkpoint.pt", "'update'", "1000000000000")),
        "update_missing": (without("update"), ("checkpoint.pt", "'update'")),
        "update_a_fraction": (changed(update=1.5), ("'update'",)),
        "nan_policy": (changed(policy=nan_policy), ("NaN",)),
        "policy_a_list": (changed(policy=[1, 2]), ("'policy'",)),
        "memory_of_another_shape": (changed(memory=wrong_maps), ("memory.maps",)),
        "in_play_names_no_level": (changed(in_play=torch.full_like(saved["in_play"], 10**6)), ("in_play",)),
        "compressed_bomb": (lambda path: path.write_bytes(_bomb()), ("unpacks to more than",)),
        "pickled_object": (lambda path: path.write_bytes(pickle.dumps(_Payload())), ("checkpoint.pt",)),
        "pickled_object_in_zip": (lambda path: torch.save({"update": _Payload()}, path), ("Python objects",)),
        "device_link": (lambda path: (path.unlink(), path.symlink_to("/dev/zero")), ("not a regular file",)),
        "history_garbage": (lambda path: (path.parent / "history.jsonl").write_text("{\n"), ("history.jsonl, line 1",)),
        "history_without_update": (lambda path: (path.parent / "history.jsonl").write_text('{"x": 1}\n'), ("'update'",)),
        "history_text_update": (lambda path: (path.parent / "history.jsonl").write_text('{"update": "2"}\n'), ("'update'",)),
        "history_fifo": (lambda path: ((path.parent / "history.jsonl").unlink(), os.mkfifo(path.parent / "history.jsonl")),
                         ("history.jsonl", "not a regular file")),
    }  # fmt: skip


CHECKPOINT_CASES = [
    "update_beyond_the_training", "update_missing", "update_a_fraction", "nan_policy", "policy_a_list",
    "memory_of_another_shape", "in_play_names_no_level", "compressed_bomb", "pickled_object", "pickled_object_in_zip",
    "device_link", "history_garbage", "history_without_update", "history_text_update", "history_fifo",
]  # fmt: skip


@pytest.mark.parametrize("case", CHECKPOINT_CASES)
def test_a_damaged_training_folder_is_refused_and_left_as_it_was(maze_training, tmp_path, capsys, case):
    folder = _copy(maze_training, tmp_path)
    damage, fragments = _checkpoint_cases(maze_training)[case]
    damage(folder / "checkpoint.pt")
    before = _snapshot(folder)
    refused(capsys, "maze", "train", "--run-dir", folder, *TINY_OPTIONS, "--updates", "4", fragments=fragments)
    assert _snapshot(folder) == before  # config.toml says 2 updates still; no checkpoint written


def test_a_training_another_process_holds_is_refused_before_its_settings_change(maze_training, tmp_path, capsys):
    folder = _copy(maze_training, tmp_path)
    before = _snapshot(folder)
    with RunFolder(folder).locked():
        refused(capsys, "maze", "train", "--run-dir", folder, *TINY_OPTIONS, "--updates", "2000000")
    assert _snapshot(folder) == before


def _agent_cases() -> dict:
    good = {"format": "structgen maze agent 1", "hidden": 8}
    from structgen.domains.layouts.maze.agent import MazePolicy

    weights = MazePolicy(8).state_dict()

    def scaled(value):
        return {k: torch.full_like(v, value) for k, v in weights.items()}

    return {
        "hidden_missing": ({"format": good["format"], "policy": weights}, "'hidden'"),
        "hidden_none": ({**good, "hidden": None, "policy": weights}, "'hidden'"),
        "hidden_negative": ({**good, "hidden": -5, "policy": weights}, "'hidden'"),
        "hidden_huge": ({**good, "hidden": 10**9, "policy": weights}, "'hidden'"),
        "hidden_2_to_70": ({**good, "hidden": 2**70, "policy": weights}, "'hidden'"),
        "hidden_text": ({**good, "hidden": "eight", "policy": weights}, "'hidden'"),
        "hidden_wrong_for_weights": ({**good, "hidden": 9, "policy": weights}, "do not fit"),
        "policy_list": ({**good, "policy": [1.0, 2.0]}, "'policy'"),
        "policy_none": ({**good, "policy": None}, "'policy'"),
        "nan_weights": ({**good, "policy": scaled(float("nan"))}, "NaN"),
        "infinite_weights": ({**good, "policy": scaled(float("inf"))}, "NaN or infinite"),
        "complex_weights": ({**good, "policy": {k: v.to(torch.complex64) for k, v in weights.items()}}, "complex"),
    }


@pytest.mark.parametrize("case", list(_agent_cases()))
def test_a_maze_agent_file_is_checked_field_by_field(tmp_path, capsys, case):
    state, fragment = _agent_cases()[case]
    path = tmp_path / "agent.pt"
    path.write_bytes(_torch_bytes(state))
    refused(capsys, "maze", "test-agent", "--weights", path, "--count", "1", fragments=("agent.pt", fragment))


def test_a_compressed_agent_file_that_inflates_past_its_limit_is_refused_before_it_is_read(tmp_path, capsys):
    path = tmp_path / "agent.pt"
    path.write_bytes(_bomb())
    refused(capsys, "maze", "test-agent", "--weights", path, "--count", "1", fragments=("unpacks to more than",))


def test_a_run_with_broken_agent_weights_is_refused_before_its_first_generation(tmp_path, capsys):
    broken = tmp_path / "broken.pt"
    broken.write_bytes(b"not torch at all")
    refused(
        capsys, "evolve", "--domain", "maze-v0", "--set", "problem.agent=learned", "--set", f"problem.agent_weights={broken}",
        "--run-dir", tmp_path / "run", fragments=("broken.pt",),
    )  # fmt: skip
    assert not (tmp_path / "run" / "metrics.jsonl").exists()


def test_options_out_of_range_are_refused_before_a_folder_is_made(tmp_path, capsys):
    refused(capsys, "maze", "train", "--run-dir", tmp_path / "big", "--envs", "1000000", fragments=("--envs",))
    assert not (tmp_path / "big").exists()
    if not torch.cuda.is_available():
        refused(capsys, "maze", "train", "--run-dir", tmp_path / "gpu", "--device", "cuda", fragments=("cuda",))
        assert not (tmp_path / "gpu").exists()
    for size in ("abc", "0x0", "100000x100000"):
        code, _, err = run(capsys, "maze", "experiment", "--large-size", size, "--small", "a", "--large", "b")
        assert code == 2 and "--large-size" in err, err
    code, _, err = run(capsys, "autoverse", "show", "--builtin", "sokoban", "-o", tmp_path / "a.png", "--actions", "2,,2")
    assert code == 2 and "--actions" in err and not (tmp_path / "a.png").exists()


def test_a_picture_option_refuses_a_name_that_is_not_png(tmp_path, capsys):
    code, _, err = run(capsys, "fortress", "figure", "archive", tmp_path, "-o", tmp_path / "f.jpg")
    assert code == 2 and ".png" in err and not (tmp_path / "f.jpg").exists()


def _evolution_run(path: Path) -> Path:
    RunFolder.create(path, "[run]\ngenerations = 1\n", manifest("sphere-v0", ()))
    (path / "metrics.jsonl").write_text('{"generation": 0}\n')
    return path


def test_overwrite_never_deletes_a_folder_of_another_kind(tmp_path, capsys):
    evolution = _evolution_run(tmp_path / "evolution")
    before = _snapshot(evolution)
    refused(
        capsys, "maze", "train", "--run-dir", evolution, *TINY_OPTIONS, "--overwrite",
        fragments=("an evolution run", "maze-agent"),
    )  # fmt: skip
    assert _snapshot(evolution) == before


def test_overwrite_never_deletes_the_folder_a_command_reads_from(tmp_path):
    training = open_training_folder(
        tmp_path / "player", TINY, run_kind="maze-agent", domain="maze-v0", table="agent", header="t"
    ).path
    with pytest.raises(Exception, match="reads from"):
        open_training_folder(
            training, TINY, run_kind="maze-agent", domain="maze-v0", table="agent", header="t", overwrite=True,
            reads=(training / "inside",),
        )  # fmt: skip
    assert (training / "config.toml").is_file()


def test_a_refused_resume_leaves_config_toml_as_it_was(tmp_path, capsys):
    folder = tmp_path / "run"
    shutil.copytree(FIXTURES / "ones_map_elites", folder)
    (folder / "metrics.jsonl").write_text("{not json\n")
    before = (folder / "config.toml").read_bytes()
    refused(capsys, "resume", folder, "--generations", "50", fragments=("metrics.jsonl",))
    assert (folder / "config.toml").read_bytes() == before


def test_a_seed_folder_with_other_settings_is_not_merged_into_the_fortress_table(tmp_path, capsys):
    out = tmp_path / "out"
    seed_run = out / "seed-20"
    shutil.copytree(FIXTURES / "ones_map_elites", seed_run)
    refused(capsys, "fortress", "experiment", "entities_nodes", out, "--seeds", "20", fragments=("seed-20",))
    (tmp_path / "file").write_text("")
    refused(capsys, "fortress", "experiment", "entities_nodes", tmp_path / "file", "--seeds", "20", fragments=("not a folder",))
    refused(
        capsys, "fortress", "experiment", "entities_nodes", tmp_path / "o2", "--seeds", "20", "--cluster", "not an address",
        fragments=("--cluster",),
    )  # fmt: skip


def test_a_game_whose_rule_reads_the_player_is_accepted_for_cloning():
    # Games may read the player (a rule that fires where the player stands is part of the language), so the playtraces
    # of such a game are cloning data like any other.
    from structgen.domains.autoverse.clone import transitions
    from structgen.domains.autoverse.engine import Observation
    from structgen.domains.autoverse.game import PLAYER, check_game, random_game

    game = random_game(np.random.default_rng(3))
    game["rules"][0, :, 0, PLAYER, 1, 1] = 1
    checked = check_game(game)
    assert checked["rules"][0, 0, 0, PLAYER, 1, 1] == 1
    entry = {**checked, "actions": np.array([0, 1, 2, 3, 4]), "fitness": 3.0, "best_return": 1.0}
    views, flats, actions = transitions([entry], Observation())
    assert len(actions) == 5 and torch.isfinite(flats).all()


def test_a_tall_checkpoint_with_a_fractional_height_is_refused_by_info(tmp_path, capsys):
    from structgen.domains.structures.tall import CHECKPOINT_FILE, TallSettings, _config_text, _manifest

    settings = TallSettings(levels=3)
    folder = RunFolder.create(tmp_path / "tall", _config_text(settings, 0), _manifest(settings))
    for state, fragment in [
        ({"levels_done": 2.5}, "levels_done"),
        ({"levels_done": 9}, "levels_done"),
        ({"levels_done": 2, "designs": {"2": {"rules": ["nope"], "tied": 0}}}, "rules"),
        ({"levels_done": 2, "refined": [2]}, "refined"),
        ({"levels_done": 2, "complete": "yes"}, "complete"),
        ({"levels_done": 2, "designs": {"\u00b2": {"rules": ["S"], "tied": 0}}}, "designs"),
        ({"levels_done": 2, "designs": {"2" * 5000: {"rules": ["S"], "tied": 0}}}, "designs"),
    ]:
        (folder.path / CHECKPOINT_FILE).write_text(json.dumps(state))
        refused(capsys, "info", folder.path, fragments=(CHECKPOINT_FILE, fragment))


def test_checked_weights_and_unpacking_are_errors_not_crashes(tmp_path):
    from structgen.runs.training_folder import load_torch

    path = tmp_path / "x.pt"
    path.write_bytes(_torch_bytes({"a": torch.zeros(3)}))
    assert torch.equal(load_torch(path, "a test file")["a"], torch.zeros(3))
    path.write_bytes(b"PK\x03\x04 broken")
    with pytest.raises(InputError, match="x.pt: not a test file"):
        load_torch(path, "a test file")
    save_agent(tmp_path / "agent.pt", __import__("structgen.domains.layouts.maze.agent", fromlist=["MazePolicy"]).MazePolicy(8))
    assert load_torch(tmp_path / "agent.pt", "an agent")["hidden"] == 8


@pytest.mark.parametrize("where", ["edge", "position", "node"])
def test_a_fortress_number_of_5000_digits_is_refused_as_input(where):
    from structgen.domains.fortress.formats import parse_entity, parse_fortress

    digits = "9" * 5000
    entity = "k\n-- NODES --\n0: idle\n-- EDGES --\n0-0: step 3\n"
    if where == "edge":
        with pytest.raises(InputError, match="is more than"):
            parse_entity(entity.replace("step 3", f"step {digits}"))
    elif where == "node":
        with pytest.raises(InputError, match="expected"):
            parse_entity(entity.replace("0: idle", f"{digits}0: idle").replace("0-0", f"{digits}-0"))
    else:
        from tests.fortress.own_worlds import GARDEN

        with pytest.raises(InputError, match="position line"):
            parse_fortress(GARDEN.replace("s-[2, 2]", f"s-[{digits}, 2]"))


def test_a_training_that_fails_before_its_first_checkpoint_leaves_nothing_behind(tmp_path, monkeypatch):
    import structgen.domains.layouts.maze.training as maze_training

    def broken(settings):
        raise RuntimeError("the curriculum broke")

    monkeypatch.setattr(maze_training, "Curriculum", broken)
    with pytest.raises(RuntimeError, match="curriculum"):
        train_agent(tmp_path / "new", TINY, progress=False)
    assert not (tmp_path / "new").exists()
    (tmp_path / "mine").mkdir()
    with pytest.raises(RuntimeError, match="curriculum"):
        train_agent(tmp_path / "mine", TINY, progress=False)
    assert (tmp_path / "mine").is_dir() and not any((tmp_path / "mine").iterdir())


def test_an_interrupted_training_keeps_its_folder_for_resume(tmp_path, monkeypatch):
    import structgen.domains.layouts.maze.training as maze_training

    def interrupted(settings):
        raise KeyboardInterrupt

    monkeypatch.setattr(maze_training, "Curriculum", interrupted)
    with pytest.raises(KeyboardInterrupt):
        train_agent(tmp_path / "new", TINY, progress=False)
    assert (tmp_path / "new" / "config.toml").is_file()
    monkeypatch.undo()
    train_agent(tmp_path / "new", TINY, progress=False)  # the same command goes on: from the beginning
    assert (tmp_path / "new" / "agent.pt").is_file()
