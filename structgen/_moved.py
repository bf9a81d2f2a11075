"""Old module names that still import, for one release, with a DeprecationWarning naming the new home.

:data:`MOVED` maps each old name to its new one; :func:`install` (run by ``import structgen``) adds a finder to
``sys.meta_path`` that answers only those names: ``import structgen.grid`` and ``from structgen.grid import Grid`` give
the very same module objects as the new names do (private helpers too), and warn the code that imported them. A moved
package is a stand-in whose submodules import by their old names and whose other names are the new package's. No
file is kept under an old name, so no old name can drift from its new module.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import warnings
from types import ModuleType
from typing import Any

__all__ = ["MOVED", "REMOVED_IN", "install"]

#: The release in which the old names stop working.
REMOVED_IN = "0.5"

_LAYOUTS = "structgen.domains.layouts"
#: Old module name -> new module name. In 0.4 each layer got its folder (what describes domains in ``registry/``,
#: what runs them in ``runs/``) and the layout domains one family package (its shared grid and generator out of
#: structgen's core, the maze in its own folder).
MOVED: dict[str, str] = {
    "structgen.commands": "structgen.registry.commands",
    "structgen.experiment": "structgen.runs.experiment",
    "structgen.seed_runs": "structgen.runs.seed_runs",
    "structgen.training_folder": "structgen.runs.training_folder",
    "structgen.domain_check": "structgen.runs.domain_check",
    "structgen.grid": f"{_LAYOUTS}.grid",
    "structgen.conv_nca": f"{_LAYOUTS}.conv_nca",
    "structgen.domains.warehouse": _LAYOUTS,
    "structgen.domains.warehouse.layouts": f"{_LAYOUTS}.kinds",
    "structgen.domains.warehouse.measures": f"{_LAYOUTS}.measures",
    "structgen.domains.warehouse.repair": f"{_LAYOUTS}.repair",
    "structgen.domains.warehouse.patch": f"{_LAYOUTS}.patch",
    "structgen.domains.warehouse.problem": f"{_LAYOUTS}.problem",
    "structgen.domains.warehouse.show": f"{_LAYOUTS}.show",
    "structgen.domains.warehouse.commands": f"{_LAYOUTS}.commands",
    "structgen.domains.warehouse.simulator": f"{_LAYOUTS}.warehouse.simulator",
    "structgen.domains.warehouse.maze": f"{_LAYOUTS}.maze.walkers",
    "structgen.domains.warehouse.maze_env": f"{_LAYOUTS}.maze.env",
    "structgen.domains.warehouse.maze_agent": f"{_LAYOUTS}.maze.agent",
    "structgen.domains.warehouse.maze_training": f"{_LAYOUTS}.maze.training",
    "structgen.domains.warehouse.maze_experiment": f"{_LAYOUTS}.maze.experiment",
    "structgen.domains.warehouse.agent_settings": f"{_LAYOUTS}.maze.agent_settings",
}


def _importer_level() -> int:
    """The stack level of the first frame outside this module, importlib and the import machinery, so the warning names the
    user's line (and Python's default filters show it where that line is in ``__main__``). ``warnings`` itself steps
    over the import machinery's frames, so they are not counted."""
    level, frame = 1, sys._getframe(1)
    while frame is not None:
        internal = "importlib" in frame.f_code.co_filename and "_bootstrap" in frame.f_code.co_filename
        # importlib.import_module: the stand-in package's way to a submodule's old name
        if not internal and frame.f_globals.get("__name__", "") not in (__name__, "importlib"):
            return level
        level += 0 if internal else 1
        frame = frame.f_back
    return level


class _OldNames(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old names only; each loads as the module now at the new name."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> importlib.machinery.ModuleSpec | None:
        return importlib.machinery.ModuleSpec(name, self) if name in MOVED else None

    def __init__(self) -> None:
        self._own_specs: dict[str, Any] = {}

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> ModuleType:
        if any(old.startswith(spec.name + ".") for old in MOVED):
            return _old_package(spec.name)
        module = importlib.import_module(MOVED[spec.name])
        # The import system is about to stamp the old name's spec on the module: keep its own to put back.
        self._own_specs[spec.name] = module.__spec__
        return module

    def exec_module(self, module: ModuleType) -> None:
        old = module.__spec__.name
        if old in self._own_specs:
            module.__spec__ = self._own_specs.pop(old)
        warnings.warn(
            f"{old} moved to {MOVED[old]}; import it from there (the old name goes in structgen {REMOVED_IN})",
            DeprecationWarning,
            stacklevel=_importer_level(),
        )


def _old_package(old: str) -> ModuleType:
    """A stand-in for a package that moved: its submodules import by their old names (``from old import module``
    must find ``old.module``, not ``new.module``), every other name is the new package's."""
    package = ModuleType(old, f"Deprecated name of {MOVED[old]}.")
    package.__path__ = []

    def __getattr__(name: str) -> Any:
        if f"{old}.{name}" in MOVED:
            return importlib.import_module(f"{old}.{name}")
        return getattr(importlib.import_module(MOVED[old]), name)

    package.__getattr__ = __getattr__  # type: ignore[method-assign]
    return package


def install() -> None:
    """Answer the old names (once per interpreter; last on ``sys.meta_path``, so no real module is ever shadowed)."""
    if not any(isinstance(finder, _OldNames) for finder in sys.meta_path):
        sys.meta_path.append(_OldNames())
