"""Files written all at once: :func:`atomic_path` (a temporary file in the target's directory
that replaces the target only when complete), :func:`write_staged` (a set of outputs that
appear together), the one-line file errors every reader raises (:func:`file_error`, the file
name shown by :func:`shown_path`), and input files read within limits (:func:`read_input`,
:func:`regular_file`, :func:`byte_limit`).

Limits on input files (docs/reliability.md), each raised by an environment variable holding a
number of bytes:

=================================  =======  =================================================
variable                           default  what it bounds
=================================  =======  =================================================
``TENSEGRITY_MAX_INPUT_BYTES``     1 GiB    a file read whole (structure files, force tables)
``TENSEGRITY_MAX_ARRAY_BYTES``     4 GiB    the array data one read takes from a file (HDF5
                                            datasets, ``.npz`` arrays), checked against the
                                            shapes in the file's headers before reading
=================================  =======  =================================================
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shutil
import stat
import tempfile
import unicodedata
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import BinaryIO

from tensegrity.model.limits import environment_limit

#: A file name: ``str`` or ``os.PathLike``.
PathLike = str | os.PathLike


# ------------------------------------------------------------------------- atomic writes
@contextlib.contextmanager
def atomic_path(path: PathLike, *, fsync: bool = True) -> Iterator[Path]:
    """Write a file atomically: yield a temporary path to write, then move it onto ``path``.

    The temporary file (``<name>.<pid>.<random>.tmp``) is created empty in ``path``'s directory,
    so the final :func:`os.replace` is an atomic rename on the same file system; temporary files
    of ``path`` that a killed process left are removed first (:func:`remove_stale`).  If the
    ``with`` body completes, the temporary file is flushed to disk (``fsync``) and replaces
    ``path``; if it raises (any exception, ``KeyboardInterrupt`` included), the temporary file
    is removed and the exception propagates, leaving ``path`` as it was (absent, or the older
    file intact).

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
    remove_stale(final.parent, final.name)
    try:
        with tempfile.NamedTemporaryFile(
            dir=final.parent, prefix=f"{final.name}.{os.getpid()}.", suffix=".tmp", delete=False
        ) as handle:
            tmp = Path(handle.name)
    except OSError as exc:
        raise naming(exc, final) from exc
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
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        if isinstance(exc, OSError) and exc.filename in (None, str(tmp), tmp):
            raise naming(exc, final) from exc
        raise
    if fsync:
        fsync_directory(final.parent)


def naming(exc: OSError, path: PathLike) -> OSError:
    """``exc`` about ``path``: the same error (type and ``errno``) naming the file the user
    asked for rather than a temporary one, or none (a full disk)."""
    return type(exc)(exc.errno, exc.strerror or str(exc), os.fspath(path))


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


#: ``errno`` values of a full disk (no space, or the user's quota used up).
DISK_FULL = frozenset({errno.ENOSPC, errno.EDQUOT})


def reserve_space(path: PathLike, size: int) -> None:
    """Allocate on disk ``size`` [bytes] past the end of the file ``path`` (and any holes in it),
    so that writes there cannot meet a full disk.

    For writers that cannot fail in the middle (HDF5 cannot close a file after a failed write:
    the process then crashes): a full disk shows here, before they start.  The file's size
    grows by ``size``; HDF5 cuts it back to its data when it closes the file.  A file system
    that cannot allocate ahead (some network ones) is left as it is.

    Raises
    ------
    OSError
        ``ENOSPC`` or ``EDQUOT``, naming ``path``, the disk and its free space.
    """
    fd = os.open(path, os.O_RDWR)
    try:
        os.posix_fallocate(fd, 0, os.fstat(fd).st_size + size)
    except OSError as exc:
        if exc.errno in DISK_FULL:
            raise disk_full(exc, path, needed=size) from None
        if exc.errno not in (errno.EINVAL, errno.EOPNOTSUPP, errno.ENOSYS):
            raise
    finally:
        os.close(fd)


