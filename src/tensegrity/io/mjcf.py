"""Export a structure to MuJoCo's MJCF, to cross-check the dynamics against a peer.

The model written by :func:`to_mjcf` is the same mechanical system as Theorem 18.1:

- **Rod** ``r`` (nodes ``a, b``) is a body ``rod{r}`` with a free joint ``rod{r}`` at the rod's
  centre.  The body's local ``z`` axis points along ``p_b - p_a``; its mass is ``m`` and its
  inertia about the centre is ``diag(m L^2/12, m L^2/12, eps)`` with
  ``eps = SPIN_INERTIA_RATIO * m L^2 / 12`` (but at least ``SPIN_INERTIA_MIN``; see below).
  Sites ``node{a}`` at ``z = -L/2`` and ``node{b}`` at ``z = +L/2`` are its end points, named by
  node index; a capsule geom without contacts shows the rod in a viewer (it has no mass).
- **Tendon** ``s`` is a spatial tendon named ``tendon_name[s]`` from site ``node{tail}`` to site
  ``node{head}`` with ``stiffness="k"``, ``springlength="0 Lbar"`` and ``damping="c"``.  The
  two-value spring length is a deadband: MuJoCo's spring force is ``k (l - Lbar)`` above ``Lbar``
  and exactly 0 between 0 and ``Lbar``, i.e. our ``T = k max(l - Lbar, 0)``.
- **Joints and supports** (``docs/constraints.md``): a ball joint between nodes ``a`` and ``b`` is
  an equality ``connect`` between sites ``node{a}`` and ``node{b}``; a fixed rod end ``a`` is a
  ``connect`` to a world site ``ground{a}`` at its position.  They are soft in MuJoCo: time
  constant ``2 timestep`` (critically damped, ``refsafe`` off) and impedance ``CONNECT_SOLIMP``
  make them nearly hard (class 2 shells follow ours to ~5e-8 m over 0.3 s).  An anchor (fixed
  node of no rod) is a world site ``node{k}``; a point mass is a body ``mass{k}`` with a free
  joint (slides along ``x, y, z`` with a ground, below), its mass, a negligible isotropic
  inertia and a site ``node{k}`` at its centre (after the rods in ``qpos``/``qvel``).
  Initial velocities are exported as given: give velocities that satisfy the constraints.
- **Planar structures** (``Structure.dim == 2``, Appendix A) lie in the plane ``z = 0``.  A rod's
  body (same frame, inertia and sites as above) has, instead of a free joint, two slide joints
  ``rod{r}_0``, ``rod{r}_1`` along the world ``x`` and ``y`` axes and a hinge ``rod{r}_rz`` about
  ``z`` at its centre, so its joint-space mass matrix is ``diag(m, m, m L^2/12)``: exactly the
  planar rod's 3 degrees of freedom (``qpos`` 0 at the initial pose, ``qvel`` the centre
  velocity and ``omega = (u x (v_b - v_a))_z / L``).  A point mass has two slides.  Tendons,
  joints and fixed ends are as in 3-D (a ``connect``'s ``z`` row is identically satisfied);
  ``gravity`` has 2 numbers.  Read nodes back with ``dim=2``.
- **Nodes on a plane or a line** are held exactly, in reduced coordinates: the held node is the
  root of its body's joints.  A point mass's body slides along an orthonormal basis of the
  directions its constraints leave free (two slides on a plane, one on a line; several planes
  and lines on one node intersect).  A rod with a held end ``a`` has slides ``rod{r}_0, ...``
  along those directions through ``p_a``, then a ball joint ``rod{r}_ball`` at ``a`` (a hinge
  ``rod{r}_rz`` about ``z`` if planar); its ``qpos`` starts at 0 and ``(1, 0, 0, 0)``, its
  ``qvel`` is the velocity of ``p_a`` along the slides and the body-frame angular velocity.  No
  auxiliary body, no added mass and no soft constraint are involved.  A plane or line on a
  fixed node is left out (the node does not move).
- **Rods with both ends held.**  The root is the end ``r`` with fewer free directions ``F_r``
  (``a`` on a tie), the other end is ``o``.  If ``F_r`` lies in ``F_o`` (both ends on one
  plane or on parallel planes, on one line or parallel lines, ``r`` on a line parallel to
  ``o``'s plane) the tree is exact: slides along ``F_r`` keep ``o`` on its planes, and so does
  turning about the normal ``n`` of ``o``'s plane; the rod has slides, a hinge
  ``rod{r}_turn`` about ``n`` at ``r`` and a hinge ``rod{r}_spin`` about its own axis ``u``
  (started at ``-theta' (n . u)``, it cancels the spin the turn gives a rod not lying in the
  plane, and stays cancelled: nothing exerts a torque about the axis), or slides only when
  ``o`` is on a line (or the rod is normal to the plane).  These are our degrees of freedom
  plus one spin, with no constraint: MuJoCo takes the same RK4 steps as ours.  Otherwise
  (ends on non-parallel planes, a plane and a line not parallel to it, skew lines, a planar
  rod on non-parallel lines) no tree of joints holds both ends: the rod gets slides and a
  ball (a hinge about ``z`` if planar) at ``r``, and the loop is closed by one MuJoCo
  equality per unit normal ``n`` of ``o``'s planes (1 on a plane, 2 on a line, 1 on a planar
  line): ``tendon`` equality ``hold{j}`` makes the lengths of two zero-stiffness spatial
  tendons ``hold{j}a``, ``hold{j}b`` from ``node{o}`` to world sites ``p_o(0) +- D n``
  (``D = CLOSURE_ARM`` times the longest rod) equal, and the points equidistant from two
  sites mirrored across a plane are exactly that plane.  The row is weighted by the rod's own
  inertia (a ``connect`` to a light sliding body, tried first, was regularized by the light
  body's inverse mass and missed by 2e-2 m over 0.5 s).  It is soft like the joints (same
  ``solref``, ``solimp``): the node lags off its plane by an amount that scales as ``tc^2``,
  ``tc = 2 timestep`` (as ``J' q' tc^2`` would if MuJoCo's reference acceleration omits the
  velocity-product term ``J' q'``), not with the impedance or the solver's tolerance
  (measured 1.7 .. 3.9 um over 0.5 s at ``timestep = 1e-4``, falling as ``timestep^2``; see
  ``docs/constraints.md``).  The tendons come after the structure's, which keep their indices.
- **Ground contact** (``ground=`` planes, ``contact_radius=r``; :mod:`tensegrity.model.ground`):
  each plane is a world geom ``plane{p}`` (local ``z`` along its normal, the empty side; infinite
  for collisions) moved ``(1 - CONTACT_SPHERE_FRACTION) r`` out along its normal, and each rod end
  a sphere geom ``end{i}`` of radius ``CONTACT_SPHERE_FRACTION r``: a sphere penetrates exactly as
  far as our end of radius ``r``, and MuJoCo's contact point stays on the rod's axis (full-size
  spheres put it ``r`` off the axis, and friction across a rod then spins it; see
  ``CONTACT_SPHERE_FRACTION``).  With a ground the spin inertia is the transverse one.  A point
  mass is a contact point too (as in :mod:`tensegrity.physics.contact`, of the same radius): its
  body carries a sphere geom ``mass{k}`` of the same size at its centre, and slides along
  ``x, y, z`` instead of a free joint (friction at the sphere's surface would spin a body of
  negligible inertia).  Geoms touch only through the explicit ``<pair>`` ``end{i}_plane{p}``
  and ``mass{k}_plane{p}`` (``contype`` and ``conaffinity`` 0 everywhere, so rods never touch
  each other), each with ``condim`` 3 (1 without friction), the sliding ``friction`` ``mu_s``,
  ``solref="-k/m -c/m"`` (``m`` the rod's mass, or the point mass) and a flat ``solimp`` of
  ``CONTACT_IMPEDANCE``; elliptic cones, ``impratio`` ``CONTACT_IMPRATIO``.
  At that impedance MuJoCo's soft contact is a penalty law: the normal force is our ``k delta +
  c delta'`` plus ``1e-4 m a_free``.  What differs: MuJoCo has one friction coefficient (``mu_s``
  is exported, so what sticks here holds there; a sliding rod with ``mu_k < mu_s`` slides slower
  in MuJoCo), and its friction is a regularised soft constraint that never sticks: below the
  friction angle it creeps (0.17-0.24 mm/s for a rod on a 20 degree slope at ``mu = 0.5``,
  ``tests/test_mjcf_ground.py``).
- Contacts are disabled without a ground, gravity is ``gravity`` (zero by default), the integrator
  and time step are options; ``<size memory>`` is set explicitly (MuJoCo's own estimate explodes
  for large models).  The energy flag is on, so ``data.energy`` holds (elastic + gravity,
  kinetic) energy [J].
- A keyframe ``initial`` holds the initial ``qpos`` and ``qvel``.  The bodies' default pose
  (``qpos0``) is already the initial configuration, but the initial *velocities* are only in the
  keyframe: call ``mujoco.mj_resetDataKeyframe(model, data, 0)`` after creating ``MjData``.

Differences from :mod:`tensegrity.physics.dynamics` that matter when comparing
------------------------------------------------------------------------------
- **Tendon damping.**  MuJoCo's tendon damping ``-c l'`` acts whether the tendon is taut or slack,
  and the total force may push; ours acts only while taut and a tendon never pushes
  (``T = max(k (l - Lbar) + c l', 0)`` while ``l > Lbar``).  Compare trajectories with damping 0:
  with damped tendons the two models really differ (a released (3,1) shell with ``c = 10 N s/m``
  differs by 5 cm after 0.05 s, as contracting tendons would push in MuJoCo).
- **Rod damping** (``Structure.rod_damping``, mass-proportional damping to ground, and
  ``rod_relative_damping``, relative to the rigid-body motion) has no counterpart in the exported
  model; a structure with nonzero rod damping of either kind is refused.
- **Spin.**  Our rods have no spin degree of freedom; a MuJoCo free body does.  Since every tendon
  attaches on the rod's axis, tendons exert no torque about it, and with the inertia symmetric
  about the axis Euler's equations keep the spin rate at zero (``I3 w3' = (I1 - I2) w1 w2 = 0``)
  and leave the transverse motion independent of ``I3``.  So ``eps`` only has to be positive and
  large enough that round-off torques (about 1e-16 of the tendon moments) cannot spin the rod up:
  ``SPIN_INERTIA_RATIO = 1e-6`` gives spin rates below 1e-9 rad/s after 0.5 s of a (4,2) shell,
  invisible at the nodes (they lie on the spin axis) and in the energy (``eps w3^2 / 2``); node
  trajectories with ratios from 1e-12 to 1e-2 differ by less than 1e-13 m.  (MuJoCo requires
  inertias above ``mjMINVAL = 1e-15``, so ``eps`` must stay above that for very light rods.)
- **Rod lengths.**  The sites are exactly ``rod_length`` apart, centred on the midpoint of the
  structure's two nodes and along the line joining them: the same projection onto the rod
  constraint that :func:`tensegrity.physics.dynamics.initial_state` makes (equal to
  ``node_position`` up to round-off when the nodes are exactly ``L`` apart).  Likewise the initial
  angular velocity is ``u x (v_b - v_a) / L`` with zero spin, which drops any rod-stretching
  velocity component just as ``initial_state`` does.

Reading positions: after ``mujoco.mj_step`` with the RK4 integrator, ``data.site_xpos`` still
holds the last Runge-Kutta stage, not the end of the step; :func:`mujoco_node_positions` calls
``mujoco.mj_kinematics`` first.

MuJoCo is an optional dependency: :func:`to_mjcf` and :func:`write_mjcf` only build text;
:func:`mujoco_node_positions` and :func:`mujoco_node_velocities` import ``mujoco`` when called.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tensegrity.model.ground import Plane, planes_of
from tensegrity.model.structure import Structure

#: Inertia about a rod's own axis, as a fraction of its transverse inertia ``m L^2 / 12`` ...
SPIN_INERTIA_RATIO = 1e-6
#: ... but at least this [kg m^2] (MuJoCo refuses inertias below ``mjMINVAL = 1e-15``), and at
#: most the transverse inertia.
SPIN_INERTIA_MIN = 1e-13
#: MuJoCo's ``mjMINVAL``: the smallest mass [kg] and inertia [kg m^2] of a moving body.
_MUJOCO_MINVAL = 1e-15

#: MuJoCo's ``integrator`` keywords accepted by :func:`to_mjcf`.
INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")

#: ``<size memory>`` is ``MEMORY_BASE + MEMORY_PER_ELEMENT * (6 R + S)`` bytes, rounded up to a
#: mebibyte.  MuJoCo's arena holds the contact/constraint buffers (contacts are off; the joints'
#: equality rows are counted in :func:`mjcf_memory`) and the stack of temporaries, which grows
#: linearly in the number of degrees of freedom plus tendons.  Peak use measured on class 1 shells
#: from (3,1) to (30,30) with MuJoCo 4.0: about 50 bytes per (dof + tendon) with
#: Euler/implicitfast, 120 with RK4, 360 with implicit, so this leaves a margin of 5x (implicit) to
#: 17x (RK4).  (MuJoCo's own estimate asks for 1.2 GB for a (20,20) shell, which needs 1 MB.)
MEMORY_BASE = 1 << 20
MEMORY_PER_ELEMENT = 2 << 10

_SITE_RADIUS_FRACTION = 0.02  # visual only: site and capsule radii relative to the rod length

#: ``solimp`` of the ball joints and supports (``connect`` equality constraints): impedance
#: 0.9999 whatever the violation, so the constraint is nearly hard; with ``solref`` time constant
#: ``2 timestep`` (critically damped) a pinned rod follows our pendulum to 2e-9 m over 0.5 s.
CONNECT_SOLIMP = "0.9999 0.9999 0.001"

#: The world sites of a closure row (a node held on a plane by a tendon equality) lie this many
#: times the longest rod away from the node, on either side of the plane.
CLOSURE_ARM = 10.0

#: Impedance ``d`` of the ground contacts (``solimp="d d ..."``): MuJoCo's minimum ``mjMINIMP``.
#: A contact's force is ``(a_ref - a_free) / (A + R)`` with ``R = (1 - d) / d * diagA`` and
#: ``diagA = 1 / m`` for a free rod of mass ``m``; at ``d = 1e-4``, ``R`` outweighs the exact
#: ``A`` (at most ``4 / m`` at a rod end) 2500 times, so the force is ``m d (a_ref - a_free)``:
#: with the direct ``solref="-k/m -c/m"`` (scaled by MuJoCo to ``k/(m d)``, ``c/(m d)``) it is the
#: penalty law ``k delta + c delta'`` of :class:`tensegrity.model.ground.Plane`, plus
#: ``d m a_free`` (1e-4 of the free acceleration's force).
CONTACT_IMPEDANCE = 1e-4

#: ``impratio`` of the exported scene (elliptic cones): friction rows are regularised
#: ``impratio`` times less than the normal rows (which ``CONTACT_IMPEDANCE`` makes soft on purpose).
CONTACT_IMPRATIO = 100.0

#: The contact spheres are this fraction of ``contact_radius`` and the planes are moved out along
#: their normals by the rest of it, so a sphere penetrates a plane exactly as far as our rod end
#: does, and MuJoCo's contact point lies at the node (to this fraction of the radius plus half
#: the penetration).  Spheres of the full radius put the contact point ``r`` off the rod's axis:
#: a friction force across a rod then spins it about its own axis, whose inertia is tiny, and the
#: run diverges (a rod lying across a 20 degree slope did within 2 ms).
CONTACT_SPHERE_FRACTION = 1e-3

#: Two planes or lines are parallel (a rod with ends on them has an exact joint tree) when their
#: unit normals and free directions are orthogonal to within this.
_PARALLEL_TOL = 1e-12


def _float(x: float) -> str:
    """Shortest decimal that round-trips the double ``x`` exactly."""
    return repr(float(x))


def _floats(values: Any) -> str:
    return " ".join(_float(x) for x in np.ravel(values))


def _quat_z_to(u: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(w, x, y, z)`` of a rotation taking the ``z`` axis to the unit ``u``.

    ``q = (1 + u_z, -u_y, u_x, 0)`` normalized, accurate for ``u_z >= 0``; for ``u_z < 0`` it is
    composed as a half turn about ``x`` (``z -> -z``) followed by the rotation taking ``z`` to
    ``-u`` (hence ``-z`` to ``u``), which avoids the cancellation in ``1 + u_z``.
    """
    if u[2] >= 0:
        q = np.array([1.0 + u[2], -u[1], u[0], 0.0])
        return q / np.linalg.norm(q)
    w, x, y, _ = _quat_z_to(-u)
    # (w, x, y, 0) * (0, 1, 0, 0): Hamilton product with the half turn about x.
    q = np.array([-x, w, 0.0, -y])
    return q / np.linalg.norm(q)


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate ``v`` by the unit quaternion ``q = (w, x, y, z)``."""
    w, r = q[0], q[1:]
    return v + 2.0 * np.cross(r, np.cross(r, v) + w * v)


def _lifted(structure: Structure) -> tuple[np.ndarray, np.ndarray]:
    """Node positions [m] and velocities [m/s] in 3-D, shape (N, 3) each (a planar structure in
    the plane ``z = 0``)."""
    pad = ((0, 0), (0, 3 - structure.dim))
    return np.pad(structure.node_position, pad), np.pad(structure.node_velocity, pad)


class _RodMotion(NamedTuple):
    """Position and motion of every rod in 3-D, world frame."""

    centre: np.ndarray  #: (R, 3) [m]
    quat: np.ndarray  #: (R, 4) orientations ``(w, x, y, z)`` taking the body ``z`` to ``axis``
    velocity: np.ndarray  #: (R, 3) centre velocities [m/s]
    omega: np.ndarray  #: (R, 3) angular velocities [rad/s], no spin
    axis: np.ndarray  #: (R, 3) unit axes ``(p_b - p_a) / |p_b - p_a|``


def _rod_motion(structure: Structure) -> _RodMotion:
    """The :class:`_RodMotion` of every rod (a planar structure in the plane ``z = 0``)."""
    a, b = structure.rod_nodes[:, 0], structure.rod_nodes[:, 1]
    p, v = _lifted(structure)
    centre = 0.5 * (p[a] + p[b])
    axis = p[b] - p[a]
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    quat = np.array([_quat_z_to(u) for u in axis]).reshape(-1, 4)
    velocity = 0.5 * (v[a] + v[b])
    omega = np.cross(axis, v[b] - v[a]) / structure.rod_length[:, None]
    return _RodMotion(centre, quat, velocity, omega, axis)


def _to_body(quat: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """World ``vectors`` (R, 3) in the body frames of orientations ``quat`` (R, 4)."""
    conjugate = quat * np.array([1.0, -1.0, -1.0, -1.0])
    return np.array([_rotate(qc, w) for qc, w in zip(conjugate, vectors, strict=True)]).reshape(
        -1, 3
    )


def rod_frames(structure: Structure) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Free-joint state of every rod: ``(centre, quat, velocity, omega_local)``.

    A planar structure is taken in the plane ``z = 0``.

    Returns
    -------
    centre : ndarray, shape (R, 3)
        Rod centres ``(p_a + p_b) / 2`` [m].
    quat : ndarray, shape (R, 4)
        Orientations ``(w, x, y, z)`` taking the body ``z`` axis to ``(p_b - p_a) / |p_b - p_a|``.
    velocity : ndarray, shape (R, 3)
        Centre velocities ``(v_a + v_b) / 2`` [m/s], world frame.
    omega_local : ndarray, shape (R, 3)
        Angular velocities [rad/s] in the body frame (MuJoCo's free-joint convention), the world
        value being ``u x (v_b - v_a) / L``: no spin, rod-stretching velocity dropped.
    """
    centre, quat, velocity, omega, _ = _rod_motion(structure)
    return centre, quat, velocity, _to_body(quat, omega)


