"""The learning maze agent: its memory reads only what the view showed and knows where it stands, its training
checkpoints and resumes exactly, the shipped agent solves mazes of a kind it never trained on, and the maze domain
and the paper's experiment use it."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import torch

from structgen.domains.layouts.maze.agent import BLOCK, CHANNELS, CROP, MazePolicy, RememberingMazes, run_agent
from structgen.domains.layouts.maze.env import _MARGIN, TorchMazes, random_maze
from structgen.domains.layouts.maze.experiment import baseline_mazes
from structgen.domains.layouts.maze.training import (
    AgentSettings,
    Curriculum,
    held_out_mazes,
    load_agent,
    shipped_agent_path,
    train_agent,
)
from structgen.domains.layouts.maze.walkers import FORWARD, diameter
from structgen.errors import InputError
from tests.helpers import cli

TINY = AgentSettings(updates=4, envs=8, steps=16, checkpoint_every=2, evaluate_every=2, hidden=16, buffer=70, size=8)


def _random_walk(env: RememberingMazes, steps: int, seed: int):
    generator = torch.Generator().manual_seed(seed)
    for _ in range(steps):
        yield env.step(torch.randint(0, 4, (env.mazes.count,), generator=generator))


def test_the_memory_knows_where_the_agent_stands_from_its_own_moves():
    rng = np.random.default_rng(0)
    mazes = [random_maze(rng, 10, kind) for kind in ("scattered", "carved") * 4]
    env = RememberingMazes(TorchMazes(mazes, seed=1))
    env.reset()
    start = env.mazes.cells().clone()
    moves = 0
    for _, _, done in _random_walk(env, 1500, seed=2):
        start[done] = env.mazes.cells()[done]
        assert torch.equal(env.memory.position, env.mazes.cells() - start)
        moves += int(done.sum())
    assert moves > 0  # some episodes ended and the memory started afresh with them


def _frontier_distance(floor: np.ndarray, wall: np.ndarray, start: tuple[int, int], *, or_here: bool = False) -> int | None:
    """Moves from ``start`` to the nearest other floor cell beside an unseen one (``or_here``: or ``start`` itself),
    through seen floor (a plain BFS)."""
    side = floor.shape[0]
    seen = {start: 0}
    queue = [start]
    for cell in queue:
        r, c = cell
        neighbours = [((r + dr) % side, (c + dc) % side) for dr, dc in ((-1, 0), (0, 1), (1, 0), (0, -1))]
        if (cell != start or or_here) and any(not floor[n] and not wall[n] for n in neighbours):
            return seen[cell]
        for n in neighbours:
            if floor[n] and n not in seen:
                seen[n] = seen[cell] + 1
                queue.append(n)
    return None


def test_the_way_on_leads_to_the_nearest_unexplored_floor_and_then_to_the_goal():
    from structgen.domains.layouts.maze.way_on import first_steps

    rng = np.random.default_rng(3)
    for _ in range(20):
        maze = np.pad(random_maze(rng, 12, "carved"), 1, constant_values=1)
        known = rng.random(maze.shape) < 0.6  # a map with holes in it
        floor, wall = (maze == 0) & known, (maze == 1) & known
        cells = np.argwhere(floor)
        start = tuple(cells[rng.integers(len(cells))])
        maps = np.stack([wall, floor]).reshape(1, 2, -1).astype(np.float32)
        way, length, to_goal = first_steps(maps, np.array([-1]), np.array([start]), 14)
        expected = _frontier_distance(floor, wall, start)
        assert (length[0] if way[0] >= 0 else None) == expected and not to_goal[0]
        if expected:  # the first step is on a shortest path
            step = (start[0] + (-1, 0, 1, 0)[way[0]], start[1] + (0, 1, 0, -1)[way[0]])
            assert floor[step] and _frontier_distance(floor, wall, step, or_here=True) == expected - 1
    # With the goal on the map, the way goes there, however near unexplored floor is.
    floor = np.zeros((5, 5), dtype=bool)
    floor[2, :4] = True
    goal = np.array([2 * 5 + 0])
    maps = np.stack([np.zeros_like(floor), floor]).reshape(1, 2, -1).astype(np.float32)
    way, length, to_goal = first_steps(maps, goal, np.array([[2, 2]]), 5)
    assert (way[0], length[0], to_goal[0]) == (3, 2, True)


def test_following_the_way_on_alone_finds_the_goal_of_every_maze():
    # A policy that only turns towards the way and steps along it is the scripted explorer: the feature is enough to
    # finish perfect mazes, where an agent that only counts its visits lost its bearings.
    rng = np.random.default_rng(7)
    mazes = [random_maze(rng, 16, "perfect") for _ in range(8)]

    class FollowTheWay(MazePolicy):
        def forward(self, patch, coarse, direction, way=None):
            ahead, right, behind, left = way[:, 0], way[:, 1], way[:, 2], way[:, 3]
            logits = torch.full((len(way), 4), -30.0)
            logits[:, 2] = torch.where(ahead > 0, 30.0, -30.0)  # forward
            logits[:, 1] = torch.where((right > 0) | (behind > 0), 30.0, -30.0)  # right
            logits[:, 0] = torch.where((left > 0) | (way[:, :4].sum(1) == 0), 30.0, -30.0)  # left: also to look
            return logits, torch.zeros(len(way))

    follower = FollowTheWay(8, way_on=True)
    assert run_agent(follower, mazes, seed=0).success_rate == 1.0
    env = RememberingMazes(TorchMazes(mazes[:2], seed=0), way_on=True)
    patch, coarse, direction, way = env.reset()
    assert way.shape == (2, 6) and patch.shape == (2, 4, CROP, CROP)


def test_the_map_around_the_agent_holds_only_what_it_saw_and_faces_its_way():
    rng = np.random.default_rng(4)
    mazes = [random_maze(rng, 12, "carved") for _ in range(4)]
    env = RememberingMazes(TorchMazes(mazes, seed=0))
    env.reset()
    for (patch, _, direction), _, _ in _random_walk(env, 60, seed=5):
        for row in range(len(mazes)):
            walls = np.pad(env.mazes.walls[row].reshape(-1, env.mazes.width).numpy(), 0)
            here = int(env.mazes.position[row])
            r0, c0 = divmod(here, env.mazes.width)
            facing = int(direction[row])
            ahead, right = [(-1, 0), (0, 1), (1, 0), (0, -1)][facing], [(-1, 0), (0, 1), (1, 0), (0, -1)][(facing + 1) % 4]
            seen_wall, seen_floor = patch[row, 0].numpy(), patch[row, 1].numpy()
            assert not (seen_wall * seen_floor).any()
            for i in range(CROP):
                for j in range(CROP):
                    if seen_wall[i, j] or seen_floor[i, j]:
                        forward, side = CROP // 2 - i, j - CROP // 2
                        r, c = r0 + forward * ahead[0] + side * right[0], c0 + forward * ahead[1] + side * right[1]
                        assert bool(walls[r, c]) == bool(seen_wall[i, j])
            # the agent's own cell is floor it has stood on
            assert seen_floor[CROP // 2, CROP // 2] == 1 and patch[row, 2, CROP // 2, CROP // 2] > 0


def test_the_coarse_patch_pools_the_square_around_the_agent_turned_its_way():
    # The reference turns every cell of the CROP * BLOCK square to the agent's facing, then pools it in blocks.
    rng = np.random.default_rng(6)
    mazes = [random_maze(rng, 20, kind) for kind in ("rooms", "perfect", "carved", "rooms")]
    env = RememberingMazes(TorchMazes(mazes, seed=1))
    env.reset()
    side = CROP * BLOCK
    reach = side // 2
    forward, sideways = np.meshgrid(reach - np.arange(side), np.arange(side) - reach, indexing="ij")
    for (_, coarse, direction), _, _ in _random_walk(env, 40, seed=8):
        memory = env.memory
        for row in range(len(mazes)):
            facing = int(direction[row])
            ahead, right = [(-1, 0), (0, 1), (1, 0), (0, -1)][facing], [(-1, 0), (0, 1), (1, 0), (0, -1)][(facing + 1) % 4]
            r = (int(memory.position[row, 0]) + forward * ahead[0] + sideways * right[0]) % memory.side
            c = (int(memory.position[row, 1]) + forward * ahead[1] + sideways * right[1]) % memory.side
            turned = memory.maps[row].reshape(CHANNELS, memory.side, memory.side)[:, r, c]
            turned[2] = (turned[2] > 0).float()
            assert torch.equal(torch.nn.functional.avg_pool2d(turned[None], BLOCK)[0], coarse[row])


def test_a_forward_step_into_a_wall_does_not_move_the_memory():
    maze = np.zeros((6, 6), dtype=np.uint8)
    env = RememberingMazes(TorchMazes([maze], seed=0))
    env.reset()
    for _ in range(12):  # walk into the outer wall and keep pushing
        env.step(torch.tensor([FORWARD]))
    offset = env.mazes.cells()[0] - torch.as_tensor(divmod(int(env.mazes.start[0]), env.mazes.width)) + (_MARGIN - 1)
    assert torch.equal(env.memory.position[0], offset)


def test_run_agent_gives_each_maze_its_own_draws():
    policy = MazePolicy(16)
    mazes = held_out_mazes(8)[:6]
    alone = run_agent(policy, mazes[:2], episodes=3, seed=7)
    together = run_agent(policy, mazes, episodes=3, seed=7)
    assert np.array_equal(alone.steps, together.steps[:2]) and np.array_equal(alone.reached, together.reached[:2])
    again = run_agent(policy, mazes, episodes=3, seed=7)
    assert np.array_equal(again.steps, together.steps)


def test_the_curriculum_keeps_the_highest_scoring_levels_and_edits_them():
    settings = dataclasses.replace(TINY, buffer=3, replay=0.0, edit=1.0)
    curriculum = Curriculum(settings)
    ids = [curriculum.fresh() for _ in range(6)]
    advantages = torch.tensor([[0.1, 0.5, -1.0, 0.9, 0.2, 0.0]])
    curriculum.score(torch.tensor([ids]), advantages, in_play={ids[0]})
    assert set(curriculum.scores) == {ids[1], ids[3], ids[4]}
    assert set(curriculum.levels) == {ids[0], ids[1], ids[3], ids[4]}  # in play or kept
    for _ in range(5):  # a full enough buffer: new levels are edits of kept ones, 1-4 cells flipped
        child = curriculum.levels[curriculum.next_level()]
        differences = [int((child != curriculum.levels[i]).sum()) for i in curriculum.scores]
        assert 1 <= min(differences) <= 4
    copy = Curriculum(settings)
    copy.load_state_dict(curriculum.state_dict())
    assert copy.scores == curriculum.scores and copy.next_level() == curriculum.next_level()


def test_training_resumes_to_the_same_weights_and_writes_its_folder(tmp_path):
    whole, _ = train_agent(tmp_path / "whole", TINY, progress=False)
    train_agent(tmp_path / "parts", dataclasses.replace(TINY, updates=2), progress=False)
    resumed, rows = train_agent(tmp_path / "parts", TINY, progress=False)
    assert all(torch.equal(a, b) for a, b in zip(whole.state_dict().values(), resumed.state_dict().values()))
    assert [row["update"] for row in rows] == [1, 2, 3, 4] and rows[-1]["held_out"] is not None
    for name in ("agent.pt", "checkpoint.pt", "history.jsonl", "learning.png", "config.toml", "manifest.json"):
        assert (tmp_path / "parts" / name).is_file()
    policy, about = load_agent(tmp_path / "parts" / "agent.pt")
    assert about["updates"] == 4 and about["settings"]["hidden"] == 16
    with pytest.raises(InputError, match="agent.envs = 8, not 9"):
        train_agent(tmp_path / "parts", dataclasses.replace(TINY, envs=9), progress=False)


def test_a_training_begun_before_the_way_on_existed_resumes_without_it(tmp_path):
    # structgen 0.4 wrote no way_on into a training's config.toml; such a folder ran without the way on, and must go
    # on so (reading the new default, true, it was refused: its checkpoint's network had no inputs for it).
    old = dataclasses.replace(TINY, updates=2, way_on=False)
    train_agent(tmp_path / "run", old, progress=False)
    config = tmp_path / "run" / "config.toml"
    config.write_text("".join(line for line in config.read_text().splitlines(keepends=True) if "way_on" not in line))
    policy, rows = train_agent(tmp_path / "run", dataclasses.replace(old, updates=3), progress=False)
    assert not policy.way_on and rows[-1]["update"] == 3


def test_a_damaged_agent_or_checkpoint_is_refused_naming_the_file(tmp_path):
    bad = tmp_path / "agent.pt"
    bad.write_bytes(b"not torch")
    with pytest.raises(InputError, match="agent.pt: not a maze agent file"):
        load_agent(bad)
    from structgen.domains.layouts.maze.training import save_agent

    save_agent(bad, MazePolicy(8, way_on=True))
    assert load_agent(bad)[0].way_on and load_agent(bad)[1]["way_on"] is True
    saved = torch.load(bad, weights_only=True)
    torch.save({**saved, "way_on": "yes"}, bad)
    with pytest.raises(InputError, match="agent.pt: 'way_on' must be true or false, got 'yes'"):
        load_agent(bad)
    del saved["way_on"]  # an agent of structgen 0.4: no way on, and its weights fit only that network
    torch.save({**saved, "policy": MazePolicy(8).state_dict()}, bad)
    assert not load_agent(bad)[0].way_on
    train_agent(tmp_path / "run", dataclasses.replace(TINY, updates=2), progress=False)
    (tmp_path / "run" / "checkpoint.pt").write_bytes(b"broken")
    with pytest.raises(InputError, match="checkpoint.pt: not a maze-agent training checkpoint"):
        train_agent(tmp_path / "run", TINY, progress=False)


def test_the_shipped_agent_solves_mazes_of_a_kind_it_never_trained_on():
    policy, about = load_agent(shipped_agent_path())
    # made by the documented defaults (it records the settings of its day; clip, value_coef and max_grad_norm were
    # PPO's own defaults then, as they are the agent's now)
    assert AgentSettings(**about["settings"]) == AgentSettings()
    rng = np.random.default_rng(2026)
    mazes = [random_maze(rng, 16, "rooms") for _ in range(60)]
    assert run_agent(policy, mazes, seed=1).success_rate >= 0.9
    untrained = run_agent(MazePolicy(about["hidden"], way_on=about["way_on"]), mazes, seed=1).success_rate
    assert untrained < 0.5


def test_baselines_match_the_wall_count_and_the_path_length_band():
    reference = random_maze(np.random.default_rng(0), 12, "scattered", 0.3)
    made, lengths, drawn = baseline_mazes(reference, 3, np.random.default_rng(1))
    length = diameter(reference)[2]
    assert drawn >= 3
    for maze, found in zip(made, lengths):
        assert (maze == 1).sum() == (reference == 1).sum()
        assert 0.8 * length <= diameter(maze)[2] == found <= 1.2 * length


def test_the_maze_problem_is_judged_by_the_learned_agent_over_walls_and_path_length():
    from structgen.domains.layouts.problem import LayoutProblem, MazeSettings

    problem = LayoutProblem(MazeSettings(episodes=2))
    assert problem.measure_names == ("walls", "path_length") and problem.measure_ranges == ((0.0, 256.0), (0.0, 648.0))
    genomes = np.random.default_rng(0).normal(0, 0.2, (3, problem.n_params))
    first = problem.evaluate(genomes, np.array([1, 2, 3]))
    maps = problem.grow(genomes)
    for i, tiles in enumerate(maps):
        grown = problem.kind.storage(tiles)
        assert first.measures[i, 0] == (grown == 1).sum() == first.fields["walls"][i]
        assert first.objective[i] == (diameter(grown) is not None)
    alone = problem.evaluate(genomes[1:2], np.array([2]))
    assert np.array_equal(alone.measures[0], first.measures[1])  # a maze's result does not depend on its batch
    assert LayoutProblem(MazeSettings(measures="entropy")).measure_names == ("entropy", "path_length")
    with pytest.raises(ValueError, match="problem measures must be walls or entropy"):
        MazeSettings(measures="doors")


def test_the_agent_commands(tmp_path, capsys):
    code, out, _ = cli(capsys, "maze", "test-agent", "--count", 20, "--json")
    result = json.loads(out)
    assert code == 0 and result["mazes"] == 20 and result["success_rate"] >= 0.8
    code, out, _ = cli(
        capsys,
        "maze",
        "train",
        "--run-dir",
        tmp_path / "run",
        "--updates",
        2,
        "--envs",
        4,
        "--steps",
        8,
        "--hidden",
        8,
        "--size",
        8,
        "--buffer",
        70,
    )
    assert code == 0 and "held-out rooms mazes reached" in out and (tmp_path / "run" / "agent.pt").is_file()
    code, out, _ = cli(capsys, "resume", tmp_path / "run", "--generations", 3)
    assert code == 0 and len((tmp_path / "run" / "history.jsonl").read_text().splitlines()) == 3
    code, out, _ = cli(capsys, "info", tmp_path / "run", "--json")
    assert code == 0 and json.loads(out)["updates_done"] == 3 and json.loads(out)["finished"]
    small, large = (random_maze(np.random.default_rng(s), n, "scattered", 0.3) for s, n in ((1, 8), (2, 12)))
    for name, maze in (("small", small), ("large", large)):
        rows = ["".join("X" if v else " " for v in row) for row in maze]
        (tmp_path / f"{name}.json").write_text(json.dumps({"name": name, "n_row": len(rows), "n_col": len(rows), "layout": rows}))
    code, out, _ = cli(
        capsys,
        "maze",
        "experiment",
        "--small",
        tmp_path / "small.json",
        "--large",
        tmp_path / "large.json",
        "--episodes",
        4,
        "--baselines",
        3,
        "--baseline-episodes",
        2,
        "--json",
    )
    table = json.loads(out)["rows"]
    assert code == 0 and [r["name"] for r in table] == ["grown small", "grown large", "baselines"]
    assert table[2]["mazes"] == 3 and table[2]["walls"] == (large == 1).sum()
    code, _, err = cli(capsys, "maze", "experiment", "--small", tmp_path / "small.json")
    assert code != 0 and "--small FILE and --large FILE" in err
    walled_in = ["XXXX", "X XX", "XX X", "XXXX"]
    (tmp_path / "shut.json").write_text(json.dumps({"name": "shut", "n_row": 4, "n_col": 4, "layout": walled_in}))
    code, _, err = cli(capsys, "maze", "test-agent", tmp_path / "shut.json")
    assert code != 0 and "shut.json: no two floor cells are connected" in err


@pytest.mark.slow
def test_the_experiment_grows_a_runs_elite_small_and_large(tmp_path, capsys):
    config = Path(__file__).resolve().parents[2] / "configs" / "maze_cma_mae.toml"
    code, _, _ = cli(
        capsys,
        "evolve",
        config,
        "--generations",
        1,
        "--workers",
        0,
        "--run-dir",
        tmp_path / "run",
        "--set",
        "problem.episodes=2",
        "--set",
        "optimizer.batch_size=4",
    )
    assert code == 0
    code, out, _ = cli(
        capsys,
        "maze",
        "experiment",
        tmp_path / "run",
        "--large-size",
        "32x32",
        "--episodes",
        3,
        "--baselines",
        2,
        "--baseline-episodes",
        1,
        "--json",
        "--keep",
        tmp_path / "kept",
    )
    result = json.loads(out)
    assert code == 0 and "(elite index:" in result["source"] and "grown at 16x16 and 32x32" in result["source"]
    assert [row["size"] for row in result["rows"]] == ["18x18", "34x34", "34x34"]
    kept = tmp_path / "kept"
    assert json.loads((kept / "experiment.json").read_text()) == result
    # The kept files alone repeat the experiment, and the kept generator regrows the large maze.
    again = ["--episodes", 3, "--baselines", 2, "--baseline-episodes", 1, "--json"]
    code, out, _ = cli(capsys, "maze", "experiment", "--small", kept / "small.json", "--large", kept / "large.json", *again)
    assert code == 0 and json.loads(out)["rows"] == result["rows"]
    code, _, _ = cli(
        capsys, "maze", "grow", "--weights", kept / "generator.npy", "--size", "32x32", "-o", tmp_path / "regrown.json"
    )
    assert code == 0
    assert (
        json.loads((tmp_path / "regrown.json").read_text())["layout"] == json.loads((kept / "large.json").read_text())["layout"]
    )
    code, _, err = cli(capsys, "maze", "experiment", tmp_path / "run", "--keep", kept, *again)
    assert code != 0 and "is not an empty folder" in err
