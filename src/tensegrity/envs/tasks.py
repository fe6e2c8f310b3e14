"""The tasks (:class:`Locomotion`, :class:`ShapeTracking`, :class:`PayloadHold`) and the
registered environments built on them (``docs/environments.md``): :func:`six_bar_roll`,
:func:`three_bar_crawl`, :func:`shell_shape`, :func:`payload_hold`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.shape_control import ShapeOutput, height_twist, shell_rings
from tensegrity.design.catalogue import actuated_cables, six_bar_robot, three_bar_robot
from tensegrity.design.rolling import STANDARD_GRAVITY, stand_on_face
from tensegrity.envs.base import Motion, TensegrityEnv
from tensegrity.model.actuators import actuators
from tensegrity.model.ground import ground
from tensegrity.model.shell import class1_shell
from tensegrity.model.structure import Structure

__all__ = [
    "Locomotion",
    "PayloadHold",
    "ShapeTracking",
    "payload_hold",
    "shell_shape",
    "six_bar_roll",
    "three_bar_crawl",
]

#: The robots' scene: contact radius of the bars' ends [m], static and kinetic friction.
CONTACT_RADIUS, FRICTION, KINETIC_FRICTION = 0.01, 0.8, 0.6
#: Gravity of the robots' scenes [m/s^2].
GRAVITY = (0.0, 0.0, -STANDARD_GRAVITY)
#: The actuated cables' largest rate of rest length [m/s] and their drive's lag [s] (a winch
#: reeling at 10 cm/s behind a 20 ms filter, of the order of the published robots' motors).
CABLE_RATE, CABLE_LAG = 0.1, 0.02
#: The six-bar robot's cables: stiffness [N/m] and prestress tension [N], those of
#: ``examples/rolling_six_bar.py``.  With the catalogue's defaults (100 N/m, 5 N) the 6 kg robot
#: does not stand: it sags until the ends of all six bars touch the ground (within 0.8 s), its
#: contacts stick and slip every few microseconds and a 20 ms period took up to 9,159 steps.
SIX_BAR_STIFFNESS, SIX_BAR_TENSION = 2000.0, 100.0


@dataclasses.dataclass
class Locomotion:
    """Move the centre of mass along ``heading`` (an angle [rad] from ``x`` on the ground).

    Reward: the centre of mass's mean speed along the heading over the period [m/s].  Never
    terminates (episodes end by their time limit).
    """

    node_mass: np.ndarray  #: (N,) [kg]
    heading: float = 0.0

    def start(self, nodes: np.ndarray) -> None:
        """Nothing to remember."""

    def reward(self, motion: Motion) -> float:
        direction = np.array([math.cos(self.heading), math.sin(self.heading)])
        moved = self.node_mass @ (motion.after - motion.before) / self.node_mass.sum()
        return float(moved[:2] @ direction / motion.period)

    def terminated(self, motion: Motion) -> bool:
        return False


@dataclasses.dataclass
class ShapeTracking:
    """Bring ``output`` (e.g. :func:`~tensegrity.analysis.shape_control.height_twist`) to
    ``target``.

    Reward: ``-sum(((y - target) / scale)**2)`` at the period's end (``scale``: the outputs'
    units of error).  Never terminates.
    """

    output: ShapeOutput
    target: np.ndarray
    scale: np.ndarray

    def start(self, nodes: np.ndarray) -> None:
        """Nothing to remember."""

    def reward(self, motion: Motion) -> float:
        error = (self.output.value(motion.after) - self.target) / self.scale
        return -float(error @ error)

    def terminated(self, motion: Motion) -> bool:
        return False


@dataclasses.dataclass
class PayloadHold:
    """Keep the node ``payload`` still.

    Reward: ``-|v|^2`` [m^2/s^2], its speed at the period's end.  Terminates when it has moved
    more than ``radius`` [m] from where the episode started.
    """

    payload: int
    radius: float = 0.2
    origin: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(3))

    def start(self, nodes: np.ndarray) -> None:
        self.origin = nodes[self.payload].copy()

    def reward(self, motion: Motion) -> float:
        v = motion.velocity[self.payload]
        return -float(v @ v)

    def terminated(self, motion: Motion) -> bool:
        return bool(np.linalg.norm(motion.after[self.payload] - self.origin) > self.radius)


def _cables(structure: Structure, names: Any, change: float) -> Any:
    """Actuators on the cables ``names``, rest lengths within ``1 -+ change`` of their own,
    moving at most :data:`CABLE_RATE` behind a lag of :data:`CABLE_LAG`."""
    index = [structure.tendon_index(n) for n in names]
    rest = structure.tendon_rest_length[index]
    return actuators(
        structure,
        index,
        min_rest_length=(1 - change) * rest,
        max_rest_length=(1 + change) * rest,
        max_rate=CABLE_RATE,
        time_constant=CABLE_LAG,
    )


def _on_ground(structure: Structure, task: Any, change: float, **options: Any) -> TensegrityEnv:
    """``structure`` (standing on ``z = CONTACT_RADIUS``) with its actuated cables, on the
    ground, under gravity."""
    return TensegrityEnv(
        structure,
        task,
        _cables(structure, actuated_cables(structure), change),
        gravity=GRAVITY,
        ground=ground(friction=FRICTION, kinetic_friction=KINETIC_FRICTION),
        contact_radius=CONTACT_RADIUS,
        **options,
    )


def six_bar_roll(
    *, heading: float = 0.0, change: float = 0.4, damping: float = 1.0, **options: Any
) -> TensegrityEnv:
    """The six-bar robot (:func:`~tensegrity.design.catalogue.six_bar_robot` with cables of
    :data:`SIX_BAR_STIFFNESS` at :data:`SIX_BAR_TENSION`, cable damping ``damping`` [N s/m]),
    its 24 shell cables actuated with rest lengths within ``1 -+ change`` of their own,
    standing on its face ``f---`` on the ground, rewarded for rolling toward ``heading`` [rad]
    (:class:`Locomotion`).  ``options`` go to :class:`~tensegrity.envs.base.TensegrityEnv`."""
    robot = six_bar_robot(stiffness=SIX_BAR_STIFFNESS, tension=SIX_BAR_TENSION, damping=damping)
    robot = stand_on_face(robot, (0, 4, 8), contact_radius=CONTACT_RADIUS)
    return _on_ground(robot, Locomotion(robot.node_mass, heading), change, **options)


def three_bar_crawl(
    *, heading: float = 0.0, change: float = 0.3, damping: float = 1.0, **options: Any
) -> TensegrityEnv:
    """The three-bar robot (:func:`~tensegrity.design.catalogue.three_bar_robot`, its nine
    cables actuated within ``1 -+ change`` of their rest lengths) standing on its bottom ring on
    the ground, rewarded for crawling toward ``heading`` [rad] (:class:`Locomotion`)."""
    robot = three_bar_robot(damping=damping)
    p = robot.node_position
    robot = robot.replace(node_position=p + np.array([0.0, 0.0, CONTACT_RADIUS - p[:, 2].min()]))
    return _on_ground(robot, Locomotion(robot.node_mass, heading), change, **options)


def shell_shape(
    *,
    n: int = 3,
    m: int = 1,
    height: float = 0.8,
    twist: float = 0.0,
    change: float = 0.2,
    damping: float = 1.0,
    **options: Any,
) -> TensegrityEnv:
    """The class 1 shell (:func:`~tensegrity.model.shell.class1_shell`, ``n x m``, free, no
    gravity) at its equilibrium, every tendon actuated within ``1 -+ change`` of its rest
    length, rewarded for bringing its top ring to ``height`` times the equilibrium's height
    above the bottom ring and to ``twist`` [rad] (:class:`ShapeTracking` of
    :func:`~tensegrity.analysis.shape_control.height_twist`, as ``tensegrity control`` does;
    errors scaled by that height and by 1 rad)."""
    shell = class1_shell(n, m, damping=damping)
    shell = shell.replace(node_position=find_equilibrium(shell).node_position)
    output = height_twist(shell.node_position, *shell_rings(n, m))
    h0 = float(output.value(shell.node_position)[0])
    task = ShapeTracking(output, np.array([height * h0, twist]), np.array([h0, 1.0]))
    return TensegrityEnv(shell, task, _cables(shell, shell.tendon_name, change), **options)


def payload_hold(
    *,
    payload_mass: float = 0.5,
    radius: float = 0.2,
    change: float = 0.3,
    damping: float = 1.0,
    **options: Any,
) -> TensegrityEnv:
    """The six-bar robot carrying a point mass ``payload_mass`` [kg] at its centre on 12
    passive cables (:func:`~tensegrity.design.catalogue.six_bar_robot`, shell cables as
    :func:`six_bar_roll`'s), standing on the ground
    with its 24 shell cables actuated within ``1 -+ change``, rewarded for keeping the payload
    still and ended when it strays ``radius`` [m] from its start (:class:`PayloadHold`)."""
    robot = six_bar_robot(
        stiffness=SIX_BAR_STIFFNESS,
        tension=SIX_BAR_TENSION,
        damping=damping,
        payload_mass=payload_mass,
    )
    robot = stand_on_face(robot, (0, 4, 8), contact_radius=CONTACT_RADIUS)
    task = PayloadHold(int(robot.point_mass_nodes[0]), radius)
    return _on_ground(robot, task, change, **options)