def mjcf_memory(structure: Structure, *, planes: int = 0) -> int:
    """The ``<size memory>`` [bytes] written by :func:`to_mjcf` (see ``MEMORY_PER_ELEMENT``); a
    point mass counts 6 elements (a free body), a joint or support 12 (3 constraint rows), a
    closure row 6 (its two tendons and a constraint row), and each of the ``(2 R + M) planes``
    contact pairs (rod ends and point masses) of a scene with ``planes`` ground planes 12 (a
    contact of 3 rows)."""
    closures = sum(
        len(tree.closure)
        for tree in _rod_trees(structure, _held_axes(structure), _rod_motion(structure).axis)
    )
    elements = (
        structure.n_coordinates
        + 3 * structure.point_mass_nodes.size
        + structure.n_tendons
        + 12 * len(_connect_pairs(structure))
        + 6 * closures
        + 12 * (2 * structure.n_rods + structure.point_mass_nodes.size) * planes
    )
    size = MEMORY_BASE + MEMORY_PER_ELEMENT * elements
    mebibyte = 1 << 20
    return -(-size // mebibyte) * mebibyte


def to_mjcf(
    structure: Structure,
    *,
    timestep: float = 1e-4,
    integrator: str = "RK4",
    gravity: Any = None,
    name: str = "tensegrity",
    ground: Plane | Sequence[Plane] | None = None,
    contact_radius: float = 0.0,
) -> str:
    """MJCF XML of ``structure`` for MuJoCo: rod bodies, spatial deadband-spring tendons.

    See the module docstring for the modelling choices (spin inertia, deadband spring, damping,
    planar structures, plane and line constraints, rods with both ends held, keyframe).  All
    numbers are written with 17 significant digits, so the model's parameters and initial state
    are bit-identical to ``structure``'s (after the rod-constraint projection).

    Parameters
    ----------
    structure : Structure
        A structure without rod damping (``rod_damping`` and ``rod_relative_damping`` all
        zero); 3-D or planar.
    timestep : float
        MuJoCo time step [s], > 0.
    integrator : str
        One of ``"Euler"``, ``"RK4"``, ``"implicit"``, ``"implicitfast"``.
    gravity : array_like, shape (d,), optional
        Gravitational acceleration [m/s^2], ``d = structure.dim`` numbers (2 for a planar
        structure, as :func:`tensegrity.engine.simulate.simulate` takes it).  Default zero (MuJoCo's
        default is ``0 0 -9.81``).
    name : str
        The model name.
    ground : Plane or sequence of Plane, optional
        Planes the rods' ends and point masses touch (:mod:`tensegrity.model.ground`, as
        ``simulate`` takes them):
        the scene is exported with contacts on (see the module docstring, "Ground contact").
        Default none: contacts off.
    contact_radius : float
        Radius [m] of the rods' ends and point masses as contact spheres, > 0 with a
        ``ground`` (a MuJoCo sphere needs a positive size), >= 0 without (then unused).

    Returns
    -------
    str
        The MJCF document.  Bodies ``rod{r}`` (a free joint ``rod{r}``, or slides ``rod{r}_0``,
        ... and a hinge ``rod{r}_rz`` (planar), a ball ``rod{r}_ball`` (an end held on a plane
        or line) or hinges ``rod{r}_turn``, ``rod{r}_spin`` (both ends held)), ``mass{k}``,
        sites ``node{i}``, tendons named ``structure.tendon_name`` (then ``hold{j}a``,
        ``hold{j}b`` of the closure equalities ``hold{j}``), keyframe ``initial`` (index 0); with
        a ``ground``, plane geoms ``plane{p}``, sphere geoms ``end{i}`` at the rod end nodes and
        ``mass{k}`` at the point masses, and contact pairs ``end{i}_plane{p}``,
        ``mass{k}_plane{p}``.

    Raises
    ------
    ValueError
        Naming the field: ``timestep``, ``integrator``, ``gravity``, ``name``,
        ``contact_radius``;
        ``rods[r].damping`` when a rod has damping MuJoCo cannot represent; ``rods[r].mass`` when
        its mass or inertia ``m L^2 / 12`` is below MuJoCo's minimum ``1e-15``; ``tendons``
        when a tendon is named like a closure tendon (``hold{j}a``, ``hold{j}b``).
    TypeError
        Naming ``ground`` if it is not a Plane or a sequence of Planes.
    """
    dt, g = _checked_options(
        structure, timestep=timestep, integrator=integrator, gravity=gravity, name=name
    )
    planes, radius = _checked_scene(ground, contact_radius)
    transverse, spin = _checked_rod_inertias(structure)
    if planes:  # a contact's small lever would roll a rod of small spin inertia about its axis
        spin = transverse
    motion = _rod_motion(structure)
    connects = _connect_pairs(structure)
    held = _held_axes(structure)
    trees = _rod_trees(structure, held, motion.axis)
    closures = [row for tree in trees for row in tree.closure]
    _check_closure_names(structure, len(closures))
    # refsafe off: the joints' and closures' time constant 2 dt is below MuJoCo's "safe" minimum
    soft = bool(connects or closures)
    root = _header(
        structure,
        name=name,
        timestep=dt,
        integrator=integrator,
        gravity=g,
        soft=soft,
        planes=len(planes),
    )
    world = ET.SubElement(root, "worldbody")
    keyframe = _Keyframe()
    _planes(world, structure, planes, contact_radius=radius)
    _rod_bodies(
        world,
        structure,
        trees,
        motion,
        keyframe,
        transverse=transverse,
        spin=spin,
        contact_radius=radius if planes else None,
    )
    _point_mass_bodies(world, structure, held, keyframe, contact_radius=radius if planes else None)
    _world_sites(world, structure, connects, closures)
    if soft:
        _equalities(root, connects, len(closures), timestep=dt)
    if planes:
        _contact_pairs(root, structure, planes)
    if structure.n_tendons or closures:
        _tendons(root, structure, closures)
    keyframe.write(root)
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def _checked_options(
    structure: Structure, *, timestep: Any, integrator: str, gravity: Any, name: Any
) -> tuple[float, np.ndarray]:
    """:func:`to_mjcf`'s options, checked: ``(timestep [s], gravity (d,) [m/s^2])``.

    Raises
    ------
    ValueError
        Naming the field: ``structure``, ``timestep``, ``integrator``, ``gravity``, ``name``.
    """
    if not isinstance(structure, Structure):
        raise ValueError(f"structure: expected a Structure, got {type(structure).__name__}")
    try:
        dt = float(timestep)
    except (TypeError, ValueError):
        raise ValueError(f"timestep: must be a number, got {timestep!r}") from None
    if not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"timestep: must be > 0 and finite, got {timestep!r}")
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator: must be one of {', '.join(INTEGRATORS)}, got {integrator!r}")
    d = structure.dim
    try:
        g = np.zeros(d) if gravity is None else np.array(gravity, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"gravity: expected {d} numbers, got {gravity!r}") from None
    if g.shape != (d,) or not np.all(np.isfinite(g)):
        raise ValueError(f"gravity: expected {d} finite numbers, got {gravity!r}")
    if not isinstance(name, str) or not name:
        raise ValueError(f"name: must be a non-empty string, got {name!r}")
    return dt, g


