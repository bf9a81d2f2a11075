"""An Autoverse game as plain arrays: rewrite rules, their rewards and the initial map.

A game is a dict of three numpy arrays, the unit the original code exchanges too:

- ``rules``: ``(5 rules, 4 rotations, 2 [in, out], 5 tiles, 3, 3)`` int8. ``in`` is 0/1 (tiles a cell must hold;
  other tiles on the cell and empty kernel cells are ignored); ``out`` is -1/0/+1 (tiles removed or added where the
  input matched). A random rule is a 1x3 pattern in the top row of its kernel, turned by ``np.rot90`` for rotations
  1-3 (left column, bottom row, right column): patterns are not centred, as in the original.
- ``rewards``: ``(5,)`` int8 in {-1, 0, 1}, paid per match of the rule (any rotation).
- ``map``: ``(5, 16, 16)`` uint8 multi-hot; channel 0 is the player (exactly one cell), 1 is ``force`` (what the
  player places), 2-4 are the free tiles a, b, c. Random maps are one-hot; mutation makes cells with several tiles
  or none.

Two optional entries describe games written by hand (:mod:`.library`); generated games never have them, and a game
without them behaves as with their defaults (:func:`game_options`):

- ``dones``: ``(5,)`` 0/1, a rule marked 1 ends the episode in the step it fires (the original's ``done`` rules);
- ``free_moves``: 1 (default) when actions 2 and 3 move the player, 0 when only rules move it (the player places
  force and a rule carries it there, as the original's hand-written games are written).

Rules may read and write the player channel (generated rules never do); an episode also ends where the rules
remove the player. Being plain data, games pickle, go through checkpoints and JSON unchanged, and hash by content
(:func:`game_key`).
"""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np

from structgen.errors import InputError

__all__ = [
    "FORCE",
    "MAP_SIZE",
    "MUTATIONS",
    "N_RULES",
    "N_TILES",
    "PLAYER",
    "TILE_NAMES",
    "check_game",
    "game_from_json",
    "game_options",
    "game_key",
    "game_to_json",
    "mutate_game",
    "random_game",
    "random_map",
    "random_rules",
]

TILE_NAMES = ("player", "force", "a", "b", "c")
PLAYER, FORCE = 0, 1
N_TILES = len(TILE_NAMES)
N_RULES = 5
MAP_SIZE = 16
RULES_SHAPE = (N_RULES, 4, 2, N_TILES, 3, 3)
#: ``rules_and_map`` mutates rewards, rule patterns and the map (what the paper describes); ``map_only`` is what the
#: released code runs (its rule mutation returns the rules unchanged, so only maps evolve).
MUTATIONS = ("rules_and_map", "map_only")


def _rotations(base: np.ndarray) -> np.ndarray:
    """``(R, 2, C, 3, 3)`` base kernels -> ``(R, 4, 2, C, 3, 3)``: ``np.rot90`` k = 0..3 over the kernel's axes."""
    return np.stack([np.rot90(base, k, axes=(-2, -1)) for k in range(4)], axis=1).astype(np.int8)


def _base_from_bits(inputs: np.ndarray, outputs: np.ndarray) -> np.ndarray:
    """Input bits and raw output bits of the top row -> base kernels: ``out = raw - in`` removes matched tiles that
    the output does not put back; the player channel is never read or written."""
    base = np.zeros((len(inputs), 2, N_TILES, 3, 3), dtype=np.int8)
    base[:, 0, :, 0, :] = inputs
    base[:, 1, :, 0, :] = outputs.astype(np.int8) - inputs
    base[:, :, PLAYER] = 0
    return base


def random_rules(rng: np.random.Generator, count: int = N_RULES) -> np.ndarray:
    """``count`` random rules as the original draws them: uniform bits for the input and output of a 1x3 pattern."""
    inputs = rng.integers(0, 2, size=(count, N_TILES, 3), dtype=np.int8)
    outputs = rng.integers(0, 2, size=(count, N_TILES, 3), dtype=np.int8)
    return _rotations(_base_from_bits(inputs, outputs))


