"""The right-hand side's analytic tangent (:mod:`tensegrity.engine.tangent`) against central
differences of the right-hand side itself: ``f_y V + f_p`` for random directions ``V``, each
parameter moved in the model's arrays by this file's own code, on every pass the tangent has
(tendons with damping, rods with gravity and external forces, supports, point masses, the
ground's normal law, kinetic friction and sticking points)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tensegrity.design.catalogue import six_bar_robot, three_bar_robot
from tensegrity.engine.compiled import ode_rhs_entry
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.sensitivity import prepare, stage_tangent_entry
from tensegrity.engine.system import CompiledSystem
from tensegrity.model.ground import FREE, SLIP, STICK, ground
from tensegrity.model.loads import ControlTable
from tensegrity.model.shell import class1_shell
from tensegrity.model.structure import Structure
from tensegrity.physics.compiling import ROD_C1, ROD_C2, ROD_LENGTH, ROD_MASS
from tensegrity.physics.dynamics import initial_state

GRAVITY = np.array([0.0, 0.0, -9.81])
#: The central differences' step, relative to each parameter's scale.
STEP = 1e-6


@dataclasses.dataclass(frozen=True)
class Param:
    """A parameter as :func:`tensegrity.engine.sensitivity.prepare` takes it."""

    kind: str
    members: tuple[int, ...] = (0,)
    scale: float = 1.0  #: its size, for the step [its unit]

    @property
    def name(self) -> str:
        return self.kind


def _move(system: CompiledSystem, p: Param, h: float) -> None:
    """Parameter ``p`` moved by ``h`` in ``system``'s records (this file's own code)."""
    model, data = system.model, system.data
    members = np.asarray(p.members)
    if p.kind in ("tendon_stiffness", "tendon_damping"):
        getattr(model, p.kind)[system.tendon_position[members]] += h
    elif p.kind == "tendon_rest_length":
        data.rest[:, system.tendon_position[members]] += h
    elif p.kind == "rod_mass":
        rod = model.rod_param[members]
        rod[:, ROD_MASS] += h
        rod[:, ROD_C1] = 2.0 / rod[:, ROD_MASS]
        rod[:, ROD_C2] = 6.0 / (rod[:, ROD_MASS] * rod[:, ROD_LENGTH] ** 2)
        model.rod_param[members] = rod
    elif p.kind == "point_mass":
        k = np.searchsorted(system.structure.point_mass_nodes, members)
        model.constraints.point_mass[k] += h
        if model.contacts is not None:
            model.contacts.point_mass[2 * system.structure.n_rods + k] += h
    elif p.kind in ("contact_stiffness", "contact_damping", "kinetic_friction"):
        field = {"kinetic_friction": "friction_kinetic"}.get(p.kind, p.kind)
        getattr(model.contacts, field)[:] += h
    else:
        assert p.kind == "initial_state"


def _rhs(system: CompiledSystem, y: np.ndarray) -> np.ndarray:
    out = np.empty_like(y)
    ode_rhs_entry(system.model, system.data, np.int64(0), y, out)
    return out


def _directions(params: list[Param], y: np.ndarray, seed: int) -> np.ndarray:
    """Random directions (P, m) of the state's size over each parameter's scale."""
    rng = np.random.default_rng(seed)
    n = (y.size - 3) // 2
    V = np.zeros((len(params), y.size))
    for j, p in enumerate(params):
        V[j, : 2 * n] = rng.normal(size=2 * n) * np.abs(y[: 2 * n]).max() / p.scale
    return V


def _tangent(system, params, y, V, side=None) -> np.ndarray:
    """The tangent (P, m) at ``y`` along ``V``, the tendons taut where ``side`` says (as the
    evaluation at ``y`` finds them: None); the records as they were after it."""
    sens = prepare(system, params, y)
    f = _rhs(system, y)
    sens.tangent.direction[:] = V
    side = system.data.tension > 0.0 if side is None else side
    stage_tangent_entry(system.model, system.data, np.int64(0), sens, side, y)
    assert np.array_equal(_rhs(system, y), f)
    return sens.K[:, 0].copy()


def _check(system: CompiledSystem, params: list[Param], y: np.ndarray, seed: int = 0) -> None:
    """The tangent at ``y`` along random directions against central differences, each
    direction's rows of ``q'``, ``q''`` and the three powers within 1e-6 of its largest."""
    m, n = y.size, (y.size - 3) // 2
    V = _directions(params, y, seed)
    tangents = _tangent(system, params, y, V)
    for j, p in enumerate(params):
        h = STEP * p.scale
        _move(system, p, h)
        up = _rhs(system, y + h * V[j])
        _move(system, p, -2.0 * h)
        down = _rhs(system, y - h * V[j])
        _move(system, p, h)
        reference = (up - down) / (2.0 * h)
        tangent = tangents[j]
        for rows in (slice(0, n), slice(n, 2 * n), slice(2 * n, m)):
            scale = np.abs(reference[rows]).max()
            assert np.abs(tangent[rows] - reference[rows]).max() <= 1e-6 * scale, (p.kind, rows)


def test_a_tendon_a_round_off_short_of_its_switch_is_taken_on_the_steps_side():
    """A state landed on a slack/taut switch may sit a round-off short of it: the step's side
    (taut) rules, and the tangent there is the taut tendon's, as 2e-12 m further on."""
    shell = class1_shell(3, 1, fixed_base=True)
    ends = shell.node_position[shell.tendon_nodes]
    length = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)
    y = _state(shell, np.random.default_rng(7), 0.0, 0.2)
    params = [Param("tendon_stiffness", (4,), 1.0), Param("tendon_rest_length", (4,), 0.1)]
    V = _directions(params, y, seed=8)
    tangents = []
    for stretch in (-1e-12, 1e-12):
        rest = shell.tendon_rest_length.copy()
        rest[4] = length[4] - stretch
        moved = shell.replace(tendon_rest_length=rest)
        system = CompiledSystem(moved, Inputs(moved, gravity=GRAVITY))
        taut = np.ones(shell.n_tendons, bool)
        tangents.append(_tangent(system, params, y, V, taut))
    n = (y.size - 3) // 2
    short, on = tangents[0][:, n : 2 * n], tangents[1][:, n : 2 * n]
    assert np.abs(short - on).max() <= 1e-6 * np.abs(on).max()


