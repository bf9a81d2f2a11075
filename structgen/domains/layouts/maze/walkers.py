"""Mazes: where an episode starts and ends, and agents that try to walk it without any downloaded weights.

Start and goal are the two ends of the maze's longest shortest path, chosen as the original does: all-pairs
distances over floor cells of the grown maze (without the outer wall), unreachable pairs ignored, the first maximum
in row-major order of (from, to). A maze is solvable when that distance is at least 1.

Agents see a 5x5 window in front of them (they stand at the middle of its bottom row; walls do not hide what lies
behind them) and act as MiniGrid agents do: turn left, turn right or step forward, one step each. An episode ends at
the goal or after ``max_steps`` (the paper's ``2 * (n + 2)**2``, 648 for 16x16). Agents:

- ``oracle``: follows a shortest path, knowing the whole maze (an upper bound);
- ``wall_follower``: keeps its right hand on the wall (``epsilon`` of its actions random);
- ``explorer``: remembers what it has seen and walks to the nearest unseen frontier, or to the goal once seen;
- ``random_walk``: walks at random until the goal comes into view, then goes to it.

New agents subclass :class:`MazeAgent` and are added to :data:`AGENTS`.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from structgen.errors import InputError

__all__ = ["AGENTS", "EpisodeStats", "MazeAgent", "diameter", "run_episodes"]

#: Kinds of random maze (:func:`.env.random_maze`); kept here, away from torch, for the command line.
MAZE_KINDS = ("scattered", "carved", "rooms", "perfect")

# Directions in (row, column) steps, clockwise from north; facing index 0..3.
_STEPS = ((-1, 0), (0, 1), (1, 0), (0, -1))
LEFT, RIGHT, FORWARD = 0, 1, 2


def _floor_graph(floor: np.ndarray):
    from scipy.sparse import csr_matrix  # loaded on first use: the command line lists the agents without it

    rows, cols = floor.shape
    index = np.arange(rows * cols).reshape(rows, cols)
    right = floor[:, :-1] & floor[:, 1:]
    down = floor[:-1, :] & floor[1:, :]
    a = np.concatenate([index[:, :-1][right], index[:-1, :][down]])
    b = np.concatenate([index[:, 1:][right], index[1:, :][down]])
    n = rows * cols
    return csr_matrix((np.ones(2 * len(a)), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(n, n))


#: The most floor cells :func:`diameter` takes: it searches from every floor cell (time grows with their square).
MAX_DIAMETER_FLOOR = 20_000
# Searches run a block of starting cells at a time, so memory stays at about this many distances.
_DISTANCES_AT_ONCE = 1 << 24


def diameter(maze: np.ndarray) -> tuple[tuple[int, int], tuple[int, int], int] | None:
    """(start, goal, distance) of the longest shortest path between floor cells (tile 0) of a grown maze, or None if
    no two floor cells are connected. Of equally long paths, the one whose start, then goal, comes first in row order.
    Searched from every floor cell, a block at a time: memory stays small; a maze of more than
    :data:`MAX_DIAMETER_FLOOR` floor cells is refused."""
    from scipy.sparse import csgraph

    floor = np.asarray(maze) == 0
    starts = np.flatnonzero(floor.ravel())
    if len(starts) > MAX_DIAMETER_FLOOR:
        raise InputError(
            f"a maze of {len(starts):,} floor cells: its longest shortest path searches from every one of them, and "
            f"more than {MAX_DIAMETER_FLOOR:,} would take hours"
        )
    graph = _floor_graph(floor)
    block = max(1, _DISTANCES_AT_ONCE // max(floor.size, 1))
    best, first, second = 0.0, -1, -1
    for at in range(0, len(starts), block):
        rows = starts[at : at + block]
        dist = csgraph.shortest_path(graph, method="D", unweighted=True, indices=rows)
        dist[~np.isfinite(dist)] = -np.inf
        row, column = np.unravel_index(int(dist.argmax()), dist.shape)
        if dist[row, column] > best:  # strictly: the first of equals in row order is kept, as over the whole table
            best, first, second = float(dist[row, column]), int(rows[row]), int(column)
    if best < 1:
        return None
    shape = floor.shape
    start = tuple(int(i) for i in np.unravel_index(first, shape))
    goal = tuple(int(i) for i in np.unravel_index(second, shape))
    return start, goal, int(best)


@dataclass
class _State:
    position: tuple[int, int]
    facing: int


class MazeAgent:
    """An agent: :meth:`reset` at the start of an episode, then :meth:`act` once per step with what it sees."""

    name = "agent"

    def reset(self, walls: np.ndarray, goal: tuple[int, int], rng: np.random.Generator) -> None:
        """``walls`` is the whole maze (with its outer wall); only the oracle may look at it beyond its view."""
        self.rng = rng

    def act(self, state: _State, view: dict[tuple[int, int], bool], goal_seen: tuple[int, int] | None) -> int:
        """One of LEFT, RIGHT, FORWARD. ``view`` maps visible cells (absolute positions) to whether they are walls;
        ``goal_seen`` is the goal's position once it is in view."""
        raise NotImplementedError


