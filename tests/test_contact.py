"""Ground contact (:mod:`tensegrity.model.ground`, :mod:`tensegrity.physics.contact`): a rod on
planes against closed forms that share no code with the engine: the restitution of the normal
law, sticking below the friction angle, sliding above it, and the energy balance."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.design.rolling import stand_on_face
from tensegrity.model.ground import Plane, ground
from tensegrity.model.structure import Structure
from tensegrity.physics.contact import REVERSAL_SPEED

MASS, LENGTH, STIFFNESS, DAMPING, G = 1.0, 1.0, 1e5, 100.0, 9.81
#: Radius of the rod's ends as contact points [m]: a resting end sinks less than that.
RADIUS = 0.01


def one_rod(ends, velocity=(0.0, 0.0, 0.0)) -> Structure:
    """A rod of 1 kg and 1 m between ``ends`` (2, 3) [m], moving at ``velocity`` [m/s]."""
    return Structure(
        node_position=ends,
        node_velocity=[velocity, velocity],
        rod_nodes=[[0, 1]],
        rod_mass=[MASS],
        rod_length=[LENGTH],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
    )


def lying_rod(z: float = 0.0, velocity=(0.0, 0.0, 0.0)) -> Structure:
    """A rod of 1 kg and 1 m along x, its centre at height ``z`` [m], moving at ``velocity``."""
    return one_rod([[-LENGTH / 2, 0.0, z], [LENGTH / 2, 0.0, z]], velocity)


def test_a_rod_dropped_flat_rebounds_with_the_laws_restitution():
    """No gravity: each end hits the plane at 1 m/s as a point of half the rod's mass."""
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=0.5)
    run = simulate(
        lying_rod(z=0.01, velocity=(0.0, 0.0, -1.0)),
        (0.0, 0.05),
        ground=plane,
        rtol=1e-11,
        atol=1e-13,
        sample_dt=1e-3,
    )
    assert run.status == 0, run.message
    expected = plane.restitution(MASS / 2)
    assert 0.3 < expected < 0.9
    assert run.node_velocity[-1, :, 2] == pytest.approx([expected, expected], rel=1e-8)
    assert np.abs(run.node_velocity[-1, :, :2]).max() < 1e-12  # (no tangential motion)
    assert len(run.switch_times) == 2  # (onset and lift-off, both ends at once)
    dissipated = 0.5 * MASS * (1.0 - expected**2)
    assert run.energy["dissipated"][-1] == pytest.approx(dissipated, rel=1e-8)
    assert np.ptp(run.total_energy) < 1e-9


def tilted_gravity(theta: float) -> list[float]:
    """Gravity tilted by ``theta`` [rad] down the +x direction of the plane z = 0."""
    return [G * math.sin(theta), 0.0, -G * math.cos(theta)]


def resting_rod(theta: float, axis: int = 0) -> Structure:
    """A rod with ends of radius :data:`RADIUS` lying on z = 0 pressed in by its weight's normal
    part (the law's rest), along x (``axis`` 0) or y (1)."""
    depth = MASS * G * math.cos(theta) / (2 * STIFFNESS)
    ends = np.zeros((2, 3))
    ends[:, axis] = [-LENGTH / 2, LENGTH / 2]
    ends[:, 2] = RADIUS - depth
    return one_rod(ends)


@pytest.mark.parametrize("mu", [0.2, 0.5, 1.0])
@pytest.mark.parametrize("fraction", [0.3, 0.9, 0.99])
def test_a_rod_on_a_slope_below_the_friction_angle_stays_put(mu, fraction):
    theta = fraction * math.atan(mu)
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu)
    structure = resting_rod(theta, axis=int(fraction > 0.5))
    run = simulate(
        structure,
        (0.0, 10.0),
        gravity=tilted_gravity(theta),
        ground=plane,
        contact_radius=RADIUS,
        sample_dt=0.5,
    )
    assert run.status == 0, run.message
    drift = np.abs(run.node_position - run.node_position[0]).max()
    assert drift <= 1e-9, drift
    assert np.ptp(run.total_energy) < 1e-9


