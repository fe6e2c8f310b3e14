"""What a run with planes reports (``SimulationResult.contact_*``, the file's contact datasets,
the summary), checked against the contact law and closed forms computed here, and the resting
contact of a bouncing rod against a one-dimensional reference integrated by SciPy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from tensegrity import simulate
from tensegrity.model.ground import FREE, SLIP, STICK, ground
from tensegrity.model.structure import Structure
from tensegrity.physics.contact import REVERSAL_SPEED
from test_contact import (
    DAMPING,
    MASS,
    RADIUS,
    STIFFNESS,
    G,
    lying_rod,
    on_its_face,
    resting_rod,
)


def oscillator(mass: float) -> tuple[float, float]:
    """``beta = c / 2m`` [1/s] and ``omega = sqrt(k/m - beta^2)`` [rad/s] of a point of ``mass``
    on the law of :data:`STIFFNESS`, :data:`DAMPING`."""
    beta = DAMPING / (2 * mass)
    return beta, math.sqrt(STIFFNESS / mass - beta * beta)


def test_a_bounce_reports_the_laws_force_its_modes_events_and_peak_penetration():
    """No gravity, each end a point of half the rod's mass hitting at 1 m/s: at every sample the
    reported normal force is ``k delta + c delta'`` of the sampled motion (0 when free), the
    mode is stick (no tangential motion) while in contact, the events are the touch-down at 0
    and the lift-off at the law's closed-form time, and the sampled penetration peaks at the
    closed form ``v / omega exp(-beta t*) sin(omega t*)``, ``tan(omega t*) = omega / beta``."""
    speed, dt = 1.0, 1e-5
    beta, omega = oscillator(MASS / 2)
    run = simulate(
        lying_rod(z=0.0, velocity=(0.0, 0.0, -speed)),
        (0.0, 0.01),
        ground=ground(stiffness=STIFFNESS, damping=DAMPING),
        rtol=1e-11,
        atol=1e-13,
        sample_dt=dt,
    )
    assert run.status == 0, run.message
    assert run.contact_normal_force.shape == run.contact_mode.shape == (run.t.size, 2)
    assert list(run.contact_node) == [0, 1] and list(run.contact_plane) == [0, 0]
    delta = run.contact_penetration
    assert np.array_equal(delta, -run.node_position[:, :, 2])  # (radius 0, the plane z = 0)
    rate = -run.node_velocity[:, :, 2]
    touching = run.contact_mode != FREE
    law = STIFFNESS * delta + DAMPING * rate
    assert np.abs(run.contact_normal_force - np.where(touching, law, 0.0)).max() < 1e-9
    assert set(np.unique(run.contact_mode)) == {FREE, STICK}
    assert np.abs(run.contact_friction_force).max() < 1e-12
    lift_off = (math.pi - math.atan2(2 * beta * omega, omega**2 - beta**2)) / omega
    assert run.contact_event_pair.tolist() == [0, 1, 0, 1]
    assert run.contact_event_mode.tolist() == [[FREE, STICK]] * 2 + [[STICK, FREE]] * 2
    assert run.contact_event_time[:2] == pytest.approx([0.0, 0.0], abs=1e-12)
    assert run.contact_event_time[2:] == pytest.approx([lift_off] * 2, rel=1e-9)
    assert run.contact_counts == {"touch_down": 2, "lift_off": 2, "slip": 0, "stick": 0}
    assert np.all(touching == ((run.t > 0) & (run.t < lift_off))[:, None])
    peak_time = math.atan2(omega, beta) / omega
    peak = speed / omega * math.exp(-beta * peak_time) * math.sin(omega * peak_time)
    largest_acceleration = STIFFNESS * peak / (MASS / 2)
    assert abs(delta.max() - peak) <= largest_acceleration * dt**2 / 2


def test_a_sliding_rod_reports_kinetic_friction_then_its_stick():
    """From 1 m/s along x and 0.5 m/s along y on flat ground: while it slips, each end's friction
    force is ``-mu_k F_n`` along its velocity and ``F_n`` is its share of the weight; it
    sticks at the closed-form stop time ``v / (mu_k g)`` and then needs no friction."""
    mu, velocity = 0.4, np.array([1.0, 0.5, 0.0])
    structure = Structure.from_dict(
        {**resting_rod(0.0).to_dict(), "velocities": [velocity.tolist()] * 2}
    )
    run = simulate(
        structure,
        (0.0, 1.0),
        gravity=[0.0, 0.0, -G],
        ground=ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu),
        contact_radius=RADIUS,
        sample_dt=0.01,
        rtol=1e-11,
        atol=1e-13,
    )
    assert run.status == 0, run.message
    stop = np.linalg.norm(velocity) / (mu * G)
    assert run.contact_event_mode.tolist() == [[FREE, SLIP]] * 2 + [[SLIP, STICK]] * 2
    # located where the velocity has turned back to REVERSAL_SPEED
    stick = stop + REVERSAL_SPEED / (mu * G)
    assert run.contact_event_time[2:] == pytest.approx([stick] * 2, abs=1e-10)
    slipping = run.t < stop - 1e-6
    assert np.all(run.contact_mode[slipping] == SLIP)
    assert np.all(run.contact_mode[run.t > stop + 1e-6] == STICK)
    assert np.abs(run.contact_normal_force - MASS * G / 2).max() < 1e-6
    v = run.node_velocity[slipping]
    direction = v / np.linalg.norm(v, axis=2, keepdims=True)
    expected = -mu * run.contact_normal_force[slipping][:, :, None] * direction
    assert np.abs(run.contact_friction_force[slipping] - expected).max() < 1e-9
    assert np.abs(run.contact_friction_force[run.t > stop + 1e-6]).max() < 1e-9
    assert run.contact_counts == {"touch_down": 2, "lift_off": 0, "slip": 0, "stick": 2}


def test_the_contact_outputs_survive_the_file_both_ways(tmp_path):
    """Written from memory (``write_trajectory``) and streamed (``simulate_to_file``), a run
    with planes reads back with the same contact arrays, types and events."""
    from tensegrity.io.stream import simulate_to_file
    from tensegrity.io.trajectory import read_trajectory, write_trajectory

    options = dict(
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.3),
        sample_dt=1e-3,
        rtol=1e-10,
        atol=1e-12,
    )
    structure = lying_rod(z=0.01, velocity=(0.5, 0.0, -1.0))
    run = simulate(structure, (0.0, 0.2), **options)
    write_trajectory(tmp_path / "memory.h5", run)
    streamed = simulate_to_file(structure, (0.0, 0.2), tmp_path / "stream.h5", **options)
    names = [name for name in vars(run) if name.startswith("contact_")]
    assert len(names) == 6 and run.contact_counts["lift_off"] > 0
    for path in (tmp_path / "memory.h5", streamed.path):
        back = read_trajectory(path)
        for name in names:
            a, b = getattr(run, name), getattr(back, name)
            assert a.dtype == b.dtype and np.array_equal(a, b), (path.name, name)
    sparse = read_trajectory(streamed.path, every=7)
    assert sparse.contact_mode.shape == (sparse.t.size, 2)
    assert np.array_equal(sparse.contact_event_time, run.contact_event_time)


def reference_bounces(height: float, mass: float, t_end: float) -> tuple[list[float], list[float]]:
    """Touch-down and lift-off times [s] of a point of ``mass`` [kg] dropped from ``height``
    [m] (its penetration ``delta = -height`` at rest) onto the law ``F = k delta + c delta'``
    under gravity :data:`G`, integrated by SciPy's RK45 phase by phase, by the rule the engine
    states: in contact until ``F`` falls to 0; free until ``min(k delta, k delta + c delta')``
    rises above 0 (so that a lift-off whose force would grow again at once ends in resting
    contact)."""
    k, c = STIFFNESS, DAMPING

    def free(t, y):
        return [y[1], G]

    def contact(t, y):
        return [y[1], G - (k * y[0] + c * y[1]) / mass]

    def lands(t, y):
        return min(k * y[0], k * y[0] + c * y[1])

    def leaves(t, y):
        return k * y[0] + c * y[1]

    lands.terminal, lands.direction = True, 1.0
    leaves.terminal, leaves.direction = True, -1.0
    touch, lift, t, y, touching = [], [], 0.0, np.array([-height, 0.0]), False
    while t < t_end:
        phase = solve_ivp(
            contact if touching else free,
            (t, t_end),
            y,
            events=leaves if touching else lands,
            rtol=1e-12,
            atol=1e-15,
            max_step=1e-3,
        )
        if phase.status != 1:
            break
        t, y = float(phase.t_events[0][0]), phase.y_events[0][0]
        (lift if touching else touch).append(t)
        touching = not touching
    return touch, lift


def test_a_bouncing_rod_settles_into_resting_contact_in_finitely_many_events():
    """The Zeno case: a rod dropped flat from 2 cm bounces ever lower; each bounce keeps a
    constant share of its speed, so without a rule for resting contact the bounces would
    accumulate.  The law's own rule ends them: once a bounce's exit speed is below ``c g / k``
    the force rises again at lift-off and the point stays in contact.  The engine's touch-downs
    and lift-offs (both ends at once) are the one-dimensional reference's (mass m/2), to 1e-7
    s, their count is finite, and the rod ends at rest in contact."""
    height = 0.02
    run = simulate(
        lying_rod(z=height),
        (0.0, 1.0),
        gravity=[0.0, 0.0, -G],
        ground=ground(stiffness=STIFFNESS, damping=DAMPING),
        rtol=1e-11,
        atol=1e-13,
        sample_dt=0.01,
    )
    assert run.status == 0, run.message
    touch, lift = reference_bounces(height, MASS / 2, 1.0)
    assert 3 <= len(lift) < 40 and len(touch) == len(lift) + 1
    before, after = run.contact_event_mode.T
    ends = run.contact_event_pair
    for end in (0, 1):
        mine = ends == end
        assert run.contact_event_time[mine & (before == FREE)] == pytest.approx(touch, abs=1e-7)
        assert run.contact_event_time[mine & (after == FREE)] == pytest.approx(lift, abs=1e-7)
    assert run.contact_counts["lift_off"] == 2 * len(lift)
    assert np.all(run.contact_mode[-1] != FREE)
    assert run.contact_normal_force[-1] == pytest.approx([MASS * G / 2] * 2, rel=1e-6)
    assert np.abs(run.node_velocity[-1]).max() < 1e-6


def test_a_rod_pulled_at_one_end_pivots_about_the_other_at_the_closed_form_rate():
    """A rod lying flat on the ground, pulled at end b by a horizontal force with parts
    ``F_perp`` across it and ``F_ax`` along it (ramped in over 1 ms).  End b cannot hold
    ``F > mu_s N`` and slips from rest; end a holds, so b can only move across the rod (its
    rigidity), with kinetic friction against that: b accelerates at ``3 (F_perp - mu_k N) / m``
    (rotation about a, ``I = m L^2 / 3``, ``N = m g / 2``; over 10 ms the rod turns by 2e-4
    rad, which changes ``F_perp`` by 2e-4 of it), a stays put, and the slip needs two events,
    not a chatter of them."""
    mu, across, along = 0.5, 4.0, 1.5
    normal = MASS * G / 2

    def pull(t):
        force = np.zeros((2, 3))
        force[1, :2] = np.array([along, across]) * min(t / 1e-3, 1.0)
        return force

    run = simulate(
        resting_rod(0.0),
        (0.0, 0.01),
        gravity=[0.0, 0.0, -G],
        ground=ground(stiffness=STIFFNESS, damping=DAMPING, friction=mu),
        contact_radius=RADIUS,
        external_force=pull,
        sample_dt=5e-4,
        rtol=1e-11,
        atol=1e-13,
    )
    assert run.status == 0, run.message
    assert run.contact_counts == {"touch_down": 2, "lift_off": 0, "slip": 1, "stick": 0}
    start = float(run.contact_event_time[-1])  # (end b's slip)
    assert run.contact_event_pair[-1] == 1 and 0.0 < start < 1e-3
    assert np.abs(run.node_position[:, 0] - run.node_position[0, 0]).max() < 1e-9
    later = run.t >= 2e-3
    acceleration = 3 * (across - mu * normal) / MASS
    y = run.node_position[later, 1, 1]
    curvature = np.polyfit(run.t[later], y, 2)[0] * 2
    assert curvature == pytest.approx(acceleration, rel=1e-3)
    assert run.contact_friction_force[later, 1, 1] == pytest.approx(-mu * normal, rel=1e-6)


def test_a_soft_six_bar_collapsing_on_the_ground_runs_to_its_end():
    """A six-bar too soft to stand (k = 100 N/m, 5 N of prestress, 6 kg) collapses on its face:
    rods come to lie with both ends on the ground and their ends crawl as the rods rock.  The
    rules for slips from rest and for slow slips let the run finish (it stalled at max_steps
    with thousands of events in 0.6 s before them); energy never grows beyond the run's
    tolerance and it comes to rest.  (At the default rtol the energy's largest growth is
    integration error, 1e-7 to 1.5e-6 J, spread by the chaotic collapse: the same structure
    turned about z gives any value in that range; at rtol 1e-11, 8e-9 to 3e-8 J.)"""
    from tensegrity.design.catalogue import six_bar_robot

    run = simulate(
        on_its_face(six_bar_robot(stiffness=100.0, tension=5.0)),
        (0.0, 2.0),
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.8, kinetic_friction=0.6),
        contact_radius=RADIUS,
        sample_dt=0.01,
        max_steps=100_000,
        rtol=1e-11,
    )
    assert run.status == 0, run.message
    assert run.nswitches < 1_000 and run.contact_counts["slip"] > 10
    total = run.total_energy
    assert (total - np.minimum.accumulate(total)).max() < 1e-7
    assert np.abs(run.node_velocity[-1]).max() < 1e-6


def point_mass_above(height: float, velocity=(0.0, 0.0, 0.0)) -> Structure:
    """A point mass of :data:`MASS` at ``height`` [m] moving at ``velocity``, tied by a slack
    tendon to an anchor 2 m above it (a structure needs a member)."""
    return Structure(
        node_position=[[0.0, 0.0, height], [0.0, 0.0, height + 2.0]],
        node_velocity=[velocity, (0.0, 0.0, 0.0)],
        node_point_mass=[MASS, 0.0],
        node_fixed=[False, True],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        tendon_nodes=[[0, 1]],
        tendon_stiffness=[10.0],
        tendon_rest_length=[5.0],
    )


def test_a_point_mass_is_a_contact_point_too():
    """A point mass hitting the ground at 1 m/s, no gravity, rebounds at the law's restitution
    for its mass; on a slope tilted below its friction angle it sticks, above it it slides at
    ``g (sin theta - mu_k cos theta)`` (the closed forms of tests/test_contact.py's rod)."""
    from test_contact import tilted_gravity

    plane = ground(stiffness=STIFFNESS, damping=DAMPING, friction=0.5)
    bounce = simulate(
        point_mass_above(0.0, (0.0, 0.0, -1.0)), (0.0, 0.05), ground=plane, rtol=1e-11, atol=1e-13
    )
    assert bounce.status == 0, bounce.message
    assert list(bounce.contact_node) == [0]
    assert bounce.node_velocity[-1, 0, 2] == pytest.approx(plane.restitution(MASS), rel=1e-8)
    assert bounce.contact_counts == {"touch_down": 1, "lift_off": 1, "slip": 0, "stick": 0}
    for theta, moves in ((0.4, False), (0.6, True)):  # (atan 0.5 = 0.4636 rad)
        depth = MASS * G * math.cos(theta) / STIFFNESS
        run = simulate(
            point_mass_above(RADIUS - depth),
            (0.0, 1.0),
            gravity=tilted_gravity(theta),
            ground=plane,
            contact_radius=RADIUS,
            sample_dt=0.1,
            rtol=1e-11,
            atol=1e-13,
        )
        assert run.status == 0, run.message
        x = run.node_position[:, 0, 0]
        if moves:
            expected = G * (math.sin(theta) - 0.5 * math.cos(theta)) / 2
            assert x[-1] - x[0] == pytest.approx(expected, rel=1e-3)
        else:
            assert np.abs(run.node_position[:, 0] - run.node_position[0, 0]).max() <= 1e-9
            assert np.all(run.contact_mode[1:] == STICK)
