"""The command line's one error boundary (issue 16, ``tensegrity.cli.errors``): whatever a verb
raises ends as one line on stderr and exit code 2 (bad input), 1 (the computation failed, or an
internal error, with a hint to rerun with ``--debug``) or 130 (Ctrl-C; 128 + N for SIGTERM and
SIGHUP); no warning is printed around the line, and nothing is written under a final name.

The inputs that would exhaust the machine on a regression (a structure of a billion elements,
dense arrays of 40000^2) run in a child process under a cap on its address space
(``RLIMIT_AS``) and a timeout, so that a regression fails the test instead of the machine.
"""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tensegrity.cli.main import main

GiB = 2**30
#: Address space of a child process [bytes]: the interpreter with numpy, scipy and h5py loaded
#: takes well under 1 GiB; the inputs below ask for much more than the rest.
MEMORY_CAP = 2 * GiB
#: Seconds a child process may take (each takes a few).
TIMEOUT = 120
#: Nested 100000 deep: past Python's recursion limit in any recursive parser.
DEPTH = 100_000


def _capped() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_CAP, MEMORY_CAP))


def _child(args: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run ``python args`` in ``cwd`` under the memory cap and the timeout."""
    return subprocess.run(
        [sys.executable, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
        preexec_fn=_capped,
    )


def _assert_one_error_line(err: str) -> None:
    assert err.count("\n") == 1 and err.startswith("tensegrity: error: "), err
    assert "Traceback" not in err and "Warning" not in err, err


@pytest.mark.parametrize(
    "argv, code, words",
    [
        (["info", "--n", "1000000000"], 2, ["--n 1000000000", "TENSEGRITY_MAX_MEMBERS"]),
        (
            ["matrices", "--n", "100", "--m", "100", "--out", "m"],
            2,
            ["matrices", "40000 nodes", "at most"],
        ),
        (
            ["info", "--structure", "deep.yaml"],
            2,
            ["--structure", "deep.yaml", "nested too deeply"],
        ),
        (
            ["info", "--structure", "deep.toml"],
            2,
            ["--structure", "deep.toml", "nested too deeply"],
        ),
        (  # (a steady-state run, the default, takes it as a bound: test_run_limits.py)
            ["simulate", "--t-end", "1e308", "--no-steady-state", "--out", "r"],
            2,
            ["--t-end", "--sample-dt"],
        ),
        (["sweep", "--t-end", "1e308", "--param", "n=3", "-o", "s.nc"], 2, ["--t-end"]),
        (
            ["simulate", "--stiffness", "1e308", "--t-end", "0.1", "--out", "r"],
            2,
            ["--damping internal", "stiffness up to 1e+308 N/m"],
        ),
    ],
)
def test_inputs_that_escaped_main_are_one_line(argv, code, words, tmp_path):
    """The issue's examples: a MemoryError (now refused up front by the size limit), a dense
    40000^2 array, nested YAML/TOML, an OverflowError, and a RuntimeWarning before a message
    blaming ``rods.damping[0]``."""
    (tmp_path / "deep.yaml").write_text("a: " + "[" * DEPTH + "]" * DEPTH + "\n")
    (tmp_path / "deep.toml").write_text("a = " + "[" * DEPTH + "]" * DEPTH + "\n")
    inputs = sorted(tmp_path.iterdir())
    done = _child(["-m", "tensegrity.cli", *argv], tmp_path)
    assert done.returncode == code, done.stderr
    _assert_one_error_line(done.stderr)
    for word in words:
        assert word in done.stderr, done.stderr
    assert "rods.damping" not in done.stderr
    assert sorted(tmp_path.iterdir()) == inputs  # nothing written


#: A child that runs ``tensegrity info`` with ``tendon_lengths`` warning first, then failing
#: (``{fail}``) or not.
WARNING_CHILD = """
import sys, warnings
import tensegrity.physics.dynamics as dynamics
lengths = dynamics.tendon_lengths
def warn_then(*args, **kwargs):
    warnings.warn("overflow encountered in multiply", RuntimeWarning)
    if {fail}:
        raise ValueError("bad tendon")
    return lengths(*args, **kwargs)
dynamics.tendon_lengths = warn_then
from tensegrity.cli.main import main
sys.exit(main(["info"]))
"""


def test_warnings_are_not_printed_around_the_error(tmp_path):
    failed = _child(["-c", WARNING_CHILD.format(fail=True)], tmp_path)
    assert failed.returncode == 2
    assert failed.stderr == "tensegrity: error: bad tendon\n", failed.stderr
    succeeded = _child(["-c", WARNING_CHILD.format(fail=False)], tmp_path)
    assert succeeded.returncode == 0 and "nodes" in succeeded.stdout
    assert "RuntimeWarning: overflow encountered in multiply" in succeeded.stderr


def _fail_with(monkeypatch, exc: BaseException) -> None:
    """``tensegrity info`` raises ``exc`` in the middle of its work."""
    import tensegrity.physics.dynamics

    def fail(*args, **kwargs):
        raise exc

    monkeypatch.setattr(tensegrity.physics.dynamics, "tendon_lengths", fail)


@pytest.mark.parametrize(
    "exc, code, words",
    [
        (np.linalg.LinAlgError("SVD did not converge"), 1, "the computation failed: SVD did not"),
        (FloatingPointError("overflow encountered"), 1, "the computation failed: overflow"),
        (OverflowError("int too large"), 1, "the computation failed: int too large"),
        (MemoryError("Unable to allocate 12 GiB"), 1, "out of memory (Unable to allocate 12 GiB)"),
        (RuntimeError("no equilibrium found"), 1, "error: no equilibrium found"),
        (KeyError("t9_1_1"), 2, "error: t9_1_1"),
        (PermissionError(13, "Permission denied", "out/x.json"), 2, "out/x.json: Permission"),
        (
            IndexError("index 5 is out of bounds"),
            1,
            "internal error (IndexError: index 5 is out of bounds); rerun with --debug",
        ),
        (TypeError("bad operand"), 1, "internal error (TypeError: bad operand)"),
        (RecursionError("maximum recursion depth"), 1, "internal error (RecursionError"),
        (KeyboardInterrupt(), 130, "tensegrity: interrupted (nothing written)"),
    ],
)
def test_every_exception_is_one_line_with_its_exit_code(exc, code, words, monkeypatch, capsys):
    _fail_with(monkeypatch, exc)
    assert main(["info"]) == code
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "Traceback" not in err, err


@pytest.mark.parametrize("argv", [["--debug", "info"], ["info", "--debug"]])
def test_debug_prints_the_trace_before_the_line(argv, monkeypatch, capsys):
    _fail_with(monkeypatch, IndexError("index 5 is out of bounds"))
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.startswith("Traceback") and "in fail" in err, err
    assert err.splitlines()[-1].startswith("tensegrity: error: internal error (IndexError"), err


def test_debug_is_off_unless_given(monkeypatch, capsys):
    _fail_with(monkeypatch, IndexError("index 5 is out of bounds"))
    assert main(["info", "--n", "3"]) == 1
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, line",
    [
        (
            ["simulate", "-o", "x"],
            "tensegrity: error: simulate: unrecognized arguments: -o x "
            "(see tensegrity simulate --help)\n",
        ),
        (["simulate", "--n", "abc"], "tensegrity: error: simulate: argument --n: invalid int"),
        (["bogus"], "tensegrity: error: argument command: invalid choice: 'bogus'"),
    ],
)
def test_option_errors_name_the_verb_once(argv, line, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(line) and err.count("\n") == 1, err
    assert "error: tensegrity" not in err, err  # not "tensegrity: error: tensegrity: ..."


@pytest.mark.parametrize(
    "argv, words",
    [
        (["info", "--n", "3", "--set", "n=5"], "--set n=5: n is given by --n too"),
        (["info", "--set", "n=5", "--set", "n=4"], "--set n=4: n is given twice"),
        (["info", "--kind", "prism", "--n", "4", "--set", "n=5"], "--set n=5: n is given by --n"),
    ],
)
def test_an_option_given_twice_is_refused(argv, words, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err, err


@pytest.mark.parametrize(
    "argv, option",
    [
        (["matrices", "--out", ""], "--out"),
        (["simulate", "--t-end", "0.02", "--out", ""], "--out"),
        (["vtk", "run.h5", "-o", ""], "-o/--output"),
        (["export", "-o", ""], "-o/--output"),
        (["info", "--structure", ""], "--structure"),
    ],
)
def test_an_empty_path_is_refused_not_taken_for_the_current_folder(
    argv, option, tmp_path, monkeypatch, capsys
):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"argument {option}: expected a file or folder name" in err
    assert not list(tmp_path.iterdir())


def test_an_error_escaping_the_trajectory_reader_names_the_file(tmp_path, monkeypatch, capsys):
    import tensegrity.io.trajectory

    def crafted(path, **kwargs):
        raise IndexError("tuple index out of range")

    monkeypatch.setattr(tensegrity.io.trajectory, "read_trajectory", crafted)
    assert main(["vtk", str(tmp_path / "run.h5"), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "run.h5: tuple index out of range (IndexError)" in err, err
    assert not (tmp_path / "out").exists()


#: A child that runs ``tensegrity matrices`` and receives ``signal.{name}`` while it writes.
SIGNAL_CHILD = """
import os, signal, sys, time
signal.signal(signal.SIGINT, signal.default_int_handler)  # (a foreground job's, even if the
# tests run in a background job, whose SIGINT is ignored, and its children's with it)
import tensegrity.io.matrices as matrices
def interrupted(*args, **kwargs):
    os.kill(os.getpid(), signal.{name})
    time.sleep(60)  # the signal lands first
matrices.write_matrices = interrupted
from tensegrity.cli.main import main
sys.exit(main(["matrices", "--out", "m"]))
"""


@pytest.mark.parametrize(
    "name, code", [("SIGINT", 130), ("SIGTERM", 128 + 15), ("SIGHUP", 128 + 1)]
)
def test_a_termination_signal_stops_any_verb_as_ctrl_c_does(name, code, tmp_path):
    """Ctrl-C, SIGTERM and SIGHUP: one line, exit code 128 + the signal, nothing written."""
    done = _child(["-c", SIGNAL_CHILD.format(name=name)], tmp_path)
    assert getattr(signal, name) + 128 == code
    assert done.returncode == code, done.stderr
    assert done.stderr == "tensegrity: interrupted (nothing written)\n", done.stderr
    assert not list(tmp_path.iterdir())


def test_a_large_run_says_before_it_starts_what_it_will_write(tmp_path, monkeypatch, capsys):
    """Above ``LARGE_RUN_BYTES`` (lowered here to 0), ``simulate`` says before the run how
    large its trajectory will be, how much is held in memory at a time and that the disk is too
    small when it is; the size it gives is that of the file written (HDF5 overhead aside)."""
    import importlib
    import re

    cli = importlib.import_module("tensegrity.cli.simulate")

    monkeypatch.setattr(cli, "LARGE_RUN_BYTES", 0)
    out = tmp_path / "out"
    # (an (8,4) shell: the file's fixed HDF5 overhead, about 0.1 MiB, is 1% of its samples)
    args = ["simulate", "--n", "8", "--m", "4", "--t-end", "0.5", "--no-steady-state"]
    assert main([*args, "--sample-dt", "0.0005", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    said = re.search(r"large run: up to 1,001 samples of .* about ([\d.]+) MiB in trajectory", err)
    assert said, err
    written = (out / "trajectory.h5").stat().st_size / 2**20
    assert 0.95 * written < float(said.group(1)) <= written
    assert "free there" not in err
    monkeypatch.setattr(cli.shutil, "disk_usage", lambda path: type("U", (), {"free": 1000})())
    assert main([*args, "--out", str(tmp_path / "small")]) == 0
    assert "more than the 1000 B free there" in capsys.readouterr().err


#: File names with a newline, a terminal escape (it turns the text red), a line separator and a
#: right-to-left override, and how a message shows them: escaped as in a Python string's repr.
ODD_NAMES = [
    ("two\nlines", "two\\nlines"),
    ("red\x1b[31m", "red\\x1b[31m"),
    ("line\u2028separator", "line\\u2028separator"),
    ("gnp.\u202eexe", "gnp.\\u202eexe"),
]


def _assert_shown_escaped(err: str, shown: str) -> None:
    """``err`` is one line ending in a newline, shows ``shown`` and holds no other control,
    format or line-separating character."""
    import unicodedata

    assert err.endswith("\n") and err.count("\n") == 1, repr(err)
    assert shown in err, repr(err)
    odd = [c for c in err[:-1] if unicodedata.category(c) in ("Cc", "Cf", "Zl", "Zp")]
    assert odd == [], repr(err)


@pytest.mark.parametrize("name, shown", ODD_NAMES, ids=["newline", "escape", "u2028", "u202e"])
def test_a_file_name_with_control_characters_is_shown_escaped(
    name, shown, tmp_path, monkeypatch, capsys
):
    """Every error line that names a file: from a reader (``--structure``), an output folder in
    the way (``--out``, ``export --output``), an ``OSError``; the name is escaped, not printed
    raw (before: a newline or line separator became a space, a terminal escape or a
    right-to-left override reached the terminal)."""
    monkeypatch.chdir(tmp_path)
    Path(name).write_text("")  # a file where --out's folder goes
    Path(f"{name}.json").mkdir()  # a folder where export's file goes
    runs = [
        (["info", "--structure", f"missing {name}.json"], f"--structure: missing {shown}.json: "),
        (["matrices", "--out", f"{name}/sub"], f"--out: {shown} exists and is not a folder"),
        (["export", "-o", f"{name}.json"], f"--output: {shown}.json is a folder"),
    ]
    for argv, words in runs:
        assert main(argv) == 2
        _assert_shown_escaped(capsys.readouterr().err, words)
    _fail_with(monkeypatch, PermissionError(13, "Permission denied", f"out/{name}.json"))
    assert main(["info"]) == 2
    _assert_shown_escaped(capsys.readouterr().err, f"out/{shown}.json: Permission denied")