@pytest.mark.parametrize("method", ["DOP853", "RK45"])
@pytest.mark.parametrize(("mu_s", "mu_k", "degrees"), [(0.3, 0.3, 25.0), (0.5, 0.4, 35.0)])
def test_a_rod_above_the_friction_angle_slides_at_the_closed_form_acceleration(
    method, mu_s, mu_k, degrees
):
    theta = math.radians(degrees)
    assert math.tan(theta) > mu_s
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu_s, kinetic_friction=mu_k)
    run = simulate(
        resting_rod(theta),
        (0.0, 1.0),
        gravity=tilted_gravity(theta),
        ground=plane,
        contact_radius=RADIUS,
        method=method,
        sample_dt=0.1,
        rtol=1e-10,
        atol=1e-12,
    )
    assert run.status == 0, run.message
    acceleration = G * (math.sin(theta) - mu_k * math.cos(theta))
    x = run.node_position[:, :, 0].mean(axis=1) - run.node_position[0, :, 0].mean()
    assert x[-1] == pytest.approx(0.5 * acceleration, rel=1e-3)
    dissipated = run.energy["dissipated"]
    assert np.all(np.diff(dissipated) >= -1e-12)  # (friction never gives energy back)
    assert np.ptp(run.total_energy) < 1e-8


def test_a_node_below_the_ground_is_refused_naming_it():
    with pytest.raises(ValueError, match=r"^ground: node 0 \(rod 0's end a\) starts 0.1 m below"):
        simulate(lying_rod(z=-0.1), (0.0, 0.1), ground=ground())


@pytest.mark.parametrize(
    ("options", "words"),
    [
        (dict(method="rk4", dt=1e-4), r"ground \(--ground\): contact needs an adaptive method"),
        (dict(locate_switches=False), r"ground \(--ground\): contact needs an adaptive method"),
        (dict(contact_radius=-1.0), "contact_radius: must be a number >= 0"),
    ],
)
def test_contact_options_that_cannot_work_are_refused(options, words):
    with pytest.raises(ValueError, match="^" + words):
        simulate(lying_rod(z=0.1), (0.0, 0.1), ground=ground(), **options)


@pytest.mark.parametrize(
    ("fields", "words"),
    [
        (dict(normal=(0, 0, 0)), "normal: must not be zero"),
        (dict(friction=-0.1), "friction: must be a finite number >= 0"),
        (dict(friction=0.3, kinetic_friction=0.5), "kinetic_friction: must not exceed friction"),
        (dict(stiffness=0.0), "stiffness: must be a finite number > 0"),
        (dict(point=(0, 0)), "point: expected 3 finite numbers"),
    ],
)
def test_a_bad_plane_is_a_one_line_error_naming_the_field(fields, words):
    with pytest.raises(ValueError, match="^" + words) as info:
        Plane(**fields)
    assert "\n" not in str(info.value)


def test_ground_must_be_planes():
    with pytest.raises(TypeError, match=r"^ground: expected a Plane"):
        simulate(lying_rod(z=0.1), (0.0, 0.1), ground=0.0)


def test_a_sliding_rod_stops_where_kinetic_friction_stops_it_and_stays():
    """On flat ground, from 1 m/s along its axis: it stops after ``v^2 / (2 mu_k g)`` at ``v /
    (mu_k g)`` (a located slip-to-stick event, where the velocity has turned back to
    ``REVERSAL_SPEED``), then sticks."""
    mu, speed = 0.4, 1.0
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu)
    structure = resting_rod(0.0)
    structure = Structure.from_dict(
        {**structure.to_dict(), "velocities": [[speed, 0.0, 0.0], [speed, 0.0, 0.0]]}
    )
    run = simulate(
        structure,
        (0.0, 2.0),
        gravity=[0.0, 0.0, -G],
        ground=plane,
        contact_radius=RADIUS,
        sample_dt=0.05,
        rtol=1e-11,
        atol=1e-13,
    )
    assert run.status == 0, run.message
    stop = speed / (mu * G)
    # the stop is located where the velocity has turned back to REVERSAL_SPEED
    assert min(abs(np.asarray(run.switch_times) - stop - REVERSAL_SPEED / (mu * G))) < 1e-10
    x = run.node_position[:, :, 0].mean(axis=1)
    assert x[-1] - x[0] == pytest.approx(speed**2 / (2 * mu * G), rel=1e-7)
    after = run.t > stop + 0.05
    assert np.abs(run.node_position[after] - run.node_position[-1]).max() <= 1e-9


