"""A stable structure to a spec (a footprint, a height, a member budget) in well under a second, grown by an NCA.

How. An NCA grows the same local rule whatever box it grows in (:func:`structgen.nca.grow_population`'s ``boxes``):
grown in a box of the spec's footprint and height, a rule that reaches the box's walls gives a structure of exactly
that footprint and height. Which NCAs, in which boxes, meet which specs and stand is found once, by quality
diversity, and kept in a small *library*: :func:`design` looks the spec up, grows one of the library's answers
(milliseconds) and checks it with the static analysis (milliseconds), so a design costs far less than a second.

The library (:func:`build_library`, ``structgen design-library``) holds NCAs of two families: ``down``, the taught
towers' kind (cutoff 0.5, building down from a seed at the top), and ``up``, the evolved kind (cutoff 0.6, no
building below a seed on the ground). Its search is MAP-Elites over the spec grid (footprint width, depth and height
in levels), the archive a pyribs ``GridArchive`` per family whose objective is the safety margin (1 - the largest
member load over the break force): parents drawn from the archive's elites are mutated, each child is grown in boxes
of randomly drawn specs (its seed placed near the box's middle), and every exact, standing result goes into the
archive and the list of answers. It starts from the NCAs that ship in ``docs/``, random ones, and pyramids taught
for the purpose (:func:`taught_pyramids`: for each height and odd width, the lightest standing one-rule-per-level
design, taught in a second or two). At the end a
greedy cover keeps the few NCAs that answer the most specs (several answers each, for variety), which are then
grown in every spec's box to list everything they meet. Last come *tilings* (:func:`taught_tilings`,
:func:`add_taught`): a pyramid spreads at most a cell a level each way, so no single one is wider than twice its
height, but pyramids side by side sharing their feet are, and carry no more than one; NCAs taught to grow them in
a box wider than tall (and walls one cell thick, end to end, in a box one cell thick) meet the wide, low specs (9x9
at three levels, 1x11 at four) the search leaves. Then the same rules cut to narrow boxes (:func:`taught_clipped`),
which meet some narrow, tall specs no pyramid reaches. Last, the static analysis being lenient near the break
force, every answer it loads above 70 % of it is simulated for PyBullet's first 0.3 s and dropped if a joint would
break there (:func:`screened`). Then designs searched in the boxes of the specs still unmet (:func:`taught_boxed`:
even sides, boxes longer than wide), their answers screened alike; and last, for specs wider than one met at
their height, the met answer set on a floor mat that fills the wider footprint (:func:`taught_on_mats`). Weights
are kept as float32, as the file stores them.

A spec is ``width x depth`` cells on the ground (x by y) and ``height`` levels (z extent ``height - 1``); a spec
with width over depth is met by a depth-by-width answer turned a quarter. Different seeds pick different answers
(another NCA or another seed placement), where the library has more than one.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import math
import random
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from evolution.files import atomic_write
from structgen.domains.structures.samples import Box
from structgen.nca import NCAConfig, grow_population, n_params
from structgen.structure import Structure

__all__ = [
    "DEFAULT_LIBRARY",
    "DesignLibrary",
    "Spec",
    "UnmeetableSpec",
    "above_ground",
    "build_library",
    "canonical_specs",
    "design",
    "load_library",
    "on_a_mat",
    "tallest_possible",
    "with_mat_flags",
]

DEFAULT_LIBRARY = Path(__file__).with_name("design_library.npz")
# The spec grid the library covers: footprints up to MAX_SIDE x MAX_SIDE, heights up to MAX_LEVELS.
MAX_SIDE, MAX_LEVELS = 11, 8
#: Answers the static analysis loads above this share of the break force are also simulated (:func:`screened`).
SCREEN_ABOVE_SHARE = 0.7
# A seed never lies more than this far from any cell of its box, which bounds the growth grid (and its cost).
REACH = 7
# Denser structures than this do not stand at these sizes (the taught eight levels on 11 x 11 have 245 vertices),
# and growth past it is stopped early, which keeps the search cheap.
MAX_VERTICES = 400
FAMILIES = {
    "down": NCAConfig(iterations=14, cutoff=0.5, build_down=True, max_extent=REACH, max_vertices=MAX_VERTICES),
    "up": NCAConfig(iterations=14, cutoff=0.6, build_down=False, max_extent=REACH, max_vertices=MAX_VERTICES),
}
# The NCAs in docs/ the search starts from, by family.
STARTS = {
    "down": ("tall_grown_7.npy", "tall_grown_8.npy"),
    "up": ("large_flat_nca.npy", "tall_five_levels_nca.npy", "tall_six_level_refined.npy", "tall_elite_start.npy"),
}


class UnmeetableSpec(ValueError):
    """No answer in the library meets the spec; the message names the nearest spec that can be met."""


@dataclass(frozen=True)
class Spec:
    """``width`` x ``depth`` cells on the ground, ``height`` levels, at most ``max_members`` edges (None: any)."""

    width: int
    depth: int
    height: int
    max_members: int | None = None

    def __post_init__(self) -> None:
        for name in ("width", "depth", "height"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not 1 <= value <= 10_000:
                raise ValueError(f"spec {name} must be a whole number from 1 to 10,000, got {value!r}")
        if self.max_members is not None and (not isinstance(self.max_members, (int, np.integer)) or self.max_members < 0):
            raise ValueError(f"spec max_members must be a whole number of at least 0, got {self.max_members!r}")

    def __str__(self) -> str:
        budget = f", at most {self.max_members} members" if self.max_members is not None else ""
        return f"footprint {self.width}x{self.depth}, height {self.height}{budget}"


def box_for(width: int, depth: int, height: int, family: str, x_seed: int, y_seed: int) -> np.ndarray:
    """The growth box of a spec with the seed ``x_seed``, ``y_seed`` cells from the box's low corner: on the top
    level for the ``down`` family, on the ground for ``up``."""
    z = [-(height - 1), 0] if family == "down" else [0, height - 1]
    return np.array([[-x_seed, width - 1 - x_seed], [-y_seed, depth - 1 - y_seed], z], dtype=np.int64)


def _seed_places(side: int) -> range:
    """Where along a side of ``side`` cells a seed may sit: within REACH of both ends."""
    return range(max(0, side - 1 - REACH), min(side - 1, REACH) + 1)


def dimensions(structure: Structure) -> tuple[int, int, int]:
    """(width, depth, height in levels) of a structure's bounding box."""
    return tuple(int(v) for v in np.ptp(structure.vertices, axis=0) + 1)  # type: ignore[return-value]


def above_ground(structure: Structure) -> tuple[int, int] | None:
    """(width, depth) of the cells a structure's vertices above its lowest level cover (None for one level): the
    footprint of what stands on the ground, which a tower on a floor mat keeps smaller than its own."""
    vertices = structure.vertices
    raised = vertices[vertices[:, 2] > vertices[:, 2].min()]
    if not len(raised):
        return None
    return tuple(int(v) for v in np.ptp(raised[:, :2], axis=0) + 1)  # type: ignore[return-value]


def on_a_mat(structure: Structure) -> bool:
    """Whether ``structure`` stands on a floor mat (as :func:`.samples.on_mat` makes and :func:`taught_on_mats`
    teaches): part of its lowest level lies more than a cell beyond the footprint of the levels above, where no member
    from above can reach (they reach a cell sideways at most), so it is floor joined along the ground. A design that
    meets a spec so is honest to it (the footprint is what touches the ground, and it stands), but is a smaller tower
    on a floor rather than a frame that fills the footprint, which a user may want to know."""
    raised = structure.vertices[structure.vertices[:, 2] > structure.vertices[:, 2].min()]
    if not len(raised):
        return False
    low, high = raised[:, :2].min(axis=0) - 1, raised[:, :2].max(axis=0) + 1
    ground = structure.vertices[structure.vertices[:, 2] == structure.vertices[:, 2].min(), :2]
    return bool(((ground < low) | (ground > high)).any())


