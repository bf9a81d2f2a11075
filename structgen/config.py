"""Typed settings from TOML files and ``--set key=value`` overrides, checked before any work starts.

Every settings object in structgen, physics and evolution is a frozen dataclass with working defaults. This module
turns text into those objects: unknown keys and values of the wrong type fail with a :class:`ConfigError` that names
the key (``physics.timestep``), the value and what was expected; the dataclass's own checks then run as usual.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import types
import typing
from collections.abc import Iterable, Mapping
from typing import Any, Literal, TypeVar, get_args, get_origin

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["ConfigError", "apply_overrides", "build", "parse_assignment", "parse_value"]

T = TypeVar("T")


class ConfigError(ValueError):
    """A setting is unknown, of the wrong type, or out of range; the message names it."""


def parse_value(text: str) -> Any:
    """A ``--set`` value as TOML would read it (``3``, ``0.5``, ``true``, ``"x"``, ``[1, 2]``, ``inf``); anything
    TOML cannot read is taken as a plain string, so ``--set optimizer.name=ga`` works without quotes."""
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        return text


def parse_assignment(text: str) -> tuple[str, Any]:
    """Split ``"section.key=value"`` into the key and its parsed value."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {text!r}: expected key=value")
    return key.strip(), parse_value(value.strip())


def _type_name(kind: Any) -> str:
    if get_origin(kind) is Literal:
        return " or ".join(repr(choice) for choice in get_args(kind))
    names = {bool: "true or false", int: "an integer", float: "a number", str: "a string"}
    if kind in names:
        return names[kind]
    if get_origin(kind) in (typing.Union, types.UnionType):
        return " or ".join(_type_name(k) for k in get_args(kind) if k is not type(None)) + " (or absent)"
    if get_origin(kind) in (tuple, list):
        return "a list"
    return getattr(kind, "__name__", str(kind))


def _convert(value: Any, kind: Any, where: str) -> Any:
    """``value`` checked against the annotation ``kind`` (int/float/bool/str, Literal, Optional, tuples)."""
    origin = get_origin(kind)
    if origin in (typing.Union, types.UnionType):
        options = get_args(kind)
        if value is None and type(None) in options:
            return None
        for option in options:
            if option is type(None):
                continue
            try:
                return _convert(value, option, where)
            except ConfigError:
                continue
    elif origin is Literal:
        if value in get_args(kind):
            return value
    elif origin in (tuple, list):
        if isinstance(value, (list, tuple)):
            args = get_args(kind)
            if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
                return tuple(_convert(v, args[0], f"{where}[{i}]") for i, v in enumerate(value))
            if origin is tuple and args and len(args) == len(value):
                return tuple(_convert(v, a, f"{where}[{i}]") for i, (v, a) in enumerate(zip(value, args)))
            if origin is list:
                return [_convert(v, args[0], f"{where}[{i}]") for i, v in enumerate(value)] if args else list(value)
    elif kind is bool:
        if isinstance(value, bool):
            return value
    elif kind is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif kind is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        if isinstance(value, str) and value.lower() in ("inf", "+inf"):
            return math.inf
    elif kind is str:
        if isinstance(value, str):
            return value
    elif kind is Any:
        return value
    raise ConfigError(f"{where} = {value!r}: expected {_type_name(kind)}")


def _fields(cls: type) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if f.init}


def build(cls: type[T], values: Mapping[str, Any], section: str, *, base: T | None = None) -> T:
    """An instance of the dataclass ``cls`` from ``values`` (unlisted fields keep ``base``'s or the defaults).

    ``section`` names the place in error messages (``"physics"`` makes keys read ``physics.timestep``).
    """
    known = _fields(cls)
    changes = {}
    for key, value in values.items():
        where = f"{section}.{key}" if section else key
        if key not in known:
            raise ConfigError(f"unknown setting {where!r}; {section or 'settings'} has: {', '.join(known)}")
        changes[key] = _convert(value, known[key], where)
    try:
        return dataclasses.replace(base, **changes) if base is not None else cls(**changes)
    except ValueError as err:  # the dataclass's own range checks, which name the field
        raise ConfigError(str(err)) from None


def apply_overrides(instance: T, assignments: Iterable[str], section: str) -> T:
    """``instance`` with ``--set key=value`` assignments applied; keys may carry the section prefix
    (``physics.timestep=0.01``) or not (``timestep=0.01``)."""
    values = {}
    for text in assignments:
        key, value = parse_assignment(text)
        prefix = f"{section}."
        values[key[len(prefix) :] if key.startswith(prefix) else key] = value
    return build(type(instance), values, section, base=instance)
