"""Run folders of agent trainings (the maze agent, Autoverse's players): one settings table in ``config.toml``, a
``manifest.json`` naming the ``run_kind``, ``history.jsonl`` with one row per update and a learning-curve picture.

The rules every such training follows, kept here once:

- A folder is made new, or it is the folder of the same training, which then resumes; only the settings named
  ``growable`` may differ, and only upwards (more updates go on where the run stopped). Anything else is refused
  with the setting named and the folder left as it was.
- History and picture are rewritten whole, atomically, at each checkpoint; rows past the checkpoint's update are
  dropped when a run resumes.
"""

from __future__ import annotations

import contextlib
import io
import json
import pickle
import re
import zipfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from evolution import RunFolder
from evolution.files import InputFileError, MiB, atomic_write, parse_json, read_bytes, read_text
from structgen.config import ConfigError, build, flatten, to_table
from structgen.errors import InputError

__all__ = [
    "HISTORY_FILE",
    "is_training_folder",
    "open_training_folder",
    "read_history",
    "read_training_settings",
    "write_training_settings",
    "checked_like",
    "checked_optimiser",
    "checked_whole",
    "checked_weights",
    "load_torch",
    "new_folder_removed_on_failure",
    "one_line",
    "save_torch",
    "write_history",
]

HISTORY_FILE = "history.jsonl"


def _config_text(settings: Any, table: str, header: str) -> str:
    import tomli_w

    return f"# {header}: every setting, as used.\n" + tomli_w.dumps({table: to_table(settings)})


def read_training_settings(folder: RunFolder, settings_class: type, table: str) -> Any:
    """The settings of the training in ``folder`` (its ``config.toml`` has the one table ``table``). A setting added
    after the folder was written takes the value it had in effect before (``settings_class.before_added``), not
    its new default, so that an older training resumes as it began."""
    from structgen.runs.experiment import parse_toml

    where = folder / RunFolder.CONFIG
    tables = parse_toml(folder.config_text(), where)
    if set(tables) != {table} or not isinstance(tables[table], dict):
        raise InputError(f"{where}: this training's configuration has one table, [{table}]")
    try:
        return build(settings_class, {**getattr(settings_class, "before_added", {}), **tables[table]}, table)
    except ConfigError as err:
        raise InputError(f"{where}: {err}") from None


def is_training_folder(path: str | Path, run_kind: str) -> bool:
    folder = RunFolder(path)
    return (folder / RunFolder.CONFIG).is_file() and folder.manifest().get("run_kind") == run_kind


