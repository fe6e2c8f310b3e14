"""Rolling a six-bar robot from face to face by its cables (``docs/simulation.md``, "Ground
contact").

:func:`six_bar_roll` stands a :func:`~tensegrity.design.catalogue.six_bar_robot` on one of its
cable triangles on the ground ``z = 0`` and plans, step by step, the rest-length changes that tip
it over an edge of its support face onto the next, in a roughly straight line, as a
:class:`~tensegrity.model.loads.ControlTable` for ``simulate(control=...)`` (or, written as CSV,
``tensegrity simulate --control-table``).

Each step, on the support face ``F`` and the edge ``(i, j)`` chosen to tip over:

1. **Margin.**  ``m(u)`` [m] is the distance of the centre of mass, projected on ``F``'s plane
   along its normal, inside the edge, at the free structure's equilibrium under the control ``u``
   (:func:`~tensegrity.analysis.equilibrium.find_equilibrium`, no gravity, no ground).  The robot
   tips when ``m < 0``.
2. **Sensitivity.**  The gradients of ``m`` and of the tensions ``T`` [N] with respect to the
   actuated cables' ``u`` are taken by finite differences of that equilibrium (the structure is
   chiral: no symmetric rule such as "shorten the two cables of the edge" does it).
3. **Linear program** (:func:`scipy.optimize.linprog`): the least ``sum |u|`` with ``m`` linearized
   ``<= -overshoot``, every tension linearized ``>= min_tension`` and ``|u| <= max_change``
   times the cable's rest length; repeated from the solution (Newton's method on the active
   constraints) until the equilibrium's own margin is within 10 % of ``-overshoot``.
4. **Rigid rolling** predicts the next faces, with the shape under the control: the other face
   of the nodes' convex hull on the edge, and on over the edge of that face with the lowest
   centre of mass above it while the centre of mass, right above the edge it came over, was
   higher by more than ``overshoot`` (the energy of the fall, less what the impact takes, carries
   it over: an open triangle between two bars' ends is passed so, the next cable triangle holds
   it), or at once if the centre of mass lies beyond an edge.  The next step's edge is the one of
   the last face that the heading (the first edge's outward normal on the ground) crosses from
   the centre of mass, so the path stays straight.

The control ramps linearly to each step's ``u`` in ``ramp`` seconds, holds it ``hold`` seconds
and ramps back to zero in ``ramp`` seconds; ``pause`` seconds separate the steps (and precede the
first).  Faces alternate between cable triangles and the open triangles between two bars' ends.

Assumptions and limits: the plan is quasi-static and rigid.  It ignores the sag under gravity
(the margin of the free structure's equilibrium stands in for the loaded one's; ``overshoot``
covers the difference) and predicts rolling on by the rigid body's energy, not its dynamics: a
run may stop on a face the plan passes, or pass one it stops on, near the threshold.  The path
zig-zags about the heading (a cable triangle's edges are 120 degrees apart).  It needs friction
enough to roll rather than slide (it does not check the cone) and a flat ground.  The robot
must be a six-bar without payload or supports; :func:`stand_on_face` places its nodes.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from tensegrity.model.ground import Scene, ground
from tensegrity.model.loads import ControlTable
from tensegrity.model.structure import Structure

#: Gravity of the plans' scenes [m/s^2].
STANDARD_GRAVITY = 9.81


class RollPlan(NamedTuple):
    """What :func:`six_bar_roll` plans: the robot on its first face, its control, the predicted
    faces and edges, and the scene to run it in (``simulate(plan.structure, (0, plan.t_end),
    control=plan.control, **plan.scene.simulate_options())``)."""

    structure: Structure  #: the robot standing on its first face, on ``z = 0``
    control: ControlTable  #: the rest-length changes ``u(t)`` [m], (T, S)
    faces: tuple[
        tuple[int, int, int], ...
    ]  #: the support faces rigid rolling predicts, first to last
    edges: tuple[tuple[int, int], ...]  #: the edge each step tips over (steps)
    shortening: np.ndarray  #: (steps, S) each step's ``u`` [m]
    heading: np.ndarray  #: (2,) the unit direction on the ground the plan rolls towards
    scene: Scene  #: the ground ``z = 0`` with the friction given, contact radius, gravity
    t_end: float  #: the table's last time plus ``pause`` [s]


def _rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The smallest rotation (3, 3) taking the unit vector ``a`` to the unit vector ``b``."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    if np.linalg.norm(v) < 1e-12:
        if c > 0:
            return np.eye(3)
        w = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
        w /= np.linalg.norm(w)
        return 2.0 * np.outer(w, w) - np.eye(3)
    k = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + c)


def _outward(p: np.ndarray, face: tuple[int, ...]) -> np.ndarray:
    """The unit normal of ``face``'s plane pointing away from the nodes ``p`` (N, 3)."""
    a, b, c = p[list(face)]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    return -n if np.dot(n, p.mean(axis=0) - a) > 0 else n


