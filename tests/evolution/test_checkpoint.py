"""Checkpoints load without running anything they contain: crafted ones are refused before any of their code runs,
and every checkpoint the engine writes loads to the same objects as plain unpickling would give."""

from __future__ import annotations

import os
import pickle
import pickletools
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from evolution import (
    Evaluation,
    Problem,
    RunFolder,
    RunFolderError,
    RunSettings,
    RunState,
    SerialEvaluator,
    advance,
    checkpoint,
    make_optimizer,
)
from evolution.optimizers import CMAESSettings, CMAMAESettings, GASettings, MapElitesSettings, RandomSettings
from evolution.toys import Ones, Sphere, SphereSettings

FIXTURES = Path(__file__).resolve().parents[1] / "fixtures" / "runs_0.1.0"


class RunsACommand:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):
        return os.system, (f"touch {self.marker}",)


def global_call(module: str, name: str, *args) -> bytes:
    """A hand-made pickle that calls module.name(*args) with protocol 2 instructions."""
    body = b"c" + f"{module}\n{name}\n".encode() + pickle.dumps(args, protocol=2)[2:-1] + pickle.REDUCE + pickle.STOP
    return pickle.PROTO + b"\x02" + body


def test_a_checkpoint_that_runs_a_command_is_refused_before_it_runs(tmp_path):
    marker = tmp_path / "PWNED"
    folder = RunFolder.create(tmp_path / "run", "", {})
    (folder / "checkpoint.pkl").write_bytes(pickle.dumps({"schema": 1, "state": RunsACommand(marker)}))
    with pytest.raises(RunFolderError, match=r"refusing to load this checkpoint: it names (posix|os)\.system"):
        folder.load_checkpoint()
    assert not marker.exists()


@pytest.mark.parametrize(
    "data, message",
    [
        (global_call("builtins", "eval", "print('hi')"), "it names builtins.eval"),
        (global_call("builtins", "getattr", 1, "real"), "it names builtins.getattr"),
        (global_call("subprocess", "Popen", ["true"]), "it names subprocess.Popen"),
        (global_call("numpy", "memmap", "/tmp/x", "uint8", "w+", 0, (1,)), "it names numpy.memmap"),
        # A class of an optimiser library is admitted, but may not be called: calling runs its __init__.
        (global_call("cma.evolution_strategy", "CMAEvolutionStrategy", [0.0, 0.0], 1.0), "it asks to call"),
        (global_call("evolution.runfolder", "RunFolder", "/"), "it names evolution.runfolder.RunFolder"),
        (global_call("cma.logger", "Logger", "victim"), "it names cma.logger.Logger"),
        (b"(cos\nsystem\nS'true'\no.", "it names os.system"),
        (b"(i__builtin__\nobject\n.", "call constructors"),
    ],
)
def test_crafted_pickles_are_refused(data, message):
    with pytest.raises(checkpoint.UnsafeCheckpointError, match=message):
        checkpoint.loads(data)


class Collected:
    """Stands for a library class that deletes the file it names when collected (pycma's Logger does)."""


def test_a_class_that_deletes_a_file_when_collected_is_refused_and_the_file_survives(tmp_path):
    import cma.logger

    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    logger = cma.logger.Logger.__new__(cma.logger.Logger)  # as a crafted checkpoint would hold it
    logger.__dict__.update({"_name": str(victim), "_delete": True})
    data = pickle.dumps({"schema": 1, "state": logger})
    logger.__dict__["_delete"] = False  # this test's own copy must not delete it when collected
    with pytest.raises(checkpoint.UnsafeCheckpointError, match="it names cma.logger.Logger, which a checkpoint never holds"):
        checkpoint.loads(data)
    import gc

    gc.collect()
    assert victim.read_text() == "keep me"


