"""Loading a checkpoint without running anything it contains.

A checkpoint is a pickle of the run's state: the optimiser (pycma's and pyribs' objects among them), numpy arrays
and random generators. Ordinary unpickling runs whatever callables a file names, so a crafted ``checkpoint.pkl``
could run any command. :func:`loads` reads only what checkpoints are made of:

- **Objects** are made without calling their constructors: a class is admitted only if it belongs to the engine or
  to the optimiser libraries (``evolution``, ``ribs``, ``cma``) and creates its instances with the plain
  ``object.__new__`` (or ``dict.__new__``/``list.__new__``), or if it is one of a few named numpy and built-in types,
  or if it is a plain dataclass of a built-in domain (``structgen.domains``: genomes such as a fortress world) with
  no ``__setstate__`` of its own, so that restoring it only sets its fields.
- **Calls** (the pickle REDUCE instruction) are allowed for the numpy functions that rebuild arrays, scalars,
  dtypes and random generators, and for ``range`` and ``slice``, which only make a value (pycma keeps a range in
  its state when it mirrors samples, as it does in populations under 6).
- The instructions of old pickle protocols that call constructors, and the extension registry, are refused; so are
  function references other than three that pycma keeps among its options, and a module name in pyribs' array
  state other than numpy's.

Anything else stops loading with :class:`UnsafeCheckpointError`, before it is created. The reader is pickle's own
pure-Python unpickler with those instructions checked, so it reads every checkpoint the engine writes.
"""

from __future__ import annotations

import collections
import io
import pickle
from collections.abc import Collection
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
_PACKAGES = ("evolution", "ribs", "cma")
# Functions pycma stores among its options (referred to, never called while loading).
_REFERENCES = {("cma.evolution_strategy", "_pass"), ("cma.options_parameters", "is_feasible"), ("numpy.linalg", "eigh")}
# pyribs keeps the name of its array module in the state and imports it when unpickling.
_ARRAY_MODULES = frozenset({"numpy", "array_api_compat.numpy"})


def plain_dataclass(found: type) -> bool:
    """Whether unpickling an instance of ``found`` only sets its fields: a dataclass made by ``object.__new__`` with
    no ``__setstate__`` (genome types must be, see :func:`loads`)."""
    return hasattr(found, "__dataclass_fields__") and found.__new__ is object.__new__ and not hasattr(found, "__setstate__")


class _Unpickler(pickle._Unpickler):  # the pure-Python reader: its instructions can be checked one by one
    dispatch = pickle._Unpickler.dispatch.copy()

    def __init__(self, file: io.BytesIO, genome_types: Collection[type]) -> None:
        super().__init__(file)
        self.genome_types = frozenset(genome_types)

    def find_class(self, module: str, name: str) -> Any:
        try:
            found = super().find_class(module, name)
        except Exception as err:
            raise UnsafeCheckpointError(f"it names {module}.{name}, which cannot be found ({err})") from None
        if found in _CALLS or found in _TYPES or (module, name) in _REFERENCES:
            return found
        if isinstance(found, type):
            if issubclass(found, np.generic):  # numpy scalar types (int32, float64, ...)
                return found
            if module.split(".")[0] in _PACKAGES and found.__new__ in _PLAIN_NEW:
                return found
            if found in self.genome_types and plain_dataclass(found):
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


def loads(data: bytes, genome_types: Collection[type] = ()) -> Any:
    """The object pickled in ``data``, if it is made only of what checkpoints hold; else UnsafeCheckpointError.

    ``genome_types`` are the classes the run's genomes are made of (the problem's ``genome_types``); each must be a
    plain dataclass (:func:`plain_dataclass`), or it is refused like any other class."""
    return _Unpickler(io.BytesIO(data), genome_types).load()
