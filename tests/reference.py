"""The originals' reference data in the tests: where it is, and the mark of the tests that need it.

Tests that compare with the originals' data (their maps, their fortress files) run where the data is found
(:func:`structgen.reference_data.reference_data`) and are skipped, saying why, where it is not: a user's clone has no
such folder. CI has it, and sets ``STRUCTGEN_REQUIRE_REFERENCE_DATA``: then a missing folder, or any test skipped
for want of it, fails the run (``tests/conftest.py``).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from structgen.reference_data import VARIABLE, reference_data

#: Every skip for want of the data starts with this, which is how the suite tells those skips from others.
SKIP_REASON = "the originals' reference data is not on this machine"
#: Set by CI where the data is: a reference test that does not run is then a failure.
REQUIRE_VARIABLE = "STRUCTGEN_REQUIRE_REFERENCE_DATA"
FOLDERS = ("warehouse-maps", "amorphous-fortress")


def folder(name: str) -> Path:
    """The data's subfolder ``name``, or a path that does not exist (globs over it find nothing)."""
    return reference_data(name) or Path("/nonexistent") / "reference-data" / name


def maps() -> Path:
    """The warehouse paper's maps (``$STRUCTGEN_REFERENCE_MAPS`` still names them too), or a path that does not exist."""
    from structgen.domains.layouts.kinds import reference_maps

    return reference_maps() or folder("warehouse-maps")


def needs(name: str) -> pytest.MarkDecorator:
    """Skip the test, saying why, unless the data's subfolder ``name`` is on this machine."""
    found = maps().is_dir() if name == "warehouse-maps" else reference_data(name) is not None
    return pytest.mark.skipif(
        not found,
        reason=f"{SKIP_REASON} ({name}/; set ${VARIABLE} to the folder that holds it)",
    )