def test_a_rod_held_by_friction_slips_when_a_ramped_pull_reaches_mu_n():
    """A horizontal pull on both ends growing at 10 N/s (a Painleve-style ramp, as Drake tests
    it): the rod sticks until the pull reaches ``mu_s m g``."""
    mu, ramp = 0.5, 10.0
    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu, kinetic_friction=0.4)
    run = simulate(
        resting_rod(0.0),
        (0.0, 0.8),
        gravity=[0.0, 0.0, -G],
        ground=plane,
        contact_radius=RADIUS,
        external_force=lambda t: np.array([[ramp * t / 2, 0.0, 0.0]] * 2),
        sample_dt=0.01,
    )
    assert run.status == 0, run.message
    slip = mu * MASS * G / ramp
    assert run.switch_times[0] == pytest.approx(slip, rel=1e-3)
    before = run.t < run.switch_times[0]
    assert np.abs(run.node_position[before] - run.node_position[0]).max() <= 1e-9
    assert run.node_position[-1, 0, 0] - run.node_position[0, 0, 0] > 1e-3  # (then it slides)


def on_its_face(robot: Structure, height: float = 0.0) -> Structure:
    """``robot`` (an expanded octahedron, e.g. the six-bar) on its face of the three nodes
    nearest (-1, -1, -1) (:func:`tensegrity.design.rolling.stand_on_face`), their centres at
    :data:`RADIUS` + ``height`` [m]."""
    face = np.argsort(robot.node_position @ np.ones(3))[:3]
    return stand_on_face(robot, face, contact_radius=RADIUS + height)


def settle_and_hold(structure: Structure, scene: dict, settle: float) -> tuple:
    """``structure`` run in ``scene`` (``simulate``'s gravity, ground, contact radius) to rest
    (within ``settle`` [s]), then 10 s more from that rest: both runs."""
    from tensegrity.physics.dynamics import State

    settled = simulate(
        structure,
        (0.0, settle),
        steady_state=True,
        velocity_tol=1e-10,
        acceleration_tol=1e-8,
        sample_dt=0.01,
        **scene,
    )
    start = State(t=0.0, q=settled.q[-1], qdot=settled.qdot[-1])
    return settled, simulate(structure, (0.0, 10.0), initial=start, sample_dt=0.5, **scene)


def test_a_prestressed_six_bar_resting_on_the_ground_does_not_creep():
    """NTRT's issue 83: an unactuated six-bar on its face. Settled (steady state), then 10 s
    more: no node moves by more than 1e-9 m (friction holds exactly; no creep)."""
    from tensegrity.design.catalogue import octahedron

    robot = on_its_face(octahedron(stiffness=2000.0, tension=100.0, damping=20.0))
    scene = dict(
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.8, kinetic_friction=0.6),
        contact_radius=RADIUS,
    )
    settled, run = settle_and_hold(robot, scene, 200.0)
    assert settled.status == 1, settled.message  # (at rest)
    assert np.sort(settled.node_position[-1, :, 2])[3] > 0.1  # (on three nodes: a face)
    assert run.status == 0 and run.nswitches == 0, run.message
    assert np.abs(run.node_position - run.node_position[0]).max() <= 1e-9


