"""Joints, supports and point masses (issue 5): constraint forces against closed forms,
invariants over long runs, and static equilibria from an independent energy minimization."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import optimize
from scipy.special import ellipk

from tensegrity import Structure, simulate
from tensegrity.model.shell import class2_joints, class2_shell, shell_node_index, shell_tendons
from tensegrity.physics import constraints as constraints_module, dynamics
from tensegrity.physics.constraints import constraints_of

G = 9.81
GRAVITY = np.array([0.0, 0.0, -G])
NO_TENDONS = dict(tendon_nodes=np.zeros((0, 2), int), tendon_stiffness=[], tendon_rest_length=[])


def pendulum(m: float = 2.0, L: float = 1.5, *, support: str, angle: float = 0.0) -> Structure:
    """A rod pinned at node 0 (at the origin), its free end at ``angle`` below the +x axis.

    ``support="fixed"`` fixes the rod's own end; ``"anchor"`` joins it to a fixed node of no rod.
    """
    tip = L * np.array([np.cos(angle), 0.0, -np.sin(angle)])
    if support == "fixed":
        return Structure(
            node_position=[[0, 0, 0], tip],
            rod_nodes=[[0, 1]],
            rod_mass=[m],
            rod_length=[L],
            node_fixed=[True, False],
            **NO_TENDONS,
        )
    return Structure(
        node_position=[[0, 0, 0], tip, [0, 0, 0]],
        rod_nodes=[[0, 1]],
        rod_mass=[m],
        rod_length=[L],
        node_fixed=[False, False, True],
        joint_nodes=[[0, 2]],
        **NO_TENDONS,
    )


@pytest.mark.parametrize("support", ["fixed", "anchor"])
def test_pinned_rod_reactions_match_the_physical_pendulum(support):
    """Support force on a uniform rod pinned at one end, from Newton-Euler about the pivot
    (``I = m L^2 / 3``, weight ``m g`` at ``L/2``):

    - released from rest horizontally: ``alpha = 3 g / (2 L)``, the centre falls at
      ``3 g / 4``, so the support pushes up with ``m g - m 3g/4 = m g / 4``;
    - hanging vertically with ``omega^2 = 3 g / L`` (after falling from horizontal): the centre
      accelerates ``omega^2 L / 2 = 3 g / 2`` upward, so the support pushes up with ``5 m g / 2``.
    """
    m, L = 2.0, 1.5
    s = pendulum(m, L, support=support)
    state = dynamics.initial_state(s)
    ev = dynamics.evaluate(
        s, state.q, state.qdot, rest_length=s.tendon_rest_length, gravity=GRAVITY
    )
    pivot = 2 if support == "anchor" else 0
    # The support's force on the rod: on node 0 itself, or passed through the joint from the anchor.
    on_rod = ev.constraint_force[0]
    np.testing.assert_allclose(on_rod, [0, 0, m * G / 4], atol=1e-9)
    if support == "anchor":
        np.testing.assert_allclose(ev.constraint_force[pivot], -on_rod, atol=1e-12)
    # Hanging, swinging through the bottom at omega^2 = 3 g / L (node 1 at (0, 0, -L)).
    omega = np.sqrt(3 * G / L)
    v_tip = np.array([omega * L, 0, 0])
    q = np.concatenate([[0, 0, -L], [0, 0, -L]])
    qdot = np.concatenate([v_tip, v_tip])
    ev = dynamics.evaluate(s, q, qdot, rest_length=s.tendon_rest_length, gravity=GRAVITY)
    np.testing.assert_allclose(ev.constraint_force[0], [0, 0, 5 * m * G / 2], atol=1e-9)
    # The pivot stays at rest to second order: its acceleration is zero.
    node_accel = dynamics.nodes_from_coordinates(s, ev.qddot, rates=True)
    np.testing.assert_allclose(node_accel[0], 0, atol=1e-12)


def test_pendulum_period_energy_and_fixed_pivot_over_a_long_run():
    """Released from horizontal, a physical pendulum with ``omega0^2 = 3 g / (2 L)`` has period
    ``T = 4 K(sin^2(pi/4)) / omega0`` (complete elliptic integral, parameter ``k^2``)."""
    m, L = 2.0, 1.5
    s = pendulum(m, L, support="fixed")
    period = 4 * ellipk(0.5) / np.sqrt(3 * G / (2 * L))
    r = simulate(s, (0.0, 5 * period), gravity=GRAVITY, sample_dt=period / 8)
    assert r.status == 0, r.message
    # After each whole period the tip is back where it started.
    whole = np.arange(0, r.t.size, 8)
    np.testing.assert_allclose(r.t[whole] / period, np.arange(whole.size), atol=1e-12)
    np.testing.assert_allclose(r.node_position[whole, 1], [[L, 0, 0]] * whole.size, atol=2e-6)
    # Half-way through each swing it is at the far side.
    np.testing.assert_allclose(r.node_position[4::8, 1], [[-L, 0, 0]] * len(r.t[4::8]), atol=2e-6)
    assert np.max(np.abs(r.node_position[:, 0])) < 1e-12
    assert r.max_constraint_error < 1e-12
    energy = r.total_energy
    assert np.ptp(energy) < 1e-7 * m * G * L


def test_class2_shell_long_undamped_run_holds_joints_and_invariants():
    """Undamped free class 2 shell: joints held (measured from the node positions, not from
    ``A``) within 1e-9 m, energy conserved, linear and angular momentum stay zero."""
    s = class2_shell(3, 2)
    r = simulate(s, (0.0, 3.0), sample_dt=0.01)
    assert r.status == 0, r.message
    p = r.node_position
    gap = np.linalg.norm(p[:, s.joint_nodes[:, 0]] - p[:, s.joint_nodes[:, 1]], axis=-1)
    assert gap.max() <= 1e-9
    assert r.max_constraint_error <= 1e-9
    # rod lengths at the ends of steps (samples come from the dense output, which holds the
    # joints, linear invariants, exactly but not the quadratic rod lengths)
    assert r.max_rod_length_error < 1e-9
    energy = r.total_energy
    assert r.energy["kinetic"].max() > 10.0  # it moves a lot
    assert np.ptp(energy) < 1e-7 * r.energy["kinetic"].max()
    # Momenta from the node velocities: a rod's centre moves at (v_a + v_b)/2, and its angular
    # momentum about its centre is (m/12) q2 x q2'.
    v, m = r.node_velocity, s.rod_mass[:, None]
    a, b = s.rod_nodes[:, 0], s.rod_nodes[:, 1]
    centre, centre_v = (p[:, a] + p[:, b]) / 2, (v[:, a] + v[:, b]) / 2
    momentum = np.sum(m * centre_v, axis=1)
    angular = np.sum(
        m * np.cross(centre, centre_v) + m / 12 * np.cross(p[:, b] - p[:, a], v[:, b] - v[:, a]),
        axis=1,
    )
    scale = s.total_mass * np.max(np.abs(v))
    assert np.max(np.abs(momentum)) < 1e-9 * scale
    assert np.max(np.abs(angular)) < 1e-8 * scale


@pytest.mark.parametrize("method", ["DOP853", "rk4"])
def test_fixed_base_ring_does_not_move(method):
    s = class2_shell(3, 2, fixed_base=True)
    fixed = np.flatnonzero(s.node_fixed)
    assert fixed.size == 6
    r = simulate(s, (0.0, 0.3), sample_dt=0.01, gravity=GRAVITY, method=method, dt=2e-4)
    assert r.status == 0, r.message
    assert r.max_constraint_error < 1e-12
    assert np.max(np.abs(r.node_position[:, fixed] - s.node_position[fixed])) < 1e-12
    assert np.max(np.abs(r.node_velocity[:, fixed])) < 1e-10
    # fixed-step RK4 is about second order through the slack switches (0.11e-6 measured)
    tolerance = 1e-7 if method == "DOP853" else 1e-6
    assert np.ptp(r.total_energy) < tolerance * r.energy["kinetic"].max()


ANCHOR_B, ANCHOR_C = np.array([1.5, 0.4, -1.5]), np.array([-0.8, 0.6, -0.5])
#: (tail, head), stiffness [N/m], rest length [m] of the hanging chain's tendons
CHAIN_TENDONS = (((3, 5), 60.0, 0.8), ((1, 7), 40.0, 0.6))


def hanging_chain(damped: bool) -> Structure:
    """Two jointed rods (class 2 at node 1 = node 2) hanging from an anchor (node 4, joined to
    node 0), pulled sideways by tendons from rod 2's free end (node 3) to anchor B (node 5) and
    from the joint to anchor C (node 7); a payload (point mass, node 6) is joined to node 3."""
    p = np.array(
        [
            [0, 0, 0],
            [0, 0, -1.0],
            [0, 0, -1.0],
            [0, 0, -2.2],
            [0, 0, 0],
            ANCHOR_B,
            [0, 0, -2.2],
            ANCHOR_C,
        ]
    )
    return Structure(
        node_position=p,
        rod_nodes=[[0, 1], [2, 3]],
        rod_mass=[1.0, 1.5],
        rod_length=[1.0, 1.2],
        rod_damping=[4.0, 4.0] if damped else None,
        node_fixed=[False, False, False, False, True, True, False, True],
        node_point_mass=[0, 0, 0, 0, 0, 0, 0.7, 0],
        joint_nodes=[[0, 4], [1, 2], [3, 6]],
        tendon_nodes=[ends for ends, _, _ in CHAIN_TENDONS],
        tendon_stiffness=[k for _, k, _ in CHAIN_TENDONS],
        tendon_rest_length=[rest for _, _, rest in CHAIN_TENDONS],
        tendon_damping=[3.0] * len(CHAIN_TENDONS) if damped else None,
    )


def static_equilibrium(s: Structure) -> np.ndarray:
    """Node positions minimizing elastic + gravitational energy subject to the rod lengths, the
    joints and the anchors (SLSQP over the free node coordinates; no library dynamics used)."""
    free = [0, 1, 2, 3, 6]
    anchors = {4: np.zeros(3), 5: ANCHOR_B, 7: ANCHOR_C}

    def nodes(x):
        p = np.empty((8, 3))
        p[free] = x.reshape(-1, 3)
        for k, value in anchors.items():
            p[k] = value
        return p

    def energy(x):
        p = nodes(x)
        rods = 0.5 * (1.0 * (p[0, 2] + p[1, 2]) + 1.5 * (p[2, 2] + p[3, 2])) * G + 0.7 * G * p[6, 2]
        springs = 0.0
        for (t, h), k, rest in CHAIN_TENDONS:
            springs += 0.5 * k * max(np.linalg.norm(p[h] - p[t]) - rest, 0.0) ** 2
        return rods + springs

    def equalities(x):
        p = nodes(x)
        return np.concatenate(
            [
                [np.sum((p[1] - p[0]) ** 2) - 1.0, np.sum((p[3] - p[2]) ** 2) - 1.2**2],
                p[0] - p[4],
                p[1] - p[2],
                p[3] - p[6],
            ]
        )

    x0 = s.node_position[free].ravel() + 0.01
    solution = optimize.minimize(
        energy,
        x0,
        method="SLSQP",
        constraints={"type": "eq", "fun": equalities},
        options={"ftol": 1e-15, "maxiter": 2000},
    )
    assert solution.success, solution.message
    return nodes(solution.x)


def test_hanging_chain_settles_at_the_static_equilibrium():
    s = hanging_chain(damped=True)
    r = simulate(
        s, (0.0, 60.0), gravity=GRAVITY, steady_state=True, sample_dt=0.05, rtol=1e-7, atol=1e-10
    )
    assert r.status == 1, r.message
    expected = static_equilibrium(s)
    np.testing.assert_allclose(r.node_position[-1], expected, atol=1e-5)
    # the equilibrium is not the start: the tendon pulled the chain sideways
    assert np.max(np.abs(expected - s.node_position)) > 0.3


def test_hanging_chain_undamped_conserves_energy():
    s = hanging_chain(damped=False)
    r = simulate(s, (0.0, 2.0), gravity=GRAVITY, sample_dt=0.01)
    assert r.status == 0, r.message
    assert r.max_constraint_error < 1e-9
    assert np.ptp(r.total_energy) < 1e-7 * r.energy["kinetic"].max()


def test_point_mass_between_two_anchors_oscillates_at_sqrt_2k_over_m():
    """A mass on two collinear taut tendons: ``x(t) = x0 cos(sqrt(2k/m) t)``."""
    k, m, x0 = 50.0, 0.3, 0.1
    s = Structure(
        node_position=[[-2, 0, 0], [2, 0, 0], [x0, 0, 0]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_fixed=[True, True, False],
        node_point_mass=[0, 0, m],
        tendon_nodes=[[0, 2], [2, 1]],
        tendon_stiffness=[k, k],
        tendon_rest_length=[1.0, 1.0],
    )
    assert s.n_coordinates == 3 and not s.has_constraints
    r = simulate(s, (0.0, 3.0), sample_dt=0.01)
    assert r.status == 0, r.message
    omega = np.sqrt(2 * k / m)
    np.testing.assert_allclose(r.node_position[:, 2, 0], x0 * np.cos(omega * r.t), atol=1e-9)
    np.testing.assert_allclose(
        r.node_position[:, :2], np.broadcast_to(s.node_position[:2], (r.t.size, 2, 3))
    )


def test_point_mass_on_an_inclined_plane_slides_with_g_sin_theta():
    """Frictionless plane with unit normal ``n``: the mass accelerates with ``g - (g . n) n``."""
    theta = 0.3
    normal = np.array([np.sin(theta), 0, np.cos(theta)])
    s = Structure(
        node_position=[[0.0, 0, 0]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_point_mass=[2.0],
        plane_nodes=[0],
        plane_normal=[normal * 3],
        **NO_TENDONS,
    )
    r = simulate(s, (0.0, 1.0), gravity=GRAVITY, sample_dt=0.1)
    along = GRAVITY - (GRAVITY @ normal) * normal
    assert np.isclose(np.linalg.norm(along), G * np.sin(theta))
    np.testing.assert_allclose(r.node_position[:, 0], 0.5 * r.t[:, None] ** 2 * along, atol=1e-10)


def test_pendulum_on_a_sliding_pivot_conserves_momentum_along_the_line():
    """A rod whose end slides freely along the x axis (a line constraint): no force acts along x,
    so the x-momentum stays zero; energy is conserved."""
    s = Structure(
        node_position=[[0, 0, 0], [0.6, 0.0, -0.8]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        line_nodes=[0],
        line_direction=[[2.0, 0, 0]],
        **NO_TENDONS,
    )
    r = simulate(s, (0.0, 3.0), gravity=GRAVITY, sample_dt=0.01)
    assert r.status == 0, r.message
    assert np.max(np.abs(r.node_position[:, 0, 1:])) < 1e-12  # the pivot stays on the line
    assert np.ptp(r.node_position[:, 0, 0]) > 0.1  # and moves along it
    centre_vx = 0.5 * (r.node_velocity[:, 0, 0] + r.node_velocity[:, 1, 0])
    assert np.max(np.abs(centre_vx)) < 1e-9
    assert np.ptp(r.total_energy) < 1e-8 * G


def test_payload_pendulum_small_oscillation_frequency():
    """Rod (m, L) pinned at one end, a point mass M joined to its other end: small oscillations
    at ``omega^2 = g (m L/2 + M L) / (m L^2/3 + M L^2)``."""
    m, M, L, amplitude = 1.0, 0.5, 0.8, 1e-3
    tip = L * np.array([np.sin(amplitude), 0, -np.cos(amplitude)])
    s = Structure(
        node_position=[[0, 0, 0], tip, tip],
        rod_nodes=[[0, 1]],
        rod_mass=[m],
        rod_length=[L],
        node_fixed=[True, False, False],
        node_point_mass=[0, 0, M],
        joint_nodes=[[1, 2]],
        **NO_TENDONS,
    )
    omega = np.sqrt(G * (m * L / 2 + M * L) / (m * L**2 / 3 + M * L**2))
    r = simulate(s, (0.0, 4 * 2 * np.pi / omega), gravity=GRAVITY, sample_dt=0.002)
    x = r.node_position[:, 2, 0]
    crossings = r.t[:-1][(x[:-1] > 0) & (x[1:] <= 0)]
    # linear interpolation is enough at this sampling; the amplitude correction is ~1e-7
    measured = 2 * np.pi / np.mean(np.diff(crossings))
    assert measured == pytest.approx(omega, rel=1e-4)
    assert np.max(np.abs(r.node_position[:, 2] - r.node_position[:, 1])) < 1e-10


def test_redundant_constraints_are_handled():
    """A rod with both ends fixed, and three rods meeting at one node joined by a cycle of pairs
    (a redundant row) rather than a chain: both behave as the non-redundant form."""
    held = Structure(
        node_position=[[0, 0, 0], [1, 0, 0]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        node_fixed=[True, True],
        plane_nodes=[1],
        plane_normal=[[0, 0, 1]],
        **NO_TENDONS,
    )
    r = simulate(held, (0.0, 1.0), gravity=GRAVITY)
    assert r.status == 0 and np.max(np.abs(r.node_position - held.node_position)) < 1e-13

    top = np.array([0, 0, 1.0])
    feet = np.array([[1, 0, 0], [-0.5, 0.8, 0], [-0.5, -0.8, 0]])
    lengths = np.linalg.norm(feet - top, axis=1)
    p = np.concatenate([feet, [top] * 3, feet])  # rod ends, joined tops, anchors at the feet
    common = dict(
        node_position=p,
        rod_nodes=[[0, 3], [1, 4], [2, 5]],
        rod_mass=[1, 2, 3],
        rod_length=lengths,
        tendon_nodes=[[0, 6], [1, 7], [2, 8]],
        tendon_stiffness=[30, 40, 50],
        tendon_rest_length=[0.0, 0.0, 0.0],
        node_fixed=[False] * 6 + [True] * 3,
    )
    chain = Structure(joint_nodes=[[3, 4], [4, 5]], **common)
    cycle = Structure(joint_nodes=[[3, 4], [4, 5], [5, 3]], **common)
    assert constraints_of(cycle).matrix.shape[0] == constraints_of(chain).matrix.shape[0] == 6
    rng = np.random.default_rng(1)
    state = dynamics.initial_state(chain)
    qdot = constraints_of(chain).project(state.q, rng.normal(size=state.q.size))[1]
    results = [
        dynamics.evaluate(s, state.q, qdot, rest_length=s.tendon_rest_length, gravity=GRAVITY)
        for s in (chain, cycle)
    ]
    np.testing.assert_allclose(results[0].qddot, results[1].qddot, atol=1e-10)
    assert np.max(np.abs(constraints_of(chain).matrix @ results[0].qddot)) < 1e-10


def test_dense_and_sparse_solves_agree(monkeypatch):
    s = class2_shell(3, 3, fixed_base=True)
    rng = np.random.default_rng(0)
    state = dynamics.initial_state(s)
    q, qdot = constraints_of(s).project(
        state.q + 1e-3 * rng.normal(size=state.q.size), rng.normal(size=state.q.size)
    )
    dense = dynamics.evaluate(s, q, qdot, rest_length=s.tendon_rest_length, gravity=GRAVITY)
    monkeypatch.setattr(constraints_module, "DENSE_ROWS", 0)
    sparse_s = s.replace()
    assert constraints_of(s).dense and not constraints_of(sparse_s).dense
    sparse = dynamics.evaluate(sparse_s, q, qdot, rest_length=s.tendon_rest_length, gravity=GRAVITY)
    np.testing.assert_allclose(sparse.qddot, dense.qddot, rtol=1e-10, atol=1e-10)


def test_projection_restores_constraints_and_rod_lengths():
    s = class2_shell(4, 3, fixed_base=True)
    rng = np.random.default_rng(2)
    state = dynamics.initial_state(s)
    q, qdot = constraints_of(s).project(
        state.q + 1e-4 * rng.normal(size=state.q.size), rng.normal(size=state.q.size)
    )
    assert np.max(np.abs(constraints_of(s).residual(q))) < 1e-13
    assert np.max(np.abs(dynamics.rod_length_error(s, q))) < 1e-13
    assert np.max(np.abs(constraints_of(s).matrix @ qdot)) < 1e-12
    q2, v2 = dynamics.rods_view(q)[:, 1], dynamics.rods_view(qdot)[:, 1]
    assert np.max(np.abs(np.sum(q2 * v2, axis=1))) < 1e-12
    # a state on the constraints is a fixed point
    q_again, qdot_again = constraints_of(s).project(q, qdot)
    np.testing.assert_allclose(q_again, q, atol=1e-15)
    np.testing.assert_allclose(qdot_again, qdot, atol=1e-12)


def test_projection_accepts_the_round_off_floor_but_not_a_real_violation():
    """The hanging chain with its payload on a line: round-off keeps the projection's error near
    1.5e-14 m, just above ``PROJECTION_RTOL`` times the length scale, and a run used to stop as
    "unstable" there.  It now runs, holding the constraints to the floor; a state far off the
    constraints with too few iterations still fails."""
    chain = hanging_chain(damped=False).replace(line_nodes=[6], line_direction=[[1.0, 0, 0]])
    result = simulate(chain, (0.0, 0.05), method="rk4", dt=1e-4, gravity=GRAVITY)
    assert result.success, result.message
    floor = constraints_module.PROJECTION_FLOOR_RTOL * constraints_of(chain).length_scale
    assert result.max_constraint_error < 1e-9
    q = result.q[-1]
    assert np.max(np.abs(constraints_of(chain).residual(q))) <= floor
    assert np.max(np.abs(dynamics.rod_length_error(chain, q))) <= floor
    state = dynamics.initial_state(chain)
    with pytest.raises(FloatingPointError, match="could not project"):
        constraints_of(chain).project(state.q + 0.3, state.qdot, max_iter=2)


# ------------------------------------------------------------------ the class 2 shell
@pytest.mark.parametrize("n, m", [(3, 2), (4, 3), (5, 4)])
def test_class2_shell_topology_follows_lemma_18_1(n, m):
    s = class2_shell(n, m)
    assert (s.n_nodes, s.n_rods, s.n_tendons) == (4 * n * m, 2 * n * m, n * (6 * m + 2))
    assert len(s.joint_nodes) == 2 * n * (m - 1)
    p = s.node_position
    # joined nodes coincide, and no other two nodes do
    np.testing.assert_allclose(p[s.joint_nodes[:, 0]], p[s.joint_nodes[:, 1]], atol=1e-12)
    distance = np.linalg.norm(p[:, None] - p[None], axis=-1) + np.eye(len(p))
    assert np.sum(distance < 1e-9) == 2 * len(s.joint_nodes)
    # the pairs are those of the spec, e.g. p2(1,1) = p1(2,2) and p3(n,2) = p4(1,1)
    pairs = {tuple(sorted(x)) for x in s.joint_nodes.tolist()}
    assert tuple(sorted((shell_node_index(2, 1, 1, n), shell_node_index(1, 2, 2, n)))) in pairs
    assert tuple(sorted((shell_node_index(3, n, 2, n), shell_node_index(4, 1, 1, n)))) in pairs
    # each joined node is the end of two rods: class 2
    assert np.all(np.bincount(s.joint_nodes.ravel(), minlength=len(p)) <= 1)
    # every class 1 tendon, its ends merged by the joints, is exactly one class 2 tendon
    group = np.arange(len(p))
    for a, b in s.joint_nodes:
        group[b] = group[a]
    kept = {frozenset(group[[a, b]]) for a, b in s.tendon_nodes}
    assert len(kept) == s.n_tendons
    merged = {frozenset(group[[tail, head]]) for _, tail, head in shell_tendons(n, m)}
    assert merged == kept
    assert all(len(x) == 2 for x in kept)


def test_class2_shell_rejects_bad_sizes():
    with pytest.raises(ValueError, match=r"^m: a class 2 shell needs m >= 2"):
        class2_shell(3, 1)
    with pytest.raises(ValueError, match=r"^n:"):
        class2_joints(2, 2)
    with pytest.raises(ValueError, match=r"^stage_height:"):
        class2_shell(3, 2, stage_height=1.5)


# ------------------------------------------------------------------ validation and the JSON form
def _rod(**extra):
    base = dict(
        node_position=[[0, 0, 0], [1, 0, 0], [1, 0, 0]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        node_point_mass=[0, 0, 0.5],
        **NO_TENDONS,
    )
    return Structure(**(base | extra))


@pytest.mark.parametrize(
    "extra, message",
    [
        (dict(joint_nodes=[[0, 2]]), r"^joint_nodes\[0\]: nodes 0 and 2 are 1\.0 m apart"),
        (dict(joint_nodes=[[1, 5]]), r"^joint_nodes\[0\]: node index 5 out of range"),
        (dict(joint_nodes=[[1, 1]]), r"^joint_nodes\[0\]: joins node 1 to itself"),
        (
            dict(node_point_mass=[0, 0.3, 0.5]),
            r"^node_point_mass\[1\]: node 1 is an end of rods\[0\]",
        ),
        (dict(node_point_mass=[0, 0, -1.0]), r"^node_point_mass\[2\]: must be >= 0"),
        (dict(node_point_mass=[0, 0, 0]), r"^nodes\[2\]: belongs to no rod"),
        (dict(node_fixed=[False, False, True]), r"^node_point_mass\[2\]: node 2 is fixed"),
        (dict(node_fixed=[0, 1, 0]), r"^node_fixed: expected 3 booleans"),
        (dict(plane_nodes=[1], plane_normal=[[0, 0, 0]]), r"^plane_normal\[0\]: must not be zero"),
        (dict(plane_nodes=[1], plane_normal=[[0, 0]]), r"^plane_normal: expected shape \(1, 3\)"),
        (
            dict(line_nodes=[3], line_direction=[[1, 0, 0]]),
            r"^line_nodes\[0\]: node index 3 out of range",
        ),
        (
            dict(line_nodes=[1.5], line_direction=[[1, 0, 0]]),
            r"^line_nodes: expected a list of node indices",
        ),
    ],
)
def test_validation_names_the_field(extra, message):
    with pytest.raises(ValueError, match=message):
        _rod(**extra)


def test_json_round_trip_keeps_supports_and_names_bad_keys():
    s = hanging_chain(damped=True).replace(
        plane_nodes=[3], plane_normal=[[0, 1, 0]], line_nodes=[6], line_direction=[[0, 0, 1]]
    )
    data = s.to_dict()
    assert data["fixed"] == [4, 5, 7] and data["joints"] == [[0, 4], [1, 2], [3, 6]]
    assert data["point_masses"] == [{"node": 6, "mass": 0.7}]
    back = Structure.from_dict(data)
    assert back.to_dict() == data
    for field in (
        "node_fixed",
        "node_point_mass",
        "joint_nodes",
        "plane_nodes",
        "plane_normal",
        "line_nodes",
        "line_direction",
    ):
        np.testing.assert_array_equal(getattr(back, field), getattr(s, field))
    # a free class 1 structure's JSON form has none of the new keys
    assert set(class2_shell(3, 2).replace(joint_nodes=None, node_fixed=None).to_dict()) >= {"nodes"}
    for key, value, message in (
        (
            "point_masses",
            [{"node": 6, "mass": "x"}],
            r"^point_masses\[0\]\.mass: expected a number",
        ),
        ("point_masses", [{"mass": 1.0}], r"^point_masses\[0\]: missing key 'node'"),
        ("fixed", [4, 99], r"^fixed\[1\]: expected a node index in \[0, 7\]"),
        ("joints", [[0, 4, 5]], r"^joints\[0\]: expected two integer node indices"),
        ("planes", [{"node": 3, "normal": [0, 1]}], r"^planes\[0\]\.normal: expected a list of 3"),
        ("lines", [{"node": 6}], r"^lines\[0\]: missing key 'direction'"),
    ):
        with pytest.raises(ValueError, match=message):
            Structure.from_dict(data | {key: value})


def test_free_class1_only_parts_reject_supported_structures():
    from tensegrity.physics.kernel import pack
    from tensegrity.physics.matrix_form import shell_size

    s = class2_shell(3, 2)
    assert not s.is_free_class1
    # (the analysis package takes these structures now: tests/test_analysis_constrained.py)
    for what, call in (("the compiled kernel", pack), ("the matrix model", shell_size)):
        with pytest.raises(ValueError, match=f"^{what}: supports only free 3-D class 1"):
            call(s)


def test_artificial_damping_treats_anchors_as_infinitely_heavy():
    """A tendon to an anchor is critically damped for the mass at its other end, ``2 sqrt(k m)``;
    one between two rods' nodes for their reduced mass, as before."""
    from tensegrity import artificial_damping

    s = hanging_chain(damped=False).replace(
        tendon_nodes=[[3, 5], [1, 7], [0, 3]],
        tendon_stiffness=[60.0, 40.0, 10.0],
        tendon_rest_length=[0.8, 0.6, 0.1],
        tendon_name=None,
        tendon_damping=None,
    )
    damped = artificial_damping(s)
    half = s.rod_mass / 2  # node 3 is rod 1's end (1.5 kg), nodes 1 and 0 rod 0's (1 kg)
    np.testing.assert_allclose(
        damped.tendon_damping,
        [
            2 * np.sqrt(60.0 * half[1]),
            2 * np.sqrt(40.0 * half[0]),
            2 * np.sqrt(10.0 * half[0] * half[1] / (half[0] + half[1])),
        ],
    )
    with pytest.raises(
        ValueError, match=r"^structure: artificial damping needs at least one rod and one tendon"
    ):
        artificial_damping(pendulum(support="fixed"))


