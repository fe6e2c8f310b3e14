"""Files written all at once: :func:`atomic_path` (a temporary file in the target's directory
that replaces the target only when complete), :func:`write_staged` (a set of outputs that
appear together), and the one-line file errors every reader raises (:func:`file_error`)."""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

#: A file name: ``str`` or ``os.PathLike``.
PathLike = str | os.PathLike


# ------------------------------------------------------------------------- atomic writes
@contextlib.contextmanager
def atomic_path(path: PathLike, *, fsync: bool = True) -> Iterator[Path]:
    """Write a file atomically: yield a temporary path to write, then move it onto ``path``.

    The temporary file (``<name>.<random>.tmp``) is created empty in ``path``'s directory, so the
    final :func:`os.replace` is an atomic rename on the same file system.  If the ``with`` body
    completes, the temporary file is flushed to disk (``fsync``) and replaces ``path``; if it
    raises (any exception, ``KeyboardInterrupt`` included), the temporary file is removed and the
    exception propagates, leaving ``path`` as it was (absent, or the older file intact).

    The new file gets the permissions of the file it replaces, or the usual ``0o666 & ~umask``
    for a new file (rather than ``mkstemp``'s private ``0o600``).

    Parameters
    ----------
    path : str or os.PathLike
        Final file name.  Its directory must exist.
    fsync : bool
        Flush the data to disk before the rename (default True), so that after a system crash
        ``path`` holds either the old or the complete new content.

    Yields
    ------
    pathlib.Path
        The temporary file to write (it exists and is empty; writers may truncate or replace it).
        Note its suffix is ``.tmp``: tools that infer the format from the name (e.g. matplotlib's
        ``savefig``) need it given explicitly.

    Examples
    --------
    >>> with atomic_path("out.png") as tmp:               # doctest: +SKIP
    ...     figure.savefig(tmp, format="png")
    """
    final = Path(path)
    with tempfile.NamedTemporaryFile(
        dir=final.parent, prefix=f"{final.name}.", suffix=".tmp", delete=False
    ) as handle:
        tmp = Path(handle.name)
    try:
        yield tmp
        os.chmod(tmp, new_file_mode(final))
        if fsync:
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    if fsync:
        fsync_directory(final.parent)


def new_file_mode(final: Path) -> int:
    """The permission bits ``final`` should get: those of the file it replaces, or the umask's."""
    try:
        return stat.S_IMODE(os.stat(final).st_mode)
    except OSError:
        pass
    return 0o666 & ~_umask()


def _umask() -> int:
    try:  # Linux: read it without changing it (os.umask is process-wide and not thread-safe)
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def fsync_directory(directory: Path) -> None:
    """Persist a rename (best effort; not possible on every platform)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def file_error(path: PathLike, problem: str) -> ValueError:
    """A one-line ``ValueError``: ``"<path>: <problem>"``."""
    return ValueError(f"{os.fspath(path)}: {' '.join(str(problem).split())}")


def os_problem(exc: OSError) -> str:
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    if isinstance(exc, IsADirectoryError):
        return "is a directory, not a file"
    if isinstance(exc, PermissionError):
        return "permission denied"
    return f"cannot read: {exc.strerror or exc}"


# ------------------------------------------------------------------- staged output folders
def write_staged(out: Path, write: Callable[[Path], list[Path]]) -> list[Path]:
    """Write every output into a staging folder inside ``out``, then move them into ``out``.

    ``write(staging)`` writes the files and returns them in the order they are to be moved;
    a file in a subfolder of ``staging`` goes to the same subfolder of ``out`` (created if
    missing; files already there and not rewritten stay).  Either all files appear (each by an
    atomic rename) or, if any write fails, none does and the folders created for them are
    removed again.
    """
    out = Path(out)
    created = [folder for folder in (out, *out.parents) if not folder.exists()]
    out.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryDirectory(dir=out, prefix=".staging-") as staging:
            moved = []
            for path in write(Path(staging)):
                target = out / Path(path).relative_to(staging)
                if not target.parent.exists():
                    target.parent.mkdir(parents=True)
                    created.append(target.parent)
                os.replace(path, target)
                moved.append(target)
            return moved
    except BaseException:
        for folder in sorted(created, key=lambda f: len(f.parts), reverse=True):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only if empty
        raise
