"""Sensitivities integrated with the state (:mod:`tensegrity.engine.sensitivity`) against
central differences of whole runs, each run made afresh with the parameter moved (its own
steps, its own events located): through slack/taut switches, touch-downs, lift-offs, sticks
and slips."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.analysis.identification import parameter
from tensegrity.design.catalogue import six_bar_robot, three_bar_robot
from tensegrity.model.ground import ground
from tensegrity.model.loads import ControlTable, ForceTable
from tensegrity.model.shell import class1_shell
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import State, coordinates_from_nodes, initial_state

GRAVITY = np.array([0.0, 0.0, -9.81])
#: The runs' tolerances: the references' own error (rtol / STEP) far below what is checked.
TIGHT = {"rtol": 1e-12, "atol": 1e-15}
#: The central differences' step, relative to the parameter.
STEP = 1e-5


@dataclasses.dataclass(frozen=True)
class StateComponent:
    """A parameter of the initial state: component ``members`` of ``y``."""

    members: tuple[int, ...]
    kind: str = "initial_state"
    name: str = "initial_state"


def _shell(damping: float = 0.8):
    s = class1_shell(3, 1, fixed_base=True)
    return s.replace(
        tendon_stiffness=np.full(s.n_tendons, 120.0),
        tendon_damping=np.full(s.n_tendons, damping),
        rod_mass=np.full(s.n_rods, 1.3),
    )


def _push() -> np.ndarray:
    w = np.zeros((12, 3))
    w[11, 0] = 5.0
    return w


SHELL_RUN = {"gravity": GRAVITY, "external_force": _push(), "sample_dt": 0.02, **TIGHT}


def _central(structure, p, span, **options) -> np.ndarray:
    """d q / d p by central differences of two whole runs."""
    value = float(np.mean(getattr(structure, p.field)[p.members]))
    h = STEP * value
    up = simulate(p.apply(structure, value + h), span, **options)
    down = simulate(p.apply(structure, value - h), span, **options)
    return (up.q - down.q) / (2 * h)


def _relative_error(reference: np.ndarray, sensitivity: np.ndarray) -> float:
    return float(np.abs(reference - sensitivity).max() / np.abs(reference).max())


def test_sensitivities_equal_central_differences_through_slack_switches():
    """The damped (3,1) shell pushed under gravity for 0.6 s: 26 slack/taut switches, damped
    tendons snapping taut (the tension jumps: the saltation carries it); every kind of
    parameter, of all members and of one, within 1e-6 of the differences."""
    shell = _shell()
    names = [
        "tendon_stiffness",
        "tendon_damping",
        "tendon_rest_length",
        "rod_mass",
        f"tendon_stiffness:{shell.tendon_name[3]}",
        "rod_mass:1",
    ]
    params = [parameter(shell, n) for n in names]
    run = simulate(shell, (0.0, 0.6), sensitivity=params, **SHELL_RUN)
    assert run.nswitches > 20
    assert run.q_sensitivity.shape == (run.t.size, len(names), run.q.shape[1])
    for j, p in enumerate(params):
        reference = _central(shell, p, (0.0, 0.6), **SHELL_RUN)
        assert _relative_error(reference, run.q_sensitivity[:, j]) < 1e-6, p.name


def test_sensitivities_with_relative_damping_by_central_differences_of_the_stages():
    """Rods damped relative to the rigid motion, which the analytic tangent does not cover:
    the run takes the stages' derivatives by central differences
    (``sensitivity.directional``), within 1e-6 of the differences of whole runs."""
    free = class1_shell(3, 1)  # (on supports, relative damping acts to ground: alpha)
    shell = free.replace(
        tendon_stiffness=np.full(free.n_tendons, 120.0),
        tendon_damping=np.full(free.n_tendons, 0.8),
        rod_relative_damping=np.full(free.n_rods, 0.5),
    )
    params = [parameter(shell, "tendon_stiffness"), parameter(shell, "rod_mass")]
    options = {"external_force": _push(), "sample_dt": 0.02, **TIGHT}
    run = simulate(shell, (0.0, 0.3), sensitivity=params, **options)
    assert run.nswitches > 0
    for j, p in enumerate(params):
        reference = _central(shell, p, (0.0, 0.3), **options)
        assert _relative_error(reference, run.q_sensitivity[:, j]) < 1e-6, p.name


def test_sensitivities_with_a_control_table_through_slack_switches():
    """Rest lengths that change along the run (a control table: the events' indicators move
    with time as well as with the state, and the stages read 16 rows of inputs): the damped
    shell's stiffness and rest-length sensitivities within 1e-6 of the differences."""
    shell = _shell()
    control = ControlTable(
        time=[0.0, 0.2, 0.4], control=np.outer([0.0, 0.02, -0.01], np.ones(shell.n_tendons))
    )
    options = {**SHELL_RUN, "control": control}
    params = [parameter(shell, "tendon_stiffness"), parameter(shell, "tendon_rest_length")]
    run = simulate(shell, (0.0, 0.4), sensitivity=params, **options)
    assert run.nswitches > 5
    for j, p in enumerate(params):
        reference = _central(shell, p, (0.0, 0.4), **options)
        assert _relative_error(reference, run.q_sensitivity[:, j]) < 1e-6, p.name


