"""Writes that fail on the disk: a full disk while a run streams its samples (a real ``ENOSPC``
on a small tmpfs, mounted for the test: needs root, skipped otherwise), and the errors of
atomic writes, which name the file the user asked for, never a temporary one."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tensegrity import class1_shell
from tensegrity.io.formats import write_structure
from test_cli_resume import cli

#: A (10,10) shell for 2 s, 201 samples in 10 segments: a trajectory file of about 5.5 MB.
RUN = [
    "simulate",
    "--n",
    "10",
    "--m",
    "10",
    "--t-end",
    "2",
    "--no-steady-state",
    "--sample-dt",
    "0.01",
    "--no-view",
    "--no-animation",
]

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="tmpfs mounts")


@pytest.fixture
def small_disk(tmp_path):
    """A folder on a tmpfs of its own, and ``remount(options)`` (``"size=6M"``, ``"ro"``)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=2M", "tmpfs", str(disk)],
        capture_output=True,
        text=True,
    )
    if mounted.returncode:
        pytest.skip(f"cannot mount a small tmpfs (needs root): {mounted.stderr.strip()}")

    def remount(options: str) -> None:
        subprocess.run(["mount", "-o", f"remount,{options}", str(disk)], check=True)

    yield disk, remount
    subprocess.run(["umount", "-l", str(disk)], check=True)


def assert_one_disk_line(child: subprocess.CompletedProcess, disk: Path) -> str:
    err = child.stderr
    assert child.returncode == 1, (child.returncode, err[-2000:])
    assert err.count("\n") == 1 and err.startswith("tensegrity: error: "), err[-2000:]
    assert f"no space left on the disk {disk}" in err, err
    assert "Traceback" not in err and "h5py" not in err
    return err


@pytest.mark.parametrize("vtk", [[], ["--vtk"]])
def test_a_full_disk_while_streaming_is_one_line_and_the_run_resumes(small_disk, vtk):
    """The disk fills after the first segments: exit 1, one line naming the disk and the kept
    partial file, nothing under a final name; with space made, ``--resume`` finishes the run."""
    disk, remount = small_disk
    remount("size=6M")
    out = disk / "out"
    child = cli(*RUN, *vtk, "--out", str(out), cwd=disk.parent)
    err = assert_one_disk_line(child, disk)
    assert f"the run so far is in {out / '.trajectory.h5.partial'}" in err and "--resume" in err
    assert sorted(p.name for p in out.iterdir()) == [".trajectory.h5.partial"]
    remount("size=64M")
    child = cli(*RUN, *vtk, "--out", str(out), "--resume", cwd=disk.parent)
    assert child.returncode == 0, child.stderr[-2000:]
    assert "from segment" in child.stdout
    assert (out / "trajectory.h5").exists() and not (out / ".trajectory.h5.partial").exists()


def test_a_disk_too_full_for_the_first_segment_leaves_nothing(small_disk):
    disk, _ = small_disk
    out = disk / "out"
    child = cli(*RUN, "--out", str(out), cwd=disk.parent)
    err = assert_one_disk_line(child, disk)
    assert err.rstrip().endswith("(nothing written)") and not out.exists()


# ------------------------------------------------------------------------- atomic writes
def test_a_read_only_disk_names_the_file_asked_for(small_disk):
    disk, remount = small_disk
    remount("ro")
    path = disk / "x.json"
    with pytest.raises(OSError) as exc_info:
        write_structure(path, class1_shell(3, 1))
    assert exc_info.value.errno == errno.EROFS and exc_info.value.filename == str(path)
    assert ".tmp" not in str(exc_info.value) and os.listdir(disk) == []


def test_a_full_disk_names_the_file_asked_for(small_disk):
    disk, _ = small_disk
    with open(disk / "ballast", "wb") as ballast, pytest.raises(OSError):  # (filled by another)
        while True:
            ballast.write(b"\0" * 2**16)
            ballast.flush()
    path = disk / "x.json"
    with pytest.raises(OSError) as exc_info:
        write_structure(path, class1_shell(10, 10))
    assert exc_info.value.errno == errno.ENOSPC and exc_info.value.filename == str(path)
    assert sorted(os.listdir(disk)) == ["ballast"]
