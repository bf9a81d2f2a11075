"""The Structure type: vertices on an integer lattice joined by edges between lattice neighbours.

A structure is what every generator in structgen produces and what the physics checks judge. Coordinates are integer
lattice cells (x, y, z) with z up; an edge joins two distinct cells that are at most one step apart on every axis (the
26-neighbourhood), so edges run along axes, face diagonals and body diagonals. Lengths in the world are lattice units
times a spacing chosen at export or simulation time.

The JSON form is the canonical file format::

    {"vertices": [[0, 0, 0], [0, 0, 1]], "edges": [[0, 1]], "metadata": {...}}

``metadata`` is optional and carries free-form provenance (which generator, which run); it travels into GLB exports.
"""

from __future__ import annotations

import json
import math
import numbers
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from evolution.files import InputFileError, MiB, atomic_write, read_json
from structgen.errors import StructureError
from structgen.lattice import are_neighbours

if TYPE_CHECKING:
    import trimesh

__all__ = ["MAX_COORDINATE", "MAX_FILE_BYTES", "Structure", "StructureError"]

#: Coordinates must lie in [-MAX_COORDINATE, MAX_COORDINATE]: far beyond any structure that can be grown, simulated
#: or drawn, and small enough that nothing computed from coordinates (differences, squared lengths, grid indices)
#: can overflow.
MAX_COORDINATE = 1 << 20
#: Structure files larger than this are refused before they are read (about 15 million vertices).
MAX_FILE_BYTES = 512 * MiB
_FILE_FIELDS = ("vertices", "edges", "metadata")


def _prefix(source: str | None) -> str:
    return f"{source}: " if source else ""


def _int_table(value: Any, name: str, width: int, source: str | None) -> np.ndarray:
    """Convert ``value`` to an ``(n, width)`` int64 array, or raise StructureError naming the first bad entry."""
    where = _prefix(source)
    what = "[x, y, z] triples" if width == 3 else "[i, j] pairs"
    if isinstance(value, np.ndarray):
        if value.size == 0 and value.ndim in (1, 2):
            return np.zeros((0, width), dtype=np.int64)
        if value.ndim != 2 or value.shape[1] != width:
            raise StructureError(f"{where}{name}: expected shape (n, {width}) of {what}, got shape {value.shape}")
        kind = value.dtype.kind
        if kind not in "iuf" or value.dtype == np.bool_:
            raise StructureError(f"{where}{name}: expected integers, got an array of dtype {value.dtype}")
        if kind == "f":
            bad = ~np.isfinite(value) | (value != np.round(value))
            if bad.any():
                i, j = np.argwhere(bad)[0]
                raise StructureError(
                    f"{where}{name}[{i}] = {value[i].tolist()}: entry {j} is {value[i, j].item()!r}, not an integer"
                )
        # Checked before converting: a float like 1e300 or a uint64 above 2**63 would wrap around in int64.
        large = (value > MAX_COORDINATE) | (value < -MAX_COORDINATE) if kind != "u" else value > MAX_COORDINATE
        if large.any():
            i, j = np.argwhere(large)[0]
            raise StructureError(
                f"{where}{name}[{i}] = {value[i].tolist()}: entry {j} is out of range (at most {MAX_COORDINATE:,} in size)"
            )
        return value.astype(np.int64)
    if not isinstance(value, (list, tuple)):
        raise StructureError(f"{where}{name}: expected a list of {what}, got {type(value).__name__}")
    for i, row in enumerate(value):
        if not isinstance(row, (list, tuple, np.ndarray)) or len(row) != width:
            raise StructureError(f"{where}{name}[{i}] = {row!r}: expected {width} integers")
        for j, x in enumerate(row):
            if isinstance(x, (bool, np.bool_)) or not isinstance(x, numbers.Real):
                raise StructureError(
                    f"{where}{name}[{i}] = {list(row)!r}: entry {j} is {x!r} ({type(x).__name__}), not an integer"
                )
            if not isinstance(x, numbers.Integral) and not (math.isfinite(x) and float(x).is_integer()):
                raise StructureError(f"{where}{name}[{i}] = {list(row)!r}: entry {j} is {x!r}, not an integer")
            if abs(x) > MAX_COORDINATE:
                raise StructureError(
                    f"{where}{name}[{i}] = {list(row)!r}: entry {j} is out of range (at most {MAX_COORDINATE:,} in size)"
                )
    if not value:
        return np.zeros((0, width), dtype=np.int64)
    return np.array(value, dtype=np.float64 if _any_float(value) else np.int64).astype(np.int64)


