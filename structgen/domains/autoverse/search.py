"""Greedy best-first search for a game's best play, many games in lockstep on one engine.

The algorithm is the original's (``search_agent.py::bfs``): the frontier node with the highest return so far is
expanded next (ties: the earliest added), its five children are stepped in a shuffled order, and a child is dropped
when its state (facing and map, player included; not the step count) was already reached with at least its return.
A child that beats the best return so far becomes the best, at the current iteration. Children at the episode's
end are kept as results but not expanded. The search stops after ``budget`` expansions or when the frontier is
empty. Fitness is the iteration at which the best return was first found.

What differs: the child order comes from a seeded generator (the original's shuffle is unseeded), and all games
advance together: each iteration expands one node of every game still searching in one batched engine call, and the
children's states are hashed on the engine's device (two 64-bit hashes of the tile codes and facing; only the
hashes cross to the host). Nodes are stored on the device, one byte a cell.
"""

from __future__ import annotations

import heapq
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from structgen.domains.autoverse.engine import Engine, Mechanics, State

__all__ = ["SearchResult", "search", "search_fitness"]

N_ACTIONS = 5


@dataclass(frozen=True)
class SearchResult:
    """One game's search.

    Attributes:
        best_iteration: the iteration (expansion) at which the best return was first found: the original's fitness.
        best_return: the best cumulative reward found.
        actions: the actions that reach it, ``(n,)`` int8 (at most 101).
        iterations: the original's iteration counter at the end: ``budget + 1`` when the budget ran out, the number
            of expansions when the frontier emptied first.
        expansions: nodes expanded.
        budget: the budget it ran under.
    """

    best_iteration: int
    best_return: float
    actions: np.ndarray
    iterations: int
    expansions: int
    budget: int


def search_fitness(result: SearchResult, tiebreak: bool = True) -> float:
    """The evolution's fitness: ``best_iteration``, plus ``iterations / (budget + 2)`` when the best was found in
    the first iteration and ``tiebreak`` is set (the original computes that and, in its sequential evaluation,
    drops it: ``tiebreak=False``)."""
    fitness = float(result.best_iteration)
    if tiebreak and result.best_iteration == 1:
        fitness += result.iterations / (result.budget + 2)
    return fitness