def stand_on_face(structure: Structure, face: Any, *, contact_radius: float = 0.0) -> Structure:
    """``structure`` turned so that the face ``face`` (three node numbers) of its nodes' convex
    hull lies flat under it, the face's node centres at ``z = contact_radius`` [m].

    ``ValueError`` naming ``face`` if it is not three nodes of a face of the hull.
    """
    p = structure.node_position
    nodes = _hull_face(p, face)
    q = p @ _rotation(_outward(p, nodes), np.array([0.0, 0.0, -1.0])).T
    q[:, 2] += contact_radius - q[list(nodes), 2].mean()
    return structure.replace(node_position=q)


def _hull_faces(p: np.ndarray) -> list[frozenset[int]]:
    from scipy.spatial import ConvexHull

    return [frozenset(int(k) for k in s) for s in ConvexHull(p).simplices]


def _hull_face(p: np.ndarray, face: Any) -> tuple[int, int, int]:
    try:
        nodes = tuple(int(k) for k in face)
    except (TypeError, ValueError):
        raise ValueError(f"face: expected three node numbers, got {face!r}") from None
    if len(nodes) != 3 or frozenset(nodes) not in _hull_faces(p):
        raise ValueError(f"face: {face!r} is not a face of the nodes' convex hull")
    return nodes


def _margin(p: np.ndarray, mass: np.ndarray, face: tuple[int, ...], edge: tuple[int, int]) -> float:
    """Distance [m] of the centre of mass, projected on ``face``'s plane, inside ``edge``."""
    n = _outward(p, face)
    com = mass @ p / mass.sum()
    a = p[face[0]]
    foot = com - np.dot(com - a, n) * n
    P, Q = p[edge[0]], p[edge[1]]
    R = p[next(k for k in face if k not in edge)]
    e = (Q - P) / np.linalg.norm(Q - P)
    inward = (R - P) - np.dot(R - P, e) * e
    return float(np.dot(foot - P, inward / np.linalg.norm(inward)))


def _node_mass(structure: Structure) -> np.ndarray:
    """The structure's mass [kg] lumped on its nodes (half of each rod on each end)."""
    mass = np.array(structure.node_point_mass, dtype=float)
    np.add.at(mass, structure.rod_nodes.ravel(), np.repeat(structure.rod_mass, 2) / 2.0)
    return mass


def _step_control(
    structure: Structure,
    face: tuple[int, int, int],
    edge: tuple[int, int],
    *,
    actuated: np.ndarray,
    overshoot: float,
    min_tension: float,
    max_change: float,
    delta: float = 1e-4,
    iterations: int = 8,
) -> np.ndarray:
    """The least-``sum |u|`` control (S,) [m] that puts the free equilibrium's centre of mass
    ``overshoot`` [m] past ``edge`` of ``face`` (module doc, steps 1-3)."""
    from scipy.optimize import linprog

    from tensegrity.analysis.equilibrium import find_equilibrium

    mass = _node_mass(structure)
    S, A = structure.n_tendons, len(actuated)
    bound = max_change * structure.tendon_rest_length[actuated]
    u = np.zeros(S)

    def state(u: np.ndarray) -> tuple[float, np.ndarray]:
        eq = find_equilibrium(structure, control=u)
        if not eq.converged:
            raise RuntimeError(f"six_bar_roll: no equilibrium under the control {u!r}")
        return _margin(eq.node_position, mass, face, edge), np.asarray(eq.tension, dtype=float)

    for _ in range(iterations):
        m, T = state(u)
        if abs(m + overshoot) <= 0.1 * overshoot and T.min() >= min_tension:
            return u
        grad_m, grad_T = np.empty(A), np.empty((S, A))
        for col, s in enumerate(actuated):
            du = u.copy()
            du[s] += delta
            m_s, T_s = state(du)
            grad_m[col], grad_T[:, col] = (m_s - m) / delta, (T_s - T) / delta
        # the new control v = v+ - v- of the actuated cables, both parts >= 0: least sum |v|
        ua = u[actuated]
        lhs = np.vstack([np.hstack([grad_m, -grad_m]), np.hstack([-grad_T, grad_T])])
        rhs = np.concatenate([[grad_m @ ua - overshoot - m], T - min_tension - grad_T @ ua])
        bounds = [(0.0, b) for b in bound] * 2
        lp = linprog(np.ones(2 * A), A_ub=lhs, b_ub=rhs, bounds=bounds, method="highs")
        if lp.status != 0:
            raise RuntimeError(
                f"six_bar_roll: no control tips face {face} over edge {edge} "
                f"({lp.message}); lower overshoot or min_tension, or raise max_change"
            )
        u[actuated] = lp.x[:A] - lp.x[A:]
    raise RuntimeError(
        f"six_bar_roll: the control over edge {edge} of face {face} did not converge in "
        f"{iterations} linear programs"
    )