def disk_full(exc: OSError, path: PathLike, *, needed: int | None = None) -> OSError:
    """The ``OSError`` of a full disk (``exc``) while writing ``path``: the file, the disk (its
    mount point) and its free space."""
    folder = Path(os.path.abspath(path)).parent
    disk = next((p for p in (folder, *folder.parents) if os.path.ismount(p)), folder)
    figures = [] if needed is None else [f"about {byte_text(needed)} needed"]
    with contextlib.suppress(OSError):
        figures.insert(0, f"{byte_text(shutil.disk_usage(disk).free)} free")
    what = "no space left" if exc.errno == errno.ENOSPC else "disk quota exceeded"
    where = f"{what} on the disk {shown_path(disk)}"
    if figures:
        where += f" ({', '.join(figures)})"
    return OSError(exc.errno, where, os.fspath(path))


def file_error(path: PathLike, problem: str) -> ValueError:
    """A one-line ``ValueError``: ``"<path>: <problem>"`` (the path as :func:`shown_path` shows
    it, the problem's runs of whitespace made one space)."""
    return ValueError(f"{shown_path(path)}: {' '.join(str(problem).split())}")


#: Unicode categories of the characters :func:`shown_path` escapes: control (newlines, tabs,
#: terminal escapes, ...), format (bidirectional overrides, zero-width), surrogate (the bytes of
#: a file name that are not UTF-8), line and paragraph separators.
ESCAPED_CATEGORIES = frozenset({"Cc", "Cf", "Cs", "Zl", "Zp"})


def shown_path(path: PathLike) -> str:
    """A file name as a message shows it: every control, format, surrogate or line-separating
    character escaped as a Python string's repr writes it (``"a\\nb.json"`` for a newline,
    ``\\x1b``, ``\\u202e``, ``\\udcff``), so that the message stays one line and sends
    nothing to the terminal but text; any other name as it is."""
    name = os.fspath(path)
    text = os.fsdecode(name) if isinstance(name, bytes) else name
    if text.isprintable():
        return text
    return "".join(
        repr(c)[1:-1] if unicodedata.category(c) in ESCAPED_CATEGORIES else c for c in text
    )


def os_problem(exc: OSError) -> str:
    """The problem an ``OSError`` of opening or reading a file means, in words."""
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    if isinstance(exc, IsADirectoryError):
        return "is a directory, not a file"
    if isinstance(exc, PermissionError):
        return "permission denied"
    return f"cannot read: {exc.strerror or exc}"


# ------------------------------------------------------------------- staged output folders
#: Name prefix of a staging folder: ``.staging-<pid>-<random>``.
STAGING_PREFIX = ".staging-"


def write_staged(
    out: Path, write: Callable[[Path], list[Path]], *, record: str | None = None
) -> list[Path]:
    """Write a set of outputs into ``out`` all together, or not at all.

    ``write(staging)`` writes the files into a new staging folder inside ``out`` (the same file
    system, so that each move is an atomic rename) and returns them in the order they are to be
    moved; a file in a subfolder of ``staging`` goes to the same subfolder of ``out`` (created
    if missing; files already there and not rewritten stay).  Then every target is checked
    (no folder where a file goes, no file where a folder goes) before anything moves, and the
    files are moved in, each file they replace kept aside until all are in.  If ``write`` or
    any move fails (or the run is interrupted), ``out`` is rolled back to what was there: the
    files replaced so far are put back, the new ones removed, and the folders created for them
    removed again.  What a killed run left in ``out`` (staging folders and temporary files of
    processes that no longer exist) is removed first (:func:`remove_stale`).

    With ``record`` (a verb's name) the outputs are listed in ``out/.<record>-outputs`` with
    their sizes and times, and those an earlier write of that record listed there and this one
    does not write (the video of a run that now has none, the files of an option not given this
    time) are removed with the move (put back if it fails; one that cannot be moved stays):
    ``out`` then holds one run's outputs, not an older run's beside them.  Only files as that
    write left them are removed (:func:`_listed`); two runs writing into one folder at once
    are not supported.

    Raises
    ------
    ValueError
        One line naming the target that is in the way (nothing moved).
    """
    out = Path(out)
    with folders_made(out) as created:
        remove_stale(out)
        with tempfile.TemporaryDirectory(
            dir=out, prefix=f"{STAGING_PREFIX}{os.getpid()}-"
        ) as staging:
            written = [*write(Path(staging))]
            if record is not None:
                written.append(_listing(Path(staging), written, record))
            moves = [(Path(path), out / Path(path).relative_to(staging)) for path in written]
            check_targets(out, [target for _, target in moves])
            aside = Path(staging) / ".replaced"
            earlier = [] if record is None else _listed(out, record)
            superseded = [out / name for name in earlier if out / name not in dict(moves).values()]
            targets = _move_all(moves, aside, out, created, superseded)
            return targets[:-1] if record is not None else targets


