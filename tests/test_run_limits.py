"""Limits checked before work (issue "Reliability and security"): a run whose fixed steps cannot
advance the time, would take more than ``max_steps`` steps or make more than ``max_samples``
samples is refused at once with a one-line ``ValueError`` naming the option to change; an
adaptive run whose steps became tiny stops after ``max_steps`` steps (status -1) instead of
grinding on."""

from __future__ import annotations

import importlib
import resource
import subprocess
import sys
import time

import numpy as np
import pytest

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism

#: Address space of a child process [bytes]: numba and its compiled code fit in well under this.
_MEMORY_CAP = 6 * 2**30


@pytest.mark.parametrize(
    ("options", "words"),
    [
        (dict(method="rk4", dt=1e-300), "dt: 1e-300 s does not advance the time"),
        (
            dict(method="rk4", dt=1e-9),
            "dt: 1e-09 s over 60 s is 60,000,000,000 steps, more than max_steps (--max-steps) = "
            "10,000,000;",
        ),
        (dict(sample_dt=1e-300), "sample_dt: 1e-300 s over 60 s is 6e+301 samples, more than"),
        (dict(max_steps=0), "max_steps: must be a whole number > 0, got 0"),
        (dict(max_samples=2.5), "max_samples: must be a whole number > 0, got 2.5"),
        (dict(max_steps=True), "max_steps: must be a whole number > 0, got True"),
    ],
)
def test_impossible_runs_are_refused_before_any_work(options, words):
    """In a child process under a time and memory cap: without the checks these runs loop
    forever or grow memory until killed, which must fail the test, not hang the machine."""
    script = (
        "from tensegrity import class1_shell, simulate\n"
        "try:\n"
        f"    simulate(class1_shell(3, 1), (0.0, 60.0), **{options!r})\n"
        "except ValueError as exc:\n"
        "    print(exc)\n"
    )
    child = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (_MEMORY_CAP, _MEMORY_CAP)),
    )
    assert child.returncode == 0, child.stderr[-2000:]
    message = child.stdout.strip()
    assert message.startswith(words) and "\n" not in message


def test_the_limits_are_exact_and_can_be_raised():
    """1000 steps of 1 ms over 1 s need ``max_steps >= 1000``; 11 samples ``max_samples >= 11``."""
    shell = class1_shell(3, 1)
    kwargs = dict(method="rk4", dt=1e-3, sample_dt=0.1)
    with pytest.raises(
        ValueError,
        match=r"^dt: 0.001 s over 1 s is 1,000 steps, more than max_steps \(--max-steps\) = 999;",
    ):
        simulate(shell, (0.0, 1.0), max_steps=999, **kwargs)
    with pytest.raises(
        ValueError, match=r"^sample_dt: 0.1 s over 1 s is 11 samples, more than max_samples = 10;"
    ):
        simulate(shell, (0.0, 1.0), max_samples=10, **kwargs)
    result = simulate(shell, (0.0, 1.0), max_steps=1000, max_samples=11, **kwargs)
    assert result.status == 0 and result.nsteps == 1000 and result.t.size == 11


def test_a_stiff_adaptive_run_stops_at_its_step_budget():
    """Tendons a million times stiffer: DOP853's steps shrink to ~1e-8 s; the run stops after
    ``max_steps`` checked steps with a message saying what to change, its samples kept."""
    stiff = class1_shell(3, 1, stiffness=1e12)
    result = simulate(stiff, (0.0, 1.0), max_steps=2000, sample_dt=1e-5)
    assert result.status == -1 and result.nsteps == 2000
    assert result.message.startswith("stopped after max_steps (--max-steps) = 2,000 steps at t = ")
    assert "raise max_steps (--max-steps)" in result.message
    assert _steps_needed(result.message) > 1e6  # (steps of ~1e-8 s over 1 s)
    assert 0 < result.t[-1] < 1e-3 and np.all(np.isfinite(result.q))
    assert simulate(stiff, (0.0, 1e-5), max_steps=2000).status == 0  # a short span: within it


def _steps_needed(message: str) -> float:
    """The whole run's steps a ``max_steps`` message estimates."""
    return float(message.split("the whole run takes about ")[1].split(" steps")[0].replace(",", ""))