def _any_float(rows: list | tuple) -> bool:
    return any(not isinstance(x, numbers.Integral) for row in rows for x in row)


class Structure:
    """A lattice structure: ``(V, 3)`` integer vertices (z up) and ``(E, 2)`` undirected edges between neighbours.

    The constructor validates its input and raises :class:`StructureError` (a ``ValueError``) naming the problem:
    wrong shape or type, non-integer coordinates, duplicate vertices, edge indices out of range, self-loops, edges
    between cells that are not 26-neighbours, and repeated edges. Edges are stored with the smaller index first, in
    the order given. Instances are immutable: the arrays are read-only.

    Args:
        vertices: ``(V, 3)`` integer lattice coordinates, ``V >= 1``.
        edges: ``(E, 2)`` vertex indices; may be empty.
        metadata: optional JSON-serialisable provenance, kept in saved files and GLB exports.
    """

    __slots__ = ("_edges", "_metadata", "_vertices")

    def __init__(self, vertices: Any, edges: Any = (), metadata: Mapping[str, Any] | None = None) -> None:
        self._init(vertices, edges, metadata, source=None)

    def _init(self, vertices: Any, edges: Any, metadata: Mapping[str, Any] | None, source: str | None) -> None:
        where = _prefix(source)
        v = _int_table(vertices, "vertices", 3, source)
        e = _int_table(edges, "edges", 2, source)
        if len(v) == 0:
            raise StructureError(f"{where}vertices: a structure needs at least one vertex")
        if np.abs(v).max() > MAX_COORDINATE:
            i = int(np.argmax(np.abs(v).max(axis=1)))
            raise StructureError(f"{where}vertices[{i}] = {v[i].tolist()}: coordinate out of range")
        _check_unique_rows(v, "vertices", where, lambda i, j: f"vertices[{j}] duplicates vertices[{i}]")
        if len(e):
            out = (e < 0) | (e >= len(v))
            if out.any():
                i, j = np.argwhere(out)[0]
                raise StructureError(
                    f"{where}edges[{i}] = {e[i].tolist()}: vertex index {e[i, j]} out of range "
                    f"(the structure has {len(v)} vertices)"
                )
            loops = e[:, 0] == e[:, 1]
            if loops.any():
                i = int(np.argmax(loops))
                raise StructureError(f"{where}edges[{i}] = {e[i].tolist()}: joins vertex {e[i, 0]} to itself")
            far = ~are_neighbours(v[e[:, 0]], v[e[:, 1]])
            if far.any():
                i = int(np.argmax(far))
                a, b = v[e[i, 0]].tolist(), v[e[i, 1]].tolist()
                raise StructureError(
                    f"{where}edges[{i}] = {e[i].tolist()}: joins {a} and {b}, which are not lattice neighbours "
                    "(each coordinate may differ by at most 1)"
                )
            e = np.sort(e, axis=1)
            _check_unique_rows(e, "edges", where, lambda i, j: f"edges[{j}] repeats edges[{i}]")
        if metadata is None:
            metadata = {}
        if not isinstance(metadata, Mapping) or not all(isinstance(k, str) for k in metadata):
            raise StructureError(f"{where}metadata: expected an object with string keys, got {metadata!r:.80}")
        try:  # it goes into JSON and GLB files, which hold neither NaN nor infinity nor arbitrary objects
            text = json.dumps(dict(metadata), allow_nan=False)
        except (TypeError, ValueError, RecursionError) as err:
            raise StructureError(f"{where}metadata: must be JSON with finite numbers ({err})") from None
        v.setflags(write=False)
        e.setflags(write=False)
        self._vertices = v
        self._edges = e
        self._metadata = json.loads(text)

    @classmethod
    def _trusted(cls, vertices: np.ndarray, edges: np.ndarray, metadata: dict[str, Any]) -> Structure:
        """Wrap arrays that are valid by construction (the NCA's output) without re-checking them."""
        structure = cls.__new__(cls)
        structure._vertices = np.ascontiguousarray(vertices, dtype=np.int64)
        structure._edges = np.ascontiguousarray(edges, dtype=np.int64).reshape(-1, 2)
        structure._vertices.setflags(write=False)
        structure._edges.setflags(write=False)
        structure._metadata = metadata
        return structure

    # -- data -------------------------------------------------------------------------------------------------------
    @property
    def vertices(self) -> np.ndarray:
        """``(V, 3)`` int64 lattice coordinates, z up (read-only)."""
        return self._vertices

    @property
    def edges(self) -> np.ndarray:
        """``(E, 2)`` int64 vertex index pairs, smaller index first (read-only)."""
        return self._edges

    @property
    def metadata(self) -> dict[str, Any]:
        """Free-form provenance; a copy, so editing it does not change the structure."""
        return json.loads(json.dumps(self._metadata)) if self._metadata else {}

    def with_metadata(self, **updates: Any) -> Structure:
        """A copy of this structure with ``updates`` merged into its metadata."""
        return Structure(self._vertices, self._edges, {**self._metadata, **updates})

    def in_growth_order(self) -> Structure:
        """The same structure listed as an NCA's growth lists it: vertices by cell (x, then y, then z), edges by
        their endpoints. PyBullet's solver visits joints in the order their bodies were made, so a design judged in
        another order can carry a few newtons more or less than the grown structure does."""
        order = np.lexsort(self._vertices.T[::-1])
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        edges = np.sort(rank[self._edges], axis=1) if len(self._edges) else self._edges
        edges = edges[np.lexsort(edges.T[::-1])] if len(edges) else edges
        return Structure._trusted(self._vertices[order], edges, self.metadata)

    # -- metrics ----------------------------------------------------------------------------------------------------
    @property
    def n_vertices(self) -> int:
        return len(self._vertices)

    @property
    def n_edges(self) -> int:
        return len(self._edges)

    @property
    def bounds(self) -> np.ndarray:
        """``(2, 3)`` array: the minimum and maximum corner of the bounding box, in lattice cells."""
        return np.stack([self._vertices.min(axis=0), self._vertices.max(axis=0)])

    @property
    def height(self) -> int:
        """Highest minus lowest vertex z, in lattice units (0 for a flat structure)."""
        z = self._vertices[:, 2]
        return int(z.max() - z.min())

    def degrees(self) -> np.ndarray:
        """``(V,)`` number of edges at each vertex."""
        return np.bincount(self._edges.ravel(), minlength=self.n_vertices)

    def component_labels(self) -> np.ndarray:
        """``(V,)`` connected-component label of each vertex; labels are 0, 1, ... in order of first vertex."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        n = self.n_vertices
        graph = coo_matrix((np.ones(self.n_edges), (self._edges[:, 0], self._edges[:, 1])), shape=(n, n))
        _, labels = connected_components(graph, directed=False)
        return labels.astype(np.int64)

    @property
    def n_components(self) -> int:
        """Number of connected pieces (a lone vertex is a piece of its own)."""
        return int(self.component_labels().max()) + 1

    def summary(self) -> dict[str, Any]:
        """The metrics shown by ``structgen info``, as plain JSON-ready values."""
        degrees = self.degrees()
        low, high = self.bounds
        return {
            "vertices": self.n_vertices,
            "edges": self.n_edges,
            "height": self.height,
            "bounds": {"min": low.tolist(), "max": high.tolist()},
            "size": (high - low).tolist(),
            "components": self.n_components,
            "isolated_vertices": int((degrees == 0).sum()),
            "max_degree": int(degrees.max()),
        }

    # -- comparison -------------------------------------------------------------------------------------------------
    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Structure):
            return NotImplemented
        return (
            np.array_equal(self._vertices, other._vertices)
            and np.array_equal(self._edges, other._edges)
            and self._metadata == other._metadata
        )

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"Structure(n_vertices={self.n_vertices}, n_edges={self.n_edges}, height={self.height})"

    # -- files ------------------------------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The JSON form: ``{"vertices": [[x, y, z], ...], "edges": [[i, j], ...]}`` plus ``metadata`` if any."""
        data: dict[str, Any] = {"vertices": self._vertices.tolist(), "edges": self._edges.tolist()}
        if self._metadata:
            data["metadata"] = self.metadata
        return data

    @classmethod
    def from_dict(cls, data: Any, *, source: str | None = None) -> Structure:
        """Build a structure from its JSON form; ``source`` (a file name) prefixes error messages."""
        where = _prefix(source)
        if not isinstance(data, Mapping):
            raise StructureError(f"{where}expected a JSON object with 'vertices' and 'edges', got {type(data).__name__}")
        unknown = sorted(set(data) - set(_FILE_FIELDS))
        if unknown:
            raise StructureError(f"{where}unknown field {unknown[0]!r} (allowed: {', '.join(_FILE_FIELDS)})")
        for required in ("vertices", "edges"):
            if required not in data:
                raise StructureError(f"{where}missing field {required!r}")
        structure = cls.__new__(cls)
        structure._init(data["vertices"], data["edges"], data.get("metadata"), source)
        return structure

    def save(self, path: str | os.PathLike) -> Path:
        """Write the structure as JSON (``.json`` suffix required), atomically; returns the path."""
        path = Path(path)
        if path.suffix.lower() != ".json":
            raise StructureError(f"{path}: save() writes JSON and needs a .json name; use export() for meshes")
        try:
            text = _dump_json(self.to_dict())
        except (TypeError, ValueError) as err:
            raise StructureError(f"{path}: metadata is not JSON-serialisable: {err}") from None
        return atomic_write(path, text)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Structure:
        """Read a structure from a JSON file.

        Raises:
            StructureError: the file cannot be read (missing, not a regular file, larger than
                :data:`MAX_FILE_BYTES`), is not valid JSON, or is not a valid structure; the message names the file
                and the field, index and value at fault.
        """
        try:
            data = read_json(path, MAX_FILE_BYTES, what="structure JSON")
        except InputFileError as err:
            raise StructureError(str(err)) from None
        return cls.from_dict(data, source=str(path))

    # -- meshes -----------------------------------------------------------------------------------------------------
    def to_mesh(self, *, solid: bool = False, **dimensions: float) -> trimesh.Trimesh:
        """One triangle mesh: a sphere at every vertex and a cylinder along every edge, standing on the ground plane
        (z = 0), with vertex normals; ``solid=True`` unions them into one watertight shell.

        Keyword arguments are :class:`structgen.mesh.MeshStyle` fields (``sphere_radius=0.25``,
        ``cylinder_radius=0.08``, ``spacing=1.0``, ...); the defaults match the physics model. Coordinates stay z-up.
        """
        from structgen.mesh import MeshStyle, structure_mesh

        return structure_mesh(self, MeshStyle(**dimensions), solid=solid)

    def export(
        self, path: str | os.PathLike, *, solid: bool = False, edge_colors: Any = None, colour_key: Any = None,
        **dimensions: float,
    ) -> Path:  # fmt: skip
        """Write the structure to ``path``, format chosen by suffix: ``.json``, ``.glb``, ``.obj``, ``.stl``, ``.ply``.

        GLB is converted to y-up as glTF requires, shares one sphere and one cylinder per direction between all
        parts, and carries the metadata; the others keep z-up. ``solid=True`` writes one watertight shell (for
        printing). ``edge_colors`` (E, 4 RGBA bytes) colours each edge's cylinder (mesh formats but STL), with
        ``colour_key`` saying what they mean in a GLB's metadata (see :mod:`structgen.mesh`). Keyword arguments
        are mesh dimensions as in :meth:`to_mesh`. The file is written atomically.
        """
        path = Path(path)
        if path.suffix.lower() == ".json":
            if dimensions or solid or edge_colors is not None:
                raise StructureError(f"{path}: mesh options do not apply to a JSON export")
            return self.save(path)
        from structgen.mesh import MeshStyle, export_structure

        return export_structure(self, path, MeshStyle(**dimensions), solid=solid, edge_colors=edge_colors,
                                colour_key=colour_key)  # fmt: skip


def _dump_json(data: dict[str, Any]) -> str:
    """JSON with one vertex or edge per line: diff-friendly and still readable for large structures."""
    lines = ["{"]
    items = list(data.items())
    for n, (key, value) in enumerate(items):
        comma = "," if n < len(items) - 1 else ""
        if key in ("vertices", "edges") and value:
            rows = ",\n".join(f"    {json.dumps(row)}" for row in value)
            lines.append(f'  "{key}": [\n{rows}\n  ]{comma}')
        else:
            lines.append(f"  {json.dumps(key)}: {json.dumps(value, allow_nan=False)}{comma}")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _check_unique_rows(rows: np.ndarray, name: str, where: str, describe) -> None:
    """Raise StructureError naming the first pair of equal rows (by the later row's index)."""
    if len(rows) < 2:
        return
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    same = np.all(ordered[1:] == ordered[:-1], axis=1)
    if not same.any():
        return
    pairs = [(order[k], order[k + 1]) for k in np.flatnonzero(same)]
    first, later = min(((min(a, b), max(a, b)) for a, b in pairs), key=lambda p: p[1])
    value = rows[later].tolist()
    raise StructureError(f"{where}{describe(int(first), int(later))}: {value}")
