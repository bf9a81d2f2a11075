"""Grid: the layout type every 2D domain shares, a ``(H, W)`` array of small-int tiles with a named vocabulary.

A tile's number is its position in the vocabulary string: with ``vocabulary=".@ersw"`` tile 0 is ``.``, tile 1 is
``@``. Text is one character per cell, one line per row, the form the warehouse paper's map files use; a JSON file
holds that text as ``layout`` (a list of rows) with ``n_row`` and ``n_col``, the vocabulary as ``tiles``, and any
metadata beside them, so files written here load in the original code and the original's files load here as they
are (:meth:`Grid.load`). numpy only.

>>> g = Grid.from_text(["..@", "e.w"], ".@ersw")
>>> g.shape, g.count("@"), g.one_hot().shape
((2, 3), 1, (6, 2, 3))
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from evolution.files import InputFileError, atomic_write, read_json
from structgen.errors import InputError

__all__ = ["MAX_GRID_CELLS", "MAX_GRID_FILE_BYTES", "Grid", "GridError"]

#: Largest grid accepted: 4096 x 4096 cells, 400 times the warehouse paper's largest map.
MAX_GRID_CELLS = 4096 * 4096
MAX_GRID_FILE_BYTES = 64 << 20
#: Keys of a map file that describe the grid itself; every other key is metadata.
_FORMAT_KEYS = ("layout", "n_row", "n_col", "tiles")


class GridError(InputError):
    """A grid, its text or its file is invalid; the message names the file, the row and column, and the character."""


def _where(source: str | None) -> str:
    return f"{source}: " if source else ""


class Grid:
    """A rectangular layout of tiles.

    Attributes:
        tiles: ``(H, W)`` ``uint8`` array of tile numbers, read-only.
        vocabulary: the tiles' characters; tile ``i`` is ``vocabulary[i]``.
        metadata: JSON-ready data about the layout (its name, how it was made, measured values).
    """

    __slots__ = ("metadata", "tiles", "vocabulary")

    def __init__(self, tiles: Any, vocabulary: str, metadata: Mapping[str, Any] | None = None) -> None:
        self._init(tiles, vocabulary, metadata, None)

    def _init(self, tiles: Any, vocabulary: str, metadata: Mapping[str, Any] | None, source: str | None) -> None:
        where = _where(source)
        if not isinstance(vocabulary, str) or not vocabulary or len(set(vocabulary)) != len(vocabulary):
            raise GridError(f"{where}vocabulary must be a string of distinct characters, got {vocabulary!r}")
        if len(vocabulary) > 255 or any(c in "\n\r" for c in vocabulary):
            raise GridError(f"{where}vocabulary {vocabulary!r}: at most 255 characters, no line breaks")
        array = np.asarray(tiles)
        if array.ndim != 2 or 0 in array.shape:
            raise GridError(f"{where}tiles must be a non-empty 2D array, got shape {array.shape}")
        if array.size > MAX_GRID_CELLS:
            raise GridError(f"{where}{array.shape[0]} x {array.shape[1]} cells is more than {MAX_GRID_CELLS:,}")
        if not np.issubdtype(array.dtype, np.integer):
            raise GridError(f"{where}tiles must be integers, got {array.dtype}")
        outside = (array < 0) | (array >= len(vocabulary))
        if outside.any():
            row, col = (int(i) for i in np.argwhere(outside)[0])
            raise GridError(
                f"{where}tile {int(array[row, col])} at row {row}, column {col} is not in the vocabulary "
                f"{vocabulary!r} (0 to {len(vocabulary) - 1})"
            )
        meta = dict(metadata or {})
        try:
            json.dumps(meta, allow_nan=False)
        except (TypeError, ValueError) as err:
            raise GridError(f"{where}metadata must be JSON with finite numbers ({err})") from None
        self.tiles = array.astype(np.uint8)
        self.tiles.flags.writeable = False
        self.vocabulary = vocabulary
        self.metadata = meta

    # -- text ---------------------------------------------------------------------------------------------------------
    @classmethod
    def from_text(
        cls,
        rows: str | Iterable[str],
        vocabulary: str,
        metadata: Mapping[str, Any] | None = None,
        *,
        source: str | None = None,
    ) -> Grid:
        """A grid from rows of characters (a list of strings, or one string of lines)."""
        where = _where(source)
        if isinstance(rows, str):
            rows = rows.splitlines()
        rows = list(rows)
        if not rows:
            raise GridError(f"{where}layout has no rows")
        for r, row in enumerate(rows):
            if not isinstance(row, str):
                raise GridError(f"{where}layout[{r}] must be a string of tiles, got {type(row).__name__}")
            if len(row) != len(rows[0]):
                raise GridError(
                    f"{where}layout[{r}] has {len(row)} tiles, row 0 has {len(rows[0])}: the rows of a grid must all be as long"
                )
        if len(rows) * len(rows[0]) > MAX_GRID_CELLS:
            raise GridError(f"{where}{len(rows)} x {len(rows[0])} cells is more than {MAX_GRID_CELLS:,}")
        codes = np.frombuffer("".join(rows).encode("utf-32-le"), dtype=np.uint32).reshape(len(rows), -1)
        known = np.array([ord(c) for c in vocabulary], dtype=np.uint32)
        order = np.argsort(known)
        position = np.minimum(np.searchsorted(known[order], codes), len(known) - 1)
        tiles = np.where(known[order][position] == codes, order[position], 255)
        unknown = tiles == 255
        if unknown.any():
            row, col = (int(i) for i in np.argwhere(unknown)[0])
            raise GridError(
                f"{where}layout[{row}][{col}] = {rows[row][col]!r} is not a tile of this domain (tiles: {vocabulary!r})"
            )
        grid = cls.__new__(cls)
        grid._init(tiles, vocabulary, metadata, source)
        return grid

    def rows(self) -> list[str]:
        """One string per row."""
        chars = np.array(list(self.vocabulary))
        return ["".join(row) for row in chars[self.tiles]]

    def to_text(self) -> str:
        return "\n".join(self.rows()) + "\n"

    # -- JSON ---------------------------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The map-file form: metadata, then ``n_row``, ``n_col``, ``tiles`` and ``layout``."""
        data = {k: v for k, v in self.metadata.items() if k not in _FORMAT_KEYS}
        data.update(n_row=self.shape[0], n_col=self.shape[1], tiles=self.vocabulary, layout=self.rows())
        return data

    @classmethod
    def from_dict(cls, data: Any, vocabulary: str | None = None, *, source: str | None = None) -> Grid:
        """A grid from a map file's data. ``vocabulary`` is required when the data does not name its tiles (the
        original's files do not); ``n_row``/``n_col`` that disagree with the layout are kept in the metadata as
        ``header_n_row``/``header_n_col`` (several of the original's files carry stale ones)."""
        where = _where(source)
        if not isinstance(data, dict):
            raise GridError(f"{where}a map file must hold a JSON object, got {type(data).__name__}")
        if "layout" not in data:
            raise GridError(f"{where}no 'layout' field (the rows of tiles)")
        named = data.get("tiles")
        if named is not None and not isinstance(named, str):
            raise GridError(f"{where}tiles = {named!r}: must be a string of tile characters")
        if vocabulary is None:
            if named is None:
                raise GridError(f"{where}the file does not name its tiles ('tiles' field); say which domain it is")
            vocabulary = named
        elif named is not None and named != vocabulary:
            raise GridError(f"{where}tiles = {named!r}, but this domain's tiles are {vocabulary!r}")
        layout = data["layout"]
        if not isinstance(layout, list):
            raise GridError(f"{where}layout must be a list of strings, one per row, got {type(layout).__name__}")
        metadata = {k: v for k, v in data.items() if k not in _FORMAT_KEYS}
        grid = cls.from_text(layout, vocabulary, metadata, source=source)
        for key, actual in (("n_row", grid.shape[0]), ("n_col", grid.shape[1])):
            stated = data.get(key)
            if stated is not None and stated != actual:
                grid.metadata[f"header_{key}"] = stated
        return grid

    def save(self, path: str | os.PathLike) -> Path:
        """Write the grid as a map file (``.json``), atomically."""
        path = Path(path)
        if path.suffix.lower() != ".json":
            raise GridError(f"{path}: a map file needs a .json name")
        data = self.to_dict()
        layout = data.pop("layout")
        head = json.dumps(data, allow_nan=False)[:-1]
        rows = ",\n    ".join(json.dumps(row) for row in layout)
        return atomic_write(path, f'{head}{", " if data else ""}"layout": [\n    {rows}\n  ]\n}}\n')

    @classmethod
    def load(cls, path: str | os.PathLike, vocabulary: str | None = None) -> Grid:
        """Read a map file; see :meth:`from_dict` for ``vocabulary``."""
        try:
            data = read_json(path, MAX_GRID_FILE_BYTES, what="map JSON")
        except InputFileError as err:
            raise GridError(str(err)) from None
        return cls.from_dict(data, vocabulary, source=str(path))

    # -- views --------------------------------------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.tiles.shape[0]), int(self.tiles.shape[1]))

    def tile(self, char: str) -> int:
        """The number of the tile written ``char``."""
        index = self.vocabulary.find(char) if isinstance(char, str) and len(char) == 1 else -1
        if index < 0:
            raise GridError(f"{char!r} is not a tile of this grid (tiles: {self.vocabulary!r})")
        return index

    def mask(self, chars: str) -> np.ndarray:
        """Boolean ``(H, W)``: where the tile is any of ``chars``."""
        return np.isin(self.tiles, [self.tile(c) for c in chars])

    def count(self, chars: str) -> int:
        """How many cells hold any of the tiles ``chars``."""
        return int(self.mask(chars).sum())

    def one_hot(self, dtype: Any = np.float32) -> np.ndarray:
        """``(len(vocabulary), H, W)``: channel ``i`` is 1 where the tile is ``i``."""
        return (np.arange(len(self.vocabulary))[:, None, None] == self.tiles[None]).astype(dtype)

    def replace(self, tiles: Any = None, metadata: Mapping[str, Any] | None = None) -> Grid:
        """A copy with other tiles or metadata, the same vocabulary."""
        return Grid(self.tiles if tiles is None else tiles, self.vocabulary, self.metadata if metadata is None else metadata)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Grid):
            return NotImplemented
        return (
            self.vocabulary == other.vocabulary
            and self.tiles.shape == other.tiles.shape
            and bool((self.tiles == other.tiles).all())
            and self.metadata == other.metadata
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        name = self.metadata.get("name")
        return f"Grid({self.shape[0]}x{self.shape[1]}, tiles {self.vocabulary!r}{f', {name!r}' if name else ''})"
