"""MuJoCo as a peer: the MJCF export is the same model, and MuJoCo integrates the same physics.

Measured on the reference machine (MuJoCo 4.0.0), largest node-position difference [m] over the
horizon, undamped:

- (3,1) shell released from its cylinder layout (all tendons taut; three go slack near 0.09 s,
  more later), 0.4 s, MuJoCo RK4 vs our DOP853 (rtol 1e-12, slack switches located):
  3.3e-6, 4.0e-7, 2.2e-7, 5.4e-8, 1.2e-8 at dt = 4e-4, 2e-4, 1e-4, 5e-5, 2.5e-5.  Up to the first
  switch the difference is fourth order (1.9e-10, 1.2e-11, 8e-13 at t = 0.05 s for 4e-4, 2e-4,
  1e-4); after it, second order, erratic per halving: RK4 stepping over the kinks of the tension
  law, exactly as our own RK4 does (ours and MuJoCo's RK4 agree to 1e-11 here).
- (4,2) shell with random rod-consistent velocities, half its rods pointing down (up to 14 of 72
  tendons slack at once), 0.3 s, MuJoCo RK4 vs our RK4 at the same dt = 1e-4: 9e-12.  Over 0.5 s:
  3e-10, 2e-11, 2e-12 at dt = 2e-4, 1e-4, 5e-5 (fourth order: the same discrete scheme applied to
  the same ODE), while each is 1.1e-5, 2.3e-6, 2.6e-7 from our DOP853.
- (3,1) shell with random velocities under gravity, 0.1 s, both RK4 at dt = 1e-4: 8e-13.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.io.mjcf import (
    SPIN_INERTIA_MIN,
    SPIN_INERTIA_RATIO,
    mjcf_memory,
    mujoco_node_positions,
    mujoco_node_velocities,
    node_site_ids,
    to_mjcf,
    write_mjcf,
)
from tensegrity.physics import dynamics

mujoco = pytest.importorskip("mujoco")

SAMPLE_DT = 0.01


def rod_consistent_velocity(structure, scale, seed):
    """Random node velocities with ``v_b - v_a`` perpendicular to ``p_b - p_a`` for every rod."""
    rng = np.random.default_rng(seed)
    v = scale * rng.normal(size=(structure.n_nodes, structure.dim))
    a, b = structure.rod_nodes.T
    u = structure.node_position[b] - structure.node_position[a]
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    d = v[b] - v[a]
    d -= np.sum(d * u, axis=1, keepdims=True) * u
    c = 0.5 * (v[a] + v[b])
    v[a], v[b] = c - 0.5 * d, c + 0.5 * d
    return v


def moving_shell():
    """A (4,2) shell with random rod-consistent velocities; every other rod listed as (b, a), so
    that half of the bodies point downward (the other branch of the orientation code)."""
    shell = class1_shell(4, 2)
    rods = shell.rod_nodes.copy()
    rods[::2] = rods[::2, ::-1]
    shell = shell.replace(rod_nodes=rods)
    return shell.replace(node_velocity=rod_consistent_velocity(shell, 0.5, seed=1))


def load(structure, **options):
    model = mujoco.MjModel.from_xml_string(to_mjcf(structure, **options))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    return model, data


def run_mujoco(structure, t_end, dt, **options):
    """Node positions (T, N, d) every SAMPLE_DT, and the set of tendons that were slack after
    any step (length <= rest length); ``options`` go to ``to_mjcf``."""
    model, data = load(structure, timestep=dt, **options)
    steps_per_sample = round(SAMPLE_DT / dt)
    positions = [mujoco_node_positions(model, data, structure.n_nodes, dim=structure.dim)]
    went_slack = np.zeros(structure.n_tendons, dtype=bool)
    for _ in range(round(t_end / SAMPLE_DT)):
        for _ in range(steps_per_sample):
            mujoco.mj_step(model, data)
            mujoco.mj_kinematics(model, data)  # the end of the step, not the last RK4 stage
            mujoco.mj_tendon(model, data)
            went_slack |= data.ten_length[: structure.n_tendons] <= structure.tendon_rest_length
        positions.append(mujoco_node_positions(model, data, structure.n_nodes, dim=structure.dim))
    return np.array(positions), went_slack


def max_difference(p, q):
    """Largest coordinate difference [m] over nodes, per sample."""
    assert p.shape == q.shape
    return np.abs(p - q).max(axis=(1, 2))


# ------------------------------------------------------------------------------ the model
@pytest.fixture(scope="module")
def varied():
    """A damped (4,2) shell with random masses, stiffnesses, rest lengths and velocities."""
    rng = np.random.default_rng(7)
    shell = moving_shell()
    R, S = shell.n_rods, shell.n_tendons
    return shell.replace(
        rod_mass=rng.uniform(0.5, 2.0, R),
        tendon_stiffness=rng.uniform(50.0, 200.0, S),
        tendon_rest_length=shell.tendon_rest_length * rng.uniform(0.5, 1.5, S),
        tendon_damping=rng.uniform(0.0, 3.0, S),
    )


def test_model_matches_structure(varied):
    s = varied
    model, data = load(s, timestep=2e-4, integrator="RK4", gravity=(0, 0, -9.81), name="shell")
    assert model.nbody == s.n_rods + 1  # + world
    assert model.njnt == s.n_rods
    assert np.all(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    assert model.nv == s.n_coordinates
    assert model.ntendon == s.n_tendons
    assert model.nsite == s.n_nodes
    assert model.opt.timestep == 2e-4
    assert model.opt.integrator == mujoco.mjtIntegrator.mjINT_RK4
    np.testing.assert_array_equal(model.opt.gravity, [0, 0, -9.81])
    assert model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert model.names.split(b"\0")[0] == b"shell"

    transverse = s.rod_mass * s.rod_length**2 / 12
    np.testing.assert_allclose(model.body_mass[1:], s.rod_mass, rtol=1e-15)
    np.testing.assert_allclose(
        model.body_inertia[1:],
        np.column_stack([transverse, transverse, SPIN_INERTIA_RATIO * transverse]),
        rtol=1e-15,
    )
    np.testing.assert_array_equal(model.body_ipos[1:], 0.0)

    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, k) for k in range(s.n_tendons)]
    assert tuple(names) == s.tendon_name
    np.testing.assert_array_equal(model.tendon_stiffness, s.tendon_stiffness)
    np.testing.assert_array_equal(model.tendon_lengthspring[:, 0], 0.0)
    np.testing.assert_array_equal(model.tendon_lengthspring[:, 1], s.tendon_rest_length)
    np.testing.assert_array_equal(model.tendon_damping, s.tendon_damping)
    # Each tendon runs from the tail's site to the head's site.
    site_of_node = node_site_ids(model, s.n_nodes)
    for k, (tail, head) in enumerate(s.tendon_nodes):
        first = model.tendon_adr[k]
        assert model.tendon_num[k] == 2
        ends = [site_of_node[tail], site_of_node[head]]
        assert list(model.wrap_objid[first : first + 2]) == ends

    # Initial state: positions (also qpos0, without the keyframe) and velocities.
    fresh = mujoco.MjData(model)
    for d in (data, fresh):
        p = mujoco_node_positions(model, d, s.n_nodes)
        np.testing.assert_allclose(p, s.node_position, rtol=0, atol=1e-12)
    v = mujoco_node_velocities(model, data, s.n_nodes)
    np.testing.assert_allclose(v, s.node_velocity, rtol=0, atol=1e-12)
    assert np.abs(data.qvel.reshape(-1, 6)[:, 5]).max() < 1e-14  # no spin about the rod axes
    state = dynamics.initial_state(s)
    mujoco.mj_forward(model, data)
    lengths = dynamics.tendon_lengths(s, s.node_position)
    np.testing.assert_allclose(data.ten_length, lengths, rtol=1e-14)
    kinetic = data.energy[1]
    assert kinetic == pytest.approx(float(dynamics.kinetic_energy(s, state.qdot)), rel=1e-12)


def test_initial_state_is_projected_like_initial_state():
    """Rods slightly off their length (within ``ROD_LENGTH_RTOL``) and velocities that would
    stretch them are projected onto the rod constraints exactly as ``initial_state`` does."""
    shell = class1_shell(3, 1)
    rng = np.random.default_rng(3)
    a, b = shell.rod_nodes.T
    p = shell.node_position.copy()
    stretch = 1 + rng.uniform(-5e-7, 5e-7, shell.n_rods)[:, None]
    centre, half = 0.5 * (p[a] + p[b]), 0.5 * (p[b] - p[a])
    p[a], p[b] = centre - stretch * half, centre + stretch * half
    s = shell.replace(node_position=p, node_velocity=rng.normal(size=(shell.n_nodes, 3)))
    state = dynamics.initial_state(s)
    model, data = load(s)
    np.testing.assert_allclose(
        mujoco_node_positions(model, data, s.n_nodes),
        dynamics.nodes_from_coordinates(s, state.q),
        rtol=0,
        atol=1e-12,
    )
    np.testing.assert_allclose(
        mujoco_node_velocities(model, data, s.n_nodes),
        dynamics.nodes_from_coordinates(s, state.qdot),
        rtol=0,
        atol=1e-12,
    )


def test_elastic_energy_matches_along_a_trajectory():
    """MuJoCo's potential energy (deadband springs) is our elastic energy, slack tendons too."""
    s = moving_shell()
    model, data = load(s)
    slack_seen = 0
    for _ in range(20):
        for _ in range(100):
            mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        p = mujoco_node_positions(model, data, s.n_nodes)
        slack_seen = max(slack_seen, int(np.sum(data.ten_length <= s.tendon_rest_length)))
        elastic = float(dynamics.elastic_energy(s, p))
        assert data.energy[0] == pytest.approx(elastic, rel=1e-12, abs=1e-12)
    assert slack_seen > 0


