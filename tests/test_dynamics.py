"""Physics of the equations of motion, checked against evidence that shares no code with them.

The reference here is an independent formulation written in this file: every rod is described by
its two end points ``x = [p_a; p_b]`` with the consistent mass matrix of a uniform rod,
``(m/6) [[2I, I], [I, 2I]]``, its length is held by a Lagrange multiplier on
``|p_b - p_a|^2 = L^2``, and the KKT system is solved with ``numpy.linalg.solve``.  Tendon forces
are assembled by an explicit loop over tendons.  Nothing of Theorem 18.1 (no ``skew(q2)^2``, no
``|q2'|^2 / L^2`` term) is used: agreement to round-off means the library's explicit formulas
solve the constrained rigid-rod problem.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from tensegrity import Structure, accelerations, artificial_damping, class1_shell
from tensegrity.physics.dynamics import (
    elastic_energy,
    kinetic_energy,
    nodes_from_coordinates,
    tendon_forces,
    tendon_tensions,
)

# --------------------------------------------------------------------------- the reference


def reference_tendon_tension(k, c, rest, length, rate):
    """A cable: pulls with ``k (l - Lbar) + c l'`` while taut (``l > Lbar``), never pushes."""
    if length <= rest:
        return 0.0
    return max(k * (length - rest) + c * rate, 0.0)


def reference_nodal_forces(structure, p, v, rest, external=None, gravity=None):
    """Nodal forces (N, 3) from an explicit loop over tendons, plus external forces and gravity.

    Gravity on a uniform rod: a force ``dm g`` on every element; its virtual work with linear
    interpolation between the end points puts ``m g / 2`` on each end.
    """
    f = np.zeros((structure.n_nodes, 3))
    for s in range(structure.n_tendons):
        tail, head = (int(x) for x in structure.tendon_nodes[s])
        t = p[head] - p[tail]
        length = math.sqrt(float(t @ t))
        e = t / length
        rate = float(e @ (v[head] - v[tail]))
        tension = reference_tendon_tension(
            structure.tendon_stiffness[s], structure.tendon_damping[s], rest[s], length, rate
        )
        f[tail] += tension * e  # the tail is pulled toward the head
        f[head] -= tension * e
    if external is not None:
        f += external
    if gravity is not None:
        for r, (a, b) in enumerate(structure.rod_nodes):
            f[a] += 0.5 * structure.rod_mass[r] * np.asarray(gravity)
            f[b] += 0.5 * structure.rod_mass[r] * np.asarray(gravity)
    return f


def reference_mass_matrix(structure):
    """The consistent mass matrix (3N, 3N) of uniform rods in end-point coordinates."""
    n = structure.n_nodes
    M = np.zeros((3 * n, 3 * n))
    eye = np.eye(3)
    for r, (a, b) in enumerate(structure.rod_nodes):
        m = structure.rod_mass[r]
        for i, j, w in ((a, a, 2), (b, b, 2), (a, b, 1), (b, a, 1)):
            M[3 * i : 3 * i + 3, 3 * j : 3 * j + 3] += (m / 6) * w * eye
    return M


def reference_node_accelerations(structure, p, v, rest, external=None, gravity=None):
    """Solve ``[[M, G^T], [G, 0]] [a; lambda] = [f; -Gdot v]`` with ``g_r = |p_b - p_a|^2 - L^2``.

    Rod damping ``alpha`` is the generalized force of ``-alpha dm v`` on every mass element,
    ``-alpha M v``.
    """
    n, R = structure.n_nodes, structure.n_rods
    M = reference_mass_matrix(structure)
    f = reference_nodal_forces(structure, p, v, rest, external, gravity).reshape(-1)
    for r, (a, b) in enumerate(structure.rod_nodes):
        alpha = structure.rod_damping[r]
        idx = np.r_[3 * a : 3 * a + 3, 3 * b : 3 * b + 3]
        f[idx] -= alpha * M[np.ix_(idx, idx)] @ v.reshape(-1)[idx]
    G = np.zeros((R, 3 * n))
    rhs_c = np.zeros(R)
    for r, (a, b) in enumerate(structure.rod_nodes):
        d = p[b] - p[a]
        dv = v[b] - v[a]
        G[r, 3 * a : 3 * a + 3] = -2 * d
        G[r, 3 * b : 3 * b + 3] = 2 * d
        rhs_c[r] = -2 * float(dv @ dv)  # d^2/dt^2 |d|^2 = 2 d.d'' + 2 |d'|^2 = 0
    kkt = np.block([[M, G.T], [G, np.zeros((R, R))]])
    sol = np.linalg.solve(kkt, np.concatenate([f, rhs_c]))
    return sol[: 3 * n].reshape(n, 3)


