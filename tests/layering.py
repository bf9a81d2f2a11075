"""The project's import graph and its layers, read from the code: what tests/test_layering.py holds to and the
layer picture of docs/architecture.md draws (docs/hooks.py).

Dependencies point one way, and the import graph has no circles.

Layers, lowest first; a module may import from its own layer's modules and from lower layers only. A module's layer
is the folder it sits in (``FOLDER_LAYERS``), so a new module is placed by where it is put:

1. ``physics/`` and ``evolution/``: libraries that never import ``structgen``. ``evolution`` never imports
   ``physics``; ``physics`` uses only evolution's worker pool (``evolution.pool``, the one pool every parallel step
   runs on).
2. structgen's own files (``structgen/*.py``): the data types, generators, export and settings (``structure``,
   ``nca``, ``mesh``, ``config``...).
3. ``structgen/registry/``: how domains are described and how they add verbs.
4. ``structgen/runs/``: configurations, runs, agent trainings and the domain contract's checker, for any domain.
5. ``structgen/domains/<name>/``: none imports another domain.
6. ``structgen/cli/`` (and ``structgen/__main__.py``, which Python needs at the top): knows domains only through
   the registry.

Imports inside functions count (they are edges all the same); those under ``if TYPE_CHECKING:`` do not place a module
(they never run) but do count as circles (a reader follows them all the same), and those in a module's ``__getattr__``
do not count, which only offers users a name from a higher layer on first use
(``structgen.check_domain``).
``import structgen`` stays light (so its thread policy is set before torch or numba can start): no physics, pybullet,
ribs, trimesh, torch or numba until they are needed, and of evolution only the file gate (``evolution.files``), which
every file structgen reads and writes goes through.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("structgen", "physics", "evolution")


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(path): path for package in PACKAGES for path in (ROOT / package).rglob("*.py")}


def _runtime_nodes(tree: ast.AST, *, type_only: bool = False) -> list[ast.AST]:
    """Every node of ``tree`` except those inside ``if TYPE_CHECKING:`` blocks (kept with ``type_only``) and a
    module's own ``__getattr__`` (PEP 562): the lazy names a package offers its users (``structgen.check_domain``)
    are not what its code uses."""
    nodes, stack = [], [tree]
    while stack:
        node = stack.pop()
        checking = ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING") if isinstance(node, ast.If) else False
        if checking and not type_only:
            stack.extend(node.orelse)
            continue
        if isinstance(node, ast.FunctionDef) and node.name == "__getattr__" and node in getattr(tree, "body", []):
            continue
        nodes.append(node)
        stack.extend(ast.iter_child_nodes(node))
    return nodes


def imports_of(name: str, *, type_only: bool = False) -> set[str]:
    """The project modules ``name`` imports at run time, anywhere in its source (and for type checkers only, with
    ``type_only``)."""
    found = set()
    tree = ast.parse(MODULES[name].read_text(), filename=str(MODULES[name]))
    # A package's own type-only imports type the names its __getattr__ offers users lazily: not its code's either.
    type_only = type_only and MODULES[name].name != "__init__.py"
    for node in _runtime_nodes(tree, type_only=type_only):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            assert node.level == 0, f"{name}: relative import"
            targets = [
                f"{node.module}.{alias.name}" if f"{node.module}.{alias.name}" in MODULES else node.module for alias in node.names
            ]
        else:
            continue
        # `from a import b` imports the module a.b if there is one (its package a runs first, as for any module of
        # a: not an edge of its own), else the name b from a.
        found.update(t for t in targets if t in MODULES)
    found.discard(name)
    return found


GRAPH = {name: imports_of(name) for name in MODULES}
#: GRAPH with the imports made for type checkers only: no circle in it either.
TYPED_GRAPH = {name: imports_of(name, type_only=True) for name in MODULES}


#: Each folder of structgen is one layer; a module's layer is where it is put. structgen's own files
#: (``structgen/*.py``) are its core (layer 2), save ``__main__``, which Python needs at the top (it only calls the
#: command line). A new folder gets its layer here.
FOLDER_LAYERS = {"registry": 3, "runs": 4, "domains": 5, "cli": 6}


def layer(name: str) -> int:
    if name.split(".")[0] in ("physics", "evolution"):
        return 1
    if name == "structgen.__main__":
        return FOLDER_LAYERS["cli"]
    place = MODULES[name].relative_to(ROOT / "structgen")
    if len(place.parts) == 1:
        return 2
    assert place.parts[0] in FOLDER_LAYERS, f"{name}: structgen/{place.parts[0]}/ has no layer; give it one in FOLDER_LAYERS"
    return FOLDER_LAYERS[place.parts[0]]


def domain_of(name: str) -> str | None:
    parts = name.split(".")
    return parts[2] if name.startswith("structgen.domains.") else None