def _checked_scene(ground: Any, contact_radius: Any) -> tuple[tuple[Plane, ...], float]:
    """:func:`to_mjcf`'s scene, checked: ``(planes, contact radius [m])``.

    Raises
    ------
    TypeError
        Naming ``ground`` if it is not a Plane or a sequence of Planes.
    ValueError
        Naming ``contact_radius`` if it is not a finite number >= 0, or 0 with a ground.
    """
    planes = () if ground is None else planes_of(ground)
    ok = isinstance(contact_radius, (int, float, np.integer, np.floating))
    radius = float(contact_radius) if ok and not isinstance(contact_radius, bool) else math.nan
    if not (math.isfinite(radius) and (radius > 0 or (radius == 0 and not planes))):
        need = "> 0 with a ground (a MuJoCo sphere needs a positive size)" if planes else ">= 0"
        raise ValueError(
            f"contact_radius: must be a finite number {need} [m], got {contact_radius!r}"
        )
    return planes, radius


def _checked_rod_inertias(structure: Structure) -> tuple[np.ndarray, np.ndarray]:
    """``(transverse, spin)`` (R,) [kg m^2]: each rod's inertia ``m L^2 / 12`` about a transverse
    axis, and about its own (see ``SPIN_INERTIA_RATIO``).

    Raises
    ------
    ValueError
        ``rods[r].damping`` or ``rods[r].relative_damping`` if a rod has damping (MuJoCo has no
        counterpart); ``rods[r].mass`` if
        its mass or transverse inertia is below MuJoCo's minimum.
    """
    for field, values in (
        ("damping", structure.rod_damping),
        ("relative_damping", structure.rod_relative_damping),
    ):
        damped = np.flatnonzero(values != 0)
        if damped.size:
            r = damped[0]
            raise ValueError(
                f"rods[{r}].{field}: is {values[r]!r} 1/s; mass-proportional rod damping has "
                f"no MuJoCo counterpart, export the structure with rod_{field} = 0"
            )
    mass, length = structure.rod_mass, structure.rod_length
    transverse = mass * length**2 / 12.0
    light = np.flatnonzero((mass <= _MUJOCO_MINVAL) | (transverse <= _MUJOCO_MINVAL))
    if light.size:
        r = light[0]
        raise ValueError(
            f"rods[{r}].mass: mass {mass[r]!r} kg and inertia m L^2/12 = {transverse[r]!r} kg m^2 "
            f"must both exceed MuJoCo's minimum {_MUJOCO_MINVAL:g} (choose other units)"
        )
    spin = np.minimum(transverse, np.maximum(SPIN_INERTIA_RATIO * transverse, SPIN_INERTIA_MIN))
    return transverse, spin


