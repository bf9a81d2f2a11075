"""Dependencies point one way, and the import graph has no circles: the rules of tests/layering.py (which reads the
graph and the layers from the code) held over every module."""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

from structgen._moved import MOVED
from tests.layering import GRAPH, MODULES, ROOT, TYPED_GRAPH, domain_of, layer


def test_the_graph_covers_the_project():
    assert {"structgen.cli", "structgen.domains.structures.problem", "evolution.runfolder", "physics.statics"} <= set(GRAPH)
    assert "structgen.registry" in GRAPH["structgen.runs.experiment"]
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


@pytest.mark.parametrize("old", sorted(MOVED))
def test_the_old_names_of_moved_modules_are_the_new_modules_with_a_warning(old):
    import importlib

    new = MOVED[old]
    code = f"import warnings; warnings.simplefilter('always'); import {old}"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    # The warning names the user's line, not the import machinery's.
    assert f"<string>:1: DeprecationWarning: {old} moved to {new};" in done.stderr, done.stderr
    with pytest.deprecated_call():
        found = importlib.import_module(old)
    if any(name.startswith(old + ".") for name in MOVED):  # a moved package: a stand-in that hands out the new names
        assert getattr(found, "__all__", None) == getattr(importlib.import_module(new), "__all__", None)
    else:
        assert found is importlib.import_module(new) and found.__spec__.name == new


def test_a_submodule_of_a_moved_package_imports_by_its_old_name():
    code = (
        "from structgen.domains.warehouse import maze_env; import structgen.domains.layouts.maze.env as e; print(maze_env is e)"
    )
    done = subprocess.run([sys.executable, "-W", "ignore", "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert done.stdout.split() == ["True"]


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


def test_git_ignores_no_file_of_the_code_docs_or_tests():
    # A pattern meant for the run folders the commands write (runs/) once hid every new module of structgen/runs/
    # from git, so a clone lacked it, and from ruff, which skips what git ignores.
    if not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: nothing for git to ignore")
    folders = ["structgen", "physics", "evolution", "tests", "benchmarks", "docs", "examples", "configs"]
    # New files an ignore pattern hides, and files in git that one matches (their new siblings would be hidden).
    for which in ("--others", "--cached"):
        listed = subprocess.run(
            ["git", "ls-files", which, "--ignored", "--exclude-standard", "--", *folders],
            capture_output=True, text=True, check=True, cwd=ROOT,
        ).stdout.split()  # fmt: skip
        assert [path for path in listed if "__pycache__" not in path and ".egg-info" not in path] == [], which
