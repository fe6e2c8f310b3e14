"""MJCF export of a scene with ground planes (:func:`tensegrity.io.mjcf.to_mjcf` with ``ground``
and ``contact_radius``), with MuJoCo as the independent peer: the model holds the planes, the
rod-end spheres and the contact parameters, and MuJoCo's soft contact reproduces the normal law
at rest and Coulomb's sliding, while below the friction angle it creeps where ours sticks.

Measured on the reference machine (MuJoCo 4.0.0, RK4, dt = 1e-4, the 1 kg, 1 m rod of
``tests/test_contact.py`` on k = 1e5 N/m, c = 100 N s/m): resting penetration 4.90451e-5 m
against our m g / (2 k) = 4.905e-5 m (1e-4 relative: MuJoCo's impedance term ``d m a_free``);
sliding at 25 and 35 degrees within 6e-7 and 1.3e-5 of g (sin - mu cos); creep on a 20 degree
slope at mu = 0.5 of 0.17 mm/s (rod along the slope) and 0.24 mm/s (across it).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.io.mjcf import (
    CONTACT_IMPEDANCE,
    CONTACT_SPHERE_FRACTION,
    mujoco_node_positions,
    to_mjcf,
)
from tensegrity.model.ground import Plane, ground
from test_contact import (  # (the same bodies and scenes as there)
    DAMPING,
    MASS,
    RADIUS,
    STIFFNESS,
    G,
    lying_rod,
    on_its_face,
    resting_rod,
    tilted_gravity,
)
from test_contact_outputs import point_mass_above

mujoco = pytest.importorskip("mujoco")

DT = 1e-4


def load(structure, **options):
    model = mujoco.MjModel.from_xml_string(to_mjcf(structure, timestep=DT, **options))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    return model, data


def run(model, data, seconds):
    for _ in range(round(seconds / DT)):
        mujoco.mj_step(model, data)


def test_the_scene_holds_planes_spheres_and_contact_parameters():
    floor = ground(0.1, friction=0.6, kinetic_friction=0.4, stiffness=2e5, damping=50.0)
    wall = Plane(point=(2.0, 0.0, 0.0), normal=(-1.0, 0.0, 1.0), friction=0.0)
    rod = lying_rod(z=0.5).replace(rod_mass=[2.0])
    model, data = load(rod, ground=[floor, wall], contact_radius=RADIUS, gravity=(0, 0, -G))
    assert not model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert model.opt.cone == mujoco.mjtCone.mjCONE_ELLIPTIC
    np.testing.assert_array_equal(model.opt.gravity, [0, 0, -G])
    mujoco.mj_forward(model, data)
    lift = (1 - CONTACT_SPHERE_FRACTION) * RADIUS
    for p, plane in enumerate((floor, wall)):
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"plane{p}")
        assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_PLANE and model.geom_bodyid[g] == 0
        np.testing.assert_allclose(data.geom_xpos[g], plane.point + lift * plane.normal, atol=1e-15)
        np.testing.assert_allclose(data.geom_xmat[g].reshape(3, 3)[:, 2], plane.normal, atol=1e-15)
    for node in (0, 1):
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"end{node}")
        assert model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
        assert model.geom_size[g, 0] == pytest.approx(CONTACT_SPHERE_FRACTION * RADIUS, rel=1e-15)
        assert model.geom_contype[g] == model.geom_conaffinity[g] == 0  # only the pairs touch
        np.testing.assert_allclose(data.geom_xpos[g], rod.node_position[node], atol=1e-15)
    assert model.npair == 4  # two ends, two planes
    for node in (0, 1):
        pair = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_PAIR, f"end{node}_plane0")
        assert model.pair_dim[pair] == 3
        np.testing.assert_array_equal(model.pair_friction[pair, :2], [0.6, 0.6])  # mu_s
        np.testing.assert_allclose(model.pair_solref[pair], [-2e5 / 2.0, -50.0 / 2.0], rtol=1e-15)
        np.testing.assert_array_equal(model.pair_solimp[pair, :2], CONTACT_IMPEDANCE)
        frictionless = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_PAIR, f"end{node}_plane1")
        assert model.pair_dim[frictionless] == 1
    # the spin inertia is the transverse one (a contact's lever cannot roll the rod)
    np.testing.assert_allclose(model.body_inertia[1], [2.0 / 12] * 3, rtol=1e-15)
    assert data.ncon == 0  # the rod is in the air


def test_a_rod_dropped_flat_rests_at_our_penetration():
    """Ours rests at m g / (2 k) per end (the spring-damper's rest); MuJoCo's penalty force is
    ours plus ``d m a_free`` (d = CONTACT_IMPEDANCE, a_free = g at rest), so it rests 1e-4
    shallower: asserted to 1e-3 of the penetration (2.5e-5 of the contact radius)."""
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=0.5)
    structure = lying_rod(z=RADIUS + 0.01)
    model, data = load(structure, ground=plane, contact_radius=RADIUS, gravity=(0, 0, -G))
    run(model, data, 1.0)
    assert data.ncon == 2
    depth = RADIUS - mujoco_node_positions(model, data, 2)[:, 2]
    ours = simulate(structure, (0.0, 1.0), gravity=(0, 0, -G), ground=plane, contact_radius=RADIUS)
    assert ours.status == 0, ours.message
    our_depth = RADIUS - ours.node_position[-1, :, 2]
    np.testing.assert_allclose(our_depth, MASS * G / (2 * STIFFNESS), rtol=1e-6)
    np.testing.assert_allclose(depth, our_depth, rtol=1e-3)


def test_a_point_mass_gets_a_contact_sphere_and_pairs():
    """A point mass is a contact point as a rod end is (docs/simulation.md, "Ground contact"):
    its body ``mass{k}`` carries a massless sphere geom ``mass{k}`` of the same size at its
    centre, paired with every plane at the point mass's own ``solref``."""
    floor = ground(0.1, friction=0.6, stiffness=2e5, damping=50.0)
    wall = Plane(point=(2.0, 0.0, 0.0), normal=(-1.0, 0.0, 1.0), friction=0.0)
    structure = point_mass_above(0.5).replace(node_point_mass=[4.0, 0.0])
    model, data = load(structure, ground=[floor, wall], contact_radius=RADIUS, gravity=(0, 0, -G))
    mujoco.mj_forward(model, data)
    g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "mass0")
    assert g >= 0 and model.geom_type[g] == mujoco.mjtGeom.mjGEOM_SPHERE
    assert model.geom_bodyid[g] == mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "mass0")
    assert model.geom_size[g, 0] == pytest.approx(CONTACT_SPHERE_FRACTION * RADIUS, rel=1e-15)
    assert model.geom_contype[g] == model.geom_conaffinity[g] == 0
    np.testing.assert_allclose(data.geom_xpos[g], structure.node_position[0], atol=1e-15)
    assert model.npair == 2  # one point mass, two planes (the anchor touches nothing)
    pair = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_PAIR, "mass0_plane0")
    assert model.pair_dim[pair] == 3
    np.testing.assert_array_equal(model.pair_friction[pair, :2], [0.6, 0.6])
    np.testing.assert_allclose(model.pair_solref[pair], [-2e5 / 4.0, -50.0 / 4.0], rtol=1e-15)
    np.testing.assert_array_equal(model.pair_solimp[pair, :2], CONTACT_IMPEDANCE)
    assert model.pair_dim[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_PAIR, "mass0_plane1")] == 1


