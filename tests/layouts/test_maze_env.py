"""The batched maze environment: the paper's agent model, checked against the scripted agents' own view and moves,
and the Gymnasium entry points against Gymnasium's checker."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env

from structgen.domains.layouts.maze.env import ENV_ID, STAY, MazeEnv, TorchMazes, random_maze
from structgen.domains.layouts.maze.walkers import _STEPS, FORWARD, LEFT, RIGHT, _State, _view, diameter
from structgen.errors import InputError


def walled(maze: np.ndarray) -> np.ndarray:
    return np.pad(maze == 1, 1, constant_values=True)


def test_the_gymnasium_entry_points_pass_the_checker():
    check_env(gymnasium.make(ENV_ID).unwrapped, skip_render_check=True)  # rendering is checked below
    drawn = gymnasium.make(ENV_ID, render_mode="rgb_array", size=6)
    drawn.reset(seed=0)
    assert drawn.render().shape == (8 * 8, 8 * 8, 3)
    check_env(MazeEnv([random_maze(np.random.default_rng(1), 8, "carved")]), skip_render_check=True)
    vector = gymnasium.make_vec(ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", size=8)
    observation, _ = vector.reset()
    assert observation["view"].shape == (3, 2, 5, 5) and observation["direction"].shape == (3,)
    observation, reward, reached, cut, _ = vector.step(np.array([FORWARD, LEFT, STAY]))
    assert vector.observation_space.contains(observation) and reward.shape == reached.shape == cut.shape == (3,)


@pytest.mark.parametrize("kind", ["scattered", "carved"])
def test_the_view_is_the_scripted_agents_view(kind):
    rng = np.random.default_rng(3)
    mazes = [random_maze(rng, 9, kind) for _ in range(6)]
    batch = TorchMazes(mazes, seed=0)
    for trial in range(20):
        floors = [np.argwhere(walled(m) == 0) for m in mazes]
        cells = [f[rng.integers(len(f))] for f in floors]
        facing = rng.integers(0, 4, len(mazes))
        batch.position = torch.as_tensor([(r + 4) * batch.width + c + 4 for r, c in cells])
        batch.direction = torch.as_tensor(facing)
        view, direction = batch.observe()
        assert direction.tolist() == facing.tolist()
        assert batch.cells().tolist() == [list(map(int, c)) for c in cells]
        for i, maze in enumerate(mazes):
            state = _State((int(cells[i][0]), int(cells[i][1])), int(facing[i]))
            seen = _view(walled(maze), state)
            forward, right = _STEPS[state.facing], _STEPS[(state.facing + 1) % 4]
            goal = tuple(int(x) + 1 for x in diameter(maze)[1])
            for row in range(5):
                for column in range(5):
                    ahead, side = 4 - row, column - 2
                    cell = (
                        state.position[0] + ahead * forward[0] + side * right[0],
                        state.position[1] + ahead * forward[1] + side * right[1],
                    )
                    assert view[i, 0, row, column] == seen.get(cell, True), (trial, i, row, column)
                    assert view[i, 1, row, column] == (cell == goal)


def shortest_actions(maze: np.ndarray, start: tuple[int, int], facing: int, goal: tuple[int, int]) -> list[int]:
    """Turns and steps along a shortest path (breadth-first), as the oracle walks."""
    from collections import deque

    walls = walled(maze)
    previous = {start: None}
    queue = deque([start])
    while queue:
        cell = queue.popleft()
        for dr, dc in _STEPS:
            nxt = (cell[0] + dr, cell[1] + dc)
            if not walls[nxt] and nxt not in previous:
                previous[nxt] = cell
                queue.append(nxt)
    path = [goal]
    while previous[path[-1]] is not None:
        path.append(previous[path[-1]])
    path.reverse()
    actions = []
    for here, there in zip(path, path[1:]):
        wanted = _STEPS.index((there[0] - here[0], there[1] - here[1]))
        while facing != wanted:
            turn = RIGHT if (wanted - facing) % 4 in (1, 2) else LEFT
            actions.append(turn)
            facing = (facing + (1 if turn == RIGHT else -1)) % 4
        actions.append(FORWARD)
    return actions


def test_walking_a_shortest_path_reaches_the_goal_and_the_episode_starts_again():
    maze = random_maze(np.random.default_rng(7), 12, "carved")
    batch = TorchMazes([maze], seed=5)
    batch.reset()
    start, goal, _ = diameter(maze)
    start, goal = (start[0] + 1, start[1] + 1), (goal[0] + 1, goal[1] + 1)
    actions = shortest_actions(maze, start, int(batch.direction[0]), goal)
    for k, action in enumerate(actions):
        _, reward, reached, cut = batch.step(torch.tensor([action]))
        if k < len(actions) - 1:
            assert not reached[0] and not cut[0] and reward[0] == 0
    assert reached[0] and not cut[0]
    assert float(reward[0]) == pytest.approx(1 - 0.9 * len(actions) / batch.horizon)
    assert batch.cells()[0].tolist() == list(start) and int(batch.steps[0]) == 0  # restarted in the same step
    assert tuple(batch.final[0][0].shape) == (2, 5, 5)


def test_standing_still_is_cut_off_at_twice_the_cells_and_walls_stop_a_step():
    maze = np.zeros((4, 4), dtype=np.uint8)
    batch = TorchMazes([maze], seed=0)
    assert batch.horizon == 2 * 6 * 6
    batch.reset()
    for _ in range(batch.horizon - 1):
        _, reward, reached, cut = batch.step(torch.tensor([STAY]))
        assert not cut[0] and not reached[0]
    _, reward, reached, cut = batch.step(torch.tensor([STAY]))
    assert cut[0] and not reached[0] and reward[0] == 0
    # Facing the outer wall, a step forward goes nowhere.
    batch.reset()
    batch.position[0] = (1 + 4) * batch.width + 1 + 4  # the top-left floor cell
    batch.direction[0] = 0  # north: the outer wall
    batch.step(torch.tensor([FORWARD]))
    assert batch.cells()[0].tolist() == [1, 1]


def test_starting_directions_repeat_with_the_seed_and_levels_can_be_swapped():
    rng = np.random.default_rng(0)
    mazes = [random_maze(rng, 8) for _ in range(16)]
    a, b, c = TorchMazes(mazes, seed=3), TorchMazes(mazes, seed=3), TorchMazes(mazes, seed=4)
    assert a.direction.tolist() == b.direction.tolist() != c.direction.tolist()
    other = random_maze(rng, 8, "carved")
    a.set_levels([other], rows=[2])
    start = tuple(int(x) + 1 for x in diameter(other)[0])
    assert a.cells()[2].tolist() == list(start) and int(a.steps[2]) == 0
    with pytest.raises(InputError, match="cannot join a batch of"):
        a.set_levels([random_maze(rng, 9)], rows=[0])


@pytest.mark.parametrize("size", [9, 16, 33])
def test_a_perfect_maze_joins_any_two_floor_cells_by_exactly_one_path(size):
    rng = np.random.default_rng(size)
    for _ in range(5):
        floor = random_maze(rng, size, "perfect") == 0
        cells = int(floor.sum())
        edges = int((floor[1:] & floor[:-1]).sum() + (floor[:, 1:] & floor[:, :-1]).sum())
        # connected (every floor cell reached from one) with one edge fewer than cells: a tree
        start = tuple(np.argwhere(floor)[0])
        seen, stack = {start}, [start]
        while stack:
            r, c = stack.pop()
            for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                n = (r + dr, c + dc)
                if 0 <= n[0] < size and 0 <= n[1] < size and floor[n] and n not in seen:
                    seen.add(n)
                    stack.append(n)
        assert len(seen) == cells and edges == cells - 1
    with pytest.raises(InputError, match="a perfect maze has no knocked-down walls"):
        random_maze(rng, size, "perfect", density=0.05)


def test_random_mazes_are_solvable_and_bad_requests_are_refused():
    rng = np.random.default_rng(2)
    for kind in ("scattered", "carved", "rooms", "perfect"):
        for _ in range(10):
            maze = random_maze(rng, 16, kind)
            assert maze.shape == (16, 16) and set(np.unique(maze)) <= {0, 1} and diameter(maze) is not None
    with pytest.raises(InputError, match="unknown maze kind 'spiral'"):
        random_maze(rng, 16, "spiral")
    with pytest.raises(InputError, match="maze size must be an integer from 2 to 1024, got 1"):
        MazeEnv(size=1)
    with pytest.raises(InputError, match="no two connected floor cells"):
        TorchMazes([np.ones((5, 5), dtype=np.uint8)])
