"""The hand-written games behave as they are meant to, on both engine backends: rules that move the player, end the
episode or remove the player."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
import torch

from structgen.domains.autoverse.engine import DIRECTIONS, Engine
from structgen.domains.autoverse.game import game_from_json, game_key, game_to_json
from structgen.domains.autoverse.library import BUILTIN, builtin_game

BACKENDS = ("numba", "torch")


def turn_and_place(directions: list[int]) -> list[int]:
    """Actions that walk a player facing west (rotation 0) along ``directions``: turn (action 0) until it faces the
    next one, then place force there (action 4), which a rule turns into a step."""
    rot, actions = 0, []
    for direction in directions:
        while rot != direction:
            actions.append(0)
            rot = (rot + 1) % 4
        actions.append(4)
    return actions


def shortest_walk(game: dict, floor: int) -> list[int]:
    """Directions of a shortest walk over floor cells from the player to the goal (tile 4)."""
    plan = game["map"]
    n = plan.shape[1]
    start, goal = tuple(np.argwhere(plan[0])[0]), tuple(np.argwhere(plan[4])[0])
    came: dict = {start: None}
    queue = deque([start])
    while queue:
        cell = queue.popleft()
        for direction, (dy, dx) in enumerate(DIRECTIONS):
            step = ((cell[0] + dy) % n, (cell[1] + dx) % n)
            if step not in came and plan[floor][step]:
                came[step] = (cell, direction)
                queue.append(step)
    walk, cell = [], goal
    while came[cell] is not None:
        cell, direction = came[cell]
        walk.append(direction)
    return walk[::-1]


def play(game: dict, actions: list[int], backend: str) -> tuple[list[float], list[bool], list]:
    engine = Engine([game], backend=backend)
    state, rewards, dones, states = engine.reset(), [], [], []
    for action in actions:
        state, reward, done = engine.step(state, torch.tensor([action]))
        rewards.append(float(reward[0]))
        dones.append(bool(done[0]))
        states.append(state)
    return rewards, dones, states


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_maze_goal_pays_one_and_ends_the_episode_and_walls_block(backend):
    game = builtin_game("maze")
    actions = turn_and_place(shortest_walk(game, floor=3))
    assert len(actions) < 101  # solvable within an episode
    rewards, dones, states = play(game, actions, backend)
    assert dones == [False] * (len(actions) - 1) + [True] and rewards[-1] == 1 and sum(rewards) == 1
    assert states[-1].pos[0].tolist() == [14, 14] and int(states[-1].map[0, 14, 14]) & 0b10000 == 0  # goal taken
    # the player starts at (1, 1) facing west, a wall: placing force there moves nothing; moving does nothing
    rewards, dones, states = play(game, [4, 2, 3], backend)
    assert all(s.pos[0].tolist() == [1, 1] for s in states) and not any(dones)
    # it can step east and back: the floor stays under its feet
    _, _, states = play(game, [1, 1, 4, 0, 0, 4], backend)  # face east, step; face west, step
    assert states[3].pos[0].tolist() == [1, 2] and states[-1].pos[0].tolist() == [1, 1]


@pytest.mark.parametrize("backend", BACKENDS)
def test_lava_removes_the_player_which_ends_the_episode(backend):
    game = builtin_game("lava_maze")
    # from (1, 1) east to (1, 6), then onto the lava at (1, 7)
    rewards, dones, states = play(game, [1, 1, 4, 4, 4, 4, 4, 4], backend)
    assert dones == [False] * 7 + [True] and rewards[-1] == -1
    assert int((states[-1].map[0] & 1).sum()) == 0  # no player left
    assert states[-1].step[0] == 8  # ended by the rule, long before the step cap


@pytest.mark.parametrize("backend", BACKENDS)
def test_sokoban_pushes_a_crate_onto_floor_only_and_pays_for_crates_on_targets(backend):
    game = builtin_game("sokoban")
    crate, target = 1 << 2, 1 << 3
    # down to (3, 1), east to (3, 2), then push the crate at (3, 3) east twice
    walk = turn_and_place([1, 1, 2, 2, 2])
    rewards, _, states = play(game, walk, backend)
    after = states[-1]
    assert after.pos[0].tolist() == [3, 4] and int(after.map[0, 3, 5]) & crate and not int(after.map[0, 3, 3]) & crate
    # push it into the wall at the right: it stays, the player stays, the force is cleared
    rewards, _, states = play(game, walk + [4] * 6, backend)
    assert int(states[-1].map[0, 3, 8]) & crate and states[-1].pos[0].tolist() == [3, 7]
    assert int(states[-1].map[0, 3, 8]) & 0b10 == 0
    assert sum(rewards) == 0  # no crate on a target yet
    # a crate pushed onto a target pays one every step it stands there
    to_target = turn_and_place([2] * 6 + [1] * 2 + [1, 1])  # east to (1, 7), down to (3, 7), push down twice
    rewards, _, states = play(game, to_target + [0, 0, 0], backend)
    assert int(states[-1].map[0, 6, 7]) & crate and int(states[-1].map[0, 6, 7]) & target
    # rules match the map as the step found it, so the push itself pays nothing; each step after it pays one
    assert rewards == [0] * len(to_target) + [1, 1, 1]


def test_builtin_games_survive_json_and_hash_apart_from_the_same_arrays_without_their_options():
    for name in BUILTIN:
        game = builtin_game(name)
        again = game_from_json(game_to_json(game), name)
        assert game_key(again) == game_key(game)
        plain = {key: game[key] for key in ("rules", "rewards", "map")}
        assert game_key(plain) != game_key(game)


def test_search_solves_the_maze():
    from structgen.domains.autoverse.search import search

    result = search([builtin_game("maze")], 2000, 0)[0]
    assert result.best_return == 1 and len(result.actions) < 101
    rewards, dones, _ = play(builtin_game("maze"), result.actions.tolist(), "numba")
    assert sum(rewards) == 1 and dones[-1]
