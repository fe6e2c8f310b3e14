"""The engine (``tensegrity.engine``) against evidence that does not share its code: scipy's
DOP853 on the NumPy reference right-hand side (``dynamics.evaluate``), the same run at a tight
tolerance (slack/taut switches located once each), and the cost per step it reports."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from states import perturbed_state
from tensegrity import class1_shell, simulate
from tensegrity.physics import dynamics
from tensegrity.physics.dynamics import State

_perturbed = perturbed_state


def _reference(structure, initial: State, t_end: float, times: np.ndarray) -> np.ndarray:
    """Node positions (T, N, 3) by ``scipy.integrate.solve_ivp`` (DOP853, rtol 1e-12) on the
    NumPy reference right-hand side, with no switch location and no projection."""
    n = structure.n_coordinates

    def rhs(t, y):
        ev = dynamics.evaluate(structure, y[:n], y[n:], rest_length=structure.tendon_rest_length)
        return np.concatenate([y[n:], ev.qddot])

    sol = solve_ivp(
        rhs,
        (0.0, t_end),
        np.concatenate([initial.q, initial.qdot]),
        method="DOP853",
        rtol=1e-12,
        atol=1e-14,
        t_eval=times,
    )
    assert sol.success
    return dynamics.nodes_from_coordinates(structure, sol.y[:n].T)


def test_dop853_follows_an_independent_integration_through_switches():
    """Undamped (4,2) shell with slack/taut switches over 0.5 s: the engine at its default
    tolerances stays within 1e-8 m of scipy's DOP853 at rtol 1e-12 on the NumPy physics."""
    shell = class1_shell(4, 2)
    initial = _perturbed(shell, 1, 0.01, 0.5)
    result = simulate(shell, (0.0, 0.5), initial=initial, sample_dt=0.05)
    assert result.status == 0, result.message
    assert result.nswitches > 0  # the case has switches
    reference = _reference(shell, initial, 0.5, result.t)
    assert np.max(np.abs(result.node_position - reference)) < 1e-8


@pytest.mark.parametrize("method", ["DOP853", "rk4"])
def test_engine_accelerations_in_the_samples_equal_the_reference(method):
    """Each sample's tensions and lengths equal the NumPy reference at the sample's state."""
    shell = dynamics.artificial_damping(class1_shell(3, 2))
    result = simulate(
        shell,
        (0.0, 0.2),
        initial=_perturbed(shell, 2, 0.01, 0.3),
        method=method,
        dt=1e-4 if method == "rk4" else None,
        sample_dt=0.02,
        gravity=[0, 0, -9.81],
    )
    for k in range(result.t.size):
        ev = dynamics.evaluate(
            shell,
            result.q[k],
            result.qdot[k],
            rest_length=shell.tendon_rest_length,
            gravity=np.array([0, 0, -9.81]),
        )
        scale = np.max(np.abs(ev.tendons.tension))
        np.testing.assert_allclose(
            result.tendon_tension[k], ev.tendons.tension, rtol=0, atol=1e-12 * scale
        )
        np.testing.assert_allclose(result.tendon_length[k], ev.tendons.length, rtol=1e-13)


def test_switches_are_located_once_each():
    """A perturbed (5,2) shell over 1 s has hundreds of slack/taut switches; the default run
    locates as many as a run at rtol 1e-11 (a switch found twice, a round-off after itself, would
    add to the count), at the same times."""
    shell = class1_shell(5, 2)
    initial = _perturbed(shell, 3, 0.01, 0.5)
    default = simulate(shell, (0.0, 1.0), initial=initial, sample_dt=0.05)
    tight = simulate(shell, (0.0, 1.0), initial=initial, sample_dt=0.05, rtol=1e-11, atol=1e-13)
    assert default.status == tight.status == 0
    assert default.nswitches > 100
    assert default.nswitches == tight.nswitches
    np.testing.assert_allclose(default.switch_times, tight.switch_times, atol=1e-6)