def _turn_towards(state: _State, target: tuple[int, int]) -> int:
    dr, dc = target[0] - state.position[0], target[1] - state.position[1]
    wanted = _STEPS.index((dr, dc))
    if wanted == state.facing:
        return FORWARD
    return RIGHT if (wanted - state.facing) % 4 in (1, 2) else LEFT


def _next_step(start: tuple[int, int], goals: set, passable) -> tuple[int, int] | None:
    """The first cell of a shortest path from ``start`` to any of ``goals`` through ``passable`` cells."""
    previous = {start: start}
    queue = deque([start])
    while queue:
        cell = queue.popleft()
        if cell in goals and cell != start:
            while previous[cell] != start:
                cell = previous[cell]
            return cell
        for dr, dc in _STEPS:
            nxt = (cell[0] + dr, cell[1] + dc)
            if nxt not in previous and passable(nxt):
                previous[nxt] = cell
                queue.append(nxt)
    return None


class Oracle(MazeAgent):
    name = "oracle"

    def reset(self, walls, goal, rng):
        super().reset(walls, goal, rng)
        self.walls, self.goal = walls, goal

    def act(self, state, view, goal_seen):
        step = _next_step(state.position, {self.goal}, lambda c: not self.walls[c])
        return FORWARD if step is None else _turn_towards(state, step)


class WallFollower(MazeAgent):
    """Right-hand rule. Walk straight until blocked, then keep a wall on the right: turn right (and step) where that
    wall ends, else go ahead, else turn left. Turning right only where a followed wall ends keeps it from circling
    a patch of open floor; like any wall follower it can circle a free-standing block of wall forever (``epsilon``,
    the chance of a random action, breaks such loops)."""

    name = "wall_follower"

    def __init__(self, epsilon: float = 0.0) -> None:
        self.epsilon = epsilon

    def reset(self, walls, goal, rng):
        super().reset(walls, goal, rng)
        self.following = False  # a wall is on the right
        self.just_turned_right = False

    def act(self, state, view, goal_seen):
        if self.epsilon and self.rng.random() < self.epsilon:
            return int(self.rng.integers(3))
        r, c = state.position
        right = (state.facing + 1) % 4
        ahead = (r + _STEPS[state.facing][0], c + _STEPS[state.facing][1])
        right_cell = (r + _STEPS[right][0], c + _STEPS[right][1])
        ahead_open = not view.get(ahead, True)
        if self.just_turned_right:  # step through the opening just turned into
            self.just_turned_right = False
            return FORWARD if ahead_open else LEFT
        if view.get(right_cell, True):
            self.following = True
        elif self.following:  # the wall on the right ends here: go round its end
            self.just_turned_right = True
            return RIGHT
        if ahead_open:
            return FORWARD
        self.following = True  # blocked ahead: turning left puts this wall on the right
        return LEFT


class Explorer(MazeAgent):
    name = "explorer"

    def reset(self, walls, goal, rng):
        super().reset(walls, goal, rng)
        self.known: dict[tuple[int, int], bool] = {}
        self.frontier: set[tuple[int, int]] = set()  # known floor with an unknown neighbour
        self.goal: tuple[int, int] | None = None

    def act(self, state, view, goal_seen):
        # The goal stays known once seen: turning towards it can take it out of view, and an explorer that forgot
        # it there turned back to the frontier, saw it again and turned away, left and right for ever.
        self.goal = goal_seen or self.goal
        new = [cell for cell in view if cell not in self.known]
        self.known.update(view)
        # Only the cells just seen and their neighbours can join or leave the frontier: updating it here instead of
        # rescanning everything known keeps a step cheap on large mazes.
        touched = set(new)
        touched.update((r + dr, c + dc) for r, c in new for dr, dc in _STEPS)
        for cell in touched:
            if self.known.get(cell) is False and any((cell[0] + dr, cell[1] + dc) not in self.known for dr, dc in _STEPS):
                self.frontier.add(cell)
            else:
                self.frontier.discard(cell)
        passable = lambda cell: self.known.get(cell) is False  # noqa: E731
        if self.goal is not None:
            step = _next_step(state.position, {self.goal}, passable)
            if step is not None:
                return _turn_towards(state, step)
        step = _next_step(state.position, self.frontier, passable)
        if step is None:
            return LEFT  # nothing left to explore in reach: look around
        return _turn_towards(state, step)