def _check_closure_names(structure: Structure, n_closures: int) -> None:
    """Raise if a tendon is named like a closure tendon ``hold{j}a``, ``hold{j}b``."""
    closure_names = {f"hold{j}{end}" for j in range(n_closures) for end in "ab"}
    taken = set(structure.tendon_name) & closure_names
    if taken:
        raise ValueError(
            f"tendons: the name {sorted(taken)[0]!r} is taken by a closure tendon of "
            "the MJCF export (a rod with both ends held); rename that tendon"
        )


def _header(
    structure: Structure,
    *,
    name: str,
    timestep: float,
    integrator: str,
    gravity: np.ndarray,
    soft: bool,
    planes: int,
) -> ET.Element:
    """The ``<mujoco>`` root with its compiler, option (``gravity`` (d,) [m/s^2] in 3-D; contacts
    off without ``planes``, else on with elliptic cones and ``CONTACT_IMPRATIO``; energy on,
    ``refsafe`` off if there are ``soft`` equalities) and size."""
    root = ET.Element("mujoco", model=name)
    ET.SubElement(root, "compiler", angle="radian", inertiafromgeom="false", autolimits="true")
    option = ET.SubElement(
        root,
        "option",
        timestep=_float(timestep),
        integrator=integrator,
        gravity=_floats(np.pad(gravity, (0, 3 - structure.dim))),
    )
    if planes:
        option.set("cone", "elliptic")
        option.set("impratio", _float(CONTACT_IMPRATIO))
    flags = {"contact": "enable" if planes else "disable", "energy": "enable"}
    flags |= {"refsafe": "disable"} if soft else {}
    ET.SubElement(option, "flag", flags)
    ET.SubElement(root, "size", memory=str(mjcf_memory(structure, planes=planes)))
    return root