def test_tripod_on_a_frictionless_floor_matches_its_closed_form():
    """Three rods (m, L) joined at the apex (a class 3 joint: two pairs), feet held on the floor
    z = 0 (plane constraints), the feet tied by three tendons (k, L0).  By symmetry the feet sit
    on a circle of radius rho, the apex at h = sqrt(L^2 - rho^2), the tendons are sides
    s = sqrt(3) rho.  The energy ``V = 3 m g h / 2 + 3 k (s - L0)^2 / 2`` is stationary when
    ``(3 m g / 2) rho / h = 3 sqrt(3) k (s - L0)``, i.e. the tension is
    ``T = m g rho / (2 sqrt(3) h)``; and the floor carries each foot's share of the weight,
    ``m g`` (the apex joint passes no net vertical force by symmetry)."""
    from scipy.optimize import brentq

    from tensegrity import artificial_damping

    m, L, k, rest = 1.2, 1.0, 80.0, 0.9
    rho0 = 0.5
    angles = 2 * np.pi * np.arange(3) / 3
    feet = rho0 * np.stack([np.cos(angles), np.sin(angles), np.zeros(3)], axis=1)
    apex = np.array([0, 0, np.sqrt(L**2 - rho0**2)])
    position = np.array([feet[0], apex, feet[1], apex, feet[2], apex])
    s = artificial_damping(
        Structure(
            node_position=position,
            rod_nodes=[[0, 1], [2, 3], [4, 5]],
            rod_mass=[m] * 3,
            rod_length=[L] * 3,
            joint_nodes=[[1, 3], [3, 5]],
            plane_nodes=[0, 2, 4],
            plane_normal=[[0, 0, 1.0]] * 3,
            tendon_nodes=[[0, 2], [2, 4], [4, 0]],
            tendon_stiffness=[k] * 3,
            tendon_rest_length=[rest] * 3,
        )
    )
    r = simulate(
        s, (0.0, 30.0), gravity=GRAVITY, steady_state=True, velocity_tol=1e-8, acceleration_tol=1e-8
    )
    assert r.status == 1, r.message
    # the stable root: between slack tendons and the second (flat, unstable) root near rho = L
    root = brentq(
        lambda rho: (
            1.5 * m * G * rho / np.sqrt(L**2 - rho**2)
            - 3 * np.sqrt(3) * k * (np.sqrt(3) * rho - rest)
        ),
        rest / np.sqrt(3),
        0.8 * L,
    )
    assert abs(root - rho0) > 0.02  # the feet slid out to get there
    p = r.node_position[-1]
    centre = p[[0, 2, 4]].mean(axis=0)
    np.testing.assert_allclose(np.linalg.norm(p[[0, 2, 4]] - centre, axis=1), root, atol=1e-7)
    np.testing.assert_allclose(p[[1, 3, 5], 2], np.sqrt(L**2 - root**2), atol=1e-7)
    expected_tension = m * G * root / (2 * np.sqrt(3) * np.sqrt(L**2 - root**2))
    np.testing.assert_allclose(r.tendon_tension[-1], expected_tension, rtol=1e-6)
    state = r.final_state
    ev = dynamics.evaluate(
        s, state.q, np.zeros_like(state.qdot), rest_length=s.tendon_rest_length, gravity=GRAVITY
    )
    np.testing.assert_allclose(ev.constraint_force[[0, 2, 4]], [[0, 0, m * G]] * 3, atol=1e-6)