def to_coordinates(structure, node_value):
    """``q = [p_a + p_b, p_b - p_a]`` rod by rod (the paper's eq. 18.24), written out here."""
    out = []
    for a, b in structure.rod_nodes:
        out += [node_value[a] + node_value[b], node_value[b] - node_value[a]]
    return np.concatenate(out)


def random_consistent_state(structure, rng, speed=1.0, jitter=0.15):
    """Node positions with every rod exactly ``L`` long, near the structure's layout, and node
    velocities with ``(v_b - v_a) . (p_b - p_a) = 0`` for every rod."""
    p = np.empty((structure.n_nodes, 3))
    v = np.empty((structure.n_nodes, 3))
    for r, (a, b) in enumerate(structure.rod_nodes):
        L = structure.rod_length[r]
        p0a, p0b = structure.node_position[a], structure.node_position[b]
        centre = 0.5 * (p0a + p0b) + jitter * rng.standard_normal(3)
        d = (p0b - p0a) / L + jitter * rng.standard_normal(3)
        d *= L / np.linalg.norm(d)
        p[a], p[b] = centre - d / 2, centre + d / 2
        vc = speed * rng.standard_normal(3)
        w = speed * rng.standard_normal(3)
        dv = np.cross(w, d)  # perpendicular to the rod
        v[a], v[b] = vc - dv / 2, vc + dv / 2
    return p, v


