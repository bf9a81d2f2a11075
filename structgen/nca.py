"""The local neural cellular automaton of Petersen et al.: a small network, shared by all vertices, grows a structure.

Network
-------
Every vertex reads its *local*: 52 flags about the 26 lattice cells around it, in the neighbour order of
:mod:`structgen.lattice`. Inputs ``0..25`` say whether neighbour ``k`` holds a vertex, inputs ``26..51`` whether
that vertex is joined to this one by an edge. A fully connected 52-``hidden``-26 network (ReLU hidden layer, sigmoid
outputs; ``hidden = 60`` in the paper) turns the local into 26 outputs. Output ``k`` *fires* when
``sigmoid(z_k) > cutoff``, evaluated exactly as ``z_k > log(cutoff / (1 - cutoff))``; a firing output is the wish
"a vertex at neighbour ``k``, joined to me".

The weights form one flat float64 vector of :func:`n_params` numbers, the way optimisers see them, in this order:
``W1`` (52 x hidden, row-major, ``hidden_pre = x @ W1 + b1``), ``b1`` (hidden), ``W2`` (hidden x 26), ``b2`` (26).

Growth semantics
----------------
Growth starts from a single *seed* vertex at the origin ``(0, 0, 0)`` with no edges and runs ``iterations`` steps
(5 in the paper). One step:

1. **Read, synchronously.** Every vertex present at the start of the step reads its local from the state at the
   start of the step. Nothing written during the step is seen until the next one.
2. **Decide.** Each vertex's network outputs give its set of wished neighbours.
3. **Write, all at once.** For two neighbouring cells ``a`` and ``b``, the edge ``a-b`` exists after the step if and
   only if ``a`` wishes for ``b`` or ``b`` wishes for ``a`` (only vertices present at the start of the step wish).
   Conflicts over a shared edge are therefore settled in favour of keeping it: an edge survives while either end
   wants it and is removed only when neither does. A wish towards an empty cell creates a vertex there, joined to
   every vertex that wished for that cell. A wish towards a cell outside the growth box, or below the seed's level
   when ``build_down`` is off (the paper's "no building down" rule), is ignored.
4. **Prune.** A vertex left without edges is removed, except the seed, which is never removed; a structure is
   therefore never empty, and a network that never fires leaves the lone seed.
5. **Caps.** The growth box holds the cells within ``max_extent`` steps of the seed along every axis; wishes that
   leave it are dropped (step 3) and the structure's ``metadata["growth"]["hit_max_extent"]`` is set. A
   structure may also be given a smaller box of its own (``boxes``: any extent along each axis, the seed inside):
   the same rule, its wishes beyond that box dropped. If a step would
   leave more than ``max_vertices`` vertices, that step is discarded and growth stops: the structure is the one from
   before the step, and ``metadata["growth"]["hit_max_vertices"]`` is set. Memory is thus bounded by
   ``population x (2 * min(iterations, max_extent) + 3) ** 3 x 14`` bytes of grids plus ``max_vertices`` rows of
   network activations per structure.
6. **Fixed point.** A step that changes nothing (no vertex or edge added or removed) would repeat forever, since a
   step depends on the state alone: growth stops there, with the same structure any number of further steps would
   give, and ``metadata["growth"]["reached_fixed_point"]`` is set. ``iterations_run`` counts the steps that changed
   something, so a large ``iterations`` costs only those.

The result is a :class:`~structgen.structure.Structure` whose vertices are sorted by (x, y, z) and whose edges
``(i, j)`` have ``i < j`` and are sorted by ``i``, then ``j``, so equal growth gives equal (``==``) structures.

Implementation
--------------
A whole population grows at once: the state of all structures lives in flat occupancy and edge grids (one cube per
structure, 13 edge directions per cell); each step gathers the locals of all occupied cells into one padded batch,
evaluates them with two batched matrix products (each structure with its own weights), and writes the new edges with
shifted elementwise operations. The products run in float32 with a certified float64 fallback for outputs near the
cutoff (see ``_Growth``), so firing decisions do not depend on how the batch is laid out. Growing one NCA is the same code
with a population of one, so single and batched growth give identical structures.
"""

