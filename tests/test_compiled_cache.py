"""numba's cache of the package's compiled code is not used stale (``physics.compiling``,
:func:`refresh_stale_cache`): numba checks a cached function against its own source file only,
so a changed callee in another file would run from the cache; the package's stamp of all its
compiled sources catches it."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from numba.core import config

from tensegrity.physics import compiling
from tensegrity.physics.compiling import STAMP_FILE, refresh_stale_cache, sources_stamp


def _package(root: Path, value: int) -> Path:
    """A package ``stale`` whose ``physics/caller.py`` calls ``engine/callee.py``'s compiled
    ``value()`` (returning ``value``), both cached."""
    package = root / "stale"
    for folder in ("physics", "engine"):
        (package / folder).mkdir(parents=True, exist_ok=True)
        (package / folder / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "physics" / "caller.py").write_text(
        textwrap.dedent(
            """
            from numba import njit
            from stale.engine.callee import value

            @njit(cache=True)
            def caller():
                return value()
            """
        )
    )
    (package / "engine" / "callee.py").write_text(
        textwrap.dedent(
            f"""
            from numba import njit

            @njit(cache=True)
            def value():
                return {value}
            """
        )
    )
    return package


def _run(root: Path, *, refresh: bool) -> int:
    """``caller()`` in a new process (after :func:`refresh_stale_cache` of the package if
    ``refresh``)."""
    code = (
        "from pathlib import Path\n"
        "from tensegrity.physics.compiling import refresh_stale_cache\n"
        f"{'' if refresh else '# '}refresh_stale_cache(Path({str(root / 'stale')!r}))\n"
        "from stale.physics.caller import caller\n"
        "print(caller())\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = os.pathsep.join([str(root), env.get("PYTHONPATH", "")])
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    return int(done.stdout.split()[-1])


def test_a_changed_callee_in_another_file_is_compiled_afresh(tmp_path):
    _package(tmp_path, 1)
    assert _run(tmp_path, refresh=True) == 1  # compiled and cached
    _package(tmp_path, 2)  # the callee's file changes, the caller's does not
    assert _run(tmp_path, refresh=False) == 1  # numba alone: the stale cache
    assert _run(tmp_path, refresh=True) == 2  # the stamp sees the change


def test_the_stamp_deletes_only_the_folders_cache_files_and_only_when_the_sources_change(
    tmp_path, monkeypatch
):
    monkeypatch.setattr(config, "CACHE_DIR", "")  # the in-tree __pycache__
    package = _package(tmp_path, 1)
    cache = package / "physics" / "__pycache__"
    cache.mkdir()

    def cached() -> list[Path]:
        files = [cache / "caller.caller-5.py311.nbi", cache / "caller.caller-5.py311.1.nbc"]
        for f in files:
            f.write_bytes(b"")
        return files

    other = cache / "elsewhere.f-1.py311.nbi"  # not a module of this folder
    other.write_bytes(b"")
    files = cached()
    assert refresh_stale_cache(package) == 2  # no stamp yet: of unknown sources
    assert not any(f.exists() for f in files) and other.exists()
    assert (cache / STAMP_FILE).read_text() == sources_stamp(package)
    files = cached()
    assert refresh_stale_cache(package) == 0  # the same sources
    assert all(f.exists() for f in files)
    (package / "engine" / "callee.py").write_text("# changed\n")
    assert refresh_stale_cache(package) == 2
    assert not any(f.exists() for f in files)


def test_the_package_stamps_its_own_cache_when_imported():
    folder = compiling.cache_folder(Path(compiling.__file__))
    if folder is None:  # pragma: no cover - no writable cache directory
        pytest.skip("numba has no writable cache directory here")
    assert (folder / STAMP_FILE).read_text() == sources_stamp(Path(compiling.__file__).parents[1])