def _shape_key(structure: Structure) -> bytes:
    vertices = structure.vertices - structure.vertices.min(axis=0)
    return hashlib.sha1(vertices.tobytes() + structure.edges.tobytes()).digest()[:8]


def _cells_key(structure: Structure) -> bytes:
    """The same for the same cells and members, whatever order growth listed them in. (:func:`_shape_key`, which
    keeps two orders apart, still decides which answers a library lists, so that the same options give the same
    library as before this key.)"""
    ordered = structure.in_growth_order()
    vertices = ordered.vertices - ordered.vertices.min(axis=0)
    return hashlib.sha1(vertices.tobytes() + ordered.edges.astype(np.int64).tobytes()).digest()[:8]


@dataclass
class DesignLibrary:
    """NCAs and the specs they meet: ``answers`` rows of (nca, width, depth, height, x_seed, y_seed, edges, vertices)
    with ``peaks`` (the largest member load over the break force), widths never above depths; ``on_mat``, where
    known (:func:`with_mat_flags`), says which answers are a smaller tower on a floor mat, so that :func:`design`
    can offer those last."""

    families: list[str]
    weights: np.ndarray  # (K, n_params) float32
    answers: np.ndarray  # (M, 8) int32
    peaks: np.ndarray  # (M,) float32
    info: dict[str, Any] = field(default_factory=dict)
    on_mat: np.ndarray | None = None  # (M,) bool

    COLUMNS = ("nca", "width", "depth", "height", "x_seed", "y_seed", "edges", "vertices")

    def save(self, path: str | Path) -> Path:
        buffer = io.BytesIO()
        flags = {} if self.on_mat is None else {"on_mat": self.on_mat.astype(bool)}
        np.savez_compressed(
            buffer, weights=self.weights.astype(np.float32), answers=self.answers.astype(np.int32),
            peaks=self.peaks.astype(np.float32), families=np.array(self.families),
            info=np.array(json.dumps(self.info)), **flags,
        )  # fmt: skip
        return atomic_write(path, buffer.getvalue())

    def config(self, nca: int) -> NCAConfig:
        return FAMILIES[self.families[nca]]

    def specs(self) -> set[tuple[int, int, int]]:
        return {tuple(int(v) for v in row[1:4]) for row in self.answers}  # type: ignore[misc]

    def candidates(self, spec: Spec) -> tuple[np.ndarray, bool]:
        """Rows of the answers that meet ``spec`` (within its member budget), and whether they are turned (the spec's
        width over its depth)."""
        turned = spec.width > spec.depth
        width, depth = (spec.depth, spec.width) if turned else (spec.width, spec.depth)
        rows = (self.answers[:, 1] == width) & (self.answers[:, 2] == depth) & (self.answers[:, 3] == spec.height)
        if spec.max_members is not None:
            rows &= self.answers[:, 6] <= spec.max_members
        return np.flatnonzero(rows), turned

    def nearest(self, spec: Spec) -> Spec | None:
        """The meetable spec nearest ``spec`` (fewest cells of width, depth and height apart; then the larger)."""
        rows = self.answers if spec.max_members is None else self.answers[self.answers[:, 6] <= spec.max_members]
        if not len(rows):
            return None
        met = np.unique(rows[:, 1:4], axis=0)
        both = np.concatenate([met, met[:, [1, 0, 2]]])  # either way round
        distance = np.abs(both - [spec.width, spec.depth, spec.height]).sum(axis=1)
        best = both[np.lexsort((-both.sum(axis=1), distance))[0]]
        return Spec(int(best[0]), int(best[1]), int(best[2]), spec.max_members)


#: A library file may hold this much on disk and unpacked (the shipped one: 2.9 MB, 3.9 MB unpacked).
MAX_LIBRARY_BYTES, MAX_LIBRARY_UNPACKED = 64 << 20, 256 << 20
#: No answer's box may be wider, deeper or taller than this (the shipped library's reach 11 cells and 8 levels):
#: growing one allocates its box.
MAX_LIBRARY_SIDE = 64


def load_library(path: str | Path | None = None) -> DesignLibrary:
    """The library at ``path`` (default: the one that ships with structgen), read through the file gate and checked
    field by field: a damaged or foreign file is an error naming the file and the field, before anything is grown."""
    from evolution.files import InputFileError, parse_json, read_npz
    from structgen.errors import InputError

    path = Path(path) if path is not None else DEFAULT_LIBRARY
    if not path.exists() and not path.is_symlink():
        raise InputError(f"{path}: no design library there (build one with structgen design-library)")
    try:
        arrays = read_npz(path, MAX_LIBRARY_BYTES, MAX_LIBRARY_UNPACKED, text=True)
    except InputFileError as err:
        raise InputError(str(err)) from None

    def field_of(name: str, kinds: str, ndim: int) -> np.ndarray:
        if name not in arrays:
            raise InputError(f"{path}: not a design library (no {name!r} array; it holds {', '.join(arrays) or 'none'})")
        array = arrays[name]
        if array.dtype.kind not in kinds or array.ndim != ndim:
            raise InputError(f"{path}: {name} is {array.dtype} of shape {array.shape}; a design library's is not")
        return array

    families = [str(f) for f in field_of("families", "U", 1)]
    weights = field_of("weights", "f", 2)
    answers = field_of("answers", "iu", 2)
    peaks = field_of("peaks", "f", 1)
    info_text = field_of("info", "U", 0)
    on_mat = field_of("on_mat", "bu", 1) if "on_mat" in arrays else None
    bad = sorted({f for f in families if f not in FAMILIES})
    if bad:
        raise InputError(f"{path}: families {bad} are not NCA families of this structgen ({', '.join(FAMILIES)})")
    if weights.shape != (len(families), n_params(FAMILIES["down"])):
        raise InputError(f"{path}: weights of shape {weights.shape}; {len(families)} NCAs of this structgen need "
                         f"({len(families)}, {n_params(FAMILIES['down'])})")  # fmt: skip
    if not np.isfinite(weights).all():
        raise InputError(f"{path}: weights hold NaN or infinity")
    if answers.shape[1:] != (len(DesignLibrary.COLUMNS),) or peaks.shape != answers.shape[:1]:
        raise InputError(f"{path}: answers of shape {answers.shape} and peaks of {peaks.shape}; expected (M, 8) and (M,)")
    if on_mat is not None and (on_mat.shape != answers.shape[:1] or not np.isin(on_mat, (0, 1)).all()):
        raise InputError(f"{path}: on_mat of shape {on_mat.shape} is not one flag (0 or 1) an answer")
    _check_answers(path, answers.astype(np.int64), len(families))
    if not (np.isfinite(peaks) & (peaks >= 0)).all():
        raise InputError(f"{path}: peaks hold a value that is not a finite share of the break force")
    try:
        info = parse_json(str(info_text), f"{path}: info")
    except InputFileError as err:
        raise InputError(str(err)) from None
    if not isinstance(info, dict):
        raise InputError(f"{path}: info is not a JSON object")
    return DesignLibrary(
        families=families, weights=weights.astype(np.float64), answers=answers.astype(np.int32), peaks=peaks,
        info=info, on_mat=None if on_mat is None else on_mat.astype(bool),
    )  # fmt: skip