def test_a_point_mass_dropped_on_the_ground_rests_at_our_penetration():
    """Ours rests at m g / k (the spring-damper's rest), MuJoCo 1e-4 shallower (its impedance
    term, as for the rod above): asserted to the rod's 1e-3 of the penetration.  The point mass
    hangs on a slack tendon from an anchor (a structure needs a member)."""
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=0.5)
    structure = point_mass_above(RADIUS + 0.01)
    model, data = load(structure, ground=plane, contact_radius=RADIUS, gravity=(0, 0, -G))
    run(model, data, 1.0)
    assert data.ncon == 1
    depth = RADIUS - mujoco_node_positions(model, data, 2)[0, 2]
    ours = simulate(structure, (0.0, 1.0), gravity=(0, 0, -G), ground=plane, contact_radius=RADIUS)
    assert ours.status == 0, ours.message
    our_depth = RADIUS - ours.node_position[-1, 0, 2]
    assert our_depth == pytest.approx(MASS * G / STIFFNESS, rel=1e-6)
    assert depth == pytest.approx(our_depth, rel=1e-3)


def test_a_point_mass_above_the_friction_angle_slides_at_the_closed_form_acceleration():
    """A point mass resting on a 0.6 rad slope at mu = 0.5 (atan 0.5 = 0.46 rad) slides at
    g (sin - mu cos) (measured within 4e-5; asserted to the rod's 1e-4).  Its body slides
    without turning: a free body of negligible inertia spins up from the friction at its
    sphere's surface and diverges."""
    theta, mu = 0.6, 0.5
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu)
    depth = MASS * G * math.cos(theta) / STIFFNESS
    model, data = load(
        point_mass_above(RADIUS - depth),
        ground=plane,
        contact_radius=RADIUS,
        gravity=tilted_gravity(theta),
    )
    t, x = [], []
    for _ in range(20):
        run(model, data, 0.05)
        t.append(data.time)
        x.append(mujoco_node_positions(model, data, 2)[0, 0])
    acceleration = 2 * np.polyfit(t, x, 2)[0]
    expected = G * (math.sin(theta) - mu * math.cos(theta))
    assert acceleration == pytest.approx(expected, rel=1e-4)


