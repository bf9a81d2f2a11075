"""Loading a checkpoint without running anything it contains.

A checkpoint is a pickle of the run's state: the optimiser (pycma's and pyribs' objects among them), numpy arrays
and random generators. Ordinary unpickling imports whatever modules a file names and runs whatever callables it
names, so a crafted ``checkpoint.pkl`` could run any command, or build an object whose collection deletes a file.
:func:`loads` reads only what checkpoints are made of, and decides from the names alone, before anything is
imported:

- **Classes** are admitted by their full name, from a list (:data:`CLASSES`) of what the engine's checkpoints hold:
  its own run state and optimisers, pyribs' archives, emitters and rankers, pycma's strategy and the parts it
  keeps. Never a whole package: a class of pycma that deletes a file when collected is refused like any other.
  Instances are made without calling their constructors (``object.__new__``, ``dict.__new__``, ``list.__new__``)
  and restored by setting their fields. Beside them: numpy's arrays, dtypes, scalar types and random generators, a
  few built-in types, and the genome classes the problem declares (:attr:`evolution.Problem.genome_types`, plain
  dataclasses).
- **Calls** (the pickle REDUCE instruction) are allowed for the numpy functions that rebuild arrays, scalars,
  dtypes and random generators, and for ``range`` and ``slice``, which only make a value (pycma keeps a range in
  its state when it mirrors samples, as it does in populations under 6).
- **References** to three functions pycma keeps among its options are allowed (never called while loading).
- The instructions of old pickle protocols that call constructors, and the extension registry, are refused; so is
  a module name in pyribs' array state other than numpy's (pyribs imports it when restoring).

Anything else stops loading with :class:`UnsafeCheckpointError` naming it, before its module is imported. The reader
is pickle's own pure-Python unpickler with those instructions checked, so it reads every checkpoint the engine
writes. ``tests/evolution/test_checkpoint.py`` holds the list to what the engine writes (every optimiser and setting,
every domain) and to the rule that no class on it runs code when restored or collected.
"""

from __future__ import annotations

import collections
import io
import pickle
from collections.abc import Callable, Collection
from typing import Any

import numpy as np

__all__ = ["UnsafeCheckpointError", "loads", "plain_dataclass"]


class UnsafeCheckpointError(pickle.UnpicklingError):
    """A checkpoint asks for something a checkpoint never needs (a function call, a foreign class)."""


def _reducer(example: Any) -> Any:
    return example.__reduce__()[0]


