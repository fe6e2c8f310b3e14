"""A command says, once, that it compiles the engine when the numba cache is cold (and not when
it is warm), and ``simulate``'s summary reports the time to result since the process started
(issue 27: the first run was silent for 20-60 s and its summary showed only the simulation's
1.25 s of the 9.5 s the user waited)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time

from tensegrity.cli.startup import COMPILING_MESSAGE, announce_compiling, seconds_since_start
from tensegrity.io.trajectory import read_trajectory

#: A run with little to compile (the rk4 path: about 17 s with an empty cache, 2026-11-27).
QUICK_RUN = [
    "simulate",
    *("--method", "rk4", "--dt", "1e-3", "--t-end", "0.01", "--sample-dt", "0.01"),
    *("--no-view", "--no-animation"),
]


def cli(argv: list[str], cwd, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "tensegrity.cli", *argv],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_a_cold_cache_is_announced_once_and_a_warm_one_not_and_both_give_the_same_run(tmp_path):
    """The default run (DOP853, slack switches located) compiled in the process and loaded from
    the cache is the same bit for bit: with fused multiply-adds allowed, LLVM fused across
    inlined callees only when they were compiled in the process (565 steps against 557)."""
    cache = tmp_path / "numba-cache"
    cache.mkdir()
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    run = ["simulate", "--t-end", "0.5", "--no-view", "--no-animation"]
    cold = cli([*run, "--out", "cold"], tmp_path, env)
    assert cold.returncode == 0, cold.stderr
    assert cold.stderr.count(COMPILING_MESSAGE) == 1, cold.stderr
    assert cold.stderr.splitlines()[0] == COMPILING_MESSAGE
    warm = cli([*run, "--out", "warm"], tmp_path, env)
    assert warm.returncode == 0, warm.stderr
    assert "compiling" not in warm.stderr, warm.stderr
    first, second = (
        read_trajectory(tmp_path / name / "trajectory.h5") for name in ("cold", "warm")
    )
    assert first.nswitches > 0
    assert (first.nsteps, first.nfev, first.nswitches) == (
        second.nsteps,
        second.nfev,
        second.nswitches,
    )
    assert first.q.tobytes() == second.q.tobytes()


def test_the_announcement_is_made_at_most_once_per_process(capsys, monkeypatch):
    from numba import njit
    from numba.core import event

    from tensegrity.cli import startup

    # as in a new process: an earlier test's command may have registered its announcer already
    earlier = startup._announcer
    if earlier is not None:
        event.unregister("numba:compile", earlier)
    monkeypatch.setattr(startup, "_announcer", None)
    announce_compiling()
    announce_compiling()
    try:
        # two new functions, never cached: each a compilation
        assert njit(lambda x: x + 1)(1) == 2
        assert njit(lambda x: x * 2.0)(1.5) == 3.0
    finally:
        event.unregister("numba:compile", startup._announcer)
        if earlier is not None:
            event.register("numba:compile", earlier)
    assert capsys.readouterr().err.count(COMPILING_MESSAGE) == 1


def test_the_summary_reports_the_time_to_result_since_the_process_started(tmp_path):
    cli([*QUICK_RUN, "--out", "warm-up"], tmp_path)  # the cache filled, if it was not
    started = time.perf_counter()
    run = cli(["simulate", "--t-end", "0.5", "--no-view", "--out", "out"], tmp_path)
    waited = time.perf_counter() - started
    assert run.returncode == 0, run.stderr
    shown = float(
        re.search(r"^time to result +([0-9.]+) s since the command started", run.stdout, re.M)[1]
    )
    simulated = float(re.search(r"^simulation wall time +([0-9.]+) s$", run.stdout, re.M)[1])
    # the process ends within about a second of printing it (the interpreter's exit)
    assert waited - 1.5 <= shown <= waited
    assert simulated < shown


def test_the_process_clock_counts_from_the_process_start():
    """A child that sleeps 1 s before importing the package reports at least that."""
    code = (
        "import time; time.sleep(1.0)\n"
        "from tensegrity.cli.startup import seconds_since_start\n"
        "print(seconds_since_start())"
    )
    child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert 1.0 <= float(child.stdout) < 30.0, child.stderr
    assert 0.0 < seconds_since_start()