class _Store:
    """Search nodes on the engine's device: packed maps, facing, position, step; grown by doubling."""

    def __init__(self, engine: Engine, capacity: int) -> None:
        self.engine = engine
        device = engine.device
        self.n_bytes = -(-engine.size * engine.size // 2) * 2  # whole 16-bit chunks of tile codes
        self.packed = torch.zeros(capacity, self.n_bytes, dtype=torch.uint8, device=device)
        self.rot = torch.zeros(capacity, dtype=torch.int64, device=device)
        self.pos = torch.zeros(capacity, 2, dtype=torch.int64, device=device)
        self.step = torch.zeros(capacity, dtype=torch.int64, device=device)
        self.game = torch.zeros(capacity, dtype=torch.int64, device=device)
        self.count = 0
        generator = torch.Generator().manual_seed(0x5EA4C4)
        chunks = self.n_bytes // 2 + 1  # the map's 16-bit chunks and the facing
        self._keys = torch.randint(-(2**62), 2**62, (2, chunks), generator=generator, dtype=torch.int64).to(device) | 1

    def pack(self, code: torch.Tensor) -> torch.Tensor:
        flat = code.reshape(len(code), -1)
        pad = self.n_bytes - flat.shape[1]
        return torch.nn.functional.pad(flat, (0, pad)) if pad else flat

    def unpack(self, packed: torch.Tensor) -> torch.Tensor:
        n = self.engine.size
        return packed[:, : n * n].reshape(len(packed), n, n)

    def hashes(self, packed: torch.Tensor, rot: torch.Tensor) -> np.ndarray:
        """``(n, 2)`` int64: two hashes of each (map codes, facing); 16-bit chunks times odd 64-bit keys, summed
        with wrap-around, so a pair of distinct states collides with probability about 2**-98."""
        chunks = packed.view(len(packed), -1, 2).to(torch.int64)
        words = torch.cat([chunks[:, :, 0] | (chunks[:, :, 1] << 8), rot.unsqueeze(1)], dim=1)
        return torch.stack([(words * keys).sum(dim=1) for keys in self._keys], dim=1).cpu().numpy()

    def add(self, packed: torch.Tensor, state: State) -> range:
        count = len(packed)
        needed = self.count + count
        if needed > len(self.rot):
            grow = max(needed, 2 * len(self.rot))
            for name in ("packed", "rot", "pos", "step", "game"):
                old = getattr(self, name)
                new = torch.zeros((grow, *old.shape[1:]), dtype=old.dtype, device=old.device)
                new[: self.count] = old[: self.count]
                setattr(self, name, new)
        rows = slice(self.count, needed)
        self.packed[rows], self.rot[rows], self.pos[rows] = packed, state.rot, state.pos
        self.step[rows], self.game[rows] = state.step, state.game
        self.count = needed
        return range(rows.start, rows.stop)

    def states(self, nodes: list[int]) -> State:
        index = torch.as_tensor(nodes, device=self.packed.device)
        return State(self.unpack(self.packed[index]), self.rot[index], self.pos[index], self.step[index], self.game[index])


def search(
    games: Sequence[dict[str, Any]] | Engine,
    budgets: int | Sequence[int],
    seeds: int | Sequence[int] = 0,
    *,
    device: str | torch.device = "cpu",
    mechanics: Mechanics | None = None,
) -> list[SearchResult]:
    """Best-first search on every game; game ``i`` expands at most ``budgets[i]`` nodes in the child order drawn
    from ``seeds[i]``. The same game, budget and seed give the same result, alone or in any batch."""
    engine = games if isinstance(games, Engine) else Engine(games, device=device, mechanics=mechanics)
    n_games = engine.n_games
    budgets = [int(budgets)] * n_games if np.isscalar(budgets) else [int(b) for b in budgets]
    seeds = [int(seeds)] * n_games if np.isscalar(seeds) else [int(s) for s in seeds]
    if len(budgets) != n_games or len(seeds) != n_games:
        raise ValueError(f"{n_games} games need as many budgets and seeds, got {len(budgets)} and {len(seeds)}")
    rngs = [np.random.default_rng(seed) for seed in seeds]
    store = _Store(engine, capacity=min(sum(budgets) * N_ACTIONS + n_games, 1 << 16))
    start = engine.reset()
    start_packed = store.pack(start.map)
    roots = store.add(start_packed, start)
    start_hashes = store.hashes(start_packed, start.rot)
    returns: list[float] = [0.0] * n_games  # by node
    parent: list[int] = [-1] * n_games
    action_of: list[int] = [-1] * n_games
    frontiers = [[(-0.0, 0, roots[g])] for g in range(n_games)]
    counters = [1] * n_games
    visited = [{tuple(start_hashes[g]): -np.inf} for g in range(n_games)]
    best_return = [-np.inf] * n_games
    best_node = [-1] * n_games
    best_iteration = [0] * n_games
    iterations = [0] * n_games
    expansions = [0] * n_games
    searching = list(range(n_games))
    while searching:
        expanding, nodes, actions = [], [], []
        for g in searching:
            if not frontiers[g]:
                continue
            iterations[g] += 1
            if iterations[g] > budgets[g]:
                continue
            _, _, node = heapq.heappop(frontiers[g])
            expansions[g] += 1
            expanding.append(g)
            nodes.extend([node] * N_ACTIONS)
            actions.extend(rngs[g].permutation(N_ACTIONS).tolist())
        searching = expanding
        if not expanding:
            break
        children, reward, done = engine.step(store.states(nodes), torch.as_tensor(actions))
        packed = store.pack(children.map)
        hashes = store.hashes(packed, children.rot)
        reward, done = reward.cpu().numpy(), done.cpu().numpy()
        kept: list[int] = []
        for slot, g in enumerate(expanding):
            for row in range(slot * N_ACTIONS, (slot + 1) * N_ACTIONS):
                child_return = returns[nodes[row]] + float(reward[row])
                key = (int(hashes[row, 0]), int(hashes[row, 1]))
                seen = visited[g].get(key)
                if seen is not None and child_return <= seen:
                    continue
                visited[g][key] = child_return
                node = store.count + len(kept)
                kept.append(row)
                returns.append(child_return)
                parent.append(nodes[row])
                action_of.append(actions[row])
                if child_return > best_return[g]:
                    best_return[g], best_node[g], best_iteration[g] = child_return, node, iterations[g]
                if not done[row]:
                    heapq.heappush(frontiers[g], (-child_return, counters[g], node))
                    counters[g] += 1
        if kept:
            rows = torch.as_tensor(kept, device=engine.device)
            store.add(packed[rows], children.index(rows))
    results = []
    for g in range(n_games):
        path, node = [], best_node[g]
        while node >= 0 and parent[node] >= 0:
            path.append(action_of[node])
            node = parent[node]
        results.append(
            SearchResult(
                best_iteration=best_iteration[g],
                best_return=float(best_return[g]),
                actions=np.array(path[::-1], dtype=np.int8),
                iterations=iterations[g],
                expansions=expansions[g],
                budget=budgets[g],
            )
        )
    return results
