"""One settings grammar: typed settings from TOML tables and ``--set key=value``, and back to tables.

Every settings object in structgen, physics and evolution is a frozen dataclass with working defaults; a field whose
type is itself a settings dataclass is a nested table (``[problem.nca]``). This module is the only place that turns
text into those objects and objects back into text:

- :func:`build` makes an object from a table, recursing into nested tables. Each default lives in the dataclass (or
  in the field's default of the dataclass that holds it), nowhere else. Unknown keys and values of the wrong type
  fail with a :class:`ConfigError` naming the key (``problem.physics.timestep``), the value and what was expected;
  the dataclass's own range checks then run as usual.
- :func:`to_table` is its inverse: every setting spelled out, ready for ``tomli_w``.
- **Presets** are a declared hook: a settings class that has a ``presets()`` classmethod (returning a mapping of
  names to instances, like :meth:`physics.PhysicsConfig.presets`) accepts a ``preset`` key, which starts its table
  from that instance before the other keys apply. :func:`to_table` writes ``preset`` back when an object equals one.
- **Limits**: a settings class may list the range and meaning of its numeric fields in a ``limits`` class attribute
  (:class:`Limit`; merged over its bases, so a subclass adds or narrows them). One place then serves the check
  (:func:`check_limits`, from ``__post_init__``), the command-line option made from the field
  (:func:`structgen.registry.commands.add_setting_options`) and its help.
- **Keys** in ``--set`` name a setting by its full dotted path (``problem.nca.cutoff``) or by any tail of it that no
  other setting shares (``nca.cutoff``, ``cutoff``): :func:`resolve_key`. The same rule holds in every subcommand,
  so ``structgen evaluate --set break_force=60`` is short for ``--set physics.break_force=60``.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import sys
import types
import typing
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Literal, TypeVar, get_args, get_origin

from structgen.errors import InputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = [
    "ConfigError",
    "Limit",
    "check_limits",
    "limits_of",
    "apply_overrides",
    "build",
    "flatten",
    "parse_assignment",
    "parse_value",
    "presets_of",
    "resolve_key",
    "set_path",
    "setting_paths",
    "to_table",
]

T = TypeVar("T")


class ConfigError(InputError):
    """A setting is unknown, of the wrong type, or out of range; the message names it.

    ``key`` is the dotted name of the setting at fault, or of the table whose own checks refused it, where known:
    callers use it to say whether the value came from a file or from ``--set``.
    """

    def __init__(self, message: str, key: str | None = None) -> None:
        super().__init__(message)
        self.key = key


# -- text ---------------------------------------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Limit:
    """The range a numeric setting may take and what it means, in one place for its check, its option and its help.

    Attributes:
        low, high: the range, both ends included (``high`` may be infinite).
        help: what the setting does, one line (its option's help).
        whole: a whole number (else any finite number).
        above: ``low`` itself excluded (a number above ``low``).
        below: ``high`` itself excluded (a number below ``high``).
        option: its command-line option where not ``--`` + the field's name with dashes.
    """

    low: float
    high: float
    help: str
    whole: bool = True
    above: bool = False
    below: bool = False
    option: str | None = None

    def describe(self) -> str:
        """The range in words: ``a whole number from 1 to 10,000``, ``a number above 0, at most 1``."""
        kind = "a whole number" if self.whole else "a number"
        shown = (lambda x: f"{x:,}") if self.whole else (lambda x: f"{x:g}")
        if self.above and self.below:
            return f"{kind} strictly between {shown(self.low)} and {shown(self.high)}"
        if self.below:
            return f"{kind} below {shown(self.high)}" + ("" if self.low == -math.inf else f", at least {shown(self.low)}")
        if self.above:
            return f"{kind} above {shown(self.low)}" + ("" if self.high == math.inf else f", at most {shown(self.high)}")
        start = "" if self.low == -math.inf else f" from {shown(self.low)}"
        end = "" if self.high == math.inf else (f" to {shown(self.high)}" if start else f" of at most {shown(self.high)}")
        return f"{kind}{start}{end}"

    def admits(self, value: Any) -> bool:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return False
        if self.whole and not isinstance(value, int):
            return False
        if isinstance(value, float) and not math.isfinite(value):  # (a whole number of any size is finite)
            return False
        above_low = value > self.low if self.above else value >= self.low
        return above_low and (value < self.high if self.below else value <= self.high)


def limits_of(cls: type) -> dict[str, Limit]:
    """Every field limit of ``cls``: its ``limits`` and its bases', a subclass's entry winning."""
    found: dict[str, Limit] = {}
    for klass in reversed(cls.__mro__):
        found.update(vars(klass).get("limits", {}))
    return found


def check_limits(settings: Any) -> None:
    """Raise ValueError naming the setting (``section name``), its value and its range for the first field of
    ``settings`` outside its :class:`Limit`."""
    section = getattr(settings, "section", type(settings).__name__)
    for name, limit in limits_of(type(settings)).items():
        value = getattr(settings, name)
        if not limit.admits(value):
            raise ValueError(f"{section} {name} = {value!r}: expected {limit.describe()}")


def parse_value(text: str) -> Any:
    """A ``--set`` value as TOML would read it (``3``, ``0.5``, ``true``, ``"x"``, ``[1, 2]``, ``inf``); anything
    TOML cannot read is taken as a plain string, so ``--set optimizer.name=ga`` works without quotes. A value nested
    too deeply, or a whole number too long to convert, is refused naming it."""
    try:
        return tomllib.loads(f"value = {text}")["value"]
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:
        raise ConfigError(f"--set value {text[:40]!r}...: nested too deeply") from None
    except ValueError:  # Python refuses to convert whole numbers of more than 4,300 digits
        raise ConfigError(f"--set value {text[:40]!r}...: a number too long to read") from None


def parse_assignment(text: str) -> tuple[str, Any]:
    """Split ``"section.key=value"`` into the key and its parsed value."""
    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ConfigError(f"--set {text!r}: expected key=value")
    return key.strip(), parse_value(value.strip())


# -- the shape of settings ------------------------------------------------------------------------------------------------
def presets_of(cls: type) -> Mapping[str, Any]:
    """The named presets a settings class declares through a ``presets()`` classmethod (empty if it has none)."""
    declared = getattr(cls, "presets", None)
    return declared() if callable(declared) else {}


def _fields(cls: type) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls) if f.init}


def _is_settings(kind: Any) -> bool:
    return isinstance(kind, type) and dataclasses.is_dataclass(kind)


def setting_paths(cls: type, prefix: str = "") -> list[str]:
    """Every dotted name a table of ``cls`` can hold: its fields, its nested tables and their fields, and
    ``preset`` where the class declares presets."""
    paths = [f"{prefix}preset"] if presets_of(cls) else []
    for name, kind in _fields(cls).items():
        paths.append(prefix + name)
        if _is_settings(kind):
            paths += setting_paths(kind, f"{prefix}{name}.")
    return paths


def resolve_key(key: str, paths: Sequence[str], roots: Iterable[str] = ()) -> str:
    """The full dotted path that ``key`` names among ``paths``.

    A key that starts with one of ``roots`` (the top-level tables, e.g. ``run``, ``problem``, ``optimizer``) is taken
    as written, and :func:`build` will say if it does not exist. Otherwise it must be a whole path or the tail of
    exactly one.
    """
    roots = list(roots)
    if key in paths or key.split(".")[0] in roots:
        return key
    matches = [path for path in paths if path.endswith("." + key)]
    if len(matches) == 1:
        return matches[0]
    if matches:
        raise ConfigError(f"--set {key}: several settings have that name ({', '.join(matches)}); write the whole name")
    if len(roots) == 1:  # one table of settings: let build() say what it holds
        return f"{roots[0]}.{key}"
    close = difflib.get_close_matches(key, paths + [p.rsplit(".", 1)[-1] for p in paths], n=3)
    hint = f" (did you mean {' or '.join(dict.fromkeys(close))}?)" if close else ""
    raise ConfigError(f"unknown setting {key!r}{hint}")


def set_path(tables: dict[str, Any], key: str, value: Any) -> None:
    """Put ``value`` at a dotted path like ``problem.nca.cutoff``, making tables on the way."""
    *parents, last = key.split(".")
    node = tables
    for i, part in enumerate(parents):
        child = node.setdefault(part, {})
        if not isinstance(child, dict):
            raise ConfigError(f"--set {key}: {'.'.join(parents[: i + 1])} is a value, not a table")
        node = child
    node[last] = value


# -- values -------------------------------------------------------------------------------------------------------------
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
    raise ConfigError(f"{where} = {value!r}: expected {_type_name(kind)}", where)


def _default(cls: type, name: str) -> Any:
    for item in dataclasses.fields(cls):
        if item.name == name:
            if item.default is not dataclasses.MISSING:
                return item.default
            if item.default_factory is not dataclasses.MISSING:
                return item.default_factory()
    return None


# -- tables <-> objects -----------------------------------------------------------------------------------------------------
def build(cls: type[T], values: Mapping[str, Any], section: str = "", *, base: T | None = None) -> T:
    """An instance of the settings dataclass ``cls`` from the table ``values``.

    Settings the table does not name keep ``base``'s values (or the class defaults); a nested table starts from the
    corresponding field of ``base`` (or that field's default), or from a preset it names. ``section`` is where the
    table sits, for error messages (``"problem"`` makes keys read ``problem.init_scale``).
    """
    values = dict(values)
    presets = presets_of(cls)
    if "preset" in values and presets:
        name = values.pop("preset")
        if name not in presets:
            where = f"{section}.preset" if section else "preset"
            raise ConfigError(f"{where}: unknown preset {name!r}; choose one of {', '.join(presets)}", where)
        base = presets[name]
    known = _fields(cls)
    changes = {}
    for key, value in values.items():
        where = f"{section}.{key}" if section else key
        if key not in known:
            names = (["preset"] if presets else []) + list(known)
            raise ConfigError(f"unknown setting {where!r}; {section or 'the settings'} has: {', '.join(names)}", where)
        kind = known[key]
        if _is_settings(kind):
            if not isinstance(value, Mapping):
                raise ConfigError(f"{where} must be a table, got {value!r}", where)
            nested_base = getattr(base, key) if base is not None else _default(cls, key)
            changes[key] = build(kind, value, where, base=nested_base)
        else:
            changes[key] = _convert(value, kind, where)
    try:
        return dataclasses.replace(base, **changes) if base is not None else cls(**changes)
    except ConfigError:
        raise
    except (ValueError, TypeError) as err:  # the dataclass's own range checks, which name the field
        raise ConfigError(str(err), section) from None


def to_table(settings: Any) -> dict[str, Any]:
    """The table :func:`build` reads back into an equal object: every setting spelled out, nested settings as
    sub-tables, ``preset`` first where the object equals a declared preset. TOML has no null, so settings that are
    None are left out (they read back as their default, None)."""
    table: dict[str, Any] = {}
    preset = next((name for name, value in presets_of(type(settings)).items() if value == settings), None)
    if preset is not None:
        table["preset"] = preset
    for item in dataclasses.fields(settings):
        if not item.init:
            continue
        value = _plain(getattr(settings, item.name))
        if value is not None:
            table[item.name] = value
    return table


def flatten(table: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Every value of nested tables under its dotted path: ``{"nca": {"cutoff": 0.6}}`` -> ``{"nca.cutoff": 0.6}``."""
    found: dict[str, Any] = {}
    for key, value in table.items():
        found.update(flatten(value, f"{prefix}{key}.") if isinstance(value, Mapping) else {prefix + key: value})
    return found


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_table(value)
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def apply_overrides(roots: Mapping[str, Any], assignments: Iterable[str | tuple[str, Any]]) -> dict[str, Any]:
    """Settings objects named by their table (``{"physics": PhysicsConfig(...)}``) with assignments applied: ``--set``
    texts (``"key=value"``) or ``(key, value)`` pairs, later ones winning.

    Keys follow :func:`resolve_key`: ``physics.break_force=60`` or, as no other setting has that name,
    ``break_force=60``. A ``preset`` assignment applies before the others whatever its position.
    """
    paths = [path for name, value in roots.items() for path in [name, *setting_paths(type(value), f"{name}.")]]
    tables: dict[str, Any] = {}
    for item in assignments:
        key, value = parse_assignment(item) if isinstance(item, str) else item
        set_path(tables, resolve_key(key, paths, roots), value)
    unknown = sorted(set(tables) - set(roots))
    if unknown:
        raise ConfigError(f"unknown setting {unknown[0]!r}; choose among {', '.join(roots)}")
    result = dict(roots)
    for name, table in tables.items():
        if not isinstance(table, dict):
            raise ConfigError(f"--set {name}: {name} is a table of settings, not a value")
        result[name] = build(type(roots[name]), table, name, base=roots[name])
    return result
