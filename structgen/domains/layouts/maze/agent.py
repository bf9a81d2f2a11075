"""A maze agent that learns: a map it keeps from what it has seen, a small network that acts on the map around it.

The agent sees what the paper's agent sees (the 5 x 5 cells in front of it and its direction, from
:class:`.env.TorchMazes`). Its memory is explicit rather than a recurrent network's: it counts its own steps
(a forward step moves it when the cell ahead in its last view was floor, which is exactly when the maze lets it), so
it knows where it stands relative to where it started, and it writes every view into a map around that start:
walls and floor seen, the goal if seen, and how many steps it has spent on each cell. The network sees a 9 x 9 patch
of that map centred on the agent and turned to face its way, a wider 27 x 27 patch in blocks of 3 x 3 (where it
has and has not been further off), and (``way_on``, the default since structgen 0.5) which way the goal, once on the
map, or else the nearest unexplored floor lies along the floor seen (:mod:`.way_on`): the summary of the whole map
that lets it keep its bearings in mazes far larger than its patches. The memory has no parameters and reads nothing
the view did not show; what to do with it (follow the way, look around where it ends, leave dead ends) is learned by
PPO.

Why explicit: on 2 CPU cores an LSTM agent like the paper's (trained by ACCEL for 20,000 updates on a GPU) is out of
reach in an hour, and path counting is what such an agent has to learn first anyway.

- :class:`PathMemory`: the map, for a batch of agents;
- :class:`MazePolicy`: the network (logits of left, right, forward, stay, and a value);
- :class:`RememberingMazes`: :class:`.env.TorchMazes` with memory, the environment PPO trains on;
- :func:`run_agent`: success rate and steps of a policy on a list of mazes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from structgen.domains.layouts.maze.env import STAY, VIEW, TorchMazes
from structgen.domains.layouts.maze.walkers import _STEPS, FORWARD
from structgen.domains.layouts.maze.way_on import WAY_FEATURES, first_steps

__all__ = ["CROP", "MazePolicy", "PathMemory", "RememberingMazes", "AgentResults", "run_agent"]

#: The side of the map patch the network sees cell by cell.
CROP = 9
#: Map channels: wall seen, floor seen, log(1 + steps spent on the cell), goal seen.
CHANNELS = 4
#: The wider, coarse patch: ``CROP`` x ``CROP`` blocks of ``BLOCK`` x ``BLOCK`` cells, each the share of its cells
#: seen as wall, seen as floor, walked on, and holding the goal.
BLOCK = 3
_REACH = CROP * BLOCK // 2


def _frame_deltas(rows: int, columns: int, ahead_of_top: int, left_of_first: int) -> torch.Tensor:
    """``deltas[facing, square] = (d_row, d_column)``: where each square of a window the agent carries (row-major,
    the top row ``ahead_of_top`` cells ahead of it, the first column ``left_of_first`` cells to its left) lies
    in the maze, for each way it can face."""
    table = np.zeros((4, rows * columns, 2), dtype=np.int64)
    for facing in range(4):
        (fr, fc), (rr, rc) = _STEPS[facing], _STEPS[(facing + 1) % 4]
        for row in range(rows):
            for column in range(columns):
                ahead, side = ahead_of_top - row, column - left_of_first
                table[facing, row * columns + column] = (ahead * fr + side * rr, ahead * fc + side * rc)
    return torch.as_tensor(table)


_VIEW_DELTAS = _frame_deltas(VIEW, VIEW, VIEW - 1, VIEW // 2)


def _turns() -> torch.Tensor:
    """``turns[facing, square]``: where each square of the patch the agent carries (or block of its coarse patch),
    turned to its facing, lies in the maze-aligned ``CROP`` x ``CROP`` square of cells (or blocks) around it, row by
    row."""
    deltas = _frame_deltas(CROP, CROP, CROP // 2, CROP // 2)
    return (deltas[..., 0] + CROP // 2) * CROP + deltas[..., 1] + CROP // 2


_TURN = _turns()
# The view square just ahead of the agent: its row is one up from the bottom, in the middle column.
_AHEAD = (VIEW - 2, VIEW // 2)


class PathMemory:
    """The maps of ``count`` agents, each a ``side`` x ``side`` torus around its start (a torus wider than the walled
    maze plus twice the farthest reach of the view or the coarse patch never folds two cells onto one, whatever the
    start: :func:`memory_side`)."""

    def __init__(self, count: int, side: int, device: torch.device | str) -> None:
        self.side = side
        self.maps = torch.zeros(count, CHANNELS, side * side, device=device)
        self.position = torch.zeros(count, 2, dtype=torch.int64, device=device)
        self._steps = torch.as_tensor(_STEPS, device=device)
        self._view_deltas = _VIEW_DELTAS.to(device)
        self._turn = _TURN.to(device)

    def state_dict(self) -> dict[str, torch.Tensor]:
        return {"maps": self.maps.cpu(), "position": self.position.cpu()}

    def load_state_dict(self, state: dict[str, torch.Tensor]) -> None:
        self.maps = state["maps"].to(self.maps.device)
        self.position = state["position"].to(self.position.device)
        self.side = int(self.maps.shape[-1] ** 0.5 + 0.5)

    def _cells(self, deltas: torch.Tensor) -> torch.Tensor:
        where = (self.position[:, None, :] + deltas) % self.side
        return where[..., 0] * self.side + where[..., 1]

    def start(self, rows: torch.Tensor) -> None:
        """Forget the maps of ``rows``: their agents stand at a new start."""
        self.maps[rows] = 0
        self.position[rows] = 0

    def see(self, view: torch.Tensor, direction: torch.Tensor, counted: torch.Tensor | None = None) -> None:
        """Write each agent's view into its map and count a step on the cell it stands on (only for the ``counted``
        rows when given: writing a view again changes nothing else)."""
        cells = self._cells(self._view_deltas[direction])  # (B, 25)
        flat = view.reshape(len(view), 2, -1).float()
        wall, goal = flat[:, 0], flat[:, 1]
        for channel, value in ((0, wall), (1, 1.0 - wall)):
            self.maps[:, channel].scatter_(1, cells, value)
        self.maps[:, 3].scatter_(1, cells, torch.maximum(self.maps[:, 3].gather(1, cells), goal))
        here = self._cells(torch.zeros(1, 1, 2, dtype=torch.int64, device=view.device)).expand(len(view), 1)
        one = torch.ones_like(here, dtype=self.maps.dtype) if counted is None else counted[:, None].to(self.maps.dtype)
        self.maps[:, 2].scatter_add_(1, here, one)

    def move(self, moved: torch.Tensor, direction: torch.Tensor) -> None:
        self.position += moved[:, None].long() * self._steps[direction]

    def _square(self, reach: int) -> torch.Tensor:
        """``(B, (2 reach + 1)^2)``: the cells of the square around each agent, maze-aligned, row by row. Indexed
        by rows and columns apart, it costs a fraction of turning every square's delta (:meth:`_cells`)."""
        offsets = torch.arange(-reach, reach + 1, device=self.position.device)
        rows = (self.position[:, :1] + offsets) % self.side
        columns = (self.position[:, 1:] + offsets) % self.side
        return (rows[:, :, None] * self.side + columns[:, None, :]).flatten(1)

    def _gather(self, cells: torch.Tensor) -> torch.Tensor:
        return self.maps.gather(2, cells[:, None, :].expand(-1, CHANNELS, -1))

    def patch(self, direction: torch.Tensor) -> torch.Tensor:
        """``(B, CHANNELS, CROP, CROP)``: the map around each agent, turned so that it faces up."""
        seen = self._gather(self._square(CROP // 2).gather(1, self._turn[direction]))
        seen[:, 2] = torch.log1p(seen[:, 2])
        return seen.reshape(len(seen), CHANNELS, CROP, CROP)

    def coarse(self, direction: torch.Tensor) -> torch.Tensor:
        """``(B, CHANNELS, CROP, CROP)``: the wider map around each agent in blocks, turned so that it faces up.
        The blocks are pooled before they are turned: a block is the same cells either way, and as every channel
        pooled holds 0 or 1, the sum is exact in any order, so the result equals pooling the turned square."""
        side = CROP * BLOCK
        seen = self._gather(self._square(_REACH))
        seen[:, 2] = (seen[:, 2] > 0).to(seen.dtype)
        blocks = torch.nn.functional.avg_pool2d(seen.reshape(len(seen), CHANNELS, side, side), BLOCK).flatten(2)
        return blocks.gather(2, self._turn[direction][:, None, :].expand(-1, CHANNELS, -1)).reshape(-1, CHANNELS, CROP, CROP)

    def way_on(self, direction: torch.Tensor) -> torch.Tensor:
        """``(B, WAY_FEATURES)``: which way the goal (once on the map and reachable) or else the nearest unexplored
        floor lies along the floor seen, relative to each agent's facing, with the path's length
        (:mod:`.way_on`). The search runs on the CPU; on another device the maps are copied there first."""
        maps = self.maps.detach().cpu()
        goal_seen, goal_cell = maps[:, 3].max(dim=1)
        goal = torch.where(goal_seen > 0, goal_cell, -1).numpy()
        way, length, to_goal = first_steps(maps.numpy(), goal, self.position.cpu().numpy(), self.side)
        features = torch.zeros(len(way), WAY_FEATURES)
        going = torch.as_tensor(way >= 0)
        relative = (torch.as_tensor(way) - direction.cpu()) % 4
        features[going, relative[going]] = 1.0
        features[:, 4] = torch.where(going, torch.log1p(torch.as_tensor(length, dtype=torch.float32)) / 8.0, 0.0)
        features[:, 5] = torch.as_tensor(to_goal, dtype=torch.float32)
        return features.to(self.maps.device)


def memory_side(mazes: TorchMazes) -> int:
    """The side of a :class:`PathMemory` torus for ``mazes``: cells written lie within the view's reach (4) of the
    walled maze and cells read within the coarse patch's, so the torus must be wider than the walled maze plus both
    reaches."""
    walled = max(mazes.shape) + 2
    return walled + 2 * _REACH + VIEW + 1


class RememberingMazes:
    """:class:`TorchMazes` whose agents keep a :class:`PathMemory`; observations are ``(patch, coarse patch,
    direction)``, with ``way_on`` also :meth:`PathMemory.way_on`'s features, and :meth:`step` returns
    ``(observation, reward, done)`` as :class:`structgen.ppo.PPO` wants. ``reached`` and ``cut`` of the last step
    are kept as attributes."""

    def __init__(self, mazes: TorchMazes, *, way_on: bool = False) -> None:
        self.mazes = mazes
        self.way_on = way_on
        self.memory = PathMemory(mazes.count, memory_side(mazes), mazes.device)
        self._view: torch.Tensor | None = None

    def _observe(
        self, view: torch.Tensor, direction: torch.Tensor, counted: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        self.memory.see(view, direction, counted)
        return self._features(view, direction)

    def _features(self, view: torch.Tensor, direction: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The observation the policy sees, from the memory as it stands; ``view`` is kept for the next move."""
        self._view = view
        seen = self.memory.patch(direction), self.memory.coarse(direction), direction
        return (*seen, self.memory.way_on(direction)) if self.way_on else seen

    def reset(self, directions: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Start every maze afresh (facing ``directions`` when given, else as drawn by the mazes' seed)."""
        view, direction = self.mazes.reset()
        if directions is not None:
            self.mazes.direction = directions.to(self.mazes.device).long().clone()
            view, direction = self.mazes.observe()
        self.memory.start(torch.arange(self.mazes.count, device=self.mazes.device))
        return self._observe(view, direction)

    def keep(self, rows: torch.Tensor) -> None:
        """Go on with ``rows`` of the batch only (the rest are dropped)."""
        self.mazes.keep(rows)
        self.memory.maps, self.memory.position = self.memory.maps[rows], self.memory.position[rows]
        if self._view is not None:
            self._view = self._view[rows]

    def current(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The observation as it stands, the memory unchanged (after loading a checkpoint)."""
        return self._features(*self.mazes.observe())

    def restart(self, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Observations after ``rows`` were given new levels (:meth:`TorchMazes.set_levels`): their maps start
        afresh; the others' maps already hold the current view and its step."""
        self.memory.start(rows)
        counted = torch.zeros(self.mazes.count, dtype=torch.bool, device=self.mazes.device)
        counted[rows] = True
        return self._observe(*self.mazes.observe(), counted)

    def step(self, actions: torch.Tensor) -> tuple[tuple[torch.Tensor, ...], torch.Tensor, torch.Tensor]:
        assert self._view is not None, "call reset() before step()"
        actions = actions.to(self.mazes.device)
        heading = self.mazes.direction.clone()
        moved = (actions == FORWARD) & (self._view[:, 0, _AHEAD[0], _AHEAD[1]] == 0)
        (view, direction), reward, reached, cut = self.mazes.step(actions)
        self.reached, self.cut = reached, cut
        self.memory.move(moved, heading)
        done = reached | cut
        if bool(done.any()):
            self.memory.start(done.nonzero().flatten())
        return self._observe(view, direction), reward, done


class MazePolicy(nn.Module):
    """Logits over left, right, forward, stay and a value, from the two map patches and the direction, and with
    ``way_on`` the way to the goal or the nearest unexplored floor (:meth:`PathMemory.way_on`)."""

    def __init__(self, hidden: int = 256, *, way_on: bool = False) -> None:
        super().__init__()
        self.hidden = hidden
        self.way_on = way_on
        inputs = 2 * CHANNELS * CROP * CROP + 4 + (WAY_FEATURES if way_on else 0)
        self.body = nn.Sequential(nn.Linear(inputs, hidden), nn.ReLU(), nn.Linear(hidden, hidden), nn.ReLU())
        self.actor = nn.Linear(hidden, 4)
        self.critic = nn.Linear(hidden, 1)
        nn.init.zeros_(self.actor.bias)
        self.actor.weight.data.mul_(0.01)

    def forward(
        self, patch: torch.Tensor, coarse: torch.Tensor, direction: torch.Tensor, way: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        parts = [patch.flatten(1), coarse.flatten(1), nn.functional.one_hot(direction, 4).float()]
        features = torch.cat(parts if way is None else [*parts, way], dim=1)
        hidden = self.body(features)
        return self.actor(hidden), self.critic(hidden).squeeze(-1)


@dataclass(frozen=True)
class AgentResults:
    """Over the mazes: the share of episodes that reached the goal and the mean steps taken (failures count the
    horizon), per maze and overall."""

    reached: np.ndarray  # (mazes,) share of episodes that reached the goal
    steps: np.ndarray  # (mazes,) mean steps
    episodes: int = 1

    @property
    def success_rate(self) -> float:
        return float(self.reached.mean())

    @property
    def standard_error(self) -> float:
        """Of the success rate: over mazes when there are several, else over the one maze's episodes."""
        if len(self.reached) > 1:
            return float(self.reached.std(ddof=1) / np.sqrt(len(self.reached)))
        rate = float(self.reached[0])
        return float(np.sqrt(rate * (1 - rate) / self.episodes))


@torch.no_grad()
def run_agent(
    policy: MazePolicy,
    mazes: list[np.ndarray],
    *,
    episodes: int = 1,
    seed: int = 0,
    seeds: list[int] | np.ndarray | None = None,
    device: str = "cpu",
) -> AgentResults:
    """Run ``policy`` for ``episodes`` episodes on each maze, all at once (one batch row per maze and episode, a row
    leaving the batch when its episode ends), actions sampled from the policy. Maze ``i``'s starting directions and
    action draws come from its own seed (``seeds[i]``, or ``(seed, i)``), so its result does not depend on the mazes
    beside it."""
    batch = [m for m in mazes for _ in range(episodes)]
    streams = [np.random.default_rng([seed, i] if seeds is None else int(seeds[i])) for i in range(len(mazes))]
    directions = torch.as_tensor(np.concatenate([rng.integers(0, 4, episodes) for rng in streams]))
    env = RememberingMazes(TorchMazes(batch, device=device), way_on=policy.way_on)
    observation = env.reset(directions)
    rows = torch.arange(len(batch))  # the episode each row of the batch plays
    running = torch.ones(len(batch), dtype=torch.bool)  # by row: finished rows stay put until the batch shrinks
    reached = torch.zeros(len(batch), dtype=torch.bool)
    steps = torch.full((len(batch),), env.mazes.horizon, dtype=torch.int64)
    policy = policy.to(env.mazes.device).eval()
    for step in range(1, env.mazes.horizon + 1):
        alive = running.nonzero().flatten()
        logits, _ = policy(*(part[alive.to(env.mazes.device)] for part in observation))
        chance = torch.softmax(logits.double(), -1).cumsum(-1).cpu()
        draw = torch.as_tensor(np.concatenate([rng.random(episodes) for rng in streams]))[rows[alive]]
        action = torch.full((len(rows),), STAY, dtype=torch.int64)
        action[alive] = (draw[:, None] > chance[:, :-1]).sum(-1)
        observation, _, done = env.step(action)
        done = done.cpu() & running
        if bool(done.any()):
            reached[rows[done]], steps[rows[done]] = env.reached.cpu()[done], step
            running &= ~done
            left = int(running.sum())
            if not left:
                break
            # Dropping finished rows copies every map: worth it only once a quarter of the batch has finished.
            if left <= 0.75 * len(rows):
                kept = running.nonzero().flatten()
                env.keep(kept.to(env.mazes.device))
                observation = tuple(part[kept.to(env.mazes.device)] for part in observation)
                rows, running = rows[kept], running[kept]
    shape = (len(mazes), episodes)
    return AgentResults(reached.reshape(shape).float().mean(1).numpy(), steps.reshape(shape).float().mean(1).numpy(), episodes)