def test_cost_per_step_is_reported_and_near_the_method_s():
    """Without switches DOP853 costs its 12 evaluations per accepted step, plus one per
    projection (here nearly every step: the rod-length drift of a step at rtol 1e-9 exceeds
    ``projection_tol`` = 1e-12; the step size carries over), 3 per sampled step (dense output)
    and the rejected attempts (12% of attempts here; measured: 14.8 per step).  The loop driven
    by scipy restarted at every projection (two more evaluations and a new initial step each)
    and needed about 30."""
    shell = class1_shell(3, 1, rest_length=0.0)  # always taut: no switches
    result = simulate(shell, (0.0, 1.0), initial=_perturbed(shell, 4, 0.0, 0.5), sample_dt=0.1)
    assert result.nswitches == 0 and result.status == 0
    floor = 12 + (result.nprojections + 3 * (result.t.size - 1)) / result.nsteps
    assert floor <= result.evaluations_per_step < 16, (floor, result.evaluations_per_step)


# --------------------------------------------------------------------------- control tables
def _control_table(shell):
    from tensegrity.model.loads import ControlTable

    times = np.array([0.0, 0.1, 0.2, 0.3])
    u = np.zeros((4, shell.n_tendons))
    u[:, 0] = [0.0, 0.05, 0.02, 0.06]  # shorten and release one tendon [m]
    u[:, 5] = [0.0, -0.02, 0.03, 0.0]
    return ControlTable(times, u)


def test_control_table_drives_as_the_same_function_and_its_work_balances_the_energy():
    """A ControlTable (slopes used for the control's work) gives the trajectory of the same
    control given as a function of time, to the integration tolerance (the two runs' control
    work, a central difference for the function, enters the error control, so their steps
    differ), and the energy balance ``E_kin + E_el - W_u`` stays constant although the control
    feeds energy in."""
    shell = class1_shell(3, 1)
    table = _control_table(shell)
    kwargs = dict(initial=_perturbed(shell, 5, 0.0, 0.0), sample_dt=0.01, rtol=1e-11, atol=1e-13)
    with_table = simulate(shell, (0.0, 0.3), control=table, **kwargs)
    with_function = simulate(shell, (0.0, 0.3), control=lambda t: table(t), **kwargs)
    assert with_table.status == with_function.status == 0
    assert with_table.settings["control"] == "table"
    np.testing.assert_allclose(
        with_table.node_position, with_function.node_position, rtol=0, atol=1e-10
    )
    work = with_table.energy["control_work"]
    drift = np.abs(with_table.total_energy - with_table.total_energy[0]).max()
    assert np.abs(work).max() > 1e-2  # the control does work ...
    assert drift < 1e-6 * np.abs(work).max()  # ... and the balance accounts for it
    # (The function's work is not compared: its central-difference rate is wrong within 1e-6 s
    # of the table's corners, where the table's exact slope is not.)


def test_control_table_bad_input_names_the_field():
    from tensegrity.model.loads import ControlTable

    shell = class1_shell(3, 1)
    with pytest.raises(ValueError, match=r"^time: must increase strictly"):
        ControlTable([0.0, 0.0], np.zeros((2, shell.n_tendons)))
    with pytest.raises(ValueError, match=r"^control: expected shape \(T, S\)"):
        ControlTable([0.0, 1.0], np.zeros((3, shell.n_tendons)))
    with pytest.raises(ValueError, match=r"^control: expected shape \(24,\)"):
        simulate(shell, (0.0, 0.1), control=ControlTable([0.0], np.zeros((1, 5))))
    too_short = ControlTable(
        [0.0, 0.1], np.stack([np.zeros(shell.n_tendons), np.full(shell.n_tendons, 10.0)])
    )
    result = simulate(shell, (0.0, 0.1), control=too_short)
    assert result.status == -1 and "control[" in result.message and "negative" in result.message


# --------------------------------------------------------------------------- compiled tables
def _force_table(structure, outside):
    from tensegrity.model.loads import ForceTable

    rng = np.random.default_rng(11)
    times = np.array([0.02, 0.05, 0.09])
    return ForceTable(times, rng.normal(size=(3, structure.n_nodes, 3)), outside)