def _tip(p: np.ndarray, face: tuple[int, ...], new: tuple[int, ...]) -> np.ndarray:
    """The nodes ``p`` (on the ground by ``face``) turned about the edge ``face`` shares with
    ``new`` until ``new`` lies on the ground."""
    pivot = next(k for k in face if k in new)
    q = p @ _rotation(_outward(p, new), np.array([0.0, 0.0, -1.0])).T
    return q + p[pivot] - q[pivot]


def _apex(p: np.ndarray, mass: np.ndarray, edge: tuple[int, int]) -> float:
    """Height [m] of the centre of mass over the ground when it is right above ``edge``."""
    P, Q = p[edge[0]], p[edge[1]]
    e = (Q - P) / np.linalg.norm(Q - P)
    v = mass @ p / mass.sum() - P
    return float(np.linalg.norm(v - np.dot(v, e) * e))


def _rolled_faces(
    p: np.ndarray,
    mass: np.ndarray,
    hull: list[frozenset[int]],
    face: tuple[int, ...],
    edge: tuple[int, int],
    drop: float,
) -> list[tuple[int, int, int]]:
    """The faces a rigid body of nodes ``p`` (the shape under the step's control) rolls onto
    from ``face`` over ``edge`` (module doc, step 4)."""
    faces: list[tuple[int, int, int]] = []
    for _ in range(len(hull)):
        top = _apex(p, mass, edge)
        other = next(f for f in hull if set(edge) <= f and f != frozenset(face))
        face = tuple(sorted(other))
        faces.append(face)  # type: ignore[arg-type]
        out = [(face[k], face[(k + 1) % 3]) for k in range(3)]
        out = [e for e in out if set(e) != set(edge)]
        beyond = [e for e in out if _margin(p, mass, face, e) < 0]
        edge = min(out, key=lambda e: _apex(p, mass, e))
        if beyond:
            edge = beyond[0]
        elif top - _apex(p, mass, edge) <= drop:
            break
    return faces


def _crossed_edge(
    p: np.ndarray, mass: np.ndarray, face: tuple[int, ...], heading: np.ndarray
) -> tuple[int, int]:
    """The edge of the (ground) ``face`` a ray along ``heading`` from the centre of mass's
    ground projection leaves it through."""
    com = (mass @ p / mass.sum())[:2]
    best: tuple[float, tuple[int, int]] | None = None
    for k in range(3):
        i, j = face[k], face[(k + 1) % 3]
        P, Q, R = p[i, :2], p[j, :2], p[face[(k + 2) % 3], :2]
        out = np.array([Q[1] - P[1], P[0] - Q[0]])
        if np.dot(R - P, out) > 0:
            out = -out
        rate = float(np.dot(out, heading))
        if rate <= 0:
            continue
        distance = float(np.dot(P - com, out)) / rate
        if best is None or distance < best[0]:
            best = (distance, (i, j))
    assert best is not None  # a ray from inside a triangle leaves it
    return best[1]


def support_faces(run: Any) -> list[tuple[float, tuple[int, ...]]]:
    """``(time [s], nodes)`` of each support triangle a run (a ``SimulationResult``) stands on,
    in turn: the samples where exactly three contact points are in contact (``contact_mode``
    not free), each new triangle recorded once."""
    faces: list[tuple[float, tuple[int, ...]]] = []
    for t, mode in zip(run.t, run.contact_mode, strict=True):
        nodes = tuple(int(k) for k in run.contact_node[mode != 0])
        if len(nodes) == 3 and (not faces or faces[-1][1] != nodes):
            faces.append((float(t), nodes))
    return faces


