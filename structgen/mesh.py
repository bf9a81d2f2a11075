"""Structures as triangle meshes: a sphere at every vertex, a cylinder along every edge.

The default dimensions are those of the simulated bodies (sphere radius 0.25 and cylinder radius 0.08 at lattice
spacing 1, as :class:`physics.PhysicsConfig` has them; a test holds the two to the same numbers, so export needs no
physics), and a cylinder runs from sphere surface to sphere surface as the
simulated bodies do. The structure stands on the ground plane as it is simulated: its lowest spheres touch height 0.

Every part is a copy of a few templates with vertex normals: one sphere, and one cylinder per edge direction (a
lattice has 13 axes, and every edge along one axis has the same length). GLB files keep that sharing: each template
is stored once and every part is a node that places it (a translation), so a 2,000-vertex structure is a few hundred
kilobytes at full resolution. OBJ, STL and PLY get the parts as one triangle list. ``solid=True`` unions every part
into one closed, watertight shell (manifold3d), for 3D printing.
"""

from __future__ import annotations

import json
import os
import struct
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from evolution.files import atomic_write
from structgen.budget import check_memory
from structgen.config import Limit, check_limits
from structgen.errors import StructureError

if TYPE_CHECKING:
    import trimesh


class Meshable(Protocol):
    """What a mesh needs of a :class:`structgen.structure.Structure` (named by shape, not imported: the structure
    module offers ``to_mesh`` and ``export`` through this one, so importing it back would make a circle)."""

    @property
    def vertices(self) -> np.ndarray: ...

    @property
    def edges(self) -> np.ndarray: ...

    @property
    def metadata(self) -> dict[str, Any]: ...

    @property
    def n_vertices(self) -> int: ...

    @property
    def n_edges(self) -> int: ...

    @property
    def height(self) -> int: ...


__all__ = ["EXPORT_FORMATS", "MeshStyle", "export_structure", "structure_mesh"]

#: Suffixes :meth:`Structure.export` understands; ``.json`` is the structure file itself.
EXPORT_FORMATS = (".json", ".glb", ".obj", ".stl", ".ply")

# z-up (structgen, physics) to y-up (glTF): (x, y, z) -> (x, z, -y), a rotation of -90 degrees about x.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class MeshStyle:
    """Dimensions (lattice units times ``spacing``) and look of an exported structure; the dimensions default to
    the physics model's."""

    section: ClassVar[str] = "mesh"
    # The upper bound of the lengths keeps every coordinate of the largest structure a finite float32, as glTF stores it.
    limits: ClassVar[dict[str, Limit]] = {
        "sphere_radius": Limit(0, 1e6, "radius of the vertex spheres", whole=False, above=True),
        "cylinder_radius": Limit(0, 1e6, "radius of the edge cylinders", whole=False, above=True),
        "spacing": Limit(0, 1e6, "world length of one lattice step", whole=False, above=True),
        "sphere_subdivisions": Limit(0, 5, "icosphere subdivisions of each sphere (0 for big structures)"),
        "cylinder_sections": Limit(3, 128, "sides of each cylinder (6 for big structures)"),
    }

    sphere_radius: float = 0.25
    cylinder_radius: float = 0.08
    spacing: float = 1.0
    sphere_subdivisions: int = 2
    cylinder_sections: int = 12
    vertex_color: tuple[int, int, int, int] = (214, 96, 60, 255)
    edge_color: tuple[int, int, int, int] = (120, 140, 165, 255)

    def __post_init__(self) -> None:
        try:
            check_limits(self)
        except ValueError as err:
            raise StructureError(str(err)) from None
        if self.sphere_radius * 2 >= self.spacing:
            raise StructureError(
                f"mesh sphere_radius {self.sphere_radius} must be less than half the spacing {self.spacing}, "
                "or neighbouring spheres touch and edges have no length"
            )


# Peak memory of an export per triangle, measured on lines of 20,000 to 100,000 vertices (GLB, several resolutions).
_BYTES_PER_TRIANGLE = 200