class _Keyframe:
    """The initial ``qpos`` and ``qvel`` of the joints, in the order they are written."""

    def __init__(self) -> None:
        self.qpos: list[Any] = []
        self.qvel: list[Any] = []

    def add(self, qpos: Any, qvel: Any) -> None:
        """Append one joint's (or several joints') positions and velocities."""
        self.qpos.append(qpos)
        self.qvel.append(qvel)

    def write(self, root: ET.Element) -> None:
        """The ``<keyframe>`` with the key ``initial`` at time 0."""
        keyframe = ET.SubElement(root, "keyframe")
        ET.SubElement(
            keyframe,
            "key",
            name="initial",
            time="0",
            qpos=_floats(np.concatenate(self.qpos or [[]])),
            qvel=_floats(np.concatenate(self.qvel or [[]])),
        )


def _rod_bodies(
    world: ET.Element,
    structure: Structure,
    trees: list[_RodTree],
    motion: _RodMotion,
    keyframe: _Keyframe,
    *,
    transverse: np.ndarray,
    spin: np.ndarray,
    contact_radius: float | None,
) -> None:
    """Bodies ``rod{r}`` at the rods' centres and orientations: the joints of their ``trees``,
    the inertias ``diag(transverse, transverse, spin)`` (R,) [kg m^2], a capsule geom without
    contacts, the sites of the end nodes and, given a ``contact_radius`` [m], sphere geoms
    ``end{i}`` of ``CONTACT_SPHERE_FRACTION`` of it at them (massless; they touch only through
    the contact pairs)."""
    omega_local = _to_body(motion.quat, motion.omega)
    for r, ((a, b), tree) in enumerate(zip(structure.rod_nodes, trees, strict=True)):
        L = float(structure.rod_length[r])
        body = ET.SubElement(
            world,
            "body",
            name=f"rod{r}",
            pos=_floats(motion.centre[r]),
            quat=_floats(motion.quat[r]),
        )
        _rod_joints(body, structure, r, tree, motion, omega_local[r], keyframe)
        ET.SubElement(
            body,
            "inertial",
            pos="0 0 0",
            mass=_float(structure.rod_mass[r]),
            diaginertia=_floats([transverse[r], transverse[r], spin[r]]),
        )
        radius = _float(_SITE_RADIUS_FRACTION * L)
        ET.SubElement(
            body,
            "geom",
            type="capsule",
            size=radius,
            fromto=_floats([0, 0, -L / 2, 0, 0, L / 2]),
            contype="0",
            conaffinity="0",
            group="1",
        )
        for node, z in ((a, -L / 2), (b, L / 2)):
            ET.SubElement(body, "site", name=f"node{node}", pos=_floats([0, 0, z]), size=radius)
            if contact_radius is not None:
                _contact_sphere(body, f"end{node}", [0, 0, z], contact_radius=contact_radius)