def test_a_small_step_budget_says_how_many_steps_the_run_needs():
    """A budget too small for an ordinary run: the message estimates the steps the whole run
    takes from those it made (before, it said the steps had become tiny)."""
    shell = class1_shell(3, 1)
    whole = simulate(shell, (0.0, 1.0))
    short = simulate(shell, (0.0, 1.0), max_steps=50)
    assert short.status == -1 and "became tiny" not in short.message
    assert whole.nsteps / 3 < _steps_needed(short.message) < 3 * whole.nsteps


def test_cli_refuses_a_step_that_cannot_advance_in_one_line(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["simulate", "--method", "rk4", "--dt", "1e-300", "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "does not advance the time" in err
    assert not out.exists() or not any(out.iterdir())


_STIFFNESSES = "stiffness=" + ",".join(str(k) for k in range(1, 1101))  # 1100 x 1000 cases
_LOADS = "load=" + ",".join(str(k) for k in range(1000))


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["info", "--n", "1000000000"], "n = 1000000000, m = 1: about 14,000,000,000 members"),
        (["info", "--kind", "prism", "--n", "100000000"], "n = 100000000: about 400,000,000"),
        (["info", "--kind", "tower", "--m", "100000000"], "n = 3, m = 100000000: about"),
        (
            ["sweep", "--param", "stiffness=1:2", "--samples", "1000000000", "-o", "x.nc"],
            "--samples: 1,000,000,000 cases, more than the limit of 1,000,000; set "
            "TENSEGRITY_MAX_CASES",
        ),
        (
            ["sweep", "--param", _STIFFNESSES, "--param", _LOADS, "-o", "x.nc"],
            "--param: 1,100,000 cases, more than the limit of 1,000,000",
        ),
    ],
)
def test_generated_sizes_are_refused_before_any_work(argv, words, tmp_path):
    """A structure or a sweep far too large is refused in one line with the number, the limit
    and the variable that raises it, in a child under a time and memory cap (before: allocated
    until memory ran out, or, for the tower, built for minutes)."""
    child = subprocess.run(
        [sys.executable, "-m", "tensegrity.cli", *argv],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
        preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (_MEMORY_CAP, _MEMORY_CAP)),
    )
    assert child.returncode == 2, child.stderr[-2000:]
    line = child.stderr.strip()
    assert "\n" not in line and words in line, line
    assert "more than the limit of" in line and "set TENSEGRITY_MAX_" in line
    assert list(tmp_path.iterdir()) == []


def test_the_size_limits_can_be_set(monkeypatch):
    monkeypatch.setenv("TENSEGRITY_MAX_MEMBERS", "41")
    with pytest.raises(ValueError, match=r"^n = 3, m = 1: about 42 members .* limit of 41;"):
        class1_shell(3, 1)
    monkeypatch.setenv("TENSEGRITY_MAX_MEMBERS", "42")
    assert class1_shell(3, 1).n_rods == 6
    monkeypatch.setenv("TENSEGRITY_MAX_MEMBERS", "many")
    with pytest.raises(ValueError, match=r"^TENSEGRITY_MAX_MEMBERS: expected a whole number"):
        class1_shell(3, 1)
    from tensegrity.sweep import SweepSpec

    monkeypatch.delenv("TENSEGRITY_MAX_MEMBERS")  # (a SweepSpec builds its cases' structures)
    monkeypatch.setenv("TENSEGRITY_MAX_CASES", "3")
    with pytest.raises(ValueError, match=r"^parameters: 4 cases, more than the limit of 3;"):
        SweepSpec({"stiffness": [1.0, 2.0], "load": [0.0, 1.0]})
    monkeypatch.setenv("TENSEGRITY_MAX_CASES", "4")
    assert len(SweepSpec({"stiffness": [1.0, 2.0], "load": [0.0, 1.0]}).cases()) == 4


