"""The batched engine against the plain reference, step for step, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from structgen.domains.autoverse.engine import Engine, Mechanics, Observation
from structgen.domains.autoverse.game import check_game, mutate_game, random_game
from tests.autoverse import reference_autoverse as ref


def _games(rng: np.random.Generator, count: int) -> list[dict]:
    """Random games of every kind the engine meets: as drawn, mutated (stacked and empty cells, stray force), with
    full 3x3 kernels, and with an empty input pattern."""
    games = []
    for i in range(count):
        game = random_game(rng)
        if i % 4 == 1:
            game = mutate_game(mutate_game(game, rng), rng)
        elif i % 4 == 2:  # arbitrary 3x3 kernels, rotations unrelated: the engine must not assume 1x3 patterns
            k_in = rng.integers(0, 2, size=(5, 4, 5, 3, 3)) * (rng.random((5, 4, 5, 3, 3)) < 0.3)
            k_out = rng.integers(0, 2, size=(5, 4, 5, 3, 3)) - k_in
            game["rules"] = np.stack([k_in, k_out], axis=2).astype(np.int8)
            game["rules"][:, :, :, 0] = 0
        elif i % 4 == 3:
            game["rules"][0, :, 0] = 0  # rule 0 has nothing to match
            game["rewards"][0] = 1
        games.append(check_game(game))
    return games


def _episode(games: list[dict], seed: int = 11) -> np.ndarray:
    """One episode's actions for ``games``: 101 steps, every action drawn."""
    return np.random.default_rng(seed).integers(0, 5, size=(101, len(games)))


def _play(engine: Engine, actions: np.ndarray) -> list[tuple]:
    """Every step's (multi-hot map, rotation, position, reward, done) of each game, as plain arrays."""
    state, trace = engine.reset(), []
    for step in actions:
        state, reward, done = engine.step(state, torch.as_tensor(step))
        # Copies: an engine may update its tensors in place on the next step.
        trace.append(tuple(t.numpy().copy() for t in (state.multi_hot(), state.rot, state.pos, reward, done)))
    return trace


@pytest.mark.parametrize("mechanics", [Mechanics(), Mechanics.original()], ids=["default", "original"])
def test_batched_engine_equals_reference_on_random_games_and_actions(mechanics):
    # The plain reference costs about twenty times the engines, so it plays once and both backends are held to it.
    games = _games(np.random.default_rng(11), 12)
    actions = _episode(games)
    traces = {backend: _play(Engine(games, mechanics=mechanics, backend=backend), actions) for backend in ("torch", "numba")}
    refs = [ref.reset(g) for g in games]
    options = {"force_clear": mechanics.force_clear, "empty_rules_fire": mechanics.empty_rules_fire}
    for t, step in enumerate(actions):
        for i, game in enumerate(games):
            refs[i], want_reward, want_done = ref.step(game, refs[i], int(step[i]), **options)
            for backend, trace in traces.items():
                grid, rot, pos, reward, done = trace[t]
                where = f"{backend}, step {t}, game {i}"
                assert np.array_equal(grid[i], refs[i][0]), where
                assert int(rot[i]) == refs[i][1], where
                assert tuple(pos[i].tolist()) == refs[i][2], where
                assert float(reward[i]) == want_reward, where
                assert bool(done[i]) == want_done, where
    assert all(bool(trace[-1][4].all()) for trace in traces.values()), "the 101st step ends the episode"


def _compiled_against_plain(monkeypatch: pytest.MonkeyPatch | None, backend: str | None) -> None:
    games = _games(np.random.default_rng(11), 12)
    actions = _episode(games)
    plain = _play(Engine(games, backend="torch"), actions)
    if backend is not None:  # the engine's own torch.compile call, with another compiler behind it
        compile_with = torch.compile
        monkeypatch.setattr(torch, "compile", lambda function, **options: compile_with(function, backend=backend, **options))
    compiled = _play(Engine(games, backend="torch", compile=True), actions)
    for t, (want, got) in enumerate(zip(plain, compiled)):
        for name, a, b in zip(("map", "rotation", "position", "reward", "done"), want, got):
            assert np.array_equal(a, b), f"step {t}: {name}"


def test_the_graph_torch_compile_captures_equals_the_plain_torch_engine(monkeypatch):
    # What torch.compile traces (one graph, no breaks; guards, functionalisation) run without code generation: seconds.
    # The plain torch engine is held to the reference above, so matching it step for step holds the graph there too.
    _compiled_against_plain(monkeypatch, "aot_eager")


@pytest.mark.inductor
def test_compiled_engine_equals_the_plain_torch_engine():
    # The whole of torch.compile, code generation included (the fast GPU path; C++ on a CPU): about 100 s of compiling
    # on 2 cores with a cold cache, so it runs in make test-all, not in make test (CONTRIBUTING.md).
    _compiled_against_plain(None, None)


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_quirks_change_what_they_name(backend):
    rng = np.random.default_rng(3)
    game = random_game(rng)
    game["rules"][:] = 0  # no rules: only the player's actions change the map
    game["map"][1] = 0
    engine_default = Engine([game], backend=backend)
    engine_original = Engine([game], mechanics=Mechanics.original(), backend=backend)
    for engine, force_left in ((engine_default, 1), (engine_original, 0)):
        state = engine.reset()
        state, _, _ = engine.step(state, torch.tensor([4]))  # place force in front
        assert int(state.multi_hot()[0, 1].sum()) == 1
        state, _, _ = engine.step(state, torch.tensor([0]))  # turn, then turn back: front is the force cell again
        state, _, _ = engine.step(state, torch.tensor([1]))
        assert int(state.multi_hot()[0, 1].sum()) == force_left
    game["rewards"][:] = [1, 0, 0, 0, 0]  # rule 0, with nothing to match, pays 1 a match
    default = Engine([game], backend=backend)
    _, reward_default, _ = default.step(default.reset(), torch.tensor([0]))
    original = Engine([game], mechanics=Mechanics.original(), backend=backend)
    _, reward_original, _ = original.step(original.reset(), torch.tensor([0]))
    assert float(reward_default[0]) == 0
    assert float(reward_original[0]) == 16 * 16 * 4