def six_bar_roll(
    robot: Structure,
    *,
    face: Any = (0, 4, 8),
    edge: Any = None,
    steps: int = 4,
    overshoot: float = 0.02,
    min_tension: float | None = None,
    max_change: float = 0.4,
    ramp: float = 0.5,
    hold: float = 1.0,
    pause: float = 0.5,
    contact_radius: float = 0.01,
    friction: float = 0.8,
    kinetic_friction: float = 0.6,
) -> RollPlan:
    """Plan the rest-length changes that roll ``robot`` over ``steps`` successive faces in a
    roughly straight line (module doc: the method, its assumptions and limits).

    Parameters
    ----------
    robot : Structure
        A :func:`~tensegrity.design.catalogue.six_bar_robot` (no payload), in any pose.
    face : three node numbers
        The face it starts on, a face of the nodes' convex hull (default ``(0, 4, 8)``, the cable
        triangle ``f---``).
    edge : two node numbers of ``face``, optional
        The first edge to tip over; it sets the heading (its outward normal on the ground).
        Default: the edge without ``face``'s lowest node number.
    steps : int
        Number of tips planned (>= 1).
    overshoot : float
        How far [m] past the edge each step's control puts the free equilibrium's centre of mass.
    min_tension : float, optional
        Least tension [N] any cable may have under a step's control; default half the least
        tension of ``robot``'s own equilibrium.
    max_change : float
        Largest ``|u|`` of a cable as a fraction of its rest length.
    ramp, hold, pause : float
        Seconds [s]: each step's ramp in (and out), hold, and the rest before each step and at
        the end.
    contact_radius, friction, kinetic_friction : float
        The scene's contact radius [m] and the ground's static and kinetic friction.

    Returns
    -------
    RollPlan

    Raises
    ------
    ValueError
        Naming the argument: ``face`` not a hull face, ``edge`` not an edge of it, a count or
        time not > 0.
    RuntimeError
        No control within the bounds tips a step (the linear program is infeasible).
    """
    from tensegrity.analysis.equilibrium import find_equilibrium
    from tensegrity.design.catalogue import actuated_cables

    if not isinstance(robot, Structure):
        raise TypeError(f"robot: expected a Structure, got {type(robot).__name__}")
    if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
        raise ValueError(f"steps: expected an integer >= 1, got {steps!r}")
    for name, value in (("overshoot", overshoot), ("max_change", max_change), ("ramp", ramp),
                        ("hold", hold), ("pause", pause)):  # fmt: skip
        if not np.isfinite(value) or value <= 0:
            raise ValueError(f"{name}: must be > 0, got {value!r}")
    start = _hull_face(robot.node_position, face)
    if edge is None:
        low = min(start)
        edge = tuple(k for k in start if k != low)
    try:
        first = (int(edge[0]), int(edge[1]))
    except (TypeError, ValueError, IndexError):
        raise ValueError(f"edge: expected two node numbers, got {edge!r}") from None
    if len(tuple(edge)) != 2 or not set(first) < set(start):
        raise ValueError(f"edge: {edge!r} is not an edge of face {face!r}")
    names = set(actuated_cables(robot))
    actuated = np.array([s for s, n in enumerate(robot.tendon_name) if n in names], dtype=int)
    if min_tension is None:
        min_tension = 0.5 * float(np.min(find_equilibrium(robot).tension))

    placed = stand_on_face(robot, start, contact_radius=contact_radius)
    p = placed.node_position
    mass = _node_mass(robot)
    hull = _hull_faces(p)
    P, Q = p[first[0], :2], p[first[1], :2]
    R = p[next(k for k in start if k not in first), :2]
    heading = np.array([Q[1] - P[1], P[0] - Q[0]])
    heading *= -1.0 if np.dot(R - P, heading) > 0 else 1.0
    heading /= np.linalg.norm(heading)

    faces: list[tuple[int, int, int]] = [tuple(sorted(start))]  # type: ignore[list-item]
    edges: list[tuple[int, int]] = []
    shortening = []
    current, this_edge = start, first
    for _ in range(steps):
        shortening.append(
            _step_control(
                robot,
                current,
                this_edge,
                actuated=actuated,
                overshoot=overshoot,
                min_tension=min_tension,
                max_change=max_change,
            )
        )
        edges.append(this_edge)
        shape = find_equilibrium(robot, control=shortening[-1]).node_position
        for face_k in _rolled_faces(shape, mass, hull, current, this_edge, overshoot):
            p = _tip(p, current, face_k)
            faces.append(face_k)
            current = face_k
        this_edge = _crossed_edge(p, mass, current, heading)

    zero = np.zeros(robot.n_tendons)
    times, rows = [0.0], [zero]
    t = pause
    for u in shortening:
        times += [t, t + ramp, t + ramp + hold, t + 2 * ramp + hold]
        rows += [zero, u, u, zero]
        t += 2 * ramp + hold + pause
    scene = Scene(
        planes=(ground(friction=friction, kinetic_friction=kinetic_friction),),
        contact_radius=contact_radius,
        gravity=(0.0, 0.0, -STANDARD_GRAVITY),
    )
    return RollPlan(
        structure=placed,
        control=ControlTable(np.array(times), np.array(rows)),
        faces=tuple(faces),
        edges=tuple(edges),
        shortening=np.array(shortening),
        heading=heading,
        scene=scene,
        t_end=t,
    )
