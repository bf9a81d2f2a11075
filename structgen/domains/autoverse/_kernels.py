"""The engine's step compiled with numba, for CPUs: one game per parallel iteration, plain loops over its cells.

On a CPU the batched torch step spends most of its time in the overhead of some forty small tensor operations a
step; this kernel does the same work (the same lookup tables: rules matching under each kernel cell, rewards and
per-tile changes of each set of matching rules) in one pass per game. The engine uses it on CPU and the torch code
on GPU; the tests hold both equal to the plain reference.
"""

from __future__ import annotations

import numba as nb
import numpy as np

_DIRECTIONS = np.array([(0, -1), (1, 0), (0, 1), (-1, 0)], dtype=np.int64)
_N_TILES = 5


# One game's step. The two drivers below run it over the batch; numba inlines it, so the split costs nothing.
@nb.njit(cache=True, inline="always")
def _step_game(
    b: int,
    n: int,
    slots: int,
    everything: int,
    codes: np.ndarray,  # (B, N, N) uint8
    rot: np.ndarray,  # (B,) int64
    pos: np.ndarray,  # (B, 2) int64
    games: np.ndarray,  # (B,) int64
    actions: np.ndarray,  # (B,) int64
    n_cells: np.ndarray,  # (S,) int64 kernel cells used in each rotation slot
    cells: np.ndarray,  # (S, L, 2) int64 (dy, dx) of each, 0..2
    match: np.ndarray,  # (G, S, L, 32) int64: rules satisfied by a code under that cell
    change: np.ndarray,  # (G, S, L, M, 5) int64: per-tile change written there by a set of matching rules
    rewards: np.ndarray,  # (G, M) int64: reward of a set of matching rules
    done_table: np.ndarray,  # (G, M) bool: a set of matching rules holds one that ends the episode
    free_moves: np.ndarray,  # (G,) bool: actions 2 and 3 move the player (else only rules do)
    player_rules: np.ndarray,  # (G,) bool: the game's rules touch the player channel
    force_clear: bool,
    out_codes: np.ndarray,
    out_rot: np.ndarray,
    out_pos: np.ndarray,
    out_reward: np.ndarray,
    out_ended: np.ndarray,  # (B,) bool: a rule ended the episode, or removed the player
) -> None:
    g = games[b]
    action = actions[b]
    facing = rot[b]
    if action == 0:
        facing = (facing + 1) % 4
    elif action == 1:
        facing = (facing + 3) % 4
    dy, dx = _DIRECTIONS[facing, 0], _DIRECTIONS[facing, 1]
    y, x = pos[b, 0], pos[b, 1]
    ny, nx = y, x
    if action == 2 and free_moves[g]:
        ny, nx = (y + dy + n) % n, (x + dx + n) % n
    elif action == 3 and free_moves[g]:
        ny, nx = (y - dy + n) % n, (x - dx + n) % n
    grid = out_codes[b]
    grid[:, :] = codes[b]
    grid[y, x] = grid[y, x] & 0xFE
    ty, tx = (ny + dy + n) % n, (nx + dx + n) % n
    if action == 4:
        grid[ty, tx] = grid[ty, tx] | 2
    elif force_clear:
        grid[ty, tx] = grid[ty, tx] & 0xFD
    grid[ny, nx] = grid[ny, nx] | 1
    delta = np.zeros((n, n, _N_TILES), dtype=np.int64)
    total = 0
    ended = False
    for s in range(slots):
        used = n_cells[s]
        for i in range(n):
            for j in range(n):
                matching = everything
                for k in range(used):
                    qi = (i + cells[s, k, 0] - 1 + n) % n
                    qj = (j + cells[s, k, 1] - 1 + n) % n
                    matching &= match[g, s, k, grid[qi, qj]]
                    if matching == 0:
                        break
                if matching == 0:
                    continue
                total += rewards[g, matching]
                ended |= done_table[g, matching]
                for k in range(used):
                    qi = (i + cells[s, k, 0] - 1 + n) % n
                    qj = (j + cells[s, k, 1] - 1 + n) % n
                    for t in range(_N_TILES):
                        delta[qi, qj, t] += change[g, s, k, matching, t]
    for i in range(n):
        for j in range(n):
            old = grid[i, j]
            new = 0
            for t in range(_N_TILES):
                if ((old >> t) & 1) + delta[i, j, t] >= 1:
                    new |= 1 << t
            grid[i, j] = new
    if player_rules[g]:  # the rules may have moved or removed the player: its first cell in row-major order
        found = False
        for i in range(n):
            for j in range(n):
                if grid[i, j] & 1:
                    ny, nx, found = i, j, True
                    break
            if found:
                break
        ended |= not found
    out_rot[b] = facing
    out_pos[b, 0] = ny
    out_pos[b, 1] = nx
    out_reward[b] = total
    out_ended[b] = ended