def test_a_module_is_never_imported_to_decide_whether_to_refuse_it():
    # The module `this` prints the Zen of Python when imported: a refusal must come before any import.
    code = (
        "import sys, pickle\n"
        "from evolution import checkpoint\n"
        "data = b'\\x80\\x02cthis\\ns\\nq\\x00.'\n"
        "try:\n    checkpoint.loads(data)\nexcept checkpoint.UnsafeCheckpointError as err:\n    print('refused:', err)\n"
        "print('this' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.splitlines() == ["refused: it names this.s, which a checkpoint never holds", "False"]


def test_no_admitted_class_runs_code_when_restored_or_collected():
    import importlib

    for module, name in sorted(checkpoint.CLASSES):
        kind = getattr(importlib.import_module(module), name)
        assert isinstance(kind, type), (module, name)
        mro = [c for c in kind.__mro__ if c is not object]
        assert not [c for c in mro if "__del__" in vars(c)], f"{module}.{name} runs code when collected"
        assert kind.__new__ in (object.__new__, dict.__new__, list.__new__), f"{module}.{name} has a constructor of its own"
        restores = [c for c in mro if "__setstate__" in vars(c)]
        # pyribs' array store restores through a mixin that imports the array module its state names: the reader
        # checks that name against numpy's before restoring (test_a_module_import_hidden_in_pyribs_state_is_refused).
        assert [c.__name__ for c in restores] in ([], ["PickleXPMixin"]), f"{module}.{name} restores with code of its own"


def test_a_module_import_hidden_in_pyribs_state_is_refused():
    from ribs.archives import GridArchive

    store = GridArchive(solution_dim=2, dims=(2, 2), ranges=[(0, 1), (0, 1)])._store
    data = pickle.dumps(store)
    state_name = b"array_api_compat.numpy"
    crafted = data.replace(bytes([len(state_name)]) + state_name, bytes([len(b"antigravity")]) + b"antigravity")
    assert crafted != data
    with pytest.raises(checkpoint.UnsafeCheckpointError, match="import the module 'antigravity'"):
        checkpoint.loads(crafted)


OPTIMIZERS = {
    "ga": ("ga", Sphere, GASettings(population=6, parents=2)),
    "ga_crossover": ("ga", Sphere, GASettings(population=6, parents=2, crossover_rate=0.5)),
    "cma_es_full": ("cma_es", Sphere, CMAESSettings(population=6, diagonal=False)),
    "map_elites_mutation": ("map_elites", Ones, MapElitesSettings(cells=(4, 4), batch_size=6, variation="problem")),
    "cma_mae_full_2imp_filter_basic": (
        "cma_mae",
        Sphere,
        CMAMAESettings(cells=(4, 4), emitters=2, batch_size=3, es="cma_es", ranker="2imp", selection="filter", restart="basic"),
    ),
    "cma_mae_obj_one_archive": (
        "cma_mae",
        Sphere,
        CMAMAESettings(cells=(4, 4), emitters=2, batch_size=3, ranker="obj", result_archive=False),
    ),
    "cma_mae_2obj": ("cma_mae", Sphere, CMAMAESettings(cells=(4, 4), emitters=2, batch_size=3, ranker="2obj")),
    "cma_es": ("cma_es", Sphere, CMAESSettings(population=6)),
    "cma_es_mirrored": ("cma_es", Sphere, CMAESSettings(population=4)),  # pycma mirrors samples and keeps a range
    # From 300 parameters on pycma adapts its step size another way, and from 33 genomes a generation on it keeps no
    # archive of them: the warehouse baseline's case (4,766 weights, 50 a generation).
    "cma_es_300_parameters_34_genomes": (
        "cma_es",
        lambda: Sphere(SphereSettings(dimensions=300)),
        CMAESSettings(population=34),
    ),
    "map_elites": ("map_elites", Ones, MapElitesSettings(cells=(4, 4), batch_size=6)),
    "cma_mae": ("cma_mae", Sphere, CMAMAESettings(cells=(4, 4), emitters=2, batch_size=3)),
    "cma_mae_iso_line": ("cma_mae", Sphere, CMAMAESettings(cells=(4, 4), emitters=2, batch_size=3, emitter="iso_line")),
    "random": ("random", Sphere, RandomSettings(population=6)),
    "random_objects": ("random", Ones, RandomSettings(population=6)),
    "random_archive": ("random", Sphere, RandomSettings(population=6, cells=(4, 4))),
    "random_archive_objects": ("random", Ones, RandomSettings(population=6, cells=(4, 4))),
}


@pytest.mark.parametrize("name", list(OPTIMIZERS))
def test_every_optimizers_checkpoint_loads_as_plain_unpickling_would(tmp_path, name):
    optimizer, problem_type, settings = OPTIMIZERS[name]
    problem = problem_type()
    folder = RunFolder.create(tmp_path / name, "", {})
    state = RunState(make_optimizer(optimizer, problem, settings, seed=1))
    advance(folder, problem, state, RunSettings(generations=2, workers=0), SerialEvaluator(), progress=False)
    data = (folder / "checkpoint.pkl").read_bytes()
    assert pickle.dumps(checkpoint.loads(data)) == pickle.dumps(pickle.loads(data))
    assert folder.load_checkpoint().generation == 2


@pytest.mark.parametrize("run", sorted(p.name for p in FIXTURES.iterdir() if p.is_dir()))
def test_checkpoints_of_structgen_0_1_load(run):
    data = (FIXTURES / run / "checkpoint.pkl").read_bytes()
    assert pickle.dumps(checkpoint.loads(data)) == pickle.dumps(pickle.loads(data))
    # Every instruction that names something is one the loader had to admit: none of them is a call it refused.
    assert any(op.name in ("GLOBAL", "STACK_GLOBAL") for op, _, _ in pickletools.genops(data))
    assert np.isfinite(checkpoint.loads(data)["state"].best.objective)


@dataclass(frozen=True)
class Faces:
    """A genome made of an object, as a plugin domain's would be (this module is no part of structgen)."""

    values: tuple[int, ...]


@dataclass(frozen=True)
class Restoring:
    values: tuple[int, ...]

    def __setstate__(self, state):  # restoring would run this: never admitted
        object.__setattr__(self, "values", state["values"])


class FacesProblem(Problem):
    name = "faces"
    measure_names = ()
    genome_types = (Faces,)

    def initial_genomes(self, count, rng):
        return [Faces(tuple(int(v) for v in rng.integers(0, 9, 4))) for _ in range(count)]

    def mutate(self, genome, rng):
        values = list(genome.values)
        values[int(rng.integers(4))] = int(rng.integers(0, 9))
        return Faces(tuple(values))

    def genome_to_json(self, genome):
        return list(genome.values)

    def evaluate(self, genomes, seeds):
        return Evaluation([float(sum(g.values)) for g in genomes], np.zeros((len(genomes), 0)))


def test_genome_classes_load_only_when_the_problem_declares_them_and_cannot_be_called():
    data = pickle.dumps([Faces((1, 2)), Faces((3, 4))])
    assert checkpoint.loads(data, genome_types=(Faces,)) == [Faces((1, 2)), Faces((3, 4))]
    with pytest.raises(checkpoint.UnsafeCheckpointError, match="test_checkpoint.Faces, which a checkpoint never holds"):
        checkpoint.loads(data)
    with pytest.raises(checkpoint.UnsafeCheckpointError, match="which a checkpoint never holds"):
        checkpoint.loads(pickle.dumps(Restoring((1,))), genome_types=(Restoring,))  # not a plain dataclass
    with pytest.raises(checkpoint.UnsafeCheckpointError, match="it asks to call"):
        checkpoint.loads(global_call(__name__, "Faces", (1, 2)), genome_types=(Faces,))


def test_a_run_of_dataclass_genomes_resumes_to_the_run_that_never_stopped(tmp_path):
    problem, settings = FacesProblem(), GASettings(population=6, parents=2)

    def run(folder: RunFolder, state: RunState, until: int) -> RunState:
        return advance(folder, problem, state, RunSettings(generations=until, workers=0), SerialEvaluator(), progress=False)

    straight = run(RunFolder.create(tmp_path / "straight", "", {}), RunState(make_optimizer("ga", problem, settings, 3)), 4)
    folder = RunFolder.create(tmp_path / "stopped", "", {})
    run(folder, RunState(make_optimizer("ga", problem, settings, 3)), 2)
    with pytest.raises(RunFolderError, match="refusing to load this checkpoint"):
        folder.load_checkpoint()  # a reader not told of the genome class
    resumed = run(folder, folder.load_checkpoint(problem.genome_types), 4)
    assert resumed.best.genome == straight.best.genome and resumed.best.objective == straight.best.objective