def test_memory_is_explicit_and_sufficient():
    s = class1_shell(10, 10)
    assert f'<size memory="{mjcf_memory(s)}" />' in to_mjcf(s)
    model, data = load(s)
    for _ in range(3):
        mujoco.mj_step(model, data)
    assert model.narena == mjcf_memory(s)
    assert 4 * max(data.maxuse_arena, data.maxuse_stack) < model.narena


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("options", "field"),
    [
        ({"timestep": 0.0}, "timestep"),
        ({"timestep": -1e-4}, "timestep"),
        ({"timestep": float("nan")}, "timestep"),
        ({"timestep": "fast"}, "timestep"),
        ({"integrator": "rk4"}, "integrator"),
        ({"gravity": (0, -9.81)}, "gravity"),
        ({"gravity": (0, 0, float("inf"))}, "gravity"),
        ({"name": ""}, "name"),
    ],
)
def test_bad_options_name_the_field(options, field):
    with pytest.raises(ValueError, match=f"^{field}:"):
        to_mjcf(class1_shell(3, 1), **options)


def test_rod_damping_is_refused():
    with pytest.raises(ValueError, match=r"^rods\[0\]\.damping:"):
        to_mjcf(artificial_damping(class1_shell(3, 1)))


def test_rods_too_light_for_mujoco_are_refused():
    shell = class1_shell(3, 1)
    light = shell.replace(rod_mass=np.full(shell.n_rods, 1e-16))
    with pytest.raises(ValueError, match=r"^rods\[0\]\.mass:"):
        to_mjcf(light)
    # Light but representable: the spin inertia is raised to SPIN_INERTIA_MIN, and it loads.
    model, _ = load(shell.replace(rod_mass=np.full(shell.n_rods, 1e-9)))
    np.testing.assert_allclose(model.body_inertia[1:, 2], SPIN_INERTIA_MIN, rtol=1e-15)


