"""Dependencies point one way: structgen may use physics and evolution, never the reverse, and `import structgen`
stays light (no physics, evolution, pybullet, ribs or trimesh until they are needed)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def imported_modules(package: str) -> set[str]:
    """Top-level names of every module imported anywhere in a package's source, including inside functions."""
    names = set()
    for path in (ROOT / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                names.update(alias.name.split(".")[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", ["physics", "evolution"])
def test_libraries_never_import_structgen(package):
    assert "structgen" not in imported_modules(package)


def test_physics_and_evolution_do_not_import_each_other():
    assert "evolution" not in imported_modules("physics")
    assert "physics" not in imported_modules("evolution")


def loaded_after(statement: str) -> set[str]:
    code = f"import sys; {statement}; print(' '.join(sorted(m.split('.')[0] for m in sys.modules)))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    return set(done.stdout.split())


def test_import_structgen_pulls_in_neither_library_nor_heavy_dependencies():
    loaded = loaded_after("import structgen")
    assert not loaded & {"physics", "evolution", "pybullet", "ribs", "trimesh", "torch"}


def test_growing_a_structure_still_needs_neither_library():
    loaded = loaded_after("import structgen; structgen.LocalNCA.random(0).grow()")
    assert "torch" in loaded
    assert not loaded & {"physics", "evolution", "pybullet", "ribs"}


@pytest.mark.parametrize("package", ["physics", "evolution"])
def test_importing_a_library_does_not_load_structgen(package):
    assert "structgen" not in loaded_after(f"import {package}")


def test_import_evolution_stays_light():
    # pyribs pulls in numba; it loads only when a quality-diversity optimiser is built.
    assert not loaded_after("import evolution") & {"ribs", "numba", "torch", "pybullet", "structgen", "physics"}
