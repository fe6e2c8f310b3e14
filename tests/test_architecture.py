"""The package's shape (docs/architecture.md): layers import only downwards, no import circles,
no module imports another's private names.

Every ``import`` and ``from ... import`` of the package is read from the source (those inside
functions too), so an import hidden in a function body cannot close a circle or reach upwards.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "tensegrity"

#: Layers, lowest first; a module may import its own layer and the layers below it.  Modules
#: of one layer may not import each other across packages of the same rank ("io" and
#: "analysis" share a rank, as do "sweep" and "plots").
LAYERS: list[tuple[str, ...]] = [
    ("model",),
    ("physics",),
    ("engine",),
    ("io", "analysis"),
    ("design",),
    ("sweep", "plots"),
    ("cli",),
]
RANK = {package: rank for rank, packages in enumerate(LAYERS) for package in packages}


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _package(module: str) -> str:
    """``tensegrity.engine.loop`` -> ``engine``; the root ``tensegrity`` -> ``""``."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def _imports(path: Path) -> list[tuple[str, list[str], int]]:
    """``(module, imported names, line)`` of every import of the package in ``path``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if (
            isinstance(node, ast.ImportFrom)
            and node.module
            and node.module.startswith("tensegrity")
        ):
            found.append((node.module, [a.name for a in node.names], node.lineno))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("tensegrity"):
                    found.append((alias.name, [], node.lineno))
    return found


def _target(module: str, name: str, modules: dict[str, Path]) -> str:
    """The module ``from module import name`` loads: a submodule, or ``module`` itself."""
    return f"{module}.{name}" if f"{module}.{name}" in modules else module


def _edges() -> list[tuple[str, str, int]]:
    modules = _modules()
    edges = []
    for source, path in modules.items():
        for module, names, line in _imports(path):
            for target in {_target(module, name, modules) for name in names} or {module}:
                edges.append((source, target, line))
    return edges


def test_every_package_has_a_layer():
    packages = {_package(m) for m in _modules()} - {""}
    assert packages == set(RANK), f"packages without a layer: {packages - set(RANK)}"


def test_imports_follow_the_layers():
    """model -> physics -> engine -> {io, analysis} -> design -> {sweep, plots} -> cli."""
    wrong = []
    for source, target, line in _edges():
        a, b = _package(source), _package(target)
        if not a or not b or a == b:
            continue  # the root re-exports; a package imports itself
        if RANK[b] >= RANK[a]:
            wrong.append(f"{source}:{line} imports {target} ({b} is not below {a})")
    assert not wrong, "\n".join(wrong)


def test_no_import_circles():
    graph: dict[str, set[str]] = {}
    for source, target, _ in _edges():
        if source != target and _package(source) and _package(target):
            graph.setdefault(source, set()).add(target)
    circles = []
    state: dict[str, int] = {}  # 1: on the current path, 2: done

    def visit(node: str, path: list[str]) -> None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                circles.append(" -> ".join([*path[path.index(nxt) :], node, nxt]))
            elif nxt not in state:
                visit(nxt, [*path, node])
        state[node] = 2

    for node in sorted(graph):
        if node not in state:
            visit(node, [])
    assert not circles, "\n".join(circles)


def _module_aliases(tree: ast.AST, modules: dict[str, str | Path]) -> dict[str, str]:
    """Local names bound to a module of the package (``from tensegrity.io import trajectory as
    tio``, ``import tensegrity.physics.dynamics as d``) -> that module."""
    aliases = {}
    for node in ast.walk(tree):
        if (
            isinstance(node, ast.ImportFrom)
            and node.module
            and node.module.startswith("tensegrity")
        ):
            for a in node.names:
                if f"{node.module}.{a.name}" in modules:
                    aliases[a.asname or a.name] = f"{node.module}.{a.name}"
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("tensegrity") and a.asname:
                    aliases[a.asname] = a.name
    return aliases


def test_no_private_names_across_modules():
    """Neither ``from m import _x`` nor ``m._x`` on an imported module ``m`` of the package."""
    modules = _modules()
    wrong = []
    for source, path in modules.items():
        for module, names, line in _imports(path):
            for name in names:
                if name.startswith("_") and _target(module, name, modules) == module != source:
                    wrong.append(f"{source}:{line} imports {module}.{name}")
        tree = ast.parse(path.read_text())
        aliases = _module_aliases(tree, modules)
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and isinstance(node.value, ast.Name)
                and node.value.id in aliases
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
            ):
                wrong.append(f"{source}:{node.lineno} uses {aliases[node.value.id]}.{node.attr}")
    assert not wrong, "\n".join(wrong)


@pytest.mark.parametrize(
    "where, line, check",
    [
        ("model/a.py", "from tensegrity.cli.main import main", test_imports_follow_the_layers),
        ("engine/a.py", "import tensegrity.engine.b", test_no_import_circles),
        (
            "model/a.py",
            "from tensegrity.model.structure import _readonly",
            test_no_private_names_across_modules,
        ),
        (
            "model/a.py",
            "from tensegrity.model import structure as s\ns._readonly",
            test_no_private_names_across_modules,
        ),
    ],
)
def test_the_checks_catch_what_they_look_for(tmp_path, monkeypatch, where, line, check):
    """Each check fails on a copy of the package with one such import added (the circle:
    ``engine/a.py`` and ``engine/b.py`` importing each other)."""
    fake = tmp_path / "tensegrity"
    for path in PACKAGE.rglob("*.py"):
        copy = fake / path.relative_to(PACKAGE)
        copy.parent.mkdir(parents=True, exist_ok=True)
        copy.write_text(path.read_text())
    (fake / where).write_text(line + "\n")
    (fake / "engine" / "b.py").write_text("import tensegrity.engine.a\n")
    check()  # the package as it is passes
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", fake)
    with pytest.raises(AssertionError):
        check()
