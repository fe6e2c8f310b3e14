"""MJCF export of rods with both end nodes held on planes or lines, with MuJoCo as a peer.

Where the other end's constraints hold whenever the root end's do (parallel planes, a line
parallel to a plane, parallel lines, in-plane structures on parallel lines) the rod's joint tree
is exact: MuJoCo's RK4 follows ours step for step.  Otherwise (a ladder against a wall, a plane
and a skew line, two skew lines, a planar trammel) the loop is closed by tendon equalities,
soft in MuJoCo.

Measured (MuJoCo 4.0.0, both RK4s at the same dt), largest node-position difference [m]: exact
trees over 0.5 s at dt = 1e-4, 5e-14 .. 6e-13 with and without gravity; closed loops under
gravity over 0.5 s, see ``benchmarks/mjcf_closure.py`` and ``docs/constraints.md``.  The
horizons here are short (our constrained RK4 takes ~5 ms a step).
"""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import Structure, simulate
from tensegrity.io.mjcf import mujoco_node_velocities, to_mjcf
from tensegrity.model.planar import planar_two_rod
from tensegrity.physics import dynamics
from tensegrity.physics.constraints import constraints_of
from test_constraints import GRAVITY
from test_mjcf import SAMPLE_DT, load, max_difference, run_mujoco

mujoco = pytest.importorskip("mujoco")

#: Horizons [s] and steps [s] of the exact trees (the same steps whatever dt) and the loops.
T_EXACT, DT_EXACT = 0.1, 2e-4
T_LOOP, DT_LOOP = 0.15, 1e-4
Z = [0.0, 0.0, 1.0]


def consistent(structure, seed=0, scale=1.5):
    """``structure`` with random node velocities projected onto its rods and constraints (the
    kinetic-energy-closest ones that satisfy them, as :func:`dynamics.initial_state` does)."""
    rng = np.random.default_rng(seed)
    s = structure.replace(node_velocity=scale * rng.normal(size=structure.node_position.shape))
    qdot = dynamics.initial_state(s).qdot
    return s.replace(node_velocity=dynamics.nodes_from_coordinates(s, qdot, rates=True))


def held_rod(ends, **held):
    """Rod 0 (nodes 0, 1) from ``ends``, held as ``held`` says; a free rod 1 (nodes 2, 3) above
    it, tied to it by four taut tendons; random consistent velocities."""
    p = np.array([*ends, [0.1, 0.2, 0.9], [0.7, -0.3, 1.2]], float)
    tendons = [[0, 2], [1, 3], [0, 3], [1, 2]]
    lengths = [np.linalg.norm(p[b] - p[a]) for a, b in tendons]
    return consistent(
        Structure(
            node_position=p,
            rod_nodes=[[0, 1], [2, 3]],
            rod_mass=[1.0, 0.8],
            rod_length=[np.linalg.norm(p[1] - p[0]), np.linalg.norm(p[3] - p[2])],
            tendon_nodes=tendons,
            tendon_stiffness=[60.0, 80.0, 50.0, 70.0],
            tendon_rest_length=0.8 * np.array(lengths),
            **held,
        )
    )


def planar_held(directions):
    """Example 2 with rod 0's ends (nodes 0, 1) on lines along ``directions`` (2, 2)."""
    return consistent(
        planar_two_rod(rest_length=0.45).replace(line_nodes=[0, 1], line_direction=directions)
    )


EXACT = {
    "same plane": lambda: held_rod(
        ([0, 0, 0], [0.8, 0.6, 0]), plane_nodes=[0, 1], plane_normal=[Z, Z]
    ),
    "same tilted plane, rod across": lambda: held_rod(
        ([0, 0, 0], [0.8, 0, 0.6]), plane_nodes=[0, 1], plane_normal=[[0.6, 0, -0.8]] * 2
    ),
    "parallel planes": lambda: held_rod(
        ([0, 0, 0], [0.8, 0, 0.6]), plane_nodes=[0, 1], plane_normal=[Z, [0, 0, -2.0]]
    ),
    "line parallel to a plane": lambda: held_rod(
        ([0, 0, 0.6], [0.8, 0, 0]),
        plane_nodes=[1],
        plane_normal=[Z],
        line_nodes=[0],
        line_direction=[[0, 1.0, 0]],
    ),
    "parallel lines": lambda: held_rod(
        ([0, 0, 0], [0.6, 0, 0.8]), line_nodes=[0, 1], line_direction=[[1, 1.0, 0], [-1, -1.0, 0]]
    ),
    "same line": lambda: held_rod(
        ([0, 0, 0], [0.6, 0, 0.8]), line_nodes=[0, 1], line_direction=[[0.6, 0, 0.8]] * 2
    ),
    "planar, parallel lines": lambda: planar_held([[1.0, 1.0], [2.0, 2.0]]),
}

