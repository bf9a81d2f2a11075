"""The lockstep batched search against the plain reference search, and its reproducibility."""

from __future__ import annotations

import numpy as np
import pytest

from structgen.domains.autoverse.engine import Engine, Mechanics
from structgen.domains.autoverse.search import search, search_fitness
from tests.autoverse import reference_autoverse as ref
from tests.autoverse.test_engine import _games


@pytest.mark.parametrize("mechanics", [Mechanics(), Mechanics.original()], ids=["default", "original"])
def test_batched_search_equals_reference_search(mechanics):
    # The plain reference search costs far more than the engines, so it runs once and both backends are held to it.
    games = _games(np.random.default_rng(21), 6)
    budgets = [25, 40, 10, 60, 1, 30]
    seeds = [0, 1, 2, 3, 4, 5]
    found = {b: search(Engine(games, mechanics=mechanics, backend=b), budgets, seeds) for b in ("torch", "numba")}
    options = {"force_clear": mechanics.force_clear, "empty_rules_fire": mechanics.empty_rules_fire}
    for i, (game, budget, seed) in enumerate(zip(games, budgets, seeds)):
        rng = np.random.default_rng(seed)
        best_iteration, best, actions, iterations = ref.search(game, budget, lambda n, rng=rng: rng.permutation(5), **options)
        for backend, results in found.items():
            result = results[i]
            where = f"{backend}, game {i}"
            assert (result.best_iteration, result.best_return, result.iterations) == (best_iteration, best, iterations), where
            assert result.actions.tolist() == actions, where
        # replaying the actions earns the best return
        state, total = ref.reset(game), 0
        for action in actions:
            state, reward, _ = ref.step(game, state, action, **options)
            total += reward
        assert total == best


def test_search_is_reproducible_and_independent_of_the_batch():
    games = _games(np.random.default_rng(4), 5)
    together = search(games, 50, seeds=[7, 8, 9, 10, 11])
    again = search(games, 50, seeds=[7, 8, 9, 10, 11])
    alone = search([games[3]], 50, seeds=[10])[0]
    assert [r.actions.tolist() for r in together] == [r.actions.tolist() for r in again]
    assert (alone.best_iteration, alone.best_return, alone.actions.tolist()) == (
        together[3].best_iteration,
        together[3].best_return,
        together[3].actions.tolist(),
    )


def test_fitness_tiebreak_only_when_the_best_came_first():
    games = _games(np.random.default_rng(9), 1)
    games[0]["rules"][:] = 0  # nothing ever pays: the first child is the best, found at iteration 1
    result = search(games, 20)[0]
    assert result.best_iteration == 1 and result.best_return == 0
    assert search_fitness(result, tiebreak=False) == 1
    assert search_fitness(result) == 1 + result.iterations / 22
