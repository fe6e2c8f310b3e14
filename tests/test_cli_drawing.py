"""The drawing of ``simulate``'s (and ``equilibrium``'s, ``modes``') figures, pages and video in
worker processes (:mod:`tensegrity.cli.drawing`): the same files as drawn in one process; a
failed, killed or interrupted job stops the command without hanging and leaves no worker behind;
a worker's warnings reach the command; a killed command takes its workers with it."""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import pytest

from tensegrity.cli.drawing import Drawing, worker_count
from tensegrity.cli.main import main

cli_simulate = importlib.import_module("tensegrity.cli.simulate")
cli_files = importlib.import_module("tensegrity.cli.simulate_files")
cli_analysis = importlib.import_module("tensegrity.cli.analysis_verbs")

RUN = ["simulate", "--n", "3", "--m", "1", "--t-end", "0.3", "--no-steady-state"]
DRAWN = ("initial.png", "equilibrium.png", "tendon_lengths.png", "view.html", "motion.gif")

needs_workers = pytest.mark.skipif(
    worker_count(2) < 2, reason="workers need Linux and two processors"
)


def _gone(pid: int, within: float) -> bool:
    """Whether the process ``pid`` has ended (or is a zombie) within ``within`` seconds."""
    end = time.monotonic() + within
    while time.monotonic() < end:
        try:
            with open(f"/proc/{pid}/stat") as stat:
                if stat.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return True
        except FileNotFoundError:
            return True
        time.sleep(0.02)
    return False


# jobs (module level: a worker finds them by name)
def _pid() -> int:
    return os.getpid()


def _sleep(seconds: float) -> None:
    time.sleep(seconds)


def _warn(text: str) -> str:
    warnings.warn(text, UserWarning, stacklevel=1)
    return text


def _fail(*_: object) -> list[Path]:
    raise ValueError("the drawing failed on purpose")


def _killed(*_: object) -> list[Path]:
    os.kill(os.getpid(), signal.SIGKILL)
    return []


def _family() -> tuple[int, int, bool]:
    """A worker's process, its parent, and whether it has matplotlib."""
    return os.getpid(), os.getppid(), "matplotlib.figure" in sys.modules


def _lock() -> threading.Lock:
    return threading.Lock()  # (does not pickle)


@needs_workers
def test_workers_draw_the_same_files_as_one_process(tmp_path, monkeypatch, capsys):
    """Every figure, the page and the video are byte for byte those the command draws alone."""
    args = [*RUN, "--animation", "gif"]
    assert main([*args, "--out", str(tmp_path / "workers")]) == 0
    monkeypatch.setattr(cli_simulate, "worker_count", lambda wanted: 0)
    assert main([*args, "--out", str(tmp_path / "alone")]) == 0
    for name in DRAWN:
        drawn, alone = (tmp_path / folder / name for folder in ("workers", "alone"))
        assert drawn.read_bytes() == alone.read_bytes(), name


@needs_workers
@pytest.mark.parametrize("verb", ["equilibrium", "modes"])
def test_analysis_verbs_draw_the_same_files_in_workers(tmp_path, monkeypatch, capsys, verb):
    """The analysis verbs that draw in workers write every figure and page byte for byte as
    drawn in the command alone."""
    assert main([verb, "--out", str(tmp_path / "workers")]) == 0
    monkeypatch.setattr(cli_analysis, "worker_count", lambda wanted: 0)
    assert main([verb, "--out", str(tmp_path / "alone")]) == 0
    drawn = sorted(p.name for p in (tmp_path / "workers").iterdir())
    assert drawn == sorted(p.name for p in (tmp_path / "alone").iterdir())
    assert any(name.endswith(".png") for name in drawn) and any(".html" in n for n in drawn)
    assert f".{verb}-outputs" in drawn  # (its list of the files, with their times: not drawn)
    for name in drawn:
        if name.startswith("."):
            continue
        workers, alone = (tmp_path / folder / name for folder in ("workers", "alone"))
        assert workers.read_bytes() == alone.read_bytes(), name


@needs_workers
def test_jobs_run_in_the_workers_and_return_their_values():
    with Drawing(2) as drawing:
        pids = {drawing.submit(_pid).result() for _ in range(8)}
    assert os.getpid() not in pids and 1 <= len(pids) <= 2
    alone = Drawing(0)
    assert alone.submit(_pid).result() == os.getpid()


@needs_workers
def test_the_first_worker_forks_the_others_once_it_has_imported_matplotlib():
    """matplotlib is imported once: the second worker is the first's child, and has it."""
    with Drawing(3) as drawing:
        jobs = [drawing.submit(_family) for _ in range(3)]  # (one each: all free at first)
        family = {job.result() for job in jobs}
    first = [pid for pid, parent, _ in family if parent == os.getpid()]
    assert len(family) == 3 and len(first) == 1
    assert all(parent == first[0] for pid, parent, _ in family if pid != first[0])
    assert all(has for _, _, has in family)
    assert all(_gone(pid, within=5.0) for pid, _, _ in family)  # (closed: all gone)


