"""Linearization, natural frequencies, rigid-body modes, mechanisms and stability (step 2)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from tensegrity import artificial_damping, class1_shell
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.linearize import finite_difference_check, linearize
from tensegrity.analysis.modes import (
    ELASTIC,
    MECHANISM,
    RIGID,
    fft_peak,
    measure_frequency,
    modal_analysis,
    stability_by_simulation,
)
from tensegrity.analysis.prestress import self_stress


@pytest.fixture(scope="module")
def shell():
    return class1_shell(3, 1)


@pytest.fixture(scope="module")
def equilibrium(shell):
    eq = find_equilibrium(shell)
    assert eq.converged
    return eq


@pytest.fixture(scope="module")
def modes(shell, equilibrium):
    return modal_analysis(linearize(shell, equilibrium))


def test_linearization_is_the_derivative_of_the_simulated_dynamics(shell, equilibrium):
    """A, B (rest-length inputs), C and the feed-through against central differences of Theorem
    18.1's accelerations and the outputs (node positions, lengths, tensions), with damping."""
    lin = linearize(artificial_damping(shell), equilibrium)
    errors = finite_difference_check(lin)
    assert max(errors.values()) < 1e-7, errors


def test_linearization_with_control_about_a_controlled_equilibrium(shell, equilibrium):
    u = np.linspace(-0.03, 0.03, shell.n_tendons)
    eq = find_equilibrium(shell, equilibrium.node_position, control=u)
    errors = finite_difference_check(linearize(shell, eq))
    assert max(errors.values()) < 1e-7, errors


def test_linearization_under_external_forces_includes_the_disturbance_matrix(shell, equilibrium):
    """About an equilibrium loaded by self-balanced nodal forces (rod 0 pulled apart by 2 N per
    metre of its axis at each end), A, B and the nodal-force matrix D against central
    differences of Theorem 18.1 with the load perturbed."""
    w = np.zeros((shell.n_nodes, 3))
    a, b = shell.rod_nodes[0]
    axis = equilibrium.node_position[b] - equilibrium.node_position[a]
    w[a], w[b] = -2.0 * axis, 2.0 * axis
    eq = find_equilibrium(shell, equilibrium.node_position, external_force=w)
    assert eq.converged
    errors = finite_difference_check(linearize(artificial_damping(shell), eq))
    assert set(errors) == {"A", "B", "D", "C", "F"}
    assert max(errors.values()) < 1e-7, errors


def test_six_rigid_body_modes_and_the_full_spectrum(modes):
    """The closed-form rigid-body motions have zero stiffness; the generalized eigenvalues of
    (K, M) computed without separating them are the same 6 zeros plus the elastic spectrum."""
    lin = modes.linearization
    assert modes.n_rigid == 6 and modes.rigid_residual < 1e-12
    assert modes.kind[:6] == (RIGID,) * 6
    full = scipy.linalg.eigh(lin.stiffness, np.diag(lin.mass), eigvals_only=True)
    scale = full.max()
    assert np.all(np.abs(full[:6]) < 1e-9 * scale)
    np.testing.assert_allclose(full[6:], modes.omega_squared[6:], rtol=1e-9, atol=1e-9 * scale)
    # undamped A: eigenvalues +-i omega
    eig = np.linalg.eigvals(lin.A)
    omega = np.sort(np.abs(eig.imag[eig.imag > 1e-6]))
    np.testing.assert_allclose(omega, np.sort(np.sqrt(modes.omega_squared[6:])), rtol=1e-8)
    # mode shapes M-orthonormal
    V = modes.shapes
    np.testing.assert_allclose(V.T @ (lin.mass[:, None] * V), np.eye(V.shape[1]), atol=1e-9)


def test_paper_example_is_stable(modes):
    assert modes.stable and modes.n_mechanisms == 0 and modes.n_unstable == 0
    assert modes.verdict.startswith("stable")
    assert modes.frequency_hz[6] == pytest.approx(2.129, abs=0.001)


def test_fft_peak_finds_a_known_frequency():
    t = np.arange(0, 10, 0.01)
    assert fft_peak(t, np.sin(2 * np.pi * 3.3 * t + 0.4)) == pytest.approx(3.3, rel=1e-3)


def test_linear_frequency_matches_fft_of_undamped_nonlinear_simulation(modes):
    """The best-separated mode, excited by its shape with 1e-4 m amplitude, simulated without
    damping: the FFT peak of its modal coordinate within 1% of the linearization (measured
    about 5e-8)."""
    check = measure_frequency(modes, periods=20)
    assert modes.kind[check.mode] == ELASTIC
    others = np.delete(modes.frequency_hz[6:], check.mode - 6)
    assert np.min(np.abs(others - check.linear_hz)) > 0.05 * check.linear_hz  # well separated
    assert check.relative_error < 0.01