def mixed_controls(structure, p, rng):
    """Random controls ``u`` with ``Lbar = L0 - u >= 0``: about a third of the tendons slack
    (``Lbar`` above the current length), one with ``Lbar = 0``, the rest taut by a random amount."""
    lengths = np.array([np.linalg.norm(p[h] - p[t]) for t, h in structure.tendon_nodes])
    S = structure.n_tendons
    rest = lengths * rng.uniform(0.3, 0.98, S)
    slack = rng.permutation(S)[: S // 3]
    rest[slack] = lengths[slack] * rng.uniform(1.02, 1.5, slack.size)
    taut = np.setdiff1d(np.arange(S), slack)
    rest[taut[0]] = 0.0
    u = structure.tendon_rest_length - rest
    return u, rest, slack


SHELLS = [
    pytest.param(dict(n=3, m=1), id="shell(3,1)"),
    pytest.param(dict(n=4, m=2), id="shell(4,2)"),
    pytest.param(dict(n=5, m=3), id="shell(5,3)"),
    pytest.param(dict(n=4, m=2, primal=True), id="primal(4,2)"),
    pytest.param(dict(n=3, m=2, primal=True), id="primal(3,2)"),
]


def _relative_error(actual, expected):
    return float(np.max(np.abs(actual - expected)) / np.max(np.abs(expected)))


# --------------------------------------------------------------------------- accelerations


@pytest.mark.parametrize("with_gravity", [False, True], ids=["no-gravity", "gravity"])
@pytest.mark.parametrize("shell", SHELLS)
def test_accelerations_match_constrained_lagrangian(shell, with_gravity):
    """Theorem 18.1 == KKT solution of the end-point Lagrangian, on random consistent states with
    random controls (a third of the tendons slack), random external forces and gravity."""
    rng = np.random.default_rng(zlib.crc32(repr((sorted(shell.items()), with_gravity)).encode()))
    structure = class1_shell(**shell)
    gravity = np.array([0.3, -1.1, -9.81]) if with_gravity else None
    for trial in range(3):
        p, v = random_consistent_state(structure, rng)
        u, rest, slack = mixed_controls(structure, p, rng)
        w = 20.0 * rng.standard_normal((structure.n_nodes, 3))
        expected = reference_node_accelerations(structure, p, v, rest, w, gravity)
        qddot = accelerations(
            structure,
            to_coordinates(structure, p),
            to_coordinates(structure, v),
            control=u,
            external_force=w,
            gravity=gravity,
        )
        got = nodes_from_coordinates(structure, qddot)
        # The state really has slack tendons (zero tension) and taut ones.
        tension = tendon_tensions(structure, p, v, control=u)
        assert np.all(tension[slack] == 0) and np.all(
            tension[np.setdiff1d(range(len(u)), slack)] > 0
        )
        assert _relative_error(got, expected) < 1e-9, f"trial {trial}"


@pytest.mark.parametrize("shell", SHELLS[:3])
def test_accelerations_with_tendon_and_rod_damping_match_lagrangian(shell):
    """Damped structure (tendon damping only while taut, mass-proportional rod damping):
    the damping forces enter the same KKT reference as generalized forces."""
    rng = np.random.default_rng(7)
    structure = artificial_damping(class1_shell(**shell))
    # Random, unequal damping values so that a wrong index would show.
    structure = structure.replace(
        tendon_damping=rng.uniform(0.5, 15.0, structure.n_tendons),
        rod_damping=rng.uniform(0.1, 5.0, structure.n_rods),
    )
    for _ in range(3):
        p, v = random_consistent_state(structure, rng, speed=3.0)
        u, rest, _ = mixed_controls(structure, p, rng)
        expected = reference_node_accelerations(structure, p, v, rest)
        got = nodes_from_coordinates(
            structure,
            accelerations(
                structure, to_coordinates(structure, p), to_coordinates(structure, v), control=u
            ),
        )
        assert _relative_error(got, expected) < 1e-9


def test_accelerations_of_random_general_structure_match_lagrangian():
    """Not a shell: random rods of different masses and lengths, tendons between random pairs of
    nodes with different stiffnesses, rest lengths and damping."""
    rng = np.random.default_rng(2024)
    R = 5
    lengths = rng.uniform(0.5, 2.0, R)
    masses = rng.uniform(0.2, 3.0, R)
    p = np.empty((2 * R, 3))
    for r in range(R):
        d = rng.standard_normal(3)
        d *= lengths[r] / np.linalg.norm(d)
        c = 2.0 * rng.standard_normal(3)
        p[2 * r], p[2 * r + 1] = c - d / 2, c + d / 2
    pairs = [(a, b) for a in range(2 * R) for b in range(a + 1, 2 * R) if a // 2 != b // 2]
    chosen = [pairs[i] for i in rng.choice(len(pairs), 18, replace=False)]
    tendon_nodes = [(b, a) if rng.random() < 0.5 else (a, b) for a, b in chosen]
    tl = np.array([np.linalg.norm(p[h] - p[t]) for t, h in tendon_nodes])
    structure = Structure(
        node_position=p,
        rod_nodes=np.arange(2 * R).reshape(R, 2),
        rod_mass=masses,
        rod_length=lengths,
        tendon_nodes=tendon_nodes,
        tendon_stiffness=rng.uniform(10, 500, len(chosen)),
        tendon_rest_length=tl * rng.uniform(0.5, 1.3, len(chosen)),
        tendon_damping=rng.uniform(0, 5, len(chosen)),
        rod_damping=rng.uniform(0, 2, R),
    )
    _, v = random_consistent_state(structure, rng, speed=2.0, jitter=0.0)
    rest = structure.tendon_rest_length
    assert 0 < np.sum(tl < rest) < len(chosen)  # some slack, some taut
    expected = reference_node_accelerations(structure, p, v, rest, gravity=[0, 0, -9.81])
    got = nodes_from_coordinates(
        structure,
        accelerations(
            structure,
            to_coordinates(structure, p),
            to_coordinates(structure, v),
            gravity=np.array([0, 0, -9.81]),
        ),
    )
    assert _relative_error(got, expected) < 1e-9


def test_accelerations_keep_rods_rigid_to_second_order():
    """``d^2/dt^2 |p_b - p_a|^2 = 0``: the node accelerations respect every rod constraint."""
    rng = np.random.default_rng(3)
    structure = class1_shell(4, 2)
    p, v = random_consistent_state(structure, rng, speed=2.0)
    u, _, _ = mixed_controls(structure, p, rng)
    acc = nodes_from_coordinates(
        structure,
        accelerations(
            structure, to_coordinates(structure, p), to_coordinates(structure, v), control=u
        ),
    )
    a, b = structure.rod_nodes.T
    d, dv, da = p[b] - p[a], v[b] - v[a], acc[b] - acc[a]
    second = np.sum(d * da, axis=1) + np.sum(dv * dv, axis=1)
    assert np.max(np.abs(second)) < 1e-10 * np.max(
        np.sum(dv * dv, axis=1) + np.abs(np.sum(d * da, axis=1))
    )


def test_free_rod_with_forces_obeys_newton_euler():
    """One rod, forces at its ends: the centre accelerates with ``F/m``, and the rod's angular
    acceleration about its centre is ``tau / I`` with ``I = m L^2 / 12`` (perpendicular part),
    plus the centripetal term ``-|w|^2 d``: Newton-Euler, a second independent reference."""
    m, L = 2.5, 1.7
    d = np.array([0.3, -0.5, 0.8])
    d *= L / np.linalg.norm(d)
    c = np.array([0.1, 0.2, 0.3])
    p = np.array([c - d / 2, c + d / 2])
    structure = Structure(
        node_position=p,
        rod_nodes=[[0, 1]],
        rod_mass=[m],
        rod_length=[L],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
    )
    omega = np.array([1.0, 2.0, -0.5])
    omega -= (omega @ d) / L**2 * d  # spin about the axis is not a degree of freedom
    vc = np.array([0.4, 0.0, -0.2])
    v = np.array([vc - np.cross(omega, d) / 2, vc + np.cross(omega, d) / 2])
    f = np.array([[1.0, -3.0, 2.0], [0.5, 4.0, -1.0]])
    qddot = accelerations(
        structure, to_coordinates(structure, p), to_coordinates(structure, v), external_force=f
    )
    acc = nodes_from_coordinates(structure, qddot)
    F = f.sum(axis=0)
    tau = np.cross(-d / 2, f[0]) + np.cross(d / 2, f[1])
    inertia = m * L**2 / 12
    alpha = tau / inertia
    alpha -= (alpha @ d) / L**2 * d
    # d'' = alpha x d + w x (w x d) ; w perpendicular to d gives w x (w x d) = -|w|^2 d
    dd = np.cross(alpha, d) + np.cross(omega, np.cross(omega, d))
    expected = np.array([F / m - dd / 2, F / m + dd / 2])
    assert _relative_error(acc, expected) < 1e-12


# --------------------------------------------------------------------------- tendon law


def _two_rod_tendon(k=80.0, c=0.0, rest=1.0):
    """Two parallel unit rods along x, 2 m apart in y; one tendon from node 0 (tail) to node 2."""
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 2.0, 0], [1, 2.0, 0]])
    return Structure(
        node_position=p,
        rod_nodes=[[0, 1], [2, 3]],
        rod_mass=[1.0, 1.0],
        rod_length=[1.0, 1.0],
        tendon_nodes=[[0, 2]],
        tendon_stiffness=[k],
        tendon_rest_length=[rest],
        tendon_damping=[c],
    )