def _contact_sphere(body: ET.Element, name: str, pos: Any, *, contact_radius: float) -> None:
    """A massless sphere geom ``name`` of ``body`` at ``pos`` (3,) [m] (body frame), of radius
    ``CONTACT_SPHERE_FRACTION`` times ``contact_radius`` [m]; it touches only through the
    contact pairs."""
    ET.SubElement(
        body,
        "geom",
        name=name,
        type="sphere",
        size=_float(CONTACT_SPHERE_FRACTION * contact_radius),
        pos=_floats(pos),
        mass="0",
        contype="0",
        conaffinity="0",
    )


def _rod_joints(
    body: ET.Element,
    structure: Structure,
    r: int,
    tree: _RodTree,
    motion: _RodMotion,
    omega_local: np.ndarray,
    keyframe: _Keyframe,
) -> None:
    """The joints of rod ``r``'s ``tree``: a free joint, or slides along the root's free
    directions (world axes, given in the body frame), then a ball, or hinges (each turning the
    next), at the root: the rod's centre or a held end.  ``omega_local`` (3,) [rad/s] is the
    rod's angular velocity in its body frame."""
    if tree.slides is None:
        ET.SubElement(body, "freejoint", name=f"rod{r}")
        keyframe.add(
            np.concatenate([motion.centre[r], motion.quat[r]]),
            np.concatenate([motion.velocity[r], omega_local]),
        )
        return
    a = structure.rod_nodes[r, 0]
    L = float(structure.rod_length[r])
    side = 0.0 if tree.root < 0 else (-0.5 if tree.root == a else 0.5)
    arm = side * L * motion.axis[r]
    rates = tree.slides @ (motion.velocity[r] + np.cross(motion.omega[r], arm))
    frame = motion.quat[r : r + 1]
    _slides(
        body,
        f"rod{r}",
        _to_body(np.tile(frame, (len(tree.slides), 1)), tree.slides),
        rates,
        keyframe,
    )
    at = _floats([0, 0, side * L])
    if tree.hinges is None:
        ET.SubElement(body, "joint", name=f"rod{r}_ball", type="ball", pos=at)
        keyframe.add([1.0, 0.0, 0.0, 0.0], omega_local)
        return
    names = ("rz",) if structure.dim == 2 else ("turn", "spin")
    # A rod with both ends held may have no hinges (`_rod_trees`): it takes none of the names.
    rates = _hinge_rates(tree.hinges, motion.omega[r])
    for joint, hinge, rate in zip(names, tree.hinges, rates, strict=False):
        ET.SubElement(
            body,
            "joint",
            name=f"rod{r}_{joint}",
            type="hinge",
            pos=at,
            axis=_floats(_to_body(frame, hinge[None])[0]),
        )
        keyframe.add([0.0], [rate])


def _site_radius(structure: Structure) -> str:
    """The radius [m] of the sites that are not on a rod (point masses, world sites)."""
    return _float(_SITE_RADIUS_FRACTION * float(structure.rod_length.max(initial=1.0)))


def _point_mass_bodies(
    world: ET.Element,
    structure: Structure,
    held: dict[int, np.ndarray],
    keyframe: _Keyframe,
    *,
    contact_radius: float | None,
) -> None:
    """Bodies ``mass{k}``: a free joint, or slides (planar, along the free directions
    ``held[k]`` of a node held on planes or lines, or along ``x, y, z`` in a scene with a
    ground), a negligible inertia, a site ``node{k}`` and, given a ``contact_radius`` [m], a
    sphere geom ``mass{k}`` of ``CONTACT_SPHERE_FRACTION`` of it at the centre (as the rods'
    ends have).  Slides, not a free joint, with a ground: friction at the sphere's surface
    would spin a free body of negligible inertia (a point mass sliding on a slope diverged
    within 0.2 ms)."""
    position, node_velocity = _lifted(structure)
    site_radius = _site_radius(structure)
    for k in structure.point_mass_nodes:
        body = ET.SubElement(world, "body", name=f"mass{k}", pos=_floats(position[k]))
        if structure.dim == 2 or k in held or contact_radius is not None:
            axes = held.get(int(k), np.eye(3)[: structure.dim])
            _slides(body, f"mass{k}", axes, axes @ node_velocity[k], keyframe)
        else:
            ET.SubElement(body, "freejoint", name=f"mass{k}")
            keyframe.add(
                np.concatenate([position[k], [1.0, 0.0, 0.0, 0.0]]),
                np.concatenate([node_velocity[k], np.zeros(3)]),
            )
        ET.SubElement(
            body,
            "inertial",
            pos="0 0 0",
            mass=_float(structure.node_point_mass[k]),
            diaginertia=_floats([SPIN_INERTIA_MIN] * 3),
        )
        ET.SubElement(body, "site", name=f"node{k}", pos="0 0 0", size=site_radius)
        if contact_radius is not None:
            _contact_sphere(body, f"mass{k}", [0, 0, 0], contact_radius=contact_radius)


def _planes(
    world: ET.Element, structure: Structure, planes: tuple[Plane, ...], *, contact_radius: float
) -> None:
    """Plane geoms ``plane{p}`` of the world: through ``point`` moved ``(1 -
    CONTACT_SPHERE_FRACTION) contact_radius`` [m] along ``normal``, local ``z`` along ``normal``
    (MuJoCo's empty side), drawn infinite; they touch only through the contact pairs."""
    lift = (1.0 - CONTACT_SPHERE_FRACTION) * contact_radius
    spacing = _float(float(structure.rod_length.max(initial=1.0)))
    for p, plane in enumerate(planes):
        ET.SubElement(
            world,
            "geom",
            name=f"plane{p}",
            type="plane",
            size=f"0 0 {spacing}",
            pos=_floats(plane.point + lift * plane.normal),
            quat=_floats(_quat_z_to(plane.normal)),
            contype="0",
            conaffinity="0",
            rgba="0.8 0.8 0.8 1",
        )


