"""The linear response to a load increment about an equilibrium (analysis.stiffness) against
finite differences of the nonlinear equilibrium, and its errors."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.stiffness import compliance, tangent_stiffness
from tensegrity.design.catalogue import prism
from tensegrity.physics import dynamics


def standing_prism():
    """The 3-bar prism on its base (bottom nodes fixed), loaded down and sideways on its top."""
    s = prism(3)
    fixed = np.arange(6) < 3
    load = np.zeros((6, 3))
    load[3:] = [2.0, 1.0, -10.0]
    return s.replace(node_fixed=fixed), load


def test_displacement_is_the_derivative_of_the_loaded_equilibrium():
    """``du(dw)`` about the loaded equilibrium equals the central difference of the equilibria
    under ``w -+ eps dw`` (an increment in another direction than the load)."""
    s, w = standing_prism()
    eq = find_equilibrium(s, external_force=w)
    assert eq.converged
    dw = np.zeros((6, 3))
    dw[4] = [0.5, -1.0, 0.3]
    dw[5] = [0.0, 0.4, -0.8]
    eps = 1e-3
    ends = [
        find_equilibrium(s, start=eq.node_position, external_force=w + sign * eps * dw)
        for sign in (-1, 1)
    ]
    central = (ends[1].node_position - ends[0].node_position) / (2 * eps)
    du = tangent_stiffness(s, eq).displacement(dw)
    assert du.shape == (6, 3)
    assert np.all(du[:3] == 0)  # the fixed nodes
    np.testing.assert_allclose(du, central, atol=1e-6 * np.max(np.abs(central)))


def test_compliance_of_a_balanced_load_on_a_free_structure():
    """A free prism pulled apart at two nodes of different rods: the rigid-body motions do no
    work, and ``e . du`` is the central difference of the nodes' separation (which no rigid
    motion or gauge changes)."""
    s = prism(3)
    a, b = 0, 4
    p = s.node_position
    axis = (p[b] - p[a]) / np.linalg.norm(p[b] - p[a])
    e = np.zeros((6, 3))
    e[a], e[b] = -axis, axis
    eq = find_equilibrium(s)
    eps = 1e-3
    gap = []
    for sign in (-1, 1):
        end = find_equilibrium(s, start=eq.node_position, external_force=sign * eps * e)
        gap.append(np.linalg.norm(end.node_position[b] - end.node_position[a]))
    c = compliance(s, eq, e)
    assert c > 0
    assert c == pytest.approx((gap[1] - gap[0]) / (2 * eps), rel=1e-5)


def test_errors_name_the_argument():
    s, w = standing_prism()
    eq = find_equilibrium(s, external_force=w)
    ts = tangent_stiffness(s, eq)
    with pytest.raises(ValueError, match=r"^load: expected finite nodal forces of shape \(6, 3\)"):
        ts.displacement(np.zeros((5, 3)))
    with pytest.raises(ValueError, match=r"^load_pattern: expected finite"):
        ts.compliance(np.full((6, 3), np.nan))
    free = prism(3)
    unbalanced = np.zeros((6, 3))
    unbalanced[3:, 2] = -1.0
    with pytest.raises(ValueError, match=r"^load_pattern: not balanced: it does work on a rigid"):
        compliance(free, None, unbalanced)
    with pytest.raises(ValueError, match=r"^load: not balanced"):
        tangent_stiffness(free).displacement(unbalanced)


def test_an_equilibrium_without_prestress_has_no_response():
    """Tendons just taut, no prestress: the prism's infinitesimal mechanism is unstiffened."""
    s = prism(3)
    lengths = dynamics.tendon_lengths(s, s.node_position)
    bare = s.replace(tendon_rest_length=lengths, node_fixed=np.arange(6) < 3)
    e = np.zeros((6, 3))
    e[3:, 2] = -1.0
    with pytest.raises(ValueError, match=r"^equilibrium: no unique response .*mechanism"):
        compliance(bare, None, e)