@pytest.mark.parametrize("outside", ["hold", "zero"])
@pytest.mark.parametrize("planar", [False, True])
def test_compiled_table_rows_equal_numpy_bit_for_bit(outside, planar):
    """The rows the compiled code interpolates from a control and a force table, at times
    before, inside, on the corners of and after the tables, are those of ``ForceTable.at`` /
    ``ControlTable.at`` (and the slopes ``ControlTable.slope``) bit for bit, in the kernel's
    order and layout; a one-row table too."""
    from tensegrity.design.catalogue import planar_two_rod
    from tensegrity.engine.inputs import Inputs
    from tensegrity.engine.system import CompiledSystem
    from tensegrity.model.loads import ControlTable

    structure = planar_two_rod() if planar else class1_shell(3, 1)
    # (a ForceTable holds 3-D forces: a planar structure takes a force function instead)
    force = None if planar else _force_table(structure, outside)
    u = np.random.default_rng(5).uniform(-0.01, 0.01, size=(3, structure.n_tendons))
    controls = [ControlTable([0.0, 0.04, 0.1], u, outside), ControlTable([0.03], u[:1], outside)]
    times = np.array([-0.01, 0.0, 0.02, 0.031, 0.04, 0.05, 0.0712, 0.09, 0.1, 0.2])
    for control in controls:
        system = CompiledSystem(structure, Inputs(structure, control=control, external_force=force))
        assert system.tables is not None  # the compiled path
        data = system.stage_inputs(times)
        rest, rate, slots = data.rest, data.rate, data.force
        assert data.has_rate and data.has_external == (force is not None)
        packed = system.packed
        expected_rest = packed.to_kernel_order(structure.tendon_rest_length - control.at(times))
        np.testing.assert_array_equal(rest, expected_rest)
        np.testing.assert_array_equal(rate, packed.to_kernel_order(control.slope(times)))
        if force is not None:
            np.testing.assert_array_equal(slots, packed.to_slots(force.at(times)))


def test_rk4_with_tables_runs_compiled_stretches_and_equals_the_functions(monkeypatch):
    """``simulate(method="rk4")`` with a control table and a force table steps in compiled
    stretches between samples (a few calls, not one per step), and gives the trajectory of the
    same tables called as Python functions of time bit for bit; the functions, called back from
    the compiled loop (``compiled.make_inputs``), step in the same stretches."""
    from tensegrity.engine import compiled

    shell = class1_shell(3, 1)
    control, force = _control_table(shell), _force_table(shell, "zero")
    calls = []
    segment = compiled.rk4_segment

    def counting(*args):
        calls.append(args[8])  # n_steps
        return segment(*args)

    monkeypatch.setattr(compiled, "rk4_segment", counting)
    kwargs = dict(method="rk4", dt=1e-4, sample_dt=0.01, initial=_perturbed(shell, 2, 0.0, 0.1))
    tables = simulate(shell, (0.0, 0.3), control=control, external_force=force, **kwargs)
    n_table_calls = len(calls)
    functions = simulate(
        shell, (0.0, 0.3), control=lambda t: control(t), external_force=lambda t: force(t), **kwargs
    )
    assert tables.status == functions.status == 0
    assert tables.nsteps == functions.nsteps == 3000
    assert n_table_calls <= 2 * tables.t.size < 100  # stretches up to each sample
    assert len(calls) - n_table_calls == n_table_calls  # the functions: the same stretches
    np.testing.assert_array_equal(tables.q, functions.q)
    np.testing.assert_array_equal(tables.qdot, functions.qdot)
    # (the control's work differs: a function's rate is a central difference, a table's exact)


def test_rk4_stops_where_a_control_table_makes_a_rest_length_negative():
    """A control table that shortens a tendon past its rest length ends an RK4 run before the
    step that would use it, with the message (tendon, time) of the same table called as a
    function, and the same last state."""
    from tensegrity.model.loads import ControlTable

    shell = class1_shell(3, 1)
    u = np.zeros((2, shell.n_tendons))
    u[1, 3] = 2 * shell.tendon_rest_length[3]  # rest length 0 at t = 0.05 s, then negative
    table = ControlTable([0.0, 0.1], u)
    kwargs = dict(method="rk4", dt=1e-3, sample_dt=0.02)
    compiled_run = simulate(shell, (0.0, 0.2), control=table, **kwargs)
    python_run = simulate(shell, (0.0, 0.2), control=lambda t: table(t), **kwargs)
    assert compiled_run.status == python_run.status == -1
    assert "control[3]" in compiled_run.message and "negative" in compiled_run.message
    assert compiled_run.message == python_run.message
    assert 0.049 < compiled_run.t[-1] <= 0.05
    np.testing.assert_array_equal(compiled_run.q[-1], python_run.q[-1])