@pytest.mark.parametrize(
    "options",
    [dict(), dict(method="rk4", dt=1e-9, max_steps=10**9), dict(method="RK45")],
    ids=["DOP853", "rk4", "RK45"],
)
def test_a_run_stops_at_its_wall_clock_budget(options):
    """Tendons a million times stiffer and one sample at the end: without the budget the run
    takes minutes (tiny steps, nothing to return for); with ``max_wall_time = 0.5`` s it stops
    soon after, status -1, the message saying what to change, its first sample and last state
    kept."""
    stiff = class1_shell(3, 1, stiffness=1e12)
    result = simulate(stiff, (0.0, 1.0), sample_dt=1.0, max_wall_time=0.5, **options)
    assert result.status == -1, result.message
    assert result.message.startswith(
        "stopped after max_wall_time (--max-wall-time) = 0.5 s of wall-clock time"
    )
    assert "raise max_wall_time (--max-wall-time)" in result.message
    assert 0.5 < result.wall_time < 5.0
    assert result.t[0] == 0.0 and 0 < result.t[-1] < 1.0 and np.all(np.isfinite(result.q))


def test_the_wall_clock_budget_is_checked():
    with pytest.raises(ValueError, match=r"^max_wall_time: must be a number > 0 in s, got 0"):
        simulate(class1_shell(3, 1), (0.0, 1.0), max_wall_time=0)


@pytest.mark.parametrize("method", ["DOP853", "rk4"])
def test_compiled_stretches_give_python_its_turn_without_changing_the_run(monkeypatch, method):
    """Between two samples the compiled loop returns to Python after a bounded amount of work
    (for signals and the budget), and the run is the same bit for bit as in one stretch."""
    from tensegrity.engine import dop853, loop

    shell = class1_shell(3, 1)
    kwargs = dict(sample_dt=0.5, method=method, dt=1e-3 if method == "rk4" else None)
    one_stretch = simulate(shell, (0.0, 1.0), **kwargs)
    turns = []
    monkeypatch.setattr(dop853, "YIELD_WORK", 24 * 12 * 10)  # ten DOP853 attempts, 30 RK4 steps
    out_of_time = loop._Run.out_of_time

    def counting(run, t):
        turns.append(t)
        return out_of_time(run, t)

    monkeypatch.setattr(loop._Run, "out_of_time", counting)
    many = simulate(shell, (0.0, 1.0), **kwargs)
    assert len(turns) > many.nsteps / 40 > 5
    assert (many.nsteps, many.nfev, many.nswitches) == (
        one_stretch.nsteps,
        one_stretch.nfev,
        one_stretch.nswitches,
    )
    np.testing.assert_array_equal(many.q, one_stretch.q)
    np.testing.assert_array_equal(many.qdot, one_stretch.qdot)


