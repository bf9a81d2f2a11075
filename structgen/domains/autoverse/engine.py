"""The batched Autoverse engine: many games, each with its own rules, stepped together in torch on CPU or GPU.

One step, as the original runs it (``gen_env/envs/play_env.py``):

1. The player acts. Action 0 turns it one way (``rot + 1``), 1 the other (``rot - 1``), 2 moves it one cell forward
   along its (new) direction, 3 one cell back, 4 places ``force`` on the cell in front of its new position. Moves
   ignore what the cells hold and wrap around the edges. Directions, by ``rot``: (0, -1), (1, 0), (0, 1), (-1, 0)
   in (row, column).
2. Every rotation of every rule is matched on the map as it is after the action, all at once; each match writes
   its output (-1 removes a tile, +1 adds one) and the writes of all matches are summed and the map clipped to
   [0, 1]. Two removals of a tile remove it; a removal and an addition cancel, so the cell keeps what it had.
   The map is a torus for matching and writing.
3. The reward is the sum over rules of the rule's reward times its matches (all rotations; each match on the torus
   counted once).
4. The episode ends after ``episode_steps + 1`` steps (the original's cap is checked before its step counter grows:
   101 steps for 100).

How it is computed: a cell's tiles are one 5-bit code, so the state is a ``(B, N, N)`` uint8 map of codes. For each
rotation slot and each kernel cell that some game uses there (3 of 9 for 1x3 patterns), a per-game lookup table
turns the code under that cell into the set of rules whose input is satisfied there (a 5-bit mask); the masks of a
slot's cells are ANDed, and two more tables turn a cell's matching rules into its reward and into its writes (the
five tiles' -5..+5 changes packed in one int64), which are summed over the shifted cells and decoded. Everything is
gathers and integer arithmetic over the whole batch; ``Mechanics`` names the original's quirks. On a CPU the same
tables drive a numba kernel instead (:mod:`._kernels`, one game per parallel iteration), which avoids the overhead of
many small tensor operations; ``backend="torch"`` keeps the tensor code there too. Both equal the plain reference.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from structgen.devices import resolve_device
from structgen.domains.autoverse.game import FORCE, N_TILES, PLAYER
from structgen.threads import FasterOf, one_torch_thread

__all__ = [
    "DIRECTIONS",
    "EPISODE_STEPS",
    "Engine",
    "Mechanics",
    "Observation",
    "State",
    "codes",
    "compile_kernels",
    "multi_hot",
    "stack_games",
]

#: (row, column) step of each facing, by ``rot``.
DIRECTIONS = ((0, -1), (1, 0), (0, 1), (-1, 0))
#: The original's ``max_episode_steps``: an episode is one step longer (its cap is checked before counting).
EPISODE_STEPS = 100
_TURN = (1, -1, 0, 0, 0)
_MOVE = (0, 0, 1, -1, 0)
# Below this many games the numba step runs on one thread: on the 2-core box 16 games gained 15 % from a second
# thread when the machine was idle and lost 11 % when another process kept a core busy (benchmarks/threads.py).
# From there on, each engine times its parallel and serial kernels as it goes and uses the faster (FasterOf).
_PARALLEL_FROM_BATCH = 32


@dataclass(frozen=True)
class Mechanics:
    """Where the original's dynamics differ from what its paper describes, the choice of behaviour.

    Attributes:
        force_clear: every action other than placing also removes ``force`` from the cell in front of the player
            (the original indexes its placeable tiles with ``action - 4`` and writes 0 there). Default False: only
            action 4 touches that cell. True reproduces the original.
        empty_rules_fire: a rule rotation with an empty input pattern matches every cell (1,024 matches a step on a
            16x16 map). Default False: a rule with nothing to match never fires. True reproduces the original.
    """

    force_clear: bool = False
    empty_rules_fire: bool = False

    @classmethod
    def original(cls) -> Mechanics:
        """The released code's behaviour in every respect."""
        return cls(force_clear=True, empty_rules_fire=True)


