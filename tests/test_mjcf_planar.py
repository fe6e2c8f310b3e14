"""MJCF export of planar structures (in z = 0: two slides and a hinge per rod) and of nodes held
on planes and lines (the held rod end is the root of its body: slides spanning the plane or line,
then a ball or hinge there), with MuJoCo as an independent peer.

Measured (MuJoCo 4.0.0), largest node-position difference [m] between MuJoCo's RK4 and ours at
the same dt = 1e-4 over 0.5 s: Example 2 with slack tendons 1.2e-13, with gravity 2.5e-13;
Example 1 spinning under gravity 3.3e-13; a pendulum sliding on a line 4e-14; a bead (point
mass) on a line 3e-13; the tripod on the floor with random velocities (the apex joints are soft
``connect`` constraints) 2.2e-9, with gravity 2.4e-10; Example 2 with a fixed node and a node on
a line 5.8e-10; the hanging chain with its payload on a plane 2.4e-9.
"""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import Structure, simulate
from tensegrity.io.mjcf import mujoco_node_positions, mujoco_node_velocities, to_mjcf
from tensegrity.model.planar import planar_rod, planar_two_rod
from test_constraints import GRAVITY, NO_TENDONS, hanging_chain
from test_mjcf import SAMPLE_DT, load, max_difference, rod_consistent_velocity, run_mujoco

mujoco = pytest.importorskip("mujoco")

T_END, DT = 0.5, 1e-4
PLANAR_GRAVITY = GRAVITY[[0, 2]]


def same_steps(structure, gravity=None):
    """Largest node-position difference [m] between MuJoCo's RK4 and ours (same dt) over T_END,
    our run, and which tendons went slack in MuJoCo."""
    ours = simulate(
        structure, (0.0, T_END), method="rk4", dt=DT, sample_dt=SAMPLE_DT, gravity=gravity
    )
    assert ours.success, ours.message
    positions, went_slack = run_mujoco(structure, T_END, DT, gravity=gravity)
    return max_difference(positions, ours.node_position).max(), ours, went_slack


def example2():
    """Example 2 with unequal rest lengths (t2 and t5 near their initial lengths) and random
    rod-consistent velocities: the tendons go slack and taut again."""
    s = planar_two_rod(rest_length=(0.5, 0.62, 0.55, 0.63))
    return s.replace(node_velocity=rod_consistent_velocity(s, 0.8, seed=2))


# --------------------------------------------------------------------- planar structures
def test_planar_model_is_three_dof_rods_in_the_plane():
    s = example2()
    model, data = load(s)
    assert model.nv == 3 * s.n_rods and model.nq == 3 * s.n_rods
    kinds = [mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE]
    assert list(model.jnt_type) == kinds * s.n_rods
    # The joint-space mass matrix is diag(m, m, m L^2/12) per rod (slides along x, y, a hinge
    # about z at the centre), whatever the rod's direction.
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    expected = np.concatenate(
        [[m, m, m * L**2 / 12] for m, L in zip(s.rod_mass, s.rod_length, strict=True)]
    )
    np.testing.assert_allclose(full, np.diag(expected), rtol=0, atol=1e-14)
    # Initial state read back as 2-D; the sites lie in z = 0.
    np.testing.assert_allclose(
        mujoco_node_positions(model, data, s.n_nodes, dim=2), s.node_position, rtol=0, atol=1e-15
    )
    np.testing.assert_allclose(
        mujoco_node_velocities(model, data, s.n_nodes, dim=2), s.node_velocity, rtol=0, atol=1e-14
    )
    assert np.abs(mujoco_node_positions(model, data, s.n_nodes)[:, 2]).max() == 0.0


def test_example2_same_steps_as_our_rk4():
    """The paper's Example 2 (eqs. 18.A.20-22) with tendons going slack: MuJoCo's RK4 follows
    ours step for step (measured 1.2e-13 m over 0.5 s), nodes stay in z = 0."""
    s = example2()
    difference, ours, went_slack = same_steps(s)
    assert difference < 1e-9, difference
    assert np.ptp(ours.node_position, axis=0).max() > 0.1  # it moves
    assert went_slack.any() and ours.slack_count.max() > 0  # the deadband is exercised
    model, data = load(s, timestep=DT)
    for _ in range(round(T_END / DT)):
        mujoco.mj_step(model, data)
    assert np.abs(mujoco_node_positions(model, data, s.n_nodes)[:, 2]).max() < 1e-12


def test_example2_under_gravity_same_steps():
    difference, ours, _ = same_steps(example2(), gravity=PLANAR_GRAVITY)
    assert difference < 1e-9, difference
    drop = ours.node_position[0, :, 1].mean() - ours.node_position[-1, :, 1].mean()
    climb = T_END * ours.node_velocity[0, :, 1].mean()
    assert drop + climb == pytest.approx(9.81 * T_END**2 / 2, rel=1e-9)  # equal node masses