def test_a_stick_that_just_failed_slips_on_instead_of_chattering():
    """The six-bar robot of the learning environments released on its face: a rod end whose
    sticking force leaves the static cone slips at a fraction of 1 um/s, speeding up; the force
    it would need at rest sits a hair inside the cone.  A slow slip that speeds up past
    ``SLOW_SLIP`` within ``SLOW_START`` slips on: the run passes that moment in a few hundred
    events (the rule for slow slips stuck it again, and it failed again 4e-13 s later,
    without end: 10^5 events, the run never reached 0.86 s)."""
    from tensegrity.design.catalogue import six_bar_robot

    robot = stand_on_face(six_bar_robot(damping=1.0), (0, 4, 8), contact_radius=RADIUS)
    run = simulate(
        robot,
        (0.0, 0.86),
        sample_dt=0.01,
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.8, kinetic_friction=0.6),
        contact_radius=RADIUS,
        max_steps=60_000,
    )
    assert run.status == 0, run.message
    assert run.contact_event_time.size < 1_000
    assert run.contact_counts["slip"] > 10


def test_a_streamed_run_with_contact_resumes_bit_for_bit(tmp_path):
    """A rod sliding to a stop, streamed in segments: interrupted after the first (its pairs
    slipping), resumed, it ends as the run that was not interrupted (the checkpoint keeps the
    contacts' modes and slip directions)."""
    from tensegrity.io.stream import simulate_to_file
    from tensegrity.io.trajectory import read_trajectory

    structure = Structure.from_dict(
        {**resting_rod(0.0).to_dict(), "velocities": [[1.0, 0.2, 0.0], [1.0, 0.2, 0.0]]}
    )
    options = dict(
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.4, stiffness=STIFFNESS, damping=DAMPING),
        contact_radius=RADIUS,
        sample_dt=0.01,
        segment=0.1,
    )

    def interrupt(info):
        if info.segment == 1:
            raise KeyboardInterrupt

    whole = simulate_to_file(structure, (0.0, 0.5), tmp_path / "whole.h5", **options)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(
            structure, (0.0, 0.5), tmp_path / "resumed.h5", progress=interrupt, **options
        )
    resumed = simulate_to_file(structure, (0.0, 0.5), tmp_path / "resumed.h5", **options)
    assert resumed.resumed_from == 1 and whole.status == resumed.status == 0
    a, b = read_trajectory(whole.path), read_trajectory(resumed.path)
    assert a.nswitches == b.nswitches > 0
    contact = [name for name in vars(a) if name.startswith("contact_")]
    for name in ("t", "q", "qdot", "switch_times", *contact):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.contact_counts["stick"] == 2  # (both ends stop, after the interruption)
    assert read_trajectory(whole.path).settings["ground"][0]["friction"] == 0.4