@dataclass(frozen=True)
class Observation:
    """What an agent sees.

    Attributes:
        window: side of the square around the player that is shown (5, 10, 20), or -1 for the whole 31x31 view
            (the map seen from the player, every cell at most 15 away).
        hide_rules: zero the rules and rewards (the rotation one-hot stays).
        padding: "zeros" (the default, as the paper and the original: the 16x16 map seen from the player, zeros
            beyond its edges, although the dynamics wrap) or "wrap" (the view repeats the torus the player lives on,
            so what lies across an edge is visible where it acts).
        blank_window: the original environment's windowed view, which is all zeros for any window but the full one
            (it slices the wrong axes). Only to reproduce it.
    """

    window: int = -1
    hide_rules: bool = False
    padding: str = "zeros"
    blank_window: bool = False

    def __post_init__(self) -> None:
        if self.window != -1 and not (isinstance(self.window, int) and 1 <= self.window < 31):
            raise ValueError(f"observation window must be -1 (full) or 1..30, got {self.window!r}")
        if self.padding not in ("wrap", "zeros"):
            raise ValueError(f"observation padding must be 'wrap' or 'zeros', got {self.padding!r}")

    @classmethod
    def original(cls, window: int = -1, hide_rules: bool = False) -> Observation:
        return cls(window=window, hide_rules=hide_rules, padding="zeros", blank_window=True)


#: The flat observation: rotation one-hot (4), every rule tensor (5x4x2x5x3x3 = 1800), rewards (5), and two
#: reward-normalisation numbers that the original shows only when asked (zeros here, as in its paper runs).
FLAT_SIZE = 4 + 1800 + 5 + 2
VIEW = 31


@dataclass
class State:
    """A batch of game states; row ``i`` plays game ``game[i]`` of its engine.

    Attributes:
        map: ``(B, N, N)`` uint8 tile codes: bit ``c`` set when the cell holds tile ``c`` (see :func:`codes`).
        rot: ``(B,)`` int64 facing.
        pos: ``(B, 2)`` int64 (row, column) of the player.
        step: ``(B,)`` int64 steps taken in the episode.
        game: ``(B,)`` int64 index of each row's game.
    """

    map: torch.Tensor
    rot: torch.Tensor
    pos: torch.Tensor
    step: torch.Tensor
    game: torch.Tensor

    def __len__(self) -> int:
        return len(self.rot)

    def index(self, rows: torch.Tensor) -> State:
        return State(self.map[rows], self.rot[rows], self.pos[rows], self.step[rows], self.game[rows])

    def where(self, mask: torch.Tensor, other: State) -> State:
        """Rows of ``other`` where ``mask`` is set, of this state elsewhere."""
        return State(
            torch.where(mask.view(-1, 1, 1), other.map, self.map),
            torch.where(mask, other.rot, self.rot),
            torch.where(mask.view(-1, 1), other.pos, self.pos),
            torch.where(mask, other.step, self.step),
            torch.where(mask, other.game, self.game),
        )

    def multi_hot(self) -> torch.Tensor:
        """``(B, 5, N, N)`` uint8: the maps in the games' own form."""
        return multi_hot(self.map)


def codes(maps: torch.Tensor) -> torch.Tensor:
    """``(..., 5, N, N)`` multi-hot -> ``(..., N, N)`` uint8 codes."""
    weights = (2 ** torch.arange(N_TILES, device=maps.device)).view(N_TILES, 1, 1)
    return (maps.to(torch.int64) * weights).sum(dim=-3).to(torch.uint8)


def multi_hot(code: torch.Tensor) -> torch.Tensor:
    """``(..., N, N)`` codes -> ``(..., 5, N, N)`` uint8 multi-hot."""
    shifts = torch.arange(N_TILES, dtype=torch.uint8, device=code.device).view(N_TILES, 1, 1)
    return (code.unsqueeze(-3).to(torch.uint8) >> shifts) & 1