def _listing(staging: Path, written: list[Path], record: str) -> Path:
    """``staging/.<record>-outputs``: JSON of the ``written`` files (in ``staging``) by their
    names relative to the output folder, each with its size [bytes] and modification time
    [ns] (a move keeps both)."""
    listing = staging / f".{record}-outputs"
    files = {}
    for path in written:
        status = os.lstat(path)
        files[Path(path).relative_to(staging).as_posix()] = [status.st_size, status.st_mtime_ns]
    listing.write_text(json.dumps(files, indent=0) + "\n", "utf-8")
    return listing


def _listed(out: Path, record: str) -> list[str]:
    """The names ``out/.<record>-outputs`` lists whose files are still those it wrote: plain
    files inside ``out`` (no ``..``, absolute path or symbolic link on the way) of the size and
    modification time listed.  A file changed, replaced or moved since (by the user, another
    verb) is passed over, as is a listing that does not read."""
    try:
        files = json.loads((out / f".{record}-outputs").read_text("utf-8"))
    except (OSError, ValueError):
        return []
    if not isinstance(files, dict):
        return []
    names = []
    for name, recorded in files.items():
        path = Path(name)
        if not name or path.is_absolute() or ".." in path.parts:
            continue
        try:
            steps = [os.lstat(out.joinpath(*path.parts[: k + 1])) for k in range(len(path.parts))]
        except OSError:
            continue  # gone
        if any(stat.S_ISLNK(step.st_mode) for step in steps) or not stat.S_ISREG(steps[-1].st_mode):
            continue
        if recorded == [steps[-1].st_size, steps[-1].st_mtime_ns]:
            names.append(name)
    return names


@contextlib.contextmanager
def folders_made(folder: PathLike) -> Iterator[list[Path]]:
    """Make ``folder`` and its missing parents for the block, which gets the list of the
    folders made (it may add more); if the block fails or is interrupted, those of them that
    are empty are removed again, deepest first.  The one rule of the command's outputs: a
    verb makes its missing output folders and removes them if it writes nothing there."""
    folder = Path(folder)
    created = [path for path in (folder, *folder.parents) if not path.exists()]
    folder.mkdir(parents=True, exist_ok=True)
    try:
        yield created
    except BaseException:
        _remove_folders(created)
        raise


def check_targets(out: Path, targets: list[Path]) -> None:
    """``ValueError`` naming the first of ``targets`` (files in ``out`` or its subfolders) a file
    cannot be written to: a folder stands there, or a file where one of its folders goes.
    :func:`write_staged` checks its files so before it moves any; a verb checks its outputs so
    before its work, to fail at once."""
    for target in targets:
        if target.is_dir() and not target.is_symlink():
            raise file_error(
                target, "is a folder, where an output file goes; none of the outputs was written"
            )
        for folder in target.relative_to(out).parents:
            path = out / folder
            if path.exists() and not path.is_dir():
                raise file_error(
                    path, "is a file, where an output folder goes; none of the outputs was written"
                )


