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

import json
from pathlib import Path
from typing import Any

from evolution import RunFolder
from evolution.files import atomic_write
from structgen.config import ConfigError, build, flatten, to_table
from structgen.errors import InputError

__all__ = [
    "HISTORY_FILE",
    "is_training_folder",
    "open_training_folder",
    "read_history",
    "read_training_settings",
    "save_torch",
    "write_history",
]

HISTORY_FILE = "history.jsonl"


def _config_text(settings: Any, table: str, header: str) -> str:
    import tomli_w

    return f"# {header}: every setting, as used.\n" + tomli_w.dumps({table: to_table(settings)})


def read_training_settings(folder: RunFolder, settings_class: type, table: str) -> Any:
    """The settings of the training in ``folder`` (its ``config.toml`` has the one table ``table``)."""
    from structgen.experiment import parse_toml

    where = folder / RunFolder.CONFIG
    tables = parse_toml(folder.config_text(), where)
    if set(tables) != {table} or not isinstance(tables[table], dict):
        raise InputError(f"{where}: this training's configuration has one table, [{table}]")
    try:
        return build(settings_class, tables[table], table)
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
) -> RunFolder:
    """A new run folder for ``settings``, or the one the same training started (see the module). ``about`` (plain
    values, such as the run a training learns from) goes into the manifest and must match when the folder resumes."""
    from structgen.runs import manifest

    folder = RunFolder(path)
    if path.exists() and not path.is_dir():
        raise InputError(f"{path}: is a file, expected a run folder")
    if not is_training_folder(path, run_kind) or overwrite:
        if (folder / RunFolder.CONFIG).is_file() and not overwrite:
            raise InputError(f"{path}: holds a run that is not a {run_kind} training; choose another folder")
        made = manifest(domain, ("numpy", "torch"), run_kind=run_kind, **(about or {}))
        return RunFolder.create(path, _config_text(settings, table, header), made, overwrite=overwrite)
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
    folder.write_config(_config_text(settings, table, header))
    return folder


def read_history(folder: RunFolder, upto: int) -> list[dict[str, Any]]:
    """The rows of ``history.jsonl`` up to update ``upto`` (those after the last checkpoint are dropped)."""
    path = folder / HISTORY_FILE
    if not path.is_file():
        return []
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return [row for row in rows if row["update"] <= upto]


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