class RandomWalk(MazeAgent):
    name = "random_walk"

    def reset(self, walls, goal, rng):
        super().reset(walls, goal, rng)
        self.known: dict[tuple[int, int], bool] = {}
        self.goal: tuple[int, int] | None = None

    def act(self, state, view, goal_seen):
        self.known.update(view)
        self.goal = goal_seen or self.goal  # remembered, as the explorer does
        if self.goal is not None:
            step = _next_step(state.position, {self.goal}, lambda cell: self.known.get(cell) is False)
            if step is not None:
                return _turn_towards(state, step)
        return int(self.rng.choice([LEFT, RIGHT, FORWARD, FORWARD]))


AGENTS: dict[str, type[MazeAgent]] = {a.name: a for a in (Oracle, WallFollower, Explorer, RandomWalk)}


def _view(walls: np.ndarray, state: _State) -> dict[tuple[int, int], bool]:
    """The 5x5 window in front of the agent, the agent at the middle of its bottom row."""
    fr, fc = _STEPS[state.facing]
    rr, rc = _STEPS[(state.facing + 1) % 4]
    seen = {}
    rows, cols = walls.shape
    for forward in range(5):
        for side in range(-2, 3):
            cell = (state.position[0] + forward * fr + side * rr, state.position[1] + forward * fc + side * rc)
            if 0 <= cell[0] < rows and 0 <= cell[1] < cols:
                seen[cell] = bool(walls[cell])
    return seen


@dataclass(frozen=True)
class EpisodeStats:
    """Results over a maze's episodes: success rate, mean steps taken (all episodes, the failures at the limit),
    mean steps of the successful ones, and the shortest path's length."""

    success_rate: float
    mean_steps: float
    mean_success_steps: float
    shortest_path: int
    episodes: int


def run_episodes(
    grown: np.ndarray,
    agent: MazeAgent | str = "explorer",
    *,
    episodes: int = 50,
    max_steps: int | None = None,
    seed: int = 0,
) -> EpisodeStats:
    """Run ``episodes`` episodes of ``agent`` on a grown maze (tile 1 walls, without the outer wall)."""
    agent = AGENTS[agent]() if isinstance(agent, str) else agent
    grown = np.asarray(grown)
    ends = diameter(grown)
    limit = max_steps if max_steps is not None else 2 * (grown.shape[0] + 2) * (grown.shape[1] + 2)
    if ends is None:
        return EpisodeStats(0.0, float(limit), 0.0, -1, episodes)
    walls = np.pad(grown == 1, 1, constant_values=True)
    start, goal = (ends[0][0] + 1, ends[0][1] + 1), (ends[1][0] + 1, ends[1][1] + 1)
    steps_taken, successes = [], []
    for episode in range(episodes):
        rng = np.random.default_rng([seed, episode])
        agent.reset(walls, goal, rng)
        state = _State(start, int(rng.integers(4)))
        reached, steps = False, 0
        while steps < limit:
            view = _view(walls, state)
            action = agent.act(state, view, goal if goal in view else None)
            steps += 1
            if action == LEFT:
                state.facing = (state.facing - 1) % 4
            elif action == RIGHT:
                state.facing = (state.facing + 1) % 4
            else:
                ahead = (state.position[0] + _STEPS[state.facing][0], state.position[1] + _STEPS[state.facing][1])
                if not walls[ahead]:
                    state.position = ahead
            if state.position == goal:
                reached = True
                break
        steps_taken.append(steps)
        successes.append(reached)
    wins = [s for s, ok in zip(steps_taken, successes) if ok]
    return EpisodeStats(
        success_rate=float(np.mean(successes)),
        mean_steps=float(np.mean(steps_taken)),
        mean_success_steps=float(np.mean(wins)) if wins else 0.0,
        shortest_path=ends[2],
        episodes=episodes,
    )
