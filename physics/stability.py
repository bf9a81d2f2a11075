"""``check_stability``: one structure under gravity, judged by the paper's integrity, height, complexity and score;
``check_transient``: its first moments, judged by how far the largest joint force is from the break force."""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Any, Literal

import numpy as np

from physics.bullet import simulate
from physics.config import PhysicsConfig
from physics.model import InputError, place, read_structure
from physics.report import BrokenJoint, StabilityReport, height_of, integrity_of, quality

__all__ = ["check_or_fail", "check_stability", "check_transient"]


def check_stability(
    structure: Any, config: PhysicsConfig | None = None, *, errors: Literal["raise", "report"] = "raise"
) -> StabilityReport:
    """Simulate ``structure`` resting on the ground under gravity, with joints that break under load.

    Args:
        structure: anything with ``vertices`` ((V, 3), lattice units, z up) and ``edges`` ((E, 2) vertex indices):
            a ``structgen.Structure``, a mapping with those keys, or a ``(vertices, edges)`` pair.
        config: model and simulation settings; the default is the faithful preset (``PhysicsConfig()``).
        errors: "raise" (default) raises on bad input; "report" returns a failed report instead (I = Q = 0,
            ``error`` set), for batches where one bad structure must not stop the rest.

    Returns:
        A :class:`StabilityReport`. A simulation that explodes (non-finite or runaway positions or speeds) is
        reported with ``exploded=True`` and I = Q = 0 rather than raised.

    Raises:
        physics.InputError: the structure is malformed or larger than ``config.max_vertices`` / ``max_joints``.
    """
    config = config or PhysicsConfig()
    if errors == "report":
        vertices, edges = read_structure(structure)
        return check_or_fail(vertices, edges, config)
    started_wall, started_cpu = time.perf_counter(), time.process_time()
    vertices, edges = read_structure(structure)
    bodies = place(vertices, edges, config)
    outcome = simulate(bodies, config)

    n_joints = bodies.n_joints
    broken = tuple(
        BrokenJoint(joint=j, edge=j // 2, vertex=int(edges[j // 2, j % 2]), time=t, force=f, torque=q)
        for j, t, f, q in outcome.broken
    )
    falling = outcome.final_speeds > config.fall_speed
    if outcome.exploded:
        integrity, height = 0.0, 0.0
    else:
        integrity = integrity_of(len(broken), n_joints)
        # A vertex still dropping when the simulation ended is not where it will come to rest.
        height = height_of(outcome.final_positions[~falling, 2], config)
    complexity = len(vertices)
    return StabilityReport(
        integrity=integrity,
        height=height,
        complexity=complexity,
        score=quality(integrity, height, complexity, config),
        n_joints=n_joints,
        broken_joints=broken,
        joint_forces=outcome.joint_forces,
        peak_force=outcome.peak_force,
        peak_forces=outcome.peak_forces,
        initial_positions=bodies.sphere_positions,
        final_positions=outcome.final_positions,
        final_edge_ends=bodies.cylinder_ends(outcome.cylinder_positions, outcome.cylinder_orientations),
        edges=edges,
        sim_time=outcome.sim_time,
        steps=outcome.steps,
        settled=outcome.settled,
        exploded=outcome.exploded,
        falling=int(falling.sum()),
        final_speed=float(outcome.final_speeds.max(initial=0.0)),
        wall_time=time.perf_counter() - started_wall,
        cpu_time=time.process_time() - started_cpu,
        config=config,
    )


def check_transient(
    structure: Any,
    config: PhysicsConfig | None = None,
    *,
    window: float = 0.3,
    errors: Literal["raise", "report"] = "raise",
) -> StabilityReport:
    """Simulate the first ``window`` seconds of ``structure`` with joints that cannot break, and rate the largest
    force any joint carried against ``config.break_force``.

    Tall structures carry their largest loads while they take up their weight, in the first tenth of a second. The
    simulation with breakable joints takes exactly the same steps until a joint breaks, so a peak within the break
    force means nothing breaks in the window, and a peak above it means something does. The report (``method =
    "transient"``) gives ``integrity`` as the strength ratio min(1, break force / peak force), which falls with
    every newton over the limit where integrity would move a joint at a time, and ``score`` as the paper's Q with
    that ratio for I; it is ``intact`` when the ratio is 1. What happens after the window (feet that slide, a
    slow tip) is not seen: :func:`check_stability` gives the verdict.
    """
    config = config or PhysicsConfig()
    if not (isinstance(window, (int, float)) and not isinstance(window, bool) and 0 < window < math.inf):
        raise ValueError(f"window must be a positive number of seconds, got {window!r}")
    held = config.replace(break_force=math.inf, horizon=min(window, config.horizon))
    report = dataclasses.replace(check_stability(structure, held, errors=errors), config=config, method="transient")
    if report.error is not None or report.exploded:
        return report  # scored 0 already
    ratio = min(1.0, config.break_force / report.peak_force) if report.peak_force > 0 else 1.0
    return dataclasses.replace(report, integrity=ratio, score=quality(ratio, report.height, report.complexity, config))


def check_or_fail(vertices: np.ndarray, edges: np.ndarray, config: PhysicsConfig) -> StabilityReport:
    """Like :func:`check_stability`, but any failure becomes a failed report (I = 0, ``error`` set): for batches."""
    try:
        return check_stability((vertices, edges), config)
    except InputError as err:
        return StabilityReport.failed(vertices, edges, f"bad input: {err}", config)
    except Exception as err:  # keep one structure's failure from ending the batch
        return StabilityReport.failed(vertices, edges, f"{type(err).__name__}: {err}", config)
