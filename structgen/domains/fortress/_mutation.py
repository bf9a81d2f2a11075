"""The original's mutation operators and orphan repair compiled with numba (:mod:`.world` describes them and is
what callers use).

Every random choice is a call on the run's ``numpy.random.Generator``, in the same order and with the same
arguments as numpy code would make it; numba's Generator methods (``random``, ``integers``) draw exactly what
numpy's do from the same bit generator and leave it in the same state, so a run's results do not depend on which
side made a choice. ``Generator.choice(n, p=...)`` is numpy's ``searchsorted(cdf, random(), side="right")`` over
the normalised cumulative weights, built here from the same table numpy would build (``harmonic_cdf``).

Edges are int64 rows ``(src, dst, condition, class argument, number)``; a class's edges behave as the original's
dict: setting an existing key changes its condition in place, a new key goes to the end, and the repairs sort
keys as strings (``rank[src, dst]``).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from structgen.domains.fortress.genome import CHARACTERS, CONDITION_NAMES

_STEP, _WITHIN = CONDITION_NAMES.index("step"), CONDITION_NAMES.index("within")
# The conditions that name a class.
_TAKES_CLASS = np.isin(CONDITION_NAMES, ("touch", "nextTo", "within"))
_N_CONDITIONS, _N_CHARACTERS = len(CONDITION_NAMES), len(CHARACTERS)
_SRC, _DST, _COND = 0, 1, 2
# Node indices stay below this, so (owner, src, dst) is one number.
_KEYS = 128


@nb.njit(cache=True)
def new_conditions(rng, count, step_low, step_high, prox_low, prox_high):
    """``(count, 3)``: random (condition, class argument, number) rows: the condition uniform, its class uniform
    over the 15 (kept by touch, nextTo and within), its number uniform over its range (kept by step and within)."""
    cond = rng.integers(0, _N_CONDITIONS, size=count)
    char = rng.integers(0, _N_CHARACTERS, size=count)
    step = rng.integers(step_low, step_high + 1, size=count)
    prox = rng.integers(prox_low, prox_high + 1, size=count)
    out = np.empty((count, 3), dtype=np.int64)
    for q in range(count):
        c = cond[q]
        out[q, 0] = c
        out[q, 1] = char[q] if _TAKES_CLASS[c] else -1
        out[q, 2] = step[q] if c == _STEP else (prox[q] if c == _WITHIN else 0)
    return out


@nb.njit(cache=True)
def assign(owner, edges, new_owner, new_rows):
    """Dict assignment of ``new_rows`` (distinct keys) into ``edges``, keys being (owner, src, dst): an edge that
    exists keeps its place and takes the new condition, the others are appended in order. Returns the owners and
    edges after, and which new rows were there already."""
    n_old, n_new = edges.shape[0], new_rows.shape[0]
    old_keys = (owner * _KEYS + edges[:, _SRC]) * _KEYS + edges[:, _DST]
    sorter = np.argsort(old_keys, kind="mergesort")
    ordered = old_keys[sorter]
    found = np.zeros(n_new, dtype=np.bool_)
    out = np.empty((n_old + n_new, 5), dtype=np.int64)
    out_owner = np.empty(n_old + n_new, dtype=np.int64)
    out[:n_old] = edges
    out_owner[:n_old] = owner
    n = n_old
    for m in range(n_new):
        key = (new_owner[m] * _KEYS + new_rows[m, _SRC]) * _KEYS + new_rows[m, _DST]
        at = np.searchsorted(ordered, key)
        if at < n_old and ordered[at] == key:
            out[sorter[at], _COND:] = new_rows[m, _COND:]
            found[m] = True
        else:
            out[n] = new_rows[m]
            out_owner[n] = new_owner[m]
            n += 1
    return out_owner[:n], out[:n], found


@nb.njit(cache=True)
def sort_edges(owner, edges, rank):
    """Edges grouped by owner, each group sorted as the original sorts its keys (as strings)."""
    keys = owner * (_KEYS * _KEYS) + rank_of(edges, rank)
    order = np.argsort(keys, kind="mergesort")
    return owner[order], edges[order]


@nb.njit(cache=True)
def rank_of(edges, rank):
    out = np.empty(edges.shape[0], dtype=np.int64)
    for q in range(edges.shape[0]):
        out[q] = rank[edges[q, _SRC], edges[q, _DST]]
    return out


@nb.njit(cache=True)
def repair(owner, edges, n_nodes, rng, orphans_only, step_low, step_high, prox_low, prox_high, rank):
    """The original's connectOrphanNodes on several classes at once (``edges[i]`` belongs to class ``owner[i]``
    of ``n_nodes[owner[i]]`` nodes), then its sort: every node of a class with two nodes or more (``orphans_only``:
    only those no other node leads to) gets an incoming edge from another node of its class, drawn uniformly, with
    a random condition."""
    n_classes = n_nodes.shape[0]
    reached = np.zeros((n_classes, _KEYS), dtype=np.bool_)
    if orphans_only:
        for q in range(edges.shape[0]):
            if edges[q, _SRC] != edges[q, _DST]:
                reached[owner[q], edges[q, _DST]] = True
    total = 0
    for k in range(n_classes):
        if n_nodes[k] > 1:
            for n in range(n_nodes[k]):
                if not reached[k, n]:
                    total += 1
    target_owner = np.empty(total, dtype=np.int64)
    targets = np.empty(total, dtype=np.int64)
    t = 0
    for k in range(n_classes):
        if n_nodes[k] > 1:
            for n in range(n_nodes[k]):
                if not reached[k, n]:
                    target_owner[t], targets[t] = k, n
                    t += 1
    draws = rng.random(total)
    rows = np.empty((total, 5), dtype=np.int64)
    for t in range(total):
        source = np.int64(draws[t] * (n_nodes[target_owner[t]] - 1))
        rows[t, _SRC] = source + (1 if source >= targets[t] else 0)
        rows[t, _DST] = targets[t]
    rows[:, _COND:] = new_conditions(rng, total, step_low, step_high, prox_low, prox_high)
    owner, edges, _ = assign(owner, edges, target_owner, rows)
    return sort_edges(owner, edges, rank)


@nb.njit(cache=True)
def remove_node(nodes, edges, index):
    """Delete a node and the edges touching it, renumbering the rest (the original's killOrphanEdges)."""
    keep = (edges[:, _SRC] != index) & (edges[:, _DST] != index)
    kept = edges[keep].copy()
    for q in range(kept.shape[0]):
        for column in (_SRC, _DST):
            if kept[q, column] > index:
                kept[q, column] -= 1
    out = np.empty(nodes.shape[0] - 1, dtype=np.int64)
    out[:index] = nodes[:index]
    out[index:] = nodes[index + 1 :]
    return out, kept


@nb.njit(cache=True)
def _harmonic(rng, top, harmonic_cdf):
    """k in 1..top with probability proportional to 1/k, as ``rng.choice(top, p=...) + 1`` draws it."""
    return np.searchsorted(harmonic_cdf[top, :top], rng.random(), side="right") + 1


@nb.njit(cache=True)
def _pop(items, size, at):
    """list.pop(at) on ``items[:size]``."""
    value = items[at]
    items[at : size - 1] = items[at + 1 : size].copy()
    return value


@nb.njit(cache=True)
def mutate(rng, nodes, node_off, edges, edge_off, chars, initial, settings, n_types, rank, harmonic_cdf, width, height):
    """One mutant of a world whose classes are ``nodes[node_off[k]:node_off[k + 1]]`` (node types) and
    ``edges[edge_off[k]:edge_off[k + 1]]``, of characters ``chars``, with initial entities ``initial``;
    ``settings``: orphans_only, edge coin, node coin, instance coin, step low, step high, range low, range high.

    Returns the mutant in the same form, which classes were replaced, and whether the initial entities were
    touched (see :func:`.world.mutate_world` for the operators)."""
    orphans_only = settings[0] > 0
    edge_p, node_p, instance_p = settings[1], settings[2], settings[3]
    s_lo, s_hi, p_lo, p_hi = np.int64(settings[4]), np.int64(settings[5]), np.int64(settings[6]), np.int64(settings[7])
    n_classes = node_off.shape[0] - 1
    class_nodes = [nodes[node_off[k] : node_off[k + 1]].copy() for k in range(n_classes)]
    class_edges = [edges[edge_off[k] : edge_off[k + 1]].copy() for k in range(n_classes)]
    changed = np.zeros(n_classes, dtype=np.bool_)
    entities_changed = False
    coins = rng.random(3)
    edge_coin, node_coin, instance_coin = coins[0], coins[1], coins[2]
    while edge_coin < edge_p:
        kind = rng.integers(0, 3)
        k = rng.integers(0, n_classes)
        own, there = class_nodes[k], class_edges[k]
        if kind == 0 and there.shape[0] > 1:
            drop = rng.integers(0, there.shape[0])
            kept = np.concatenate((there[:drop], there[drop + 1 :]))
            _, class_edges[k] = repair(
                np.zeros(kept.shape[0], dtype=np.int64), kept, np.array([own.shape[0]]), rng, orphans_only,
                s_lo, s_hi, p_lo, p_hi, rank,
            )  # fmt: skip
            changed[k] = True
        elif kind == 1:
            ends = rng.integers(0, own.shape[0], size=2)
            row = np.empty((1, 5), dtype=np.int64)
            row[0, _SRC], row[0, _DST] = ends[0], ends[1]
            row[:, _COND:] = new_conditions(rng, 1, s_lo, s_hi, p_lo, p_hi)
            _, class_edges[k], _ = assign(np.zeros(there.shape[0], dtype=np.int64), there, np.zeros(1, dtype=np.int64), row)
            changed[k] = True
        elif kind == 2 and there.shape[0] > 0:
            # The condition is drawn before the edge it goes to (the original's assignment evaluates its
            # right-hand side first).
            condition = new_conditions(rng, 1, s_lo, s_hi, p_lo, p_hi)[0]
            after = there.copy()
            after[rng.integers(0, there.shape[0]), _COND:] = condition
            class_edges[k] = after
            changed[k] = True
        edge_coin = rng.random()
    if node_coin < node_p:
        kind = rng.integers(0, 3)
        k = rng.integers(0, n_classes)
        own, there = class_nodes[k].copy(), class_edges[k]
        # The node types the class lacks, in order (a Python list: pops shift, appends go last).
        used = np.zeros(n_types, dtype=np.bool_)
        for t in own:
            used[t] = True
        available = np.empty(n_types, dtype=np.int64)
        size = 0
        for t in range(n_types):
            if not used[t]:
                available[size] = t
                size += 1
        replaced = True
        if kind == 0 and own.shape[0] > 1:
            for _ in range(_harmonic(rng, own.shape[0] - 1, harmonic_cdf)):
                own, there = remove_node(own, there, rng.integers(0, own.shape[0]))
        elif kind == 1 and size > 0:
            count = _harmonic(rng, size, harmonic_cdf)
            added = np.empty(count, dtype=np.int64)
            for a in range(count):
                added[a] = _pop(available, size, rng.integers(0, size))
                size -= 1
            first = own.shape[0]
            draws = rng.random(count)
            rows = np.empty((count, 5), dtype=np.int64)
            for a in range(count):
                # Each new node is wired in from a node before it.
                rows[a, _SRC] = np.int64(draws[a] * (first + a))
                rows[a, _DST] = first + a
            own = np.concatenate((own, added))
            rows[:, _COND:] = new_conditions(rng, count, s_lo, s_hi, p_lo, p_hi)
            owner, there, _ = assign(np.zeros(there.shape[0], dtype=np.int64), there, np.zeros(count, dtype=np.int64), rows)
            _, there = sort_edges(owner, there, rank)
        elif kind == 2:
            for _ in range(_harmonic(rng, own.shape[0], harmonic_cdf)):
                if size > 0:
                    index = rng.integers(0, own.shape[0])
                    old = own[index]
                    own[index] = _pop(available, size, rng.integers(0, size))
                    available[size - 1] = old
                else:
                    ij = rng.integers(0, own.shape[0], size=2)
                    own[ij[0]], own[ij[1]] = own[ij[1]], own[ij[0]]
        else:
            replaced = False
        if replaced:
            class_nodes[k], class_edges[k] = own, there
            changed[k] = True
    while instance_coin < instance_p:
        if rng.integers(0, 2) == 0:
            if initial.shape[0] > 0:
                drop = rng.integers(0, initial.shape[0])
                initial = np.concatenate((initial[:drop], initial[drop + 1 :]))
        else:
            row = np.empty((1, 3), dtype=np.int64)
            row[0, 0] = chars[rng.integers(0, n_classes)]
            row[0, 1] = rng.integers(1, width - 1)
            row[0, 2] = rng.integers(1, height - 1)
            initial = np.concatenate((initial, row))
        entities_changed = True
        instance_coin = rng.random()
    out_node_off = np.zeros(n_classes + 1, dtype=np.int64)
    out_edge_off = np.zeros(n_classes + 1, dtype=np.int64)
    for k in range(n_classes):
        out_node_off[k + 1] = out_node_off[k] + class_nodes[k].shape[0]
        out_edge_off[k + 1] = out_edge_off[k] + class_edges[k].shape[0]
    out_nodes = np.empty(out_node_off[-1], dtype=np.int64)
    out_edges = np.empty((out_edge_off[-1], 5), dtype=np.int64)
    for k in range(n_classes):
        out_nodes[out_node_off[k] : out_node_off[k + 1]] = class_nodes[k]
        out_edges[out_edge_off[k] : out_edge_off[k + 1]] = class_edges[k]
    return out_nodes, out_node_off, out_edges, out_edge_off, changed, initial, entities_changed


@nb.njit(cache=True)
def random_classes(rng, extra, n_types, orphans_only, step_low, step_high, prox_low, prox_high, rank):
    """Classes as the original's makeTree builds them, all drawn at once: class k has ``idle`` and ``extra[k]``
    distinct random node types (the first of a random order of the others), twice as many random edges (a later
    one overwrites an earlier one with the same ends), then the orphan repair. Returns the node types and the edges
    concatenated over the classes, with each class's offsets into them."""
    n_classes = extra.shape[0]
    draws = rng.random((n_classes, n_types - 1))
    owner = np.repeat(np.arange(n_classes), 2 * extra)
    ends = rng.random((owner.shape[0], 2))
    conditions = new_conditions(rng, owner.shape[0], step_low, step_high, prox_low, prox_high)
    # The last edge written under each key wins (the repair's sort settles the order).
    written = np.zeros((n_classes, _KEYS * _KEYS), dtype=np.bool_)
    keep = np.zeros(owner.shape[0], dtype=np.bool_)
    rows = np.empty((owner.shape[0], 5), dtype=np.int64)
    for q in range(owner.shape[0] - 1, -1, -1):
        size = extra[owner[q]] + 1
        src, dst = np.int64(ends[q, 0] * size), np.int64(ends[q, 1] * size)
        rows[q, _SRC], rows[q, _DST] = src, dst
        rows[q, _COND:] = conditions[q]
        if not written[owner[q], src * _KEYS + dst]:
            written[owner[q], src * _KEYS + dst] = True
            keep[q] = True
    owner, edges = repair(owner[keep], rows[keep], extra + 1, rng, orphans_only, step_low, step_high, prox_low, prox_high, rank)
    node_off = np.zeros(n_classes + 1, dtype=np.int64)
    edge_off = np.zeros(n_classes + 1, dtype=np.int64)
    for k in range(n_classes):
        node_off[k + 1] = node_off[k] + extra[k] + 1
    for q in range(owner.shape[0]):
        edge_off[owner[q] + 1] += 1
    for k in range(n_classes):
        edge_off[k + 1] += edge_off[k]
    nodes = np.zeros(node_off[-1], dtype=np.int64)  # node 0 of every class is idle (type 0)
    for k in range(n_classes):
        order = np.argsort(draws[k])
        nodes[node_off[k] + 1 : node_off[k + 1]] = 1 + order[: extra[k]]
    return nodes, node_off, edges, edge_off


@nb.njit(cache=True)
def mutate_many(rng, nodes, node_off, edges, edge_off, classes_of, chars, initial, initial_off, settings, n_types, rank,
                harmonic_cdf, width, height):  # fmt: skip
    """:func:`mutate` on several worlds in turn (the same draws as one call each): world w owns classes
    ``classes_of[w]:classes_of[w + 1]`` (``node_off`` / ``edge_off`` / ``chars`` over all classes) and initial
    entities ``initial[initial_off[w]:initial_off[w + 1]]``. Returns the mutants in the same form, which classes
    were replaced, and which worlds' initial entities were touched."""
    n_worlds = classes_of.shape[0] - 1
    parts_nodes, parts_edges, parts_initial = [], [], []
    n_classes = chars.shape[0]
    out_node_off = np.zeros(n_classes + 1, dtype=np.int64)
    out_edge_off = np.zeros(n_classes + 1, dtype=np.int64)
    out_initial_off = np.zeros(n_worlds + 1, dtype=np.int64)
    changed = np.zeros(n_classes, dtype=np.bool_)
    touched = np.zeros(n_worlds, dtype=np.bool_)
    for w in range(n_worlds):
        first, last = classes_of[w], classes_of[w + 1]
        n0, n1, e0, e1 = node_off[first], node_off[last], edge_off[first], edge_off[last]
        got_nodes, got_node_off, got_edges, got_edge_off, got_changed, got_initial, got_touched = mutate(
            rng, nodes[n0:n1], node_off[first : last + 1] - n0, edges[e0:e1], edge_off[first : last + 1] - e0,
            chars[first:last], initial[initial_off[w] : initial_off[w + 1]], settings, n_types, rank, harmonic_cdf,
            width, height,
        )  # fmt: skip
        parts_nodes.append(got_nodes)
        parts_edges.append(got_edges)
        parts_initial.append(got_initial)
        for k in range(last - first):
            out_node_off[first + k + 1] = out_node_off[first] + got_node_off[k + 1]
            out_edge_off[first + k + 1] = out_edge_off[first] + got_edge_off[k + 1]
        changed[first:last] = got_changed
        touched[w] = got_touched
        out_initial_off[w + 1] = out_initial_off[w] + got_initial.shape[0]
    out_nodes = np.empty(out_node_off[-1], dtype=np.int64)
    out_edges = np.empty((out_edge_off[-1], 5), dtype=np.int64)
    out_initial = np.empty((out_initial_off[-1], 3), dtype=np.int64)
    for w in range(n_worlds):
        first, last = classes_of[w], classes_of[w + 1]
        out_nodes[out_node_off[first] : out_node_off[last]] = parts_nodes[w]
        out_edges[out_edge_off[first] : out_edge_off[last]] = parts_edges[w]
        out_initial[out_initial_off[w] : out_initial_off[w + 1]] = parts_initial[w]
    return out_nodes, out_node_off, out_edges, out_edge_off, changed, out_initial, out_initial_off, touched