def test_dop853_runs_compiled_between_samples_and_equals_its_python_twin(monkeypatch):
    """The default method's whole loop (steps, error control, located switches, checks,
    projections) runs compiled from one sample to the next: a (4,2) shell with switches and a
    force table returns to Python about once per sample, not once per step.  The same force
    given as a Python function runs the same compiled loop (the function called back from it,
    ``compiled.make_inputs``), and the two runs agree bit for bit: trajectories, switch times
    and counts."""
    from tensegrity.engine import dop853

    shell = class1_shell(4, 2)
    force = _force_table(shell, "zero")
    calls = []
    compiled_run = dop853.dop853_run

    def counting(model, rows, point, loop, *args):
        calls.append(loop.clock[0])  # clock[T]
        return compiled_run(model, rows, point, loop, *args)

    monkeypatch.setattr(dop853, "dop853_run", counting)
    kwargs = dict(sample_dt=0.01, initial=_perturbed(shell, 2, 0.03, 1.0))
    table = simulate(shell, (0.0, 0.3), external_force=force, **kwargs)
    n_table_calls = len(calls)
    function = simulate(shell, (0.0, 0.3), external_force=lambda t: force(t), **kwargs)
    assert table.status == function.status == 0
    assert table.nswitches > 50 and table.nsteps > 200  # switches located, many steps
    assert n_table_calls <= table.t.size + 1 < table.nsteps / 5  # one call per sample
    assert len(calls) - n_table_calls == n_table_calls  # the function's run: the same calls
    assert (table.nsteps, table.nswitches, table.nprojections, table.nfev) == (
        function.nsteps,
        function.nswitches,
        function.nprojections,
        function.nfev,
    )
    np.testing.assert_array_equal(table.switch_times, function.switch_times)
    np.testing.assert_array_equal(table.q, function.q)
    np.testing.assert_array_equal(table.qdot, function.qdot)


def test_dop853_stops_where_a_control_table_makes_a_rest_length_negative():
    """A control table that shortens a tendon past its rest length ends a DOP853 run with a
    message naming the tendon and the time, as the same table called as a function does (at a
    stage time a little different: a function's control rate is a central difference, which
    changes the control's work in the state and with it the steps)."""
    from tensegrity.model.loads import ControlTable

    shell = class1_shell(3, 1)
    u = np.zeros((2, shell.n_tendons))
    u[1, 3] = 2 * shell.tendon_rest_length[3]  # rest length 0 at t = 0.05 s, then negative
    table = ControlTable([0.0, 0.1], u)
    compiled_run = simulate(shell, (0.0, 0.2), control=table, sample_dt=0.02)
    python_run = simulate(shell, (0.0, 0.2), control=lambda t: table(t), sample_dt=0.02)
    assert compiled_run.status == python_run.status == -1
    assert "control[3]" in compiled_run.message and "negative" in compiled_run.message
    for run in (compiled_run, python_run):
        failed_at = float(run.message.rsplit("t = ", 1)[1].removesuffix(" s"))
        assert 0.05 < failed_at < 0.051  # the first stage past the zero rest length
        assert 0.04 < run.t[-1] <= failed_at


@pytest.mark.parametrize("method", ["RK45", "Radau"])
def test_scipy_methods_follow_the_default_method(method):
    """The other ``scipy.integrate`` methods, stepped by scipy on the compiled right-hand side
    (imported only when asked for), follow DOP853's trajectory to their tolerance."""
    shell = class1_shell(3, 1)
    kwargs = dict(initial=_perturbed(shell, 7, 0.0, 0.2), sample_dt=0.01, rtol=1e-9, atol=1e-11)
    result = simulate(shell, (0.0, 0.1), method=method, **kwargs)
    reference = simulate(shell, (0.0, 0.1), **kwargs)
    assert result.status == reference.status == 0, result.message
    assert result.settings["method"] == method
    assert result.nswitches == reference.nswitches > 0
    np.testing.assert_allclose(result.node_position, reference.node_position, rtol=0, atol=1e-8)
