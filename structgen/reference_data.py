"""Where the originals' reference data lies on this machine, if anywhere.

The papers' public code ships data that our tests and benchmarks compare with: the warehouse paper's maps
(``warehouse-maps/``) and the Amorphous Fortress's entity and fortress files (``amorphous-fortress/``). Those
repositories carry no licence, so their files are never part of structgen: a user who wants the comparisons puts
them in a folder and names it in ``$STRUCTGEN_REFERENCE_DATA``; in a checkout, ``shared/data`` beside it (or beside
any folder above it) is found without being named. Everything else in the project works without them.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["VARIABLE", "reference_data"]

#: Environment variable naming the folder that holds ``warehouse-maps/`` and ``amorphous-fortress/``.
VARIABLE = "STRUCTGEN_REFERENCE_DATA"


def reference_data(name: str | None = None) -> Path | None:
    """The reference data folder (``$STRUCTGEN_REFERENCE_DATA``, else ``shared/data`` beside the checkout or a
    folder above it), or its subfolder ``name``; None where it is not on this machine."""
    named = os.environ.get(VARIABLE)
    if named:
        root: Path | None = Path(named)
    else:
        root = next(
            (folder / "shared" / "data" for folder in Path(__file__).resolve().parents if (folder / "shared" / "data").is_dir()),
            None,
        )
    if root is None or not root.is_dir():
        return None
    if name is None:
        return root
    folder = root / name
    return folder if folder.is_dir() else None
