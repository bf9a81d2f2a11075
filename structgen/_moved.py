"""Old module names that still import, for one release, with a DeprecationWarning naming the new home.

Each alias module holds one call, ``moved(__name__, "new.home")``: it puts the new module in ``sys.modules`` under the
old name, so ``import structgen.teach`` and ``from structgen.teach import teach`` give the very same objects as the new
name does (private helpers too), and warns the code that imported it.
"""

from __future__ import annotations

import importlib
import sys
import warnings

#: The release in which the old names stop working.
REMOVED_IN = "0.4"


def _importer_level() -> int:
    """The stack level of the first frame outside this module, the alias module and the import machinery, so the
    warning names the user's line (and Python's default filters show it where that line is in ``__main__``).
    ``warnings`` itself steps over the import machinery's frames, so they are not counted."""
    level, frame = 1, sys._getframe(1)
    while frame is not None:
        name = frame.f_globals.get("__name__", "")
        internal = "importlib" in frame.f_code.co_filename and "_bootstrap" in frame.f_code.co_filename
        if not internal and name != __name__ and name not in _ALIASES:
            return level
        level += 0 if internal else 1
        frame = frame.f_back
    return level


_ALIASES: dict[str, str] = {}


def moved(old: str, new: str) -> None:
    """Make the module ``old`` (being imported now) the module ``new``, with a DeprecationWarning."""
    _ALIASES[old] = new
    module = importlib.import_module(new)
    sys.modules[old] = module
    warnings.warn(
        f"{old} moved to {new}; import it from there (the old name goes in structgen {REMOVED_IN})",
        DeprecationWarning,
        stacklevel=_importer_level(),
    )
