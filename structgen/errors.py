"""The one error type for bad input, so that the command line can tell the user's mistakes from bugs.

Every error about input a person gave (a file, a setting, an option value) is an :class:`InputError`: the command line
reports it in one line with exit code 2. Its subclasses say where it arose (``StructureError`` for structure files,
``ConfigError`` for settings); a new data type or domain derives its own from it.
"""

from __future__ import annotations

__all__ = ["InputError", "StructureError"]


class InputError(ValueError):
    """Bad input from the user (a file, a setting, an option value); the message names it and says what is wrong."""


class StructureError(InputError):
    """A structure, its file, or a mesh of it is invalid; the message names the file, the field, the index and the
    value at fault."""