def test_example1_rod_tumbling_under_gravity():
    """Example 1: a single planar rod thrown spinning: its centre falls as g t^2 / 2 and its
    angular velocity is constant, in MuJoCo as in ours (same steps)."""
    s = planar_rod(mass=0.7, length=1.3, angle=0.4)
    arm = s.node_position - s.node_position.mean(axis=0)
    spin = 3.0 * np.column_stack([-arm[:, 1], arm[:, 0]])  # 3 rad/s about the centre
    s = s.replace(node_velocity=np.array([0.4, 2.0]) + spin)
    difference, ours, _ = same_steps(s, gravity=PLANAR_GRAVITY)
    assert difference < 1e-9, difference
    r = ours.node_position[:, 1] - ours.node_position[:, 0]
    angle = np.unwrap(np.arctan2(r[:, 1], r[:, 0]))
    np.testing.assert_allclose(angle - angle[0], 3.0 * ours.t, rtol=0, atol=1e-9)


def test_planar_fixed_node_and_line_same_steps():
    """Example 2 with node 0 fixed (a ``connect`` to ground whose z row is empty in the plane)
    and node 2 on a line (rod 1 on a slide along it and a hinge at node 2), under gravity."""
    s = example2()
    v = s.node_velocity.copy()
    v[[0, 1]] = 0.0  # rod 0 starts at rest: node 0 is fixed
    v[3] -= v[2]  # rod 1: node 2 starts at rest too (any velocity along the line would do)
    v[2] = 0.0
    s = s.replace(
        node_velocity=v,
        node_fixed=[True, False, False, False],
        line_nodes=[2],
        line_direction=[[1.0, 1.0]],
    )
    difference, ours, _ = same_steps(s, gravity=PLANAR_GRAVITY)
    assert difference < 1e-6, difference  # measured 5.8e-10 (the soft connect)
    p = ours.node_position
    assert np.abs(p[:, 0] - p[0, 0]).max() < 1e-12
    assert np.abs((p[:, 2, 0] - p[0, 2, 0]) - (p[:, 2, 1] - p[0, 2, 1])).max() < 1e-12
    assert np.ptp(p[:, 2, 0]) > 0.01  # node 2 slides along the line