# The callables numpy's own pickles name, found from numpy itself so that its module layout does not matter.
_CALLS = frozenset(
    {
        _reducer(np.zeros(1)),  # ndarray reconstruction
        _reducer(np.float64(1.0)),  # numpy scalars
        np.dtype,
        _reducer(np.random.default_rng(0)),  # Generator
        _reducer(np.random.PCG64(0)),  # bit generators
        _reducer(np.random.SeedSequence(0)),
        _reducer(np.random.RandomState(0)),
        range,
        slice,
    }
)
_TYPES = frozenset(
    {
        np.ndarray,
        np.dtype,
        np.random.Generator,
        np.random.RandomState,
        np.random.SeedSequence,
        np.random.BitGenerator,
        np.random.PCG64,
        np.random.PCG64DXSM,
        np.random.MT19937,
        np.random.Philox,
        np.random.SFC64,
        dict,
        list,
        tuple,
        set,
        frozenset,
        int,
        float,
        complex,
        str,
        bytes,
        bytearray,
        bool,
        slice,
        range,
        object,
        collections.OrderedDict,
    }
)
_PLAIN_NEW = frozenset({object.__new__, dict.__new__, list.__new__})
#: The classes of the engine and its optimiser libraries that checkpoints hold, by module and name. Old names stay
#: (``evolution.run``'s ``Best`` and ``RunState`` are how checkpoints of structgen 0.1 name them).
CLASSES = frozenset(
    {
        ("evolution.runfolder", "Best"),
        ("evolution.runfolder", "RunState"),
        ("evolution.run", "Best"),
        ("evolution.run", "RunState"),
        ("evolution.optimizers", "CMAES"),
        ("evolution.optimizers", "GASettings"),
        ("evolution.optimizers", "GeneticAlgorithm"),
        ("evolution.optimizers", "_Normal"),
        ("evolution.optimizers", "RandomSearch"),
        ("evolution.optimizers", "RandomSettings"),
        ("evolution.qd", "FieldRankedArchive"),
        ("evolution.qd", "ProblemMutationEmitter"),
        ("evolution.qd", "RibsOptimizer"),
        ("ribs.archives._archive_stats", "ArchiveStats"),
        ("ribs.archives._array_store", "ArrayStore"),
        ("ribs.archives._grid_archive", "GridArchive"),
        ("ribs.emitters._evolution_strategy_emitter", "EvolutionStrategyEmitter"),
        ("ribs.emitters._gaussian_emitter", "GaussianEmitter"),
        ("ribs.emitters._iso_line_emitter", "IsoLineEmitter"),
        ("ribs.emitters.opt._cma_es", "CMAEvolutionStrategy"),
        ("ribs.emitters.opt._cma_es", "DecompMatrix"),
        ("ribs.emitters.opt._sep_cma_es", "DiagonalMatrix"),
        ("ribs.emitters.opt._sep_cma_es", "SeparableCMAEvolutionStrategy"),
        ("ribs.emitters.rankers", "ImprovementRanker"),
        ("ribs.emitters.rankers", "ObjectiveRanker"),
        ("ribs.emitters.rankers", "TwoStageImprovementRanker"),
        ("ribs.emitters.rankers", "TwoStageObjectiveRanker"),
        ("ribs.schedulers._scheduler", "Scheduler"),
        ("cma.boundary_handler", "BoundNone"),
        ("cma.boundary_handler", "BoundTransform"),
        ("cma.evolution_strategy", "CMAEvolutionStrategy"),
        ("cma.evolution_strategy", "_CMASolutionDict_functional"),
        ("cma.evolution_strategy", "_CMASolutionDict_empty"),  # pycma's archive from 33 genomes a generation on
        ("cma.evolution_strategy", "_CMAStopDict"),
        ("cma.evolution_strategy", "_StopTolXStagnation"),
        ("cma.logger", "CMADataLogger"),
        ("cma.optimization_tools", "BestSolution"),
        ("cma.options_parameters", "CMAOptions"),
        ("cma.options_parameters", "CMAParameters"),
        ("cma.recombination_weights", "RecombinationWeights"),
        ("cma.sampler", "GaussFullSampler"),
        ("cma.sampler", "GaussStandardConstant"),
        ("cma.sigma_adaptation", "CMAAdaptSigmaCSA"),
        # pycma adapts the step size this way instead of CSA from 300 parameters on (every NCA's genome).
        ("cma.sigma_adaptation", "CMAAdaptSigmaTPA"),
        ("cma.sigma_adaptation", "_TPAParameters"),
        ("cma.transformations", "DiagonalDecoding"),
        ("cma.transformations", "GenoPheno"),
        ("cma.transformations", "RoundIntegerVariables"),
        ("cma.utilities.utils", "BlancClass"),
        ("cma.utilities.utils", "DictFromTagsInString"),
        ("cma.utilities.utils", "ElapsedWCTime"),
        ("cma.utilities.utils", "MoreToWrite"),
        ("cma.utilities.utils", "SolutionDict"),
    }
)
# Functions pycma stores among its options (referred to, never called while loading).
_REFERENCES = frozenset(
    {("cma.evolution_strategy", "_pass"), ("cma.options_parameters", "is_feasible"), ("numpy.linalg", "eigh")}
)


def _name(found: Any) -> tuple[str, str]:
    return found.__module__, found.__qualname__ if isinstance(found, type) else found.__name__


# numpy's callables and types and the built-in types, by the names pickles give them (numpy's module layout differs
# between versions, so the names are read off numpy itself).
_NAMED_CALLS = {_name(call): call for call in _CALLS}
_NAMED_TYPES = {_name(kind): kind for kind in _TYPES}
# pyribs keeps the name of its array module in the state and imports it when unpickling.
_ARRAY_MODULES = frozenset({"numpy", "array_api_compat.numpy"})


