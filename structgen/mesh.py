"""Structures as triangle meshes: a sphere at every vertex, a cylinder along every edge, exported with trimesh.

The default dimensions are read from the physics model's defaults (sphere radius 0.25 and cylinder radius 0.08 at
lattice spacing 1, :class:`physics.PhysicsConfig`), and a cylinder runs from sphere surface to sphere surface as the
simulated bodies do. Meshes are built from one template sphere and one template cylinder transformed with numpy, so
large structures export quickly.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from evolution.files import atomic_write
from physics.config import PhysicsConfig
from structgen.budget import check_memory
from structgen.errors import StructureError

if TYPE_CHECKING:
    import trimesh

    from structgen.structure import Structure

__all__ = ["EXPORT_FORMATS", "MeshStyle", "export_structure", "structure_mesh"]

#: Suffixes :meth:`Structure.export` understands; ``.json`` is the structure file itself.
EXPORT_FORMATS = (".json", ".glb", ".obj", ".stl", ".ply")

# z-up (structgen, physics) to y-up (glTF): (x, y, z) -> (x, z, -y), a rotation of -90 degrees about x.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


_MODEL = PhysicsConfig()


@dataclass(frozen=True)
class MeshStyle:
    """Dimensions (lattice units times ``spacing``) and look of an exported structure; the dimensions default to
    the physics model's."""

    sphere_radius: float = _MODEL.sphere_radius
    cylinder_radius: float = _MODEL.cylinder_radius
    spacing: float = _MODEL.spacing
    sphere_subdivisions: int = 2
    cylinder_sections: int = 12
    vertex_color: tuple[int, int, int, int] = (214, 96, 60, 255)
    edge_color: tuple[int, int, int, int] = (120, 140, 165, 255)

    def __post_init__(self) -> None:
        for name in ("sphere_radius", "cylinder_radius", "spacing"):
            value = getattr(self, name)
            # The upper bound keeps every coordinate of the largest structure a finite float32, as glTF stores it.
            if not (isinstance(value, (int, float)) and np.isfinite(value) and 0 < value <= 1e6):
                raise StructureError(f"mesh {name} must be a positive number up to 1e6, got {value!r}")
        if self.sphere_radius * 2 >= self.spacing:
            raise StructureError(
                f"mesh sphere_radius {self.sphere_radius} must be less than half the spacing {self.spacing}, "
                "or neighbouring spheres touch and edges have no length"
            )
        if not (isinstance(self.sphere_subdivisions, int) and 0 <= self.sphere_subdivisions <= 5):
            raise StructureError(f"mesh sphere_subdivisions must be an integer in 0..5, got {self.sphere_subdivisions!r}")
        if not (isinstance(self.cylinder_sections, int) and 3 <= self.cylinder_sections <= 128):
            raise StructureError(f"mesh cylinder_sections must be an integer in 3..128, got {self.cylinder_sections!r}")