def _contact_pairs(root: ET.Element, structure: Structure, planes: tuple[Plane, ...]) -> None:
    """One ``<pair>`` ``{geom}_plane{p}`` per contact sphere and plane, the spheres the rods'
    ends ``end{i}`` then the point masses ``mass{k}``: sliding friction ``mu_s`` (``condim`` 3,
    1 without friction), the direct ``solref="-k/m -c/m"`` of the mass ``m`` of the sphere's body
    (the rod's, the point mass) and impedance ``CONTACT_IMPEDANCE`` (see the module docstring,
    "Ground contact")."""
    contact = ET.SubElement(root, "contact")
    solimp = f"{_float(CONTACT_IMPEDANCE)} {_float(CONTACT_IMPEDANCE)} 0.001 0.5 2"
    spheres = [
        (f"end{node}", float(structure.rod_mass[r]))
        for r, ends in enumerate(structure.rod_nodes)
        for node in ends
    ] + [(f"mass{k}", float(structure.node_point_mass[k])) for k in structure.point_mass_nodes]
    for geom, m in spheres:
        for p, plane in enumerate(planes):
            mu = _float(plane.friction)
            ET.SubElement(
                contact,
                "pair",
                name=f"{geom}_plane{p}",
                geom1=geom,
                geom2=f"plane{p}",
                condim="3" if plane.friction > 0 else "1",
                friction=f"{mu} {mu} 0 0 0",
                solref=f"{_float(-plane.stiffness / m)} {_float(-plane.damping / m)}",
                solimp=solimp,
            )


def _world_sites(
    world: ET.Element,
    structure: Structure,
    connects: list[tuple[str, str, np.ndarray | None]],
    closures: list[tuple[int, np.ndarray]],
) -> None:
    """Sites fixed in the world: anchors ``node{k}``, fixed rod ends ``ground{a}`` (of
    ``connects``) and the two sites ``hold{j}a``, ``hold{j}b`` of each closure row."""
    position, _ = _lifted(structure)
    site_radius = _site_radius(structure)
    for k in structure.anchor_nodes:
        ET.SubElement(world, "site", name=f"node{k}", pos=_floats(position[k]), size=site_radius)
    for _, site2, where in connects:
        if site2.startswith("ground"):
            ET.SubElement(world, "site", name=site2, pos=_floats(where), size=site_radius)
    # a closure row holds node k on the plane through its position with unit normal n: the
    # points equidistant from two world sites mirrored across that plane
    arm = CLOSURE_ARM * float(structure.rod_length.max(initial=1.0))
    for j, (k, n) in enumerate(closures):
        for sign, end in ((1.0, "a"), (-1.0, "b")):
            ET.SubElement(
                world,
                "site",
                name=f"hold{j}{end}",
                pos=_floats(position[k] + sign * arm * n),
                size=site_radius,
            )


def _equalities(
    root: ET.Element,
    connects: list[tuple[str, str, np.ndarray | None]],
    n_closures: int,
    *,
    timestep: float,
) -> None:
    """The soft equalities: a ``connect`` per joint or fixed rod end, a ``tendon`` equality
    ``hold{j}`` per closure row (time constant ``2 timestep`` [s], impedance ``CONNECT_SOLIMP``)."""
    equality = ET.SubElement(root, "equality")
    solref, solimp = f"{_float(2 * timestep)} 1", CONNECT_SOLIMP
    for site1, site2, _ in connects:
        ET.SubElement(equality, "connect", site1=site1, site2=site2, solref=solref, solimp=solimp)
    for j in range(n_closures):
        ET.SubElement(
            equality,
            "tendon",
            name=f"hold{j}",
            tendon1=f"hold{j}a",
            tendon2=f"hold{j}b",
            polycoef="0 1 0 0 0",
            solref=solref,
            solimp=solimp,
        )


def _tendons(
    root: ET.Element, structure: Structure, closures: list[tuple[int, np.ndarray]]
) -> None:
    """The spatial tendons: the structure's (deadband springs between node sites), then the two
    zero-stiffness tendons ``hold{j}a``, ``hold{j}b`` of each closure row."""
    tendons = ET.SubElement(root, "tendon")
    width = _float(0.5 * _SITE_RADIUS_FRACTION * float(structure.rod_length.min(initial=1.0)))
    for s, (tail, head) in enumerate(structure.tendon_nodes):
        spatial = ET.SubElement(
            tendons,
            "spatial",
            name=structure.tendon_name[s],
            stiffness=_float(structure.tendon_stiffness[s]),
            springlength=f"0 {_float(structure.tendon_rest_length[s])}",
            damping=_float(structure.tendon_damping[s]),
            width=width,
        )
        ET.SubElement(spatial, "site", site=f"node{tail}")
        ET.SubElement(spatial, "site", site=f"node{head}")
    for j, (k, _) in enumerate(closures):
        for end in "ab":
            spatial = ET.SubElement(
                tendons, "spatial", name=f"hold{j}{end}", width=width, rgba="0.5 0.5 0.5 0.2"
            )
            ET.SubElement(spatial, "site", site=f"node{k}")
            ET.SubElement(spatial, "site", site=f"hold{j}{end}")


def _slides(
    body: ET.Element, name: str, axes: np.ndarray, rates: np.ndarray, keyframe: _Keyframe
) -> None:
    """Slide joints ``{name}_0, {name}_1, ...`` of ``body`` along ``axes`` (k, 3) in the body
    frame, starting at 0 with the given ``rates`` (k,) [m/s]."""
    for i, axis in enumerate(axes):
        ET.SubElement(body, "joint", name=f"{name}_{i}", type="slide", axis=_floats(axis))
    keyframe.add(np.zeros(len(axes)), rates)


def _held_axes(structure: Structure) -> dict[int, np.ndarray]:
    """The free directions of every node held on planes or lines (and not fixed): an orthonormal
    basis (k, 3) of the directions its constraints allow (a planar structure's in ``z = 0``),
    ``k = 0`` if they leave none."""
    from scipy.linalg import null_space

    from tensegrity.physics.constraints import normals

    d = structure.dim
    rows: dict[int, list[np.ndarray]] = {}
    for k, normal in zip(structure.plane_nodes, structure.plane_normal, strict=True):
        rows.setdefault(int(k), []).append(normal[None])
    if structure.line_nodes.size:
        for k, line_normals in zip(
            structure.line_nodes, normals(structure.line_direction), strict=True
        ):
            rows.setdefault(int(k), []).append(line_normals)
    return {
        k: np.pad(null_space(np.vstack(r)).T, ((0, 0), (0, 3 - d)))
        for k, r in rows.items()
        if not structure.node_fixed[k]
    }


class _RodTree(NamedTuple):
    """The joints of a rod's body (world frame): ``slides`` (k, 3) along unit axes, then
    ``hinges`` (h, 3) at ``root`` (each turning the next), and the rows that close the loop."""

    root: int  # node at the slides' end and the hinges (a held end), or -1: the centre
    slides: np.ndarray | None  # None: a free joint
    hinges: np.ndarray | None  # None: a ball joint
    closure: list[tuple[int, np.ndarray]]  # (node, unit normal): planes the node is held on


