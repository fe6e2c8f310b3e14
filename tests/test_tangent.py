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
from tensegrity.model.ground import SLIP, STICK, ground
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


def _check(system: CompiledSystem, params: list[Param], y: np.ndarray, seed: int = 0) -> None:
    """The tangent at ``y`` along random directions against central differences, each
    direction's rows of ``q'``, ``q''`` and the three powers within 1e-6 of its largest."""
    sens = prepare(system, params, y)
    rng = np.random.default_rng(seed)
    m, n = y.size, (y.size - 3) // 2
    V = np.zeros((len(params), m))
    size = np.abs(y[: 2 * n]).max()
    for j, p in enumerate(params):
        V[j, : 2 * n] = rng.normal(size=2 * n) * size / p.scale
    f = _rhs(system, y)
    side = system.data.tension > 0.0
    sens.tangent.direction[:] = V
    stage_tangent_entry(system.model, system.data, np.int64(0), sens, side, y)
    assert np.array_equal(_rhs(system, y), f)  # (the records as they were)
    for j, p in enumerate(params):
        h = STEP * p.scale
        _move(system, p, h)
        up = _rhs(system, y + h * V[j])
        _move(system, p, -2.0 * h)
        down = _rhs(system, y - h * V[j])
        _move(system, p, h)
        reference = (up - down) / (2.0 * h)
        tangent = sens.K[j, 0]
        for rows in (slice(0, n), slice(n, 2 * n), slice(2 * n, m)):
            scale = np.abs(reference[rows]).max()
            assert np.abs(tangent[rows] - reference[rows]).max() <= 1e-6 * scale, (p.kind, rows)


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
    y = _state(shell, np.random.default_rng(1), 1e-3, 0.2)
    params = [
        Param("tendon_stiffness", tuple(range(0, shell.n_tendons, 2)), 120.0),
        Param("tendon_damping", (1, 4, 7), 0.8),
        Param("tendon_rest_length", (2, 5), 0.5),
        Param("rod_mass", (0, 2), 1.3),
        Param("initial_state", (3,)),
    ]
    _, counts = np.unique(_side(system, y), return_counts=True)
    assert counts.size == 2  # (some tendons slack, some taut)
    _check(system, params, y)


def _side(system: CompiledSystem, y: np.ndarray) -> np.ndarray:
    _rhs(system, y)
    return system.data.tension > 0.0


def test_the_tangent_of_a_robot_with_a_point_mass():
    robot = six_bar_robot(payload_mass=0.4)
    system = CompiledSystem(robot, Inputs(robot, gravity=GRAVITY))
    y = _state(robot, np.random.default_rng(2), 1e-3, 0.3)
    params = [
        Param("point_mass", tuple(robot.point_mass_nodes), 0.4),
        Param("tendon_stiffness", tuple(range(robot.n_tendons)), float(robot.tendon_stiffness[0])),
        Param("rod_mass", tuple(range(robot.n_rods)), float(robot.rod_mass[0])),
    ]
    _check(system, params, y)


@pytest.mark.parametrize("stuck", [False, True], ids=["slipping", "one-end-sticking"])
def test_the_tangent_of_a_robot_on_the_ground(stuck: bool):
    """The three-bar robot pressed 1 mm into the ground: its ends on the ground slip (each
    its own way) or one sticks."""
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
        work.mode[k] = STICK if stuck and i == 0 else SLIP
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