def triangles(structure: Meshable, style: MeshStyle) -> int:
    """How many triangles the parts have: 20 * 4**subdivisions per sphere, 4 * sections per cylinder."""
    return structure.n_vertices * 20 * 4**style.sphere_subdivisions + structure.n_edges * 4 * style.cylinder_sections


@dataclass(frozen=True)
class _Template:
    """One part's geometry, centred on the origin, z-up: positions, unit normals and triangles."""

    positions: np.ndarray  # (n, 3)
    normals: np.ndarray  # (n, 3)
    faces: np.ndarray  # (m, 3), counter-clockwise seen from outside


def _sphere(style: MeshStyle) -> _Template:
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=style.sphere_subdivisions, radius=1.0)
    unit = np.asarray(ball.vertices, dtype=np.float64)
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    return _Template(unit * style.sphere_radius, unit, np.asarray(ball.faces, dtype=np.int64))


def _cylinder(style: MeshStyle, axis: np.ndarray, length: float) -> _Template:
    """A closed cylinder of ``length`` along the unit vector ``axis``: the side with smooth normals, each cap flat
    (its own ring of vertices, so the rim keeps a sharp edge)."""
    n = style.cylinder_sections
    angle = 2 * np.pi * np.arange(n) / n
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(n)], axis=1)
    r, half = style.cylinder_radius, length / 2
    low, high = ring * r - [0, 0, half], ring * r + [0, 0, half]
    positions = np.concatenate([low, high, low, high, [[0, 0, -half], [0, 0, half]]])
    down, up = np.tile([0.0, 0.0, -1.0], (n, 1)), np.tile([0.0, 0.0, 1.0], (n, 1))
    normals = np.concatenate([ring, ring, down, up, [[0, 0, -1.0], [0, 0, 1.0]]])
    k = np.arange(n)
    following = (k + 1) % n
    side = np.concatenate([np.stack([k, following, n + following], 1), np.stack([k, n + following, n + k], 1)])
    bottom = np.stack([np.full(n, 4 * n), 2 * n + following, 2 * n + k], 1)
    top = np.stack([np.full(n, 4 * n + 1), 3 * n + k, 3 * n + following], 1)
    rotation = _rotation_z_to(axis)
    return _Template(positions @ rotation.T, normals @ rotation.T, np.concatenate([side, bottom, top]))


def _rotation_z_to(direction: np.ndarray) -> np.ndarray:
    """The rotation taking +z onto the unit vector ``direction`` (Rodrigues' formula)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, direction)
    sin, cos = float(np.linalg.norm(axis)), float(direction @ z)
    if sin < 1e-12:  # parallel or anti-parallel to z
        return np.eye(3) if cos > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / sin
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sin * cross + (1 - cos) * cross @ cross


@dataclass(frozen=True)
class _Parts:
    """The structure as templates and where each copy goes (z-up, standing on the ground)."""

    sphere: _Template
    centres: np.ndarray  # (V, 3) where a sphere goes
    steps: np.ndarray  # (A, 3) the lattice step of each edge axis in use (first non-zero component positive)
    cylinders: list[_Template]  # one per axis, in the order of ``steps``
    axis_of_edge: np.ndarray  # (E,) which axis each edge lies along
    middles: np.ndarray  # (E, 3) where each edge's cylinder goes

    def by_axis(self) -> list[tuple[np.ndarray, _Template, np.ndarray]]:
        """(lattice step, cylinder template, where its copies go) for each edge axis in use."""
        return [(step, t, self.middles[self.axis_of_edge == a]) for a, (step, t) in enumerate(zip(self.steps, self.cylinders))]


def _parts(structure: Meshable, style: MeshStyle) -> _Parts:
    count = triangles(structure, style)
    check_memory(
        count * _BYTES_PER_TRIANGLE,
        f"a mesh of {structure.n_vertices:,} vertices and {structure.n_edges:,} edges ({count:,} triangles)",
        "use a lighter mesh (--sphere-subdivisions 0 --cylinder-sections 3)",
    )
    centres = structure.vertices.astype(np.float64) * style.spacing
    if len(centres):  # the lowest spheres rest on the ground plane z = 0, as in the simulation
        centres[:, 2] += style.sphere_radius - centres[:, 2].min()
    steps = structure.vertices[structure.edges[:, 1]] - structure.vertices[structure.edges[:, 0]]
    # An edge and its reverse are the same cylinder: orient every step so its first non-zero component is positive.
    first = steps[np.arange(len(steps)), np.argmax(steps != 0, axis=1)] if len(steps) else np.zeros(0)
    steps = steps * np.where(first < 0, -1, 1)[:, None]
    axes, axis_of_edge = np.unique(steps.reshape(-1, 3), axis=0, return_inverse=True)
    cylinders = []
    for step in axes:
        distance = float(np.linalg.norm(step)) * style.spacing
        cylinders.append(_cylinder(style, step / np.linalg.norm(step), distance - 2 * style.sphere_radius))
    middles = (centres[structure.edges[:, 0]] + centres[structure.edges[:, 1]]) / 2
    return _Parts(_sphere(style), centres, axes, cylinders, axis_of_edge.ravel(), middles)


def _placed(template: _Template, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, normals, faces) of one copy of ``template`` at every offset, as one list."""
    k = len(template.positions)
    positions = (offsets[:, None, :] + template.positions[None]).reshape(-1, 3)
    normals = np.broadcast_to(template.normals, (len(offsets), k, 3)).reshape(-1, 3)
    faces = (template.faces[None] + (np.arange(len(offsets)) * k)[:, None, None]).reshape(-1, 3)
    return positions, normals, faces


