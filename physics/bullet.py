"""The simulation in headless PyBullet: breakable fixed joints between sphere and cylinder bodies.

Facts this module relies on (measured on pybullet 3.2.7, and pinned by tests):

- Each sphere and each cylinder is its own base-only multibody; ``getConstraintState`` then reports the force (first
  three rows, N) and torque (last three, N m) a fixed constraint applied in the last step. Bodies made with maximal
  coordinates report nothing, so they are not used.
- Bodies joined to each other must not collide with each other, or contacts carry part of the load and the joint
  forces read wrong: structure bodies collide with the ground only (collision group 1 hits mask 2, the ground).
- PyBullet cannot break a joint by itself (its breaking threshold is not exposed; a force limit makes joints slide),
  so every joint is polled after every step and removed once its load exceeds the limit.
- Spheres get a little rolling and spinning friction, or debris rolls forever and never settles.
- One client per process. Its world is emptied before every structure (every constraint and body removed; collision
  shapes are made once and kept) rather than reset: the same commands then give bit-for-bit the result a fresh world
  gives (pinned by a test), and the constraint solver keeps its buffers. A fresh world's first step costs time
  growing with the square of the joint count (Bullet grows its Jacobian buffers one row at a time: 2.8 s at 2,354
  joints, minutes at 10,000); an emptied world pays that once per process for the largest structure so far.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from physics._quiet import import_pybullet, silenced
from physics.config import PhysicsConfig
from physics.model import Bodies

__all__ = ["Outcome", "simulate"]

_GROUND_GROUP, _STRUCTURE_GROUP = 2, 1


class _Client:
    """A DIRECT PyBullet client owned by one process."""

    def __init__(self) -> None:
        self.pb = import_pybullet()
        with silenced():
            self.id = self.pb.connect(self.pb.DIRECT)
        self.pid = os.getpid()
        # Collision shapes by kind and size, made once: PyBullet will not remove a shape a removed body used.
        self.shapes: dict[tuple, int] = {}

    def empty_world(self) -> None:
        """Remove everything the last structure put into the world, keeping the solver's buffers."""
        pb, cid = self.pb, self.id
        for index in reversed(range(pb.getNumConstraints(physicsClientId=cid))):
            pb.removeConstraint(pb.getConstraintUniqueId(index, physicsClientId=cid), physicsClientId=cid)
        for index in reversed(range(pb.getNumBodies(physicsClientId=cid))):
            pb.removeBody(pb.getBodyUniqueId(index, physicsClientId=cid), physicsClientId=cid)

    def shape(self, kind: int, **size: float) -> int:
        # Sizes rounded in the key, so float noise in a length does not make another shape.
        key = (kind, *sorted((name, round(value, 9)) for name, value in size.items()))
        if key not in self.shapes:
            self.shapes[key] = self.pb.createCollisionShape(kind, physicsClientId=self.id, **size)
        return self.shapes[key]


_client: _Client | None = None


def _this_process_client() -> _Client:
    # A client cannot be shared with a forked child: each process connects its own.
    global _client
    if _client is None or _client.pid != os.getpid():
        _client = _Client()
    return _client


@dataclass(frozen=True)
class Outcome:
    """Raw result of one simulation."""

    broken: tuple[tuple[int, float, float, float], ...]  # (joint, time, force, torque)
    joint_forces: np.ndarray  # (J,) force on each joint in the last step, N; NaN where broken
    peak_force: float  # largest joint force seen in any step, N
    peak_forces: np.ndarray  # (J,) largest force each joint carried in any step, N (a broken one's includes its last)
    final_positions: np.ndarray  # (V, 3)
    cylinder_positions: np.ndarray  # (E, 3)
    cylinder_orientations: np.ndarray  # (E, 4)
    sim_time: float
    steps: int
    settled: bool
    exploded: bool
    final_speeds: np.ndarray  # (V,) each vertex's speed at the last check, m/s


def simulate(bodies: Bodies, config: PhysicsConfig) -> Outcome:
    """Build the bodies in this process's client, apply gravity, and run until settled or at the horizon."""
    client = _this_process_client()
    with silenced():
        handles = _build(client, bodies, config)
        return _run(client, bodies, handles, config)


