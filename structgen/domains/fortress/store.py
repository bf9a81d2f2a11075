"""A run folder's fortress worlds, each written once: the genome store of :class:`.problem.FortressProblem`.

A paper run's archive holds about 10,000 worlds of up to 1,410 nodes; as text they take 440 MB, and a checkpoint
that pickles them takes 260 MB more, both rewritten at every checkpoint. Here a world is 15 references to classes
plus its initial entities, and a class (:class:`.genome.ClassArrays`) is stored once however many worlds share it,
so a mutant that changed one class costs one class. At each checkpoint the worlds and classes not stored yet go
into one new compressed file, ``genomes/segment-NNNNNN.npz``, and are known by key from then on; nothing written is
ever rewritten. Keys are handed out in order, so each file holds a contiguous range of class keys and of world keys.

A file's arrays (read through the file gate, ``evolution.files.read_npz``: no pickles): ``class_first`` and
``world_first`` (the first key of each kind), ``class_char`` (character numbers), ``class_nodes`` and
``class_edges`` (each class's counts), ``nodes`` (node types, concatenated), ``edges`` (``(5, E)``: src, dst,
condition, class argument, number), ``world_classes`` (``(worlds, classes)``: class keys), ``world_initial``
(entity counts) and ``initial`` (``(3, N)``: class, x, y).
"""

from __future__ import annotations

import bisect
import io
import re
import weakref
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from evolution.files import InputFileError, atomic_write
from evolution.problem import GenomeStore
from structgen.domains.fortress.genome import ClassArrays, Genome

__all__ = ["FortressStore"]

_SEGMENT = re.compile(r"^segment-(\d{6})\.npz$")


def _npz(arrays: dict[str, np.ndarray]) -> bytes:
    """An ``.npz`` file (what ``np.savez_compressed`` writes, read back by ``np.load``) compressed at zlib level 3:
    a paper run's store is 3% larger than at numpy's level 6 and written in a third of the time (2.4 s against
    7.2 s over a run's checkpoints)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED, compresslevel=3) as archive:
        for name, values in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(values), allow_pickle=False)
            archive.writestr(f"{name}.npy", member.getvalue())
    return buffer.getvalue()


def _small(values: np.ndarray) -> np.ndarray:
    # int8 when every value fits (they almost always do): the files compress better.
    return values.astype(np.int8) if values.size == 0 or np.abs(values).max() < 128 else values.astype(np.int16)


#: A segment file may hold this much on disk and unpacked (a paper run's checkpoints write a few MB each).
_SEGMENT_BYTES, _SEGMENT_UNPACKED = 1 << 30, 2 << 30
#: Each array of a segment file: its number of dimensions (the first of ``edges`` and ``initial`` is fixed).
_SEGMENT_ARRAYS = {
    "class_first": 0, "world_first": 0, "class_char": 1, "class_nodes": 1, "class_edges": 1, "nodes": 1, "edges": 2,
    "world_classes": 2, "world_initial": 1, "initial": 2,
}  # fmt: skip


def _segment_arrays(path: Path) -> dict[str, np.ndarray]:
    """A segment file's arrays, through the file gate and checked against each other (whole numbers, of the shapes
    and counts the module's description gives), so that a damaged or foreign file is refused naming it."""
    from evolution.files import read_npz

    arrays = read_npz(path, _SEGMENT_BYTES, _SEGMENT_UNPACKED)
    for name, ndim in _SEGMENT_ARRAYS.items():
        if name not in arrays or arrays[name].dtype.kind not in "iub" or arrays[name].ndim != ndim:
            found = f"{arrays[name].dtype} of shape {arrays[name].shape}" if name in arrays else "missing"
            raise InputFileError(f"{path}: not a genome store file ({name}: {found})")
    sizes, counts, initial = arrays["class_nodes"], arrays["class_edges"], arrays["world_initial"]
    consistent = (
        len(sizes) == len(counts) == len(arrays["class_char"])
        and (sizes >= 0).all() and (counts >= 0).all() and (initial >= 0).all()
        and int(sizes.sum()) == len(arrays["nodes"])
        and arrays["edges"].shape == (5, int(counts.sum()))
        and arrays["initial"].shape == (3, int(initial.sum()))
        and len(arrays["world_classes"]) == len(initial)
        and int(arrays["class_first"]) >= 0 and int(arrays["world_first"]) >= 0
        and (arrays["world_classes"] >= 0).all()
    )  # fmt: skip
    if not consistent:
        raise InputFileError(f"{path}: not a genome store file (its arrays' counts and shapes disagree)")
    return arrays


