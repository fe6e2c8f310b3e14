"""The event mechanism (:mod:`tensegrity.engine.events`): one compiled locator for every adaptive
method, checked against closed-form event times and an independent root finder."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tensegrity import simulate
from tensegrity.engine import events
from tensegrity.model.structure import Structure

MASS, STIFFNESS, REST, GAP, SPEED = 0.3, 50.0, 1.0, 0.6, 2.0


def mass_on_a_slack_tether() -> Structure:
    """A point mass [kg] tied to a fixed anchor by a tendon slack by ``REST - GAP`` [m], moving
    straight away from the anchor at ``SPEED`` [m/s], no gravity: the tendon goes taut at
    ``(REST - GAP) / SPEED``, pulls the mass back as a linear spring (``k`` = ``STIFFNESS``)
    for half a period ``pi sqrt(m / k)``, and goes slack again with the speed reversed."""
    return Structure(
        node_position=[[0.0, 0.0, 0.0], [GAP, 0.0, 0.0]],
        node_velocity=[[0.0, 0.0, 0.0], [SPEED, 0.0, 0.0]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_fixed=[True, False],
        node_point_mass=[0.0, MASS],
        tendon_nodes=[[0, 1]],
        tendon_stiffness=[STIFFNESS],
        tendon_rest_length=[REST],
    )


TAUT_AT = (REST - GAP) / SPEED
SLACK_AT = TAUT_AT + math.pi * math.sqrt(MASS / STIFFNESS)


@pytest.mark.parametrize("method", ["DOP853", "RK45", "Radau", "BDF", "LSODA"])
def test_every_adaptive_method_locates_the_closed_form_switches(method):
    run = simulate(
        mass_on_a_slack_tether(), (0.0, 0.5), method=method, rtol=1e-10, atol=1e-12, sample_dt=0.01
    )
    assert run.status == 0, run.message
    assert len(run.switch_times) == 2, run.switch_times
    taut, slack = run.switch_times
    # Before the first switch the motion is uniform: every dense output is exact there.
    assert taut == pytest.approx(TAUT_AT, rel=1e-12, abs=0)
    # The second is as accurate as the integration of the spring's half period.
    assert slack == pytest.approx(SLACK_AT, rel=1e-7, abs=0)
    # After it the mass leaves at the speed it came with (the tendon stores no energy).
    assert run.qdot[-1][-3] == pytest.approx(-SPEED, rel=1e-7)


def test_a_run_without_location_finds_no_switches():
    run = simulate(mass_on_a_slack_tether(), (0.0, 0.5), method="RK45", locate_switches=False)
    assert run.status == 0 and len(run.switch_times) == 0


@pytest.mark.parametrize(
    ("g", "lo", "hi"),
    [
        (lambda t: math.cos(t) - t, 0.0, 1.0),
        (lambda t: 1e-3 - t**3, 0.0, 1.0),  # flat near the root: the bisections keep it going
        (lambda t: min(1.0 - t, 0.5 * (1.0 - t)) + 1e-9, 0.0, 3.0),  # a kink at the root
    ],
)
def test_the_bracket_closes_on_the_root_an_independent_solver_finds(g, lo, hi):
    tol = 1e-13
    bracket = events.bracket_start(lo, hi, g(lo), g(hi), tol)
    t = events.bracket_next(bracket, math.nan, math.nan)
    evaluations = 0
    while not math.isnan(t):
        evaluations += 1
        t = events.bracket_next(bracket, t, g(t))
    root = brentq(g, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    assert bracket[events.LO] <= root <= bracket[events.HI] + 1e-15
    assert bracket[events.HI] - bracket[events.LO] <= tol
    assert g(bracket[events.LO]) > 0 >= g(bracket[events.HI])
    assert evaluations < 200