from __future__ import annotations

import io
import json
import math
import os
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np
import torch

from evolution.files import atomic_write, read_weights
from structgen.budget import check_memory
from structgen.lattice import N_DIRECTIONS, N_NEIGHBOURS, OFFSETS
from structgen.nca_config import INIT_SCALE, N_INPUTS, N_OUTPUTS, NCAConfig, n_params
from structgen.structure import Structure

__all__ = [
    "INIT_SCALE",
    "LocalNCA",
    "NCAConfig",
    "check_seed",
    "grow",
    "grow_on",
    "grow_population",
    "grow_steps",
    "load_weights",
    "n_params",
    "random_weights",
    "save_weights",
]


def random_weights(count: int, seed: int, config: NCAConfig | None = None, scale: float = INIT_SCALE) -> np.ndarray:
    """``(count, n_params)`` weight vectors drawn uniformly from ``[-scale, scale]``; the same seed gives the same array."""
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    rng = np.random.default_rng(seed)
    return rng.uniform(-scale, scale, size=(count, n_params(config)))


def _check_weights(weights: Any, config: NCAConfig) -> np.ndarray:
    """``(P, n_params)`` float64 array, or ValueError naming what is wrong."""
    array = np.asarray(weights, dtype=np.float64)
    if array.ndim == 1:
        array = array[None, :]
    expected = n_params(config)
    if array.ndim != 2 or array.shape[1] != expected:
        raise ValueError(
            f"expected {expected} weights per NCA (52-{config.hidden}-26 network), got an array of shape {np.shape(weights)}"
        )
    if not np.isfinite(array).all():
        raise ValueError("NCA weights must be finite numbers (found NaN or infinity)")
    return array


def grow_population(weights: Any, config: NCAConfig | None = None, boxes: Any = None) -> list[Structure]:
    """Grow one structure per row of ``weights`` (``(P, n_params)``), all in one batched computation.

    ``boxes`` (``(P, 3, 2)`` or one ``(3, 2)`` for all): each structure grows only inside its box, the cells whose
    x, y and z offsets from the seed lie within ``[low, high]`` (inclusive; the seed inside), as well as within
    ``max_extent``; wishes that leave it are dropped as at the growth box's walls. Returns the structures in row
    order; each carries ``metadata["growth"]`` (iterations run, caps hit, its box).
    """
    config = config or NCAConfig()
    weights = _check_weights(weights, config)
    with torch.no_grad():
        return _Growth(weights, config, boxes=_check_boxes(boxes, len(weights))).run()[0]


def _check_boxes(boxes: Any, population: int) -> np.ndarray | None:
    if boxes is None:
        return None
    array = np.asarray(boxes)
    if array.shape == (3, 2):
        array = np.broadcast_to(array, (population, 3, 2))
    if array.shape != (population, 3, 2) or not np.issubdtype(array.dtype, np.integer):
        raise ValueError(
            f"boxes must be whole numbers shaped ({population}, 3, 2) or (3, 2): [[x_low, x_high], [y_low, y_high], "
            f"[z_low, z_high]] offsets from the seed; got shape {array.shape} of {array.dtype}"
        )
    if (array[..., 0] > 0).any() or (array[..., 1] < 0).any():
        raise ValueError("every box must hold the seed: low <= 0 <= high on each axis")
    return array.astype(np.int64)


def grow_steps(weights: Any, config: NCAConfig | None = None) -> list[Structure]:
    """The structure of one NCA after each growth step: the lone seed first, then one structure per step that
    changed something (growth ends early at a fixed point or at the vertex cap), the last equal to :func:`grow`'s."""
    config = config or NCAConfig()
    weights = _check_weights(weights, config)
    if len(weights) != 1:
        raise ValueError(f"grow_steps() takes one weight vector, got {len(weights)}")
    with torch.no_grad():
        return [frame[0] for frame in _Growth(weights, config).run(every_step=True)]


