"""From vertex and edge arrays to the rigid bodies and joints that get simulated (pure numpy, no PyBullet).

Every vertex becomes a sphere, every edge a cylinder running from one sphere's surface to the other's, and each
cylinder is held to each of its two spheres by a fixed joint: joint ``2 * e`` joins edge ``e`` to vertex
``edges[e, 0]``, joint ``2 * e + 1`` to vertex ``edges[e, 1]``. The structure is placed so that its lowest spheres
rest on the ground (z = 0), keeping its x and y.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from physics.config import PhysicsConfig

__all__ = ["Bodies", "InputError", "read_structure", "place"]


class InputError(ValueError):
    """The structure given to a check is malformed or too large; the message names the problem."""


def read_structure(structure: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices (V, 3) float64, edges (E, 2) int64)`` from anything that offers them.

    Accepted: an object with ``vertices`` and ``edges`` attributes (a ``structgen.Structure``), a mapping with those
    keys, or a ``(vertices, edges)`` pair. Coordinates are in lattice units and need not be integers.
    """
    if isinstance(structure, Mapping):
        try:
            vertices, edges = structure["vertices"], structure["edges"]
        except KeyError as err:
            raise InputError(f"structure mapping has no {err.args[0]!r} entry") from None
    elif hasattr(structure, "vertices") and hasattr(structure, "edges"):
        vertices, edges = structure.vertices, structure.edges
    elif isinstance(structure, (tuple, list)) and len(structure) == 2:
        vertices, edges = structure
    else:
        raise InputError(
            f"cannot read a structure from {type(structure).__name__}: give an object with vertices and edges, "
            "a mapping with those keys, or a (vertices, edges) pair"
        )
    try:
        v = np.asarray(vertices, dtype=np.float64)
        e = np.asarray(edges)
    except (TypeError, ValueError) as err:
        raise InputError(f"structure arrays are not numeric: {err}") from None
    if v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise InputError(f"vertices must have shape (V, 3) with V >= 1, got {v.shape}")
    if not np.isfinite(v).all():
        raise InputError(f"vertices[{int(np.argwhere(~np.isfinite(v))[0, 0])}] is not finite")
    if e.size == 0:
        e = np.zeros((0, 2), dtype=np.int64)
    if e.ndim != 2 or e.shape[1] != 2:
        raise InputError(f"edges must have shape (E, 2), got {e.shape}")
    if e.dtype.kind not in "iu":
        if e.dtype.kind != "f" or not np.array_equal(e, np.round(e)):
            raise InputError(f"edges must hold integer vertex indices, got dtype {e.dtype}")
    e = e.astype(np.int64)
    bad = (e < 0) | (e >= len(v))
    if bad.any():
        i = int(np.argwhere(bad)[0, 0])
        raise InputError(f"edges[{i}] = {e[i].tolist()}: vertex index out of range (0..{len(v) - 1})")
    loops = e[:, 0] == e[:, 1]
    if loops.any():
        i = int(np.argmax(loops))
        raise InputError(f"edges[{i}] = {e[i].tolist()} joins a vertex to itself")
    return v, e


@dataclass(frozen=True)
class Bodies:
    """World placement (metres, z up) of a structure's spheres and cylinders."""

    sphere_positions: np.ndarray  # (V, 3)
    cylinder_positions: np.ndarray  # (E, 3) centres
    cylinder_orientations: np.ndarray  # (E, 4) quaternions (x, y, z, w) turning +z onto the edge direction
    cylinder_lengths: np.ndarray  # (E,)
    directions: np.ndarray  # (E, 3) unit vectors from edges[:, 0] to edges[:, 1]
    edges: np.ndarray  # (E, 2)

    @property
    def n_joints(self) -> int:
        return 2 * len(self.edges)

    def cylinder_ends(self, centres: np.ndarray, orientations: np.ndarray) -> np.ndarray:
        """``(E, 2, 3)`` end points of cylinders at the given poses (to draw where edges ended up)."""
        axes = _rotate_z(orientations)
        half = (self.cylinder_lengths / 2)[:, None] * axes
        return np.stack([centres - half, centres + half], axis=1)


def _rotate_z(quaternions: np.ndarray) -> np.ndarray:
    """The +z axis rotated by each quaternion (x, y, z, w)."""
    x, y, z, w = quaternions.T
    return np.stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)], axis=1)


def _quaternions_z_to(directions: np.ndarray) -> np.ndarray:
    """Shortest-arc quaternions (x, y, z, w) turning +z onto each unit direction."""
    axis = np.stack([-directions[:, 1], directions[:, 0], np.zeros(len(directions))], axis=1)  # z x d
    half = np.arctan2(np.linalg.norm(axis, axis=1), directions[:, 2]) / 2
    norm = np.linalg.norm(axis, axis=1)
    unit = np.divide(axis, norm[:, None], out=np.zeros_like(axis), where=norm[:, None] > 1e-12)
    unit[norm <= 1e-12] = [1.0, 0.0, 0.0]  # straight up (angle 0) or straight down (angle pi about x)
    return np.concatenate([unit * np.sin(half)[:, None], np.cos(half)[:, None]], axis=1)


def place(vertices: np.ndarray, edges: np.ndarray, config: PhysicsConfig, *, enforce_caps: bool = True) -> Bodies:
    """Bodies of a structure resting on the ground; raises InputError if an edge is too short or, with
    ``enforce_caps`` (the simulation's limits), if it is too large."""
    # The caps keep a simulation's first step affordable; the static analysis has none, so the hint points there.
    remedy = (
        "judge it with the static analysis instead (check --statics: milliseconds, no cap), raise the cap if the "
        "simulation is worth its time (--set {name}=N), or grow a smaller structure (grow --max-vertices N)"
    )
    over = config.room_for(len(vertices), len(edges)) if enforce_caps else {}
    if "max_vertices" in over:
        raise InputError(
            f"structure has {len(vertices)} vertices, more than max_vertices = {config.max_vertices}; "
            + remedy.format(name="max_vertices")
        )
    if "max_joints" in over:
        raise InputError(
            f"structure has {len(edges)} edges ({2 * len(edges)} joints), more than max_joints = {config.max_joints}; "
            + remedy.format(name="max_joints")
        )
    spheres = vertices * config.spacing
    spheres = spheres + np.array([0.0, 0.0, config.sphere_radius - spheres[:, 2].min()])
    start, end = spheres[edges[:, 0]], spheres[edges[:, 1]]
    span = end - start
    distance = np.linalg.norm(span, axis=1)
    lengths = distance - 2 * config.sphere_radius
    if len(edges) and lengths.min() <= 1e-6:
        i = int(np.argmin(lengths))
        raise InputError(
            f"edges[{i}] = {edges[i].tolist()} is {distance[i]:.3g} m long: too short for two spheres of radius "
            f"{config.sphere_radius} and a cylinder between them"
        )
    directions = span / np.where(distance > 0, distance, 1.0)[:, None]
    return Bodies(
        sphere_positions=spheres,
        cylinder_positions=(start + end) / 2,
        cylinder_orientations=_quaternions_z_to(directions),
        cylinder_lengths=lengths,
        directions=directions,
        edges=edges,
    )