@pytest.mark.parametrize("gap", [0.5, 1.0, 1.7, 2.0, 2.000001, 2.5, 3.9])
def test_tendon_tension_closed_form_without_damping(gap):
    k, rest = 80.0, 2.0
    structure = _two_rod_tendon(k=k, rest=rest)
    p = structure.node_position.copy()
    p[2:, 1] = gap
    tension = tendon_tensions(structure, p)[0]
    expected = k * (gap - rest) if gap > rest else 0.0
    assert tension == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert float(elastic_energy(structure, p)) == pytest.approx(
        0.5 * k * max(gap - rest, 0.0) ** 2, rel=1e-12, abs=1e-15
    )


@pytest.mark.parametrize(
    "gap, rate, expected",
    [
        (2.5, 0.0, 80 * 0.5),  # taut, at rest: elastic only
        (2.5, 3.0, 80 * 0.5 + 6 * 3.0),  # taut, lengthening: damping adds
        (2.5, -3.0, 80 * 0.5 - 6 * 3.0),  # taut, shortening: damping subtracts
        (2.5, -100.0, 0.0),  # taut, shortening fast: would push, clipped to 0
        (1.5, 50.0, 0.0),  # slack and lengthening: no damping while slack
        (1.5, -50.0, 0.0),  # slack and shortening
        (2.0, 10.0, 0.0),  # exactly at rest length: slack (l > Lbar is taut)
    ],
)
def test_tendon_tension_damping_only_while_taut_and_never_negative(gap, rate, expected):
    k, c, rest = 80.0, 6.0, 2.0
    structure = _two_rod_tendon(k=k, c=c, rest=rest)
    p = structure.node_position.copy()
    p[2:, 1] = gap
    v = np.zeros_like(p)
    v[2:, 1] = rate / 2  # head end moves away at rate/2, tail end toward -y at rate/2
    v[:2, 1] = -rate / 2
    forces = tendon_forces(structure, p, v, structure.tendon_rest_length)
    assert forces.length[0] == pytest.approx(gap, rel=1e-14)
    assert forces.length_rate[0] == pytest.approx(rate, rel=1e-14, abs=1e-14)
    assert forces.tension[0] == pytest.approx(expected, rel=1e-12, abs=1e-12)
    assert forces.tension[0] >= 0