def grow(weights: Any, config: NCAConfig | None = None, box: Any = None) -> Structure:
    """Grow the structure of a single NCA given its flat weight vector (inside ``box``: see :func:`grow_population`)."""
    config = config or NCAConfig()
    weights = _check_weights(weights, config)
    if len(weights) != 1:
        raise ValueError(f"grow() takes one weight vector; use grow_population() for {len(weights)}")
    return grow_population(weights, config, None if box is None else np.asarray(box)[None])[0]


def check_seed(structure: Structure) -> None:
    """ValueError unless ``structure`` has a vertex at the origin, where an NCA's seed stands (as in every structure
    an NCA grew: its coordinates count from the seed)."""
    if not (structure.vertices == 0).all(axis=1).any():
        raise ValueError("the structure has no vertex at the origin, where the NCA's seed stands (not grown by an NCA?)")


def grow_on(weights: Any, start: Structure, config: NCAConfig | None = None) -> Structure:
    """Let one NCA grow on from ``start`` (a structure whose seed vertex is at the origin, such as a damaged copy
    of what the NCA grew) for ``config.iterations`` more steps, or until nothing changes: the same local rule, read
    from the structure as it is. An NCA whose rule only adds what is missing regrows what was cut away."""
    config = config or NCAConfig()
    weights = _check_weights(weights, config)
    if len(weights) != 1:
        raise ValueError(f"grow_on() takes one weight vector, got {len(weights)}")
    check_seed(start)
    with torch.no_grad():
        return _Growth(weights, config, start).run()[0][0]


class LocalNCA:
    """A local NCA: a configuration plus one flat weight vector, with get/set for optimisers.

    >>> nca = LocalNCA.random(seed=0)
    >>> structure = nca.grow()
    """

    def __init__(self, weights: Any | None = None, config: NCAConfig | None = None) -> None:
        self.config = config or NCAConfig()
        self._weights = np.zeros(n_params(self.config))
        if weights is not None:
            self.set_weights(weights)

    @classmethod
    def random(cls, seed: int, config: NCAConfig | None = None, scale: float = INIT_SCALE) -> LocalNCA:
        """An NCA with weights drawn uniformly from ``[-scale, scale]`` by a generator seeded with ``seed``."""
        return cls(random_weights(1, seed, config, scale)[0], config)

    @property
    def n_params(self) -> int:
        return n_params(self.config)

    def get_weights(self) -> np.ndarray:
        """A copy of the flat weight vector."""
        return self._weights.copy()

    def set_weights(self, weights: Any) -> None:
        """Replace the weights with a flat vector of length :attr:`n_params`."""
        array = _check_weights(weights, self.config)
        if len(array) != 1:
            raise ValueError(f"set_weights() takes one flat vector of {self.n_params} numbers")
        self._weights = array[0].copy()

    def layers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The weights as ``(W1, b1, W2, b2)`` views of shapes (52, h), (h,), (h, 26), (26,)."""
        return _split(self._weights, self.config.hidden)

    def grow(self) -> Structure:
        """Grow this NCA's structure from a single seed vertex."""
        return grow(self._weights, self.config)


