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
    blank = cells.sum(axis=0) == 0  # a cell that asks for the player alone shows it
    image[np.kron(blank, np.ones((scale, scale), dtype=bool))] = 110
    return image


def draw_game(
    game: dict[str, Any],
    path: str | Path,
    actions: np.ndarray | None = None,
    tile_names: tuple[str, str, str] | None = None,
    **engine: Any,
) -> Path:
    """A PNG of the game, written atomically: its initial map, and each rule (rotation 0) as the 3x3 pattern it
    matches and what the matched cells become, with its reward. With ``actions`` (a playtrace), also the map at the end
    of the play and the return along it. ``tile_names`` names tiles 2-4 in the legend (a hand-written game's)."""
    from evolution.files import atomic_write
    from evolution.plots import figure_png, new_figure

    rules, rewards = np.asarray(game["rules"]), np.asarray(game["rewards"])
    played = actions is not None and len(np.asarray(actions).reshape(-1)) > 0
    figure = new_figure(figsize=(11 if played else 8, 7.2 if played else 5.0))
    rows = len(rules) + (3 if played else 0)
    columns = [3, 1, 1, 3] if played else [3, 1, 1]
    grid = figure.add_gridspec(rows, len(columns), width_ratios=columns, hspace=0.6, wspace=0.15)
    axis = figure.add_subplot(grid[: len(rules), 0])
    axis.imshow(map_image(game["map"], rot=0))
    axis.set_title("initial map (the dot: the way the player faces)", fontsize=9)
    axis.axis("off")
    for index, rule in enumerate(rules):
        before = figure.add_subplot(grid[index, 1])
        after = figure.add_subplot(grid[index, 2])
        before.imshow(_pattern_image(rule[0, 0]))
        after.imshow(_pattern_image(np.clip(rule[0, 0] + rule[0, 1], 0, 1)))  # what the matched cells hold after
        before.set_ylabel(f"{'ABCDE'[index]}: {int(rewards[index]):+d}", rotation=0, ha="right", va="center", fontsize=8)
        for part in (before, after):
            part.set_xticks([])
            part.set_yticks([])
        if index == 0:
            before.set_title("matches", fontsize=8)
            after.set_title("becomes", fontsize=8)
    if played:
        maps, returns, rots = replay(game, actions, **engine)
        axis = figure.add_subplot(grid[: len(rules), 3])
        axis.imshow(map_image(maps[-1], rot=rots[-1]))
        axis.set_title(f"after the {len(returns) - 1} actions of the play", fontsize=9)
        axis.axis("off")
        axis = figure.add_subplot(grid[len(rules) + 1 :, :])
        axis.plot(np.arange(len(returns)), returns, color="#3060a0")
        axis.set_xlabel("step of the play")
        axis.set_ylabel("return so far")
        axis.set_title(f"return along the play: {returns[-1]:g}", fontsize=9)
    shown = (TILE_NAMES[1], *(tile_names or TILE_NAMES[2:N_TILES]))
    names = ", ".join(f"{name} {colour}" for name, colour in zip(shown, ("red", "green", "blue", "yellow")))
    figure.suptitle(
        f"tiles: {names}; a cell holding several shows their mean colour, an empty one is black; white: the player.\n"
        "Rules (letter: reward a match) match a 3x3 pattern (grey: any tile) and rewrite it, in all four rotations.",
        fontsize=9,
    )
    return atomic_write(Path(path), figure_png(figure, 100))


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