@dataclasses.dataclass(frozen=True)
class ControlEntries:
    """A parameter of the control table: its entries ``knot * S + tendon``."""

    members: tuple[int, ...]
    kind: str = "control"
    name: str = "control"


def test_sensitivities_to_the_control_tables_values_through_slack_switches():
    """The values of a control table as parameters (what a trajectory optimisation moves): one
    knot for every tendon, and one entry alone, through the shell's slack switches; each moves
    the rest lengths and their rates where the interpolation weighs it (the last knot holds
    after the table's end).  Within 1e-6 of whole runs with the table's values moved.  The runs
    at rtol 1e-13: the table's knots are kinks of the inputs inside steps, where the derivative
    at fixed steps and differences of adaptive runs part by about the tolerance (measured for
    the single entry: 2.4e-6 at rtol 1e-12, 4e-8 at 1e-13)."""
    shell = _shell()
    S = shell.n_tendons
    time = np.array([0.0, 0.15, 0.3])
    values = np.outer([0.0, 0.02, -0.01], np.linspace(0.5, 1.5, S))  # (each tendon its own)
    options = {**SHELL_RUN, "rtol": 1e-13, "control": ControlTable(time=time, control=values)}
    params = [ControlEntries(tuple(S + np.arange(S))), ControlEntries((2 * S + 4,))]
    run = simulate(shell, (0.0, 0.4), sensitivity=params, **options)
    assert run.nswitches > 5
    for j, p in enumerate(params):
        moved = np.zeros(values.size)
        moved[list(p.members)] = STEP
        up, down = (
            simulate(
                shell,
                (0.0, 0.4),
                **{
                    **options,
                    "control": ControlTable(
                        time=time, control=values + sign * moved.reshape(values.shape)
                    ),
                },
            )
            for sign in (1.0, -1.0)
        )
        reference = (up.q - down.q) / (2 * STEP)
        assert _relative_error(reference, run.q_sensitivity[:, j]) < 1e-6, p.members


def test_sensitivities_to_a_point_mass():
    """The six-bar robot's payload (a point mass held by 12 cables) thrown sideways in free
    flight: the payload's mass, the cables' stiffness and the bars' mass within 1e-6 of the
    differences."""
    robot = six_bar_robot(payload_mass=0.4)
    payload = robot.point_mass_nodes[0]
    v = np.zeros_like(robot.node_position)
    v[payload] = [0.8, 0.3, 0.0]
    start = State(0.0, initial_state(robot).q, coordinates_from_nodes(robot, v))
    options = {"initial": start, "gravity": GRAVITY, "sample_dt": 0.02, **TIGHT}
    params = [
        parameter(robot, "point_mass"),
        parameter(robot, "tendon_stiffness"),
        parameter(robot, "rod_mass"),
    ]
    run = simulate(robot, (0.0, 0.3), sensitivity=params, **options)
    for j, p in enumerate(params):
        reference = _central(robot, p, (0.0, 0.3), **options)
        assert _relative_error(reference, run.q_sensitivity[:, j]) < 1e-6, p.name


