"""The engine loop's controller hook and checkpoints (``tensegrity.engine.loop``): a controller
is called at its update times and held in between, the energy balance holds across its updates,
a constant controller is the constant control, and a run resumed from any checkpoint continues
bit for bit as the run that saved it (DOP853 with slack/taut switches, RK4, a controller, joints).
"""

from __future__ import annotations

import numpy as np
import pytest

from states import perturbed_state
from tensegrity import class1_shell, simulate
from tensegrity.engine.feedback import LinearFeedback
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.loop import Checkpointing, Feedback, run
from tensegrity.engine.options import Options
from tensegrity.engine.result import MemorySink
from tensegrity.model.shell import class2_shell
from tensegrity.physics.dynamics import State


def _perturbed(structure, seed: int = 3, jitter: float = 0.02, speed: float = 0.5) -> State:
    return perturbed_state(structure, seed, jitter, speed)


SHELL = class1_shell(3, 1, damping=0.3)


# ----------------------------------------------------------------------------- controller
def test_controller_is_called_at_its_update_times_and_held():
    calls = []

    def law(t, q, qdot):
        calls.append(t)
        return np.full(SHELL.n_tendons, 0.01 * np.sin(2 * np.pi * t))

    shell = class1_shell(3, 1)  # undamped tendons: T = k (l - (L0 - u)) while taut
    result = simulate(shell, (0.0, 0.5), controller=Feedback(law, 0.05), sample_dt=0.01)
    assert result.status == 0, result.message
    np.testing.assert_allclose(calls, np.arange(10) * 0.05, atol=1e-12)
    # between updates the rest lengths are those of the last update: a sample at 0.07 s sees
    # the control of 0.05 s
    k = int(np.argmin(np.abs(result.t - 0.07)))
    held = 0.01 * np.sin(2 * np.pi * 0.05)
    taut = result.tendon_tension[k] > 0
    expected = shell.tendon_stiffness * (result.tendon_length[k] - shell.tendon_rest_length + held)
    np.testing.assert_allclose(result.tendon_tension[k][taut], expected[taut], rtol=1e-12)
    with pytest.raises(ValueError, match="give a control or a controller"):
        simulate(
            SHELL, (0.0, 0.1), control=np.zeros(SHELL.n_tendons), controller=Feedback(law, 0.05)
        )


@pytest.mark.parametrize("method", ["DOP853", "rk4"])
def test_constant_controller_is_the_constant_control(method):
    u = np.linspace(0.0, 0.03, SHELL.n_tendons)
    options = dict(
        method=method,
        dt=1e-3 if method == "rk4" else None,
        sample_dt=0.01,
        initial=_perturbed(SHELL),
    )
    held = simulate(SHELL, (0.0, 0.3), controller=Feedback(lambda t, q, qd: u, 0.02), **options)
    fixed = simulate(SHELL, (0.0, 0.3), control=u, **options)
    assert held.status == fixed.status == 0
    # the controller's run ends steps at its update times: equal to the integration tolerance
    tol = 1e-12 if method == "rk4" else 1e-7
    np.testing.assert_allclose(held.node_position, fixed.node_position, atol=tol)


def test_energy_balance_holds_across_the_controllers_jumps():
    """Rest lengths jump at every update; the control's work takes the jump in elastic energy,
    so ``E_kin + E_el + E_d - W_u`` stays constant (undamped structure, no load)."""
    shell = class1_shell(3, 1)
    rng = np.random.default_rng(0)

    def law(t, q, qdot):
        return 0.02 * rng.random(shell.n_tendons)

    result = simulate(
        shell, (0.0, 0.5), controller=Feedback(law, 0.05), sample_dt=0.005, rtol=1e-11, atol=1e-13
    )
    assert result.status == 0, result.message
    control_work = result.energy["control_work"]
    assert np.ptp(control_work) > 1e-3  # the jumps did work
    assert np.ptp(result.total_energy) < 1e-8 * np.max(np.abs(result.energy["elastic"]))