def _state(structure: Structure, rng: np.random.Generator, moved: float, speed: float):
    """``y = [q, q', 0, 0, 0]`` of ``structure`` moved off its positions by ``moved`` [m] and
    with velocities of ``speed`` [m/s], both random."""
    start = initial_state(structure)
    q = start.q + moved * rng.normal(size=start.q.size)
    return np.concatenate([q, speed * rng.normal(size=q.size), np.zeros(3)])


def test_the_tangent_of_a_damped_shell_on_supports_under_gravity_and_a_push():
    shell = class1_shell(3, 1, fixed_base=True)
    rest = shell.tendon_rest_length.copy()
    rest[[3, 9, 15]] *= 3.0  # (slack)
    ends = shell.node_position[shell.tendon_nodes]
    near = [0, 6, 7, 12, 13, 18, 19, 21]  # (stretched 0.2 mm: some held at zero by damping)
    rest[near] = np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1)[near] - 2e-4
    shell = shell.replace(
        tendon_rest_length=rest,
        tendon_stiffness=np.full(shell.n_tendons, 120.0),
        tendon_damping=np.full(shell.n_tendons, 0.8),
        rod_mass=np.full(shell.n_rods, 1.3),
        rod_damping=np.full(shell.n_rods, 0.3),
    )
    push = np.zeros((shell.n_nodes, 3))
    push[11] = [5.0, -2.0, 1.0]
    system = CompiledSystem(shell, Inputs(shell, gravity=GRAVITY, external_force=push))
    y = _state(shell, np.random.default_rng(1), 1e-5, 0.2)
    params = [
        Param("tendon_stiffness", tuple(range(0, shell.n_tendons, 2)), 120.0),
        Param("tendon_damping", (1, 4, 7), 0.8),
        Param("tendon_rest_length", (2, 5), 0.5),
        Param("rod_mass", (0, 2), 1.3),
        Param("initial_state", (3,)),
    ]
    _rhs(system, y)
    tension, elastic = system.data.tension, system.data.elastic_tension
    assert np.any(tension > 0.0) and np.any(elastic == 0.0)  # (taut, and slack)
    assert np.any((tension == 0.0) & (elastic > 0.0))  # (stretched, held at zero by damping)
    _check(system, params, y)