def plain_dataclass(found: type) -> bool:
    """Whether unpickling an instance of ``found`` only sets its fields: a dataclass made by ``object.__new__`` with
    no ``__setstate__`` (genome types must be, see :func:`loads`)."""
    return hasattr(found, "__dataclass_fields__") and found.__new__ is object.__new__ and not hasattr(found, "__setstate__")


def _numpy_scalar_type(module: str, name: str) -> bool:
    # numpy is loaded already: looking a name up in it imports nothing.
    found = getattr(np, name, None) if module == "numpy" else None
    return isinstance(found, type) and issubclass(found, np.generic)


class _Unpickler(pickle._Unpickler):  # the pure-Python reader: its instructions can be checked one by one
    dispatch = pickle._Unpickler.dispatch.copy()

    def __init__(self, file: io.BytesIO, genome_types: Collection[type], genomes: Callable[[Any], Any] | None) -> None:
        super().__init__(file)
        self.genome_types = {_name(kind): kind for kind in genome_types}
        self.genomes = genomes

    def persistent_load(self, pid: Any) -> Any:
        # A genome kept in the run's genome store, named by its key (the pid is plain data, read by this reader).
        if self.genomes is None or not (isinstance(pid, tuple) and len(pid) == 2 and pid[0] == "genome" and type(pid[1]) is int):
            raise UnsafeCheckpointError(f"it refers to an outside object {pid!r} that no genome store provides")
        return self.genomes(pid[1])

    def find_class(self, module: str, name: str) -> Any:
        key = (module, name)
        # Decided from the name alone: nothing is imported for a name that is not admitted.
        if key in _NAMED_CALLS:
            return _NAMED_CALLS[key]
        if key in _NAMED_TYPES:
            return _NAMED_TYPES[key]
        if key in self.genome_types:
            kind = self.genome_types[key]
            if plain_dataclass(kind):
                return kind
        elif key in CLASSES or key in _REFERENCES or _numpy_scalar_type(module, name):
            try:
                found = super().find_class(module, name)
            except Exception as err:
                raise UnsafeCheckpointError(f"it names {module}.{name}, which cannot be found ({err})") from None
            if key in _REFERENCES or _numpy_scalar_type(module, name):
                return found
            if isinstance(found, type) and found.__new__ in _PLAIN_NEW:
                return found
        raise UnsafeCheckpointError(f"it names {module}.{name}, which a checkpoint never holds")

    def load_reduce(self) -> None:
        function = self.stack[-2]
        if function not in _CALLS:
            raise UnsafeCheckpointError(f"it asks to call {getattr(function, '__qualname__', function)!r}")
        super().load_reduce()

    def load_build(self) -> None:
        state = self.stack[-1]
        if isinstance(state, dict) and "_xp" in state and state["_xp"] not in _ARRAY_MODULES:
            raise UnsafeCheckpointError(f"it asks to import the module {state['_xp']!r}")
        super().load_build()

    def _refuse(self) -> None:
        raise UnsafeCheckpointError("it uses pickle instructions that call constructors or the extension registry")

    dispatch[pickle.REDUCE[0]] = load_reduce
    dispatch[pickle.BUILD[0]] = load_build
    for _code in (pickle.INST, pickle.OBJ, pickle.EXT1, pickle.EXT2, pickle.EXT4):
        dispatch[_code[0]] = _refuse
    del _code


def loads(data: bytes, genome_types: Collection[type] = (), genomes: Callable[[int], Any] | None = None) -> Any:
    """The object pickled in ``data``, if it is made only of what checkpoints hold; else UnsafeCheckpointError.

    ``genome_types`` are the classes the run's genomes are made of (the problem's ``genome_types``); each must be a
    plain dataclass (:func:`plain_dataclass`), or it is refused like any other class. ``genomes`` gives the genome
    of a key, for checkpoints that refer to genomes in the run's genome store (``("genome", key)``)."""
    return _Unpickler(io.BytesIO(data), genome_types, genomes).load()
