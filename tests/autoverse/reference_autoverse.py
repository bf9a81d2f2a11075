"""A plain, one-game-at-a-time Autoverse written from the research notes (A1, A2, A5), independent of the package:
numpy rolls over the torus instead of padded slices and matrix products, Python loops over rules, rotations and
kernel cells. The tests hold the batched engine and search equal to it."""

from __future__ import annotations

import numpy as np

DIRS = [(0, -1), (1, 0), (0, 1), (-1, 0)]


def shifted(layer: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """``out[i, j] = layer[(i + dy) % N, (j + dx) % N]``."""
    return np.roll(layer, (-dy, -dx), axis=(0, 1))


def apply_rules(rules, rewards, game_map, empty_rules_fire):
    m = game_map.astype(np.int64)
    delta = np.zeros_like(m)
    reward = 0
    for r in range(rules.shape[0]):
        for o in range(rules.shape[1]):
            k_in, k_out = rules[r, o, 0], rules[r, o, 1]
            if k_in.sum() == 0 and not empty_rules_fire:
                continue
            match = np.ones(m.shape[1:], dtype=bool)
            for c, ky, kx in zip(*np.nonzero(k_in)):
                match &= shifted(m[c], ky - 1, kx - 1) == 1
            reward += int(rewards[r]) * int(match.sum())
            for c, ky, kx in zip(*np.nonzero(k_out)):
                # the match at (i, j) writes cell (i + ky - 1, j + kx - 1): shift the match grid the other way
                delta[c] += k_out[c, ky, kx] * shifted(match.astype(np.int64), -(ky - 1), -(kx - 1))
    return np.clip(m + delta, 0, 1).astype(np.uint8), reward


def step(game, state, action, *, force_clear=False, empty_rules_fire=False, episode_steps=100):
    m, rot, pos, n_step = state
    m = m.copy()
    n = m.shape[1]
    if action == 0:
        rot = (rot + 1) % 4
    elif action == 1:
        rot = (rot - 1) % 4
    dr, dc = DIRS[rot]
    if action == 2:
        new = ((pos[0] + dr) % n, (pos[1] + dc) % n)
    elif action == 3:
        new = ((pos[0] - dr) % n, (pos[1] - dc) % n)
    else:
        new = pos
    m[0, pos[0], pos[1]] = 0
    target = ((new[0] + dr) % n, (new[1] + dc) % n)
    if action == 4:
        m[1, target[0], target[1]] = 1
    elif force_clear:
        m[1, target[0], target[1]] = 0
    m[0, new[0], new[1]] = 1
    m, reward = apply_rules(game["rules"], game["rewards"], m, empty_rules_fire)
    done = n_step >= episode_steps
    player = np.argwhere(m[0] == 1)[0]
    return (m, rot, (int(player[0]), int(player[1])), n_step + 1), reward, done


def reset(game):
    player = np.argwhere(game["map"][0] == 1)[0]
    return (game["map"].copy(), 0, (int(player[0]), int(player[1])), 0)


def search(game, budget, order_of, **mechanics):
    """Greedy best-first search on cumulative reward, as the original's ``bfs``; ``order_of(n_iter)`` gives the
    order in which the children of the n-th popped node are tried. Returns (n_iter_best, best return, actions,
    n_iter)."""
    start = reset(game)

    def key(state):
        return (state[1], state[0].astype(bool).tobytes())

    frontier = [(start, [], 0)]
    visited = {key(start): -np.inf}
    best, best_actions, n_iter_best = -np.inf, None, 0
    n_iter = 0
    while frontier:
        n_iter += 1
        if n_iter > budget:
            break
        index = int(np.argmax([f[2] for f in frontier]))
        parent, actions, ret = frontier.pop(index)
        for action in order_of(n_iter):
            child, reward, done = step(game, parent, int(action), **mechanics)
            child_ret = ret + reward
            k = key(child)
            if k in visited and child_ret <= visited[k]:
                continue
            visited[k] = child_ret
            if child_ret > best:
                best, best_actions, n_iter_best = child_ret, actions + [int(action)], n_iter
            if not done:
                frontier.append((child, actions + [int(action)], child_ret))
    return n_iter_best, best, best_actions, n_iter