def test_a_bad_controller_output_names_the_controller():
    with pytest.raises(ValueError, match="controller"):
        simulate(SHELL, (0.0, 0.1), controller=Feedback(lambda t, q, qd: np.zeros(3), 0.05))
    with pytest.raises(ValueError, match=r"controller\[0\]: rest length"):
        simulate(
            SHELL,
            (0.0, 0.1),
            controller=Feedback(lambda t, q, qd: np.full(SHELL.n_tendons, 10.0), 0.05),
        )
    with pytest.raises(ValueError, match="period"):
        Feedback(lambda t, q, qd: np.zeros(SHELL.n_tendons), 0.0)


# ----------------------------------------------------------------------------- checkpoints
def _run(structure, t_end, options, *, controller=None, resume=None, every=10, initial=None):
    sink, saved = MemorySink(), []
    summary = run(
        structure,
        (0.0, t_end),
        initial=initial,
        inputs=Inputs(structure),
        options=options,
        sink=sink,
        controller=controller,
        checkpoint=Checkpointing(every=every, save=saved.append),
        resume=resume,
    )
    return sink.samples, summary, saved


CASES = {
    "DOP853 with switches": (class1_shell(4, 2), Options(sample_dt=0.01), None),
    "rk4": (SHELL, Options(method="rk4", dt=2e-3, sample_dt=0.01), None),
    "controller": (
        SHELL,
        Options(sample_dt=0.01),
        Feedback(lambda t, q, qd: 0.02 * np.tanh(qd[: SHELL.n_tendons]), 0.015),
    ),
    "joints": (class2_shell(3, 2), Options(sample_dt=0.01, rtol=1e-7), None),
    "compiled feedback": (
        SHELL,
        Options(sample_dt=0.01),
        LinearFeedback(
            np.random.default_rng(0).normal(scale=1e-3, size=(SHELL.n_tendons, 72)),
            np.concatenate([SHELL.node_position.ravel(), np.zeros(36)]),
            np.full(SHELL.n_tendons, 0.01),
            0.015,
        ),
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_resumed_run_is_bitwise_the_uninterrupted_one(case):
    structure, options, controller = CASES[case]
    initial = _perturbed(structure)
    samples, summary, saved = _run(structure, 0.3, options, controller=controller, initial=initial)
    assert summary.status == 0, summary.message
    assert len(saved) == 2  # at samples 10 and 20
    if case == "DOP853 with switches":
        assert summary.nswitches > 0  # switches before and after the checkpoints
        assert saved[0].switch_times and len(summary.switch_times) > len(saved[1].switch_times)
    if case in ("controller", "compiled feedback"):
        assert np.any(saved[0].control != 0)  # the held control is part of the state
    for state in saved:
        resumed, again, _ = _run(structure, 0.3, options, controller=controller, resume=state)
        start = state.next_sample
        assert resumed.t.tolist() == samples.t[start:].tolist()
        for field in ("q", "qdot", "tendon_tension", "energy"):
            assert np.array_equal(getattr(resumed, field), getattr(samples, field)[start:]), field
        assert (again.nfev, again.nsteps, again.nswitches, again.nprojections) == (
            summary.nfev,
            summary.nsteps,
            summary.nswitches,
            summary.nprojections,
        )
        assert again.switch_times == summary.switch_times
        assert np.array_equal(again.control_updates, summary.control_updates)
        assert again.max_rod_length_error == summary.max_rod_length_error


def test_loop_state_round_trips_through_arrays():
    structure, options, controller = CASES["controller"]
    _, _, saved = _run(
        structure, 0.3, options, controller=controller, initial=_perturbed(structure)
    )
    from tensegrity.engine.loop import LoopState

    state = saved[0]
    back = LoopState.from_arrays(state.to_arrays())
    for name, value in state.to_arrays().items():
        assert np.array_equal(back.to_arrays()[name], value, equal_nan=True), name


def test_checkpointing_needs_a_whole_number_of_samples():
    for every in (0, 2.5):
        with pytest.raises(ValueError, match=r"^checkpoint\.every: must be a whole number > 0"):
            _run(SHELL, 0.1, Options(sample_dt=0.01), every=every)
