"""A slow, literal implementation of the growth rules in structgen.nca's docstring, used as a test oracle.

It shares nothing with the batched implementation except the neighbour ordering and the weight layout: vertices are
a Python set of tuples, edges a set of frozensets, and every vertex is evaluated on its own in float64 numpy.
"""

from __future__ import annotations

import math

import numpy as np

from structgen import Structure
from structgen.lattice import OFFSETS
from structgen.nca import NCAConfig

NEIGHBOURS = [tuple(int(c) for c in d) for d in OFFSETS]


def _add(a: tuple[int, int, int], d: tuple[int, int, int]) -> tuple[int, int, int]:
    return (a[0] + d[0], a[1] + d[1], a[2] + d[2])


def reference_grow(weights: np.ndarray, config: NCAConfig) -> Structure:
    h = config.hidden
    w1 = weights[: 52 * h].reshape(52, h)
    b1 = weights[52 * h : 53 * h]
    w2 = weights[53 * h : 53 * h + 26 * h].reshape(h, 26)
    b2 = weights[53 * h + 26 * h :]
    threshold = math.log(config.cutoff / (1 - config.cutoff))
    seed = (0, 0, 0)
    vertices = {seed}
    edges: set[frozenset] = set()
    steps_run, hit_vertices, hit_extent, fixed_point = 0, False, False, False

    for _ in range(config.iterations):
        wishes = {}
        for v in vertices:
            near = [_add(v, d) for d in NEIGHBOURS]
            x = np.array([u in vertices for u in near] + [frozenset((v, u)) in edges for u in near], dtype=float)
            z = np.maximum(x @ w1 + b1, 0.0) @ w2 + b2
            wishes[v] = [u for u, fire in zip(near, z > threshold) if fire]

        new_edges = set()
        left_box = False
        for v, targets in wishes.items():
            for u in targets:
                if max(abs(c) for c in u) > config.max_extent:
                    left_box = True
                    continue
                if u not in vertices and not config.build_down and u[2] < seed[2]:
                    continue
                new_edges.add(frozenset((v, u)))
        new_vertices = {u for e in new_edges for u in e} | {seed}
        if len(new_vertices) > config.max_vertices:
            hit_vertices = True
            break
        hit_extent |= left_box
        if new_vertices == vertices and new_edges == edges:  # nothing changed: every later step would repeat this
            fixed_point = True
            break
        vertices, edges = new_vertices, new_edges
        steps_run += 1

    ordered = sorted(vertices)
    index = {v: i for i, v in enumerate(ordered)}
    pairs = sorted(tuple(sorted(index[u] for u in e)) for e in edges)
    growth = {
        "generator": "local_nca",
        "hidden": config.hidden,
        "iterations": config.iterations,
        "cutoff": config.cutoff,
        "build_down": config.build_down,
        "max_vertices": config.max_vertices,
        "max_extent": config.max_extent,
        "iterations_run": steps_run,
        "hit_max_vertices": hit_vertices,
        "hit_max_extent": hit_extent,
        "reached_fixed_point": fixed_point,
    }
    return Structure(np.array(ordered).reshape(-1, 3), np.array(pairs).reshape(-1, 2), {"growth": growth})