def _move_all(
    moves: list[tuple[Path, Path]],
    aside: Path,
    out: Path,
    created: list[Path],
    superseded: list[Path],
) -> list[Path]:
    """Move each ``(source, target)``, the file a target replaces moved into ``aside`` first,
    then the ``superseded`` files into ``aside`` too (their folders removed if that empties
    them); on any failure put everything back (the folders made for targets are added to
    ``created``)."""
    done: list[tuple[Path, Path | None]] = []

    def set_aside(target: Path) -> Path | None:
        if not (target.exists() or target.is_symlink()):
            return None
        kept = aside / target.relative_to(out)
        kept.parent.mkdir(parents=True, exist_ok=True)
        os.replace(target, kept)
        return kept

    try:
        for source, target in moves:
            for folder in reversed(target.relative_to(out).parents):
                if not (out / folder).exists():
                    (out / folder).mkdir()
                    created.append(out / folder)
            done.append((target, set_aside(target)))
            os.replace(source, target)
        for target in superseded:  # (at best: one that cannot be moved stays)
            try:
                done.append((target, set_aside(target)))
            except OSError:
                continue
    except BaseException:
        for target, kept in reversed(done):  # roll back, last move first
            with contextlib.suppress(OSError):
                if kept is not None:
                    os.replace(kept, target)
                else:
                    target.unlink()
        raise
    _remove_folders(
        [folder for path in superseded for folder in path.parents if out in folder.parents]
    )
    return [target for _, target in moves]


def _remove_folders(folders: list[Path]) -> None:
    """Remove ``folders`` that are empty, deepest first."""
    for folder in sorted(folders, key=lambda f: len(f.parts), reverse=True):
        with contextlib.suppress(OSError):
            folder.rmdir()  # only if empty


def remove_stale(folder: Path, name: str | None = None) -> list[Path]:
    """Remove what killed runs left in ``folder``: staging folders (``.staging-<pid>-*``) and
    temporary files (``<name>.<pid>.<random>.tmp``; of ``name`` only, if given) whose process
    ``<pid>`` no longer exists.  Those of a live process (a run going on) stay, as do names of
    another form.  Returns what was removed."""
    removed: list[Path] = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        pid = _owner(entry.name, name)
        if pid is None or _alive(pid):
            continue
        path = Path(entry.path)
        with contextlib.suppress(OSError):
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(path)
            else:
                path.unlink()
            removed.append(path)
    return removed


def _owner(entry: str, name: str | None) -> int | None:
    """The process id in a staging folder's or temporary file's name, or None."""
    if entry.startswith(STAGING_PREFIX) and name is None:
        pid = entry[len(STAGING_PREFIX) :].split("-", 1)[0]
    elif entry.endswith(".tmp") and (name is None or entry.startswith(f"{name}.")):
        parts = entry.split(".")
        pid = parts[-3] if len(parts) >= 4 else ""
    else:
        return None
    return int(pid) if pid.isdigit() else None


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists (a process of another user counts as alive)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        return True
    return True


# ----------------------------------------------------------------------------- input limits
#: Environment variable: the largest file [bytes] a reader reads whole.
MAX_INPUT_BYTES = "TENSEGRITY_MAX_INPUT_BYTES"
#: Environment variable: the most array data [bytes] one read takes from a file.
MAX_ARRAY_BYTES = "TENSEGRITY_MAX_ARRAY_BYTES"
#: The limits [bytes] when their variables are not set.
DEFAULT_LIMITS = {MAX_INPUT_BYTES: 2**30, MAX_ARRAY_BYTES: 4 * 2**30}


def byte_limit(variable: str) -> int:
    """The limit [bytes] named by ``variable`` (:data:`MAX_INPUT_BYTES` or
    :data:`MAX_ARRAY_BYTES`): the environment variable's value if set, else its default.

    Raises
    ------
    ValueError
        One line naming the variable if it is set to anything but a whole number >= 1.
    """
    return environment_limit(variable, DEFAULT_LIMITS[variable], unit="a number of bytes")