@pytest.mark.parametrize(("mu", "degrees"), [(0.3, 25.0), (0.5, 35.0)])
def test_a_rod_above_the_friction_angle_slides_at_the_closed_form_acceleration(mu, degrees):
    """Measured within 1.3e-5 of g (sin - mu cos); asserted to 1e-4 (the impedance term, and
    friction's regularisation, shift it by about 1e-5)."""
    theta = math.radians(degrees)
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu)
    model, data = load(
        resting_rod(theta), ground=plane, contact_radius=RADIUS, gravity=tilted_gravity(theta)
    )
    t, x = [], []
    for _ in range(50):
        run(model, data, 0.01)
        t.append(data.time)
        x.append(mujoco_node_positions(model, data, 2)[:, 0].mean())
    later = np.array(t) > 0.1
    acceleration = 2 * np.polyfit(np.array(t)[later], np.array(x)[later], 2)[0]
    expected = G * (math.sin(theta) - mu * math.cos(theta))
    assert acceleration == pytest.approx(expected, rel=1e-4)


@pytest.mark.parametrize("axis", [0, 1])
def test_below_the_friction_angle_mujoco_creeps_where_ours_sticks(axis):
    """20 degrees at mu = 0.5 (atan 0.5 = 26.6 degrees): ours moves less than 1e-9 m over 2 s;
    MuJoCo's regularised friction creeps at a steady, small speed (measured 0.17 mm/s along the
    rod, 0.24 mm/s across it), neither zero nor a slide."""
    theta, mu = math.radians(20.0), 0.5
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu)
    structure = resting_rod(theta, axis)
    gravity = tilted_gravity(theta)
    model, data = load(structure, ground=plane, contact_radius=RADIUS, gravity=gravity)
    run(model, data, 1.0)
    before = mujoco_node_positions(model, data, 2)
    run(model, data, 1.0)
    speed = (mujoco_node_positions(model, data, 2) - before)[:, 0]
    assert np.all((speed > 1e-5) & (speed < 1e-3)), speed
    ours = simulate(structure, (0.0, 2.0), gravity=gravity, ground=plane, contact_radius=RADIUS)
    assert ours.status == 0, ours.message
    assert np.abs(ours.node_position - ours.node_position[0]).max() < 1e-9