def open_training_folder(
    path: Path,
    settings: Any,
    *,
    run_kind: str,
    domain: str,
    table: str,
    header: str,
    overwrite: bool = False,
    growable: tuple[str, ...] = ("updates",),
    about: dict[str, Any] | None = None,
    reads: tuple[str | Path, ...] = (),
) -> RunFolder:
    """A new run folder for ``settings``, or the one the same training started (see the module). ``about`` (plain
    values, such as the run a training learns from) goes into the manifest and must match when the folder resumes;
    ``reads`` are the folders the command reads from, which ``overwrite`` never deletes. A resumed folder is not
    changed here: the caller writes its settings with :func:`write_training_settings` once its checkpoint and
    history have been read back, with the folder's lock held, so that a refused command changes nothing."""
    from structgen.runs import manifest

    folder = RunFolder(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{path}: is a file, expected a run folder")
    if not is_training_folder(path, run_kind) or overwrite:
        if (folder / RunFolder.CONFIG).is_file() and not overwrite:
            raise InputError(f"{path}: holds a run that is not a {run_kind} training; choose another folder")
        made = manifest(domain, ("numpy", "torch"), run_kind=run_kind, **(about or {}))
        return RunFolder.create(path, _config_text(settings, table, header), made, overwrite=overwrite, keep=reads)
    recorded = folder.manifest()
    for key, value in (about or {}).items():
        if recorded.get(key) != value:
            raise InputError(
                f"{folder / 'manifest.json'}: this folder holds a training with {key} {recorded.get(key)!r}, not {value!r}; "
                "choose another folder"
            )
    saved = read_training_settings(folder, type(settings), table)
    before, now = flatten(to_table(saved)), flatten(to_table(settings))
    for key in sorted(before.keys() | now.keys()):
        if before.get(key) != now.get(key) and not (key in growable and now[key] > before[key]):
            raise InputError(
                f"{folder / RunFolder.CONFIG}: this folder holds a training with {table}.{key} = {before.get(key)!r}, "
                f"not {now.get(key)!r}; give the same settings to resume it (or more {' or '.join(growable)} to go on), "
                "or another folder"
            )
    return folder


def write_training_settings(folder: RunFolder, settings: Any, table: str, header: str) -> None:
    """Record ``settings`` (more updates than before, say) in the training's ``config.toml``; call it with the
    folder's lock held, once nothing can refuse any more."""
    text = _config_text(settings, table, header)
    if folder.config_text() != text:
        folder.write_config(text)


#: The most rows a training's history may hold (one per update) and the bytes it may take.
_MAX_HISTORY_ROWS, _MAX_HISTORY_BYTES = 10**7, 1024 * MiB


def read_history(folder: RunFolder, upto: int) -> list[dict[str, Any]]:
    """The rows of ``history.jsonl`` up to update ``upto`` (those after the last checkpoint are dropped). Every row
    is checked: a JSON object whose ``update`` is a whole number from 0 to ``upto``'s bound and whose other fields
    are numbers or null; anything else, or a path that is not a regular file, is an :class:`InputError` naming the
    file and the line."""
    path = folder / HISTORY_FILE
    if not path.exists() and not path.is_symlink():
        return []
    try:
        text = read_text(path, _MAX_HISTORY_BYTES, what="one JSON object per line")
    except InputFileError as err:
        raise InputError(str(err)) from None
    rows = []
    for number, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        try:
            row = parse_json(line, f"{path}, line {number}")
        except InputFileError as err:
            raise InputError(str(err)) from None
        update = row.get("update") if isinstance(row, dict) else None
        if isinstance(update, bool) or not isinstance(update, int) or not 0 <= update <= _MAX_HISTORY_ROWS:
            raise InputError(
                f"{path}, line {number}: field 'update' is {update!r}; expected a whole number from 0 to "
                f"{_MAX_HISTORY_ROWS} in a JSON object"
            )
        for key, value in row.items():  # a row holds numbers, and null where an update measured nothing
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))):
                raise InputError(f"{path}, line {number}: field {key!r} is {value!r}; expected a number or null")
        if update <= upto:
            rows.append(row)
    return rows


def write_history(folder: RunFolder, rows: list[dict[str, Any]], pictures: dict[str, Any]) -> None:
    """``history.jsonl`` and each ``pictures`` entry (file name -> figure), atomically."""
    from evolution.plots import figure_png

    atomic_write(folder / HISTORY_FILE, "".join(json.dumps(row) + "\n" for row in rows))
    for name, figure in pictures.items():
        atomic_write(folder / name, figure_png(figure))


def save_torch(path: Path, state: Any) -> Path:
    """``torch.save`` of ``state`` to ``path``, written atomically (a checkpoint or weights file is never left half
    written)."""
    import io

    import torch

    buffer = io.BytesIO()
    torch.save(state, buffer)
    return atomic_write(path, buffer.getvalue())


#: What a weights file or a training checkpoint may hold, on disk and unpacked: far above what any training writes.
TORCH_FILE_LIMIT = 256 * MiB
_TERMINAL_CODES = re.compile(r"\x1b\[[0-9;]*m")


