"""Pictures of a fortress: its map as text (as the original prints it) and as an image, a simulation as an animated
GIF or a strip of frames, and the population of each class over time."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from evolution.files import atomic_write
from evolution.plots import figure_png, new_figure
from structgen.domains.fortress.engine import HEIGHT, WIDTH, Trace, placements
from structgen.domains.fortress.formats import FortressFile

__all__ = ["draw_world", "map_image", "map_text", "population_figure", "population_panel", "trace_gif", "trace_strip"]

_SCALE = 24


def map_text(entities: Sequence[tuple], width: int = WIDTH, height: int = HEIGHT) -> str:
    """The map as the original renders it: walls ``#``, floor ``.``, on a tile with several entities the one created
    first."""
    rows = [["#" if x in (0, width - 1) or y in (0, height - 1) else "." for x in range(width)] for y in range(height)]
    for char, x, y, *_ in reversed(list(entities)):
        if 0 <= x < width and 0 <= y < height:
            rows[y][x] = char
    return "\n".join("".join(row) for row in rows)


def _colours(chars: Sequence[str]) -> dict[str, tuple[int, int, int]]:
    from matplotlib import colormaps

    palette = colormaps["tab20"]
    return {c: tuple(int(255 * v) for v in palette(i % 20)[:3]) for i, c in enumerate(chars)}


def map_image(entities: Sequence[tuple], chars: Sequence[str], scale: int = _SCALE) -> np.ndarray:
    """``(HEIGHT*scale, WIDTH*scale, 3)`` uint8: walls dark, floor light, each tile with entities in the colour of
    the first created there, its class character written on it, and a count when several share it."""
    from PIL import Image, ImageDraw, ImageFont

    colours = _colours(chars)
    image = Image.new("RGB", (WIDTH * scale, HEIGHT * scale), (235, 232, 225))
    draw = ImageDraw.Draw(image)
    # The class characters must read at the size a strip of frames shows them: most of the tile's height.
    glyph, count = ImageFont.load_default(size=max(8, int(scale * 0.62))), ImageFont.load_default(size=max(6, scale // 3))
    for x in range(WIDTH):
        for y in range(HEIGHT):
            if x in (0, WIDTH - 1) or y in (0, HEIGHT - 1):
                draw.rectangle([x * scale, y * scale, (x + 1) * scale - 1, (y + 1) * scale - 1], fill=(60, 60, 70))
    on_tile: dict[tuple[int, int], list[str]] = {}
    for char, x, y, *_ in entities:
        on_tile.setdefault((x, y), []).append(char)
    for (x, y), found in on_tile.items():
        box = [x * scale + 1, y * scale + 1, (x + 1) * scale - 2, (y + 1) * scale - 2]
        draw.rectangle(box, fill=colours.get(found[0], (128, 128, 128)))
        draw.text(((x + 0.5) * scale, (y + 0.5) * scale), found[0], fill=(0, 0, 0), font=glyph, anchor="mm")
        if len(found) > 1:  # several entities on one tile: how many, in the corner
            draw.text(((x + 1) * scale - 3, (y + 1) * scale - 2), str(len(found)), fill=(255, 255, 255), font=count, anchor="rd")
    return np.asarray(image)


def trace_gif(trace: Trace, chars: Sequence[str], path: str | Path, *, frame_ms: int = 120) -> Path:
    """An animated GIF of a simulation, one frame a tick (written atomically)."""
    import io

    from PIL import Image

    frames = [Image.fromarray(map_image(entities, chars)) for entities in trace.entities]
    buffer = io.BytesIO()
    frames[0].save(buffer, format="GIF", save_all=True, append_images=frames[1:], duration=frame_ms, loop=0)
    return atomic_write(path, buffer.getvalue())


def trace_strip(trace: Trace, chars: Sequence[str], path: str | Path, *, frames: int = 6) -> Path:
    """A PNG of ``frames`` evenly spaced ticks side by side, each labelled with its tick."""
    ticks = np.unique(np.linspace(0, len(trace.entities) - 1, frames).round().astype(int))
    columns = min(3, len(ticks))
    rows = -(-len(ticks) // columns)
    figure = new_figure(figsize=(4.6 * columns, 2.7 * rows))
    for i, t in enumerate(ticks):
        axes = figure.add_subplot(rows, columns, i + 1)
        axes.imshow(map_image(trace.entities[t], chars))
        axes.set_title(f"tick {t}: {len(trace.entities[t])} entities", fontsize=10)
        axes.axis("off")
    figure.tight_layout()
    return atomic_write(path, figure_png(figure))


def population_panel(axes: Any, trace: Trace, chars: Sequence[str], title: str) -> None:
    """How many entities of each class there were after each tick, on ``axes`` (classes that never appear are left
    out), with the total dashed and a legend beside it."""
    counts = trace.populations(chars)
    colours = _colours(chars)
    for k, c in enumerate(chars):
        if counts[:, k].any():
            axes.plot(counts[:, k], label=c, color=np.array(colours[c]) / 255)
    axes.plot(counts.sum(axis=1), label="all", color="black", linestyle="--")
    axes.set_xlabel("tick")
    axes.set_ylabel("entities")
    axes.set_title(title, fontsize=9)
    axes.legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.0, 1.0))


def population_figure(trace: Trace, chars: Sequence[str], title: str = "") -> object:
    """:func:`population_panel` as a figure of its own."""
    figure = new_figure(figsize=(7, 3.6))
    population_panel(figure.add_subplot(1, 1, 1), trace, chars, title or f"population by class (seed {trace.seed})")
    figure.tight_layout()
    return figure


def world_view(world: FortressFile) -> dict[str, Any]:
    """A world as a report shows it (:mod:`structgen.runs.report`): its initial map, a cell a square (walls dark,
    floor light, a tile with entities in the colour of the first created there), and each class's machine size."""
    from structgen.runs.report import image_figure

    entities = placements(world.initial)
    colours = {"#": (60, 60, 60), ".": (235, 232, 225), **_colours(list(world.classes))}
    rows = map_text(entities).splitlines()
    picture = np.array([[colours[c] for c in row] for row in rows], dtype=np.uint8)
    fields = {"entities": len(entities), **{f"class {c}: nodes": len(e.nodes) for c, e in world.classes.items()}}
    labels = [[{"#": "wall", ".": "floor"}.get(c, f"class {c}") for c in row] for row in rows]
    return {"figure": image_figure(picture, f"initial map: {len(entities)} entities", labels), "fields": fields}


def draw_world(world: FortressFile, path: str | Path) -> Path:
    """A PNG of a world's initial map and the size of each class's machine."""
    entities = placements(world.initial)
    chars = list(world.classes)
    figure = new_figure(figsize=(9, 3.2))
    axes = figure.add_subplot(1, 2, 1)
    axes.imshow(map_image(entities, chars))
    axes.set_title(f"initial map: {len(entities)} entities", fontsize=9)
    axes.axis("off")
    bars = figure.add_subplot(1, 2, 2)
    nodes = [len(e.nodes) for e in world.classes.values()]
    bars.bar(chars, nodes, color="#4c72b0", label="nodes")
    bars.bar(chars, [len(e.edges) for e in world.classes.values()], bottom=nodes, color="#f2a65a", label="edges")
    bars.set_title("machine size per class: nodes, and edges stacked on them", fontsize=9)
    bars.set_xlabel("class")
    bars.set_ylabel("nodes + edges")
    bars.legend(fontsize=7)
    figure.tight_layout()
    return atomic_write(path, figure_png(figure))