def _check_answers(path: Path, answers: np.ndarray, ncas: int) -> None:
    """Every answer names an NCA of the library, a box of 1 to :data:`MAX_LIBRARY_SIDE` cells each way with its seed
    inside, and counts of members and vertices that are not negative."""
    from structgen.errors import InputError

    nca, width, depth, height, x_seed, y_seed, edges, vertices = answers.T
    problems = {
        "nca": (nca < 0) | (nca >= ncas),
        "width": (width < 1) | (width > MAX_LIBRARY_SIDE),
        "depth": (depth < 1) | (depth > MAX_LIBRARY_SIDE),
        "height": (height < 1) | (height > MAX_LIBRARY_SIDE),
        "x_seed": (x_seed < 0) | (x_seed >= width),
        "y_seed": (y_seed < 0) | (y_seed >= depth),
        "edges": edges < 0,
        "vertices": vertices < 1,
    }
    for name, wrong in problems.items():
        if wrong.any():
            row = int(np.flatnonzero(wrong)[0])
            raise InputError(f"{path}: answers[{row}] has {name} {int(answers[row, DesignLibrary.COLUMNS.index(name)])}, "
                             f"out of range ({int(wrong.sum())} answers so)")  # fmt: skip


def _turned(structure: Structure) -> Structure:
    """A quarter turn about the vertical: (x, y, z) -> (-y, x, z), so width and depth swap."""
    vertices = structure.vertices[:, [1, 0, 2]] * [-1, 1, 1]
    return Structure(vertices, structure.edges, structure.metadata)


def _grow_answer(library: DesignLibrary, row: np.ndarray) -> Structure:
    nca, width, depth, height, x_seed, y_seed = (int(v) for v in row[:6])
    family = library.families[nca]
    box = box_for(width, depth, height, family, x_seed, y_seed)
    return grow_population(library.weights[nca][None], FAMILIES[family], box[None])[0]


def _grown(weights: np.ndarray, families: list[str], ncas: np.ndarray, places: np.ndarray) -> Iterator[tuple[int, Structure]]:
    """``(i, structure)`` for each ``i``: NCA ``ncas[i]`` grown in the box of ``places[i]`` (width, depth, height,
    x_seed, y_seed), a family at a time in batches of 512."""
    for family in FAMILIES:
        mine = np.flatnonzero([families[int(n)] == family for n in ncas])
        for start in range(0, len(mine), 512):
            part = mine[start : start + 512]
            boxes = np.stack([box_for(*map(int, places[i, :3]), family, *map(int, places[i, 3:5])) for i in part])
            yield from zip(part.tolist(), grow_population(weights[ncas[part]], FAMILIES[family], boxes))


def with_mat_flags(library: DesignLibrary) -> DesignLibrary:
    """``library`` with ``on_mat`` set: every answer grown (:func:`_grown`, as :func:`_judge` grows them) and asked
    :func:`on_a_mat`. A few milliseconds an answer; :func:`build_library` does it last."""
    flags = np.zeros(len(library.answers), dtype=bool)
    for i, structure in _grown(library.weights, library.families, library.answers[:, 0], library.answers[:, 1:6]):
        flags[i] = on_a_mat(structure)
    return DesignLibrary(library.families, library.weights, library.answers, library.peaks, library.info, flags)


def tallest_possible(
    width: int, depth: int, physics: Any = None, cap: int = 100, *, axial: bool = False, sharing: float = 1.0
) -> int:
    """The most levels any structure of a ``width`` x ``depth`` footprint could have that the static analysis finds
    standing (``physics``: a :class:`physics.PhysicsConfig`, default the paper's), by equilibrium alone. Cut between
    two levels, everything above is held up only by the members crossing the cut, through the joints at their lower
    ends, and the verdict lets each carry at most the break force over the load factor, its own weight included.
    Counting the fewest bodies above each cut (a vertex a level, no more members than carry the load there, every
    load shared perfectly) bounds the height: 3 levels for a 1x1 footprint (a column of four breaks), 11 for 2x2.
    An upper bound, not a design: real frames share their load unevenly (``benchmarks/design_limits.py --bound``).

    Two assumptions tighten it into a model of what a design must achieve (``benchmarks/tall_sharing.py``):
    ``axial`` lets a member carry load only along its axis, so a diagonal's joint takes the vertical load it passes
    down over the cosine of its slope (side diagonals 1.41 times it, corner diagonals 1.73 times); ``sharing`` is how
    far the most loaded member of a cut is above the even share (1: every member alike; PyBullet's spawn transient
    alone puts 1.16 to 1.24 on a lone member), dividing what each member may carry. Neither is a law of the physics
    (fixed joints let a diagonal pass load by bending), so with either the result is no longer a bound."""
    from physics import PhysicsConfig

    physics = physics or PhysicsConfig()
    if physics.sphere_mass != physics.cylinder_mass:
        raise ValueError("the bound counts bodies: spheres and cylinders must weigh alike")
    if not (isinstance(sharing, (int, float)) and 1.0 <= sharing < math.inf):
        raise ValueError(f"sharing must be a number from 1 (every member loaded alike) up, got {sharing!r}")
    body = physics.sphere_mass * physics.gravity
    limit = physics.break_force / physics.statics_load_factor / sharing
    across, along = min(3, width) - 1, min(3, depth) - 1  # cells a member can reach sideways within the footprint
    below_each = (across + 1) * (along + 1)  # members a vertex can send to the level below within the footprint
    # (bodies a member holds up above the cut, its own weight being on its lower joint too; members a vertex sends)
    if axial:
        slopes = ((1.0, 1), (math.sqrt(0.5), across + along), (math.sqrt(1 / 3), across * along))
        kinds = sorted(((limit * cosine - body) / body, count) for cosine, count in slopes if count)[::-1]
    else:
        kinds = [((limit - body) / body, below_each)]
    kinds = [(holds, count) for holds, count in kinds if holds > 0]
    if not kinds:
        return 1  # no member can even hold itself up: only the top level's vertices, lying on the ground
    crossing_cap = (3 * width - 2) * (3 * depth - 2)  # pairs of cells one level apart and at most a cell sideways

    def fewest(above: float, vertices: int) -> list[int] | None:
        """Members of each kind, strongest first, that hold ``above`` bodies from ``vertices`` vertices (None: they
        cannot)."""
        counts = []
        for holds, count in kinds:
            counts.append(min(count * vertices, math.ceil(above / holds - 1e-9)))
            above -= counts[-1] * holds
            if above <= 1e-9:
                return counts
        return None

    above, vertices, levels = 1.0, 1, 1  # the top level: one vertex
    while levels < cap:
        counts = fewest(above, vertices)
        if counts is None:  # more vertices on the upper level to send them from: the fewest that hold, if any do
            # Each vertex more adds one body to hold and the same capacity every time, so whether k more hold is
            # monotone in k: a bisection finds the fewest (a 10,000 x 10,000 footprint took minutes one by one).
            room = width * depth - vertices
            if room <= 0 or fewest(above + room, vertices + room) is None:
                return levels
            low, high = 0, room
            while high - low > 1:
                middle = (low + high) // 2
                low, high = (middle, high) if fewest(above + middle, vertices + middle) is None else (low, middle)
            vertices, above = vertices + high, above + high
            counts = fewest(above, vertices)
        members = sum(counts)
        if members > crossing_cap or vertices > width * depth:
            return levels
        # The level below: as few vertices as take the members, each taking at most its share of every kind.
        vertices = max(1, math.ceil(members / below_each), *(math.ceil(n / c) for n, (_, c) in zip(counts, kinds)))
        above += members + vertices
        levels += 1
    return levels


