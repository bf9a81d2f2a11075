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

How it is computed: for each rotation slot, the kernel cells that any game uses there (3 of 9 for 1x3 patterns)
are read from the circularly padded map, a batched matrix product counts each rule's satisfied input tiles per cell,
and a second one spreads the outputs of the matches back; ``Mechanics`` names the original's quirks.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F

from structgen.domains.autoverse.game import FORCE, N_TILES, PLAYER

__all__ = ["DIRECTIONS", "EPISODE_STEPS", "Engine", "Mechanics", "Observation", "State", "stack_games"]

#: (row, column) step of each facing, by ``rot``.
DIRECTIONS = ((0, -1), (1, 0), (0, 1), (-1, 0))
#: The original's ``max_episode_steps``: an episode is one step longer (its cap is checked before counting).
EPISODE_STEPS = 100
_TURN = (1, -1, 0, 0, 0)
_MOVE = (0, 0, 1, -1, 0)


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
        padding: "wrap" shows the torus the player lives on; "zeros" shows zeros beyond the map's edges, as the
            original does although its dynamics wrap.
        blank_window: the original environment's windowed view, which is all zeros for any window but the full one
            (it slices the wrong axes). Only to reproduce it.
    """

    window: int = -1
    hide_rules: bool = False
    padding: str = "wrap"
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
        map: ``(B, 5, N, N)`` uint8 multi-hot.
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
        m = mask.view(-1, 1, 1, 1)
        return State(
            torch.where(m, other.map, self.map),
            torch.where(mask, other.rot, self.rot),
            torch.where(mask.view(-1, 1), other.pos, self.pos),
            torch.where(mask, other.step, self.step),
            torch.where(mask, other.game, self.game),
        )


def stack_games(games: Sequence[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Games -> stacked arrays ``rules (G, ...)``, ``rewards (G, 5)``, ``map (G, 5, N, N)``."""
    if not games:
        raise ValueError("no games given")
    return {key: np.stack([np.asarray(g[key]) for g in games]) for key in ("rules", "rewards", "map")}


