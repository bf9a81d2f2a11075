"""Mazes as a batched environment in torch, and as Gymnasium environments, for agents that learn.

The agent model is the paper's (and :mod:`.walkers`'s scripted agents'): the agent stands in a maze with an outer wall,
starts at one end of the longest shortest path facing a random direction, and must reach the other end. It sees the
5 x 5 cells in front of it (it stands at the middle of the bottom row; walls do not hide what lies behind them, and
cells beyond the map read as wall) and its direction, and each step it turns left, turns right, steps forward
(blocked by walls) or stays. An episode ends at the goal, with reward ``1 - 0.9 * steps / horizon`` (MiniGrid's), or
is cut off after ``horizon = 2 x`` the cells of the walled maze (648 for 16 x 16), with reward 0.

- :class:`TorchMazes`: ``B`` mazes of one size stepped together as tensors on any device; an episode that ends
  restarts in the same step (its last observation is kept in :attr:`TorchMazes.final`).
- ``structgen/Maze-v0`` (:class:`MazeEnv`): one maze at a time, the next of the list it was given at each reset (or a
  random maze). Observations: ``view`` (2, 5, 5) uint8, walls then the goal, and ``direction`` (0 north, 1 east,
  2 south, 3 west). Its vector entry point is :class:`MazeVectorEnv`.
- :func:`random_maze`: solvable random mazes, scattered walls or carved corridors, for training and testing.

Importing this module registers the id.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from structgen.devices import resolve_device
from structgen.domains.layouts.maze.walkers import _STEPS, FORWARD, LEFT, MAZE_KINDS, RIGHT, diameter
from structgen.errors import InputError
from structgen.threads import one_torch_thread

__all__ = ["ENV_ID", "MAZE_KINDS", "STAY", "MazeEnv", "MazeVectorEnv", "TorchMazes", "random_maze"]

ENV_ID = "structgen/Maze-v0"
#: The fourth action: stand still for a step.
STAY = 3
VIEW = 5


def random_maze(rng: np.random.Generator, size: int = 16, kind: str = "scattered", density: float | None = None) -> np.ndarray:
    """A solvable ``size`` x ``size`` maze (1 wall, 0 floor, without the outer wall), drawn until solvable.

    ``scattered``: each cell a wall with probability ``density`` (drawn from 0.1-0.5 when None), like the random
    obstacle levels that curricula start from. ``carved``: corridors one cell wide carved by a depth-first walk,
    then ``density`` (0-0.1 when None) of the walls knocked down to make loops. ``rooms``: 3-8 straight walls
    across the maze with one or two doors each, then ``density`` (0-0.1 when None) of the cells walls (the maze
    agent never trains on these: they test it on a kind of maze it has not seen). ``perfect``: carved corridors with no
    wall knocked down, so exactly one path joins any two floor cells (``density`` must be None or 0)."""
    _check_kind_and_size(kind, size)
    while True:
        if kind == "scattered":
            p = rng.uniform(0.1, 0.5) if density is None else density
            maze = (rng.random((size, size)) < p).astype(np.uint8)
        elif kind == "carved":
            maze = _carved(rng, size, rng.uniform(0.0, 0.1) if density is None else density)
        elif kind == "perfect":
            if density:
                raise InputError(f"a perfect maze has no knocked-down walls; density must be 0, got {density!r}")
            maze = _carved(rng, size, 0.0)
        else:
            maze = _rooms(rng, size, rng.uniform(0.0, 0.1) if density is None else density)
        if _has_two_connected_floor_cells(maze):
            return maze


def _has_two_connected_floor_cells(maze: np.ndarray) -> bool:
    """Whether :func:`.walkers.diameter` would find a start and a goal: some two floor cells side by side (checked
    here without its search from every cell, which :class:`TorchMazes` runs once per maze anyway)."""
    floor = maze == 0
    return bool((floor[:, 1:] & floor[:, :-1]).any() or (floor[1:, :] & floor[:-1, :]).any())


def _check_kind_and_size(kind: str, size: int) -> None:
    if kind not in MAZE_KINDS:
        raise InputError(f"unknown maze kind {kind!r}; choose one of {', '.join(MAZE_KINDS)}")
    if not isinstance(size, int) or isinstance(size, bool) or not 2 <= size <= 1024:
        raise InputError(f"maze size must be an integer from 2 to 1024, got {size!r}")


def _carved(rng: np.random.Generator, size: int, knock_down: float) -> np.ndarray:
    maze = np.ones((size, size), dtype=np.uint8)
    start = (int(rng.integers(0, size, 1)[0]) // 2 * 2, int(rng.integers(0, size, 1)[0]) // 2 * 2)
    maze[start] = 0
    stack = [start]
    while stack:
        r, c = stack[-1]
        options = [
            (r + 2 * dr, c + 2 * dc, r + dr, c + dc)
            for dr, dc in _STEPS
            if 0 <= r + 2 * dr < size and 0 <= c + 2 * dc < size and maze[r + 2 * dr, c + 2 * dc]
        ]
        if not options:
            stack.pop()
            continue
        nr, nc, wr, wc = options[int(rng.integers(len(options)))]
        maze[wr, wc] = maze[nr, nc] = 0
        stack.append((nr, nc))
    walls = np.argwhere(maze == 1)
    if len(walls) and knock_down > 0:
        chosen = walls[rng.random(len(walls)) < knock_down]
        maze[chosen[:, 0], chosen[:, 1]] = 0
    return maze


def _rooms(rng: np.random.Generator, size: int, clutter: float) -> np.ndarray:
    maze = np.zeros((size, size), dtype=np.uint8)
    for _ in range(int(rng.integers(3, 9))):
        line = int(rng.integers(size))
        doors = rng.integers(0, size, int(rng.integers(1, 3)))
        if rng.random() < 0.5:
            maze[line, :] = 1
            maze[line, doors] = 0
        else:
            maze[:, line] = 1
            maze[doors, line] = 0
    maze[rng.random((size, size)) < clutter] = 1
    return maze


def _ends(maze: np.ndarray) -> tuple[tuple[int, int], tuple[int, int]]:
    found = diameter(maze)
    if found is None:
        raise InputError("a maze with no two connected floor cells has no start and goal")
    return found[0], found[1]


class TorchMazes:
    """``mazes`` (grown mazes of one size: 1 wall, 0 floor, no outer wall) stepped together on ``device``.

    :meth:`reset` and :meth:`step` return observations as ``(view, direction)``: ``(B, 2, 5, 5)`` uint8 (walls,
    goal) and ``(B,)`` int64. Starting directions are drawn from ``seed``. Positions are kept as flat indices into
    each maze padded with wall all round, so that a step is a handful of gathers and a view never reads outside."""

    def __init__(self, mazes: list[np.ndarray] | np.ndarray, *, device: str = "cpu", seed: int = 0) -> None:
        self.device = resolve_device(device)
        self.generator = torch.Generator(device="cpu").manual_seed(int(seed))
        self.set_levels(mazes)

    def set_levels(self, mazes: list[np.ndarray] | np.ndarray, rows: Any = None) -> None:
        """Put ``mazes`` in the batch: all of it (``rows`` None), or in place of ``rows``; those start afresh."""
        mazes = [np.asarray(m) for m in mazes]
        shapes = {m.shape for m in mazes}
        if not mazes or len(shapes) != 1 or len(next(iter(shapes))) != 2:
            raise InputError(f"mazes must be a non-empty list of 2D arrays of one shape, got shapes {sorted(shapes)}")
        shape = mazes[0].shape
        if rows is not None and shape != self.shape:
            raise InputError(f"mazes of shape {shape} cannot join a batch of {self.shape}")
        # The walled maze, then a margin of 4 more wall cells so that any 5 x 5 view reads inside the tensor.
        width = shape[1] + 2 * _MARGIN
        found: dict[bytes, Any] = {}  # a maze repeated for many episodes is searched once
        ends = [found[m.tobytes()] if m.tobytes() in found else found.setdefault(m.tobytes(), _ends(m)) for m in mazes]
        walls = torch.as_tensor(np.stack([np.pad(m == 1, _MARGIN, constant_values=True).ravel() for m in mazes]))
        start = torch.as_tensor([(r + _MARGIN) * width + c + _MARGIN for (r, c), _ in ends])
        goal = torch.as_tensor([(r + _MARGIN) * width + c + _MARGIN for _, (r, c) in ends])
        walls, start, goal = walls.to(self.device), start.to(self.device), goal.to(self.device)
        if rows is None:
            self._set_shape(shape)
            self.walls, self.start, self.goal = walls, start, goal
            count = len(mazes)
            self.position = start.clone()
            self.direction = torch.zeros(count, dtype=torch.int64, device=self.device)
            self.steps = torch.zeros(count, dtype=torch.int64, device=self.device)
            rows = torch.arange(count, device=self.device)
        else:
            rows = torch.as_tensor(rows, device=self.device)
            self.walls[rows], self.start[rows], self.goal[rows] = walls, start, goal
        self._restart(rows)

    def _set_shape(self, shape: tuple[int, int]) -> None:
        self.shape = shape
        self.width = shape[1] + 2 * _MARGIN
        self.horizon = 2 * (shape[0] + 2) * (shape[1] + 2)
        self._view_at = _view_offsets(self.width).to(self.device)  # (4, 25) flat offsets by direction
        self._step_by = torch.as_tensor([dr * self.width + dc for dr, dc in _STEPS], device=self.device)

    @property
    def count(self) -> int:
        return len(self.walls)

    _STATE = ("walls", "start", "goal", "position", "direction", "steps")

    def keep(self, rows: torch.Tensor) -> None:
        """Go on with ``rows`` of the batch only (the rest are dropped)."""
        for name in self._STATE:
            setattr(self, name, getattr(self, name)[rows])

    def state_dict(self) -> dict[str, Any]:
        """Everything a checkpoint needs to go on exactly where this batch stands (tensors, on the CPU)."""
        state: dict[str, Any] = {name: getattr(self, name).cpu() for name in self._STATE}
        return {**state, "shape": list(self.shape), "generator": self.generator.get_state()}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        self._set_shape(tuple(state["shape"]))
        for name in self._STATE:
            setattr(self, name, state[name].to(self.device))
        self.generator.set_state(state["generator"])

    def cells(self) -> torch.Tensor:
        """Each agent's (row, column) in its walled maze (the outer wall is row and column 0)."""
        row, column = self.position // self.width, self.position % self.width
        return torch.stack([row, column], dim=1) - (_MARGIN - 1)

    def _restart(self, rows: torch.Tensor) -> None:
        self.position[rows] = self.start[rows]
        drawn = torch.randint(0, 4, (len(rows),), generator=self.generator)
        self.direction[rows] = drawn.to(self.device)
        self.steps[rows] = 0

    def observe(self) -> tuple[torch.Tensor, torch.Tensor]:
        seen = self.position[:, None] + self._view_at[self.direction]  # (B, 25)
        wall = self.walls.gather(1, seen)
        goal = seen == self.goal[:, None]
        view = torch.stack([wall, goal], dim=1).to(torch.uint8).reshape(self.count, 2, VIEW, VIEW)
        return view, self.direction.clone()

    def reset(self) -> tuple[torch.Tensor, torch.Tensor]:
        self._restart(torch.arange(self.count, device=self.device))
        return self.observe()

    def step(self, actions: torch.Tensor) -> tuple[tuple[torch.Tensor, torch.Tensor], torch.Tensor, torch.Tensor, torch.Tensor]:
        """``(observation after the step or the restart, reward, reached the goal, cut off at the horizon)``."""
        with one_torch_thread():  # a dozen small operations: torch's extra threads cost more than they give
            actions = actions.to(self.device)
            turn = (actions == RIGHT).long() - (actions == LEFT).long()
            self.direction = (self.direction + turn) % 4
            ahead = self.position + self._step_by[self.direction]
            moves = (actions == FORWARD) & ~self.walls.gather(1, ahead[:, None])[:, 0]
            self.position = torch.where(moves, ahead, self.position)
            self.steps += 1
            reached = self.position == self.goal
            cut = (self.steps >= self.horizon) & ~reached
            reward = reached * (1.0 - 0.9 * self.steps / self.horizon)
            done = reached | cut
            #: the observation each maze reached, before the ones that ended restarted
            self.final = self.observe()
            if bool(done.any()):
                self._restart(done.nonzero().flatten())
                return self.observe(), reward, reached, cut
            return self.final, reward, reached, cut