@nb.njit(parallel=True, cache=True)
def step(
    codes: np.ndarray,  # (B, N, N) uint8
    rot: np.ndarray,  # (B,) int64
    pos: np.ndarray,  # (B, 2) int64
    games: np.ndarray,  # (B,) int64
    actions: np.ndarray,  # (B,) int64
    n_cells: np.ndarray,  # (S,) int64 kernel cells used in each rotation slot
    cells: np.ndarray,  # (S, L, 2) int64 (dy, dx) of each, 0..2
    match: np.ndarray,  # (G, S, L, 32) int64: rules satisfied by a code under that cell
    change: np.ndarray,  # (G, S, L, M, 5) int64: per-tile change written there by a set of matching rules
    rewards: np.ndarray,  # (G, M) int64: reward of a set of matching rules
    done_table: np.ndarray,  # (G, M) bool: a set of matching rules holds one that ends the episode
    free_moves: np.ndarray,  # (G,) bool: actions 2 and 3 move the player (else only rules do)
    player_rules: np.ndarray,  # (G,) bool: the game's rules touch the player channel
    force_clear: bool,
    out_codes: np.ndarray,
    out_rot: np.ndarray,
    out_pos: np.ndarray,
    out_reward: np.ndarray,
    out_ended: np.ndarray,  # (B,) bool: a rule ended the episode, or removed the player
) -> None:
    """One step of every game, a game per thread."""
    count, n = codes.shape[0], codes.shape[1]
    slots = cells.shape[0]
    everything = rewards.shape[1] - 1  # every rule
    for b in nb.prange(count):
        _step_game(
            b,
            n,
            slots,
            everything,
            codes,
            rot,
            pos,
            games,
            actions,
            n_cells,
            cells,
            match,
            change,
            rewards,
            done_table,
            free_moves,
            player_rules,
            force_clear,
            out_codes,
            out_rot,
            out_pos,
            out_reward,
            out_ended,
        )


@nb.njit(cache=True)
def step_serial(
    codes: np.ndarray,  # (B, N, N) uint8
    rot: np.ndarray,  # (B,) int64
    pos: np.ndarray,  # (B, 2) int64
    games: np.ndarray,  # (B,) int64
    actions: np.ndarray,  # (B,) int64
    n_cells: np.ndarray,  # (S,) int64 kernel cells used in each rotation slot
    cells: np.ndarray,  # (S, L, 2) int64 (dy, dx) of each, 0..2
    match: np.ndarray,  # (G, S, L, 32) int64: rules satisfied by a code under that cell
    change: np.ndarray,  # (G, S, L, M, 5) int64: per-tile change written there by a set of matching rules
    rewards: np.ndarray,  # (G, M) int64: reward of a set of matching rules
    done_table: np.ndarray,  # (G, M) bool: a set of matching rules holds one that ends the episode
    free_moves: np.ndarray,  # (G,) bool: actions 2 and 3 move the player (else only rules do)
    player_rules: np.ndarray,  # (G,) bool: the game's rules touch the player channel
    force_clear: bool,
    out_codes: np.ndarray,
    out_rot: np.ndarray,
    out_pos: np.ndarray,
    out_reward: np.ndarray,
    out_ended: np.ndarray,  # (B,) bool: a rule ended the episode, or removed the player
) -> None:
    """:func:`step` on the calling thread alone, for batches too small to be worth waking the others."""
    count, n = codes.shape[0], codes.shape[1]
    slots = cells.shape[0]
    everything = rewards.shape[1] - 1
    for b in range(count):
        _step_game(
            b,
            n,
            slots,
            everything,
            codes,
            rot,
            pos,
            games,
            actions,
            n_cells,
            cells,
            match,
            change,
            rewards,
            done_table,
            free_moves,
            player_rules,
            force_clear,
            out_codes,
            out_rot,
            out_pos,
            out_reward,
            out_ended,
        )
