"""``tensegrity simulate`` streams its samples to ``OUT/.trajectory.h5.partial`` as it goes: a
killed run leaves only that file, ``--resume`` continues it to exactly the trajectory of an
uninterrupted run, a resume with other options is refused, and a failed run leaves no file."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from tensegrity.cli.main import main
from tensegrity.io.stream import read_checkpoint
from tensegrity.io.trajectory import read_trajectory

RUN = [
    "simulate",
    "--n",
    "3",
    "--m",
    "1",
    "--t-end",
    "2",
    "--no-steady-state",
    "--sample-dt",
    "0.01",
]
FINAL_NAMES = {
    "trajectory.h5",
    "structure.json",
    "initial.png",
    "equilibrium.png",
    "tendon_lengths.png",
    "view.html",
    "motion.gif",
    ".simulate-outputs",  # (their list: tensegrity.io.files.write_staged)
}
PARTIAL = ".trajectory.h5.partial"
DATASETS = (
    "t",
    "q",
    "qdot",
    "tendon_tension",
    "energy",
    "residual_acceleration",
    "switch_times",
)

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")


def cli(*argv: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "tensegrity.cli", *argv],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
    )


def stored_segments(partial: Path, probe: Path) -> int:
    """Segments stored in ``partial`` per its checkpoint, read from a copy (the running writer
    holds an HDF5 lock on the file itself); -1 while there is none to read."""
    try:
        shutil.copyfile(partial, probe)
        return read_checkpoint(probe).next_segment
    except (OSError, ValueError):  # not there yet, or copied in the middle of a write
        return -1


def writing(pid: int, partial: Path) -> bool:
    """Whether process ``pid`` has ``partial`` open (Linux; elsewhere assume not)."""
    try:
        fds = os.listdir(f"/proc/{pid}/fd")
    except OSError:
        return False
    for fd in fds:
        try:
            if os.readlink(f"/proc/{pid}/fd/{fd}") == str(partial.resolve()):
                return True
        except OSError:
            pass
    return False


def kill_after_a_checkpoint(out: Path, probe: Path) -> int | None:
    """Start ``RUN`` writing to ``out``, SIGKILL it once a checkpoint after a finished segment is
    on disk and the file is closed; return that segment count, or None if the run ended first."""
    partial = out / PARTIAL
    process = subprocess.Popen(
        [sys.executable, "-m", "tensegrity.cli", *RUN, "--out", str(out)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 240
        while process.poll() is None and time.monotonic() < deadline:
            if stored_segments(partial, probe) >= 1:
                process.send_signal(signal.SIGSTOP)  # hold it still while we look
                while writing(process.pid, partial):  # not inside a write: let it close the file
                    process.send_signal(signal.SIGCONT)
                    time.sleep(0.0005)
                    process.send_signal(signal.SIGSTOP)
                process.send_signal(signal.SIGKILL)
                process.wait()
                return read_checkpoint(partial).next_segment
            time.sleep(0.002)
        return None
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def assert_same_trajectory(a: Path, b: Path) -> None:
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        for name in DATASETS:
            x, y = fa[name][()], fb[name][()]
            assert x.shape == y.shape and x.dtype == y.dtype, name
            assert x.tobytes() == y.tobytes(), f"{name} differs"
        for name in ("status", "message", "nfev", "nsteps", "nswitches", "max_rod_length_error"):
            assert fa.attrs[name] == fb.attrs[name], name


def test_killed_run_resumes_to_the_uninterrupted_trajectory_bit_for_bit(tmp_path):
    whole = tmp_path / "whole"
    done = cli(*RUN, "--out", str(whole), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert {p.name for p in whole.iterdir()} == FINAL_NAMES
    assert read_trajectory(whole / "trajectory.h5").t.size == 201

    # The run has 10 checkpointed segments; the first one (compiling the kernels) is the slow
    # one, the others take milliseconds each, so the kill may come too late: then try again.
    for attempt in range(3):
        out = tmp_path / f"killed{attempt}"
        stored = kill_after_a_checkpoint(out, tmp_path / "probe.h5")
        if stored is not None and stored < 10:
            break
    else:
        pytest.fail("could not kill the run between two of its checkpoints in 3 attempts")
    assert [p.name for p in out.iterdir()] == [PARTIAL], "a final name appeared before the end"

    resumed = cli(*RUN, "--out", str(out), "--resume", cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert f"resumed                      from segment {stored + 1} of 10" in resumed.stdout
    for words in (
        "status",
        "samples",
        "final residual acceleration",
        "energy balance error",
        "slack tendons at the end",
        "integration",
        "steps",
        "evaluations",
        "wall time",
    ):
        assert words in resumed.stdout
    assert {p.name for p in out.iterdir()} == FINAL_NAMES
    assert_same_trajectory(whole / "trajectory.h5", out / "trajectory.h5")


def test_terminated_run_leaves_only_its_partial_file(tmp_path):
    out = tmp_path / "out"
    # 60 times longer than RUN: with the compiled engine RUN can end before the signal lands
    long_run = [*RUN[: RUN.index("--t-end") + 1], "120", *RUN[RUN.index("--t-end") + 2 :]]
    process = subprocess.Popen(
        [sys.executable, "-m", "tensegrity.cli", *long_run, "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 240
    while stored_segments(out / PARTIAL, tmp_path / "probe.h5") < 0:
        assert process.poll() is None and time.monotonic() < deadline, "the run did not start"
        time.sleep(0.002)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=120)
    if process.returncode == 0:
        pytest.skip("the run ended before SIGTERM arrived")
    assert process.returncode == 128 + signal.SIGTERM, stderr
    assert stderr.count("\n") == 1 and "--resume" in stderr and "Traceback" not in stderr, stderr
    assert [p.name for p in out.iterdir()] == [PARTIAL]


def interrupted_at_sample(monkeypatch, call: int, argv: list[str]) -> int:
    """``main(argv)``'s exit code, the run interrupted (Ctrl-C) at its ``call``-th sample."""
    from tensegrity.engine.system import CompiledSystem

    calls = []
    record = CompiledSystem.record

    def interrupt(system, samples, row, t, y, inputs):
        calls.append(1)
        if len(calls) == call:
            raise KeyboardInterrupt
        record(system, samples, row, t, y, inputs)

    monkeypatch.setattr(CompiledSystem, "record", interrupt)
    code = main(argv)
    monkeypatch.setattr(CompiledSystem, "record", record)
    return code


