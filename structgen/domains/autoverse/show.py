"""Pictures of a game: its map and its rules as before/after patterns (PNG), and a playtrace as an animation (GIF)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from structgen.domains.autoverse.game import N_TILES, PLAYER, TILE_NAMES

__all__ = ["draw_game", "map_image", "playtrace_gif", "replay"]

# Colours of force, a, b, c; a cell holding several tiles shows their mean, an empty cell is dark.
_COLOURS = np.array([[0, 0, 0], [220, 60, 50], [70, 170, 90], [60, 110, 210], [235, 200, 60]], dtype=np.float64)
_EMPTY = np.array([30, 30, 30], dtype=np.float64)


def map_image(game_map: np.ndarray, scale: int = 16, rot: int | None = None) -> np.ndarray:
    """``(5, N, N)`` multi-hot -> ``(N*scale, N*scale, 3)`` uint8 RGB; the player is a white square with a dot on
    the side it faces (``rot``)."""
    game_map = np.asarray(game_map)
    tiles = game_map[1:].astype(np.float64)  # (4, N, N)
    count = tiles.sum(axis=0)
    mean = np.einsum("tij,tc->ijc", tiles, _COLOURS[1:]) / np.maximum(count, 1)[..., None]
    rgb = np.where(count[..., None] > 0, mean, _EMPTY)
    image = np.kron(rgb, np.ones((scale, scale, 1))).astype(np.uint8)
    from structgen.domains.autoverse.engine import DIRECTIONS

    for r, c in np.argwhere(game_map[PLAYER] == 1):
        lo, hi = scale // 4, scale - scale // 4
        image[r * scale + lo : r * scale + hi, c * scale + lo : c * scale + hi] = 255
        if rot is not None:
            dy, dx = DIRECTIONS[rot]
            cy, cx = r * scale + scale // 2 + dy * scale // 3, c * scale + scale // 2 + dx * scale // 3
            image[cy - 1 : cy + 2, cx - 1 : cx + 2] = 0
    return image


def _pattern_image(kernel: np.ndarray, scale: int = 16) -> np.ndarray:
    """One side of a rule (``(5, 3, 3)``, positive entries drawn) as a 3x3 picture; unconstrained cells grey."""
    cells = (kernel > 0).astype(np.uint8)
    image = map_image(cells, scale)
    blank = cells[1:].sum(axis=0) == 0
    image[np.kron(blank, np.ones((scale, scale), dtype=bool))] = 110
    return image


def draw_game(game: dict[str, Any], path: str | Path, actions: np.ndarray | None = None, **engine: Any) -> Path:
    """A PNG of the game: its initial map, and each rule (rotation 0) as input -> output with its reward. With
    ``actions``, also the map at the end of the playtrace and the return along it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rules, rewards = np.asarray(game["rules"]), np.asarray(game["rewards"])
    panels = 2 if actions is None else 3
    figure = plt.figure(figsize=(4.2 * panels, 4.6))
    grid = figure.add_gridspec(len(rules), 2 * panels, width_ratios=[3, 1] * panels)
    axis = figure.add_subplot(grid[:, 0])
    axis.imshow(map_image(game["map"], rot=0))
    axis.set_title("initial map")
    axis.axis("off")
    for index, rule in enumerate(rules):
        before = figure.add_subplot(grid[index, 2])
        after = figure.add_subplot(grid[index, 3])
        inputs = rule[0, 0]
        outputs = np.clip(rule[0, 0] + rule[0, 1], 0, 1)  # what the matched cells hold afterwards
        before.imshow(_pattern_image(inputs))
        after.imshow(_pattern_image(outputs))
        before.set_title(f"rule {'ABCDE'[index]} (reward {int(rewards[index]):+d})", fontsize=8, loc="left")
        before.axis("off")
        after.axis("off")
    if actions is not None:
        maps, returns, rots = replay(game, actions, **engine)
        axis = figure.add_subplot(grid[: len(rules) // 2 + 1, 4])
        axis.imshow(map_image(maps[-1], rot=rots[-1]))
        axis.set_title(f"after {len(actions)} actions")
        axis.axis("off")
        axis = figure.add_subplot(grid[len(rules) // 2 + 1 :, 4:])
        axis.plot(np.arange(len(returns)), returns)
        axis.set_xlabel("step")
        axis.set_ylabel("return")
    legend = ", ".join(f"{name}" for name in TILE_NAMES[1:N_TILES])
    figure.suptitle(f"tiles: {legend} (red, green, blue, yellow); white: player; grey: any", fontsize=9)
    path = Path(path)
    figure.savefig(path, dpi=100)
    plt.close(figure)
    return path


def replay(game: dict[str, Any], actions: np.ndarray, **engine: Any) -> tuple[list[np.ndarray], list[float], list[int]]:
    """The maps (multi-hot), returns and facings along a playtrace, the initial state first."""
    import torch

    from structgen.domains.autoverse.engine import Engine

    simulator = Engine([game], **engine)
    state = simulator.reset()
    maps, returns, rots = [state.multi_hot()[0].cpu().numpy()], [0.0], [0]
    for action in np.asarray(actions).reshape(-1):
        if action < 0:
            break
        state, reward, _ = simulator.step(state, torch.tensor([int(action)]))
        maps.append(state.multi_hot()[0].cpu().numpy())
        returns.append(returns[-1] + float(reward[0]))
        rots.append(int(state.rot[0]))
    return maps, returns, rots


def playtrace_gif(game: dict[str, Any], actions: np.ndarray, path: str | Path, *, frame_ms: int = 150, **engine: Any) -> Path:
    """An animated GIF of the playtrace, one frame a step."""
    from PIL import Image

    maps, _, rots = replay(game, actions, **engine)
    frames = [Image.fromarray(map_image(m, rot=r)) for m, r in zip(maps, rots)]
    path = Path(path)
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=frame_ms, loop=0)
    return path
