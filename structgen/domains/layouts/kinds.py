"""The three layout kinds of the warehouse paper (warehouse, manufacturing, maze): tiles, sizes, seed blocks and the
fixed parts added around what the NCA grows.

- warehouse: the NCA grows the storage area over tiles ``.@e`` (floor, shelf, endpoint); two fixed columns on each
  side carry the workstations ``w`` (one every third row, none in the first and last rows). Files may also hold ``r``
  (robot start, the original's "r mode") and ``s`` (the repair's flow source).
- manufacturing: the NCA grows the whole map over ``.012e`` (floor, station kinds 0/1/2, endpoint).
- maze: the NCA grows ``" X"`` (floor, wall) inside an outer wall.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from structgen.domains.layouts.grid import Grid
from structgen.reference_data import reference_data

__all__ = ["KINDS", "MANUFACTURING", "MAZE", "REPAIR_TIME_LIMIT", "WAREHOUSE", "LayoutKind", "Size", "reference_maps"]

#: Seconds a repair may take unless told otherwise (the problem's ``repair_time_limit``, ``repair --time-limit``).
REPAIR_TIME_LIMIT = 60.0
#: Environment variable naming the folder of the original's map files (``warehouse/``, ``manufacture/``, ``maze/``).
REFERENCE_MAPS_VARIABLE = "STRUCTGEN_REFERENCE_MAPS"


def reference_maps() -> Path | None:
    """The folder of the original paper's map files, which the tests and ``benchmarks/grid.py`` check against: the
    folder named by ``$STRUCTGEN_REFERENCE_MAPS``, else ``warehouse-maps/`` of the reference data
    (:func:`structgen.reference_data.reference_data`); None where there is none (the maps are research data, not
    part of the package)."""
    named = os.environ.get(REFERENCE_MAPS_VARIABLE)
    if named:
        return Path(named)
    return reference_data("warehouse-maps")


@dataclass(frozen=True)
class Size:
    """One map size: ``grown`` is what the NCA grows (rows, columns); ``shelves`` the exact shelf count the repair
    keeps (warehouse only); ``iterations`` the NCA steps the paper used at this size."""

    grown: tuple[int, int]
    shelves: int = 0
    iterations: int = 50


@dataclass(frozen=True)
class LayoutKind:
    """What a layout kind is made of.

    Attributes:
        name: the kind's name (``warehouse``).
        vocabulary: every tile a map file of this kind may hold; the NCA's tiles come first.
        nca_tiles: how many of the first tiles the NCA grows.
        tile_names: a name for each tile character, for legends and messages.
        colours: a colour for each tile character, for pictures.
        sizes: named sizes; the paper's training size is ``"33x36"`` (``"16x16"`` for mazes).
        seed_block: the tiles (rows of text) placed at the centre of an otherwise empty seed.
        seed_offset: subtracted from the centre (rows, columns) to place the block's top-left corner.
        seed_rows: the original's seed files place the block differently at a few heights; these are its rows there.
        blocking: the tiles that block movement and count as shelves (warehouse ``@``, manufacturing's stations).
    """

    name: str
    vocabulary: str
    nca_tiles: int
    tile_names: dict[str, str]
    colours: dict[str, str]
    sizes: dict[str, Size]
    default_size: str
    seed_block: tuple[str, ...]
    seed_offset: tuple[int, int]
    seed_rows: dict[int, int] = field(default_factory=dict)
    blocking: str = ""

    def size(self, name: str) -> Size:
        """A named size (``"33x36"``), or any ``"RxC"`` of what the NCA grows for sizes the paper did not use."""
        if name in self.sizes:
            return self.sizes[name]
        rows, sep, cols = str(name).partition("x")
        if sep and rows.isdigit() and cols.isdigit():
            grown = (int(rows), int(cols))
            if min(grown) < 4 or grown[0] * grown[1] > 4096 * 4096:
                raise ValueError(f"size {name!r}: rows and columns must be at least 4 and the map at most 4096 x 4096")
            return Size(grown, shelves=0)
        raise ValueError(f"unknown {self.name} size {name!r}: one of {', '.join(self.sizes)}, or ROWSxCOLUMNS")

    def blocking_tiles(self) -> list[int]:
        """The numbers of the :attr:`blocking` tiles."""
        return [self.vocabulary.index(c) for c in self.blocking]

    def seed(self, grown: tuple[int, int]) -> np.ndarray:
        """The seed the NCA starts from: empty floor with the seed block near the centre, as the original's files."""
        rows, cols = grown
        block = np.array([[self.vocabulary.index(c) for c in row] for row in self.seed_block], dtype=np.uint8)
        top = self.seed_rows.get(rows, rows // 2 - self.seed_offset[0])
        left = cols // 2 - self.seed_offset[1]
        seed = np.zeros(grown, dtype=np.uint8)
        if top < 0 or left < 0 or top + block.shape[0] > rows or left + block.shape[1] > cols:
            raise ValueError(f"a {rows} x {cols} {self.name} is too small for its seed block")
        seed[top : top + block.shape[0], left : left + block.shape[1]] = block
        return seed

    def complete(self, grown: np.ndarray) -> np.ndarray:
        """The whole map from what the NCA grew (adds the fixed parts)."""
        return np.asarray(grown, dtype=np.uint8)

    def storage(self, tiles: np.ndarray) -> np.ndarray:
        """The part of a whole map that the NCA grows (the inverse of :meth:`complete`)."""
        return np.asarray(tiles)

    def grid(self, tiles: np.ndarray, **metadata) -> Grid:
        return Grid(tiles, self.vocabulary, metadata)

    def tiled(self, tiles: np.ndarray, size: str) -> np.ndarray:
        """The whole map ``tiles`` repeated to fill ``size`` (a named size or ROWSxCOLUMNS of the grown area): its
        grown part is repeated along both axes as often as needed, cut to the new grown area from the top-left,
        and the fixed parts added (the warehouse paper's tiling baseline, which it then repairs)."""
        small = self.storage(tiles)
        rows, cols = self.size(size).grown
        repeats = (-(-rows // small.shape[0]), -(-cols // small.shape[1]))
        return self.complete(np.tile(small, repeats)[:rows, :cols])


class _Warehouse(LayoutKind):
    #: Columns on each side of the storage area that hold the workstations.
    border = 2

    def complete(self, grown: np.ndarray) -> np.ndarray:
        grown = np.asarray(grown, dtype=np.uint8)
        rows = grown.shape[0]
        left = np.zeros((rows, self.border), dtype=np.uint8)
        station = self.vocabulary.index("w")
        workstation_rows = [i for i in range(1, rows - 1) if (i - 1) % 3 == 0]
        left[workstation_rows, 0] = station
        return np.hstack([left, grown, left[:, ::-1]])

    def storage(self, tiles: np.ndarray) -> np.ndarray:
        return np.asarray(tiles)[:, self.border : -self.border]


class _Maze(LayoutKind):
    def complete(self, grown: np.ndarray) -> np.ndarray:
        return np.pad(np.asarray(grown, dtype=np.uint8), 1, constant_values=self.vocabulary.index("X"))

    def storage(self, tiles: np.ndarray) -> np.ndarray:
        return np.asarray(tiles)[1:-1, 1:-1]


def _warehouse_sizes() -> dict[str, Size]:
    # Full map (rows x columns with the workstation columns) -> shelves, from the original's offline scripts.
    table = {(33, 36): 240, (45, 47): 440, (57, 58): 700, (69, 69): 1020, (81, 80): 1400, (93, 91): 1840}
    sizes = {f"{r}x{c}": Size((r, c - 4), shelves, 50) for (r, c), shelves in table.items()}
    sizes["101x102"] = Size((101, 98), 2500, 200)
    sizes["9x16"] = Size((9, 12), 20, 50)  # the original's small map (its human layout has 20 shelves); for tests
    return sizes


def _whole_sizes(extra: dict[str, Size]) -> dict[str, Size]:
    shapes = [(33, 36), (45, 47), (57, 58), (69, 69), (81, 80), (93, 91)]
    sizes = {f"{r}x{c}": Size((r, c), 0, 50) for r, c in shapes}
    sizes["101x102"] = Size((101, 102), 0, 200)
    sizes.update(extra)
    return sizes


WAREHOUSE = _Warehouse(
    name="warehouse",
    vocabulary=".@ersw",
    nca_tiles=3,
    tile_names={".": "floor", "@": "shelf", "e": "endpoint", "r": "robot start", "s": "source", "w": "workstation"},
    colours={".": "#f4f4f4", "@": "#4a4a4a", "e": "#8fc1e3", "r": "#f2b134", "s": "#d95f02", "w": "#d95f02"},
    sizes=_warehouse_sizes(),
    default_size="33x36",
    seed_block=("ee", "@@", "ee"),
    seed_offset=(1, 1),
    seed_rows={93: 39, 101: 50},
    blocking="@",
)

MANUFACTURING = LayoutKind(
    name="manufacturing",
    vocabulary=".012es",
    nca_tiles=5,
    tile_names={
        ".": "floor",
        "0": "station 0 (wait 2)",
        "1": "station 1 (wait 5)",
        "2": "station 2 (wait 10)",
        "e": "endpoint",
        "s": "source",
    },
    colours={".": "#f4f4f4", "0": "#1b9e77", "1": "#7570b3", "2": "#e7298a", "e": "#8fc1e3", "s": "#d95f02"},
    sizes=_whole_sizes({"9x16": Size((9, 16), 0, 50)}),
    default_size="33x36",
    seed_block=("eeee", "0221", "eeee"),
    seed_offset=(1, 2),
    seed_rows={93: 39, 101: 50},
    blocking="012",
)

MAZE = _Maze(
    name="maze",
    vocabulary=" X",
    nca_tiles=2,
    tile_names={" ": "floor", "X": "wall"},
    colours={" ": "#f4f4f4", "X": "#303030"},
    sizes={
        "16x16": Size((16, 16), 0, 50),
        "32x32": Size((32, 32), 0, 50),
        "64x64": Size((64, 64), 0, 50),
        "96x96": Size((96, 96), 0, 50),
    },
    default_size="16x16",
    seed_block=("XX", "XX"),
    seed_offset=(1, 1),
    seed_rows={96: 31},
    blocking="X",
)

KINDS = {kind.name: kind for kind in (WAREHOUSE, MANUFACTURING, MAZE)}
