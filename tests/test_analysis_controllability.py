"""Controllability and observability with named inputs and outputs (step 3)."""

from __future__ import annotations

import control
import numpy as np
import pytest

from tensegrity import artificial_damping, class1_shell
from tensegrity.analysis.controllability import (
    controllability,
    controllability_table,
    krylov_rank,
    observability,
    resolve_inputs,
    resolve_outputs,
)
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import RIGID, modal_analysis
from tensegrity.analysis.prestress import self_stress

SETS = ["all", "t1_*", "t1_1_1", "t1_1_1,t5_2_1"]


@pytest.fixture(scope="module")
def shell():
    return class1_shell(3, 1)


@pytest.fixture(scope="module")
def equilibrium(shell):
    return find_equilibrium(shell)


@pytest.fixture(scope="module")
def undamped(shell, equilibrium):
    lin = linearize(shell, equilibrium)
    return lin, modal_analysis(lin)


def test_names_resolve(undamped):
    lin, _ = undamped
    assert resolve_inputs(lin, "t1_*") == ("t1_1_1", "t1_2_1", "t1_3_1")
    assert len(resolve_inputs(lin, "all")) == 24
    assert resolve_outputs(lin, "p0_*") == ("p0_x", "p0_y", "p0_z")
    assert len(resolve_outputs(lin, "tension")) == 24
    with pytest.raises(KeyError):
        resolve_inputs(lin, "nope*")


@pytest.mark.parametrize("inputs", SETS)
def test_pbh_per_mode_equals_the_direct_rank_test(undamped, inputs):
    """Each cluster's verdict (rank of V^T B) against rank [A - i omega I, B] by SVD."""
    lin, modes = undamped
    result = controllability(lin, modes, inputs)
    cols = lin.input_indices(result.signals)
    n = lin.A.shape[0]
    for test in result.mode_tests:
        lam = 1j * np.sqrt(max(modes.omega_squared[test.modes[0]], 0.0))
        sv = np.linalg.svd(np.hstack([lin.A - lam * np.eye(n), lin.B[:, cols]]), compute_uv=False)
        deficit = int(np.sum(sv < 1e-9 * sv[0]))
        assert deficit == test.deficit, (inputs, test)


@pytest.mark.parametrize("inputs", SETS)
def test_rank_agrees_with_the_staircase_algorithm(undamped, inputs):
    """Rank from the modes (2 x modes reached) against the orthogonal staircase on the full A."""
    lin, modes = undamped
    result = controllability(lin, modes, inputs)
    cols = lin.input_indices(result.signals)
    root = np.sqrt(lin.mass)
    w = np.sqrt(np.max(modes.omega_squared))
    T = np.concatenate([w * root, root])
    staircase = krylov_rank((T[:, None] * lin.A) / T[None, :], T[:, None] * lin.B[:, cols])
    assert result.rank == staircase
    assert result.rank == result.elastic_rank  # tendons cannot move the structure as a whole


def test_staircase_agrees_with_kalman_rank_on_a_small_system():
    rng = np.random.default_rng(0)
    A = np.diag([-1.0, -2.0, -3.0, -4.0, -5.0])
    B = np.array([[1.0], [1.0], [0.0], [1.0], [0.0]])
    T = rng.normal(size=(5, 5))
    A, B = T @ A @ np.linalg.inv(T), T @ B
    assert krylov_rank(A, B) == np.linalg.matrix_rank(control.ctrb(A, B)) == 3


def test_paper_example_facts(undamped, shell, equilibrium):
    """(3,1) shell: every tendon set misses exactly one mode, the prestress-stiffened mechanism
    (3.24 Hz) -- it stretches no tendon to first order, so no rest-length change can drive it,
    and tendon lengths and tensions cannot see it; node positions see everything."""
    lin, modes = undamped
    ctrl, obs = controllability_table(lin, modes)
    mechanism = self_stress(shell, equilibrium.q).mechanisms  # (5R, 1)
    for r in ctrl:
        assert r.n_states == 60 and r.elastic_states == 48
        rigid = next(t for t in r.mode_tests if t.kind == RIGID)
        assert rigid.rank == 0  # internal forces cannot move the whole
    full_sets = [r for r in ctrl if r.name != "t1_1_1"]
    for r in full_sets:
        assert r.missed_modes() == [9] and r.rank == 46
    v = modes.shapes[:, 9]
    cos = abs(v @ mechanism[:, 0]) / np.linalg.norm(v) / np.linalg.norm(mechanism[:, 0])
    assert cos > 1 - 1e-9
    assert modes.frequency_hz[9] == pytest.approx(3.2356, abs=1e-3)
    by_name = {r.name: r for r in obs}
    assert (
        by_name["position"].rank == 60
        and by_name["position"].missed_modes(include_rigid=True) == []
    )
    assert by_name["length"].missed_modes() == [9] and by_name["tension"].missed_modes() == [9]
    # one input cannot reach more than one mode of each repeated frequency
    single = {r.name: r for r in ctrl}["t1_1_1"]
    assert all(t.rank <= 1 for t in single.mode_tests)
    assert single.rank == 18


def test_gramians_need_damping_and_solve_the_lyapunov_equation(shell, equilibrium, undamped):
    lin, modes = undamped
    assert controllability(lin, modes, "all").gramian_eigenvalues is None
    damped = linearize(artificial_damping(shell), equilibrium)
    dmodes = modal_analysis(damped)
    result = controllability(damped, dmodes, "all")
    g = result.gramian_eigenvalues
    assert g is not None and g.size == 48
    # one uncontrollable mode = two zero eigenvalues; the others clearly positive
    assert np.sum(g < 1e-9 * g.max()) == 2
    assert np.sort(g)[2] > 1e-6 * g.max()
    obs = observability(damped, dmodes, "position")
    assert obs.gramian_eigenvalues.min() > 0


def test_gramian_equals_the_time_integral(shell, equilibrium):
    """The Lyapunov-solver Gramian of the non-rigid part against the integral
    W = int_0^inf e^{At} B B^T e^{A^T t} dt of the *full* damped linearization (60 states, rigid
    modes included: tendons never excite them), computed independently by Van Loan's matrix
    exponential over dt = 5 ms (small enough for expm to be accurate to ~1e-12) and doubling
    (W <- W + Phi W Phi^T, Phi <- Phi^2) to 0.005 x 2^18 s, then expressed in the non-rigid
    coordinates eta = Z^T M x."""
    import scipy.linalg

    from tensegrity.analysis.coordinates import mass_complement

    lin = linearize(artificial_damping(shell), equilibrium)
    result = controllability(lin, modal_analysis(lin), "t1_*")
    B = lin.B[:, lin.input_indices(result.signals)]
    n, dt = lin.A.shape[0], 0.005
    block = scipy.linalg.expm(np.block([[-lin.A, B @ B.T], [np.zeros((n, n)), lin.A.T]]) * dt)
    phi = block[n:, n:].T
    W = phi @ block[:n, n:]
    for _ in range(18):
        W, phi = W + phi @ W @ phi.T, phi @ phi
    Z = mass_complement(lin.rigid_basis, lin.mass)
    # converged: every non-rigid motion has died out (rigid positions never do)
    assert np.max(np.abs(phi @ np.kron(np.eye(2), Z))) < 1e-9
    P = np.kron(np.eye(2), Z.T * lin.mass)  # [x, x'] -> [eta, eta']
    expected = np.linalg.eigvalsh(0.5 * (P @ W @ P.T + (P @ W @ P.T).T))
    got = np.sort(result.gramian_eigenvalues)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * expected.max())