#: Wall cells around each walled maze in :class:`TorchMazes`: the outer wall and 4 more, the view's reach.
_MARGIN = 5


def _view_offsets(width: int) -> torch.Tensor:
    """``offsets[direction]``: the flat offset of each view square (row-major, farthest row first, the agent at the
    middle of the last row) from the agent, in a maze ``width`` cells wide."""
    table = np.zeros((4, VIEW * VIEW), dtype=np.int64)
    for facing in range(4):
        (fr, fc), (rr, rc) = _STEPS[facing], _STEPS[(facing + 1) % 4]
        for row in range(VIEW):
            for column in range(VIEW):
                ahead, side = VIEW - 1 - row, column - VIEW // 2
                table[facing, row * VIEW + column] = (ahead * fr + side * rr) * width + ahead * fc + side * rc
    return torch.as_tensor(table)


def _spaces() -> spaces.Dict:
    return spaces.Dict({"view": spaces.Box(0, 1, shape=(2, VIEW, VIEW), dtype=np.uint8), "direction": spaces.Discrete(4)})


class MazeEnv(gymnasium.Env):
    """One maze at a time: the next of ``mazes`` at every reset, or a random ``kind`` maze of ``size`` when none
    are given."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 8}

    def __init__(
        self, mazes: list[np.ndarray] | None = None, *, size: int = 16, kind: str = "scattered", render_mode: str | None = None
    ) -> None:
        self.mazes = [np.asarray(m) for m in mazes] if mazes else None
        _check_kind_and_size(kind, size)
        self.size, self.kind = size, kind
        self.observation_space = _spaces()
        self.action_space = spaces.Discrete(4)
        self.render_mode = render_mode
        self._next = 0
        self._batch: TorchMazes | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, Any], dict]:
        super().reset(seed=seed)
        if self.mazes:
            maze = self.mazes[self._next % len(self.mazes)]
            self._next += 1
        else:
            maze = random_maze(self.np_random, self.size, self.kind)
        self._batch = TorchMazes([maze], seed=int(self.np_random.integers(2**31)))
        return self._observation(self._batch.observe()), {"maze": maze.copy()}

    @staticmethod
    def _observation(observed: tuple[torch.Tensor, torch.Tensor]) -> dict[str, Any]:
        view, direction = observed
        return {"view": view[0].numpy(), "direction": int(direction[0])}

    def step(self, action: int) -> tuple[dict[str, Any], float, bool, bool, dict]:
        if self._batch is None:
            raise RuntimeError("call reset() before step()")
        _, reward, reached, cut = self._batch.step(torch.tensor([int(action)]))
        return self._observation(self._batch.final), float(reward[0]), bool(reached[0]), bool(cut[0]), {}

    def render(self) -> np.ndarray | None:
        if self._batch is None:
            return None
        batch = self._batch
        inner = slice(_MARGIN - 1, -(_MARGIN - 1))
        walls = batch.walls[0].reshape(-1, batch.width)[inner, inner].numpy()
        image = np.where(walls[..., None], 40, 235).astype(np.uint8).repeat(3, axis=2)
        goal = divmod(int(batch.goal[0]), batch.width)
        image[goal[0] - _MARGIN + 1, goal[1] - _MARGIN + 1] = (60, 180, 75)
        here = batch.cells()[0].tolist()
        image[here[0], here[1]] = (230, 25, 75)
        return image.repeat(8, axis=0).repeat(8, axis=1)


class MazeVectorEnv(VectorEnv):
    """``num_envs`` mazes in one :class:`TorchMazes`; env ``i`` plays ``mazes[i % len(mazes)]`` (random mazes from
    ``seed`` when none are given), restarting in the step where an episode ends."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        num_envs: int = 8,
        mazes: list[np.ndarray] | None = None,
        *,
        size: int = 16,
        kind: str = "scattered",
        seed: int = 0,
        device: str = "cpu",
    ) -> None:
        if mazes:
            chosen = [mazes[i % len(mazes)] for i in range(num_envs)]
        else:
            rng = np.random.default_rng(seed)
            chosen = [random_maze(rng, size, kind) for _ in range(num_envs)]
        self.num_envs = num_envs
        self.mazes = TorchMazes(chosen, device=device, seed=seed)
        self.single_observation_space = _spaces()
        self.single_action_space = spaces.Discrete(4)
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)

    @staticmethod
    def _numpy(observed: tuple[torch.Tensor, torch.Tensor]) -> dict[str, np.ndarray]:
        view, direction = observed
        return {"view": view.cpu().numpy(), "direction": direction.cpu().numpy()}

    def reset(self, *, seed: int | list[int] | None = None, options: dict | None = None) -> tuple[dict, dict]:
        return self._numpy(self.mazes.reset()), {}

    def step(self, actions: np.ndarray) -> tuple[dict, np.ndarray, np.ndarray, np.ndarray, dict]:
        observed, reward, reached, cut = self.mazes.step(torch.as_tensor(np.asarray(actions), dtype=torch.int64))
        info: dict[str, Any] = {}
        done = (reached | cut).cpu().numpy()
        if done.any():
            info["final_obs"] = self._numpy(self.mazes.final)
            info["_final_obs"] = done
        return self._numpy(observed), reward.cpu().numpy(), reached.cpu().numpy(), cut.cpu().numpy(), info


if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        ENV_ID,
        entry_point="structgen.domains.layouts.maze.env:MazeEnv",
        vector_entry_point="structgen.domains.layouts.maze.env:MazeVectorEnv",
        max_episode_steps=None,
    )