@pytest.mark.parametrize(
    ("options", "error", "field"),
    [
        ({"ground": ground(), "contact_radius": -0.01}, ValueError, "contact_radius"),
        ({"ground": ground(), "contact_radius": 0.0}, ValueError, "contact_radius"),
        ({"ground": ground()}, ValueError, "contact_radius"),
        ({"contact_radius": -1.0}, ValueError, "contact_radius"),
        ({"ground": ground(), "contact_radius": float("nan")}, ValueError, "contact_radius"),
        ({"ground": "floor", "contact_radius": 0.01}, TypeError, "ground"),
    ],
)
def test_bad_scene_options_name_the_field(options, error, field):
    with pytest.raises(error, match=f"^{field}:") as info:
        to_mjcf(lying_rod(z=0.5), **options)
    assert "\n" not in str(info.value)


def six_bar_on_its_face(height: float):
    """The six-bar of ``tests/test_contact.py`` (k = 2000 N/m, 100 N of prestress, c = 20 N s/m)
    turned onto its face ``f---`` (nodes 0, 4, 8), those ends ``height`` [m] above the ground."""
    from tensegrity.design.catalogue import six_bar_robot

    return on_its_face(six_bar_robot(stiffness=2000.0, tension=100.0, damping=20.0), height)


@pytest.mark.parametrize(
    ("mujoco_friction", "mujoco_height", "agrees"),
    [(0.8, 0.5, True), (0.3, 0.5, False), (0.8, 0.51, False)],
)
def test_a_six_bar_dropped_from_half_a_metre_lands_as_in_mujoco(
    mujoco_friction, mujoco_height, agrees
):
    """The six-bar dropped flat on its face from 0.5 m (3.1 m/s at impact), bouncing once and
    settling, 1.5 s.  The centres of mass (the mean of the nodes: equal rods) agree to 1e-15 m in
    free fall; after the impact they differ by at most 0.67 mm (measured, at 0.64 s, in the
    flight after the bounce: the take-off speed differs by the impedance term ``d m a_free`` of
    MuJoCo's normal force and by its soft friction during the impact, where ours sticks the ends
    by an impulse), of which 0.32 mm horizontally: MuJoCo's regularised friction creeps
    (0.17-0.24 mm/s for a rod, above; 0.24 mm/s x 1.5 s = 0.36 mm).  Asserted: 0.5 mm
    horizontally (that creep bound and 40%) and 1 mm in all (the measured 0.67 mm and 50%).
    Wrong scenes fail: MuJoCo at mu = 0.3 (the face's ends slide apart at impact: 34 mm), or
    dropped from 0.51 m (10 mm)."""
    plane = ground(friction=0.8)
    ours_robot = six_bar_on_its_face(0.5)
    ours = simulate(
        ours_robot,
        (0.0, 1.5),
        gravity=(0, 0, -G),
        ground=plane,
        contact_radius=RADIUS,
        sample_dt=0.01,
    )
    assert ours.status == 0, ours.message
    assert np.ptp(ours.total_energy) < 1e-5  # (the run's balance: rtol 1e-9 of ~30 J)
    model, data = load(
        six_bar_on_its_face(mujoco_height),
        ground=ground(friction=mujoco_friction),
        contact_radius=RADIUS,
        gravity=(0, 0, -G),
    )
    centre = []
    for t in ours.t:
        while data.time < t - DT / 2:
            mujoco.mj_step(model, data)
        centre.append(mujoco_node_positions(model, data, 12).mean(axis=0))
    difference = np.array(centre) - ours.node_position.mean(axis=1)
    horizontal = np.linalg.norm(difference[:, :2], axis=1).max()
    total = np.linalg.norm(difference, axis=1).max()
    assert ((horizontal < 5e-4) and (total < 1e-3)) == agrees, (horizontal, total)
    assert ours.node_position[-1, :, 2].min() > RADIUS - 3e-3  # (resting on its ends)


