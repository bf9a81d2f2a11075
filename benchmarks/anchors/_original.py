"""What every anchor script does to get hold of an original: take the checkout it was given, or clone one."""

from __future__ import annotations

import importlib
import subprocess
import sys
from pathlib import Path
from types import ModuleType


def checkout_of_original(given: Path | None, scratch: Path, repository: str, needs: tuple[str, ...]) -> Path:
    """``given`` if it holds every path in ``needs`` (relative to it), else a shallow clone of ``repository`` into
    ``scratch``; exits with a message naming the folder, or the clone's error, when neither works."""
    if given is not None:
        missing = [need for need in needs if not (given / need).exists()]
        if missing:
            raise SystemExit(f"--original {given}: not a checkout of {repository} (no {', '.join(missing)})")
        return given
    target = scratch / repository.rstrip("/").rsplit("/", 1)[-1]
    done = subprocess.run(["git", "clone", "--quiet", "--depth", "1", repository, str(target)], capture_output=True, text=True)
    if done.returncode:
        raise SystemExit(
            f"could not clone {repository}: {done.stderr.strip()} (figures recorded without it: benchmarks/anchors/README.md)"
        )
    return target


def import_from_original(checkout: Path, module: str) -> ModuleType:
    """``module`` imported from the original's checkout; exits naming what is missing (usually a dependency that
    ``pip install 'structgen[anchors]'`` brings)."""
    sys.path.insert(0, str(checkout))
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as error:
        raise SystemExit(f"cannot import the original from {checkout}: {error} (pip install 'structgen[anchors]')") from None