@pytest.mark.parametrize("backend", ["torch", "numba"])
def test_rows_may_play_any_game_in_any_order(backend):
    rng = np.random.default_rng(5)
    games = _games(rng, 4)
    engine = Engine(games, backend=backend)
    order = torch.tensor([3, 3, 0, 2, 1])
    state = engine.reset(order)
    actions = torch.tensor([0, 2, 4, 3, 1])
    stepped, reward, _ = engine.step(state, actions)
    for row, game_index in enumerate(order.tolist()):
        alone = Engine([games[game_index]])
        want, want_reward, _ = alone.step(alone.reset(), actions[row : row + 1])
        assert torch.equal(stepped.map[row], want.map[0]) and torch.equal(stepped.pos[row], want.pos[0])
        assert float(reward[row]) == float(want_reward[0])


def test_observation_window_and_padding():
    rng = np.random.default_rng(8)
    game = random_game(rng)
    engine = Engine([game])
    state = engine.reset()
    view, flat = engine.observe(state)
    assert view.shape == (1, 5, 31, 31) and flat.shape == (1, 1811)
    # the player is at the centre; by default (as the paper) the map is seen once, zeros beyond its edges
    assert view[0, 0, 15, 15] == 1 and int(view[0, 0].sum()) == 1
    assert int(view[0].sum()) == 256  # one-hot map, every cell seen once
    wrapped, _ = engine.observe(state, Observation(padding="wrap"))
    assert torch.equal(wrapped[0, :, :15, :], wrapped[0, :, 16:31, :][:, :15])  # the torus, period 16
    windowed, _ = engine.observe(state, Observation(window=5))
    assert int((windowed[0].sum(0) > 0).sum()) == 25 and windowed[0, :, 13:18, 13:18].sum() == 25
    blank, _ = engine.observe(state, Observation.original(window=5))
    assert int(blank.sum()) == 0  # the original environment's windowed view
    _, hidden = engine.observe(state, Observation(hide_rules=True))
    assert hidden[0, :4].tolist() == [1, 0, 0, 0] and int(hidden[0, 4:].abs().sum()) == 0
    assert torch.equal(flat[0, 4:1804], torch.as_tensor(game["rules"]).float().flatten())


def test_bad_games_are_refused_with_the_field_named():
    from structgen.errors import InputError

    game = random_game(np.random.default_rng(0))
    game["dones"] = [0, 1, 2, 0, 0]
    with pytest.raises(InputError, match=r"g.dones: expected five 0/1 values, one per rule, got \[0, 1, 2, 0, 0\]"):
        check_game(game, "g")
    game = random_game(np.random.default_rng(0))
    game["free_moves"] = 3
    with pytest.raises(InputError, match="g.free_moves: expected 0 or 1, got 3"):
        check_game(game, "g")
    game = random_game(np.random.default_rng(0))
    game["map"][0] = 0
    with pytest.raises(InputError, match="g.map: the player channel must hold exactly one cell, holds 0"):
        check_game(game, "g")


def test_compiling_the_numba_backend_is_refused():
    with pytest.raises(ValueError, match="numba backend is compiled already"):
        Engine(_games(np.random.default_rng(0), 1), backend="numba", compile=True)


def test_the_numba_steps_parallel_and_serial_kernels_agree():
    rng = np.random.default_rng(21)
    games = [random_game(rng) for _ in range(40)]  # enough games for the engine to choose between kernels
    engines = {way: Engine(games, backend="numba") for way in ("serial", "parallel")}
    for way, engine in engines.items():
        engine._kernel_choice.pick = lambda way=way: way
    states = {way: engine.reset() for way, engine in engines.items()}
    for step in range(30):
        actions = torch.as_tensor(rng.integers(0, 5, size=40))
        outcomes = {way: engines[way].step(states[way], actions) for way in engines}
        (serial, serial_reward, _), (parallel, parallel_reward, _) = outcomes["serial"], outcomes["parallel"]
        assert torch.equal(serial.map, parallel.map) and torch.equal(serial.pos, parallel.pos), step
        assert torch.equal(serial_reward, parallel_reward)
        states = {"serial": serial, "parallel": parallel}


def test_the_observation_is_the_same_on_one_torch_thread_and_on_several():
    rng = np.random.default_rng(22)
    engine = Engine([random_game(rng) for _ in range(8)], backend="numba")
    state = engine.reset()
    before = torch.get_num_threads()
    try:
        torch.set_num_threads(2)
        seen = {}
        for way in ("one thread", "torch's threads"):
            engine._observe_choice.pick = lambda way=way: way
            seen[way] = engine.observe(state)
            assert torch.get_num_threads() == 2
    finally:
        torch.set_num_threads(before)
    assert all(torch.equal(a, b) for a, b in zip(seen["one thread"], seen["torch's threads"]))