def test_names_are_escaped():
    shell = class1_shell(3, 1)
    names = ('a"b', "<t>", "x&y", *shell.tendon_name[3:])
    model, _ = load(shell.replace(tendon_name=names), name='my "shell" & <co>')
    got = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, k) for k in range(shell.n_tendons)]
    assert tuple(got) == names


def test_write_mjcf_is_atomic(tmp_path):
    s = class1_shell(3, 1)
    path = tmp_path / "shell.xml"
    assert write_mjcf(path, s, timestep=5e-5) == path
    model = mujoco.MjModel.from_xml_path(str(path))
    assert model.opt.timestep == 5e-5 and model.nbody == s.n_rods + 1
    before = path.read_text()
    with pytest.raises(ValueError, match=r"^timestep:"):
        write_mjcf(path, s, timestep=-1.0)
    assert path.read_text() == before
    with pytest.raises(FileNotFoundError):
        write_mjcf(tmp_path / "missing" / "shell.xml", s)
    assert sorted(os.listdir(tmp_path)) == ["shell.xml"]


# ------------------------------------------------------------------------- same physics
@pytest.fixture(scope="module")
def released():
    """(3,1) shell released from its cylinder layout; our DOP853 reference over 0.4 s."""
    s = class1_shell(3, 1)
    reference = simulate(s, (0.0, 0.4), rtol=1e-12, atol=1e-15, sample_dt=SAMPLE_DT)
    assert reference.success, reference.message
    return s, reference


