"""Prestress and form-finding (step 4)."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import class1_shell
from tensegrity.analysis.coordinates import deformation
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.prestress import (
    feasible_prestress,
    form_find,
    rest_lengths_for_tensions,
    self_stress,
)


@pytest.fixture(scope="module", params=[(3, 1), (4, 2)], ids=["shell31", "shell42"])
def case(request):
    s = class1_shell(*request.param)
    eq = find_equilibrium(s)
    assert eq.converged
    return s, eq


def test_self_stress_and_maxwell_rule(case):
    """The equilibrium tensions span the (one-dimensional) self-stress space, and
    s - m = S - (5R - 6) (Maxwell's rule for rigid rods in 3-D)."""
    s, eq = case
    ss = self_stress(s, eq.q)
    assert ss.n_states == 1
    assert ss.n_states - ss.n_mechanisms == s.n_tendons - (5 * s.n_rods - 6)
    assert np.max(np.abs(ss.matrix @ eq.tension)) < 1e-10 * eq.tension.max()
    direction = ss.states[:, 0] * np.sign(ss.states[:, 0].sum())
    np.testing.assert_allclose(direction, eq.tension / np.linalg.norm(eq.tension), atol=1e-10)


def test_linear_program_finds_the_all_taut_prestress(case):
    s, eq = case
    mean = float(eq.tension.mean())
    ps = feasible_prestress(s, eq.q, mean_tension=mean)
    assert ps.feasible
    np.testing.assert_allclose(ps.tension, eq.tension, rtol=1e-9)
    assert ps.min_ratio == pytest.approx(eq.tension.min() / mean, rel=1e-9)
    assert ps.residual < 1e-9 * mean and np.all(ps.rod_compression > 0)


def test_no_prestress_at_the_rough_layout():
    """The cylinder layout is not an equilibrium of any all-taut tension set."""
    s = class1_shell(3, 1)
    ps = feasible_prestress(s)
    assert not ps.feasible and "no self-stress" in ps.message


def test_rest_lengths_realize_chosen_tensions(case):
    """Rest lengths for 1.5 x the tensions: the same geometry is an equilibrium of them (it does
    not move), with exactly those tensions."""
    s, eq = case
    rest, u = rest_lengths_for_tensions(s, eq.q, 1.5 * eq.tension)
    np.testing.assert_allclose(rest, eq.tendon_length - 1.5 * eq.tension / s.tendon_stiffness)
    again = find_equilibrium(s, eq.node_position, control=u, descend=False)
    assert again.converged
    assert deformation(again.node_position, eq.node_position, s.node_mass) < 1e-10
    np.testing.assert_allclose(again.tension, 1.5 * eq.tension, rtol=1e-9)


def test_unrealizable_tension_is_refused():
    s = class1_shell(3, 1)
    eq = find_equilibrium(s)
    with pytest.raises(ValueError, match="rest length"):
        rest_lengths_for_tensions(s, eq.q, 2.0 * eq.tension)  # needs Lbar < 0 at k = 100 N/m
    with pytest.raises(ValueError, match="< 0"):
        rest_lengths_for_tensions(s, eq.q, -eq.tension)


def test_form_finding_from_rough_geometry():
    """From a cylinder layout with every node moved by ~5 cm at random (rods projected back to
    their lengths) to a stable equilibrium with every tendon taut at a mean of 20 N."""
    s = class1_shell(3, 1)
    rough = s.node_position + np.random.default_rng(0).normal(
        scale=0.05, size=s.node_position.shape
    )
    result = form_find(s, rough, mean_tension=20.0)
    eq = result.equilibrium
    assert result.stable, result.verdict
    assert eq.converged and eq.residual_force < 1e-9 and not eq.slack.any()
    assert eq.tension.mean() == pytest.approx(20.0, rel=1e-9)
    assert feasible_prestress(result.structure, eq.q).feasible