def test_cli_budget_and_signals_reach_a_run_of_tiny_steps(tmp_path):
    """Runs of tiny steps with no sample before their end (a minute or more of compiled
    stepping): a SIGTERM is heard at once (before: only at the next sample, a minute later),
    and ``--max-wall-time`` ends one with exit 1 and one line in the CLI's words."""
    import signal
    import time

    argv = [sys.executable, "-m", "tensegrity.cli", "simulate", "--stiffness", "1e12"]
    argv += ["--t-end", "1", "--sample-dt", "1", "--no-steady-state"]
    rk4 = ["--method", "rk4", "--dt", "1e-7"]  # 10^7 steps: a minute in one compiled call
    process = subprocess.Popen(
        [*argv, *rk4, "--out", str(tmp_path / "a")], stderr=subprocess.PIPE, text=True
    )
    time.sleep(4.0)  # (imports, the cache loaded, stepping)
    assert process.poll() is None
    sent = time.monotonic()
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=60)
    assert time.monotonic() - sent < 2.0
    assert process.returncode == 128 + signal.SIGTERM, stderr

    child = subprocess.run(
        [*argv, "--max-wall-time", "0.5", "--out", str(tmp_path / "b")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    line = child.stderr.strip()
    assert child.returncode == 1 and "\n" not in line, line
    assert "stopped after max_wall_time (--max-wall-time) = 0.5 s of wall-clock time" in line
    assert "raise max_wall_time (--max-wall-time)" in line and "(nothing written)" in line
    assert not (tmp_path / "b").exists()


# ------------------------------------------------------------------ the cost of a run, up front
@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--stiffness", "1e12"],
        ["equilibrium", "--stiffness", "1e12"],
        ["matrices", "--at", "equilibrium", "--stiffness", "1e12"],
    ],
)
def test_a_run_too_stiff_for_its_step_budget_is_refused_at_once(argv, tmp_path):
    """Before: 170 s of steps until ``--max-steps``, then exit 1.  Now one line, exit 2, in
    seconds (the child's imports included), saying what to change."""
    started = time.perf_counter()
    child = subprocess.run(
        [sys.executable, "-m", "tensegrity.cli", *argv, "--out", "out"],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert time.perf_counter() - started < 15
    line = child.stderr.strip()
    assert child.returncode == 2 and "\n" not in line, child.stderr
    assert "a run to 60 s needs at least 3.6e+07 DOP853 steps (highest rate 2e+06 1/s" in line
    assert "so it cannot come to rest" in line and "softer tendons" in line
    if argv[0] == "simulate":
        assert "more than --max-steps 10,000,000" in line and "--method Radau or BDF" in line
    assert list(tmp_path.iterdir()) == []


def _simulate_args(*argv: str):
    from tensegrity.cli.main import build_parser
    from tensegrity.cli.simulate import _simulation_inputs

    args = build_parser().parse_args(["simulate", *argv])
    return args, _simulation_inputs(args)[0]


def _check_simulation_cost(args, structure):
    """``simulate``'s check of its run's cost, with the options it makes of ``args``."""
    from tensegrity.cli.limits import check_run_cost
    from tensegrity.cli.simulate import _run_options

    check_run_cost(structure, args.t_end, _run_options(args))


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["--n", "10", "--m", "10"],
        ["--n", "10", "--m", "10", "--no-steady-state"],
        ["--kind", "prism", "--no-steady-state"],
        ["--kind", "octahedron", "--no-steady-state"],
        ["--method", "rk4", "--dt", "1e-4"],
        ["--t-end", "1e308"],
    ],
)
def test_ordinary_runs_are_neither_refused_nor_announced(argv, capsys):
    args, structure = _simulate_args(*argv)
    _check_simulation_cost(args, structure)
    assert capsys.readouterr().err == ""


def test_an_unstable_rk4_step_is_refused():
    """(Measured: that run fails with a rod-length error at its first step.)"""
    from tensegrity.cli.errors import CommandError

    with pytest.raises(CommandError, match=r"^--dt: 0.2 s is beyond RK4's stability limit"):
        _check_simulation_cost(*_simulate_args("--method", "rk4", "--dt", "0.2"))


def test_a_long_run_is_announced_in_seconds(capsys):
    _check_simulation_cost(*_simulate_args("--stiffness", "1e10"))
    err = capsys.readouterr().err
    assert err.startswith("tensegrity: a long run: about 3.76e+08 DOP853 steps, more than ")
    assert "--max-steps 10,000,000: it would stop there after about " in err


@pytest.mark.parametrize(
    ("make", "t_end"),
    [
        (lambda: prism(3), 100.0),  # undamped, at rest: the fewest steps per radian (0.32)
        (lambda: artificial_damping(class1_shell(3, 1)), 100.0),  # settling: 1.6
        (lambda: artificial_damping(class1_shell(3, 1, stiffness=1e10)), 2e-3),  # at rest
    ],
)
def test_the_step_estimate_bounds_real_runs(make, t_end):
    """The estimate's lower bound holds for real runs, and its expected count is within a
    factor of 3 of theirs."""
    from tensegrity.engine.budget import estimate

    structure = make()
    cost = estimate(structure, t_end)
    run = simulate(structure, (0.0, t_end), sample_dt=t_end / 10)
    assert run.status == 0
    assert cost.least_steps <= run.nsteps
    assert run.nsteps / 3 <= cost.steps <= run.nsteps * 3 or cost.steps == cost.least_steps