LOOPS = {
    "ladder against a wall": lambda: held_rod(
        ([0.8, 0, 0], [0, 0, 0.6]), plane_nodes=[0, 1], plane_normal=[Z, [1.0, 0, 0]]
    ),
    "plane and a skew line": lambda: held_rod(
        ([0.8, 0, 0], [0, 0, 0.6]),
        plane_nodes=[0],
        plane_normal=[Z],
        line_nodes=[1],
        line_direction=[[0, 0.3, 1.0]],
    ),
    "skew lines": lambda: held_rod(
        ([0.8, 0, 0], [0, 0, 0.6]),
        line_nodes=[0, 1],
        line_direction=[[1.0, 0.2, 0], [0.1, 0.3, 1.0]],
    ),
    "planar trammel": lambda: planar_held([[1.0, 0.3], [0.2, 1.0]]),
}


def off_constraints(structure, positions):
    """Largest distance [m] of the held nodes from their planes and lines along ``positions``
    (T, N, d)."""
    start = structure.node_position
    worst = 0.0
    for k, normal in zip(structure.plane_nodes, structure.plane_normal, strict=True):
        worst = max(worst, np.abs((positions[:, k] - start[k]) @ normal[: structure.dim]).max())
    for k, e in zip(structure.line_nodes, structure.line_direction, strict=True):
        offset = positions[:, k] - start[k]
        worst = max(worst, np.linalg.norm(offset - np.outer(offset @ e, e), axis=1).max())
    return worst


def same_steps(structure, gravity, t_end, dt):
    """Largest node-position difference [m] between MuJoCo's RK4 and ours (same ``dt`` [s]) over
    ``t_end`` [s], our node positions and MuJoCo's."""
    g = None if gravity is None else (gravity if structure.dim == 3 else gravity[[0, 2]])
    ours = simulate(structure, (0.0, t_end), method="rk4", dt=dt, sample_dt=SAMPLE_DT, gravity=g)
    assert ours.success, ours.message
    theirs, _ = run_mujoco(structure, t_end, dt, gravity=g)
    return max_difference(theirs, ours.node_position).max(), ours.node_position, theirs


def spins(model):
    """Joints that turn a rod about its own axis: free joints, balls and ``spin`` hinges."""
    kinds = (int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL))
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    return sum(
        kind in kinds or name.endswith("_spin")
        for kind, name in zip(model.jnt_type, names, strict=True)
    )


def our_dof(structure):
    """Degrees of freedom of our constrained model: 5 per rod (3 if planar) less the independent
    constraint rows."""
    return structure.n_dof - constraints_of(structure).matrix.shape[0]


# ------------------------------------------------------------------------------ exact trees
@pytest.mark.parametrize("name", EXACT)
def test_exact_tree_has_our_degrees_of_freedom_and_initial_state(name):
    """No equality constraint; MuJoCo's degrees of freedom are ours plus a spin per rod (zero
    spin momentum, invisible at the nodes); the keyframe has our node velocities."""
    s = EXACT[name]()
    model, data = load(s)
    assert model.neq == 0 and model.ntendon == s.n_tendons
    assert model.nv == our_dof(s) + spins(model)
    np.testing.assert_allclose(
        mujoco_node_velocities(model, data, s.n_nodes, dim=s.dim),
        s.node_velocity,
        rtol=0,
        atol=1e-12,
    )
    mujoco.mj_forward(model, data)
    assert data.energy[1] == pytest.approx(
        float(dynamics.kinetic_energy(s, dynamics.initial_state(s).qdot)), rel=1e-12
    )


@pytest.mark.parametrize(
    ("name", "gravity"), [(name, GRAVITY if k % 2 else None) for k, name in enumerate(EXACT)]
)
def test_exact_tree_same_steps_as_our_rk4(name, gravity):
    """Measured 1e-14 .. 1e-13 m over 0.1 s (5e-14 .. 6e-13 m over 0.5 s at dt = 1e-4, with
    gravity and without); MuJoCo's held nodes stay on their planes and lines to round-off while
    they move."""
    s = EXACT[name]()
    difference, ours, theirs = same_steps(s, gravity, T_EXACT, DT_EXACT)
    assert difference < 1e-9, difference
    assert off_constraints(s, theirs) < 1e-12
    assert np.ptp(ours[:, :2], axis=0).max() > 0.01  # the held rod moves