def _soup(
    structure: Meshable, style: MeshStyle, edge_colors: np.ndarray | None = None
) -> tuple[trimesh.Trimesh, trimesh.Trimesh | None]:
    """Spheres and cylinders as two meshes with vertex normals (cylinders None without edges), z-up; each cylinder
    in its own colour where ``edge_colors`` (E, 4 RGBA bytes) is given."""
    import trimesh

    parts = _parts(structure, style)
    positions, normals, faces = _placed(parts.sphere, parts.centres)
    spheres = trimesh.Trimesh(positions, faces, vertex_normals=normals, process=False)
    spheres.visual.face_colors = style.vertex_color
    if structure.n_edges == 0:
        return spheres, None
    pieces = [_placed(template, middles) for _, template, middles in parts.by_axis()]
    offsets = np.cumsum([0] + [len(p[0]) for p in pieces[:-1]])
    cylinders = trimesh.Trimesh(
        np.concatenate([p[0] for p in pieces]),
        np.concatenate([p[2] + o for p, o in zip(pieces, offsets)]),
        vertex_normals=np.concatenate([p[1] for p in pieces]),
        process=False,
    )
    if edge_colors is None:
        cylinders.visual.face_colors = style.edge_color
    else:  # the cylinders are listed axis by axis, as by_axis places them
        order = np.concatenate([np.flatnonzero(parts.axis_of_edge == a) for a in range(len(parts.steps))])
        faces_each = [len(template.faces) for _, template, middles in parts.by_axis() for _ in range(len(middles))]
        cylinders.visual.face_colors = np.repeat(edge_colors[order], faces_each, axis=0)
    return spheres, cylinders