def load_torch(path: str | Path, what: str, limit: int = TORCH_FILE_LIMIT) -> Any:
    """What :func:`save_torch` wrote to ``path`` (``what`` names it in errors: "a maze agent file"), read as data:
    a regular file of at most ``limit`` bytes whose archive members unpack to at most ``limit`` bytes in all (checked
    by unpacking them, before torch allocates anything), loaded with torch's tensors-and-numbers-only unpickler.
    Anything else is an :class:`InputError` of one line naming the file."""
    import torch

    try:
        data = read_bytes(path, limit)
    except InputFileError as err:
        raise InputError(str(err)) from None
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            unpacked = 0
            for member in archive.infolist():
                with archive.open(member) as stream:
                    while chunk := stream.read(1 << 20):
                        unpacked += len(chunk)
                        if unpacked > limit:
                            raise InputError(
                                f"{path}: unpacks to more than {limit // MiB} MiB (a compressed archive, which "
                                f"save_torch never writes); not {what}"
                            )
    except (zipfile.BadZipFile, EOFError, ValueError, NotImplementedError, RuntimeError, OSError) as err:
        raise InputError(f"{path}: not {what} (not a torch archive: {one_line(err)})") from None
    try:
        return torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises many kinds; a pickle of other objects says so at length, in colour
        message = one_line(err)
        if isinstance(err, pickle.UnpicklingError) or "weights_only" in message.lower() or "Weights only" in message:
            message = "it holds Python objects other than tensors, numbers and strings, and is not unpickled"
        raise InputError(f"{path}: not {what} ({message})") from None


def one_line(err: BaseException) -> str:
    """An exception as ``Type: first line of its message``, without terminal colour codes, for a one-line error."""
    text = _TERMINAL_CODES.sub("", str(err)).strip()
    return f"{type(err).__name__}: {text.splitlines()[0] if text else ''}".rstrip(": ")


def checked_whole(saved: Any, key: str, path: str | Path, low: int, high: int) -> int:
    """``saved[key]`` as a whole number from ``low`` to ``high`` (a Python int or a one-element integer tensor);
    otherwise an :class:`InputError` naming the file, the field and the value."""
    import torch

    value = saved.get(key) if isinstance(saved, dict) else None
    if isinstance(value, torch.Tensor) and value.numel() == 1 and not value.is_floating_point() and not value.is_complex():
        value = int(value.item())
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
        raise InputError(f"{path}: field {key!r} is {shown}; expected a whole number from {low} to {high}")
    return value


def checked_weights(saved: Any, key: str, path: str | Path) -> dict[str, Any]:
    """``saved[key]`` as a network's state dict: names to real, finite floating-point tensors (counters such as
    batch norm's may be integers); otherwise an :class:`InputError` naming the file and the field."""
    import torch

    weights = saved.get(key) if isinstance(saved, dict) else None
    if not isinstance(weights, dict) or not weights:
        raise InputError(f"{path}: field {key!r} is {type(weights).__name__}; expected the network's weights by name")
    for name, tensor in weights.items():
        if not isinstance(tensor, torch.Tensor):
            raise InputError(f"{path}: {key}.{name} is a {type(tensor).__name__}, not a tensor")
        if tensor.is_complex() or not (tensor.is_floating_point() or tensor.dtype in (torch.int64, torch.int32)):
            raise InputError(f"{path}: {key}.{name} holds {tensor.dtype} numbers; expected real floating point")
        if tensor.is_floating_point() and not bool(torch.isfinite(tensor).all()):
            raise InputError(f"{path}: {key}.{name} holds NaN or infinite weights")
    return weights