def test_tendon_control_shortens_rest_length():
    """``Lbar = L0 - u``: a positive control makes a slack tendon taut with ``k (l - L0 + u)``."""
    k = 80.0
    structure = _two_rod_tendon(k=k, rest=2.5)
    p = structure.node_position
    assert tendon_tensions(structure, p)[0] == 0.0
    assert tendon_tensions(structure, p, control=np.array([1.0]))[0] == pytest.approx(k * 0.5)
    assert tendon_tensions(structure, p, control=np.array([2.5]))[0] == pytest.approx(k * 2.0)


def test_tendon_pulls_its_end_nodes_together():
    """A taut tendon accelerates the two rods toward each other, along the tendon, with equal and
    opposite forces: centre accelerations ``+-T / m`` and the rods start to rotate."""
    k, gap, rest, m = 80.0, 2.0, 1.0, 1.0
    structure = _two_rod_tendon(k=k, rest=rest)
    p = structure.node_position
    q = to_coordinates(structure, p)
    acc = nodes_from_coordinates(structure, accelerations(structure, q, np.zeros_like(q)))
    T = k * (gap - rest)
    centre = 0.5 * (acc[0::2] + acc[1::2])
    assert centre[0] == pytest.approx([0, T / m, 0], abs=1e-12)
    assert centre[1] == pytest.approx([0, -T / m, 0], abs=1e-12)
    # A force T at the end of a rod, perpendicular to it: end acceleration T/m + (T L/2)(L/2)/I
    # = T/m + 3T/m = 4T/m at the loaded end, T/m - 3T/m = -2T/m at the free end.
    assert acc[0] == pytest.approx([0, 4 * T / m, 0], abs=1e-12)
    assert acc[1] == pytest.approx([0, -2 * T / m, 0], abs=1e-12)
    assert acc[2] == pytest.approx([0, -4 * T / m, 0], abs=1e-12)
    assert acc[3] == pytest.approx([0, 2 * T / m, 0], abs=1e-12)


# --------------------------------------------------------------------------- energies


def test_energies_match_independent_formulas():
    """Kinetic energy ``x'^T M x' / 2`` with the consistent mass matrix; elastic energy of taut
    tendons only, from an explicit loop."""
    rng = np.random.default_rng(11)
    structure = class1_shell(4, 2)
    p, v = random_consistent_state(structure, rng, speed=2.0)
    _, rest, _ = mixed_controls(structure, p, rng)
    M = reference_mass_matrix(structure)
    ke = 0.5 * v.reshape(-1) @ M @ v.reshape(-1)
    assert float(kinetic_energy(structure, to_coordinates(structure, v))) == pytest.approx(
        ke, rel=1e-13
    )
    el = 0.0
    for s, (t, h) in enumerate(structure.tendon_nodes):
        stretch = np.linalg.norm(p[h] - p[t]) - rest[s]
        el += 0.5 * structure.tendon_stiffness[s] * stretch**2 if stretch > 0 else 0.0
    assert float(elastic_energy(structure, p, rest)) == pytest.approx(el, rel=1e-13)


def test_accelerations_are_the_gradient_flow_of_the_energy():
    """Power balance: ``d/dt (E_kin + E_el) = w . v`` with no damping, evaluated with the library's
    accelerations and a finite-difference time derivative of the elastic energy."""
    rng = np.random.default_rng(5)
    structure = class1_shell(3, 2)
    p, v = random_consistent_state(structure, rng, speed=1.0)
    u, rest, _ = mixed_controls(structure, p, rng)
    w = 5.0 * rng.standard_normal(p.shape)
    acc = nodes_from_coordinates(
        structure,
        accelerations(
            structure,
            to_coordinates(structure, p),
            to_coordinates(structure, v),
            control=u,
            external_force=w,
        ),
    )
    M = reference_mass_matrix(structure)
    dke = v.reshape(-1) @ M @ acc.reshape(-1)
    h = 1e-6
    del_ = (
        float(elastic_energy(structure, p + h * v, rest))
        - float(elastic_energy(structure, p - h * v, rest))
    ) / (2 * h)
    assert dke + del_ == pytest.approx(float(np.sum(w * v)), rel=1e-6, abs=1e-6)