def _solid(structure: Meshable, style: MeshStyle) -> trimesh.Trimesh:
    """Every part unioned into one closed shell: each cylinder reaches into its two spheres, so every joint fuses."""
    import trimesh

    try:
        import manifold3d
    except ImportError:  # pragma: no cover - depends on the installation
        raise StructureError("a solid mesh needs the manifold3d package: pip install manifold3d") from None

    def manifold(vertices: np.ndarray, faces: np.ndarray) -> manifold3d.Manifold:
        closed = trimesh.Trimesh(vertices, faces, process=True)  # merged: caps and side share their rim
        mesh = manifold3d.Mesh(vert_properties=closed.vertices.astype(np.float32), tri_verts=closed.faces.astype(np.uint32))
        return manifold3d.Manifold(mesh)

    from scipy.spatial.transform import Rotation

    parts = _parts(structure, style)
    # Exact coincidences make a union's intersection curves degenerate (slivers that collapse when the coordinates
    # are rounded to float32): diagonal cylinders of equal radius crossing at their midpoints touch tangentially,
    # and template vertices line up with other parts' edges. So every part is set slightly apart: the sphere turned
    # by an arbitrary rotation, each direction's cylinder turned about its own axis by its own angle and a
    # fraction of a percent thicker than the last, and every cylinder reaching half a sphere radius into its spheres
    # (its caps well inside them, so that neighbours along one line never touch each other).
    ball = manifold(parts.sphere.positions @ Rotation.from_rotvec([0.3, 0.71, 0.13]).as_matrix().T, parts.sphere.faces)
    pieces = [ball.translate(tuple(c)) for c in parts.centres]
    for a, (step, _, middles) in enumerate(parts.by_axis()):
        axis = step / np.linalg.norm(step)
        thicker = replace(style, cylinder_radius=style.cylinder_radius * (1 + 0.002 * a))
        reaching = _cylinder(thicker, axis, float(np.linalg.norm(step)) * style.spacing - style.sphere_radius)
        turn = Rotation.from_rotvec(axis * (0.1 + 0.37 * a)).as_matrix()
        rod = manifold(reaching.positions @ turn.T, reaching.faces)
        pieces += [rod.translate(tuple(m)) for m in middles]
    # Where a cylinder enters a sphere the union leaves slivers far below the mesh's resolution; simplifying them
    # away keeps the shell watertight once its coordinates are rounded to float32 by the file formats.
    shell = manifold3d.Manifold.batch_boolean(pieces, manifold3d.OpType.Add).simplify(1e-4 * style.spacing).to_mesh()
    result = trimesh.Trimesh(np.asarray(shell.vert_properties)[:, :3], np.asarray(shell.tri_verts), process=False)
    result.visual.face_colors = style.vertex_color
    return result


def _check_edge_colors(structure: Meshable, edge_colors: np.ndarray | None, solid: bool) -> np.ndarray | None:
    if edge_colors is None:
        return None
    if solid:
        raise StructureError("a solid shell has one colour: member colours (--stress) need the separate parts")
    colours = np.asarray(edge_colors)
    if colours.shape != (structure.n_edges, 4) or colours.dtype != np.uint8:
        raise StructureError(
            f"edge colours must be ({structure.n_edges}, 4) RGBA bytes, one per edge; got {colours.shape} of {colours.dtype}"
        )
    return colours


def structure_mesh(
    structure: Meshable, style: MeshStyle | None = None, *, solid: bool = False, edge_colors: np.ndarray | None = None
) -> trimesh.Trimesh:
    """One z-up triangle mesh of the structure standing on the ground (spheres first, then cylinders), coloured per
    face, with vertex normals; ``solid=True``: the parts unioned into one watertight shell. ``edge_colors`` (E, 4
    RGBA bytes) colours each edge's cylinder on its own (the load colours of ``--stress``)."""
    import trimesh

    style = style or MeshStyle()
    edge_colors = _check_edge_colors(structure, edge_colors, solid)
    if solid:
        return _solid(structure, style)
    spheres, cylinders = _soup(structure, style, edge_colors)
    return spheres if cylinders is None else trimesh.util.concatenate([spheres, cylinders])


def _linear(colour: tuple[int, int, int, int]) -> list[float]:
    """An 8-bit sRGB colour as glTF's linear base colour factor."""
    srgb = np.asarray(colour[:3], dtype=np.float64) / 255
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return [round(float(c), 5) for c in linear] + [colour[3] / 255]