class FortressStore(GenomeStore):
    genome_type = Genome

    def __init__(self, run_folder: str | Path) -> None:
        self.path = Path(run_folder) / "genomes"
        # id(object) -> (weak reference, key): what is stored already (the reference tells a reused id apart).
        self._known: dict[int, tuple[weakref.ref, int]] = {}
        self._pending_classes: list[ClassArrays] = []
        self._pending_worlds: list[tuple[Genome, list[int]]] = []
        # What has been read back, by key (worlds written in this process are not kept: a run lets go of elites).
        self._classes: dict[int, ClassArrays] = {}
        self._worlds: dict[int, Genome] = {}
        self._world_rows: dict[Path, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._segments: list[tuple[int, int, int, int, Path]] = []  # class first, count, world first, count, file
        self._loaded: set[Path] = set()
        for path in sorted(self.path.glob("segment-*.npz")) if self.path.is_dir() else []:
            if _SEGMENT.match(path.name):
                data = _segment_arrays(path)
                first_class, first_world = int(data["class_first"]), int(data["world_first"])
                self._segments.append((first_class, len(data["class_char"]), first_world, len(data["world_initial"]), path))
        self._next_class = max((a + n for a, n, *_ in self._segments), default=0)
        self._next_world = max((w + n for _, _, w, n, _ in self._segments), default=0)

    # -- writing -----------------------------------------------------------------------------------------------------
    def _key_of(self, obj: Any) -> int | None:
        found = self._known.get(id(obj))
        return found[1] if found is not None and found[0]() is obj else None

    def _remember(self, obj: Any, key: int) -> None:
        name = id(obj)
        self._known[name] = (weakref.ref(obj, lambda _: self._known.pop(name, None)), key)

    def _class_key(self, entity: ClassArrays) -> int:
        key = self._key_of(entity)
        if key is None:
            key = self._next_class
            self._next_class += 1
            self._pending_classes.append(entity)
            self._remember(entity, key)
        return key

    def keys(self, genomes: Any) -> list[int]:
        found = []
        for world in genomes:
            if not isinstance(world, Genome):
                raise TypeError(f"the fortress store keeps Genome worlds, not {type(world).__name__}")
            key = self._key_of(world)
            if key is None:
                key = self._next_world
                self._next_world += 1
                self._pending_worlds.append((world, [self._class_key(c) for c in world.classes]))
                self._remember(world, key)
            found.append(key)
        return found

    def flush(self) -> None:
        if not self._pending_classes and not self._pending_worlds:
            return
        classes, worlds = self._pending_classes, self._pending_worlds
        first_class = self._next_class - len(classes)
        first_world = self._next_world - len(worlds)
        edges = np.concatenate([c.edges for c in classes]) if classes else np.zeros((0, 5), dtype=np.int16)
        initial = np.concatenate([w.initial for w, _ in worlds]) if worlds else np.zeros((0, 3), dtype=np.int16)
        width = max((len(keys) for _, keys in worlds), default=0)
        if any(len(keys) != width for _, keys in worlds):
            raise ValueError("the fortress store keeps worlds with the same number of classes")
        data = _npz(
            dict(
                class_first=np.int64(first_class),
                world_first=np.int64(first_world),
                class_char=np.array([c.char for c in classes], dtype=np.int8),
                class_nodes=np.array([len(c.nodes) for c in classes], dtype=np.int32),
                class_edges=np.array([len(c.edges) for c in classes], dtype=np.int32),
                nodes=np.concatenate([c.nodes for c in classes]) if classes else np.zeros(0, dtype=np.int8),
                edges=_small(edges.T),
                world_classes=np.array([keys for _, keys in worlds], dtype=np.int64).reshape(len(worlds), width),
                world_initial=np.array([len(w.initial) for w, _ in worlds], dtype=np.int32),
                initial=_small(initial.T),
            )
        )
        self.path.mkdir(exist_ok=True)
        path = self.path / f"segment-{len(self._segments):06d}.npz"
        # A file left by a run killed before its checkpoint keeps its name and its keys (the next keys start after
        # every file's), and nothing refers to it.
        while path.exists():
            path = path.with_name(f"segment-{int(_SEGMENT.match(path.name)[1]) + 1:06d}.npz")
        atomic_write(path, data)
        self._segments.append((first_class, len(classes), first_world, len(worlds), path))
        self._pending_classes, self._pending_worlds = [], []

    # -- reading -----------------------------------------------------------------------------------------------------
    def _read(self, path: Path) -> None:
        arrays = _segment_arrays(path)
        sizes, counts = arrays["class_nodes"].astype(np.int64), arrays["class_edges"].astype(np.int64)
        node_at = np.concatenate([[0], np.cumsum(sizes)])
        edge_at = np.concatenate([[0], np.cumsum(counts)])
        edges = arrays["edges"].T
        first = int(arrays["class_first"])
        for k, char in enumerate(arrays["class_char"].tolist()):
            key = first + k
            if key not in self._classes:
                entity = ClassArrays(char, arrays["nodes"][node_at[k] : node_at[k + 1]], edges[edge_at[k] : edge_at[k + 1]])
                self._classes[key] = entity
                self._remember(entity, key)
        self._loaded.add(path)
        initial_at = np.concatenate([[0], np.cumsum(arrays["world_initial"].astype(np.int64))])
        self._world_rows[path] = (arrays["world_classes"], arrays["initial"].T, initial_at)

    def _segment_of(self, key: int, column: int) -> Path:
        firsts = [segment[column] for segment in self._segments]
        order = sorted(range(len(firsts)), key=firsts.__getitem__)
        at = bisect.bisect_right([firsts[i] for i in order], key) - 1
        if at >= 0:
            segment = self._segments[order[at]]
            if key < segment[column] + segment[column + 1]:
                return segment[4]
        raise InputFileError(f"{self.path}: no stored {'world' if column else 'class'} {key} (a file of the store is missing)")

    def _class(self, key: int) -> ClassArrays:
        if key not in self._classes:
            path = self._segment_of(key, 0)
            if path not in self._loaded:
                self._read(path)
        return self._classes[key]

    def load(self, keys: Any) -> list[Genome]:
        found = []
        for key in (int(k) for k in keys):
            world = self._worlds.get(key)
            if world is None:
                path = self._segment_of(key, 2)
                if path not in self._loaded:
                    self._read(path)
                classes_of, initial, initial_at = self._world_rows[path]
                row = key - next(first for _, _, first, _, p in self._segments if p == path)
                world = Genome(
                    tuple(self._class(int(c)) for c in classes_of[row]), initial[initial_at[row] : initial_at[row + 1]]
                )
                self._worlds[key] = world
                self._remember(world, key)
            found.append(world)
        return found
