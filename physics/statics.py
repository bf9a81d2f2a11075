"""Static frame analysis: the joint forces of a structure under its own weight, and what breaks, without simulating.

The model is the simulation's (``physics.bullet``) with time taken out:

- Every edge is an Euler-Bernoulli beam between its two vertices (six degrees of freedom per vertex), so the
  fixed sphere-cylinder joints become rigid beam-to-node connections. A cylinder's weight acts along its length
  (consistent fixed-end loads); a sphere's weight acts at its vertex. Stiffnesses are those of a solid cylinder of
  the cylinder radius; only their ratios matter, and only where the structure is statically indeterminate.
- The force a joint carries is the beam's end force at that vertex (for a column of four: 6, 5, 4, 3, 2 and 1 unit
  weights from the bottom joint up, the same as PyBullet reads once the structure is at rest).
- Vertices at the lowest level rest on the ground as pins (no moment, as a sphere on a plane). A support that would
  have to pull the structure down is released. A supported piece whose centre of mass lies outside the convex
  hull of its ground contacts tips over. The pins hold in every direction; with ``sliding_ground`` they hold only
  vertically (plus the least that stops the piece sliding or spinning), the other bound on the simulation's
  friction.
- Progressive failure: every joint whose force times ``config.statics_load_factor`` exceeds the break force breaks;
  the structure is solved again, and so on until nothing more breaks. A piece that no longer touches the ground
  (cut loose, or tipping) falls, and its joints count as broken: in the simulation, falling pieces hit the ground
  hard enough to break them (see the validation in ``benchmarks/structures.md``). A cylinder left on one joint hangs
  from it.

The prediction: broken joints, integrity, the height of what still stands, and Q; exact for statically determinate
structures, approximate where the load can take several paths or where the simulation's dynamics (the spawn
transient, impacts) decide.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu

from physics.config import PhysicsConfig
from physics.model import Bodies, InputError, place, read_structure
from physics.report import BrokenJoint, EveryJointFell, StabilityReport, height_of, integrity_of, quality

__all__ = [
    "StaticsResult",
    "bounding_loads",
    "check_collapse",
    "check_statics",
    "check_statics_with_loads",
    "joint_forces",
    "overload_ratio",
    "predict",
]

# Young's modulus of the beams (Pa); the solution for forces does not depend on it, only on stiffness ratios.
_E = 1.0e9
_G = _E / 2.6  # shear modulus of an isotropic material with Poisson's ratio 0.3
# Tiny rotational stiffness at ground pins keeps the stiffness matrix invertible for structures balanced on one or
# two contacts (their weight passes through the contacts, so these springs carry next to nothing).
_PIN_SPRING = 1e-9
# Pieces with up to this many degrees of freedom (200 vertices) are solved with dense matrices, larger ones sparse.
_DENSE_LIMIT = 1200


def _local_stiffness(length: float, radius: float) -> np.ndarray:
    """12 x 12 stiffness of a solid circular beam along local x (DOFs: u v w rx ry rz at each end)."""
    r = radius
    area, inertia = math.pi * r * r, math.pi * r**4 / 4
    ea, ei, gj, L = _E * area, _E * inertia, _G * 2 * inertia, length
    k = np.zeros((12, 12))

    def pair(i: int, j: int, value: float) -> None:
        k[i, j] = k[j, i] = value

    pair(0, 0, ea / L), pair(6, 6, ea / L), pair(0, 6, -ea / L)
    pair(3, 3, gj / L), pair(9, 9, gj / L), pair(3, 9, -gj / L)
    # Bending in the local xy plane (v with rotation about z) and xz plane (w with rotation about y, opposite sign).
    for v, rot, sign in ((1, 5, 1.0), (2, 4, -1.0)):
        pair(v, v, 12 * ei / L**3), pair(v + 6, v + 6, 12 * ei / L**3), pair(v, v + 6, -12 * ei / L**3)
        pair(v, rot, sign * 6 * ei / L**2), pair(v, rot + 6, sign * 6 * ei / L**2)
        pair(v + 6, rot, -sign * 6 * ei / L**2), pair(v + 6, rot + 6, -sign * 6 * ei / L**2)
        pair(rot, rot, 4 * ei / L), pair(rot + 6, rot + 6, 4 * ei / L), pair(rot, rot + 6, 2 * ei / L)
    return k


def _frames(directions: np.ndarray) -> np.ndarray:
    """(E, 3, 3) rotations whose first row is each beam's axis (any perpendicular pair will do: round sections)."""
    helper = np.where(np.abs(directions[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    second = np.cross(helper, directions)
    second /= np.linalg.norm(second, axis=1, keepdims=True)
    third = np.cross(directions, second)
    return np.stack([directions, second, third], axis=1)


@dataclass
class _Frame:
    """Element matrices and loads of every beam, computed once per structure."""

    stiffness: np.ndarray  # (E, 12, 12) global
    loads: np.ndarray  # (E, 12) equivalent nodal loads of the beam's own weight, global
    dofs: np.ndarray  # (E, 12) global degree-of-freedom numbers


def _frame(bodies: Bodies, config: PhysicsConfig) -> _Frame:
    edges = bodies.edges
    if not len(edges):
        return _Frame(np.zeros((0, 12, 12)), np.zeros((0, 12)), np.zeros((0, 12), dtype=np.int64))
    lengths = np.linalg.norm(bodies.sphere_positions[edges[:, 1]] - bodies.sphere_positions[edges[:, 0]], axis=1)
    keys, which = np.unique(np.round(lengths, 9), return_inverse=True)
    local = np.stack([_local_stiffness(L, config.statics_beam_radius) for L in keys])[which.ravel()]
    rotation = _frames(bodies.directions)
    transform = np.zeros((len(edges), 12, 12))
    for block in range(4):
        transform[:, 3 * block : 3 * block + 3, 3 * block : 3 * block + 3] = rotation
    stiffness = np.einsum("eji,ejk,ekl->eil", transform, local, transform, optimize=True)
    # A uniform load q along the beam is equivalent to q L / 2 at each end plus end moments +-(L^2 / 12) a x q.
    weight = np.array([0.0, 0.0, -config.cylinder_mass * config.gravity])
    moment = np.cross(bodies.directions, weight) * (lengths / 12)[:, None]
    loads = np.concatenate([np.tile(weight / 2, (len(edges), 1)), moment, np.tile(weight / 2, (len(edges), 1)), -moment], axis=1)
    base = 6 * edges
    dofs = np.concatenate([base[:, :1] + np.arange(6), base[:, 1:] + np.arange(6)], axis=1)
    return _Frame(stiffness, loads, dofs)


def _vertical_holds(contacts: np.ndarray, first_dofs: np.ndarray) -> np.ndarray:
    """Degrees of freedom that hold a piece on sliding ground: every contact's vertical, plus the two horizontal
    ones of the contact nearest the middle and one of the contact furthest from it (across the line between them),
    the least that stops the piece sliding or spinning without resisting any spreading of its feet."""
    middle = int(np.argmin(np.abs(contacts - contacts.mean(axis=0)).sum(axis=1)))
    apart = np.abs(contacts - contacts[middle])
    far = int(np.argmax(apart.sum(axis=1)))
    held = [first_dofs + 2, first_dofs[middle] + np.arange(2)]
    if far != middle:
        held.append(np.array([first_dofs[far] + (1 if apart[far, 0] >= apart[far, 1] else 0)]))
    return np.unique(np.concatenate(held))


def _inside_hull(point: np.ndarray, contacts: np.ndarray, tolerance: float, margin: float = 0.0) -> bool:
    """Whether a 2D point lies in the convex hull of 2D contact points (a point, a segment or a polygon), at least
    ``margin`` inside a polygon's edges (a point or segment of contacts has no inside: only balance counts)."""
    if len(contacts) >= 3:
        from scipy.spatial import ConvexHull, QhullError

        try:
            hull = ConvexHull(contacts)
            return bool((hull.equations[:, :2] @ point + hull.equations[:, 2] <= tolerance - margin).all())
        except QhullError:  # all contacts on one line: treat them as the segment they span
            pass
    centre = contacts.mean(axis=0)
    spread = contacts - centre
    extent = np.abs(spread).max()
    if extent <= tolerance:  # a single contact: the centre of mass must be right above it
        return bool(np.linalg.norm(point - centre) <= tolerance)
    direction = spread[np.argmax(np.linalg.norm(spread, axis=1))]
    direction = direction / np.linalg.norm(direction)
    along = spread @ direction
    offset = point - centre
    t = offset @ direction
    on_line = np.linalg.norm(offset - t * direction) <= tolerance
    return bool(on_line and along.min() - tolerance <= t <= along.max() + tolerance)


@dataclass(frozen=True)
class StaticsResult:
    """Forces and failures predicted by the static analysis."""

    first_forces: np.ndarray  # (J,) joint forces of the intact structure, N (NaN where no static answer: falls)
    first_loads: np.ndarray  # (J,) the same with the load factors applied, as compared with the break force
    broken: np.ndarray  # (J,) bool
    broken_round: np.ndarray  # (J,) int: the failure round in which a joint broke (-1: intact)
    break_loads: np.ndarray  # (J,) the load (factors applied) that broke each overloaded joint (NaN: intact or fell)
    fell: np.ndarray  # (J,) bool: broke because its piece fell (lost support or tipped), not overloaded
    standing: np.ndarray  # (V,) bool: the vertex is still held up at the end
    rounds: int


def _solve_piece(
    frame: _Frame,
    members: np.ndarray,
    hanging: np.ndarray,
    nodes: np.ndarray,
    supports: np.ndarray,
    bodies: Bodies,
    config: PhysicsConfig,
    sliding: bool = False,
) -> tuple[np.ndarray | None, np.ndarray]:
    """Solve one connected piece; ``hanging`` lists the vertex each one-jointed cylinder hangs from. Returns (member
    end forces (M, 12) or None if the piece falls, the contacts still supporting it)."""
    if not len(members):  # a lone vertex on the ground holds itself and whatever hangs from it
        return np.zeros((0, 12)), supports
    g = config.gravity
    index = np.full(len(bodies.sphere_positions), -1)
    index[nodes] = np.arange(len(nodes))
    n = 6 * len(nodes)
    force = np.zeros(n)
    force[6 * index[nodes] + 2] -= config.sphere_mass * g
    local_dofs = 6 * index[frame.dofs[members] // 6] + frame.dofs[members] % 6
    np.add.at(force, local_dofs.ravel(), frame.loads[members].ravel())
    np.add.at(force, 6 * index[hanging] + 2, -config.cylinder_mass * g)  # a one-jointed cylinder hangs from its vertex
    mass = config.sphere_mass * len(nodes) + config.cylinder_mass * (len(members) + len(hanging))
    centre = (
        config.sphere_mass * bodies.sphere_positions[nodes].sum(axis=0)
        + config.cylinder_mass * bodies.cylinder_positions[members].sum(axis=0)
        + config.cylinder_mass * bodies.sphere_positions[hanging].sum(axis=0)
    ) / mass
    supports = np.array(supports)
    tolerance = 1e-6 * config.spacing
    element = frame.stiffness[members]
    # Each vertex's own weight and hanging cylinders, which its ground contact carries besides the members' forces.
    carried = np.zeros(len(nodes))
    np.add.at(carried, index[hanging], config.cylinder_mass * g)
    carried += config.sphere_mass * g
    while len(supports):
        if not _inside_hull(centre[:2], bodies.sphere_positions[supports, :2], tolerance, config.statics_tip_margin):
            return None, supports  # tips over
        # Number the free degrees of freedom (all but the held translations of the supports) and assemble only their block.
        position = np.full(n, -1)
        if sliding:
            fixed = _vertical_holds(bodies.sphere_positions[supports, :2], 6 * index[supports])
        else:
            fixed = (6 * index[supports][:, None] + np.arange(3)).ravel()
        free = np.ones(n, dtype=bool)
        free[fixed] = False
        position[free] = np.arange(free.sum())
        nf = int(free.sum())
        rows, cols = position[local_dofs][:, :, None], position[local_dofs][:, None, :]
        keep = (rows >= 0) & (cols >= 0)
        rows, cols, values = np.broadcast_to(rows, keep.shape)[keep], np.broadcast_to(cols, keep.shape)[keep], element[keep]
        spring_at = position[(6 * index[supports][:, None] + np.arange(3, 6)).ravel()]
        scale = float(np.abs(values[rows == cols]).max())
        try:
            if nf <= _DENSE_LIMIT:  # small pieces: one dense factorisation beats sparse bookkeeping by far
                system = np.bincount(rows * nf + cols, weights=values, minlength=nf * nf).reshape(nf, nf)
                system[spring_at, spring_at] += _PIN_SPRING * scale
                # Held by pins and springs, the stiffness is symmetric positive definite: Cholesky, half of LU's work.
                solution = cho_solve(cho_factor(system), force[free])
            else:
                system = coo_matrix((values, (rows, cols)), shape=(nf, nf)).tocsc()
                system = system + coo_matrix(
                    (np.full(len(spring_at), _PIN_SPRING * scale), (spring_at, spring_at)), shape=(nf, nf)
                )
                # Symmetric positive definite too: no pivoting and an ordering for symmetric matrices factor it in
                # about half the time of SuperLU's default (same forces to 1e-11 N; benchmarks/structures.md).
                factors = splu(system.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
                solution = factors.solve(force[free])
        except (RuntimeError, np.linalg.LinAlgError, ValueError):  # singular: nothing holds it
            return None, supports
        displacement = np.zeros(n)
        displacement[free] = solution
        ends = np.einsum("eij,ej->ei", element, displacement[local_dofs]) - frame.loads[members]
        # A contact carries its vertex's load plus what the vertex passes on to its members; it can only push.
        vertical = carried.copy()
        np.add.at(vertical, index[frame.dofs[members, 0] // 6], ends[:, 2])
        np.add.at(vertical, index[frame.dofs[members, 6] // 6], ends[:, 8])
        pulling = vertical[index[supports]] < -1e-9 * mass * g
        if not pulling.any():
            return ends, supports
        supports = supports[~pulling]  # the ground cannot pull: let go of those contacts and solve again
    return None, supports


def joint_forces(structure: Any, config: PhysicsConfig | None = None) -> np.ndarray:
    """``(J,)`` static force on each joint (N) of the intact structure resting on the ground, in the joint order of
    :mod:`physics.model`; NaN for joints of pieces that could not stand (tipping, no support)."""
    return predict(structure, config, rounds=0).first_forces


def _groups(keys: np.ndarray, count: int) -> list[np.ndarray]:
    """Indices of ``keys`` grouped by value ``0 .. count - 1``, each group in ascending order."""
    order = np.argsort(keys, kind="stable")
    return np.split(order, np.cumsum(np.bincount(keys, minlength=count))[:-1])


_blas = None


def _one_blas_thread():
    """A context in which BLAS uses one thread: these systems are small, and threads waiting on each other (or on a
    busy second core) made one factorisation a hundred times slower in measurements."""
    global _blas
    if _blas is None:
        from threadpoolctl import ThreadpoolController

        _blas = ThreadpoolController().select(user_api="blas")  # discovering the libraries once costs ~2 ms
    return _blas.limit(limits=1)


def predict(
    structure: Any, config: PhysicsConfig | None = None, *, rounds: int | None = None, sliding_ground: bool = False
) -> StaticsResult:
    """Static forces of the intact structure, then progressive failure (at most ``rounds`` rounds; None: until
    nothing more breaks).

    ``sliding_ground``: the ground holds the contacts up but not sideways (only as much as stops the whole piece
    sliding or spinning), as on ice. The default holds them in every direction, which is what the load factors were
    fitted with; a wide structure whose feet push outwards loads its lowest joints more in the simulation than
    that predicts, and its sliding-ground forces bound them from the other side."""
    config = config or PhysicsConfig()
    return _predict(_placed(structure, config), config, rounds, sliding_ground)


def bounding_loads(structure: Any, config: PhysicsConfig | None = None) -> np.ndarray:
    """``(J,)`` each joint's static load (load factors applied) on the intact structure, the larger of held and
    sliding ground; NaN for joints of pieces that could not stand.

    The simulation's ground lies between the two: friction holds feet that push outwards only so far. A search
    judged on held ground alone ends on designs whose spreading feet break their joints in the simulation
    (benchmarks/structures.md, "Tall structures"); the larger of the two is the safer guide."""
    config = config or PhysicsConfig()
    bodies = _placed(structure, config)
    held = _predict(bodies, config, rounds=0).first_loads
    return np.fmax(held, _predict(bodies, config, rounds=0, sliding_ground=True).first_loads)


def memory_estimate(n_vertices: int) -> float:
    """Bytes a static solve of ``n_vertices`` may take at its peak: about 100 KB a vertex, growing with size as the
    sparse factorisation fills in (measured: 255 MB for 4,649 vertices, 377 MB for 4,750 in three levels)."""
    return 100e3 * n_vertices * (1 + n_vertices / 20_000)


def _placed(structure: Any, config: PhysicsConfig) -> Bodies:
    vertices, edges = read_structure(structure)
    # The size caps exist for the simulation's first step, which grows with the square of the joint count; a sparse
    # static solve has no such limit, only its memory.
    needed = memory_estimate(len(vertices)) / (1 << 20)
    if needed > config.max_memory_mb:
        raise InputError(
            f"structure has {len(vertices):,} vertices: its static solve needs about {needed:,.0f} MiB, more than "
            f"max_memory_mb = {config.max_memory_mb:,.0f} (raise that setting to allow it)"
        )
    return place(vertices, edges, config, enforce_caps=False)


def _predict(bodies: Bodies, config: PhysicsConfig, rounds: int | None, sliding_ground: bool = False) -> StaticsResult:
    with _one_blas_thread():
        return _progressive_failure(bodies, config, rounds, sliding_ground)


def _progressive_failure(bodies: Bodies, config: PhysicsConfig, rounds: int | None, sliding_ground: bool) -> StaticsResult:
    edges = bodies.edges
    frame = _frame(bodies, config)
    n_vertices, n_edges = len(bodies.sphere_positions), len(edges)
    ground = np.isclose(bodies.sphere_positions[:, 2], config.sphere_radius, atol=1e-9)
    broken = np.zeros(2 * n_edges, dtype=bool)
    broken_round = np.full(2 * n_edges, -1)
    break_loads = np.full(2 * n_edges, np.nan)
    fell = np.zeros(2 * n_edges, dtype=bool)
    first_forces = np.full(2 * n_edges, np.nan)
    first_loads = np.full(2 * n_edges, np.nan)
    standing = np.zeros(n_vertices, dtype=bool)
    solved: dict[tuple, np.ndarray | None] = {}
    weight_of_cylinder = config.cylinder_mass * config.gravity
    round_number = 0
    while True:
        members_all = np.flatnonzero(~broken[0::2] & ~broken[1::2])
        graph = coo_matrix(
            (np.ones(len(members_all)), (edges[members_all, 0], edges[members_all, 1])), shape=(n_vertices, n_vertices)
        )
        n_pieces, label = connected_components(graph, directed=False)
        # Cylinders left on one joint hang from the vertex at their intact end.
        one_sided = np.flatnonzero(broken[0::2] ^ broken[1::2])
        lost_first = broken[2 * one_sided].astype(np.int64)
        held_joint = 2 * one_sided + lost_first
        held_node = edges[one_sided, lost_first]
        member_label, hang_label = label[edges[members_all, 0]], label[held_node]
        busy = np.zeros(n_pieces, dtype=bool)
        busy[member_label] = busy[hang_label] = True
        # Lone vertices with nothing attached stand where they touch the ground and otherwise fall without a joint.
        standing[:] = ground & ~busy[label]
        node_groups, member_groups, hang_groups = (_groups(keys, n_pieces) for keys in (label, member_label, hang_label))
        forces = np.full(2 * n_edges, np.nan)
        loads = np.full(2 * n_edges, np.nan)  # forces with the dynamic factors applied, compared with the limit
        falling_joints: list[np.ndarray] = []
        for piece in np.flatnonzero(busy):
            nodes, members = node_groups[piece], members_all[member_groups[piece]]
            hanging = hang_groups[piece]
            supports = nodes[ground[nodes]]
            # A piece no break touched since the last round has the same answer.
            key = (nodes.tobytes(), members.tobytes(), one_sided[hanging].tobytes())
            if key not in solved:
                found = len(supports) > 0
                solved[key] = (
                    _solve_piece(frame, members, held_node[hanging], nodes, supports, bodies, config, sliding_ground)[0]
                    if found
                    else None
                )
            ends = solved[key]
            if ends is None:
                falling_joints += [2 * members, 2 * members + 1, held_joint[hanging]]
                continue
            standing[nodes] = True
            forces[2 * members] = np.linalg.norm(ends[:, 0:3], axis=1)
            forces[2 * members + 1] = np.linalg.norm(ends[:, 6:9], axis=1)
            axis = bodies.directions[members]
            for end, start in ((0, 0), (1, 6)):
                along = np.abs(np.einsum("ij,ij->i", ends[:, start : start + 3], axis))
                across = np.sqrt(np.maximum(forces[2 * members + end] ** 2 - along**2, 0.0))
                loads[2 * members + end] = np.hypot(config.statics_load_factor * along, config.statics_shear_factor * across)
            forces[held_joint[hanging]] = loads[held_joint[hanging]] = weight_of_cylinder
        if round_number == 0:
            first_forces, first_loads = forces.copy(), loads.copy()
        overloaded = ~broken & np.nan_to_num(loads > config.break_force)
        falling = np.zeros_like(broken)
        if falling_joints:
            falling[np.concatenate(falling_joints)] = True
        newly = overloaded | (falling & ~broken)
        if rounds is not None and round_number >= rounds:
            break
        if not newly.any():
            break
        fell |= newly & ~overloaded
        broken_round[newly] = round_number
        break_loads[overloaded] = loads[overloaded]
        broken |= newly
        round_number += 1
    return StaticsResult(first_forces, first_loads, broken, broken_round, break_loads, fell, standing, round_number)


def check_statics(structure: Any, config: PhysicsConfig | None = None) -> StabilityReport:
    """A :class:`StabilityReport` predicted by the static analysis instead of a simulation (``method="statics"``).

    Broken joints carry the failure round in ``time`` (0 for joints overloaded in the intact structure) and in
    ``force`` the load that broke them, load factors applied, as compared with the break force (for joints that
    fell with their piece, the intact structure's static force, within the limit). Final positions are the initial
    ones for vertices still held up and on the ground for the rest.
    """
    return check_statics_with_loads(structure, config)[0]


def check_statics_with_loads(structure: Any, config: PhysicsConfig | None = None) -> tuple[StabilityReport, np.ndarray]:
    """:func:`check_statics`'s report and, from the same solve, the intact structure's joint loads as compared with
    the break force (``StaticsResult.first_loads``; NaN where a piece has no static answer)."""
    config = config or PhysicsConfig()
    started_wall, started_cpu = time.perf_counter(), time.process_time()
    bodies = _placed(structure, config)
    edges = bodies.edges
    result = _predict(bodies, config, None)
    n_joints = bodies.n_joints
    forces = np.where(np.isnan(result.first_forces), 0.0, result.first_forces)
    broken = tuple(
        BrokenJoint(
            joint=int(j),
            edge=int(j // 2),
            vertex=int(edges[j // 2, j % 2]),
            time=float(result.broken_round[j]),
            force=float(forces[j] if result.fell[j] else result.break_loads[j]),
            torque=0.0,
            fell=bool(result.fell[j]),
        )
        for j in np.flatnonzero(result.broken)
    )
    final = bodies.sphere_positions.copy()
    final[~result.standing, 2] = config.sphere_radius
    integrity = integrity_of(len(broken), n_joints)
    height = height_of(final[:, 2], config)
    standing_edges = result.standing[edges[:, 0]] & result.standing[edges[:, 1]] if len(edges) else np.zeros(0, bool)
    ends = bodies.cylinder_ends(bodies.cylinder_positions, bodies.cylinder_orientations)
    ends[~standing_edges, :, 2] = config.cylinder_radius
    report = StabilityReport(
        integrity=integrity,
        height=height,
        complexity=len(final),
        score=quality(integrity, height, len(final), config),
        n_joints=n_joints,
        broken_joints=broken,
        joint_forces=np.where(result.broken, np.nan, result.first_forces),
        peak_force=float(np.nanmax(result.first_forces)) if n_joints and not np.isnan(result.first_forces).all() else 0.0,
        initial_positions=bodies.sphere_positions,
        final_positions=final,
        final_edge_ends=ends,
        edges=edges,
        sim_time=0.0,
        steps=result.rounds,
        settled=True,
        wall_time=time.perf_counter() - started_wall,
        cpu_time=time.process_time() - started_cpu,
        config=config,
        method="statics",
    )
    return report, result.first_loads


def overload_ratio(structure: Any, config: PhysicsConfig | None = None) -> float:
    """How many times over the joints crossing the worst horizontal cut are loaded, at the least (no solve: linear
    in the structure's size).

    Cut the structure between two lattice levels. Everything above the cut, and the cylinders crossing it, rest on
    the crossing cylinders' lower joints, and a joint's force is at least its vertical part, so those joints carry
    on average at least (weight above + crossing cylinders' weight) / (number crossing). The ratio of that to the
    break force, at the worst cut, is a bound: above 1 no static equilibrium holds every joint, and far above it (a
    random network's block of a thousand vertices, 3 to 130) the simulation crushes the structure from the bottom
    up and keeps almost none of its joints. Infinite for a part above a cut that nothing joins to the ground.
    """
    config = config or PhysicsConfig()
    bodies = _placed(structure, config)
    edges = bodies.edges
    if not len(edges):
        return 0.0
    level = np.rint((bodies.sphere_positions[:, 2] - config.sphere_radius) / config.spacing).astype(np.int64)
    low = np.minimum(level[edges[:, 0]], level[edges[:, 1]])
    high = np.maximum(level[edges[:, 0]], level[edges[:, 1]])
    top = int(level.max())
    # Per cut k (between levels k and k + 1): spheres and whole cylinders above it, and the cylinders crossing it.
    spheres_above = len(level) - np.cumsum(np.bincount(level, minlength=top + 1))[:top]
    cylinders_above = len(edges) - np.cumsum(np.bincount(low, minlength=top + 1))[:top]
    # On the lattice an edge spans at most one level, so the edges crossing cut k are those from level k to k + 1.
    crossing = np.bincount(low[high > low], minlength=top + 1)[:top]
    if not top:
        return 0.0
    load = (spheres_above * config.sphere_mass + (cylinders_above + crossing) * config.cylinder_mass) * config.gravity
    with np.errstate(divide="ignore"):
        ratios = np.where(crossing > 0, load / (config.break_force * np.maximum(crossing, 1)), np.inf)
    return float(ratios.max())


def check_collapse(structure: Any, config: PhysicsConfig | None = None) -> StabilityReport:
    """The report of a structure that falls apart entirely (``method="collapse"``): every joint broken, every vertex on
    the ground, I = H = Q = 0. What a screen reports for structures whose :func:`overload_ratio` is far above 1,
    without a solve or a simulation."""
    config = config or PhysicsConfig()
    started_wall, started_cpu = time.perf_counter(), time.process_time()
    bodies = _placed(structure, config)
    edges = bodies.edges
    final = bodies.sphere_positions.copy()
    final[:, 2] = config.sphere_radius
    ends = bodies.cylinder_ends(bodies.cylinder_positions, bodies.cylinder_orientations)
    ends[:, :, 2] = config.cylinder_radius
    broken = EveryJointFell(edges)
    integrity = integrity_of(len(broken), bodies.n_joints)
    return StabilityReport(
        integrity=integrity,
        height=0.0,
        complexity=len(final),
        score=quality(integrity, 0.0, len(final), config),
        n_joints=bodies.n_joints,
        broken_joints=broken,
        joint_forces=np.full(bodies.n_joints, np.nan),
        peak_force=0.0,
        initial_positions=bodies.sphere_positions,
        final_positions=final,
        final_edge_ends=ends,
        edges=edges,
        sim_time=0.0,
        steps=0,
        settled=True,
        wall_time=time.perf_counter() - started_wall,
        cpu_time=time.process_time() - started_cpu,
        config=config,
        method="collapse",
    )