def test_perturbation_decays_with_damping_and_stays_bounded_without(modes):
    result = stability_by_simulation(modes)
    assert result.returns and result.bounded and result.stable
    assert result.damped_deformation[-1] <= 0.01 * result.initial_deformation
    assert result.undamped_deformation.max() <= result.bound
    assert result.verdict.startswith("stable")


def test_no_prestress_shows_its_mechanism(shell, equilibrium):
    """Rest lengths equal to the lengths: no prestress.  Tendons at zero tension keep their
    material stiffness, so what is left is the infinitesimal mechanism of the geometry -- one,
    as the null space of the equilibrium matrix says (Maxwell: 24 tendons, 24 non-rigid dof,
    1 self-stress) -- and the verdict says the equilibrium is not stable."""
    unstressed = shell.replace(
        node_position=equilibrium.node_position, tendon_rest_length=equilibrium.tendon_length
    )
    m = modal_analysis(linearize(unstressed, equilibrium.q))
    assert m.n_rigid == 6 and m.n_unstable == 0
    assert m.n_mechanisms == self_stress(unstressed, equilibrium.q).n_mechanisms == 1
    assert not m.stable and "mechanism" in m.verdict and m.verdict.startswith("not stable")
    # the mechanism stretches no tendon to first order
    mech = m.shapes[:, [i for i, k in enumerate(m.kind) if k == MECHANISM]]
    lin = m.linearization
    assert np.max(np.abs(lin.equilibrium_matrix.T @ mech)) < 1e-9


def test_slack_network_has_only_mechanisms_and_does_not_return(shell, equilibrium):
    slack = shell.replace(
        node_position=equilibrium.node_position, tendon_rest_length=1.2 * equilibrium.tendon_length
    )
    m = modal_analysis(linearize(slack, equilibrium.q))
    assert m.n_rigid == 6 and m.n_mechanisms == 24 and not m.stable
    assert "24 slack tendon(s)" in m.verdict
    mechanism = m.shapes[:, 6]
    result = stability_by_simulation(m, shape=mechanism, damped_time=1.0, undamped_time=1.0)
    assert not result.returns and not result.stable
    assert result.damped_deformation[-1] == pytest.approx(result.initial_deformation, rel=1e-6)


def test_saddle_equilibrium_is_unstable(shell):
    saddle = find_equilibrium(shell, descend=False)  # 3 slack tendons (see equilibrium tests)
    m = modal_analysis(linearize(shell, saddle))
    assert m.n_unstable > 0 and not m.stable and m.verdict.startswith("unstable")


def test_statespace_is_named(shell, equilibrium):
    lin = linearize(shell, equilibrium)
    sys = lin.statespace(["t1_1_1", "t5_2_1"], ["tension", "p0_x"])
    assert sys.ninputs == 2 and sys.noutputs == shell.n_tendons + 1 and sys.nstates == 60
    assert sys.input_labels == ["t1_1_1", "t5_2_1"]
    assert sys.output_labels[0] == "tension_t1_1_1" and sys.output_labels[-1] == "p0_x"
    # a rest-length step shows in the tension at once: T = k (l - L0 + u)
    assert sys.D[0, 0] == pytest.approx(shell.tendon_stiffness[0])


@pytest.mark.parametrize("size", [(3, 1), (6, 5)])
def test_reprs_are_short_summaries(size):
    """An equilibrium, its linearization and its modes print as one short line each (they
    printed their arrays: 3,000, 65,000 and 87,000 characters at (3,1); issue 27).  (6,5), not
    (10,10): its equilibrium takes minutes."""
    s = class1_shell(*size)
    eq = find_equilibrium(s)
    lin = linearize(s, eq)
    modes = modal_analysis(lin)
    for text in (repr(eq), repr(lin), repr(modes)):
        assert len(text) < 300 and "\n" not in text, text
    assert repr(eq).startswith("<EquilibriumResult: converged by least_squares (")
    assert f"{int(eq.slack.sum())} of {s.n_tendons} tendons slack" in repr(eq)
    assert repr(s) in repr(eq) and repr(s) in repr(lin)
    k = lin.n_dof
    assert f"{k} degrees of freedom, A ({2 * k}, {2 * k}), B ({2 * k}, {s.n_tendons})" in repr(lin)
    assert repr(modes).startswith(
        f"<ModalAnalysis: {k} modes (6 rigid, 0 mechanisms, {k - 6} elastic, 0 unstable), "
    )
    assert repr(modes).endswith(", stable (Definition 18.1)>")