def test_resume_with_other_options_is_refused_in_one_line(tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    # samples 0..20 are the first segment (20 samples each)
    assert interrupted_at_sample(monkeypatch, 25, [*RUN, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--resume" in err, err
    assert [p.name for p in out.iterdir()] == [PARTIAL]
    assert read_checkpoint(out / PARTIAL).next_segment == 1

    for change, words in (
        (["--t-end", "3"], "t_span"),
        (["--rtol", "1e-8"], "rtol"),
        (["--damping", "none"], "structure"),
    ):
        argv = [*RUN, "--out", str(out), "--resume", *change]
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.startswith("tensegrity: error:") and err.count("\n") == 1, err
        assert "cannot resume" in err and words in err and "without --resume" in err, err
        # The interrupted run is left as it was, still resumable.
        assert [p.name for p in out.iterdir()] == [PARTIAL]
        assert read_checkpoint(out / PARTIAL).next_segment == 1

    # Without --resume the other options start afresh.
    assert main([*RUN, "--out", str(out), "--t-end", "0.5"]) == 0
    assert {p.name for p in out.iterdir()} == FINAL_NAMES
    assert read_trajectory(out / "trajectory.h5").t[-1] == pytest.approx(0.5)


@pytest.mark.parametrize("existing", [False, True])
def test_unstable_run_leaves_no_trajectory(tmp_path, capsys, existing):
    out = tmp_path / "out"
    if existing:
        out.mkdir()
    code = main(
        [
            "simulate",
            "--n",
            "3",
            "--m",
            "1",
            "--method",
            "rk4",
            "--dt",
            "0.05",
            "--damping",
            "none",
            "--t-end",
            "5",
            "--out",
            str(out),
        ]
    )
    assert code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unstable" in err and "nothing written" in err, err
    if existing:
        assert not list(out.iterdir())  # no trajectory.h5, nor the work file or its partial
    else:
        assert not out.exists()


def test_a_run_out_of_its_wall_clock_budget_can_be_resumed(tmp_path, capsys):
    """``--max-wall-time`` stops a run with exit 1 and one line; its finished segments stay in
    the partial file, and ``--resume`` (with no budget) finishes it as an uninterrupted run,
    bit for bit."""
    out, whole = tmp_path / "out", tmp_path / "whole"
    run = ["simulate", "--n", "10", "--m", "10", "--t-end", "120", "--no-steady-state"]
    assert main([*run, "--out", str(out), "--max-wall-time", "1.5"]) == 1
    err = capsys.readouterr().err.strip()
    assert (
        "\n" not in err
        and "simulation stopped after max_wall_time (--max-wall-time) = 1.5 s" in err
    ), err
    assert err.endswith("continue it with the same options and --resume"), err
    assert [p.name for p in out.iterdir()] == [PARTIAL]
    assert read_checkpoint(out / PARTIAL).next_segment >= 1
    assert main([*run, "--out", str(out), "--resume"]) == 0
    assert main([*run, "--out", str(whole)]) == 0
    capsys.readouterr()
    with h5py.File(out / "trajectory.h5", "r") as got, h5py.File(whole / "trajectory.h5") as want:
        for name in DATASETS:
            assert np.array_equal(got[name][()], want[name][()]), name


@pytest.mark.parametrize(
    ("option", "name", "table", "changed"),
    [
        (
            "--control-table",
            "options.control",
            "t,side_0,side_1\n0,0,0\n0.2,0.1,0.05\n0.5,0,0.08\n",
            "t,side_0,side_1\n0,0,0\n0.2,0.1,0.05\n0.5,0,0.09\n",
        ),
        (
            "--force-table",
            "options.external_force",
            "0" + ",0" * 18 + "\n1" + ",0.5" * 18 + "\n",
            "0" + ",0" * 18 + "\n1" + ",0.6" * 18 + "\n",
        ),
    ],
)
def test_resume_with_a_changed_table_file_is_refused_in_one_line(
    tmp_path, capsys, monkeypatch, option, name, table, changed
):
    """The same options with a table file whose numbers changed since the interrupted run:
    ``--resume`` refuses, naming the run's option the file gives (the run would go on with other
    inputs); with the same numbers (the file written again, with a comment), it resumes."""
    out, path = tmp_path / "out", tmp_path / "table.csv"
    path.write_text(table)
    argv = ["simulate", "--kind", "three-bar", "--set", "actuated=side_*", option, str(path)]
    argv += ["--t-end", "1", "--no-steady-state", "--no-view", "--no-animation", "--out", str(out)]
    # samples 0..10 are the first segment (10 samples each)
    assert interrupted_at_sample(monkeypatch, 15, argv) == 130
    capsys.readouterr()
    assert read_checkpoint(out / PARTIAL).next_segment == 1

    path.write_text(changed)
    assert main([*argv, "--resume"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("tensegrity: error:") and err.count("\n") == 1, err
    assert "cannot resume" in err and name in err and "without --resume" in err, err
    assert [p.name for p in out.iterdir()] == [PARTIAL]
    assert read_checkpoint(out / PARTIAL).next_segment == 1

    path.write_text("# the same numbers, written again\n" + table)
    assert main([*argv, "--resume"]) == 0
    assert "resumed" in capsys.readouterr().out.lower()


def test_resume_with_a_changed_load_is_refused_in_one_line(tmp_path, capsys, monkeypatch):
    """``--load`` reaches the run as its force table: a resume with another load (or ramp) is
    refused, naming the run's external force; with the same loads it resumes."""
    out = tmp_path / "out"
    argv = ["simulate", "--kind", "three-bar", "--load", "4:0,0,-1@0.5"]
    argv += ["--t-end", "1", "--no-steady-state", "--no-view", "--no-animation", "--out", str(out)]
    assert interrupted_at_sample(monkeypatch, 15, argv) == 130
    capsys.readouterr()
    for changed in ("4:0,0,-1.5@0.5", "4:0,0,-1@0.6", "3:0,0,-1@0.5"):
        assert main([*argv[:4], changed, *argv[5:], "--resume"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("tensegrity: error:") and err.count("\n") == 1, err
        assert "cannot resume" in err and "options.external_force" in err, err
    assert [p.name for p in out.iterdir()] == [PARTIAL]
    assert main([*argv, "--resume"]) == 0
    assert "resumed" in capsys.readouterr().out.lower()