def checked_like(reference: Any, loaded: Any, path: str | Path, field: str, *, varying: tuple[str, ...] = ()) -> Any:
    """``loaded`` (part of a checkpoint) when it has the layout of ``reference`` (what a fresh training of the same
    settings holds there): the same keys, tensors of the same dtype and shape (only the same number of dimensions
    under the keys in ``varying``, whose sizes grow with the training), values of the same plain types; NaN and
    infinite floating-point tensors refused. Otherwise an :class:`InputError` naming the file and the field."""
    import torch

    if isinstance(reference, dict):
        if not isinstance(loaded, dict):
            raise InputError(f"{path}: {field} is {type(loaded).__name__}; expected a table of {', '.join(map(str, reference))}")
        for key, value in reference.items():
            if key not in loaded:
                raise InputError(f"{path}: {field}.{key} is missing")
            grows = key in varying
            checked_like(value, loaded[key], path, f"{field}.{key}", varying=varying if not grows else ("*",))
        return loaded
    if isinstance(reference, torch.Tensor):
        if not isinstance(loaded, torch.Tensor) or loaded.dtype != reference.dtype:
            found = loaded.dtype if isinstance(loaded, torch.Tensor) else type(loaded).__name__
            raise InputError(f"{path}: {field} is {found}; expected a tensor of {reference.dtype}")
        shape_ok = loaded.dim() == reference.dim() if "*" in varying else loaded.shape == reference.shape
        if not shape_ok:
            raise InputError(f"{path}: {field} has shape {tuple(loaded.shape)}; expected {tuple(reference.shape)}")
        if loaded.is_floating_point() and not bool(torch.isfinite(loaded).all()):
            raise InputError(f"{path}: {field} holds NaN or infinite values")
        return loaded
    if isinstance(reference, (list, tuple)):
        if not isinstance(loaded, (list, tuple)) or ("*" not in varying and len(loaded) != len(reference)):
            raise InputError(f"{path}: {field} is {type(loaded).__name__}; expected a list of {len(reference)}")
        if "*" not in varying:
            for number, (a, b) in enumerate(zip(reference, loaded)):
                checked_like(a, b, path, f"{field}[{number}]", varying=varying)
        return loaded
    plain = (bool,) if isinstance(reference, bool) else (int,) if isinstance(reference, int) else (type(reference),)
    wrong_bool = isinstance(loaded, bool) and not isinstance(reference, bool)
    if reference is not None and (not isinstance(loaded, plain) or wrong_bool):
        raise InputError(f"{path}: {field} is {type(loaded).__name__}; expected {type(reference).__name__}")
    return loaded


def checked_optimiser(saved: Any, key: str, path: str | Path, parameters: list[Any]) -> dict[str, Any]:
    """``saved[key]`` as the state of an Adam optimiser of ``parameters``: its moments shaped as the parameters and
    finite, so that a damaged checkpoint is refused when read rather than failing part-way through training."""
    import torch

    state = saved.get(key) if isinstance(saved, dict) else None
    if not isinstance(state, dict) or not isinstance(state.get("state"), dict) or not isinstance(state.get("param_groups"), list):
        raise InputError(f"{path}: field {key!r} is not an optimiser's state (no 'state' and 'param_groups')")
    for index, moments in state["state"].items():
        if not isinstance(index, int) or not 0 <= index < len(parameters) or not isinstance(moments, dict):
            raise InputError(f"{path}: {key}.state holds an entry {index!r} for no parameter")
        for name, value in moments.items():
            if not isinstance(value, torch.Tensor) or not value.is_floating_point() or not bool(torch.isfinite(value).all()):
                raise InputError(f"{path}: {key}.state[{index}].{name} is not a finite floating-point tensor")
            if name != "step" and value.shape != parameters[index].shape:
                raise InputError(
                    f"{path}: {key}.state[{index}].{name} has shape {tuple(value.shape)}; expected "
                    f"{tuple(parameters[index].shape)}"
                )
    return state


@contextlib.contextmanager
def new_folder_removed_on_failure(path: Path, *progress_files: str) -> Iterator[None]:
    """Around a training that may make the folder ``path``: if it was not there (or was empty) and the training
    fails before it has written any of ``progress_files`` (a checkpoint), what it wrote is removed again, so that a
    refused or failed command leaves nothing behind (a folder the user made stays, empty). An interrupted training
    (Ctrl-C) keeps its folder: ``resume`` starts it again from the beginning, to the same result."""
    made_here = not path.exists()
    fresh = made_here or (path.is_dir() and not any(path.iterdir()))
    try:
        yield
    except Exception:
        folder = RunFolder(path)
        if fresh and path.is_dir() and not any((path / name).exists() for name in progress_files) and folder.is_marked():
            folder.remove(keep_folder=not made_here)
        raise