def random_map(rng: np.random.Generator, size: int = MAP_SIZE) -> np.ndarray:
    """A one-hot map: every cell one of a, b, c (1/3 each), then the player on one random cell."""
    tiles = rng.integers(2, N_TILES, size=(size, size))
    game_map = (np.arange(N_TILES)[:, None, None] == tiles[None]).astype(np.uint8)
    cell = int(rng.integers(size * size))
    game_map[:, cell // size, cell % size] = 0
    game_map[PLAYER, cell // size, cell % size] = 1
    return game_map


def random_game(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Random rules, random rewards in {-1, 0, 1} and a random map: the original's initial population."""
    rules = random_rules(rng)
    rewards = rng.integers(-1, 2, size=N_RULES).astype(np.int8)
    return {"rules": rules, "rewards": rewards, "map": random_map(rng)}


def mutate_game(game: dict[str, Any], rng: np.random.Generator, mode: str = "rules_and_map") -> dict[str, np.ndarray]:
    """A mutated copy of ``game``.

    The map: every bit of the non-player channels flips with one rate drawn from U(0, 0.5) (the original's XOR; it
    makes stacked and empty cells). With ``mode="rules_and_map"`` also: each reward is redrawn with probability 0.3,
    and the input and output bits of each rule's 1x3 pattern are redrawn at a rate from U(0, 0.5), all four
    rotations rebuilt from the new pattern (the original's intended operator redrew every rotation on its own,
    leaving them inconsistent). ``mode="map_only"`` leaves rules and rewards alone, as the released code does.
    """
    if mode not in MUTATIONS:
        raise ValueError(f"mutation must be one of {', '.join(MUTATIONS)}, got {mode!r}")
    game_map = np.array(game["map"], dtype=np.uint8, copy=True)
    rate = rng.uniform(0.0, 0.5)
    flips = rng.random(game_map[1:].shape) < rate
    game_map[1:] ^= flips.astype(np.uint8)
    rules = np.array(game["rules"], dtype=np.int8, copy=True)
    rewards = np.array(game["rewards"], dtype=np.int8, copy=True)
    if mode == "rules_and_map":
        redraw = rng.random(N_RULES) < 0.3
        rewards = np.where(redraw, rng.integers(-1, 2, size=N_RULES), rewards).astype(np.int8)
        inputs = rules[:, 0, 0, :, 0, :].copy()
        outputs = rules[:, 0, 1, :, 0, :] + inputs  # the raw output bits: out = raw - in
        rate = rng.uniform(0.0, 0.5)
        new_in = rng.random(inputs.shape) < rate
        inputs = np.where(new_in, rng.integers(0, 2, size=inputs.shape), inputs)
        new_out = rng.random(outputs.shape) < rate
        outputs = np.where(new_out, rng.integers(0, 2, size=outputs.shape), outputs)
        rules = _rotations(_base_from_bits(inputs.astype(np.int8), np.clip(outputs, 0, 1)))
    return {"rules": rules, "rewards": rewards, "map": game_map}


def check_game(game: Any, where: str = "game") -> dict[str, np.ndarray]:
    """The game with arrays of the right types, or an :class:`InputError` naming the field and what is wrong."""
    if not isinstance(game, dict):
        raise InputError(f"{where}: expected a mapping with rules, rewards and map, got {type(game).__name__}")
    missing = [key for key in ("rules", "rewards", "map") if key not in game]
    if missing:
        raise InputError(f"{where}: missing {', '.join(missing)}")
    checked = {}
    for key, shape, dtype, allowed in (
        ("rules", RULES_SHAPE, np.int8, (-1, 0, 1)),
        ("rewards", (N_RULES,), np.int8, (-1, 0, 1)),
        ("map", None, np.uint8, (0, 1)),
    ):
        try:
            array = np.asarray(game[key])
        except (TypeError, ValueError) as err:
            raise InputError(f"{where}.{key}: not an array ({err})") from None
        if not (np.issubdtype(array.dtype, np.integer) or np.issubdtype(array.dtype, np.floating) or array.dtype == bool):
            raise InputError(f"{where}.{key}: must hold numbers, got {array.dtype} values")
        if shape is not None and array.shape != shape:
            raise InputError(f"{where}.{key}: expected shape {shape}, got {array.shape}")
        if key == "map" and (array.ndim != 3 or array.shape[0] != N_TILES or array.shape[1] != array.shape[2]):
            raise InputError(f"{where}.map: expected shape ({N_TILES}, N, N), got {array.shape}")
        if array.size and not np.isin(array, allowed).all():
            wrong = sorted({v.item() for v in np.unique(array)} - set(allowed))
            raise InputError(f"{where}.{key}: values must be in {allowed}, got {wrong}")
        checked[key] = array.astype(dtype)
    if int(checked["map"][PLAYER].sum()) != 1:
        raise InputError(f"{where}.map: the player channel must hold exactly one cell, holds {int(checked['map'][PLAYER].sum())}")
    if (checked["rules"][:, :, 0] < 0).any():
        raise InputError(f"{where}.rules: input patterns must be 0 or 1")
    for key, shape in (("dones", (N_RULES,)), ("free_moves", ())):
        if key not in game:
            continue
        array = np.asarray(game[key])
        if array.shape != shape or not np.isin(array, (0, 1)).all():
            raise InputError(
                f"{where}.{key}: expected {'five 0/1 values, one per rule' if shape else '0 or 1'}, got {game[key]!r}"
            )
        checked[key] = array.astype(np.uint8)
    return checked


def game_options(game: dict[str, Any]) -> dict[str, Any]:
    """A game's ``dones`` and ``free_moves``, their defaults (no rule ends the episode; actions move the player)
    where it has none."""
    dones = np.asarray(game["dones"], dtype=np.uint8) if "dones" in game else np.zeros(N_RULES, dtype=np.uint8)
    return {"dones": dones, "free_moves": int(game.get("free_moves", 1))}


def _optional(game: dict[str, Any]) -> dict[str, Any]:
    """The options that differ from their defaults (so that a generated game hashes and saves as it always has)."""
    options = game_options(game)
    found = {}
    if options["dones"].any():
        found["dones"] = options["dones"]
    if options["free_moves"] != 1:
        found["free_moves"] = options["free_moves"]
    return found


def game_key(game: dict[str, Any]) -> str:
    """A content hash of a game (rules, rewards, map): equal games share it."""
    digest = hashlib.blake2b(digest_size=12)
    for value in [game[key] for key in ("rules", "rewards", "map")] + list(_optional(game).values()):
        array = np.ascontiguousarray(value, dtype=np.int8)
        digest.update(str(array.shape).encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


def game_to_json(game: dict[str, Any]) -> dict[str, Any]:
    """Nested lists of small integers (``budget``, when present, kept)."""
    data = {key: np.asarray(game[key]).astype(int).tolist() for key in ("rules", "rewards", "map")}
    data.update({key: np.asarray(value).astype(int).tolist() for key, value in _optional(game).items()})
    if "budget" in game:
        data["budget"] = int(game["budget"])
    return data


def game_from_json(data: Any, where: str = "game") -> dict[str, Any]:
    game = check_game(data, where)
    if isinstance(data, dict) and "budget" in data:
        budget = data["budget"]
        if not isinstance(budget, int) or isinstance(budget, bool) or not 1 <= budget <= 10**7:
            raise InputError(f"{where}.budget = {budget!r}: expected a whole number of expansions from 1 to 10,000,000")
        game["budget"] = budget
    return game