def design(
    spec: Spec, seed: int = 0, library: DesignLibrary | None = None, physics: Any = None, *, mats: bool = True
) -> Structure:
    """A structure grown by one of the library's NCAs that meets ``spec`` exactly and that the static analysis finds
    standing; ``seed`` picks among the answers. :class:`UnmeetableSpec` names the nearest spec that can be met.
    ``mats=False`` passes over answers that are a smaller tower on a floor mat (:func:`on_a_mat`)."""
    from physics.statics import check_statics

    library = library or load_library()
    rows, turned = library.candidates(spec)
    if not len(rows):
        nearest = library.nearest(spec)
        where = f"; the nearest that can be met: {nearest}" if nearest else "; no spec within that member budget can be met"
        possible = tallest_possible(spec.width, spec.depth, physics)
        if spec.height > possible:  # not the library's gap: nothing of that footprint stands so tall
            where += f" (no structure on a {spec.width}x{spec.depth} footprint stands over {possible} levels)"
        raise UnmeetableSpec(f"no design in the library meets {spec}{where}")
    order = rows[np.random.default_rng(seed).permutation(len(rows))]
    if library.on_mat is not None:  # answers that fill the footprint first; a tower on a mat only where none stands
        order = np.concatenate([order[~library.on_mat[order]], order[library.on_mat[order]]])
    matted = 0
    for row in order:
        structure = _grow_answer(library, library.answers[row])
        if turned:
            structure = _turned(structure)
        if dimensions(structure) != (spec.width, spec.depth, spec.height):
            continue  # cannot happen with a library built by this code; checked all the same
        if not mats and on_a_mat(structure):
            matted += 1
            continue
        report = check_statics(structure, physics)
        if not report.stands:
            continue
        nca, _, _, _, x_seed, y_seed = (int(v) for v in library.answers[row][:6])
        return structure.with_metadata(design={
            "spec": asdict(spec), "seed": seed, "nca": nca, "family": library.families[nca], "seed_place": [x_seed, y_seed],
            "turned": turned, "answers": int(len(rows)), "library": library.info.get("name", "design library"),
            "on_mat": on_a_mat(structure), "above_ground": above_ground(structure),
        })  # fmt: skip
    if matted == len(rows):
        raise UnmeetableSpec(f"all {len(rows)} answers for {spec} are towers on a floor mat, which were refused")
    if matted:
        raise UnmeetableSpec(f"{matted} of the {len(rows)} answers for {spec} are towers on a floor mat, which were "
                             "refused, and none of the others stands under these physics settings")  # fmt: skip
    raise UnmeetableSpec(f"none of the {len(rows)} answers for {spec} stands under these physics settings")


# -- building the library -----------------------------------------------------------------------------------------------
def canonical_specs(max_side: int = MAX_SIDE, max_levels: int = MAX_LEVELS) -> np.ndarray:
    """Every spec of the grid with width at most depth (a wider one is met by its answer turned a quarter): the 528
    specs of the documented range, by default."""
    return np.array([(w, d, h) for w in range(1, max_side + 1) for d in range(w, max_side + 1) for h in range(1, max_levels + 1)])


@dataclass
class _Found:
    """Answers found so far: one per distinct structure of a spec."""

    rows: list[tuple[int, ...]] = field(default_factory=list)
    peaks: list[float] = field(default_factory=list)
    seen: set[tuple[tuple[int, int, int], bytes]] = field(default_factory=set)
    # Each distinct structure is judged once: its largest load share, or None where it does not stand. Many tries
    # grow the same structure (a tiling's seed one period along, say), and the static analysis is the cost.
    judged: dict[tuple[tuple[int, int, int], bytes], float | None] = field(default_factory=dict)


def _judge(
    weights: np.ndarray, ids: list[int], families: list[str], tries: np.ndarray, found: _Found
) -> list[tuple[int, np.ndarray, float]]:
    """Grow NCA ``ids[i]`` in each of its tries' boxes ((nca position, width, depth, height, x_seed, y_seed) rows),
    keep the exact, standing results in ``found``; (position, spec, margin) of each."""
    from physics.statics import overload_ratio
    from structgen.domains.structures.stress import member_load_shares

    successes: list[tuple[int, np.ndarray, float]] = []
    if not len(tries):
        return successes
    for i, structure in _grown(weights, families, np.asarray(ids)[tries[:, 0]], tries[:, 1:6]):
        t = tries[i]
        spec = tuple(int(v) for v in t[1:4])
        if dimensions(structure) != spec:
            continue
        key, cells = (spec, _shape_key(structure)), (spec, _cells_key(structure))
        if cells not in found.judged:
            found.judged[cells] = None
            if overload_ratio(structure) <= 1.0:  # a bound, linear in size: above it some joint is overloaded
                report, shares = member_load_shares(structure)
                if report.stands:
                    found.judged[cells] = float(np.nanmax(shares)) if structure.n_edges else 0.0
        peak = found.judged[cells]
        if peak is None:
            continue
        successes.append((int(t[0]), np.array(spec), 1.0 - peak))
        if key in found.seen:
            continue
        found.seen.add(key)
        found.rows.append((ids[int(t[0])], *spec, int(t[4]), int(t[5]), structure.n_edges, structure.n_vertices))
        found.peaks.append(peak)
    return successes