@needs_workers
def test_a_jobs_error_comes_back_with_the_workers_traceback():
    """A job's exception is raised in the command, the worker's traceback in a note (shown
    by ``--debug``); an outcome that does not pickle is one line that says so; the workers
    go on with the next jobs."""
    with Drawing(2) as drawing:
        with pytest.raises(ValueError, match="failed on purpose") as raised:
            drawing.submit(_fail).result()
        assert "in a drawing worker" in raised.value.__notes__[0]
        assert "_fail" in raised.value.__notes__[0]
        with pytest.raises(RuntimeError, match="a drawing job's outcome"):
            drawing.submit(_lock).result()
        assert drawing.submit(_pid).result() != os.getpid()


def test_a_failed_drawing_fails_the_run_in_one_line(tmp_path, monkeypatch, capsys):
    """The job's error ends the command as its own would (one line, exit 2, saying where the
    run is kept for ``--resume``) and no figure is written under a final name; with workers or
    without."""
    monkeypatch.setattr(cli_files, "viewer_page", _fail)
    for workers in (2, 0):
        monkeypatch.setattr(cli_simulate, "worker_count", lambda wanted, n=workers: min(wanted, n))
        out = tmp_path / f"run{workers}"
        assert main([*RUN, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        kept = f"the run so far is in {out / '.trajectory.h5'}: continue it with the same options"
        assert err.strip().splitlines() == [
            f"tensegrity: error: the drawing failed on purpose; {kept} and --resume"
        ]
        assert not any(p.suffix in (".png", ".html") for p in out.rglob("*")), workers


@needs_workers
def test_a_killed_worker_fails_the_run_without_hanging(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(cli_files, "_figures", _killed)
    start = time.monotonic()
    assert main([*RUN, "--out", str(tmp_path / "run")]) == 1
    assert time.monotonic() - start < 60
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "drawing worker process ended abruptly" in err[0]


@needs_workers
def test_an_interrupt_while_waiting_stops_the_workers():
    """Ctrl-C (here an alarm) while the command waits for a job: the workers are stopped, and
    gone, when the interrupt leaves the block."""

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        with pytest.raises(KeyboardInterrupt), Drawing(2) as drawing:
            pids = [drawing.submit(_pid).result() for _ in range(2)]
            job = drawing.submit(_sleep, 60.0)
            signal.setitimer(signal.ITIMER_REAL, 0.3)
            start = time.monotonic()
            job.result()
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert time.monotonic() - start < 10
    assert all(_gone(pid, within=5.0) for pid in pids)


@needs_workers
def test_a_worker_killed_while_the_block_ends_stops_the_others():
    """A worker killed in a job nobody waited for: leaving the block raises the one-line
    error, and the other worker is gone too (not left waiting for jobs)."""
    drawing = Drawing(2)
    pids = [drawing.submit(_pid).result() for _ in range(2)]
    drawing.submit(_sleep, 0.5)
    drawing.submit(_killed)
    with pytest.raises(RuntimeError, match="ended abruptly"):
        drawing.close()
    assert all(_gone(pid, within=5.0) for pid in pids)


@needs_workers
def test_a_workers_warning_is_raised_in_the_command():
    with Drawing(1) as drawing, pytest.warns(UserWarning, match="from a worker"):
        assert drawing.submit(_warn, "from a worker").result() == "from a worker"


@needs_workers
def test_a_killed_command_takes_its_workers_with_it(tmp_path):
    script = (
        "import os, sys, time\n"
        "from tensegrity.cli.drawing import Drawing\n"
        "from test_cli_drawing import _pid, _sleep\n"
        "drawing = Drawing(2)\n"
        "jobs = [drawing.submit(_pid), drawing.submit(_pid)]\n"
        "print(*(job.result() for job in jobs), flush=True)\n"
        "drawing.submit(_sleep, 60.0)\n"
        "drawing.submit(_sleep, 60.0)\n"
        "time.sleep(60)\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), *sys.path])}
    command = subprocess.Popen(
        [sys.executable, "-c", script], stdout=subprocess.PIPE, text=True, env=env
    )
    try:
        workers = [int(pid) for pid in command.stdout.readline().split()]
        assert len(set(workers)) == 2  # (the first worker and its child)
        command.send_signal(signal.SIGKILL)
        command.wait()
        assert all(_gone(worker, within=5.0) for worker in workers)
    finally:
        command.kill()
        command.wait()
        command.stdout.close()


def test_worker_count_follows_the_processors(monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0})
    assert worker_count(2) == 0
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1})
    assert (worker_count(1), worker_count(2), worker_count(3)) == (1, 2, 2)
    monkeypatch.setattr(sys, "platform", "darwin")
    assert worker_count(2) == 0


@needs_workers
def test_workers_stopped_as_they_start_print_nothing():
    """Workers stopped at once (bad input found just after they were forked) end silently: a
    signal that comes before a worker has set its own handlers waits for them, instead of
    running the command's (which raised in the worker and printed a traceback)."""
    script = (
        "from tensegrity.cli.drawing import Drawing\n"
        "from tensegrity.cli.errors import signals_as_interrupts\n"
        "with signals_as_interrupts():\n"
        "    for _ in range(30):\n"
        "        Drawing(2).cancel()\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0 and done.stderr == ""