def test_released_shell_converges_to_our_reference(released):
    """MuJoCo RK4 at four step sizes vs our DOP853 (slack switches located): every run within
    1e-5 m, and the difference shrinks as dt does: fourth order while every tendon is taut,
    second order once RK4 steps over the kinks of the tension law (in MuJoCo as in ours)."""
    s, reference = released
    taut = reference.t <= 0.05 + 1e-12
    assert np.all(reference.slack_count[taut] == 0)  # all taut at release and until 0.05 s
    ours_went_slack = np.any(reference.tendon_tension <= 0, axis=0)
    assert ours_went_slack.any() and reference.nswitches > 0
    errors = {}
    for dt in (4e-4, 2e-4, 1e-4, 2.5e-5):
        positions, went_slack = run_mujoco(s, 0.4, dt)
        errors[dt] = max_difference(positions, reference.node_position)
        assert errors[dt].max() < 1e-5, (dt, errors[dt].max())
        # The same tendons go slack (sampled every step in MuJoCo, every 10 ms in ours).
        assert np.all(went_slack[ours_went_slack]), dt
    worst = {dt: e.max() for dt, e in errors.items()}
    assert worst[1e-4] < 5e-7, worst  # measured 2.2e-7
    # Second order overall: x4 in dt gives about x16 (measured 15 and 18); first order gives x4.
    assert worst[4e-4] / worst[1e-4] > 8 and worst[1e-4] / worst[2.5e-5] > 8, worst
    # Fourth order while all tendons are taut: x2 in dt gives about x16 (measured 16).
    early = {dt: e[taut].max() for dt, e in errors.items()}
    assert early[4e-4] / early[2e-4] > 10, early


def test_moving_shell_same_steps_as_our_rk4():
    """A (4,2) shell with random velocities and many slack tendons: MuJoCo RK4 and our RK4 at the
    same dt follow the same discrete trajectory (measured 1e-11 m, fourth order in dt)."""
    s = moving_shell()
    t_end, dt = 0.3, 1e-4
    ours = simulate(s, (0.0, t_end), method="rk4", dt=dt, sample_dt=SAMPLE_DT)
    assert ours.success, ours.message
    positions, went_slack = run_mujoco(s, t_end, dt)
    difference = max_difference(positions, ours.node_position)
    assert difference.max() < 1e-5
    assert difference.max() < 1e-9, difference.max()
    assert ours.slack_count.max() >= 5 and went_slack.sum() >= 5
    # Energy is conserved alike (undamped): total kinetic + elastic drift below 1e-6 relative.
    assert np.ptp(ours.total_energy) < 1e-6 * ours.total_energy[0]


def test_gravity_same_steps_as_our_rk4():
    """Gravity: our half-weight at each end node is MuJoCo's weight at the body's centre."""
    shell = class1_shell(3, 1)
    s = shell.replace(node_velocity=rod_consistent_velocity(shell, 0.3, seed=5))
    g = np.array([0.0, 0.0, -9.81])
    ours = simulate(s, (0.0, 0.1), method="rk4", dt=1e-4, sample_dt=SAMPLE_DT, gravity=g)
    model, data = load(s, gravity=g)
    positions = [mujoco_node_positions(model, data, s.n_nodes)]
    for _ in range(10):
        for _ in range(100):
            mujoco.mj_step(model, data)
        positions.append(mujoco_node_positions(model, data, s.n_nodes))
    difference = max_difference(np.array(positions), ours.node_position)
    assert difference.max() < 1e-9, difference.max()
    # The fall itself is resolved: the centre of mass dropped by g t^2 / 2.
    drop = ours.node_position[0, :, 2].mean() - ours.node_position[-1, :, 2].mean()
    climb = 0.1 * ours.node_velocity[0, :, 2].mean()
    assert drop + climb == pytest.approx(9.81 * 0.1**2 / 2, rel=1e-9)