# ------------------------------------------------------------------ plane and line constraints
def test_pendulum_sliding_on_a_line_same_steps():
    s = Structure(
        node_position=[[0, 0, 0], [0.6, 0.0, -0.8]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        line_nodes=[0],
        line_direction=[[2.0, 0, 0]],
        **NO_TENDONS,
    )
    difference, ours, _ = same_steps(s, gravity=GRAVITY)
    assert difference < 1e-9, difference
    assert np.ptp(ours.node_position[:, 0, 0]) > 0.05


def tripod():
    """Three rods joined at the apex, feet on the floor z = 0 by plane constraints, tied by three
    tendons (as in test_constraints), released with random velocities consistent with all that."""
    L = 1.0
    angles = 2 * np.pi * np.arange(3) / 3
    feet = 0.5 * np.stack([np.cos(angles), np.sin(angles), np.zeros(3)], axis=1)
    apex = np.array([0, 0, np.sqrt(L**2 - 0.25)])
    rng = np.random.default_rng(8)
    apex_v = 0.5 * rng.normal(size=3)
    # foot velocities in the floor with (foot - apex) . (v_foot - v_apex) = 0
    v = []
    for foot in feet:
        u = foot - apex
        w = 0.5 * rng.normal(size=3)
        w[2] = 0.0
        # solve u . (w + s e - apex_v) = 0 for a floor direction e, keeping w in the floor
        e = np.array([u[0], u[1], 0.0])
        w += (u @ (apex_v - w)) / (u @ e) * e
        v += [w, apex_v]
    return Structure(
        node_position=np.array([feet[0], apex, feet[1], apex, feet[2], apex]),
        node_velocity=np.array(v),
        rod_nodes=[[0, 1], [2, 3], [4, 5]],
        rod_mass=[1.2] * 3,
        rod_length=[L] * 3,
        joint_nodes=[[1, 3], [3, 5]],
        plane_nodes=[0, 2, 4],
        plane_normal=[[0, 0, 1.0]] * 3,
        tendon_nodes=[[0, 2], [2, 4], [4, 0]],
        tendon_stiffness=[80.0] * 3,
        tendon_rest_length=[0.9] * 3,
    )


@pytest.mark.parametrize("gravity", [None, GRAVITY])
def test_tripod_on_the_floor_same_steps(gravity):
    s = tripod()
    difference, ours, _ = same_steps(s, gravity=gravity)
    assert difference < 1e-6, difference  # measured 2.2e-9 and 2.4e-10 (soft apex joints)
    feet = ours.node_position[:, [0, 2, 4]]
    assert np.abs(feet[..., 2]).max() < 1e-12 and np.ptp(feet[..., :2], axis=0).max() > 0.05


def test_bead_on_a_line_payload_on_a_plane_and_a_block_sliding_down_a_plane():
    """A bead (point mass) on a skew line, tied to anchors and to a free rod by tendons; the
    hanging chain with its payload (a point mass joined to rod 1's end) on the plane y = 0,
    swinging under gravity; and a point mass on an inclined plane slides down it at
    g sin(theta), in MuJoCo alone (a closed form)."""
    bead = Structure(
        node_position=[
            [0.0, 0, 0],
            [1.0, 0, 0.5],
            [-1.0, 0.2, 0.5],
            [0.3, 0.1, 0.1],
            [0.3, 0.1, 0.9],
        ],
        node_velocity=[[0.5, 0.5, 0.0]] + [[0.0] * 3] * 4,
        rod_nodes=[[3, 4]],
        rod_mass=[1.0],
        rod_length=[0.8],
        node_fixed=[False, True, True, False, False],
        node_point_mass=[0.5, 0, 0, 0, 0],
        line_nodes=[0],
        line_direction=[[1.0, 1.0, 0.0]],
        tendon_nodes=[[0, 1], [0, 2], [0, 3], [4, 1], [4, 2]],
        tendon_stiffness=[40.0, 60.0, 30.0, 50.0, 50.0],
        tendon_rest_length=[0.8, 0.9, 0.1, 0.5, 0.5],
    )
    difference, ours, _ = same_steps(bead, gravity=GRAVITY)
    assert difference < 1e-9, difference  # measured 3e-13
    path = ours.node_position[:, 0]
    assert np.ptp(path[:, 0]) > 0.1 and np.abs(path[:, 0] - path[:, 1]).max() < 1e-12

    chain = hanging_chain(damped=False).replace(plane_nodes=[6], plane_normal=[[0, 2.0, 0]])
    difference, ours, _ = same_steps(chain, gravity=GRAVITY)
    assert difference < 1e-6, difference  # measured 2.4e-9 (the joints are soft)
    assert np.ptp(ours.node_position[:, 6, 0]) > 0.5

    theta = 0.3
    normal = np.array([np.sin(theta), 0, np.cos(theta)])
    block = Structure(
        node_position=[[0.0, 0, 0]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_point_mass=[2.0],
        plane_nodes=[0],
        plane_normal=[normal],
        **NO_TENDONS,
    )
    model, data = load(block, gravity=GRAVITY)
    assert model.nv == 2
    for _ in range(round(T_END / 1e-4)):
        mujoco.mj_step(model, data)
    along = GRAVITY - (GRAVITY @ normal) * normal
    np.testing.assert_allclose(
        mujoco_node_positions(model, data, 1)[0], T_END**2 / 2 * along, rtol=0, atol=1e-12
    )


# ------------------------------------------------------------------------------ refusals
@pytest.mark.parametrize(
    ("structure", "options", "message"),
    [
        (lambda: planar_rod(), {"gravity": (0, 0, -9.81)}, r"^gravity: expected 2 finite numbers"),
        (lambda: tripod(), {"gravity": (0, -9.81)}, r"^gravity: expected 3 finite numbers"),
    ],
)
def test_what_cannot_be_exported_is_refused(structure, options, message):
    with pytest.raises(ValueError, match=message):
        to_mjcf(structure(), **options)


def test_read_back_dimension_is_checked():
    model, data = load(planar_rod())
    for dim in (1, 4, True):
        with pytest.raises(ValueError, match=r"^dim:"):
            mujoco_node_positions(model, data, 2, dim=dim)


@pytest.mark.parametrize("kind", ["planar", "rod"])
def test_cli_exports_planar_kinds_to_mjcf(kind, tmp_path, capsys):
    from tensegrity.cli.main import main
    from tensegrity.design import catalogue as generators

    path = tmp_path / "p.xml"
    assert main(["export", "--kind", kind, "--format", "mjcf", "-o", str(path)]) == 0
    assert "(mjcf:" in capsys.readouterr().out
    expected = generators.generate(kind)
    model = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    assert model.nv == 3 * expected.n_rods and model.ntendon == expected.n_tendons
    np.testing.assert_allclose(
        mujoco_node_positions(model, data, expected.n_nodes, dim=2),
        expected.node_position,
        rtol=0,
        atol=1e-15,
    )