def _rotations_z_to(directions: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotations taking +z onto each unit vector in ``directions`` (Rodrigues' formula)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, directions)
    sin = np.linalg.norm(axis, axis=1)
    cos = directions @ z
    rotations = np.empty((len(directions), 3, 3))
    for n, (a, s, c) in enumerate(zip(axis, sin, cos)):
        if s < 1e-12:  # parallel or anti-parallel to z
            rotations[n] = np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
            continue
        k = a / s
        cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        rotations[n] = np.eye(3) + s * cross + (1 - c) * cross @ cross
    return rotations


# Peak memory of an export per triangle, measured on lines of 20,000 to 100,000 vertices (GLB, several resolutions).
_BYTES_PER_TRIANGLE = 200


def triangles(structure: Structure, style: MeshStyle) -> int:
    """How many triangles the mesh of ``structure`` has: 20 * 4**subdivisions per sphere, 4 * sections per cylinder."""
    return structure.n_vertices * 20 * 4**style.sphere_subdivisions + structure.n_edges * 4 * style.cylinder_sections


def _parts(structure: Structure, style: MeshStyle) -> tuple[trimesh.Trimesh, trimesh.Trimesh | None]:
    """The spheres and the cylinders as two meshes (cylinders ``None`` if there are no edges), z-up."""
    import trimesh

    count = triangles(structure, style)
    check_memory(
        count * _BYTES_PER_TRIANGLE,
        f"a mesh of {structure.n_vertices:,} vertices and {structure.n_edges:,} edges ({count:,} triangles)",
        "use a lighter mesh (--sphere-subdivisions 0 --cylinder-sections 3)",
    )

    centres = structure.vertices.astype(np.float64) * style.spacing
    ball = trimesh.creation.icosphere(subdivisions=style.sphere_subdivisions, radius=style.sphere_radius)
    k = len(ball.vertices)
    sphere_vertices = (centres[:, None, :] + ball.vertices[None, :, :]).reshape(-1, 3)
    sphere_faces = (ball.faces[None, :, :] + (np.arange(len(centres)) * k)[:, None, None]).reshape(-1, 3)
    spheres = trimesh.Trimesh(sphere_vertices, sphere_faces, process=False)
    spheres.visual.face_colors = style.vertex_color
    if structure.n_edges == 0:
        return spheres, None

    start, end = centres[structure.edges[:, 0]], centres[structure.edges[:, 1]]
    span = end - start
    distance = np.linalg.norm(span, axis=1)
    unit = span / distance[:, None]
    length = distance - 2 * style.sphere_radius
    # Edges point in at most 26 lattice directions: compute each rotation once.
    keys = np.round(unit * 1e6).astype(np.int64)
    _, first, which = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    rotations = _rotations_z_to(unit[first])[which.ravel()]
    rod = trimesh.creation.cylinder(radius=style.cylinder_radius, height=1.0, sections=style.cylinder_sections)
    template = rod.vertices[None, :, :] * np.stack([np.ones_like(length), np.ones_like(length), length], axis=1)[:, None]
    middle = (start + end) / 2
    cylinder_vertices = np.einsum("eij,evj->evi", rotations, template) + middle[:, None, :]
    m = len(rod.vertices)
    cylinder_faces = rod.faces[None, :, :] + (np.arange(len(length)) * m)[:, None, None]
    cylinders = trimesh.Trimesh(cylinder_vertices.reshape(-1, 3), cylinder_faces.reshape(-1, 3), process=False)
    cylinders.visual.face_colors = style.edge_color
    return spheres, cylinders


def structure_mesh(structure: Structure, style: MeshStyle | None = None) -> trimesh.Trimesh:
    """One z-up triangle mesh of the structure (spheres first, then cylinders), coloured per face."""
    import trimesh

    spheres, cylinders = _parts(structure, style or MeshStyle())
    return spheres if cylinders is None else trimesh.util.concatenate([spheres, cylinders])


def _glb_bytes(structure: Structure, style: MeshStyle) -> bytes:
    import trimesh

    from structgen._version import __version__

    scene = trimesh.Scene()
    for name, part in zip(("vertices", "edges"), _parts(structure, style)):
        if part is not None:
            part.vertices = part.vertices @ Z_UP_TO_Y_UP.T
            scene.add_geometry(part, geom_name=name, node_name=name)
    # glTF "extras": the provenance travels with the file and trimesh reads it back as scene.metadata.
    scene.metadata = {
        "generator": f"structgen {__version__}",
        "up_axis": "y",
        "converted_from": "z-up lattice coordinates: (x, y, z) -> (x, z, -y)",
        "n_vertices": structure.n_vertices,
        "n_edges": structure.n_edges,
        "height": structure.height,
        "mesh_style": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(style).items()},
        "structure_metadata": structure.metadata,
    }
    return scene.export(file_type="glb")


def export_structure(structure: Structure, path: str | os.PathLike, style: MeshStyle | None = None) -> Path:
    """Write a mesh of ``structure`` to ``path`` in the format its suffix names (``.glb``, ``.obj``, ``.stl``, ``.ply``)."""
    path = Path(path)
    style = style or MeshStyle()
    suffix = path.suffix.lower()
    if suffix == ".glb":
        payload: bytes | str = _glb_bytes(structure, style)
    elif suffix in (".obj", ".stl", ".ply"):
        payload = structure_mesh(structure, style).export(file_type=suffix[1:])
    else:
        raise StructureError(
            f"{path}: unknown export format {path.suffix or '(no suffix)'!r}; use one of {', '.join(EXPORT_FORMATS)}"
        )
    return atomic_write(path, payload)