def test_the_gradient_of_a_loss_of_the_trajectory():
    """``L = sum over samples of |q - q_target|^2 / 2 + |qdot|^2 / 2``: its gradient in the
    rod masses and tendon stiffness against central differences of ``L``."""
    shell = _shell()
    params = [parameter(shell, "rod_mass"), parameter(shell, "tendon_stiffness")]
    run = simulate(shell, (0.0, 0.3), sensitivity=params, **SHELL_RUN)
    target = run.q[0]

    def loss(result):
        return 0.5 * np.sum((result.q - target) ** 2) + 0.5 * np.sum(result.qdot**2)

    gradient = run.gradient(run.q - target, run.qdot)
    for j, p in enumerate(params):
        value = float(np.mean(getattr(shell, p.field)))
        h = STEP * value
        up, down = (
            simulate(p.apply(shell, v), (0.0, 0.3), **SHELL_RUN) for v in (value + h, value - h)
        )
        assert abs(gradient[j] - (loss(up) - loss(down)) / (2 * h)) < 1e-6 * abs(gradient[j])


@dataclasses.dataclass(frozen=True)
class PlaneParameter:
    kind: str
    members: tuple[int, ...] = ()

    @property
    def name(self) -> str:
        return self.kind


def _robot_run(
    friction: float = 0.5, kinetic: float = 0.4, stiffness: float = 1e5, damping: float = 100.0
) -> dict:
    robot = three_bar_robot(stiffness=300.0, tension=20.0)
    robot = robot.replace(node_position=robot.node_position + np.array([0.0, 0.0, 0.01]))
    v = np.zeros_like(robot.node_position)
    v[:, 0] = 1.5
    start = State(0.0, initial_state(robot).q, coordinates_from_nodes(robot, v))
    return {
        "initial": start,
        "gravity": GRAVITY,
        "ground": ground(
            friction=friction, kinetic_friction=kinetic, stiffness=stiffness, damping=damping
        ),
        "sample_dt": 0.02,
        **TIGHT,
    }


def _check_plane_parameters(structure, span, options_of, plane, run, params) -> None:
    """The ground's parameters, the last ``len(plane)`` of ``params`` (their values ``plane``):
    ``run``'s sensitivities to them within 1e-4 of central differences of runs with the options
    ``options_of(*plane)`` made for the moved values."""
    plane = np.asarray(plane, dtype=float)
    first = len(params) - plane.size
    for j in range(plane.size):
        h = np.zeros(plane.size)
        h[j] = STEP * plane[j]
        up = simulate(structure, span, **options_of(*(plane + h)))
        down = simulate(structure, span, **options_of(*(plane - h)))
        reference = (up.q - down.q) / (2 * h[j])
        error = _relative_error(reference, run.q_sensitivity[:, first + j])
        assert error < 1e-4, params[first + j].kind


def test_sensitivities_through_touch_downs_lift_offs_sticks_and_slips():
    """The three-bar robot dropped 1 cm onto the ground sliding at 1.5 m/s for 1 s: it
    bounces, slides, sticks and slips again (30 located contact events).  Cable stiffness,
    rod mass, the ground's static and kinetic friction, contact stiffness and damping within
    1e-4 of the differences (measured: 1e-5)."""
    robot = three_bar_robot(stiffness=300.0, tension=20.0)
    options = _robot_run()
    params = [
        parameter(robot, "tendon_stiffness"),
        parameter(robot, "rod_mass"),
        PlaneParameter("friction"),
        PlaneParameter("kinetic_friction"),
        PlaneParameter("contact_stiffness"),
        PlaneParameter("contact_damping"),
    ]
    run = simulate(robot, (0.0, 1.0), sensitivity=params, **options)
    modes = {tuple(m) for m in run.contact_event_mode.tolist()}
    assert {(0, 1), (1, 0), (1, 2), (2, 1)} <= modes  # touch-down, lift-off, stick, slip
    for j, p in enumerate(params[:2]):
        reference = _central(robot, p, (0.0, 1.0), **options)
        assert _relative_error(reference, run.q_sensitivity[:, j]) < 1e-4, p.name
    _check_plane_parameters(robot, (0.0, 1.0), _robot_run, [0.5, 0.4, 1e5, 100.0], run, params)


