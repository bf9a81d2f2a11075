"""Hand-written Autoverse games, after the games the original ships beside its evolved ones (``gen_env/games``),
written in this project's game format.

The player moves the way those games move it: actions 2 and 3 do nothing (``free_moves = 0``); the player places
``force`` in front of itself and a rule carries it onto that cell when the cell can be walked on. Each game uses the
five tiles of the format: the player, force and three of its own (:data:`TILES`). A cell without floor is a wall:
nothing carries the player there.

- ``maze``: walls, floor and a goal; reaching the goal pays 1 and ends the episode (the original's ``maze``). Its
  rules as written there take the floor away wherever the player steps, so that it can never step back; here the
  floor stays, as in its ``lava_maze``, and force placed on a wall is cleared (else each wall so marked would make
  another state for search to tell apart).
- ``lava_maze``: floor, lava and a goal; reaching the goal pays 1 and ends the episode; stepping onto lava removes the
  player (-1), which ends the episode (the original's ``lava_maze``).
- ``sokoban``: floor, crates and targets; pushing a crate moves it one cell when the cell beyond is floor (force on a
  crate that cannot move is cleared), and every crate standing on a target pays 1 a step (the original's ``sokoban``,
  without its ``done_at_reward``, which its batched engine does not run either). Crates stand on no floor.

The maps are our own. ``structgen autoverse play|search|show --builtin NAME`` uses them. They are written for the
default mechanics: with ``Mechanics.original()`` their empty rule slots would match every cell.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from structgen.domains.autoverse.game import FORCE, N_RULES, N_TILES, PLAYER, _rotations, check_game

__all__ = ["BUILTIN", "TILES", "builtin_game"]

#: The names of tiles 2, 3 and 4 in each game (0 is the player, 1 force).
TILES = {"maze": ("wall", "floor", "goal"), "lava_maze": ("lava", "floor", "goal"), "sokoban": ("crate", "target", "floor")}


def _rule(inputs: list[set[int]], outputs: list[set[int]], rotate: bool = True) -> np.ndarray:
    """A row pattern (cells left to right at the top of the 3x3 kernel, as the original pads its patterns) and what
    it becomes, as the format's ``(4 rotations, 2, 5, 3, 3)`` kernels: tiles matched and not put back are removed.
    ``rotate=False`` leaves rotations 1-3 empty, so that the rule matches once where it matches (rewards are paid
    per match and rotation; an empty rotation matches nothing under the default mechanics)."""
    base = np.zeros((1, 2, N_TILES, 3, 3), dtype=np.int8)
    for column, (wanted, made) in enumerate(zip(inputs, outputs)):
        for tile in wanted:
            base[0, 0, tile, 0, column] = 1
        for tile in made:
            base[0, 1, tile, 0, column] = 1
    base[0, 1] -= base[0, 0]
    kernels = _rotations(base)[0]
    if not rotate:
        kernels[1:] = 0
    return kernels


def _game(rules: list[tuple[np.ndarray, int, bool]], picture: str, legend: dict[str, set[int]]) -> dict[str, Any]:
    """Rules ``(kernels, reward, ends the episode)`` (padded to five with rules that match nothing) and a map drawn
    as text, one character a cell."""
    kernels = np.zeros((N_RULES, 4, 2, N_TILES, 3, 3), dtype=np.int8)
    rewards = np.zeros(N_RULES, dtype=np.int8)
    dones = np.zeros(N_RULES, dtype=np.uint8)
    for index, (kernel, reward, done) in enumerate(rules):
        kernels[index], rewards[index], dones[index] = kernel, reward, done
    rows = [line.strip() for line in picture.strip().splitlines()]
    game_map = np.zeros((N_TILES, len(rows), len(rows)), dtype=np.uint8)
    for y, line in enumerate(rows):
        for x, char in enumerate(line):
            for tile in legend[char]:
                game_map[tile, y, x] = 1
    return check_game({"rules": kernels, "rewards": rewards, "map": game_map, "dones": dones, "free_moves": 0}, "builtin")


def maze() -> dict[str, Any]:
    wall, floor, goal = 2, 3, 4
    move = _rule([{PLAYER}, {floor, FORCE}], [set(), {floor, PLAYER}])
    reach = _rule([{PLAYER}, {goal, FORCE}], [set(), {PLAYER}])
    # Force placed on a wall would stay there, and every such wall make another state for search to visit.
    spent = _rule([{wall, FORCE}], [{wall}], rotate=False)
    picture = """
        ################
        #P.....#.......#
        #.####.#.#####.#
        #.#....#.#...#.#
        #.#.####.#.#.#.#
        #.#......#.#...#
        #.########.###.#
        #......#...#...#
        ######.#.###.###
        #......#.#...#.#
        #.######.#.###.#
        #.#......#.....#
        #.#.########.#.#
        #.#........#.#.#
        #.########...#G#
        ################
    """
    legend = {"#": {wall}, ".": {floor}, "P": {PLAYER, floor}, "G": {goal, floor}}
    return _game([(move, 0, False), (reach, 1, True), (spent, 0, False)], picture, legend)


def lava_maze() -> dict[str, Any]:
    lava, floor, goal = 2, 3, 4
    move = _rule([{PLAYER}, {floor, FORCE}], [set(), {floor, PLAYER}])
    reach = _rule([{PLAYER}, {goal, FORCE}], [set(), {PLAYER}])
    fall = _rule([{PLAYER}, {lava, FORCE}], [set(), {lava}])
    picture = """
        ................
        .P.....~........
        .......~........
        ..~~~..~..~~~~..
        ..~....~.....~..
        ..~..~~~~~...~..
        ..~..........~..
        ..~~~~~~~.~~~~..
        ................
        .....~......~...
        ..~..~..~~..~...
        ..~..~...~..~...
        ..~~~~...~~~~...
        .........~....G.
        .........~......
        ................
    """
    legend = {"~": {lava}, ".": {floor}, "P": {PLAYER, floor}, "G": {goal, floor}}
    return _game([(move, 0, False), (reach, 1, True), (fall, -1, False)], picture, legend)


def sokoban() -> dict[str, Any]:
    crate, target, floor = 2, 3, 4
    move = _rule([{PLAYER}, {floor, FORCE}], [set(), {floor, PLAYER}])
    push = _rule([{PLAYER}, {crate, FORCE}, {floor}], [set(), {PLAYER, floor}, {crate}])
    stuck = _rule([{crate, FORCE}], [{crate}], rotate=False)
    scored = _rule([{crate, target}], [{crate, target}], rotate=False)
    picture = """
        ##########
        #P.......#
        #........#
        #..C.....#
        #......C.#
        #........#
        #......T.#
        #........#
        #.T......#
        ##########
    """
    legend = {"#": set(), ".": {floor}, "P": {PLAYER, floor}, "C": {crate}, "T": {target, floor}}
    return _game([(push, 0, False), (stuck, 0, False), (move, 0, False), (scored, 1, False)], picture, legend)


BUILTIN = {"maze": maze, "lava_maze": lava_maze, "sokoban": sokoban}


def builtin_game(name: str) -> dict[str, Any]:
    """The hand-written game ``name`` (one of :data:`BUILTIN`)."""
    if name not in BUILTIN:
        raise KeyError(f"no built-in game {name!r}; choose from {', '.join(BUILTIN)}")
    return BUILTIN[name]()
