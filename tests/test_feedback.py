"""Compiled linear feedback and actuators (issue 30): the law run inside the compiled loop
against the same law as a Python controller, the actuators' limits and lag against their closed
forms, the energy balance through them, saturation reports, and errors."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import class1_shell, simulate
from tensegrity.design.catalogue import prism
from tensegrity.engine.feedback import LinearFeedback, output_sizes
from tensegrity.engine.loop import Feedback
from tensegrity.engine.result import total_energy
from tensegrity.model.actuators import Winch, actuators
from tensegrity.physics import dynamics
from tensegrity.physics.coordinates import nodes_from_coordinates


def shell() -> object:
    return class1_shell(3, 1)


def outputs_of(structure, q, qdot, groups, rest=None):
    """The outputs ``y`` of a LinearFeedback, by NumPy from ``(q, q')``."""
    p = nodes_from_coordinates(structure, q)
    v = nodes_from_coordinates(structure, qdot, rates=True)
    parts = {"position": p.ravel(), "velocity": v.ravel()}
    length = dynamics.tendon_lengths(structure, p)
    parts["length"] = length
    if "tension" in groups:
        rest = structure.tendon_rest_length if rest is None else rest
        parts["tension"] = dynamics.tendon_forces(structure, p, v, rest).tension
    return np.concatenate([parts[g] for g in groups])


def applied_control(run, tendons):
    """The control ``u = L0 - Lbar`` [m] applied at each sample, from the recorded tensions
    and lengths (undamped tendons, taut): ``Lbar = l - T / k``."""
    s = run.structure
    rest = (
        run.tendon_length[:, tendons] - run.tendon_tension[:, tendons] / s.tendon_stiffness[tendons]
    )
    return s.tendon_rest_length[tendons] - rest


def test_zero_gain_is_the_open_loop_held_by_a_python_controller_bit_for_bit():
    s = shell()
    u_ref = np.full(s.n_tendons, 0.01)
    Y = sum(output_sizes(s).values())
    law = LinearFeedback(np.zeros((s.n_tendons, Y)), np.zeros(Y), u_ref, 0.01,
                         outputs=("position", "velocity", "length", "tension"))  # fmt: skip
    compiled = simulate(s, (0, 0.2), sample_dt=0.01, controller=law)
    held = simulate(s, (0, 0.2), sample_dt=0.01, controller=Feedback(lambda t, q, v: u_ref, 0.01))
    assert compiled.status == held.status == 0
    assert np.array_equal(compiled.q, held.q) and np.array_equal(compiled.qdot, held.qdot)
    assert np.array_equal(compiled.energy["control_work"], held.energy["control_work"])
    # ... and the run with the control constant from the start, to the integration tolerance
    constant = simulate(s, (0, 0.2), sample_dt=0.01, control=u_ref)
    assert np.abs(compiled.q - constant.q).max() < 1e-8
    # every update is recorded: 20 periods and the end's none
    assert np.allclose(compiled.control_time, np.arange(20) * 0.01)
    assert np.array_equal(compiled.control_command, np.tile(u_ref, (20, 1)))


@pytest.mark.parametrize("groups", [("position", "velocity"), ("length", "tension")])
def test_compiled_law_equals_the_same_law_in_python(groups):
    s = shell()
    rng = np.random.default_rng(3)
    sizes = output_sizes(s)
    Y = sum(sizes[g] for g in groups)
    state0 = dynamics.initial_state(s)
    rest0 = s.tendon_rest_length
    y_ref = outputs_of(s, state0.q, state0.qdot, groups)
    scale = {"position": 0.002, "velocity": 0.002, "length": 0.002, "tension": 1e-5}
    K = rng.normal(size=(s.n_tendons, Y)) * np.concatenate(
        [np.full(sizes[g], scale[g]) for g in groups]
    )
    u_ref = np.full(s.n_tendons, 0.005)
    law = LinearFeedback(K, y_ref, u_ref, 0.005, outputs=groups)
    held = {"u": np.zeros(s.n_tendons)}

    def python_law(t, q, qdot):
        y = outputs_of(s, q, qdot, groups, rest=rest0 - held["u"])
        held["u"] = u_ref - K @ (y - y_ref)
        return held["u"]

    state = dynamics.State(0.0, state0.q, state0.qdot + 0.05 * rng.normal(size=state0.q.size))
    state = dynamics.State(0.0, *dynamics.project_to_constraints(s, state.q, state.qdot))
    compiled = simulate(s, (0, 0.3), initial=state, sample_dt=0.01, controller=law)
    python = simulate(
        s, (0, 0.3), initial=state, sample_dt=0.01, controller=Feedback(python_law, 0.005)
    )
    assert compiled.status == python.status == 0
    assert np.abs(compiled.q - compiled.q[0]).max() > 1e-3  # (it moved)
    assert np.abs(compiled.q - python.q).max() < 1e-10
    assert np.allclose(compiled.control_command, np.array(python.control_command), atol=1e-12)


def test_rest_length_bounds_hold_and_the_clipped_commands_are_reported():
    s = prism()
    tendons = [0, 1, 2]
    rest0 = s.tendon_rest_length[tendons]
    act = actuators(s, tendons, min_rest_length=rest0 - 0.02, max_rest_length=rest0 + 0.01)
    commands = iter([np.array([0.05, -0.05, 0.0]), np.array([0.01, 0.0, -0.2])])
    law = Feedback(lambda t, q, v: next(commands, np.zeros(3)), 0.1)
    run = simulate(s, (0, 0.3), sample_dt=0.01, controller=law, actuators=act)
    assert run.status == 0, run.message
    assert np.allclose(run.control_command[0], [0.02, -0.01, 0.0])
    assert np.allclose(run.control_command[1], [0.01, 0.0, -0.01])
    u = applied_control(run, tendons)
    assert np.all(u <= 0.02 + 1e-9) and np.all(u >= -0.01 - 1e-9)
    bound = [(x.tendon, x.start, x.end) for x in run.saturations() if x.kind == "bound"]
    names = [s.tendon_name[i] for i in tendons]
    assert (names[0], 0.0, 0.1) in [(n, round(a, 9), round(b, 9)) for n, a, b in bound]
    assert (names[1], 0.0, 0.1) in [(n, round(a, 9), round(b, 9)) for n, a, b in bound]
    assert (names[2], 0.1, 0.2) in [(n, round(a, 9), round(b, 9)) for n, a, b in bound]


def test_rate_limit_ramps_at_the_limit_and_reports_how_long():
    s = prism()
    act = actuators(s, [0], max_rate=0.05)
    law = Feedback(lambda t, q, v: np.array([0.01]), 1.0)
    run = simulate(s, (0, 0.5), sample_dt=0.01, controller=law, actuators=act)
    assert run.status == 0, run.message
    u = applied_control(run, [0])[:, 0]
    expected = np.minimum(0.05 * run.t, 0.01)
    assert np.abs(u - expected).max() < 1e-9
    (sat,) = run.saturations()
    assert sat.kind == "rate" and sat.start == 0.0 and sat.end == pytest.approx(0.2, rel=1e-12)


def test_a_lag_shows_its_time_constant_in_the_step_response():
    s = prism()
    tau = 0.05
    act = actuators(s, [0], time_constant=tau)
    law = Feedback(lambda t, q, v: np.array([0.01]), 10.0)
    run = simulate(s, (0, 0.3), sample_dt=0.002, controller=law, actuators=act)
    assert run.status == 0, run.message
    u = applied_control(run, [0])[:, 0]
    # the time constant fitted from the samples (log of the distance left), within 1%
    inside = (run.t > 0) & (run.t < 0.2)
    slope = np.polyfit(run.t[inside], np.log(0.01 - u[inside]), 1)[0]
    assert -1.0 / slope == pytest.approx(tau, rel=0.01)


def test_the_energy_balance_closes_through_rate_limits_and_lags():
    s = class1_shell(3, 1)
    act = actuators(s, None, max_rate=0.02, time_constant=0.01)
    rng = np.random.default_rng(1)
    law = Feedback(lambda t, q, v: 0.01 * rng.uniform(-1, 1, s.n_tendons), 0.02)
    run = simulate(s, (0, 0.3), sample_dt=0.005, controller=law, actuators=act)
    assert run.status == 0, run.message
    work = run.energy["control_work"]
    assert np.abs(work).max() > 1e-3  # (the controls did work)
    balance = total_energy(run.energy)
    scale = (run.energy["kinetic"] + run.energy["elastic"]).max()
    # the balance drifts by the integration error only (rtol 1e-9), 1e5 times less than the
    # control's work it accounts for
    assert np.abs(balance - balance[0]).max() < 1e-8 * scale
    assert np.abs(balance - balance[0]).max() < 1e-5 * np.abs(work).max()


def test_a_step_ends_where_a_ramp_meets_the_lag():
    """Actuators ramping at their rate limit into their lag: the rate is continuous where the
    ramp ends but its slope is not, so the adaptive loop ends a step there
    (:func:`tensegrity.engine.actuation.next_ramp_end`).  The control's work is then as accurate
    as the motion: within 3e-10 of its size of a run at ``rtol`` 1e-12 (measured 5e-11; with
    steps across those times 1e-8, and 1.6 times the evaluations)."""
    s = class1_shell(3, 1)
    act = actuators(s, None, max_rate=0.02, time_constant=0.01)

    def run(**tolerances):
        rng = np.random.default_rng(1)
        law = Feedback(lambda t, q, v: 0.01 * rng.uniform(-1, 1, s.n_tendons), 0.02)
        return simulate(s, (0, 0.3), sample_dt=0.005, controller=law, actuators=act, **tolerances)

    default, tight = run(), run(rtol=1e-12, atol=1e-14)
    assert default.status == tight.status == 0
    work = tight.energy["control_work"]
    assert np.abs(default.energy["control_work"] - work).max() < 3e-10 * np.abs(work).max()
    assert np.abs(default.q - tight.q).max() < 1e-8


def test_a_winch_sets_the_rate_limit():
    s = prism()
    act = actuators(s, [0], winch=Winch(radius=0.01, max_speed=5.0))
    assert act.max_rate[0] == pytest.approx(0.05) and np.isinf(act.max_tension[0])
    run = simulate(s, (0, 0.3), controller=Feedback(lambda t, q, v: np.array([0.02]), 1.0),
                   actuators=act, sample_dt=0.01)  # fmt: skip
    assert np.abs(applied_control(run, [0])[:, 0] - np.minimum(0.05 * run.t, 0.02)).max() < 1e-9


def test_a_winch_caps_the_tension_and_the_energy_balance_still_closes():
    """A damped prism's cable pulled in past what its winch holds (0.06 N m on a 1 cm drum:
    6 N): the tension stays at the cap, the spring's potential beyond it grows linearly, so the
    balance closes (with the uncapped potential it would be off by joules)."""
    s = prism(damping=2.0)
    act = actuators(s, [0], winch=Winch(radius=0.01, max_speed=100.0, max_torque=0.06))
    assert act.max_tension[0] == pytest.approx(6.0)
    law = Feedback(lambda t, q, v: np.array([0.2]), 1.0)
    run = simulate(s, (0, 1.0), sample_dt=0.01, controller=law, actuators=act)
    assert run.status == 0, run.message
    tension = run.tendon_tension[:, 0]
    assert tension.max() <= 6.0 * (1 + 1e-12) and np.sum(tension >= 6.0 * (1 - 1e-12)) > 10
    balance = total_energy(run.energy)
    work = np.abs(run.energy["control_work"]).max()
    assert work > 1.0 and np.abs(balance - balance[0]).max() < 1e-6 * work
    force = [x for x in run.saturations() if x.kind == "force"]
    assert force and all(x.tendon == s.tendon_name[0] for x in force)


@pytest.mark.parametrize(
    ("output", "match"),
    [
        (np.zeros(2), r"controller: got shape \(2,\) at t = 0 s"),
        (np.array([np.nan]), r"controller: got a value that is not finite at t = 0 s"),
    ],
)
def test_a_bad_controller_output_is_one_line_naming_the_time(output, match):
    s = prism()
    law = Feedback(lambda t, q, v: output, 0.1)
    with pytest.raises(ValueError, match=match):
        simulate(s, (0, 0.2), controller=law, actuators=actuators(s, [0]))


def test_a_law_that_does_not_fit_the_structure_is_named():
    s = prism()
    with pytest.raises(ValueError, match=r"y_ref: expected 36 outputs \(position 18 \+ "):
        simulate(s, (0, 0.1), controller=LinearFeedback(np.zeros((9, 3)), np.zeros(3),
                                                        np.zeros(9), 0.01))  # fmt: skip
    with pytest.raises(ValueError, match=r"controller\.tendons: must be the actuated tendons"):
        simulate(s, (0, 0.1), controller=LinearFeedback.zero(s, 0.01, tendons=[1]),
                 actuators=actuators(s, [0]))  # fmt: skip


def test_the_closed_loop_decays_at_the_rate_of_its_linear_poles():
    """An LQR law (analysis.control_design) run by the compiled loop on the nonlinear (3,1)
    shell: a small disturbance along the slowest closed-loop mode decays at that pole's rate,
    within 1%, measured on the mode's own coordinate (its left eigenvector)."""
    import scipy.linalg

    from tensegrity.analysis.control_design import lqr, reachable
    from tensegrity.analysis.equilibrium import find_equilibrium
    from tensegrity.analysis.linearize import linearize

    s = shell()
    lin = linearize(s, find_equilibrium(s))
    model = reachable(lin)
    design = lqr(model, period=2e-4)
    closed = model.system.A - model.system.B @ design.gain
    poles, left, right = scipy.linalg.eig(closed, left=True)
    j = int(np.argmin(-poles.real))
    rate = -poles[j].real
    r = model.shapes.shape[1]
    start = np.real(right[:, j])
    eta = model.shapes @ start[:r]
    scale = 1e-4 / np.abs(lin.position_jacobian @ eta).max()  # (0.1 mm at most)
    q, qdot = lin.configuration(scale * np.concatenate([eta, model.shapes @ start[r:]]))
    t_end = 3.0 / rate
    run = simulate(
        s, (0, t_end), initial=dynamics.State(0.0, q, qdot), sample_dt=t_end / 60,
        controller=design.feedback, rtol=1e-10, atol=1e-13,
    )  # fmt: skip
    assert run.status == 0, run.message
    states = zip(run.q, run.qdot, strict=True)
    coordinate = np.array([left[:, j].conj() @ model.reduce(lin.state(q, v)) for q, v in states])
    slope = np.polyfit(run.t, np.log(np.abs(coordinate)), 1)[0]
    assert -slope == pytest.approx(rate, rel=0.01)


def test_a_controller_that_raises_fails_the_run_in_one_line_naming_the_time():
    s = prism()

    def law(t, q, v):
        if t > 0.05:
            raise ZeroDivisionError("no gain\nsecond line")
        return np.zeros(s.n_tendons)

    run = simulate(s, (0, 0.2), sample_dt=0.01, controller=Feedback(law, 0.02))
    assert run.status == -1
    assert run.message == "controller: raised ZeroDivisionError at t = 0.06 s: no gain"
    assert run.t[-1] == pytest.approx(0.06)  # (the samples up to it are kept)