def _sled_run(friction: float = 0.5, kinetic: float = 0.4) -> dict:
    """A point mass on the ground between two anchors (a sled on two springs), started sliding
    sideways and pushed along y by a force growing at 4 N/s: its run's options."""
    start = State(0.0, np.array([0.3, 0.2, 0.0]), np.array([0.0, 1.2, 0.0]))
    plane = ground(friction=friction, kinetic_friction=kinetic, stiffness=1e5, damping=50.0)
    push = np.zeros((2, 3, 3))
    push[1, 2, 1] = 4.0 * SLED_SPAN[1]
    return {
        "initial": start,
        "gravity": GRAVITY,
        "ground": plane,
        "external_force": ForceTable(time=np.array(SLED_SPAN), force=push),
        "sample_dt": 0.02,
        **TIGHT,
    }


#: The sled's run [s]: it slides to and fro, sticks (at 1.32 s) and slips again (at 1.57 s).
SLED_SPAN = (0.0, 2.0)


def _sled(mass: float = 0.3, stiffness: float = 20.0) -> Structure:
    return Structure(
        node_position=[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.3, 0.2, 0.0]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_fixed=[True, True, False],
        node_point_mass=[0.0, 0.0, mass],
        tendon_nodes=[[0, 2], [2, 1]],
        tendon_stiffness=[stiffness, 1.5 * stiffness],
        tendon_rest_length=[0.9, 0.9],
    )


def test_sensitivities_of_a_point_mass_sliding_and_sticking_on_the_ground():
    """The sled pressed on the ground by gravity slides to and fro, sticks, and slips again as
    the push grows: its mass (which the contacts hold a copy of: the sticking force is ``m``
    times the acceleration it cancels), a spring's stiffness and both friction coefficients
    within 1e-4 of the differences."""
    sled = _sled()
    options = _sled_run()
    params = [
        parameter(sled, "point_mass"),
        parameter(sled, "tendon_stiffness:s1"),
        PlaneParameter("friction"),
        PlaneParameter("kinetic_friction"),
    ]
    run = simulate(sled, SLED_SPAN, sensitivity=params, **options)
    assert run.status == 0, run.message
    assert run.contact_counts == {"touch_down": 1, "lift_off": 0, "slip": 1, "stick": 1}
    for j, p in enumerate(params[:2]):
        reference = _central(sled, p, SLED_SPAN, **options)
        assert _relative_error(reference, run.q_sensitivity[:, j]) < 1e-4, p.name
    _check_plane_parameters(sled, SLED_SPAN, _sled_run, [0.5, 0.4], run, params)


def test_bad_sensitivity_requests_are_refused_in_one_line():
    shell = _shell()
    cases = [
        (PlaneParameter("tendon_colour", (0,)), "has kind 'tendon_colour'"),
        (PlaneParameter("rod_mass", (6,)), r"members must be rod indices in 0..5, got \[6\]"),
        (PlaneParameter("friction"), "the run has no ground planes"),
        (PlaneParameter("control", (0,)), "the run has no control table"),
        (PlaneParameter("point_mass", (0,)), r"members must be nodes with a point mass \(\[\]\)"),
    ]
    for p, message in cases:
        with pytest.raises(ValueError, match=message):
            simulate(shell, (0.0, 0.01), sensitivity=[p])
    mass = [parameter(shell, "rod_mass")]
    with pytest.raises(ValueError, match="method='DOP853' only"):
        simulate(shell, (0.0, 0.01), method="RK45", sensitivity=mass)
    with pytest.raises(ValueError, match="locating its events"):
        simulate(shell, (0.0, 0.01), locate_switches=False, sensitivity=mass)
    table = ControlTable(time=np.array([0.0, 1.0]), control=np.zeros((2, shell.n_tendons)))
    with pytest.raises(ValueError, match=r"other inputs as tables too \(its external force"):
        simulate(
            shell,
            (0.0, 0.01),
            control=table,
            external_force=lambda t: np.zeros((shell.n_nodes, 3)),
            sensitivity=[PlaneParameter("control", (0,))],
        )