def over_limit(what: str, size: int, variable: str) -> str:
    """The problem of ``what`` taking ``size`` bytes, more than ``variable`` allows: the
    number, and how to raise it."""
    limit = byte_limit(variable)
    return (
        f"{what} takes {byte_text(size)}, more than the limit of {byte_text(limit)} "
        f"({variable}={limit}); set {variable} to a larger number of bytes to read it"
    )


def byte_text(size: int) -> str:
    """``size`` bytes in the largest binary unit that keeps it >= 1: ``"7.0 GiB"``, ``"12 B"``."""
    for power, unit in ((4, "TiB"), (3, "GiB"), (2, "MiB"), (1, "KiB")):
        if size >= 1024**power:
            return f"{size / 1024**power:.1f} {unit}"
    return f"{size} B"


_FILE_KINDS = (
    (stat.S_ISDIR, "is a directory, not a file"),
    (stat.S_ISFIFO, "not a regular file (a FIFO)"),
    (stat.S_ISCHR, "not a regular file (a character device)"),
    (stat.S_ISBLK, "not a regular file (a block device)"),
    (stat.S_ISSOCK, "not a regular file (a socket)"),
)


def _require_regular(path: PathLike, mode: int) -> None:
    if not stat.S_ISREG(mode):
        problem = next((text for test, text in _FILE_KINDS if test(mode)), "not a regular file")
        raise file_error(path, problem)


def regular_file(path: PathLike) -> os.stat_result:
    """The status of ``path`` (links followed), if it is a regular file: a device or a FIFO, read
    on, would never end (``/dev/zero``) or never start.

    Raises
    ------
    ValueError
        ``"<path>: no such file"``, ``"<path>: not a regular file (a FIFO)"``, ...
    """
    try:
        status = os.stat(path)
    except OSError as exc:
        raise file_error(path, os_problem(exc)) from exc
    _require_regular(path, status.st_mode)
    return status


def read_input(path: PathLike) -> bytes:
    """The content of the regular file ``path``, read whole, if it holds at most
    :data:`MAX_INPUT_BYTES` (checked before reading, and again while reading a file that grows).

    Raises
    ------
    ValueError
        One line starting with the file name: missing, not a regular file, too large (with the
        limit and the variable that raises it).
    """
    limit = byte_limit(MAX_INPUT_BYTES)
    with os.fdopen(_open_regular(path), "rb") as handle:
        size = os.fstat(handle.fileno()).st_size
        if size > limit:
            raise file_error(path, over_limit("the file", size, MAX_INPUT_BYTES))
        try:
            content = _read_at_most(handle, size, limit)
        except OSError as exc:
            raise file_error(path, os_problem(exc)) from exc
    if len(content) > limit:
        raise file_error(path, over_limit("the file", len(content), MAX_INPUT_BYTES))
    return content


def _open_regular(path: PathLike) -> int:
    """A descriptor of ``path`` open for reading, if it is a regular file (opened without
    blocking, so that a FIFO is refused rather than waited on)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as exc:
        raise file_error(path, os_problem(exc)) from exc
    try:
        _require_regular(path, os.fstat(fd).st_mode)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _read_at_most(handle: BinaryIO, size: int, limit: int) -> bytes:
    """The content of ``handle``, a file of ``size`` bytes by its status, up to ``limit + 1``
    bytes: one read of ``size + 1`` bytes, then (a file that grew, or one of ``/proc`` whose
    size is 0) reads of at most 1 MiB, so that no read asks for memory the file has not filled."""
    content = handle.read(min(size, limit) + 1)
    if len(content) <= size:
        return content
    parts = [content]
    total = len(content)
    while total <= limit:
        part = handle.read(min(2**20, limit + 1 - total))
        if not part:
            break
        parts.append(part)
        total += len(part)
    return b"".join(parts)
