"""The package's shape (docs/architecture.md): layers import only downwards, no import circles,
no module imports another's private names, no layer imports a name through the root.

Every ``import`` and ``from ... import`` of the package is read from the source (those inside
functions too), so an import hidden in a function body cannot close a circle or reach upwards;
so are relative imports (``from ..cli import main``) and ``importlib.import_module`` (or
``__import__``) of a literal module name.
"""

from __future__ import annotations

import ast
import functools
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "tensegrity"

#: Layers, lowest first; a module may import its own layer and the layers below it.  Modules
#: of one layer may not import each other across packages of the same rank ("io" and
#: "analysis" share a rank, as do "sweep", "plots" and "envs").
LAYERS: list[tuple[str, ...]] = [
    ("model",),
    ("physics",),
    ("engine",),
    ("io", "analysis"),
    ("design",),
    ("sweep", "plots", "envs"),
    ("cli",),
    ("__main__",),  # python -m tensegrity: the command
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


@functools.cache
def _tree(path: Path) -> ast.Module:
    """The parsed source of ``path`` (each file is read once)."""
    return ast.parse(path.read_text(), str(path))


def _absolute(source: str, path: Path, node: ast.ImportFrom) -> str | None:
    """The module ``node`` imports from, a relative import resolved against ``source``."""
    if not node.level:
        return node.module
    package = source.split(".") if path.name == "__init__.py" else source.split(".")[:-1]
    base = package[: len(package) - node.level + 1]
    return ".".join([*base, node.module] if node.module else base)


def _imported_by_name(node: ast.AST) -> str | None:
    """The literal module of ``importlib.import_module("...")`` or ``__import__("...")``."""
    if not (isinstance(node, ast.Call) and node.args):
        return None
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    first = node.args[0]
    if name in ("import_module", "__import__") and isinstance(first, ast.Constant):
        return first.value if isinstance(first.value, str) else None
    return None


def _imports(path: Path) -> list[tuple[str, list[str], int]]:
    """``(module, imported names, line)`` of every import of the package in ``path``."""
    source = _module_name(path)
    found = []
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.ImportFrom):
            module = _absolute(source, path, node)
            if module and module.split(".")[0] == "tensegrity":
                found.append((module, [a.name for a in node.names], node.lineno))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "tensegrity":
                    found.append((alias.name, [], node.lineno))
        elif (module := _imported_by_name(node)) and module.split(".")[0] == "tensegrity":
            found.append((module, [], node.lineno))
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
    """model -> physics -> engine -> {io, analysis} -> design -> {sweep, plots, envs} -> cli."""
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


def _module_aliases(source: str, path: Path, modules: dict[str, Path]) -> dict[str, str]:
    """Local names bound to a module of the package (``from tensegrity.io import trajectory as
    tio``, ``from . import files``, ``import tensegrity.physics.dynamics as d``; ``tensegrity``
    itself after ``import tensegrity.engine.loop``) -> that module."""
    aliases = {}
    for node in ast.walk(_tree(path)):
        if isinstance(node, ast.ImportFrom):
            module = _absolute(source, path, node)
            for a in node.names:
                if f"{module}.{a.name}" in modules:
                    aliases[a.asname or a.name] = f"{module}.{a.name}"
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == "tensegrity":
                    aliases[a.asname or "tensegrity"] = a.name if a.asname else "tensegrity"
    return aliases


def _attributes(path: Path, aliases: dict[str, str]) -> list[tuple[str, str, int]]:
    """``(module, attribute, line)`` for each ``m.x`` whose ``m`` is a module of the package: an
    alias, or a dotted path from one (``tensegrity.engine.loop._stepper``)."""
    found = []
    for node in ast.walk(_tree(path)):
        if not isinstance(node, ast.Attribute):
            continue
        parts, value = [], node.value
        while isinstance(value, ast.Attribute):
            parts.append(value.attr)
            value = value.value
        if isinstance(value, ast.Name) and value.id in aliases:
            found.append((".".join([aliases[value.id], *reversed(parts)]), node.attr, node.lineno))
    return found


def test_no_private_names_across_modules():
    """Neither ``from m import _x`` nor ``m._x`` on an imported module ``m`` of the package,
    ``m`` reached by any path (an alias, a relative import, ``tensegrity.engine.loop._x``)."""
    modules = _modules()
    wrong = []
    for source, path in modules.items():
        for module, names, line in _imports(path):
            for name in names:
                if name.startswith("_") and _target(module, name, modules) == module != source:
                    wrong.append(f"{source}:{line} imports {module}.{name}")
        for module, name, line in _attributes(path, _module_aliases(source, path, modules)):
            private = name.startswith("_") and not name.startswith("__")
            if private and module in modules and module != source:
                wrong.append(f"{source}:{line} uses {module}.{name}")
    assert not wrong, "\n".join(wrong)


def test_no_layer_imports_through_the_root():
    """A module of a layer imports a name from the module that defines it: the root
    re-exports names of the engine, the model and physics, so ``from tensegrity import
    simulate`` (or ``tensegrity.simulate``) would hide an import of a layer."""
    modules = _modules()
    wrong = []
    for source, path in modules.items():
        if not _package(source):
            continue
        for module, names, line in _imports(path):
            through = [n for n in names if f"{module}.{n}" not in modules] if names else [""]
            if module == "tensegrity" and through:
                wrong.append(
                    f"{source}:{line} imports {', '.join(through) or module} from the root"
                )
        for module, name, line in _attributes(path, _module_aliases(source, path, modules)):
            if module == "tensegrity" and f"{module}.{name}" not in modules:
                wrong.append(f"{source}:{line} uses tensegrity.{name} through the root")
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
        ("model/a.py", "from ..cli.main import main", test_imports_follow_the_layers),
        ("model/a.py", "from .. import cli", test_imports_follow_the_layers),
        ("engine/a.py", "from . import b", test_no_import_circles),
        ("engine/a.py", "from tensegrity import simulate", test_no_layer_imports_through_the_root),
        ("engine/a.py", "import tensegrity", test_no_layer_imports_through_the_root),
        (
            "engine/a.py",
            "import tensegrity.engine.b\ntensegrity.simulate",
            test_no_layer_imports_through_the_root,
        ),
        (
            "model/a.py",
            "import importlib\nimportlib.import_module('tensegrity.cli.main')",
            test_imports_follow_the_layers,
        ),
        ("model/a.py", "__import__('tensegrity.engine.loop')", test_imports_follow_the_layers),
        (
            "design/a.py",
            "import tensegrity.engine.loop\ntensegrity.engine.loop._stepper",
            test_no_private_names_across_modules,
        ),
        (
            "design/a.py",
            "from tensegrity import engine\nengine.loop._stepper",
            test_no_private_names_across_modules,
        ),
        ("design/a.py", "from ..engine.loop import _stepper", test_no_private_names_across_modules),
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