class Engine:
    """The games' rules compiled for batched stepping, on one device.

    ``step`` is a function of (state, actions): states are never modified in place, so a search can keep any
    number of them and step any subset.
    """

    def __init__(
        self,
        games: Sequence[dict[str, Any]] | dict[str, np.ndarray],
        *,
        device: str | torch.device = "cpu",
        mechanics: Mechanics = Mechanics(),
        episode_steps: int = EPISODE_STEPS,
    ) -> None:
        arrays = games if isinstance(games, dict) else stack_games(games)
        self.device = torch.device(device)
        self.mechanics = mechanics
        self.episode_steps = episode_steps
        rules = torch.as_tensor(np.asarray(arrays["rules"], dtype=np.int8), device=self.device).float()
        self.rules = rules  # (G, R, 4, 2, C, 3, 3)
        self.rewards = torch.as_tensor(np.asarray(arrays["rewards"]), device=self.device).float()
        self.maps = torch.as_tensor(np.asarray(arrays["map"], dtype=np.uint8), device=self.device)
        self.n_games, self.n_rules = rules.shape[:2]
        self.size = int(self.maps.shape[-1])
        if self.maps.shape[1] != N_TILES or self.maps.shape[-2] != self.size:
            raise ValueError(f"maps must be (G, {N_TILES}, N, N), got {tuple(self.maps.shape)}")
        self._directions = torch.tensor(DIRECTIONS, device=self.device)
        self._turn = torch.tensor(_TURN, device=self.device)
        self._move = torch.tensor(_MOVE, device=self.device)
        # Per rotation slot: the kernel cells some game uses, and the kernels reduced to them.
        self._slots = []
        for o in range(rules.shape[2]):
            used = (rules[:, :, o] != 0).any(dim=(0, 1, 2, 3))  # (3, 3)
            # A slot nobody uses still runs (on the centre cell) when empty inputs fire everywhere.
            cells = [(int(dy), int(dx)) for dy, dx in used.nonzero().tolist()] or [(1, 1)]
            ys, xs = zip(*cells)
            k_in = rules[:, :, o, 0][..., list(ys), list(xs)]  # (G, R, C, L)
            k_out = rules[:, :, o, 1][..., list(ys), list(xs)]
            need = rules[:, :, o, 0].sum(dim=(-3, -2, -1))  # (G, R)
            # An input with no tiles matches everywhere in the original; a rule that can never match is the same as
            # one that never fires, so the sensible behaviour sets its count out of reach.
            if not mechanics.empty_rules_fire:
                need = torch.where(need == 0, torch.full_like(need, -1.0), need)
            self._slots.append(
                (
                    cells,
                    k_in.reshape(self.n_games, self.n_rules, -1).contiguous(),  # (G, R, C*L)
                    k_out.reshape(self.n_games, self.n_rules, -1).transpose(1, 2).contiguous(),  # (G, C*L, R)
                    need,
                )
            )
        self._flat_rules = torch.cat(
            [rules.reshape(self.n_games, -1), self.rewards, torch.zeros(self.n_games, 2, device=self.device)], dim=1
        )
        self.initial_pos = self._player_positions(self.maps)

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
        count = len(games)
        zeros = torch.zeros(count, dtype=torch.int64, device=self.device)
        return State(self.maps[games].clone(), zeros.clone(), self.initial_pos[games].clone(), zeros, games)

    # -- dynamics --------------------------------------------------------------------------------------------------------
    def act(self, state: State, actions: torch.Tensor) -> State:
        """The player's part of a step: turn, move, place."""
        actions = actions.to(self.device).long()
        n, size = self.size, len(state)
        rot = (state.rot + self._turn[actions]) % 4
        facing = self._directions[rot]
        pos = (state.pos + self._move[actions, None] * facing) % n
        target = (pos + facing) % n
        game_map = state.map.clone()
        rows = torch.arange(size, device=self.device)
        game_map[rows, PLAYER, state.pos[:, 0], state.pos[:, 1]] = 0
        place = actions == 4
        if self.mechanics.force_clear:
            game_map[rows, FORCE, target[:, 0], target[:, 1]] = place.to(torch.uint8)
        else:
            old = game_map[rows, FORCE, target[:, 0], target[:, 1]]
            game_map[rows, FORCE, target[:, 0], target[:, 1]] = torch.where(place, torch.ones_like(old), old)
        game_map[rows, PLAYER, pos[:, 0], pos[:, 1]] = 1
        return State(game_map, rot, pos, state.step, state.game)

    def apply_rules(self, maps: torch.Tensor, games: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Every rule on every map at once: ``(next maps, rewards)``; row ``i`` uses game ``games[i]``'s rules."""
        count, n = len(maps), self.size
        identity = games is None or (len(games) == self.n_games and bool((games == self._arange()).all()))
        current = maps.float()
        padded = F.pad(current, (1, 1, 1, 1), mode="circular")
        writes = torch.zeros(count, N_TILES, n + 2, n + 2, device=self.device)
        reward = torch.zeros(count, device=self.device)
        rewards = self.rewards if identity else self.rewards[games]
        for cells, k_in, k_out, need in self._slots:
            if not identity:
                k_in, k_out, need = k_in[games], k_out[games], need[games]
            views = torch.stack([padded[:, :, dy : dy + n, dx : dx + n] for dy, dx in cells], dim=2)
            counts = torch.bmm(k_in, views.reshape(count, -1, n * n))  # (B, R, N*N)
            matches = (counts == need.unsqueeze(-1)).float()
            reward += (matches.sum(dim=-1) * rewards).sum(dim=-1)
            spread = torch.bmm(k_out, matches).view(count, N_TILES, len(cells), n, n)
            for index, (dy, dx) in enumerate(cells):
                writes[:, :, dy : dy + n, dx : dx + n] += spread[:, :, index]
        # Fold the writes that fell off an edge onto the other side of the torus (rows first, then columns, so that
        # corner writes reach the opposite corner).
        writes[:, :, n] += writes[:, :, 0]
        writes[:, :, 1] += writes[:, :, n + 1]
        writes[:, :, :, n] += writes[:, :, :, 0]
        writes[:, :, :, 1] += writes[:, :, :, n + 1]
        next_maps = (current + writes[:, :, 1 : n + 1, 1 : n + 1]).clamp_(0, 1).to(torch.uint8)
        return next_maps, reward

    def _arange(self) -> torch.Tensor:
        if not hasattr(self, "_games_arange"):
            self._games_arange = torch.arange(self.n_games, device=self.device)
        return self._games_arange

    def step(self, state: State, actions: torch.Tensor) -> tuple[State, torch.Tensor, torch.Tensor]:
        """``(next state, reward, done)`` for one action per row; rewards are the rules' raw rewards."""
        moved = self.act(state, actions)
        next_maps, reward = self.apply_rules(moved.map, state.game)
        done = state.step >= self.episode_steps
        return State(next_maps, moved.rot, moved.pos, state.step + 1, state.game), reward, done

    # -- observations ----------------------------------------------------------------------------------------------------
    def observe(self, state: State, observation: Observation = Observation()) -> tuple[torch.Tensor, torch.Tensor]:
        """``(view (B, 5, 31, 31) float32, flat (B, 1811) float32)``: the map around the player (not turned with
        it; the player at the centre) and the rotation one-hot, rules and rewards."""
        count, n, half = len(state), self.size, VIEW // 2
        offsets = torch.arange(-half, half + 1, device=self.device)
        rows = state.pos[:, 0:1] + offsets  # (B, 31)
        cols = state.pos[:, 1:2] + offsets
        batch = torch.arange(count, device=self.device)[:, None, None]
        if observation.padding == "wrap":
            view = state.map[batch, :, rows[:, :, None] % n, cols[:, None, :] % n]  # (B, 31, 31, C)
        else:
            padded = F.pad(state.map, (half, half, half, half))
            view = padded[batch, :, rows[:, :, None] + half, cols[:, None, :] + half]
        view = view.permute(0, 3, 1, 2).float()
        if observation.window != -1:
            if observation.blank_window:
                view = torch.zeros_like(view)
            else:
                low = (VIEW - observation.window) // 2
                high = low + observation.window
                mask = torch.zeros(VIEW, VIEW, device=self.device)
                mask[low:high, low:high] = 1
                view = view * mask
        rules = self._flat_rules[state.game]
        if observation.hide_rules:
            rules = torch.zeros_like(rules)
        flat = torch.cat([F.one_hot(state.rot, 4).float(), rules], dim=1)
        return view, flat