def test_the_tangent_of_a_robot_with_a_point_mass():
    robot = six_bar_robot(payload_mass=0.4)
    push = np.zeros((robot.n_nodes, 3))
    push[robot.point_mass_nodes[0]] = [1.0, -0.5, 2.0]
    push[0] = [0.0, 3.0, 0.0]
    system = CompiledSystem(robot, Inputs(robot, gravity=GRAVITY, external_force=push))
    y = _state(robot, np.random.default_rng(2), 1e-3, 0.3)
    params = [
        Param("point_mass", tuple(robot.point_mass_nodes), 0.4),
        Param("tendon_stiffness", tuple(range(robot.n_tendons)), float(robot.tendon_stiffness[0])),
        Param("rod_mass", tuple(range(robot.n_rods)), float(robot.rod_mass[0])),
    ]
    _check(system, params, y)


@pytest.mark.parametrize("stuck", [False, True], ids=["slipping", "one-end-sticking"])
def test_the_tangent_of_a_robot_on_the_ground(stuck: bool):
    """The three-bar robot pressed 1 mm into the ground: of its ends on the ground, two slip
    (each its own way) or one sticks and one slips, and one is free (lifting off: no force,
    but its spring's energy still counts)."""
    robot = three_bar_robot(stiffness=300.0, tension=20.0, damping=2.0)
    plane = ground(friction=0.5, kinetic_friction=0.4, stiffness=1e5, damping=100.0)
    lowered = robot.node_position[:, 2].min() + 1e-3
    robot = robot.replace(node_position=robot.node_position - [0.0, 0.0, lowered])
    system = CompiledSystem(robot, Inputs(robot, gravity=GRAVITY, ground=plane))
    y = _state(robot, np.random.default_rng(3), 1e-5, 0.2)
    work = system.data.contact_work
    touching = np.flatnonzero(robot.node_position[:, 2] < 0.0)
    assert touching.size == 3
    for i, node in enumerate(touching):
        k = _contact_point(robot, node)
        work.mode[k] = (STICK if stuck else SLIP, SLIP, FREE)[i]
        angle = 2.0 * np.pi * i / 3.0
        work.slip_direction[k] = [np.cos(angle), np.sin(angle), 0.0]
    params = [
        Param("contact_stiffness", (0,), 1e5),
        Param("contact_damping", (0,), 100.0),
        Param("kinetic_friction", (0,), 0.4),
        Param("rod_mass", (0, 1), 1.0),
        Param("tendon_stiffness", (0, 4), 300.0),
        Param("initial_state", (10,)),
    ]
    _check(system, params, y)


def _contact_point(structure: Structure, node: int) -> int:
    """The contact point of a rod's end node: ``2 r + end``."""
    r, end = np.argwhere(structure.rod_nodes == node)[0]
    return int(2 * r + end)


def test_the_tangent_of_a_sticking_point_mass():
    """A point mass between two anchors pressed into the ground, sticking."""
    sled = Structure(
        node_position=[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.3, 0.2, -1e-4]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_fixed=[True, True, False],
        node_point_mass=[0.0, 0.0, 0.3],
        tendon_nodes=[[0, 2], [2, 1]],
        tendon_stiffness=[20.0, 30.0],
        tendon_rest_length=[0.9, 0.9],
    )
    plane = ground(friction=0.5, kinetic_friction=0.4, stiffness=1e5, damping=50.0)
    system = CompiledSystem(sled, Inputs(sled, gravity=GRAVITY, ground=plane))
    y = np.array([0.3, 0.2, -1e-4, 1e-3, -2e-3, 0.05, 0.0, 0.0, 0.0])
    system.data.contact_work.mode[0] = STICK
    params = [
        Param("point_mass", (2,), 0.3),
        Param("tendon_stiffness", (0,), 20.0),
        Param("contact_stiffness", (0,), 1e5),
    ]
    _check(system, params, y)