class _GlbWriter:
    """A minimal glTF 2.0 binary writer: meshes of positions, normals and indices, nodes that place them."""

    def __init__(self) -> None:
        self.chunks: list[bytes] = []
        self.length = 0
        self.views: list[dict] = []
        self.accessors: list[dict] = []
        self.meshes: list[dict] = []

    def _data(self, array: np.ndarray, target: int) -> int:
        raw = array.tobytes()
        self.views.append({"buffer": 0, "byteOffset": self.length, "byteLength": len(raw), "target": target})
        padded = raw + b"\0" * (-len(raw) % 4)
        self.chunks.append(padded)
        self.length += len(padded)
        return len(self.views) - 1

    def _accessor(self, array: np.ndarray, kind: str, target: int, bounds: bool = False) -> int:
        component = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125}[array.dtype]
        accessor = {"bufferView": self._data(array, target), "componentType": component, "count": len(array), "type": kind}
        if bounds:
            accessor["min"] = [float(v) for v in array.min(axis=0)]
            accessor["max"] = [float(v) for v in array.max(axis=0)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def mesh(self, name: str, positions: np.ndarray, normals: np.ndarray, faces: np.ndarray, material: int) -> int:
        index_type = np.uint16 if len(positions) < 65536 else np.uint32
        primitive = {
            "attributes": {
                "POSITION": self._accessor(positions.astype(np.float32), "VEC3", 34962, bounds=True),
                "NORMAL": self._accessor(normals.astype(np.float32), "VEC3", 34962),
            },
            "indices": self._accessor(faces.astype(index_type).ravel(), "SCALAR", 34963),
            "material": material,
        }
        self.meshes.append({"name": name, "primitives": [primitive]})
        return len(self.meshes) - 1

    def recoloured(self, mesh: int, material: int) -> int:
        """A mesh sharing ``mesh``'s geometry (no data written again) in another material."""
        (primitive,) = self.meshes[mesh]["primitives"]
        name = f"{self.meshes[mesh]['name']} m{material}"
        self.meshes.append({"name": name, "primitives": [{**primitive, "material": material}]})
        return len(self.meshes) - 1

    def glb(self, document: dict) -> bytes:
        document = {**document, "meshes": self.meshes, "accessors": self.accessors, "bufferViews": self.views}
        document["buffers"] = [{"byteLength": self.length}]
        text = json.dumps(document, separators=(",", ":")).encode()
        text += b" " * (-len(text) % 4)
        binary = b"".join(self.chunks)
        total = 12 + 8 + len(text) + 8 + len(binary)
        return b"".join(
            [
                struct.pack("<4sII", b"glTF", 2, total),
                struct.pack("<I4s", len(text), b"JSON"),
                text,
                struct.pack("<I4s", len(binary), b"BIN\0"),
                binary,
            ]
        )


def _y_up(points: np.ndarray) -> np.ndarray:
    return points @ Z_UP_TO_Y_UP.T


def _glb_bytes(
    structure: Meshable, style: MeshStyle, solid: bool, edge_colors: np.ndarray | None = None, colour_key: Any = None
) -> bytes:
    from structgen._version import __version__

    writer = _GlbWriter()
    look = {"metallicFactor": 0.0, "roughnessFactor": 0.6}
    materials = [
        {"name": name, "pbrMetallicRoughness": {"baseColorFactor": _linear(colour), **look}}
        for name, colour in (("vertex", style.vertex_color), ("edge", style.edge_color))
    ]
    nodes: list[dict] = [{"name": "structure", "children": []}]

    def add_group(name: str, placements: list[tuple[int, np.ndarray]]) -> None:
        """A node named ``name`` under the root, with one child node per copy of each mesh at each offset."""
        group: dict = {"name": name, "children": []}
        nodes[0]["children"].append(len(nodes))
        nodes.append(group)
        for mesh, offsets in placements:
            start = len(nodes)
            # Six decimals: a millionth of a lattice step, far below anything a viewer or printer resolves.
            nodes.extend({"mesh": mesh, "translation": [round(float(c), 6) for c in at]} for at in _y_up(offsets))
            group["children"].extend(range(start, len(nodes)))

    if solid:
        shell = _solid(structure, style)
        mesh = writer.mesh("solid", _y_up(shell.vertices), _y_up(shell.vertex_normals), shell.faces, 0)
        nodes = [{"name": "structure", "mesh": mesh}]
        materials = materials[:1]  # one shell, one colour
    else:
        parts = _parts(structure, style)
        sphere = writer.mesh("vertex", _y_up(parts.sphere.positions), _y_up(parts.sphere.normals), parts.sphere.faces, 0)
        add_group("vertices", [(sphere, parts.centres)])
        if parts.cylinders:
            placements = []
            # Own colours: one material per colour in use, each axis's cylinder shared by every colour it takes.
            palette, colour_of_edge = (
                (np.zeros((1, 4), np.uint8), np.zeros(structure.n_edges, np.int64))
                if (edge_colors is None)
                else np.unique(edge_colors, axis=0, return_inverse=True)
            )
            if edge_colors is not None:
                first = len(materials)
                materials += [{"name": f"edge #{bytes(c[:3]).hex()}",
                               "pbrMetallicRoughness": {"baseColorFactor": _linear(tuple(int(v) for v in c)), **look}}
                              for c in palette]  # fmt: skip
            for a, (_, template, middles) in enumerate(parts.by_axis()):
                mesh = writer.mesh(f"edge {a}", _y_up(template.positions), _y_up(template.normals), template.faces, 1)
                if edge_colors is None:
                    placements.append((mesh, middles))
                    continue
                colours = colour_of_edge.ravel()[parts.axis_of_edge == a]
                for colour in np.unique(colours):
                    placements.append((writer.recoloured(mesh, first + int(colour)), middles[colours == colour]))
            add_group("edges", placements)
    metadata = {
        "generator": f"structgen {__version__}",
        "up_axis": "y",
        "converted_from": "z-up lattice coordinates: (x, y, z) -> (x, z, -y), lowest spheres on the ground y = 0",
        "n_vertices": structure.n_vertices,
        "n_edges": structure.n_edges,
        "height": structure.height,
        "solid": solid,
        "mesh_style": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(style).items()},
        "structure_metadata": structure.metadata,
        **({"edge_colours": colour_key} if colour_key is not None else {}),
    }
    document = {
        "asset": {"version": "2.0", "generator": f"structgen {__version__}"},
        "scene": 0,
        "scenes": [{"name": "structure", "nodes": [0], "extras": metadata}],
        "nodes": nodes,
        "materials": materials,
    }
    return writer.glb(document)


