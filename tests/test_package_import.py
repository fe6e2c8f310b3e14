"""What importing the package costs (issue 28): ``import tensegrity`` loads none of its modules
until a name is used (PEP 562), and the modules that read and describe a run load neither SciPy
nor the compiled engine."""

from __future__ import annotations

import importlib
import math
import subprocess
import sys

import pytest

import tensegrity

#: Loaded only by what needs them: the compiled engine, SciPy, the plots, the HDF5 files.
HEAVY = ("numba", "scipy", "matplotlib", "h5py")


def loaded_after(code: str) -> set[str]:
    """The top-level packages loaded by a fresh interpreter after ``code``."""
    shown = subprocess.run(
        [sys.executable, "-c", f"{code}\nimport sys\nprint(' '.join(sys.modules))"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    return set(shown)


def test_importing_the_package_loads_none_of_it():
    loaded = loaded_after("import tensegrity")
    assert not {m for m in loaded if m.startswith("tensegrity.")}
    assert not loaded & {*HEAVY, "numpy"}


@pytest.mark.parametrize(
    "module", ["tensegrity.model.structure", "tensegrity.engine.result", "tensegrity.io.trajectory"]
)
def test_the_model_and_a_run_read_back_load_no_heavy_package(module):
    assert not {m.split(".")[0] for m in loaded_after(f"import {module}")} & set(HEAVY)


def test_the_command_line_loads_no_heavy_package_before_a_verb_runs():
    """Every verb's parser (``--help``, ``info``) comes without SciPy, numba, matplotlib or h5py:
    a verb imports them when it runs.  Before: SciPy (0.15-0.2 s) through
    ``physics.constraints``, which ``physics.dynamics`` imports."""
    loaded = {m.split(".")[0] for m in loaded_after("import tensegrity.cli.main")}
    assert not loaded & set(HEAVY)


@pytest.mark.parametrize("verb", ["", "simulate", "info", "modes", "sweep", "view"])
def test_the_parser_of_a_command_line_loads_no_heavy_package(verb):
    """The parser a command line needs (every verb's options but those of ``design`` and
    ``fit``, which only name theirs unless asked for) comes without SciPy, numba, matplotlib
    or h5py.  Before, building it imported the design and identification packages for their
    options' defaults: SciPy's optimisation and statistics, 0.4 s of every command's start."""
    code = f"from tensegrity.cli.main import build_parser\nbuild_parser({verb!r})"
    assert not {m.split(".")[0] for m in loaded_after(code)} & set(HEAVY)


@pytest.mark.parametrize("name", tensegrity.__all__)
def test_each_name_of_the_package_is_its_module_s(name):
    """Each name of ``__all__`` resolves, on first use, to the object of the module that
    defines it, and is listed by ``dir``."""
    value = getattr(tensegrity, name)
    assert value is getattr(importlib.import_module(value.__module__), name)
    assert name in dir(tensegrity)


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'simulation'"):
        tensegrity.simulation  # noqa: B018
    with pytest.raises(ImportError):
        exec("from tensegrity import simulation", {})


@pytest.mark.parametrize("package", ["tensegrity", "tensegrity.plots"])
def test_both_packages_serve_their_names_through_one_function(package):
    """The root and ``tensegrity.plots`` share one ``__getattr__`` body
    (:func:`tensegrity.model.lazy.imported_name`): a name is imported from its module and kept
    in the package; an unknown one is an ``AttributeError`` naming the package."""
    from tensegrity.model.lazy import imported_name

    module = importlib.import_module(package)
    namespace = {"__name__": package}
    with pytest.raises(AttributeError, match=f"^module '{package}' has no attribute 'nope'$"):
        imported_name(namespace, {"pi": "math"}, "nope")
    assert imported_name(namespace, {"pi": "math"}, "pi") is namespace["pi"] == math.pi
    with pytest.raises(AttributeError, match=f"^module '{package}' has no attribute 'nope'$"):
        module.nope  # noqa: B018
    name = module.__all__[0]
    value = getattr(module, name)
    assert vars(module)[name] is value
    assert value is getattr(importlib.import_module(value.__module__), name)