def test_the_start_and_damping_from_zero_through_contact():
    """The robot's run: d/d(its start's sliding speed) against differences of the start,
    positions and velocities of the nodes; d/d(damping) at zero (the records carry zero
    damping that can move) against one-sided second-order differences (damping cannot go
    below 0).  (The speed of all three rods together: the robot lands on three ends at once,
    and a perturbation that broke that symmetry would part the three events, which share one
    event time here: ``docs/sensitivity.md``.)"""
    robot = three_bar_robot(stiffness=300.0, tension=20.0)
    options = _robot_run()
    start = options.pop("initial")
    n = start.q.size
    index = [0, 6, 12]  # each rod's q1_x rate (q1 = p_a + p_b: free of the rod's constraint)
    params = [StateComponent(tuple(n + i for i in index)), parameter(robot, "tendon_damping")]
    run = simulate(robot, (0.0, 0.5), initial=start, sensitivity=params, **options)
    h = 1e-4
    moved = []
    for sign in (1, -1):
        qdot = start.qdot.copy()
        qdot[index] += sign * h
        moved.append(simulate(robot, (0.0, 0.5), initial=State(0.0, start.q, qdot), **options))
    assert _relative_error((moved[0].q - moved[1].q) / (2 * h), run.q_sensitivity[:, 0]) < 1e-4
    for name in ("node_position", "node_velocity"):
        reference = (getattr(moved[0], name) - getattr(moved[1], name)) / (2 * h)
        derivative = getattr(run, f"{name}_sensitivity")()
        assert derivative.shape == (run.t.size, 2, robot.n_nodes, 3)
        assert _relative_error(reference, derivative[:, 0]) < 1e-4, name
    p = params[1]
    q1, q2 = (
        simulate(p.apply(robot, c), (0.0, 0.5), initial=start, **options).q for c in (h, 2 * h)
    )
    reference = (-3 * run.q + 4 * q1 - q2) / (2 * h)
    assert _relative_error(reference, run.q_sensitivity[:, 1]) < 1e-4  # (the O(h^2) of it)


def test_the_run_with_sensitivities_is_the_same_run():
    """Samples, steps, switches, tensions and contact events identical with and without the
    sensitivities (whose differences move the records and the scratch in place)."""
    shell = _shell()
    robot = three_bar_robot(stiffness=300.0, tension=20.0)
    kinds = ["tendon_stiffness", "tendon_damping", "tendon_rest_length", "rod_mass"]
    cases = [
        (shell, SHELL_RUN, [parameter(shell, k) for k in kinds]),
        (robot, _robot_run(), [parameter(robot, k) for k in kinds]
         + [PlaneParameter(k) for k in ("friction", "kinetic_friction", "contact_stiffness")]),
    ]  # fmt: skip
    for structure, options, params in cases:
        plain = simulate(structure, (0.0, 0.5), **options)
        run = simulate(structure, (0.0, 0.5), sensitivity=params, **options)
        for name in ("q", "qdot", "tendon_tension", "contact_event_time", "switch_times"):
            np.testing.assert_array_equal(getattr(run, name), getattr(plain, name), err_msg=name)
        assert (run.nsteps, run.nfev) == (plain.nsteps, plain.nfev)
        assert plain.q_sensitivity is None
    with pytest.raises(ValueError, match="q_sensitivity: the run integrated no sensitivities"):
        plain.node_position_sensitivity()