def export_structure(
    structure: Meshable,
    path: str | os.PathLike,
    style: MeshStyle | None = None,
    *,
    solid: bool = False,
    edge_colors: np.ndarray | None = None,
    colour_key: Any = None,
) -> Path:
    """Write a mesh of ``structure`` to ``path`` in the format its suffix names (``.glb``, ``.obj``, ``.stl``,
    ``.ply``); ``solid=True`` writes one watertight shell instead of separate parts. ``edge_colors`` (E, 4 RGBA
    bytes) colours each edge's cylinder on its own (GLB, OBJ as vertex colours, PLY; STL holds no colour), and
    ``colour_key``, what those colours mean, goes into a GLB's metadata."""
    path = Path(path)
    style = style or MeshStyle()
    suffix = path.suffix.lower()
    edge_colors = _check_edge_colors(structure, edge_colors, solid)
    if edge_colors is not None and suffix == ".stl":
        raise StructureError(f"{path}: STL holds no colours; write member colours to .glb, .obj or .ply")
    if suffix == ".glb":
        payload: bytes | str = _glb_bytes(structure, style, solid, edge_colors, colour_key)
    elif suffix in (".obj", ".stl", ".ply"):
        mesh = structure_mesh(structure, style, solid=solid, edge_colors=edge_colors)
        payload = mesh.export(file_type=suffix[1:], **({"include_normals": True} if suffix == ".obj" else {}))
    else:
        raise StructureError(
            f"{path}: unknown export format {path.suffix or '(no suffix)'!r}; use one of {', '.join(EXPORT_FORMATS)}"
        )
    return atomic_write(path, payload)