def _split(flat: np.ndarray, hidden: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    a = N_INPUTS * hidden
    b = a + hidden
    c = b + hidden * N_OUTPUTS
    return (
        flat[..., :a].reshape(*flat.shape[:-1], N_INPUTS, hidden),
        flat[..., a:b],
        flat[..., b:c].reshape(*flat.shape[:-1], hidden, N_OUTPUTS),
        flat[..., c:],
    )


# Unit roundoff of float32 and the classic bound on the error of an n-term float sum (any order, FMA or not).
_U32 = 2.0**-24


def _gamma(n: int) -> float:
    return n * _U32 / (1 - n * _U32)


# Memory of growth, per cell of the grids (state, wishes, masks and the step's copies) and per vertex that reads its
# neighbourhood in a step (inputs, hidden layer, outputs, margins); generous, so the check never refuses work that fits.
_BYTES_PER_CELL, _BYTES_PER_ROW = 100, 600


class _Growth:
    """State of a population's growth as flat grids; every step is a few gathers, two batched matrix products and
    shifted elementwise operations, with no sorting.

    Each structure owns a cube of side ``G = 2 * radius + 3`` (the growth box plus a one-cell margin that stays
    empty, so every neighbour of a box cell is inside the cube). Cell ``(x, y, z)`` of structure ``p`` is number
    ``p * G^3 + x * G^2 + y * G + z``; one extra, always empty cube at the end gives padding rows a harmless cell to
    read. The state is one ``(14, n_cells)`` bool grid: row 0 says which cells hold a vertex, row ``1 + m`` which
    cells have an edge in direction ``13 + m`` (the 13 directions whose number step is positive), so each edge is
    stored once, at its endpoint with the smaller number.

    The network runs in float32 for speed, but its decisions are those of exact arithmetic: a bound on the float32
    rounding error of every output (from the weights alone) marks the outputs that land too close to the cutoff to
    trust, and only those rows are recomputed in float64. So the result does not depend on how rows are batched.
    """

    def __init__(
        self, weights: np.ndarray, config: NCAConfig, start: Structure | None = None, boxes: np.ndarray | None = None
    ) -> None:
        self.config = config
        self.population = len(weights)
        self.threshold = math.log(config.cutoff / (1 - config.cutoff))
        self.exact = tuple(t.contiguous() for t in _split(torch.tensor(weights), config.hidden))
        w1, b1, w2, b2 = self.exact
        self.w1, self.w2 = w1.float(), w2.float()
        self.b1, self.b2 = b1[:, None, :].float(), b2[:, None, :].float()
        # |float32 output - exact output| <= tolerance, for 0/1 inputs (see _gamma): hidden pre-activations are sums
        # of 53 terms bounded by reach = |b1| + sum|W1|, outputs sums of 61 terms; +1 term each for rounding weights.
        reach = b1.abs() + w1.abs().sum(1)
        spread = torch.einsum("pj,pjk->pk", reach, w2.abs())
        g_hidden, g_out = _gamma(N_INPUTS + 2), _gamma(config.hidden + 2)
        tolerance = g_out * b2.abs() + (g_out * (1 + g_hidden) + g_hidden) * spread + _U32 * abs(self.threshold)
        # The margin is compared in float32; a relative slack of a few roundoffs keeps that comparison on the safe side.
        self.tolerance = ((1 + 8 * _U32) * tolerance[:, None, :]).float()

        # A start structure's vertices lie up to ``reach`` cells from the seed; growth adds a cell a step to that.
        self.reach = 0 if start is None else int(np.abs(start.vertices).max(initial=0))
        if self.reach > config.max_extent:
            raise ValueError(f"the structure reaches {self.reach} cells from its seed, beyond max_extent {config.max_extent}")
        self.radius = min(self.reach + config.iterations, config.max_extent)
        side = self.side = 2 * self.radius + 3
        self.volume = side**3
        check_memory(
            _BYTES_PER_CELL * (self.population + 1) * self.volume
            + _BYTES_PER_ROW * self.population * min(self.volume, config.max_vertices),
            f"growing {self.population:,} NCA{'s' if self.population != 1 else ''} in boxes of {side}^3 cells",
            "use fewer --iterations or a smaller --max-extent",
        )
        offsets = torch.tensor(OFFSETS.tolist(), dtype=torch.int64)
        self.delta = offsets[:, 0] * side * side + offsets[:, 1] * side + offsets[:, 2]  # (26,) number steps
        self.forward_step = self.delta[N_DIRECTIONS:].tolist()  # positive steps of directions 13..25
        axis = torch.arange(side)
        x, y, z = torch.meshgrid(axis, axis, axis, indexing="ij")
        inner = (x >= 1) & (x <= side - 2) & (y >= 1) & (y <= side - 2) & (z >= 1) & (z <= side - 2)
        centre = self.radius + 1
        buildable = inner & (config.build_down | (z >= centre))
        cubes = self.population + 1
        n_cells = self.n_cells = cubes * self.volume
        self.in_box = inner.reshape(-1).repeat(cubes)
        self.in_box[self.population * self.volume :] = False
        self.buildable = buildable.reshape(-1).repeat(cubes) & self.in_box
        self.boxes = boxes
        if boxes is not None:  # each structure's own box, as offsets from its seed
            offsets = torch.stack([x, y, z], -1).reshape(-1, 3) - centre
            low, high = torch.as_tensor(boxes[:, :, 0]), torch.as_tensor(boxes[:, :, 1])
            inside = ((offsets[None] >= low[:, None]) & (offsets[None] <= high[:, None])).all(-1)
            mask = torch.cat([inside.reshape(-1), torch.zeros(self.volume, dtype=torch.bool)])
            self.in_box &= mask
            self.buildable &= mask
        self.seed_cells = torch.arange(self.population) * self.volume + (centre * side + centre) * side + centre
        self.padding_cell = self.population * self.volume + (centre * side + centre) * side + centre
        # Where a cell finds its 52 inputs in the flattened state grid: the occupancy of neighbour k in row 0; its
        # edge towards neighbour k >= 13 in row k - 12 at the cell itself, and towards k < 13 at the neighbour, in
        # the opposite direction 25 - k (row 13 - k).
        k = torch.arange(N_NEIGHBOURS)
        edge_rows = torch.where(k >= N_DIRECTIONS, (k - N_DIRECTIONS + 1) * n_cells, (N_DIRECTIONS - k) * n_cells + self.delta)
        self.input_lookup = torch.cat([self.delta, edge_rows])

        self.state = torch.zeros((1 + N_DIRECTIONS, n_cells), dtype=torch.bool)
        self.state[0, self.seed_cells] = True
        if start is not None:
            self._place(start)
        self.wished = torch.zeros((N_NEIGHBOURS, n_cells), dtype=torch.bool)
        self.active = torch.ones(self.population, dtype=torch.bool)
        self.hit_max_vertices = torch.zeros(self.population, dtype=torch.bool)
        self.hit_max_extent = torch.zeros(self.population, dtype=torch.bool)
        self.reached_fixed_point = torch.zeros(self.population, dtype=torch.bool)
        self.steps_run = torch.zeros(self.population, dtype=torch.int64)

    def _place(self, start: Structure) -> None:
        """Start every structure of the population from ``start`` (its vertex at the origin on the seed)."""
        side, centre = self.side, self.radius + 1
        cells = ((start.vertices[:, 0] + centre) * side + start.vertices[:, 1] + centre) * side + start.vertices[:, 2] + centre
        step = {int(d): m for m, d in enumerate(self.forward_step)}
        anchors = np.minimum(cells[start.edges[:, 0]], cells[start.edges[:, 1]])
        rows = 1 + np.array([step[int(d)] for d in np.abs(cells[start.edges[:, 1]] - cells[start.edges[:, 0]])], dtype=np.int64)
        for p in range(self.population):
            offset = p * self.volume
            self.state[0, torch.as_tensor(cells + offset)] = True
            self.state[torch.as_tensor(rows), torch.as_tensor(anchors + offset)] = True

    def run(self, every_step: bool = False) -> list[list[Structure]]:
        """The structures at the end (one list), or after every step from the lone seed on (one list a step, until
        every structure has stopped)."""
        frames = [self._structures()] if every_step else []
        for _ in range(self.config.iterations):
            if not self.active.any():
                break
            self._step()
            if every_step and self.active.any():
                frames.append(self._structures())
        if every_step:  # the last frame again, now with its final growth metadata (caps hit, fixed point)
            frames[-1] = self._structures()
            return frames
        return [self._structures()]

    def _cube_flags(self, per_structure: torch.Tensor) -> torch.Tensor:
        """Broadcast a ``(P,)`` bool to every cell (the padding cube gets False)."""
        return torch.cat([per_structure, per_structure.new_zeros(1)]).repeat_interleave(self.volume)

    # -- one growth step ------------------------------------------------------------------------------------------
    def _read(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Cells of the growing structures in a padded ``(P, rows)`` layout, and their 52 input flags."""
        occupied = self.state[0]
        growing = occupied if bool(self.active.all()) else occupied & self._cube_flags(self.active)
        cells = torch.nonzero(growing).squeeze(1)
        owner = torch.div(cells, self.volume, rounding_mode="floor")
        counts = torch.bincount(owner, minlength=self.population)
        rank = torch.arange(len(cells)) - (torch.cumsum(counts, 0) - counts)[owner]
        rows = torch.full((self.population, int(counts.max())), self.padding_cell, dtype=torch.int64)
        rows[owner, rank] = cells

        return rows, torch.take(self.state, rows[..., None] + self.input_lookup).float()

    def _decide(self, flags: torch.Tensor) -> torch.Tensor:
        """``(P, rows, 26)`` firing decisions for float32 input flags, exact up to float64 rounding."""
        hidden = torch.baddbmm(self.b1, flags, self.w1).clamp_(min=0)
        margin = torch.baddbmm(self.b2, hidden, self.w2).sub_(self.threshold)
        fires = margin > 0
        unsure = (margin.abs_() <= self.tolerance).any(-1)
        if bool(unsure.any()):
            # Recompute the doubtful rows in float64, structure by structure so each uses its own weights as they
            # are (a padded batch would be sized by the structure with the most doubtful rows).
            p, r = torch.nonzero(unsure, as_tuple=True)
            x = flags[p, r].double()
            exact = torch.empty((len(p), N_OUTPUTS), dtype=torch.bool)
            w1, b1, w2, b2 = self.exact
            start = 0
            for q, count in enumerate(torch.bincount(p, minlength=self.population).tolist()):
                if count:
                    h = torch.addmm(b1[q], x[start : start + count], w1[q]).clamp_(min=0)
                    exact[start : start + count] = torch.addmm(b2[q], h, w2[q]) > self.threshold
                    start += count
            fires[p, r] = exact
        return fires

    def _step(self) -> None:
        rows, flags = self._read()
        wishes = self._decide(flags) & (rows != self.padding_cell)[..., None]  # (P, rows, 26)
        if self.boxes is None and self.reach + int(self.steps_run.max()) < self.radius:  # within reach + steps run
            leaves_box = torch.zeros_like(self.active)
        else:
            leaves_box = (wishes & ~torch.take(self.in_box, rows[..., None] + self.delta)).flatten(1).any(1)

        wished = self.wished.zero_()
        # Padding rows repeat one cell, but their wishes are all False, so the order of those writes does not matter.
        wished.index_copy_(1, rows.reshape(-1), wishes.reshape(-1, N_NEIGHBOURS).T)
        grantable = self.state[0] | self.buildable
        state = torch.zeros_like(self.state)
        occupied, joined = state[0], state[1:]
        n = self.n_cells
        for m, step in enumerate(self.forward_step):
            # Edge a -- a + step exists iff a wishes forward (and a + step may hold a vertex) or a + step wishes
            # backward (and a may hold one).
            forward = wished[N_DIRECTIONS + m, : n - step] & grantable[step:]
            backward = wished[N_DIRECTIONS - 1 - m, step:] & grantable[: n - step]
            edge = joined[m, : n - step]
            torch.logical_or(forward, backward, out=edge)
            occupied[: n - step] |= edge
            occupied[step:] |= edge
        occupied[self.seed_cells] = True

        counts = occupied.view(self.population + 1, self.volume).sum(1)[: self.population]
        over = self.active & (counts > self.config.max_vertices)
        changed = (state != self.state).view(1 + N_DIRECTIONS, self.population + 1, self.volume)[:, : self.population]
        still = self.active & ~changed.any(2).any(0)
        advancing = self.active & ~over & ~still
        self.hit_max_vertices |= over
        self.reached_fixed_point |= still
        self.hit_max_extent |= self.active & ~over & leaves_box
        self.steps_run += advancing.long()
        if bool(advancing.all()):
            self.state = state
        else:  # structures that stop (now or earlier) keep their previous state
            self.state = torch.where(self._cube_flags(~advancing), self.state, state)
        self.active = advancing

    # -- results --------------------------------------------------------------------------------------------------
    def _structures(self) -> list[Structure]:
        side, volume = self.side, self.volume
        occupied = self.state[0].numpy()
        cells = np.flatnonzero(occupied)
        number = np.cumsum(occupied) - 1  # vertex number of every occupied cell, counted across the population
        local = cells % volume
        coords = np.stack([local // (side * side), (local // side) % side, local % side], axis=1) - (self.radius + 1)
        vertex_starts = np.searchsorted(cells, np.arange(self.population + 1) * volume)

        # Cell-major order lists edges by smaller endpoint, then by direction, which is by larger endpoint.
        anchor, direction = np.divmod(np.flatnonzero(self.state[1:].T.contiguous().numpy()), N_DIRECTIONS)
        first = number[anchor]
        second = number[anchor + np.asarray(self.forward_step)[direction]]
        edge_starts = np.searchsorted(anchor, np.arange(self.population + 1) * volume)

        settings = asdict(self.config)
        structures = []
        for p in range(self.population):
            v0, v1 = vertex_starts[p], vertex_starts[p + 1]
            e0, e1 = edge_starts[p], edge_starts[p + 1]
            pairs = np.stack([first[e0:e1], second[e0:e1]], axis=1) - v0
            growth = {
                "generator": "local_nca",
                **settings,
                "iterations_run": int(self.steps_run[p]),
                "hit_max_vertices": bool(self.hit_max_vertices[p]),
                "hit_max_extent": bool(self.hit_max_extent[p]),
                "reached_fixed_point": bool(self.reached_fixed_point[p]),
                **({"box": self.boxes[p].tolist()} if self.boxes is not None else {}),
            }
            structures.append(Structure._trusted(coords[v0:v1], pairs, {"growth": growth}))
        return structures


def load_weights(path: str | os.PathLike, config: NCAConfig | None = None) -> np.ndarray:
    """Read one flat weight vector from ``.npy`` (a 1-D array) or ``.json`` (a list of numbers, or an object with a
    ``"weights"`` list); raise ValueError naming the file and the problem if it does not fit ``config``."""
    config = config or NCAConfig()
    return read_weights(path, n_params(config), f"a 52-{config.hidden}-26 NCA")


def save_weights(path: str | os.PathLike, weights: Any) -> Path:
    """Write a flat weight vector as ``.npy`` (exact) or ``.json`` (readable), atomically."""
    path = Path(path)
    weights = np.asarray(weights, dtype=np.float64).ravel()
    suffix = path.suffix.lower()
    if suffix == ".npy":
        buffer = io.BytesIO()
        np.save(buffer, weights, allow_pickle=False)
        return atomic_write(path, buffer.getvalue())
    if suffix == ".json":
        # repr-precision floats round-trip exactly through JSON.
        return atomic_write(path, json.dumps({"weights": weights.tolist()}) + "\n")
    raise ValueError(f"{path}: unknown weights format {path.suffix!r}; use .npy or .json")