def test_the_simulate_command_stands_a_robot_on_the_ground(tmp_path, capsys):
    """``tensegrity simulate --ground Z``: a six-bar dropped on its nodes' lowest level comes to
    rest on the plane (none of its ends below it by more than its radius), the file's settings
    hold the plane, and the summary counts the events."""
    from tensegrity.cli.main import main
    from tensegrity.io.trajectory import read_trajectory

    out = tmp_path / "out"
    argv = ["simulate", "--kind", "six-bar", "--set", "stiffness=2000", "--set", "tension=100"]
    argv += ["--gravity", "9.81", "--ground", "-0.5", "--friction", "0.8,0.6"]
    argv += ["--contact-radius", "0.01", "--t-end", "2", "--no-view", "--no-animation"]
    assert main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "events (slack/taut switches, contacts) located" in printed
    counts = read_trajectory(out / "trajectory.h5").contact_counts
    assert re.search(rf"contact events +{counts['touch_down']} touch-downs, ", printed)
    run = read_trajectory(out / "trajectory.h5")
    assert run.status == 1  # (at rest)
    assert run.settings["ground"] == [ground(-0.5, friction=0.8, kinetic_friction=0.6).settings()]
    lowest = run.node_position[-1, :, 2].min()
    assert -0.5 < lowest < -0.49  # (resting on the plane, within the ends' radius)


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--ground-normal", "0,0,0"], "--ground-normal: must not be zero"),
        (["--friction", "-1"], "--friction: must be a finite number >= 0"),
        (["--friction", "0.3,0.5"], "--friction: must not exceed friction"),
        (["--contact-stiffness", "0"], "--contact-stiffness: must be a finite number > 0"),
        (["--contact-radius", "-1"], "--contact-radius: must be >= 0"),
        (["--method", "rk4", "--dt", "1e-4"], r"ground \(--ground\): contact needs"),
    ],
)
def test_a_bad_ground_option_is_one_line_naming_it(tmp_path, capsys, argv, words):
    from tensegrity.cli.main import main

    code = main(["simulate", "--ground", "-1", *argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1
    assert re.search(words, err), err


def test_a_six_bar_with_a_payload_rests_on_the_ground_and_a_jointed_structure_is_refused():
    """Point masses held by cables (the six-bar's payload) take part; joints and supports, whose
    forces a sticking end would share, are refused naming ``ground``."""
    from tensegrity.design.catalogue import six_bar_robot
    from tensegrity.model.shell import class2_shell

    robot = six_bar_robot(stiffness=2000.0, tension=100.0, damping=20.0, payload_mass=0.5)
    nodes = robot.node_position.copy()
    nodes[:, 2] += RADIUS - nodes[:, 2].min()
    run = simulate(
        robot.replace(node_position=nodes),
        (0.0, 3.0),
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.8),
        contact_radius=RADIUS,
        sample_dt=0.1,
    )
    assert run.status == 0, run.message
    assert np.ptp(run.total_energy) < 1e-7
    assert run.node_position[-1, :12, 2].min() > 0.0  # (resting on its ends)
    with pytest.raises(ValueError, match=r"^ground: contact is for structures without joints"):
        simulate(class2_shell(3, 2), (0.0, 0.1), ground=ground(-10.0))


def test_a_rod_dropped_on_one_end_on_a_slope_does_not_spin_or_walk():
    """NTRT's issue 12: a rod dropped on one end onto a slope (gravity tilted by 0.3 rad, mu
    0.8 above the friction angle) topples and comes to rest.  Dropped in the vertical plane of
    the slope it stays in that plane (no spin: every y within the issue's 1e-9 m; measured
    1.1e-12 m, round-off of the sticking solve), and once at rest it stays there: no node moves
    more than 1e-9 m in 10 s more (no walk)."""
    low = RADIUS + 0.01
    rod = one_rod([[0.0, 0.0, low], [math.sqrt(0.5), 0.0, low + math.sqrt(0.5)]])
    scene = dict(
        gravity=tilted_gravity(0.3),
        ground=ground(stiffness=STIFFNESS, damping=DAMPING, friction=0.8),
        contact_radius=RADIUS,
    )
    fall, rest = settle_and_hold(rod, scene, 5.0)
    assert fall.status == 1, fall.message  # (at rest)
    assert np.abs(fall.node_position[:, :, 1]).max() <= 1e-9
    assert fall.contact_counts["touch_down"] >= 2  # (both ends came down)
    assert np.all(fall.contact_mode[-1] == 2)  # (lying, both ends stuck)
    assert rest.status == 0 and rest.nswitches == 0, rest.message
    assert np.abs(rest.node_position - rest.node_position[0]).max() <= 1e-9


def test_a_bad_trial_stage_in_a_sticking_solve_is_rejected_not_fatal():
    """A trial stage whose state is not finite (a step too long) reaches a rod's sticking solve:
    it must give NaN, which the step's error control rejects, not stop the run (the rolling
    example's robot standing on its face at rtol 1e-11 stopped at 0.099 s with "Array must not
    contain infs or NaNs" from the eigen-solve)."""
    from pathlib import Path

    from tensegrity.io.formats import read_scene, read_structure

    example = Path(__file__).resolve().parents[1] / "examples" / "six_bar_roll.json"
    scene = read_scene(example).simulate_options()
    run = simulate(read_structure(example), (0.0, 0.3), rtol=1e-11, sample_dt=0.01, **scene)
    assert run.status == 0, run.message