def stack_games(games: Sequence[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Games -> stacked arrays ``rules (G, ...)``, ``rewards (G, R)``, ``map (G, 5, N, N)``, ``dones (G, R)`` and
    ``free_moves (G,)`` (the last two from :func:`.game.game_options`, their defaults where a game has none)."""
    from structgen.domains.autoverse.game import game_options

    if not games:
        raise ValueError("no games given")
    stacked = {key: np.stack([np.asarray(g[key]) for g in games]) for key in ("rules", "rewards", "map")}
    options = [game_options(g) for g in games]
    stacked["dones"] = np.stack([o["dones"] for o in options])
    stacked["free_moves"] = np.array([o["free_moves"] for o in options], dtype=np.uint8)
    return stacked


_FIELD = 10  # bits per tile in a packed write: up to 36 contributions of 0..10 each
_BIAS = 5  # a contribution of -5..+5 is stored as 0..10


class Engine:
    """The games' rules compiled for batched stepping, on one device.

    ``step`` is a function of (state, actions): states are never modified in place, so a search can keep any
    number of them and step any subset. The player's position is tracked; in a game whose rules read or write the
    player channel (hand-written games: generated rules never do) it is looked up after the rules (the first player
    cell in row-major order, as the original finds it), and an episode ends where the rules removed the player. A
    step also ends the episode where a rule marked ``done`` fired, or at the step cap.
    """

    def __init__(
        self,
        games: Sequence[dict[str, Any]] | dict[str, np.ndarray],
        *,
        device: str | torch.device = "cpu",
        mechanics: Mechanics | None = None,
        episode_steps: int = EPISODE_STEPS,
        backend: str = "auto",
        compile: bool = False,
    ) -> None:
        arrays = games if isinstance(games, dict) else stack_games(games)
        self.device = resolve_device(device)
        if backend not in ("auto", "torch", "numba"):
            raise ValueError(f"backend must be 'auto', 'torch' or 'numba', got {backend!r}")
        if backend == "auto":
            backend = "numba" if self.device.type == "cpu" else "torch"
        if backend == "numba" and self.device.type != "cpu":
            raise ValueError("the numba backend runs on the CPU only")
        if compile and backend == "numba":
            raise ValueError("compile=True compiles the tensor code; the numba backend is compiled already")
        self.backend = backend
        self._kernel_choice = FasterOf()
        self._observe_choice = FasterOf(("one thread", "torch's threads"))
        # torch.compile fuses the rules' forty-odd gathers and shifts into a few kernels: 2.7x the env-steps/s on an
        # H100 at large batches, for about 20 s of compiling on first use (benchmarks/autoverse.md).
        self._rules = torch.compile(self._rules_on_codes, dynamic=False) if compile else self._rules_on_codes
        self.mechanics = mechanics = mechanics or Mechanics()
        self.episode_steps = episode_steps
        rules = torch.as_tensor(np.asarray(arrays["rules"], dtype=np.int8)).to(torch.int64)  # (G, R, 4, 2, C, 3, 3)
        if "dones" not in arrays:  # arrays stacked by hand: the options' defaults
            arrays = {
                **arrays,
                "dones": np.zeros(rules.shape[:2], dtype=np.uint8),
                "free_moves": np.ones(len(rules), dtype=np.uint8),
            }
        rule_dones = torch.as_tensor(np.asarray(arrays["dones"], dtype=np.int64))
        #: per game: actions 2 and 3 move the player (else only rules do), and the rules touch the player channel
        self._free_moves = torch.as_tensor(np.asarray(arrays["free_moves"], dtype=np.int64)).to(self.device)
        self._player_rules = (rules[:, :, :, :, PLAYER] != 0).flatten(1).any(dim=1).to(self.device)
        self._any_player_rules = bool(self._player_rules.any())
        self._all_free = bool(self._free_moves.all())
        rewards = torch.as_tensor(np.asarray(arrays["rewards"])).to(torch.int64)
        maps = torch.as_tensor(np.asarray(arrays["map"], dtype=np.uint8))
        self.n_games, self.n_rules = rules.shape[:2]
        if self.n_rules > 8:
            raise ValueError(f"at most 8 rules per game, got {self.n_rules}")
        self.size = int(maps.shape[-1])
        if maps.shape[1] != N_TILES or maps.shape[-2] != self.size:
            raise ValueError(f"maps must be (G, {N_TILES}, N, N), got {tuple(maps.shape)}")
        self.codes = codes(maps).to(self.device)
        self._every_game = torch.arange(self.n_games, device=self.device)
        self._directions = torch.tensor(DIRECTIONS, device=self.device)
        self._turn = torch.tensor(_TURN, device=self.device)
        self._move = torch.tensor(_MOVE, device=self.device)
        masks = torch.arange(1 << self.n_rules)  # every set of matching rules
        bits = (masks.view(-1, 1) >> torch.arange(self.n_rules)) & 1  # (M, R)
        tile_bit = 2 ** torch.arange(N_TILES)
        all_codes = torch.arange(1 << N_TILES)
        # reward of a cell from the set of rules matching there
        self._reward_table = (bits.unsqueeze(0) * rewards.unsqueeze(1)).sum(-1).to(self.device)  # (G, M)
        # whether a set of matching rules holds one that ends the episode
        self._done_table = ((bits.unsqueeze(0) * rule_dones.unsqueeze(1)).sum(-1) > 0).to(self.device)  # (G, M)
        self._any_rule_dones = bool(rule_dones.any())
        self._slots = []
        kernel_tables = []
        for o in range(rules.shape[2]):
            used = (rules[:, :, o] != 0).any(dim=(0, 1, 2, 3))  # (3, 3)
            # A slot nobody uses still runs (on the centre cell) when empty inputs fire everywhere.
            cells = [(int(dy), int(dx)) for dy, dx in used.nonzero().tolist()] or [(1, 1)]
            match_tables, write_tables, changes = [], [], []
            empty = rules[:, :, o, 0].sum(dim=(-3, -2, -1)) == 0  # (G, R)
            for index, (dy, dx) in enumerate(cells):
                required = (rules[:, :, o, 0, :, dy, dx] * tile_bit).sum(-1)  # (G, R) tile codes
                ok = (all_codes.view(1, 1, -1) & required.unsqueeze(-1)) == required.unsqueeze(-1)  # (G, R, 32)
                if index == 0 and not mechanics.empty_rules_fire:
                    ok &= ~empty.unsqueeze(-1)
                match_tables.append((ok.to(torch.int64) << torch.arange(self.n_rules).view(1, -1, 1)).sum(1))
                out = rules[:, :, o, 1, :, dy, dx]  # (G, R, C)
                change = (bits.view(1, -1, self.n_rules, 1) * out.unsqueeze(1)).sum(2) + _BIAS  # (G, M, C)
                write_tables.append((change << (_FIELD * torch.arange(N_TILES))).sum(-1))  # (G, M)
                changes.append(change - _BIAS)
            self._slots.append(
                (cells, torch.stack(match_tables, 1).to(self.device), torch.stack(write_tables, 1).to(self.device))
            )
            kernel_tables.append((cells, torch.stack(match_tables, 1), torch.stack(changes, 1)))
        if backend == "numba":
            self._kernel_tables = self._pad_for_kernel(kernel_tables)
        self._writes_per_cell = sum(len(cells) for cells, _, _ in self._slots)
        if self._writes_per_cell * 2 * _BIAS >= 1 << _FIELD:
            raise ValueError("too many kernel cells in use for the packed writes")
        self._flat_rules = (
            torch.cat([rules.reshape(self.n_games, -1), rewards, torch.zeros(self.n_games, 2, dtype=torch.int64)], dim=1)
            .to(torch.int8)
            .to(self.device)
        )
        self.initial_pos = self._player_positions(maps).to(self.device)
        self._tile_shifts = torch.arange(N_TILES, dtype=torch.uint8, device=self.device).view(1, N_TILES, 1)

    def _pad_for_kernel(self, tables: list) -> tuple[np.ndarray, ...]:
        """The slots' tables as fixed-shape arrays for the numba kernel (cells padded to the widest slot)."""
        width = max(len(cells) for cells, _, _ in tables)
        masks = 1 << self.n_rules
        n_cells = np.array([len(cells) for cells, _, _ in tables], dtype=np.int64)
        cells = np.ones((len(tables), width, 2), dtype=np.int64)
        match = np.zeros((self.n_games, len(tables), width, 1 << N_TILES), dtype=np.int64)
        change = np.zeros((self.n_games, len(tables), width, masks, N_TILES), dtype=np.int64)
        for s, (slot_cells, slot_match, slot_change) in enumerate(tables):
            cells[s, : len(slot_cells)] = slot_cells
            match[:, s, : len(slot_cells)] = slot_match.numpy()
            change[:, s, : len(slot_cells)] = slot_change.numpy()
        return (
            n_cells,
            cells,
            match,
            change,
            self._reward_table.cpu().numpy().astype(np.int64),
            self._done_table.cpu().numpy(),
            self._free_moves.cpu().numpy().astype(np.bool_),
            self._player_rules.cpu().numpy(),
        )

    # -- states ----------------------------------------------------------------------------------------------------------
    def _player_positions(self, maps: torch.Tensor) -> torch.Tensor:
        """The first player cell of each map in row-major order, as the original finds it."""
        flat = maps[:, PLAYER].reshape(len(maps), -1)
        if (flat.sum(dim=1) == 0).any():
            raise ValueError("a map has no player")
        cell = flat.to(torch.uint8).argmax(dim=1)
        return torch.stack([cell // self.size, cell % self.size], dim=1)

    def reset(self, games: torch.Tensor | None = None) -> State:
        """The initial state of each game in ``games`` (default: every game, in order)."""
        if games is None:
            games = torch.arange(self.n_games, device=self.device)
        games = games.to(self.device)
        zeros = torch.zeros(len(games), dtype=torch.int64, device=self.device)
        return State(self.codes[games], zeros.clone(), self.initial_pos[games], zeros, games)

    # -- dynamics --------------------------------------------------------------------------------------------------------
    def act(self, state: State, actions: torch.Tensor) -> State:
        """The player's part of a step: turn, move, place."""
        actions = actions.to(self.device).long()
        n = self.size
        rot = (state.rot + self._turn[actions]) % 4
        facing = self._directions[rot]
        move = self._move[actions] if self._all_free else self._move[actions] * self._free_moves[state.game]
        pos = (state.pos + move[:, None] * facing) % n
        target = (pos + facing) % n
        flat = state.map.reshape(len(state), n * n).clone()
        old_cell = (state.pos[:, 0] * n + state.pos[:, 1]).unsqueeze(1)
        flat.scatter_(1, old_cell, flat.gather(1, old_cell) & ~(1 << PLAYER))
        target_cell = (target[:, 0] * n + target[:, 1]).unsqueeze(1)
        front = flat.gather(1, target_cell)
        place = (actions == 4).unsqueeze(1)
        if self.mechanics.force_clear:
            front = torch.where(place, front | (1 << FORCE), front & ~(1 << FORCE))
        else:
            front = torch.where(place, front | (1 << FORCE), front)
        flat.scatter_(1, target_cell, front)
        new_cell = (pos[:, 0] * n + pos[:, 1]).unsqueeze(1)
        flat.scatter_(1, new_cell, flat.gather(1, new_cell) | (1 << PLAYER))
        return State(flat.view(len(state), n, n), rot, pos, state.step, state.game)

    def apply_rules(
        self, code: torch.Tensor, games: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Every rule on every map at once: ``(next codes, rewards, whether a rule marked done fired)``; row ``i`` uses
        game ``games[i]``'s rules."""
        # Decided outside the compiled part: a Python bool that depends on tensor values would break its graph.
        return self._rules(code, games, self._plays_every_game(games))

    def _rules_on_codes(
        self, code: torch.Tensor, games: torch.Tensor | None, identity: bool
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        count, n = len(code), self.size
        padded = F.pad(code.unsqueeze(1).float(), (1, 1, 1, 1), mode="circular").squeeze(1).to(torch.int64)
        writes = torch.zeros(count, n + 2, n + 2, dtype=torch.int64, device=self.device)
        reward_table = self._reward_table if identity else self._reward_table[games]
        done_table = self._done_table if identity or not self._any_rule_dones else self._done_table[games]
        reward = torch.zeros(count, dtype=torch.int64, device=self.device)
        ended = torch.zeros(count, dtype=torch.bool, device=self.device)
        for cells, match_tables, write_tables in self._slots:
            if not identity:
                match_tables, write_tables = match_tables[games], write_tables[games]
            matching = None
            for index, (dy, dx) in enumerate(cells):
                under = padded[:, dy : dy + n, dx : dx + n].reshape(count, n * n)
                found = match_tables[:, index].gather(1, under)
                matching = found if matching is None else matching & found
            reward += reward_table.gather(1, matching).sum(dim=1)
            if self._any_rule_dones:  # decided once per engine: generated games leave the step as it was
                ended |= done_table.gather(1, matching).any(dim=1)
            for index, (dy, dx) in enumerate(cells):
                writes[:, dy : dy + n, dx : dx + n] += write_tables[:, index].gather(1, matching).view(count, n, n)
        # Fold the writes that fell off an edge onto the other side of the torus (rows first, then columns, so that
        # corner writes reach the opposite corner).
        writes[:, n] += writes[:, 0]
        writes[:, 1] += writes[:, n + 1]
        writes[:, :, n] += writes[:, :, 0]
        writes[:, :, 1] += writes[:, :, n + 1]
        writes = writes[:, 1 : n + 1, 1 : n + 1]
        old = code.to(torch.int64)
        new = torch.zeros_like(old)
        base = self._writes_per_cell * _BIAS
        for tile in range(N_TILES):
            change = ((writes >> (_FIELD * tile)) & ((1 << _FIELD) - 1)) - base
            new |= ((((old >> tile) & 1) + change) >= 1).to(torch.int64) << tile
        return new.to(torch.uint8), reward.float(), ended

    def _plays_every_game(self, games: torch.Tensor | None) -> bool:
        """Whether rows are the games in order (their tables are then used as they are, without a gather)."""
        return games is None or (len(games) == self.n_games and bool((games == self._every_game).all()))

    def step(self, state: State, actions: torch.Tensor) -> tuple[State, torch.Tensor, torch.Tensor]:
        """``(next state, reward, done)`` for one action per row; rewards are the rules' raw rewards."""
        done = state.step >= self.episode_steps
        if self.backend == "numba":
            import numba

            from structgen.domains.autoverse import _kernels

            count = len(state)
            codes, rot, pos = torch.empty_like(state.map), torch.empty_like(state.rot), torch.empty_like(state.pos)
            reward = np.empty(count, dtype=np.int64)
            ended = np.empty(count, dtype=np.bool_)
            choosing = count >= _PARALLEL_FROM_BATCH and numba.get_num_threads() > 1
            way = self._kernel_choice.pick() if choosing else "serial"
            began = time.perf_counter()
            (_kernels.step if way == "parallel" else _kernels.step_serial)(
                state.map.numpy(),
                state.rot.numpy(),
                state.pos.numpy(),
                state.game.numpy(),
                actions.to(torch.int64).numpy(),
                *self._kernel_tables,
                self.mechanics.force_clear,
                codes.numpy(),
                rot.numpy(),
                pos.numpy(),
                reward,
                ended,
            )
            if choosing:
                self._kernel_choice.record(way, time.perf_counter() - began, count)
            stepped = State(codes, rot, pos, state.step + 1, state.game)
            return stepped, torch.from_numpy(reward).float(), done | torch.from_numpy(ended)
        moved = self.act(state, actions)
        next_maps, reward, ended = self.apply_rules(moved.map, state.game)
        pos = moved.pos
        if self._any_player_rules:
            pos, gone = self._find_players(next_maps, pos, state.game)
            ended = ended | gone
        return State(next_maps, moved.rot, pos, state.step + 1, state.game), reward, done | ended

    def _find_players(self, maps: torch.Tensor, pos: torch.Tensor, games: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Where rules may have moved the player: its first cell in row-major order (the position kept where it has
        none), and whether it has none."""
        n = self.size
        has = (maps.reshape(len(maps), n * n) & 1).bool()
        gone = ~has.any(dim=1)
        cell = has.to(torch.uint8).argmax(dim=1)
        found = torch.stack([cell // n, cell % n], dim=1)
        looked = (self._player_rules[games] & ~gone).unsqueeze(1)
        return torch.where(looked, found, pos), self._player_rules[games] & gone

    # -- observations ----------------------------------------------------------------------------------------------------
    def observe(self, state: State, observation: Observation | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """``(view (B, 5, 31, 31) uint8, flat (B, 1811) int8)``: the map around the player (not turned with it;
        the player at the centre) and the rotation one-hot, rules and rewards. Small integers, so a batch is a
        quarter of its float32 size; networks convert them on their device."""
        observation = observation or Observation()
        if self.device.type != "cpu":
            return self._observe(state, observation)
        # A handful of gathers and shifts: on small batches, or beside a busy process, torch's threads wait for each
        # other longer than they work (64 games: 0.2 ms on one thread, 0.4 on two); at thousands of games on an idle
        # machine they pay. Both ways give the same tensors, so the faster one of the moment is used.
        way = self._observe_choice.pick()
        began = time.perf_counter()
        if way == "one thread":
            with one_torch_thread():
                seen = self._observe(state, observation)
        else:
            seen = self._observe(state, observation)
        self._observe_choice.record(way, time.perf_counter() - began, len(state))
        return seen

    def _observe(self, state: State, observation: Observation) -> tuple[torch.Tensor, torch.Tensor]:
        count, n, half = len(state), self.size, VIEW // 2
        offsets = torch.arange(-half, half + 1, device=self.device)
        rows = (state.pos[:, 0:1] + offsets).unsqueeze(2)  # (B, 31, 1)
        cols = (state.pos[:, 1:2] + offsets).unsqueeze(1)  # (B, 1, 31)
        cells = ((rows % n) * n + cols % n).view(count, -1)
        seen = state.map.reshape(count, n * n).gather(1, cells)  # (B, 961) codes
        if observation.padding == "zeros":
            inside = ((rows >= 0) & (rows < n) & (cols >= 0) & (cols < n)).view(count, -1)
            seen = seen * inside
        view = ((seen.unsqueeze(1) >> self._tile_shifts) & 1).view(count, N_TILES, VIEW, VIEW)
        if observation.window != -1:
            if observation.blank_window:
                view = torch.zeros_like(view)
            else:
                low = (VIEW - observation.window) // 2
                high = low + observation.window
                mask = torch.zeros(VIEW, VIEW, dtype=torch.uint8, device=self.device)
                mask[low:high, low:high] = 1
                view = view * mask
        rules = self._flat_rules if self._plays_every_game(state.game) else self._flat_rules.index_select(0, state.game)
        if observation.hide_rules:
            rules = torch.zeros_like(rules)
        flat = torch.cat([F.one_hot(state.rot, 4).to(torch.int8), rules], dim=1)
        return view, flat


def compile_kernels() -> None:
    """Compile the numba backend's step functions (or load them from numba's cache in ``__pycache__``) by stepping a
    batch of random games: the engine tries its serial and, with several threads, its parallel kernel on the first
    steps. ``make install`` calls it (see :func:`structgen.registry.compile_kernels`)."""
    from structgen.domains.autoverse.game import random_game

    rng = np.random.default_rng(0)
    engine = Engine([random_game(rng) for _ in range(_PARALLEL_FROM_BATCH)], backend="numba")
    state = engine.reset()
    for _ in range(4):  # each way twice: to warm up, then to count
        state, _, _ = engine.step(state, torch.zeros(len(state), dtype=torch.int64))
