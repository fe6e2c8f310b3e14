"""The dynamic check (tensegrity.design.dynamic): a load applied suddenly to a statically
determinate structure overshoots its static response as a single degree of freedom does: the
tendon force ``k x + c x'`` (the recorded tension includes the damper's) over the static one is
``1 - exp(-zeta w t) (cos w_d t - zeta / sqrt(1 - zeta^2) sin w_d t)``, whose peak is 2 undamped
and a little less with damping (``1 + exp(-pi zeta / sqrt(1 - zeta^2))`` for the displacement)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tensegrity.design.dynamic import dynamic_check
from tensegrity.design.materials import material
from tensegrity.design.sizing import LoadCase, size_members
from tensegrity.model.structure import Structure

F = 1000.0  # [N]


def _pendulum(min_area: float) -> tuple:
    """A steel rod pinned at its tail (a fixed node), its tip held by one tendon to an anchor
    at right angles, pulled away from the anchor by F: statically determinate, T = F, C = 0.
    For small motions one degree of freedom: the tip's, of effective mass m/3 (I / L^2 of a
    rod about its end) on the tendon's stiffness E A / L.  Sized with ``min_area`` [m^2]."""
    s = Structure(
        node_position=np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0]]),
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        tendon_nodes=[[1, 2]],
        tendon_stiffness=[1.0],
        tendon_rest_length=[1.0],
        node_fixed=[True, False, True],
    )
    force = np.zeros((3, 3))
    force[1] = [0, -F, 0]
    case = LoadCase("pull", force)
    steel = material("steel")
    sizing = size_members(
        s, rod_material=steel, tendon_material=steel, load_cases=[case], min_area=min_area
    )
    return sizing, case


@pytest.fixture(scope="module")
def pendulum():
    """The pendulum with a heavy rod (min_area 1e-4 m^2): its tendon far below yield."""
    return _pendulum(1e-4)


@pytest.mark.parametrize("zeta", [0.0, 0.02, 0.1])
def test_sudden_load_overshoots_by_the_sdof_factor(pendulum, zeta):
    sizing, case = pendulum
    s = sizing.structure
    static = sizing.utilisation.tendon[0, 0]
    assert sizing.tendon_tension[0, 0] == pytest.approx(F, rel=1e-9)
    k, m = s.tendon_stiffness[0], s.rod_mass[0] / 3
    period = 2 * math.pi / math.sqrt(k / m)
    # the tendon's damping is zeta of 2 sqrt(k mu), mu = m_rod / 2 (its end's share): the tip's
    # damping ratio is zeta sqrt(3/2)
    ratio = zeta * math.sqrt(3 / 2)
    w = 2 * math.pi / period
    wd, t = w * math.sqrt(1 - ratio**2), np.linspace(0, 2 * period, 200_001)
    shape = np.cos(wd * t) - ratio / math.sqrt(1 - ratio**2) * np.sin(wd * t)
    force = 1 - np.exp(-ratio * w * t) * shape
    expected, when = float(force.max()), float(t[np.argmax(force)])
    if zeta == 0.02:  # close to the displacement's factor for light damping
        assert expected == pytest.approx(1 + math.exp(-math.pi * ratio), abs=2e-3)
    (run,) = dynamic_check(
        s, sizing.members, [case], damping_ratio=zeta, duration=2 * period, sample_dt=period / 400
    )
    assert run.name == "pull" and run.utilisation.t[-1] == pytest.approx(2 * period)
    peak = run.utilisation.tendon_peak[0] / static
    assert peak == pytest.approx(expected, abs=2e-3)
    # when: the first peak (undamped, every period after it too)
    assert ((run.utilisation.tendon_peak_time[0] - when) / period + 0.5) % 1 == pytest.approx(
        0.5, abs=0.01
    )
    assert not run.fails  # min_area keeps this tendon far below yield


def test_default_duration_covers_the_first_overshoot(pendulum):
    """Without duration and sample_dt: 5 longest periods of the modes, a twentieth of the
    shortest between samples; the overshoot is found to the sampling's 1 - cos(pi/20)."""
    sizing, case = pendulum
    s = sizing.structure
    period = 2 * math.pi / math.sqrt(s.tendon_stiffness[0] / (s.rod_mass[0] / 3))
    (run,) = dynamic_check(s, sizing.members, [case], damping_ratio=0.0)
    assert run.duration == pytest.approx(5 * period, rel=1e-6)
    assert run.sample_dt == pytest.approx(period / 20, rel=1e-6)
    peak = run.utilisation.tendon_peak[0] / sizing.utilisation.tendon[0, 0]
    assert 2 * (1 - (1 - math.cos(math.pi / 20))) - 1e-3 <= peak <= 2 + 1e-3


def test_a_member_sized_to_its_limit_fails_in_motion():
    """Sized with min_area small, the tendon's static utilisation is 1: applied suddenly it
    exceeds 1 (about 2), and the check says so.  (The rod, of the least area, C = 0 in the
    small-displacement statics, also buckles in motion: turned by the tip's swing it takes a
    part of the fixed-direction load along its axis.)"""
    sizing, case = _pendulum(1e-6)
    assert sizing.utilisation.tendon[0, 0] == pytest.approx(1.0, rel=1e-9)
    (run,) = dynamic_check(sizing.structure, sizing.members, [case])
    assert run.fails and 1.8 < run.utilisation.tendon_peak[0] <= 2.0 + 1e-3
    assert run.utilisation.failures(sizing.structure)[0].startswith("tendon 's0': utilisation")
