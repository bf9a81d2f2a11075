"""The warehouse paper's maze experiment: does an agent trained on small mazes solve large mazes grown by a
generator trained small, more often than random large mazes of the same difficulty?

An NCA generator trained at 16 x 16 (18 x 18 with the outer wall) grows a maze at that size and at 64 x 64
(66 x 66); the agent plays each ``episodes`` times. Baselines are made as the original's script makes them: the same
number of walls placed uniformly at random, drawn again until the longest shortest path lies within ``band`` (80-120
%) of the large grown maze's; each is played ``baseline_episodes`` times. The paper reports 90 %, 93 % and 22 %
(standard error 3 %) for its ACCEL agent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from structgen.domains.layouts.maze.agent import MazePolicy, run_agent
from structgen.domains.layouts.maze.walkers import diameter

__all__ = ["PAPER", "ExperimentRow", "baseline_mazes", "maze_experiment"]

#: The paper's success rates (and the baselines' standard error) for its ACCEL agent.
PAPER = {"grown small": (0.90, None), "grown large": (0.93, None), "baselines": (0.22, 0.03)}


@dataclass(frozen=True)
class ExperimentRow:
    """One line of the table: what was played, on how many mazes, how often, the success rate and its standard
    error (over episodes for one maze, over mazes for many), the longest shortest path (mean over mazes) and the
    walls."""

    name: str
    size: str
    mazes: int
    episodes: int
    success_rate: float
    standard_error: float
    path_length: float
    walls: float


def baseline_mazes(
    reference: np.ndarray,
    count: int,
    rng: np.random.Generator,
    band: tuple[float, float] = (0.8, 1.2),
    tries: int | None = None,
    progress: bool = False,
    reference_length: int | None = None,
) -> tuple[list[np.ndarray], list[int], int]:
    """``count`` mazes the shape of ``reference`` with as many walls, placed uniformly at random and drawn again until
    the longest shortest path lies within ``band`` times the reference's; returns them, their longest shortest paths
    and the number drawn. Gives
    up after ``tries`` draws (default 20 per maze: a 66x66 draw takes about 0.1 s, and for the paper's maze one in
    five lands in the band). ``reference_length``: the reference's longest shortest path, when the caller has found
    it already (at 66x66 finding it costs as much as a draw)."""
    from tqdm import tqdm

    tries = 20 * count if tries is None else tries
    if reference_length is None:
        found = diameter(reference)
        if found is None:
            raise ValueError("the reference maze has no path, so no baseline can match its length")
        reference_length = found[2]
    low, high = band[0] * reference_length, band[1] * reference_length
    walls = int((reference == 1).sum())
    kept: list[np.ndarray] = []
    lengths: list[int] = []
    bar = tqdm(total=count, desc="baseline mazes", unit="maze", disable=not progress, leave=False)
    for drawn in range(1, tries + 1):
        maze = np.zeros(reference.size, dtype=np.uint8)
        maze[rng.choice(reference.size, walls, replace=False)] = 1
        maze = maze.reshape(reference.shape)
        ends = diameter(maze)
        if ends is not None and low <= ends[2] <= high:
            kept.append(maze)
            lengths.append(ends[2])
            bar.update(1)
            if len(kept) == count:
                bar.close()
                return kept, lengths, drawn
    bar.close()
    raise ValueError(
        f"only {len(kept)} of {count} baseline mazes in {tries:,} draws: random mazes with {walls} walls seldom have a "
        f"longest path of {low:.0f}-{high:.0f} cells (the grown maze's is {reference_length}); choose another generator (--elite)"
    )


def _row(
    name: str, policy: MazePolicy, mazes: list[np.ndarray], lengths: list[int], episodes: int, seed: int, device: str
) -> ExperimentRow:
    """``lengths``: the mazes' longest shortest paths, known already (finding them is the slow part at 66x66)."""
    results = run_agent(policy, mazes, episodes=episodes, seed=seed, device=device)
    return ExperimentRow(
        name,
        f"{mazes[0].shape[0] + 2}x{mazes[0].shape[1] + 2}",
        len(mazes),
        episodes,
        results.success_rate,
        results.standard_error,
        float(np.mean(lengths)),
        float(np.mean([(m == 1).sum() for m in mazes])),
    )


def maze_experiment(
    policy: MazePolicy,
    small: np.ndarray,
    large: np.ndarray,
    *,
    episodes: int = 100,
    baselines: int = 100,
    baseline_episodes: int = 10,
    seed: int = 0,
    device: str = "cpu",
    progress: bool = False,
) -> tuple[list[ExperimentRow], list[np.ndarray]]:
    """The table's three rows for a small and a large grown maze (without their outer walls), and the baselines."""
    rng = np.random.default_rng([seed, 2])
    grown = [(small, diameter(small)), (large, diameter(large))]
    known = None if grown[1][1] is None else grown[1][1][2]  # with no path, baseline_mazes says so
    made, lengths, _ = baseline_mazes(large, baselines, rng, progress=progress, reference_length=known)
    if any(ends is None for _, ends in grown):
        raise ValueError("a grown maze has no path between two floor cells, so there is nothing to run")
    rows = [
        _row(name, policy, [maze], [ends[2]], episodes, seed, device)  # type: ignore[index]
        for name, (maze, ends) in zip(("grown small", "grown large"), grown)
    ]
    rows.append(_row("baselines", policy, made, lengths, baseline_episodes, seed, device))
    return rows, made
