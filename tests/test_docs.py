"""The documentation site (``docs/``, Sphinx): it builds with warnings as errors, its API
reference lists every module of the library and every public function and class of each, its
tutorials (``examples/tutorial_*.py``, run by sphinx-gallery) run and show their figures, and
the examples in the docstrings run as doctests (issue 33)."""

from __future__ import annotations

import doctest
import importlib
import inspect
import re
import subprocess
import sys
import zlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PACKAGE = ROOT / "src" / "tensegrity"

pytest.importorskip("sphinx")
pytest.importorskip("sphinx_gallery")


def library_modules() -> list[str]:
    """Every module of the package but the command line's (documented in ``docs/cli.md``)."""
    names = []
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        name = ".".join(parts)
        if not (name.startswith("tensegrity.cli") or name.endswith("__main__")):
            names.append(name)
    return names


def public_names(module_name: str) -> list[str]:
    """The functions and classes a module defines under a name without a leading underscore
    (compiled functions by their Python function's module)."""
    module = importlib.import_module(module_name)
    found = []
    for name, value in vars(module).items():
        if name.startswith("_"):
            continue
        source = getattr(getattr(value, "py_func", value), "__module__", None)
        kind = inspect.isfunction(value) or inspect.isclass(value) or hasattr(value, "py_func")
        if source == module_name and kind:
            found.append(name)
    return found


def test_the_api_reference_lists_every_module_of_the_library():
    listed = re.findall(r"^   (tensegrity[\w.]*)$", (DOCS / "api.rst").read_text(), re.M)
    assert sorted(listed) == sorted(library_modules())


def test_the_examples_in_docstrings_run_as_doctests():
    flags = doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE
    ran = 0
    for name in library_modules():
        path = PACKAGE.parent.joinpath(*name.split("."))
        source = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
        if ">>> " not in source.read_text(encoding="utf-8"):
            continue
        result = doctest.testmod(importlib.import_module(name), optionflags=flags)
        assert result.failed == 0, name
        ran += result.attempted
    assert ran >= 6


def inventory(path: Path) -> set[str]:
    """The object names of a Sphinx ``objects.inv``."""
    data = path.read_bytes().split(b"\n", 4)[4]
    return {line.split(" ", 1)[0] for line in zlib.decompress(data).decode().splitlines()}


def test_the_site_builds_with_warnings_as_errors_and_documents_every_public_name(tmp_path):
    out = tmp_path / "html"
    done = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(DOCS), str(out)],
        capture_output=True, text=True, timeout=1200,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-5000:]
    documented = inventory(out / "objects.inv")
    missing = [
        f"{module}.{name}"
        for module in library_modules()
        for name in public_names(module)
        if f"{module}.{name}" not in documented
    ]
    assert not missing, missing
    assert len(documented) > 1500
    # every tutorial ran and shows its figures
    tutorials = sorted((ROOT / "examples").glob("tutorial_*.py"))
    assert tutorials
    for script in tutorials:
        page = (out / "tutorials" / f"{script.stem}.html").read_text(encoding="utf-8")
        shown = re.findall(rf"sphx_glr_{script.stem}_\d+\.png", page)
        made = r"^\w+ = (?:figure_\w+|new_figure)\("  # (each figure a tutorial makes)
        said = len(re.findall(made, script.read_text(encoding="utf-8"), re.M))
        assert len(set(shown)) == said, script.name


#: What no page of ``docs/`` may say outside code (issue 33: clock times belong on the benchmark
#: pages, ``benchmarks/README.md`` and ``benchmarks/history.md``): a date, a time of day, a
#: measured wall-clock or CPU time, the host's history. Simulated times (``20 s``, ``a 5 ms
#: lag``) match none of these.
CLOCK_TIME = re.compile(
    r"\b20\d\d-\d\d-\d\d\b"  # 2026-11-26
    r"|\b\d{1,2}:\d{2}\b|\bUTC\b"  # 05:33 UTC
    r"|\b(?:took|takes?)\s+(?:about\s+|only\s+)?\d[\d.,]*\s?(?:s|ms|µs|min|minutes|seconds|hours?)\b"
    r"|\b\d[\d.]*\s?(?:s|ms)\s+against\s+\d[\d.]*\s?(?:s|ms)\b"  # 1.21 s against 2.14 s
    r"|\b\d[\d.,]*\s?(?:s|ms|µs|min|minutes|seconds)\s+(?:of\s+)?(?:wall|CPU)\b"  # 29 s wall time
    r"|\b\d[\d.,]*\s?(?:ns|µs|ms)\s+(?:a|per|each)\s+(?:frame|step|evaluation|tendon|call|sample)\b"
    r"|\bthe host (?:was|is)\b"  # the host was about 10% faster then
    r"|\b\d[\d.,]*\s?(?:min|minutes|hours?)\b"  # (no simulated run here lasts minutes)
)


def clock_times(text: str) -> list[str]:
    """The clock times of a markdown page, its fenced code blocks and inline code left out (a
    command's range ``load=0:20``, a message the program prints)."""
    text = re.sub(r"^```.*?^```[ \t]*$", "", text, flags=re.M | re.S)
    text = re.sub(r"`[^`]*`", "", text)
    return [match.group(0) for match in CLOCK_TIME.finditer(text)]


def test_the_clock_time_pattern_tells_wall_clock_from_simulated_times():
    said = [
        "2026-11-26",
        "05:33 UTC",
        "took 21 s",
        "1.21 s against 2.14 s",
        "29 s wall time",
        "5 ms a frame",
        "41 minutes on a 2-core machine",
    ]
    physics = ["simulate 20 s", "a 10 ms lag", "t = 4.04 s", "every 2 ms", "`load=0:20`"]
    assert all(clock_times(text) for text in said), [t for t in said if not clock_times(t)]
    assert not any(clock_times(text) for text in physics)


def test_the_pages_have_no_clock_times_outside_the_benchmark_pages():
    found = {
        page.name: clock_times(page.read_text(encoding="utf-8"))
        for page in sorted(DOCS.glob("*.md"))
    }
    found = {name: times for name, times in found.items() if times}
    assert not found, found