def _build(client: _Client, bodies: Bodies, config: PhysicsConfig) -> tuple[list[int], list[int], list[int]]:
    pb, cid = client.pb, client.id
    client.empty_world()
    pb.setGravity(0, 0, -config.gravity, physicsClientId=cid)
    pb.setPhysicsEngineParameter(
        fixedTimeStep=config.timestep,
        numSolverIterations=config.solver_iterations,
        solverResidualThreshold=config.solver_residual,
        numSubSteps=0,
        physicsClientId=cid,
    )
    ground = pb.createMultiBody(0, client.shape(pb.GEOM_PLANE), physicsClientId=cid)
    pb.setCollisionFilterGroupMask(ground, -1, _GROUND_GROUP, 0xFFFF, physicsClientId=cid)
    pb.changeDynamics(ground, -1, lateralFriction=config.friction, physicsClientId=cid)

    ball = client.shape(pb.GEOM_SPHERE, radius=config.sphere_radius)
    spheres = []
    for position in bodies.sphere_positions.tolist():
        body = pb.createMultiBody(config.sphere_mass, ball, -1, position, physicsClientId=cid)
        pb.setCollisionFilterGroupMask(body, -1, _STRUCTURE_GROUP, _GROUND_GROUP, physicsClientId=cid)
        pb.changeDynamics(
            body,
            -1,
            lateralFriction=config.friction,
            rollingFriction=config.rolling_friction,
            spinningFriction=config.spinning_friction,
            physicsClientId=cid,
        )
        spheres.append(body)

    cylinders, joints = [], []
    radius = config.sphere_radius
    for (a, b), centre, orientation, length, direction in zip(
        bodies.edges.tolist(),
        bodies.cylinder_positions.tolist(),
        bodies.cylinder_orientations.tolist(),
        bodies.cylinder_lengths.tolist(),
        bodies.directions.tolist(),
    ):
        rod = client.shape(pb.GEOM_CYLINDER, radius=config.cylinder_radius, height=length)  # three lengths on a lattice
        body = pb.createMultiBody(config.cylinder_mass, rod, -1, centre, orientation, physicsClientId=cid)
        pb.setCollisionFilterGroupMask(body, -1, _STRUCTURE_GROUP, _GROUND_GROUP, physicsClientId=cid)
        pb.changeDynamics(body, -1, lateralFriction=config.friction, physicsClientId=cid)
        cylinders.append(body)
        # Joint frames match the bodies' current poses, so nothing snaps when the simulation starts: the frame sits
        # on the sphere's surface where the cylinder touches it, oriented like the world (sphere side) and undoing
        # the cylinder's rotation (cylinder side).
        inverse = [-orientation[0], -orientation[1], -orientation[2], orientation[3]]
        for vertex, sign in ((a, 1.0), (b, -1.0)):
            joints.append(
                pb.createConstraint(
                    spheres[vertex],
                    -1,
                    body,
                    -1,
                    pb.JOINT_FIXED,
                    [0, 0, 0],
                    parentFramePosition=[sign * radius * d for d in direction],
                    childFramePosition=[0, 0, -sign * length / 2],
                    parentFrameOrientation=[0, 0, 0, 1],
                    childFrameOrientation=inverse,
                    physicsClientId=cid,
                )
            )
    return spheres, cylinders, joints


def _run(client: _Client, bodies: Bodies, handles: tuple[list[int], list[int], list[int]], config: PhysicsConfig) -> Outcome:
    pb, cid = client.pb, client.id
    spheres, cylinders, joints = handles
    step, read_joint, remove = pb.stepSimulation, pb.getConstraintState, pb.removeConstraint
    position_of, velocity_of = pb.getBasePositionAndOrientation, pb.getBaseVelocity
    dt = config.timestep
    n_steps = max(1, round(config.horizon / dt))
    check_every = max(1, round(config.check_interval / dt))
    quiet_needed = math.ceil(config.settle_window / (check_every * dt) - 1e-9)
    force_limit, torque_limit = config.break_force, config.break_torque
    # Comparing squared loads saves a square root per joint per step.
    force_limit_sq = force_limit * force_limit
    torque_limit_sq = torque_limit * torque_limit if math.isfinite(torque_limit) else math.inf
    everything = spheres + cylinders
    start = np.concatenate([bodies.sphere_positions, bodies.cylinder_positions]) if cylinders else bodies.sphere_positions

    alive = list(enumerate(joints))
    broken: list[tuple[int, float, float, float]] = []
    # Each joint's own peak: where a structure is loaded in its first moments, not only how much at the worst.
    joint_peak_sq = [0.0] * len(joints)
    quiet_checks, settled, exploded = 0, False, False
    steps_done = 0
    sphere_speeds = np.zeros(len(spheres))
    for n in range(1, n_steps + 1):
        step(physicsClientId=cid)
        steps_done = n
        survivors = []
        for index, handle in alive:
            fx, fy, fz, tx, ty, tz = read_joint(handle, physicsClientId=cid)
            force_sq = fx * fx + fy * fy + fz * fz
            torque_sq = tx * tx + ty * ty + tz * tz
            if force_sq > joint_peak_sq[index]:
                joint_peak_sq[index] = force_sq
            if force_sq > force_limit_sq or torque_sq > torque_limit_sq:
                remove(handle, physicsClientId=cid)
                broken.append((index, n * dt, math.sqrt(force_sq), math.sqrt(torque_sq)))
            else:
                survivors.append((index, handle))
        alive = survivors
        if n % check_every and n != n_steps:
            continue
        # Every check_interval: has it blown up, and has every vertex been at rest long enough?
        speeds = np.array([velocity_of(b, physicsClientId=cid)[0] for b in everything])
        where = np.array([position_of(b, physicsClientId=cid)[0] for b in everything])
        speed = np.linalg.norm(speeds, axis=1)
        if (
            not np.isfinite(speed).all()
            or not np.isfinite(where).all()
            or speed.max() > config.max_speed
            or np.linalg.norm(where - start, axis=1).max() > config.max_distance
        ):
            exploded = True
            break
        sphere_speeds = speed[: len(spheres)]
        quiet_checks = quiet_checks + 1 if sphere_speeds.max() < config.settle_speed else 0
        settled = quiet_checks >= quiet_needed
        if settled and config.early_stop:
            break

    joint_forces = np.full(len(joints), np.nan)
    for index, handle in alive:
        joint_forces[index] = math.sqrt(sum(f * f for f in read_joint(handle, physicsClientId=cid)[:3]))
    final = [position_of(b, physicsClientId=cid) for b in everything]
    positions = np.array([p for p, _ in final], dtype=np.float64).reshape(-1, 3)
    orientations = np.array([q for _, q in final], dtype=np.float64).reshape(-1, 4)
    v = len(spheres)
    return Outcome(
        broken=tuple(broken),
        joint_forces=joint_forces,
        peak_force=math.sqrt(max(joint_peak_sq, default=0.0)),
        peak_forces=np.sqrt(np.array(joint_peak_sq, dtype=np.float64)),
        final_positions=positions[:v],
        cylinder_positions=positions[v:],
        cylinder_orientations=orientations[v:],
        sim_time=steps_done * dt,
        steps=steps_done,
        settled=settled,
        exploded=exploded,
        final_speeds=sphere_speeds,
    )