# ------------------------------------------------------------------------------ closed loops
@pytest.mark.parametrize(
    ("name", "gravity"),
    [
        ("ladder against a wall", GRAVITY),
        ("plane and a skew line", None),
        ("skew lines", GRAVITY),
        ("planar trammel", None),
    ],
)
def test_closed_loop_follows_our_rk4(name, gravity):
    """The other end is held by tendon equalities (soft: time constant 2 dt): measured
    4e-8 .. 5.6e-7 m over 0.15 s, all of it the held node lagging off its plane or line (the
    two numbers agree); the issue asks 1e-5 m."""
    s = LOOPS[name]()
    difference, ours, theirs = same_steps(s, gravity, T_LOOP, DT_LOOP)
    assert difference < 1e-5, difference
    assert off_constraints(s, theirs) < 1e-5
    assert np.ptp(ours[:, :2], axis=0).max() > 0.02


def test_closed_loop_model():
    """A ladder: its bottom (node 0, on the floor) is the root of two slides and a ball, its top
    (node 1, on the wall x = 0) is held by one tendon equality between two tendons to world
    sites mirrored across the wall; our tendons keep their indices."""
    s = LOOPS["ladder against a wall"]()
    model, data = load(s)
    joint = mujoco.mjtJoint
    kinds = [joint.mjJNT_SLIDE] * 2 + [joint.mjJNT_BALL, joint.mjJNT_FREE]
    assert list(model.jnt_type) == [int(kind) for kind in kinds]
    assert model.neq == 1 and model.eq_type[0] == mujoco.mjtEq.mjEQ_TENDON
    assert model.nv - model.neq == our_dof(s) + spins(model)
    assert model.ntendon == s.n_tendons + 2
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_TENDON, k) for k in range(model.ntendon)]
    assert tuple(names[: s.n_tendons]) == s.tendon_name
    np.testing.assert_array_equal(model.tendon_stiffness[s.n_tendons :], 0.0)
    mujoco.mj_forward(model, data)
    lengths = data.ten_length[s.n_tendons :]
    assert lengths[0] == lengths[1] == pytest.approx(10.0 * s.rod_length.max())
    sites = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"hold0{end}") for end in "ab"]
    mirror = data.site_xpos[sites].copy()
    np.testing.assert_allclose(mirror[:, 1:], [s.node_position[1, 1:]] * 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(
        mirror[:, 0], [10.0 * s.rod_length.max(), -10.0 * s.rod_length.max()], rtol=1e-15
    )


# --------------------------------------------------------------------------------- the CLI
def test_cli_exports_a_structure_file_with_held_rods(tmp_path, capsys):
    from tensegrity.cli.main import main
    from tensegrity.io.formats import write_network

    s = LOOPS["skew lines"]()
    write_network(tmp_path / "skew.json", s)
    out = tmp_path / "skew.xml"
    assert (
        main(
            [
                "export",
                "--structure",
                str(tmp_path / "skew.json"),
                "--format",
                "mjcf",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    assert "(mjcf:" in capsys.readouterr().out
    model = mujoco.MjModel.from_xml_path(str(out))
    assert model.neq == 2 and model.ntendon == s.n_tendons + 4

    damped = s.replace(rod_damping=[0.5, 0.0])
    write_network(tmp_path / "damped.json", damped)
    assert (
        main(
            [
                "export",
                "--structure",
                str(tmp_path / "damped.json"),
                "--format",
                "mjcf",
                "-o",
                str(tmp_path / "damped.xml"),
            ]
        )
        != 0
    )
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "rods[0].damping" in err
    assert not (tmp_path / "damped.xml").exists()
    assert (
        main(
            [
                "export",
                "--structure",
                str(tmp_path / "skew.json"),
                "--kind",
                "prism",
                "-o",
                str(out),
            ]
        )
        != 0
    )
    assert "cannot be combined with --structure" in capsys.readouterr().err


def test_a_tendon_named_like_a_closure_tendon_is_refused():
    s = LOOPS["ladder against a wall"]()
    with pytest.raises(
        ValueError, match=r"^tendons: the name 'hold0b' is taken by a closure tendon"
    ):
        to_mjcf(s.replace(tendon_name=["t0", "hold0b", "t2", "t3"]))
    to_mjcf(
        EXACT["parallel planes"]().replace(tendon_name=["t0", "hold0b", "t2", "t3"])
    )  # no closure
