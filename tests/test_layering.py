"""Dependencies point one way, and the import graph has no circles.

Layers, lowest first; a module may import from its own layer's modules and from lower layers only:

1. ``physics`` and ``evolution``: libraries that never import ``structgen``. ``evolution`` never imports ``physics``;
   ``physics`` uses only evolution's worker pool (``evolution.pool``, the one pool every parallel step runs on).
2. structgen's core: the data types, generators, export and settings (``structure``, ``nca``, ``mesh``, ``config``...).
3. ``structgen.registry`` and ``structgen.commands``: how domains are described and how they add verbs.
4. ``structgen.experiment``, ``structgen.runs``, ``structgen.seed_runs`` and ``structgen.domain_check``: configurations,
   runs and the domain contract's checker, for any domain.
5. the domains (``structgen.domains.<name>``): none imports another domain.
6. ``structgen.cli``: knows domains only through the registry.

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
import subprocess
import sys
from pathlib import Path

import pytest

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


#: structgen's core (layer 2), by name: what more than one domain or the product shares. A new module of structgen
#: outside the domains must be added here (or to another layer) on purpose.
CORE = {
    "structgen",
    "structgen._moved",
    "structgen._version",
    "structgen.budget",
    "structgen.config",
    "structgen.conv_nca",
    "structgen.devices",
    "structgen.errors",
    "structgen.grid",
    "structgen.lattice",
    "structgen.mesh",
    "structgen.nca",
    "structgen.nca_config",
    "structgen.ppo",
    "structgen.ppo_settings",
    "structgen.reference_data",
    "structgen.structure",
    "structgen.threads",
}
#: Old names of modules that moved into a domain, kept for one release (structgen._moved): the top layer, so that no
#: module of the project imports them.
ALIASES = {"structgen.render", "structgen.samples", "structgen.tall", "structgen.teach"}


def layer(name: str) -> int:
    top = name.split(".")[0]
    if top in ("physics", "evolution"):
        return 1
    if name in CORE:
        return 2
    if name in ("structgen.domains", "structgen.registry", "structgen.commands"):
        return 3
    if name in (
        "structgen.experiment",
        "structgen.runs",
        "structgen.seed_runs",
        "structgen.training_folder",
        "structgen.domain_check",
    ):
        return 4
    if name.startswith("structgen.domains."):
        return 5
    if name == "structgen.cli" or name == "structgen.__main__":
        return 6
    if name in ALIASES:
        return 7
    raise AssertionError(f"{name}: no layer; name it in tests/test_layering.py (CORE, ALIASES, ...)")


def domain_of(name: str) -> str | None:
    parts = name.split(".")
    return parts[2] if name.startswith("structgen.domains.") else None


def test_the_graph_covers_the_project():
    assert {"structgen.cli", "structgen.domains.structures.problem", "evolution.runfolder", "physics.statics"} <= set(GRAPH)
    assert "structgen.registry" in GRAPH["structgen.experiment"]
    assert "structgen.mesh" in GRAPH["structgen.structure"]  # imported inside a method: an edge all the same


def test_the_import_graph_has_no_circles_type_only_imports_included():
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(name: str, path: list[str]) -> None:
        state[name] = 1
        for target in sorted(TYPED_GRAPH[name]):
            if state.get(target) == 1:
                circle = path[path.index(target) :] + [target]
                raise AssertionError("import circle: " + " -> ".join(circle))
            if target not in state:
                visit(target, [*path, target])
        state[name] = 2

    for name in sorted(TYPED_GRAPH):
        if name not in state:
            visit(name, [name])


def test_every_module_has_a_layer():
    for name in MODULES:
        layer(name)


def test_the_old_names_of_moved_modules_are_the_new_modules_with_a_warning():
    import importlib

    for old in sorted(ALIASES):
        new = "structgen.domains.structures." + old.split(".")[-1]
        code = f"import warnings; warnings.simplefilter('error'); import {old}"
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
        assert done.returncode != 0 and "DeprecationWarning" in done.stderr and new in done.stderr, old
        with pytest.deprecated_call():
            assert importlib.import_module(old) is importlib.import_module(new)


def test_no_module_imports_from_a_higher_layer():
    upward = [(a, b) for a in GRAPH for b in GRAPH[a] if layer(b) > layer(a)]
    assert upward == []


@pytest.mark.parametrize("package", ["physics", "evolution"])
def test_libraries_never_import_structgen(package):
    assert not [(a, b) for a in GRAPH if a.startswith(package) for b in GRAPH[a] if b.startswith("structgen")]


@pytest.mark.parametrize("package", ["physics", "evolution"])
def test_libraries_do_not_even_name_structgen_in_their_code(package):
    # Not in an import, nor in a string (a module name checked at run time); docstrings and comments may.
    named = []
    for name, path in MODULES.items():
        if name.split(".")[0] != package:
            continue
        tree = ast.parse(path.read_text())
        docstrings = {
            id(node.body[0].value)
            for node in ast.walk(tree)
            if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and node.body
            and isinstance(node.body[0], ast.Expr)
            and isinstance(node.body[0].value, ast.Constant)
        }
        for node in ast.walk(tree):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
                if "structgen" in node.value:
                    named.append((name, node.lineno, node.value[:60]))
    assert named == []


#: What physics may use of evolution: the one worker pool, which itself imports nothing else of the project.
SHARED_INFRASTRUCTURE = {"evolution.pool"}


def test_evolution_never_imports_physics_and_physics_uses_only_the_worker_pool_of_evolution():
    assert not [(a, b) for a in GRAPH if a.startswith("evolution") for b in GRAPH[a] if b.startswith("physics")]
    used = {b for a in GRAPH if a.startswith("physics") for b in GRAPH[a] if b.startswith("evolution")}
    assert used <= SHARED_INFRASTRUCTURE
    for name in SHARED_INFRASTRUCTURE:
        assert GRAPH[name] == set(), name


def test_domains_do_not_import_each_other():
    crossing = [(a, b) for a in GRAPH for b in GRAPH[a] if domain_of(a) and domain_of(b) and domain_of(a) != domain_of(b)]
    assert crossing == []


def test_the_command_line_names_no_domain():
    import re

    from structgen import domains

    source = MODULES["structgen.cli"].read_text()
    for spec in domains.specs():
        for name in (spec.id, spec.group_name, *spec.aliases):
            assert not re.search(rf"\b{re.escape(name)}\b", source), name
        for verb in spec.shortcuts:  # a verb as a string literal ("check"; the word checkpoint is fine)
            assert f'"{verb}"' not in source and f"'{verb}'" not in source, verb


def loaded_after(statement: str, *, full: bool = False) -> set[str]:
    """The modules loaded after ``statement`` in a fresh interpreter (top-level names unless ``full``)."""
    name = "m" if full else "m.split('.')[0]"
    code = f"import sys; {statement}; print(' '.join(sorted({name} for m in sys.modules)))"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    return set(done.stdout.split())


def engine_modules(loaded: set[str]) -> set[str]:
    """Loaded modules of the evolution engine beyond the package and its file gate."""
    return {m for m in loaded if m.startswith("evolution.") and m != "evolution.files"}


def test_import_structgen_pulls_in_neither_library_nor_heavy_dependencies():
    loaded = loaded_after("import structgen", full=True)
    assert not {m.split(".")[0] for m in loaded} & {"physics", "pybullet", "ribs", "trimesh", "torch", "numba"}
    assert not engine_modules(loaded)


def test_growing_a_structure_still_needs_neither_library():
    loaded = loaded_after("import structgen; structgen.LocalNCA.random(0).grow()", full=True)
    assert "torch" in loaded
    assert not {m.split(".")[0] for m in loaded} & {"physics", "pybullet", "ribs"} and not engine_modules(loaded)


def test_listing_domains_and_building_the_command_line_load_no_engine():
    loaded = loaded_after(
        "from structgen import domains; domains.specs(); from structgen.cli import build_parser; build_parser()"
    )
    assert not loaded & {"torch", "pybullet", "ribs", "numba", "trimesh", "scipy", "matplotlib"}


@pytest.mark.parametrize("package", ["physics", "evolution"])
def test_importing_a_library_does_not_load_structgen(package):
    assert "structgen" not in loaded_after(f"import {package}")


def test_import_evolution_stays_light():
    # pyribs pulls in numba; it loads only when a quality-diversity optimiser is built.
    assert not loaded_after("import evolution") & {"ribs", "numba", "torch", "pybullet", "structgen", "physics"}