def test_the_tangent_of_a_rod_lying_with_both_ends_stuck():
    """A rod lying on the ground, pulled sideways by a cable from an anchor, both ends
    sticking: its ends' forces along its axis move nothing (the sticking solve drops that
    direction, tilted 1e-4 rad: an eigenvalue 1e-8 of the largest)."""
    rod = Structure(
        node_position=[[0.0, 0.0, -1e-4], [1.0, 0.0, -2e-4], [0.2, 0.8, 0.3]],
        rod_nodes=[[0, 1]],
        rod_mass=[0.7],
        rod_length=[float(np.hypot(1.0, 1e-4))],
        node_fixed=[False, False, True],
        tendon_nodes=[[2, 1]],
        tendon_stiffness=[50.0],
        tendon_rest_length=[0.7],
    )
    plane = ground(friction=0.5, kinetic_friction=0.4, stiffness=1e5, damping=50.0)
    system = CompiledSystem(rod, Inputs(rod, gravity=GRAVITY, ground=plane))
    y = _state(rod, np.random.default_rng(4), 0.0, 1e-3)
    system.data.contact_work.mode[:2] = STICK
    params = [
        Param("rod_mass", (0,), 0.7),
        Param("tendon_stiffness", (0,), 50.0),
        Param("contact_stiffness", (0,), 1e5),
        Param("initial_state", (4,)),
    ]
    _check(system, params, y)


def test_the_tangent_of_a_control_tables_values_and_their_work():
    """A control table moving rest lengths at the time of a stage: an entry's value moves the
    rest length by its weight there and the rate by its slope (``W_u' = sum T_el u'``);
    the references are the right-hand sides of systems made with the table moved."""
    shell = class1_shell(3, 1, fixed_base=True)
    shell = shell.replace(tendon_damping=np.full(shell.n_tendons, 0.5))
    S = shell.n_tendons
    control = np.zeros((3, S))
    control[1, :6] = [0.02, -0.01, 0.03, 0.0, 0.01, -0.02]
    control[2, :6] = [0.04, 0.01, -0.02, 0.03, 0.0, 0.01]
    time = np.array([0.0, 0.5, 1.0])
    t = 0.3

    def stage(values: np.ndarray) -> tuple[CompiledSystem, object]:
        system = CompiledSystem(shell, Inputs(shell, control=ControlTable(time, values)))
        return system, system.stage_inputs(np.array([t]))

    system, data = stage(control)
    assert data.has_rate
    y = _state(shell, np.random.default_rng(5), 1e-5, 0.1)
    entries = [(1, 0), (1, 2), (2, 4)]  # (knot, tendon)
    params = [Param("control", (knot * S + e,), 0.01) for knot, e in entries]
    params.append(Param("tendon_stiffness", (0, 2, 4), float(shell.tendon_stiffness[0])))
    sens = prepare(system, params, y)
    sens.stage_time[0] = t
    rng = np.random.default_rng(6)
    V = rng.normal(size=(len(params), y.size)) * 0.1
    V[:, -3:] = 0.0
    out = np.empty_like(y)
    ode_rhs_entry(system.model, data, np.int64(0), y, out)
    sens.tangent.direction[:] = V
    stage_tangent_entry(system.model, data, np.int64(0), sens, data.tension > 0.0, y)
    for j, p in enumerate(params):
        h = STEP * p.scale
        moved = []
        for sign in (1.0, -1.0):
            if p.kind == "control":
                values = control.copy()
                knot, e = entries[j]
                values[knot, e] += sign * h
                other, other_data = stage(values)
                model = other.model
            else:
                model, other_data = system.model, data
                model.tendon_stiffness[system.tendon_position[list(p.members)]] += sign * h
            ode_rhs_entry(model, other_data, np.int64(0), y + sign * h * V[j], out)
            moved.append(out.copy())
            if p.kind != "control":
                model.tendon_stiffness[system.tendon_position[list(p.members)]] -= sign * h
        reference = (moved[0] - moved[1]) / (2.0 * h)
        n = (y.size - 3) // 2
        for rows in (slice(n, 2 * n), slice(2 * n, y.size)):
            scale = np.abs(reference[rows]).max()
            assert scale > 0.0
            assert np.abs(sens.K[j, 0, rows] - reference[rows]).max() <= 1e-6 * scale, (p, rows)