def first_rolling_step():
    """The six-bar on its face ``f---`` with its scene, and the first step of
    ``examples/six_bar_roll.csv`` (the plan of :func:`tensegrity.design.rolling.six_bar_roll`:
    ramped in from 0.5 s to 1 s, held to 2 s, ramped out by 2.5 s)."""
    from pathlib import Path

    from tensegrity.io.formats import read_scene, read_structure
    from tensegrity.io.tables import read_control_table
    from tensegrity.model.loads import ControlTable

    path = Path(__file__).resolve().parent.parent / "examples" / "six_bar_roll"
    robot = read_structure(path.with_suffix(".json"))
    table = read_control_table(path.with_suffix(".csv"), robot)
    return (
        robot,
        read_scene(path.with_suffix(".json")),
        ControlTable(table.time[:5], table.control[:5]),
    )


@pytest.mark.parametrize(
    ("kinetic_friction", "mujoco_friction", "mujoco_control", "agrees"),
    [(0.8, 0.8, 1.0, True), (0.6, 0.8, 1.0, False), (0.8, 0.5, 1.0, False), (0.8, 0.8, 0.0, False)],
)
def test_the_first_rolling_step_of_the_six_bar_tips_as_in_mujoco(
    kinetic_friction, mujoco_friction, mujoco_control, agrees
):
    """The first step of the rolling example, 3 s: the control deforms the robot (its face's
    ends slide about 0.1 m, at kinetic friction), tips it over the edge (4, 8) at 1.0 s onto the
    open face (4, 6, 8) at 1.2 s and on to the cable face (1, 6, 8) at 1.6 s; the centre of mass
    moves 0.5 m.  MuJoCo has one friction coefficient, so ours runs with mu_k = mu_s = 0.8 here.
    The centres of mass then agree to 0.58 mm up to 1.2 s (the slides and the tip: MuJoCo's
    regularised friction against our exact one, the impedance term of its normal force) and to
    4.6 mm over the 3 s (measured, at 2.4 s, rocking on the new face after two landings: our
    sticking impulse at touch-down against MuJoCo's soft one; 4.0 mm at MuJoCo's dt = 2.5e-5, so
    not its time step).  Asserted: 1 mm up to 1.2 s and 7 mm in all (the measured and 50%).
    Wrong scenes fail: our mu_k = 0.6 (the example's) against MuJoCo's single 0.8 (the slides
    differ by 10 mm: 9.1 mm up to 1.2 s, 17.5 mm in all), MuJoCo at mu = 0.5 (16 mm, 77 mm),
    or MuJoCo without the control (it stays: 0.53 m)."""
    robot, scene, table = first_rolling_step()
    plane = scene.planes[0]
    ours = simulate(
        robot,
        (0.0, 3.0),
        control=table,
        rtol=1e-12,
        sample_dt=0.01,
        gravity=scene.gravity,
        ground=ground(friction=0.8, kinetic_friction=kinetic_friction),
        contact_radius=scene.contact_radius,
    )
    assert ours.status == 0, ours.message
    model, data = load(
        robot,
        ground=ground(friction=mujoco_friction, stiffness=plane.stiffness, damping=plane.damping),
        contact_radius=scene.contact_radius,
        gravity=scene.gravity,
    )
    rest = model.tendon_lengthspring[:, 1].copy()  # the springlength "0 Lbar" of each cable
    centre = []
    for t in ours.t:
        while data.time < t - DT / 2:
            model.tendon_lengthspring[:, 1] = rest - mujoco_control * table(data.time + DT / 2)
            mujoco.mj_step(model, data)
        centre.append(mujoco_node_positions(model, data, robot.n_nodes).mean(axis=0))
    difference = np.linalg.norm(np.array(centre) - ours.node_position.mean(axis=1), axis=1)
    tip = difference[ours.t <= 1.2].max()
    assert np.linalg.norm(ours.node_position[-1].mean(axis=0)[:2]) > 0.45  # it rolled
    assert ((tip < 1e-3) and (difference.max() < 7e-3)) == agrees, (tip, difference.max())