def test_a_steady_state_run_takes_a_huge_t_end_as_a_bound(tmp_path, capsys):
    """Before: refused as "inf samples".  A steady-state run stops when it comes to rest; a
    --t-end beyond the samples limit bounds it at that limit's end, said on stderr.  A run to
    --t-end itself (--no-steady-state) is still refused."""
    out = tmp_path / "out"
    assert (
        main(["simulate", "--t-end", "1e308", "--no-view", "--no-animation", "--out", str(out)])
        == 0
    )
    printed = capsys.readouterr()
    assert "steady state at t = 4.03 s" in printed.out
    assert (
        "tensegrity: --t-end 1e+308 s: the run stops when it comes to rest, at the latest at "
        "100000 s (10,000,000 samples at --sample-dt 0.01 s)" in printed.err
    )
    assert (out / "trajectory.h5").exists()
    code = main(["simulate", "--t-end", "1e308", "--no-steady-state", "--out", str(tmp_path / "b")])
    assert code == 2 and "is inf samples, more than 10,000,000" in capsys.readouterr().err


def test_a_structure_too_large_for_the_memory_is_refused_before_any_work(
    tmp_path, capsys, monkeypatch
):
    """(Cheaply: the threshold lowered to the (3,1) shell's 30 members, 1 MiB available.)  Before:
    a structure of 10^6 members ran for minutes at 2.5-3.6 GB with no word of it."""
    cli = importlib.import_module("tensegrity.cli.limits")

    monkeypatch.setattr(cli, "LARGE_STRUCTURE_MEMBERS", 30)
    monkeypatch.setattr(cli, "available_memory", lambda: 2**20)
    out = tmp_path / "out"
    assert main(["simulate", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (
        "tensegrity: error: a structure of 30 members needs about 204.2 MiB of memory to "
        "simulate, more than the 1.0 MiB available; simulate a smaller one"
    )
    assert not out.exists()


def test_a_large_structure_is_announced_with_its_memory_and_time(monkeypatch, capsys):
    cli = importlib.import_module("tensegrity.cli.limits")

    monkeypatch.setattr(cli, "available_memory", lambda: 2**40)
    cli.check_structure_size(class1_shell(10000, 1))  # 100,000 members
    assert capsys.readouterr().err == (
        "tensegrity: a large structure: 100,000 members, about 471.1 MiB of memory, 9 s to set "
        "up and write and 0.036 s a step\n"
    )
    cli.check_structure_size(class1_shell(30, 30))  # 10,620 members: quick, said nothing
    assert capsys.readouterr().err == ""


def test_a_span_of_inf_samples_is_refused_in_one_line():
    """Before: ``OverflowError: cannot convert float infinity to integer`` (``equilibrium`` and
    ``matrices --at equilibrium --t-end 1e308``: "the computation failed")."""
    with pytest.raises(ValueError, match=r"^sample_dt: 0.01 s over 1e\+308 s is inf samples, more"):
        simulate(class1_shell(3, 1), (0.0, 1e308), sample_dt=0.01, steady_state=True)


def test_a_sweep_too_large_for_the_memory_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    """A 100 x 100 grid with 1 GiB available (before: a 1000 x 1000 grid, 92 GiB by the same
    estimate, ran for minutes with no word of it)."""
    cli = importlib.import_module("tensegrity.cli.limits")
    monkeypatch.setattr(cli, "available_memory", lambda: 2**30)
    values = ",".join(str(k) for k in range(1, 101))
    argv = ["sweep", "--param", f"stiffness={values}", "--param", f"load={values}"]
    assert main([*argv, "-o", str(tmp_path / "s.nc")]) == 2
    assert capsys.readouterr().err.strip() == (
        "tensegrity: error: a sweep of 10,000 cases needs about 1.1 GiB of memory for its "
        "results, more than the 1.0 GiB available; sweep fewer cases"
    )
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(cli, "available_memory", lambda: 2**40)
    from tensegrity.sweep.run import SweepSpec

    cli.check_sweep_size(SweepSpec({"stiffness": list(range(1, 101)), "load": list(range(100))}))
    assert capsys.readouterr().err == (
        "tensegrity: a large sweep: 10,000 cases, about 1.1 GiB of memory\n"
    )
    cli.check_sweep_size(SweepSpec({"stiffness": list(range(1, 100)), "load": list(range(100))}))
    assert capsys.readouterr().err == ""  # 9,900 cases: said nothing