def _random_tries(rng: np.random.Generator, count: int, specs_each: int, specs: np.ndarray) -> np.ndarray:
    """``specs_each`` of ``specs`` at random for each of ``count`` NCAs, seeds in the middle of the box for half of
    them (where taught pyramids meet their specs) and anywhere within REACH for the rest."""
    rows = []
    for position in range(count):
        for w, d, h in specs[rng.choice(len(specs), min(specs_each, len(specs)), replace=False)]:
            if rng.random() < 0.5:
                x_seed, y_seed = (int(rng.integers((side - 1) // 2, side // 2 + 1)) for side in (w, d))
            else:
                x_seed, y_seed = (int(rng.choice(_seed_places(side))) for side in (w, d))
            rows.append((position, w, d, h, x_seed, y_seed))
    return np.array(rows, dtype=np.int64)


def _lightest_first(by_width: dict[int, list[tuple]], min_width: int = 1) -> list[tuple]:
    """The entries of one height of :func:`_lightest_by_level`, of every width from ``min_width``, lightest first
    (ties by rules, then tied levels, so the order repeats)."""
    entries = (entry for width, listed in by_width.items() if width >= min_width for entry in listed)
    return sorted(entries, key=lambda entry: (entry[0], entry[1], entry[2]))


def _lightest_by_level(
    max_side: int, max_levels: int, beam: int, wall: bool = False, extent: int | Box | None = None, per_width: bool = True
) -> Iterator[tuple[int, dict[int, list[tuple]]]]:
    """For each height from 2 to ``max_levels``: the one-rule-per-level designs (:func:`.samples.by_level_rules`,
    one cell thick with ``wall``, cut ``extent`` cells from their axis when given) a local rule grows, by width (the
    longer side) up to ``max_side``, each list lightest first (its largest static joint load, held and sliding
    ground) as ``(load, rules, tied_levels, design)``. A beam search from the top down keeps the ``beam`` lightest of
    each width (of all, without ``per_width``) at each height to extend."""
    from physics.statics import bounding_loads
    from structgen.domains.structures.samples import by_level_rules_one_taller
    from structgen.domains.structures.tall import teachable

    def load(structure: Structure) -> float:
        loads = bounding_loads(structure) if structure.n_edges else np.zeros(1)
        return float(np.nanmax(loads)) if np.isfinite(loads).any() else math.inf

    prefixes: list[tuple[str, ...]] = [()]
    for height in range(2, max_levels + 1):
        by_width: dict[int, list[tuple]] = {}
        for rules, tied, candidate in by_level_rules_one_taller(prefixes, MAX_VERTICES, extent, wall=wall):
            width, depth, levels = dimensions(candidate)
            width = max(width, depth)
            if width > max_side or levels != height or not teachable(candidate, whole=False):
                continue
            by_width.setdefault(width, []).append((load(candidate), rules, tied, candidate))
        for width in by_width:
            by_width[width].sort(key=lambda entry: (entry[0], entry[1], entry[2]))
        yield height, by_width
        if per_width:
            prefixes = list(dict.fromkeys(rules for width in sorted(by_width) for _, rules, _, _ in by_width[width][:beam]))
        else:
            prefixes = list(dict.fromkeys(rules for _, rules, _, _ in _lightest_first(by_width)))[:beam]


def taught_pyramids(
    max_side: int = MAX_SIDE, max_levels: int = MAX_LEVELS, beam: int = 4
) -> list[tuple[tuple[int, int], np.ndarray]]:
    """For each height and odd width a one-rule-per-level design can have (:func:`.samples.by_level_rules`), the
    design of that footprint that carries least among those a local rule grows and that stand, taught to an NCA of
    the ``down`` family: ``((width, height), weights)``. Grown in the boxes of narrower or rectangular footprints, the
    same NCAs answer those too."""
    from physics.statics import check_statics
    from structgen.domains.structures.tall import teachable
    from structgen.domains.structures.teach import TeachError, teach

    taught = []
    for height, by_width in _lightest_by_level(max_side, max_levels, beam):
        for width in sorted(by_width):
            for _, _, _, candidate in by_width[width]:
                if not teachable(candidate, whole=True) or not check_statics(candidate).stands:
                    continue
                try:
                    result = teach(candidate)
                except TeachError:
                    continue
                taught.append(((width, height), result.weights))
                break
    return taught


def tiling_box(height: int, wall: bool = False) -> np.ndarray:
    """The box a tiling is taught in, around its middle top: REACH cells each way across (one cell thick for a
    wall), ``height`` levels down."""
    across = [0, 0] if wall else [-REACH, REACH]
    return np.array([across, [-REACH, REACH], [-(height - 1), 0]], dtype=np.int64)


def taught_tilings(
    max_side: int = MAX_SIDE, max_levels: int = MAX_LEVELS, beam: int = 4, per_height: int = 3, tries: int = 40
) -> list[tuple[int, np.ndarray]]:
    """For each height, NCAs that grow :func:`.samples.tiled_by_level_rules` tilings, taught in
    :func:`tiling_box`: ``(height, weights)``. Footprints wider than one design of the height can spread (over twice
    the height) are out of the pyramids' reach, while a tiling carries no more at its feet than one of its designs.
    The ``tries`` lightest designs of the height (any width from 3) are tiled in turn; the first ``per_height`` whose
    tiling stands across the largest footprint (the static analysis) and that a local rule grows are taught. Then
    the same for walls one cell thick (tiled along their length), which answer the 1-cell-wide specs."""
    from physics.statics import check_statics
    from structgen.domains.structures.samples import tiled_by_level_rules
    from structgen.domains.structures.teach import TeachError, teach

    taught = []
    for wall in (False, True):
        for height, by_width in _lightest_by_level(max_side, max_levels, beam, wall):
            ranked = _lightest_first(by_width, min_width=3)[:tries]
            kept = 0
            for _, rules, tied, _ in ranked:
                largest = tiled_by_level_rules(rules, tied, (max_side - 1) // 2, wall=wall)
                if largest is None or dimensions(largest)[2] != height or not check_statics(largest).stands:
                    continue
                target = tiled_by_level_rules(rules, tied, REACH, wall=wall)
                middle_top = np.flatnonzero((target.vertices == [0, 0, 0]).all(axis=1))
                try:
                    result = teach(target, seed_vertex=int(middle_top[0]), box=tiling_box(height, wall))
                except TeachError:
                    continue
                taught.append((height, result.weights))
                kept += 1
                if kept == per_height:
                    break
    return taught


def _lightest_by_class(
    rules: tuple[str, ...], tied: int, extent: int | Box, passes: int, rng: random.Random,
    footprint: tuple[int, int] | None = None,
) -> Structure | None:  # fmt: skip
    """From a one-rule-per-level design cut ``extent`` cells from its axis (or to a box), a first-improvement descent
    over a rule per in-degree class (:func:`.samples.level_rule_moves`) on the largest static load (held and sliding
    ground), among designs of the same height (and ``footprint``, when given) that a local rule grows whole; the
    lightest found (None when none is)."""
    from structgen.domains.structures.samples import IN_DEGREE_CLASSES, by_level_rules, level_rule_moves
    from structgen.domains.structures.tall import largest_static_load, teachable

    levels = len(rules) + 1

    def load(design: tuple[list, int]) -> tuple[float, Structure | None]:
        structure = by_level_rules(*design, extent)
        if (structure is None or structure.n_vertices > MAX_VERTICES or dimensions(structure)[2] != levels
                or (footprint is not None and dimensions(structure)[:2] != footprint)
                or not teachable(structure, whole=True)):  # fmt: skip
            return math.inf, None
        return largest_static_load(structure), structure

    best: tuple[list, int] = ([(rule,) * len(IN_DEGREE_CLASSES) for rule in rules], tied)
    best_load, best_structure = load(best)
    for _ in range(passes):
        improved = False
        for candidate in level_rule_moves(*best, rng):
            value, structure = load(candidate)
            if value < best_load - 1e-6:
                best, best_load, best_structure, improved = candidate, value, structure, True
        if not improved:
            break
    return best_structure


def taught_clipped(
    max_side: int = MAX_SIDE, max_levels: int = MAX_LEVELS, beam: int = 12, per_height: int = 3, lowest: int = 4,
    by_class_from: int | None = 5, class_extent: int = 5, starts: int = 2, passes: int = 3, seed: int = 0,
    one_rule: bool = True,
) -> list[tuple[int, np.ndarray]]:  # fmt: skip
    """Designs cut to narrow boxes, taught: ``(height, weights)``. A pyramid is only as wide as its height lets it
    spread, so the narrow, tall specs are out of its reach; cut ``e`` cells from its axis (``by_level_rules(...,
    extent=e)``, as a box's walls cut growth), the same kind of rules carry the load down through fewer, steeper
    members, and grown in the boxes of other footprints of their height (the seed anywhere) they meet some of
    those specs.

    For each half-width ``e`` from 1 to ``(max_side - 1) // 2`` and each height from ``lowest`` (every spec up to
    three levels is met by the search and the tilings): the ``per_height`` lightest one-rule-per-level designs,
    solid and one cell thick, that stand (the static analysis) and that a local rule grows (a beam search as
    :func:`taught_pyramids`', over all widths rather than per width and wider: a narrow beam misses the 3x3
    six-level one, a prefix's load ranking its descendants poorly). From
    ``by_class_from`` levels the ``starts`` lightest solid ones cut at most ``class_extent`` cells from the axis are
    also improved with a rule per in-degree class (:func:`_lightest_by_class`, ``passes`` passes, moves in an order
    drawn from ``seed`` and the design's place in this loop, so that each descent is the same whichever others
    run), as it bought the tall tower its ninth level: at six levels a 3x3 box then holds (46 N in the first 0.3 s
    where its lightest one-rule design takes 60 N) and a 5x5 one carries 41 N. ``one_rule=False`` leaves the
    one-rule designs out (to add the per-class ones to a library that has them). Each distinct design is taught
    once, and only if it also holds through the faithful preset's first 0.3 s (:func:`.tall.transient_peak`): the
    static analysis lets narrow, tall frames stand that PyBullet breaks within 0.06 s (3x3 at six and seven
    levels: 60 N against its 86 to 90 % of the break force)."""
    from physics import PhysicsConfig
    from physics.statics import check_statics
    from structgen.domains.structures.tall import teachable, transient_peak
    from structgen.domains.structures.teach import TeachError, teach

    break_force = PhysicsConfig().break_force
    taught = []
    seen: set[bytes] = set()

    def add(candidate: Structure | None, height: int) -> bool:
        if candidate is None:
            return False
        key = _cells_key(candidate)
        if key in seen or not teachable(candidate, whole=True) or not check_statics(candidate).stands:
            return False
        seen.add(key)
        if transient_peak(candidate) > break_force:  # the static analysis is lenient on narrow, tall frames
            return False
        try:
            result = teach(candidate)
        except TeachError:
            return False
        taught.append((height, result.weights))
        return True

    for wall in (False, True) if one_rule else (False,):  # walls have no per-class designs
        for extent in range(1, (max_side - 1) // 2 + 1):
            for height, by_width in _lightest_by_level(max_side, max_levels, beam, wall, extent, per_width=False):
                if height < lowest:
                    continue
                ranked = _lightest_first(by_width)
                if one_rule:
                    kept = 0
                    for _, _, _, candidate in ranked:
                        kept += add(candidate, height)
                        if kept == per_height:
                            break
                if wall or by_class_from is None or height < by_class_from or extent > class_extent:
                    continue
                for start, (_, rules, tied, _) in enumerate(ranked[:starts]):
                    rng = random.Random(f"{seed}/{extent}/{height}/{start}")
                    add(_lightest_by_class(rules, tied, extent, passes, rng), height)
    return taught


def spec_box(width: int, depth: int) -> Box:
    """The growth box of a ``width`` x ``depth`` footprint around a seed at its middle (the lower middle of an even
    side), as offsets from the seed: the box :func:`box_for` gives with that seed place."""
    box = box_for(width, depth, 1, "down", (width - 1) // 2, (depth - 1) // 2)
    return (int(box[0, 0]), int(box[0, 1]), int(box[1, 0]), int(box[1, 1]))


@dataclass(frozen=True)
class _BoxedSearch:
    """One footprint's step of :func:`taught_boxed` (a worker's job): ``(height, weights)`` for each height it
    holds, lowest first."""

    beam: int
    candidates: int
    starts: int
    passes: int
    seed: int

    def __call__(self, job: tuple[int, int, tuple[int, ...]]) -> list[tuple[int, np.ndarray]]:
        from physics import PhysicsConfig
        from physics.statics import check_statics
        from structgen.domains.structures.tall import teachable, transient_peak
        from structgen.domains.structures.teach import TeachError, teach

        width, depth, heights = job
        box, break_force = spec_box(width, depth), PhysicsConfig().break_force
        taught: list[tuple[int, np.ndarray]] = []
        for height, by_width in _lightest_by_level(depth, max(heights), self.beam, extent=box, per_width=False):
            if height not in heights:
                continue
            fills = [e for e in _lightest_first(by_width) if dimensions(e[3])[:2] == (width, depth)]
            designs: list[Structure] = []
            for _, _, _, candidate in fills:  # lightest first, so judging stops at the ones kept
                if len(designs) == self.candidates:
                    break
                if teachable(candidate, whole=True) and check_statics(candidate).stands:
                    designs.append(candidate)
            for start, (_, rules, tied, _) in enumerate(fills[: self.starts]):
                rng = random.Random(f"{self.seed}/{width}x{depth}x{height}/{start}")
                found = _lightest_by_class(rules, tied, box, self.passes, rng, footprint=(width, depth))
                # A descent that moved nothing gives back a design already listed: simulated once.
                if (found is not None and _cells_key(found) not in {_cells_key(d) for d in designs}
                        and check_statics(found).stands):  # fmt: skip
                    designs.append(found)
            # The static analysis is lenient on narrow, tall frames: the one that holds in PyBullet's first 0.3 s
            # with the most to spare is taught.
            peaks = sorted((transient_peak(d), k) for k, d in enumerate(designs))
            for peak, k in peaks:
                if peak > break_force:
                    break
                try:
                    taught.append((height, teach(designs[k]).weights))
                    break
                except TeachError:
                    continue
            if not taught or taught[-1][0] != height:
                break  # a taller design in the same box carries more still
        return taught


def taught_boxed(
    specs: np.ndarray | list[tuple[int, int, int]], beam: int = 12, candidates: int = 2, starts: int = 2,
    passes: int = 2, seed: int = 0, workers: int = 0, progress: bool = False,
) -> list[tuple[int, np.ndarray]]:  # fmt: skip
    """Designs searched in each spec's own box, taught: ``(height, weights)``. :func:`taught_clipped` cuts its
    designs to square boxes around their axis, so a footprint with an even side, or one longer than wide, gets only
    what a square design leaves when grown there; here the one-rule-per-level beam search runs with the growth cut
    to the footprint's box (:func:`spec_box`, the seed at its middle), and from the ``starts`` lightest designs that
    fill it a per-class descent (:func:`_lightest_by_class`, ``passes`` passes) runs in the same box. Of the
    ``candidates`` lightest one-rule designs that stand by the static analysis and the per-class ones, the one with
    the lowest peak in PyBullet's first 0.3 s (:func:`.tall.transient_peak`) is taught if that peak is within the
    break force. ``specs`` (width at most depth) are taken a footprint at a time, lowest height first, and a
    footprint stops at the first height none holds. Footprints run in ``workers`` processes (0: this one); the
    result is the same whatever ``workers``, and a footprint whose worker dies adds nothing."""
    from tqdm import tqdm

    from evolution.pool import Lost, WorkerPool

    by_footprint: dict[tuple[int, int], list[int]] = {}
    for width, depth, height in (tuple(int(v) for v in spec) for spec in specs):
        if width > depth:
            raise ValueError(f"specs must have width at most depth, got {width}x{depth}")
        by_footprint.setdefault((width, depth), []).append(height)
    jobs = [(w, d, tuple(sorted(set(h)))) for (w, d), h in sorted(by_footprint.items())]
    bar = tqdm(total=len(jobs), desc="design library: boxed designs", unit="footprint", disable=not progress)
    with WorkerPool(workers, quiet=True) as pool:
        found = pool.map(_BoxedSearch(beam, candidates, starts, passes, seed), jobs, done=lambda _: bar.update(1))
    bar.close()
    return [taught for result in found if not isinstance(result, Lost) for taught in result]


def taught_on_mats(
    library: DesignLibrary, specs: np.ndarray | list[tuple[int, int, int]], tries: int = 4
) -> list[tuple[int, np.ndarray]]:
    """NCAs taught to grow a design the library has on a floor mat (:func:`.samples.on_mat`): ``(height, weights)``.
    A spec no answer meets may be wider than one that is met at its height (a tower that stands on 3x3 cells where
    nothing 11x11 does); that answer set on a mat filling the spec's footprint meets it, the mat lying on the ground
    and carrying only itself. For each of ``specs`` (width at most depth), the ``down`` answers of its height that
    fit inside it, the smallest footprint and then the lowest static load first (``tries`` of them), are grown and
    set in the middle of a mat of the spec's footprint, and the first that holds there in PyBullet's first 0.3 s
    (:func:`.tall.transient_peak`; the mat ties the feet together, which moves their load) is chosen. Each answer
    chosen is taught once, on the mat of the largest footprint it was chosen for (in that box, so the mat's rule is
    seen spreading every way it can), falling back to the next largest where no local rule grows it; grown in
    another box, the NCA spreads the mat to that box's walls, which :func:`add_taught` finds."""
    from physics import PhysicsConfig
    from structgen.domains.structures.samples import on_mat
    from structgen.domains.structures.tall import transient_peak
    from structgen.domains.structures.teach import TeachError, teach

    break_force = PhysicsConfig().break_force
    answers, down = library.answers, np.array([family == "down" for family in library.families])
    chosen: dict[int, list[tuple[int, int]]] = {}  # answer row -> the footprints it holds on a mat of
    for width, depth, height in sorted((tuple(int(v) for v in spec) for spec in specs), key=lambda s: (s[2], s[0] * s[1], s)):
        if width > depth:
            raise ValueError(f"specs must have width at most depth, got {width}x{depth}")
        fit = np.flatnonzero(down[answers[:, 0]] & (answers[:, 3] == height) & (answers[:, 1] <= width)
                             & (answers[:, 2] <= depth))  # fmt: skip
        for k in fit[np.lexsort((library.peaks[fit], answers[fit, 1] * answers[fit, 2]))][:tries]:
            if transient_peak(on_mat(_grow_answer(library, answers[k]), width, depth)) <= break_force:
                chosen.setdefault(int(k), []).append((width, depth))
                break
    taught = []
    for k, footprints in chosen.items():
        row = answers[k]
        base, height = _grow_answer(library, row), int(row[3])
        # The seed is the answer's own: on_mat keeps the base's vertices first, in their order.
        top = int(np.flatnonzero((base.vertices - base.vertices.min(axis=0) == [row[4], row[5], height - 1]).all(axis=1))[0])
        for width, depth in sorted(footprints, key=lambda f: (-f[0] * f[1], f)):
            target = on_mat(base, width, depth)
            seed = target.vertices[top, :2]
            try:
                taught.append((height, teach(target, seed_vertex=top, box=box_for(width, depth, height, "down", *seed)).weights))
                break
            except TeachError:
                continue
    return taught


def build_library(
    ncas: int = 2_000, seed: int = 0, *, specs_each: int = 48, batch: int = 16, keep: int = 64, answers_each: int = 6,
    starts: dict[str, list[np.ndarray]] | None = None, max_side: int = MAX_SIDE, max_levels: int = MAX_LEVELS,
    tilings: bool = True, clipped: bool = True, screen: bool = True, boxed: bool = True, mats: bool = True,
    workers: int = 0, progress: bool = False,
) -> DesignLibrary:  # fmt: skip
    """Search ``ncas`` NCAs by MAP-Elites over the spec grid (footprints up to ``max_side`` square, heights up to
    ``max_levels``; see the module's docstring), keep the ``keep`` that cover the most specs with up to
    ``answers_each`` answers each, and list everything those meet; then, with ``tilings``, add the taught tilings,
    and with ``clipped`` the taught designs cut to narrow boxes (:func:`add_taught`); then, with ``screen``, the
    answers that break in PyBullet's first 0.3 s are dropped (:func:`screened`, in ``workers`` processes). Last, with
    ``boxed``, designs searched in the boxes of the specs still unmet (:func:`taught_boxed`, those equilibrium does
    not rule out) are added, and their answers screened alike; and with ``mats``, for the specs still unmet, answers
    of smaller footprints set on a floor mat filling theirs (:func:`taught_on_mats`), screened alike. The same
    arguments give the same library, whatever ``workers``."""
    from ribs.archives import GridArchive
    from tqdm import tqdm

    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    size = n_params(FAMILIES["down"])
    if starts is None:
        from structgen.nca import load_weights

        docs = Path(__file__).resolve().parents[3] / "docs"
        starts = {family: [load_weights(docs / n) for n in names if (docs / n).exists()] for family, names in STARTS.items()}
        starts["down"] += [w for _, w in taught_pyramids(max_side, max_levels)]
    weights: list[np.ndarray] = []
    families: list[str] = []
    archives = {
        family: GridArchive(solution_dim=size, dims=(max_side, max_side, max_levels),
                            ranges=((0.5, max_side + 0.5), (0.5, max_side + 0.5), (0.5, max_levels + 0.5)),
                            extra_fields={"nca": ((), np.int32)}, seed=seed)
        for family in FAMILIES
    }  # fmt: skip
    found = _Found()
    specs = canonical_specs(max_side, max_levels)

    def add(new: list[tuple[str, np.ndarray]]) -> None:
        ids = []
        for family, w in new:
            weights.append(np.asarray(w, dtype=np.float32).astype(np.float64))  # as the library file keeps them
            families.append(family)
            ids.append(len(weights) - 1)
        stacked = np.stack(weights)
        tries = _random_tries(rng, len(ids), specs_each, specs)
        for position, spec, margin in _judge(stacked, ids, families, tries, found):
            archives[families[ids[position]]].add(stacked[ids[position]][None], [margin], spec[None].astype(float),
                                                  nca=[ids[position]])  # fmt: skip

    first = [(family, w) for family, ws in starts.items() for w in ws]
    for family in FAMILIES:  # random NCAs of each family, at the paper's scale and smaller
        first += [(family, w) for w in rng.uniform(-0.25, 0.25, (batch, size))]
    bar = tqdm(total=ncas, desc="design library: NCAs", unit="NCA", disable=not progress)
    add(first)
    bar.update(len(first))
    while len(weights) < ncas:
        children = []
        for _ in range(min(batch, ncas - len(weights))):
            family = str(rng.choice(list(FAMILIES)))
            archive = archives[family]
            if archive.empty:
                children.append((family, rng.uniform(-0.25, 0.25, size)))
                continue
            parent = archive.sample_elites(1)["solution"][0]
            scale = float(rng.choice([0.01, 0.03, 0.1, 0.3])) * float(np.abs(parent).mean())
            children.append((family, parent + rng.normal(0.0, scale, size)))
        add(children)
        bar.update(len(children))
        bar.set_postfix(specs=len({row[1:4] for row in found.rows}), answers=len(found.rows))
    bar.close()
    searched = time.perf_counter() - started
    library = _cover(np.stack(weights), families, found, keep, answers_each, specs)
    if tilings:
        tiling_started = time.perf_counter()
        library = add_taught(library, taught_tilings(max_side, max_levels), specs, "tiling")
        library.info["tiling_seconds"] = round(time.perf_counter() - tiling_started, 1)
    if clipped:
        clipped_started = time.perf_counter()
        library = add_taught(library, taught_clipped(max_side, max_levels), specs, "clipped")
        library.info["clipped_seconds"] = round(time.perf_counter() - clipped_started, 1)
    if screen:
        library = screened(library, workers=workers, progress=progress)
    for kind, wanted, teach_for in (
        ("boxed", boxed, lambda _, unmet: taught_boxed(unmet, workers=workers, progress=progress)),
        ("mat", mats, taught_on_mats),  # from the answers of the library as it stands by then
    ):  # fmt: skip
        if not wanted:
            continue
        step_started = time.perf_counter()
        met, first = library.specs(), len(library.families)
        unmet = [s for s in map(tuple, specs.tolist()) if s not in met and s[2] <= tallest_possible(s[0], s[1])]
        library = add_taught(library, teach_for(library, unmet), specs, kind)
        if screen:
            library = screened(library, workers=workers, progress=progress, from_nca=first, step=kind)
        library.info[f"{kind}_seconds"] = round(time.perf_counter() - step_started, 1)
    library = with_mat_flags(library)
    library.info.update({
        "name": f"design library (seed {seed}, {ncas} NCAs searched)", "ncas_searched": ncas, "seed": seed,
        "specs_each": specs_each, "search_seconds": round(searched, 1),
        "seconds": round(time.perf_counter() - started, 1), "specs_found_in_search": len({r[1:4] for r in found.rows}),
        "grid": {"max_side": max_side, "max_levels": max_levels},
    })  # fmt: skip
    return library


def _spec_order(answers: np.ndarray) -> np.ndarray:
    """The order a library lists its answers in: by width, depth, height, then NCA."""
    return np.lexsort((answers[:, 0], answers[:, 3], answers[:, 2], answers[:, 1]))


def _cover(
    weights: np.ndarray, families: list[str], found: _Found, keep: int, answers_each: int, specs: np.ndarray
) -> DesignLibrary:
    """Greedily keep the NCAs adding the most (spec, answer) pairs up to ``answers_each`` a spec, then grow each kept
    NCA in every spec's box (centred seeds) to list all it meets."""
    rows = np.array(found.rows, dtype=np.int64).reshape(-1, 8)
    have: dict[tuple[int, int, int], int] = {}
    chosen: list[int] = []
    by_nca = {int(n): rows[rows[:, 0] == n] for n in np.unique(rows[:, 0])} if len(rows) else {}
    while len(chosen) < keep and by_nca:

        def gain(n: int) -> tuple[int, int]:
            """Specs no kept NCA answers yet first (a spec met beats a spec met again), then answers added."""
            specs = {tuple(int(v) for v in r[1:4]) for r in by_nca[n]}
            return sum(1 for s in specs if s not in have), sum(1 for s in specs if have.get(s, 0) < answers_each)

        best = max(by_nca, key=lambda n: (gain(n), -n))
        if gain(best) == (0, 0):
            break
        for s in {tuple(int(v) for v in r[1:4]) for r in by_nca.pop(best)}:
            have[s] = have.get(s, 0) + 1
        chosen.append(best)
    chosen.sort()
    kept = DesignLibrary([families[n] for n in chosen], weights[chosen].astype(np.float32), np.zeros((0, 8), np.int32),
                         np.zeros(0, np.float32))  # fmt: skip
    # Every spec, every kept NCA, the seed placed at the middle (both middles of an even side) and where the search found it.
    tries = {(i, *map(int, spec), x, y) for i in range(len(chosen)) for spec in specs
             for x in {(spec[0] - 1) // 2, spec[0] // 2} for y in {(spec[1] - 1) // 2, spec[1] // 2}}  # fmt: skip
    index = {n: i for i, n in enumerate(chosen)}
    tries |= {(index[int(r[0])], *map(int, r[1:6])) for r in rows if int(r[0]) in index}
    final = _Found()
    every = np.array(sorted(tries), dtype=np.int64)
    _judge(kept.weights.astype(np.float64), list(range(len(chosen))), kept.families, every, final)
    kept.answers = np.array(final.rows, dtype=np.int32).reshape(-1, 8)
    kept.peaks = np.array(final.peaks, dtype=np.float32)
    order = _spec_order(kept.answers)
    kept.answers, kept.peaks = kept.answers[order], kept.peaks[order]
    kept.info["kept_ncas"] = len(chosen)
    return kept


def _transient_peak_of(library: DesignLibrary, row: np.ndarray) -> float:
    """The largest joint force in the faithful preset's first 0.3 s of what ``row`` grows (a worker's job)."""
    from structgen.domains.structures.tall import transient_peak

    return transient_peak(_grow_answer(library, row))


def screened(
    library: DesignLibrary, above_share: float = SCREEN_ABOVE_SHARE, workers: int = 0, progress: bool = False,
    from_nca: int = 0, step: str = "added",
) -> DesignLibrary:  # fmt: skip
    """``library`` without the answers PyBullet breaks: each answer the static analysis loads above ``above_share``
    of the break force is grown and run for the faithful preset's first 0.3 s with unbreakable joints
    (:func:`.tall.transient_peak`, where these structures carry the most), and goes if any joint's force passes the
    break force; the simulation with breakable joints takes the same steps until one breaks, so what is kept loses
    no joint in that time. The static analysis alone is lenient: of 1,074 answers of the previous library
    simulated so, 323 broke (13 of 100 two levels tall, 195 of 484 six levels tall), none of the 196 at or below 0.7
    of the break force, which is why those are not simulated. NCAs left with no answer are dropped. The same
    library gives the same result whatever ``workers`` (processes; 0: this one); an answer whose worker dies is
    dropped. Only the answers of NCAs numbered ``from_nca`` and on are simulated: those of the NCAs before were
    screened already (a library extended by :func:`add_taught`). ``info`` counts what went (``screen_*``, or
    ``screen_<step>_*`` from a later NCA, keeping the earlier screens' counts). Mat flags, where the library has them,
    stay with the answers kept."""
    from tqdm import tqdm

    from evolution.pool import Lost, WorkerPool
    from physics import PhysicsConfig

    started = time.perf_counter()
    break_force = PhysicsConfig().break_force
    rows = np.flatnonzero((library.peaks > above_share) & (library.answers[:, 0] >= from_nca))
    bar = tqdm(total=len(rows), desc="design library: transient screen", unit="answer", disable=not progress)
    with WorkerPool(workers, quiet=True) as pool:
        job = functools.partial(_transient_peak_of, library)
        peaks = pool.map(job, [library.answers[row] for row in rows], done=lambda _: bar.update(1))
    bar.close()
    keep = np.ones(len(library.answers), dtype=bool)
    keep[rows] = [not isinstance(peak, Lost) and peak <= break_force for peak in peaks]
    answers, static_peaks = library.answers[keep].copy(), library.peaks[keep]
    used = np.unique(answers[:, 0])
    renumber = np.full(len(library.families), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    answers[:, 0] = renumber[answers[:, 0]]  # in the same order, so the answers stay sorted
    flags = None if library.on_mat is None else library.on_mat[keep]
    kept = DesignLibrary([library.families[n] for n in used], library.weights[used], answers, static_peaks, on_mat=flags)
    counts = {"above_share": above_share, "simulated": len(rows), "answers_dropped": int((~keep).sum()),
              "specs_lost": len(library.specs() - kept.specs()), "seconds": round(time.perf_counter() - started, 1)}  # fmt: skip
    prefix = f"screen_{step}_" if from_nca else "screen_"
    kept.info = {**library.info, **{prefix + key: value for key, value in counts.items()}}
    return kept


def add_taught(
    library: DesignLibrary, taught: list[tuple[int, np.ndarray]], specs: np.ndarray | None = None, kind: str = "tiling"
) -> DesignLibrary:
    """``library`` with taught NCAs (:func:`taught_tilings`, :func:`taught_clipped`: ``(height, weights)``) added,
    family ``down``, and every spec of their height each meets, its seed at every place of the box (where a tiling's
    tops fall decides what is cut at the walls). The NCAs and answers already there stay as they are, so this step
    can be added to a library already built; ``info`` counts what ``kind`` added. A library whose answers carry mat
    flags (:func:`with_mat_flags`) keeps them, the new answers flagged alike, as :func:`screened` keeps them."""
    if not taught:
        return library
    specs = canonical_specs() if specs is None else specs
    first = len(library.families)
    weights = np.concatenate([library.weights.astype(np.float32), np.stack([w for _, w in taught]).astype(np.float32)])
    families = [*library.families, *["down"] * len(taught)]
    tries = np.array([(first + i, *map(int, spec), x, y) for i, (height, _) in enumerate(taught)
                      for spec in specs if spec[2] == height
                      for x in _seed_places(int(spec[0])) for y in _seed_places(int(spec[1]))], dtype=np.int64)  # fmt: skip
    found = _Found()
    _judge(weights.astype(np.float64), list(range(len(families))), families, tries, found)
    answers = np.concatenate([library.answers, np.array(found.rows, dtype=np.int32).reshape(-1, 8)])
    peaks = np.concatenate([library.peaks, np.array(found.peaks, dtype=np.float32)])
    order = _spec_order(answers)
    info = {**library.info, f"{kind}_ncas": len(taught), f"{kind}_answers": len(found.rows),
            f"{kind}_specs": len({row[1:4] for row in found.rows})}  # fmt: skip
    flags = None
    if library.on_mat is not None:  # flag the new answers alone, so that an extended library keeps mats last
        added = DesignLibrary(families, weights, answers[len(library.answers) :], peaks[len(library.answers) :])
        flags = np.concatenate([library.on_mat, with_mat_flags(added).on_mat])[order]
    return DesignLibrary(families, weights, answers[order], peaks[order], info, flags)