def _rod_trees(
    structure: Structure, held: dict[int, np.ndarray], axis: np.ndarray
) -> list[_RodTree]:
    """The joint tree of every rod's body, ``axis`` (R, 3) the rods' unit axes, ``held`` from
    :func:`_held_axes`.

    No held end: a free joint (slides along ``x``, ``y`` and a hinge about ``z`` if planar); one
    held end: slides along its free directions and a ball (a hinge about ``z``) there; both
    held: see the module docstring ("Rods with both ends held").
    """
    from scipy.linalg import null_space

    planar = structure.dim == 2
    plane, z = np.eye(3)[:2], np.eye(3)[2:]
    rotation = z if planar else None  # a hinge about z, or a ball
    trees = []
    for r, (a, b) in enumerate(structure.rod_nodes):
        a, b = int(a), int(b)
        if a not in held and b not in held:
            trees.append(_RodTree(-1, plane if planar else None, rotation, []))
            continue
        root, other = (
            (a, b) if b not in held or (a in held and len(held[a]) <= len(held[b])) else (b, a)
        )
        slides = held[root]
        if other not in held:
            trees.append(_RodTree(root, slides, rotation, []))
            continue
        # unit normals of the other end's planes in 3-D (with z = 0 if planar)
        normals = null_space(held[other]).T
        if np.abs(normals @ slides.T).max(initial=0.0) > _PARALLEL_TOL:
            kept = null_space(np.vstack([held[other], z])).T if planar else normals  # by the tree
            trees.append(_RodTree(root, slides, rotation, [(other, n) for n in kept]))
            continue
        # exact: the root's slides keep the other end on its planes; so does a turn about the
        # normal of a single plane (with a spin hinge cancelling the spin that turn gives a rod
        # not lying in the plane), unless the rod is normal to it; on a line, no turn
        turns = len(normals) == 1 and np.linalg.norm(np.cross(normals[0], axis[r])) > _PARALLEL_TOL
        hinges = np.array([normals[0], axis[r]]) if turns else np.zeros((0, 3))
        trees.append(_RodTree(root, slides, hinges, []))
    return trees


def _hinge_rates(hinges: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Rates [rad/s] of ``hinges`` (h, 3): a turn about ``n`` and a spin about the rod's axis
    ``u`` whose sum has the rod's angular velocity ``omega`` (normal to ``u``) and no spin:
    ``theta' = omega . n / (1 - (n . u)^2)``, ``phi' = -theta' (n . u)``."""
    if len(hinges) == 0:
        return np.zeros(0)
    n = hinges[0]
    c = float(n @ hinges[1]) if len(hinges) > 1 else 0.0
    turn = float(omega @ n) / (1.0 - c * c)
    return np.array([turn, -turn * c][: len(hinges)])


def _connect_pairs(structure: Structure) -> list[tuple[str, str, np.ndarray | None]]:
    """MuJoCo ``connect`` constraints ``(site1, site2, ground position)``: one per ball joint, and
    one per fixed rod end to a world site ``ground{a}`` at its position (3-D)."""
    pairs: list[tuple[str, str, np.ndarray | None]] = [
        (f"node{a}", f"node{b}", None) for a, b in structure.joint_nodes
    ]
    in_rod = np.zeros(structure.n_nodes, bool)
    in_rod[structure.rod_nodes] = True
    position, _ = _lifted(structure)
    pairs += [
        (f"node{a}", f"ground{a}", position[a])
        for a in np.flatnonzero(structure.node_fixed & in_rod)
    ]
    return pairs


def write_mjcf(path: str | os.PathLike, structure: Structure, **options: Any) -> Path:
    """Write :func:`to_mjcf` ``(structure, **options)`` to ``path``, atomically.

    The document is written to a temporary file in the same directory, flushed to disk and moved
    over ``path`` with :func:`os.replace`, so ``path`` never holds a partial model; on any error
    the temporary file is removed and ``path`` is unchanged.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    text = to_mjcf(structure, **options)  # validate before touching the file system
    final = Path(path)
    fd, tmp = tempfile.mkstemp(dir=final.parent, prefix=f".{final.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        try:
            os.chmod(tmp, os.stat(final).st_mode & 0o7777)
        except FileNotFoundError:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, final)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return final


def node_site_ids(model: Any, n_nodes: int) -> np.ndarray:
    """Site ids of ``node0 .. node{n_nodes-1}`` in a model built from :func:`to_mjcf`, (N,).

    Raises
    ------
    ValueError
        If ``n_nodes`` is not a positive integer or a node site is missing.
    """
    import mujoco

    if isinstance(n_nodes, bool) or not isinstance(n_nodes, (int, np.integer)) or n_nodes < 1:
        raise ValueError(f"n_nodes: must be a positive integer, got {n_nodes!r}")
    ids = np.array(
        [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"node{i}") for i in range(n_nodes)]
    )
    missing = np.flatnonzero(ids < 0)
    if missing.size:
        raise ValueError(f"n_nodes: the model has no site 'node{missing[0]}'")
    return ids


def _check_dim(dim: Any) -> None:
    if dim not in (2, 3) or isinstance(dim, bool):
        raise ValueError(f"dim: must be 3, or 2 for a planar structure, got {dim!r}")


def mujoco_node_positions(model: Any, data: Any, n_nodes: int, *, dim: int = 3) -> np.ndarray:
    """Node positions [m], shape (N, dim), of a MuJoCo model built from :func:`to_mjcf`.

    Calls ``mujoco.mj_kinematics`` first (after ``mj_step`` with RK4, ``site_xpos`` holds the last
    Runge-Kutta stage, not the end of the step), then reads ``site_xpos`` in node order.
    ``dim=2`` (a planar structure, in the plane ``z = 0``) returns the ``x, y`` columns.
    """
    import mujoco

    _check_dim(dim)
    ids = node_site_ids(model, n_nodes)
    mujoco.mj_kinematics(model, data)
    return data.site_xpos[ids, :dim].copy()


def mujoco_node_velocities(model: Any, data: Any, n_nodes: int, *, dim: int = 3) -> np.ndarray:
    """Node velocities [m/s], shape (N, dim), world frame, of a model built from :func:`to_mjcf`
    (``dim=2``: the ``x, y`` columns of a planar structure's).

    Calls ``mujoco.mj_kinematics``, ``mujoco.mj_comPos`` and ``mujoco.mj_comVel`` (which
    ``mj_objectVelocity`` needs) first.
    """
    import mujoco

    _check_dim(dim)
    ids = node_site_ids(model, n_nodes)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_comVel(model, data)
    out = np.empty((n_nodes, 3))
    twist = np.empty(6)
    for k, site in enumerate(ids):
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, int(site), twist, 0)
        out[k] = twist[3:]
    return out[:, :dim]
