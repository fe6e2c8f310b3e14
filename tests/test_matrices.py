"""The matrix model (18.59) against the fast kernel, the node positions and the printed forms.

The matrices are built from the topology (``tensegrity.physics.matrix_form``); here they are checked

- against :func:`dynamics.accelerations` (q'' to 1e-10 relative, slack tendons included),
- against tendon vectors computed directly from node positions (q = Q l, l^d = R q),
- against finite-difference Jacobians (B = dq''/du, D = dq''/dw),
- against the printed blocks: Q (18.28-18.29), R (18.32-18.37, App. C), T (18.55-18.56, App. C),
  B^d/B^o (18.15, App. C, App. E), with the corrections listed in docs/matrix-model.md,
- and for the dimensions of Appendix D and the files written by ``write_matrices``.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.io
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from tensegrity.io.matrices import write_matrices
from tensegrity.model.shell import class1_shell, shell_node_index
from tensegrity.physics import dynamics
from tensegrity.physics.matrix_form import (
    ShellMatrixModel,
    control_names,
    shell_size,
    shell_topology,
)

#: (n, m, primal): the issue's sizes and their primal variants.
SIZES = [
    (3, 1, False),
    (4, 2, False),
    (5, 3, False),
    (8, 4, False),
    (4, 2, True),
    (5, 3, True),
    (8, 4, True),
]
SIZE_IDS = [f"{n}x{m}{'-primal' if p else ''}" for n, m, p in SIZES]


# ------------------------------------------------------------------------------ helpers
def randomized_shell(n, m, primal, rng, *, margin=0.0):
    """A shell with random rod masses and tendon stiffnesses, and a random rigid-rod state whose
    tendons are about half slack: rest lengths ``L0 = l (1 +- [margin, 0.5])`` of the lengths
    ``l`` at that state.  Returns ``(structure, q, qdot)``."""
    base = class1_shell(n, m, primal=primal)
    q = dynamics.initial_state(base).q.reshape(-1, 2, 3).copy()
    L = base.rod_length[:, None]
    q[:, 0] += rng.normal(scale=0.3, size=q[:, 0].shape)
    direction = q[:, 1] + rng.normal(scale=0.4, size=q[:, 1].shape)
    q[:, 1] = L * direction / np.linalg.norm(direction, axis=1, keepdims=True)
    q = q.reshape(-1)
    qdot = rng.normal(size=q.shape)
    lengths = dynamics.tendon_lengths(base, dynamics.nodes_from_coordinates(base, q))
    factor = rng.uniform(margin, 0.5, size=lengths.shape) * rng.choice(
        [-1.0, 1.0], size=lengths.shape
    )
    structure = base.replace(
        rod_mass=rng.uniform(0.5, 2.0, base.n_rods),
        tendon_stiffness=rng.uniform(50.0, 200.0, base.n_tendons),
        tendon_rest_length=lengths * (1.0 + factor),
    )
    return structure, q, qdot


def kernel_qddot(model, q, qdot, u, w):
    s = model.structure
    return dynamics.accelerations(
        s, q, qdot, control=model.control_to_structure(u), external_force=w.reshape(-1, 3)
    )


def tendon_vector_by_name(structure, q):
    p = dynamics.nodes_from_coordinates(structure, q)
    return p, dict(zip(structure.tendon_name, dynamics.tendon_vectors(structure, p), strict=True))


def block_pattern(matrix, row_sizes, col_sizes):
    """Boolean (rows, cols) pattern of the non-zero blocks of ``matrix``."""
    dense = matrix.toarray() if sp.issparse(matrix) else matrix
    r_edges = np.concatenate([[0], np.cumsum(row_sizes)])
    c_edges = np.concatenate([[0], np.cumsum(col_sizes)])
    return np.array(
        [
            [
                np.any(dense[r_edges[a] : r_edges[a + 1], c_edges[b] : c_edges[b + 1]] != 0)
                for b in range(len(col_sizes))
            ]
            for a in range(len(row_sizes))
        ]
    )


def kron3(blocks):
    return np.kron(np.array(blocks, dtype=float), np.eye(3))


def lower_pattern(first, diag, column, below, count):
    """[[first], [column, diag], [column, below, diag], ...] (the layout of 18.29 and of Q11)."""
    size = first.shape[0]
    out = np.zeros((count * size, count * size))
    for r in range(count):
        out[r * size : (r + 1) * size, r * size : (r + 1) * size] = first if r == 0 else diag
        if r >= 1:
            out[r * size : (r + 1) * size, :size] = column
        for c in range(1, r):
            out[r * size : (r + 1) * size, c * size : (c + 1) * size] = below
    return out


# ------------------------------------------------------------------------------ dimensions
@pytest.mark.parametrize("n, m, primal", SIZES, ids=SIZE_IDS)
def test_dimensions(n, m, primal):
    structure = class1_shell(n, m, primal=primal)
    model = ShellMatrixModel(structure)
    top = model.topology
    state = dynamics.initial_state(structure)
    mats = model.evaluate(state.q, state.qdot)
    nq, nd, no = 12 * n * m, 24 * n * m + 3, 6 * n * m
    nu = 8 * n * m if primal else n * (10 * m - 2)
    assert structure.n_tendons == nu
    assert top.n_controls == nu and len(top.u_names) == nu
    shapes = {
        "Q": (nq, nq),
        "Q_inv": (nq, nq),
        "R": (nd, nq),
        "R_o": (no, nq),
        "T": (10 * n * m + 1, nu),
        "W_o": (nq, nq),
        "B_d": (nq, nd),
        "B_o": (nq, no),
        "P": (nq, nq),
        "H": (nq, nq),
        "K_r": (nq, nq),
        "K_d": (nd, nq),
        "K_o": (no, nq),
        "P_d": (nd, 8 * n * m + 1),
        "P_o": (no, 2 * n * m),
        "K_tilde": (nq, nq),
        "B_tilde": (nq, 10 * n * m + 1),
        "K_p": (nq, nq),
        "B": (nq, nu),
        "D": (nq, nq),
        "C_t": (3 * nu, nq),
        "C_l": (nu, nq),
        "C_f": (nu, nq),
    }
    got = {**top.matrices(), **mats.matrices()}
    assert set(got) == set(shapes)
    for name, shape in shapes.items():
        assert got[name].shape == shape, name
        assert sp.isspmatrix_csr(got[name]), name
    assert len(top.l_labels) == 4 * n * m
    assert len(top.d_slots) == 8 * n * m + 1 and len(top.o_slots) == 2 * n * m
    # 10nm degrees of freedom (not the conclusion's 6nm): 12nm coordinates, 2nm length constraints
    assert structure.n_dof == 10 * n * m == nq - structure.n_rods


def test_appendix_d_dimensions_for_3_1():
    structure = class1_shell(3, 1)
    model = ShellMatrixModel(structure)
    top = model.topology
    state = dynamics.initial_state(structure)
    mats = model.evaluate(state.q, state.qdot)
    assert state.q.shape == (36,)
    assert top.Q.shape == (36, 36)  # Q = Q11
    assert top.R.shape == (75, 36)
    assert (top.B_d @ mats.P_d).shape == (36, 25)
    assert (top.B_o @ mats.P_o).shape == (36, 6)
    assert top.B_d.shape == (36, 75) and mats.K_d.shape == (75, 36)
    assert top.B_o.shape == (36, 18) and mats.K_o.shape == (18, 36)
    assert top.T.shape == (31, 24)
    assert mats.B.shape == (36, 24) and mats.D.shape == (36, 36) and mats.K_p.shape == (36, 36)


# ------------------------------------------------------------------------------ vs the kernel
@pytest.mark.parametrize("n, m, primal", SIZES, ids=SIZE_IDS)
def test_qddot_matches_the_fast_kernel(n, m, primal):
    rng = np.random.default_rng(1000 * n + 10 * m + primal)
    for trial in range(3):
        structure, q, qdot = randomized_shell(n, m, primal, rng)
        model = ShellMatrixModel(structure)
        L0 = model.control_from_structure(structure.tendon_rest_length)
        u = rng.uniform(-0.3, 0.3, size=L0.shape) * L0  # keeps L0 - u >= 0
        w = rng.normal(scale=5.0, size=12 * n * m)
        mats = model.evaluate(q, qdot, u)
        taut = mats.taut_d[1:].sum() + mats.taut_o.sum()
        assert (
            0.2 * structure.n_tendons
            < np.count_nonzero(
                dynamics.tendon_tensions(
                    structure,
                    dynamics.nodes_from_coordinates(structure, q),
                    control=model.control_to_structure(u),
                )
                == 0
            )
            < 0.8 * structure.n_tendons
        ), "want a mix of slack and taut tendons"
        assert taut > 0
        expected = kernel_qddot(model, q, qdot, u, w)
        got = mats.qddot(w)
        scale = np.abs(expected).max()
        assert np.abs(got - expected).max() <= 1e-10 * scale, (
            trial,
            np.abs(got - expected).max() / scale,
        )


def test_qddot_matches_the_kernel_with_every_tendon_taut_and_zero_control():
    structure = class1_shell(5, 3)  # default rest length: every tendon taut
    model = ShellMatrixModel(structure)
    state = dynamics.initial_state(structure)
    got = model.qddot(state.q, state.qdot)
    expected = dynamics.accelerations(structure, state.q, state.qdot)
    assert np.abs(got - expected).max() <= 1e-10 * np.abs(expected).max()
    assert model.evaluate(state.q, state.qdot).taut_o.all()


def test_kr_is_theorem_18_1_with_qdot_so_the_rod_constraint_holds():
    """q2 . q2'' = -|q2'|^2 (the rods keep their length) needs K = L^-2 q2'^T q2' I, not the
    printed L^-2 q2^T q2 I, which would give q2 . q2'' = -L^2."""
    rng = np.random.default_rng(7)
    structure, q, qdot = randomized_shell(4, 2, False, rng)
    model = ShellMatrixModel(structure)
    mats = model.evaluate(q, qdot)
    acc = mats.qddot(rng.normal(size=q.shape)).reshape(-1, 2, 3)
    q2, v2 = q.reshape(-1, 2, 3)[:, 1], qdot.reshape(-1, 2, 3)[:, 1]
    np.testing.assert_allclose(
        np.sum(q2 * acc[:, 1], axis=1), -np.sum(v2 * v2, axis=1), rtol=1e-9, atol=1e-9
    )
    diag = mats.K_r.diagonal().reshape(-1, 2, 3)
    np.testing.assert_allclose(
        diag[:, 1], (np.sum(v2 * v2, axis=1) / structure.rod_length**2)[:, None] * np.ones(3)
    )
    assert np.all(diag[:, 0] == 0)


# ------------------------------------------------------------------------------ Jacobians
@pytest.mark.parametrize(
    "n, m, primal", [(3, 1, False), (4, 2, False), (5, 3, True), (8, 4, False)]
)
def test_b_and_d_are_the_jacobians_of_qddot(n, m, primal):
    rng = np.random.default_rng(5 + n + m)
    structure, q, qdot = randomized_shell(n, m, primal, rng, margin=0.1)  # |l - L0| >= 0.1 l
    model = ShellMatrixModel(structure)
    L0 = model.control_from_structure(structure.tendon_rest_length)
    u = rng.uniform(-0.02, 0.02, size=L0.shape) * L0  # no tendon crosses slack <-> taut
    w = rng.normal(size=12 * n * m)
    mats = model.evaluate(q, qdot, u)
    h = 1e-3
    jac_u = np.empty(mats.B.shape)
    for k in range(u.size):
        du = np.zeros_like(u)
        du[k] = h
        jac_u[:, k] = (
            kernel_qddot(model, q, qdot, u + du, w) - kernel_qddot(model, q, qdot, u - du, w)
        ) / (2 * h)
    B = mats.B.toarray()
    assert np.abs(B).max() > 0
    assert np.abs(B - jac_u).max() <= 1e-8 * np.abs(B).max()
    jac_w = np.empty(mats.D.shape)
    for k in range(w.size):
        dw = np.zeros_like(w)
        dw[k] = 1.0
        jac_w[:, k] = (
            kernel_qddot(model, q, qdot, u, w + dw) - kernel_qddot(model, q, qdot, u, w - dw)
        ) / 2
    D = mats.D.toarray()
    assert np.abs(D - jac_w).max() <= 1e-9 * np.abs(D).max()
    # a slack tendon has no control authority: its column of B is zero
    slack = model.control_index[
        ~np.isin(
            model.control_index,
            np.flatnonzero(
                dynamics.tendon_tensions(
                    structure,
                    dynamics.nodes_from_coordinates(structure, q),
                    control=model.control_to_structure(u),
                )
                > 0
            ),
        )
    ]
    columns = [list(model.control_index).index(s) for s in slack]
    assert columns and np.all(B[:, columns] == 0)


# ------------------------------------------------------------------------------ Q, R and Q^-1
@pytest.mark.parametrize("n, m, primal", SIZES, ids=SIZE_IDS)
def test_q_inverse_is_the_inverse_and_equals_a_sparse_lu_solve(n, m, primal):
    top = shell_topology(n, m, primal)
    nq = 12 * n * m
    assert abs(top.Q @ top.Q_inv - sp.identity(nq)).max() <= 1e-12
    assert abs(top.Q_inv @ top.Q - sp.identity(nq)).max() <= 1e-12
    lu = splu(sp.csc_matrix(top.Q)).solve(np.eye(nq))
    assert np.abs(top.Q_inv.toarray() - lu).max() <= 1e-12


def test_q_inverse_is_block_bidiagonal_the_theta_powers_vanish():
    """Each l_ij depends on q_ij and one neighbour only, so Appendix B's Theta^k terms are zero."""
    n, m = 5, 4
    top = shell_topology(n, m)
    pattern = block_pattern(top.Q_inv, [12] * n * m, [12] * n * m)
    expected = np.eye(n * m, dtype=bool)
    for e in range(n * m):
        i, j = e % n + 1, e // n + 1
        if j == 1 and i > 1:
            expected[e, e - 1] = True  # t1_(i-1)1 from q_(i-1)1
        if j > 1:
            expected[e, e - n] = True  # t1_ij from q_i(j-1)
    np.testing.assert_array_equal(pattern, expected)


@pytest.mark.parametrize("n, m, primal", SIZES, ids=SIZE_IDS)
def test_q_l_and_r_q_reproduce_the_tendon_vectors_of_the_node_positions(n, m, primal):
    rng = np.random.default_rng(11)
    structure, q, _ = randomized_shell(n, m, primal, rng)
    top = shell_topology(n, m, primal)
    p, t = tendon_vector_by_name(structure, q)

    def node(k, i, j):
        return p[shell_node_index(k, i, j, n)]

    parts = []
    for label in top.l_labels:
        kind, i, j = label.split("_")
        i, j = int(i), int(j)
        parts.append(
            {
                "rho": lambda: node(1, 1, 1),
                "r1": lambda i=i, j=j: node(2, i, j) - node(1, i, j),
                "r2": lambda i=i, j=j: node(4, i, j) - node(3, i, j),
            }.get(kind, lambda label=label: t[label])()
        )
    l_vector = np.concatenate(parts)
    np.testing.assert_allclose(top.Q @ l_vector, q, atol=1e-12)
    np.testing.assert_allclose(top.Q_inv @ q, l_vector, atol=1e-12)

    def slot_vector(name):
        if name in t:
            return t[name]
        alpha, i, j = (int(x) for x in name[1:].split("_"))
        if alpha == 9 and j == 1:
            return -t[f"t1_{i}_1"]  # closure (18.2)
        if alpha == 10 and j == m:
            return -t[f"t7_{i}_{m}"]  # closure (18.7)
        assert primal  # a primal shell's t9/t10 slots: the geometry of (18.31)
        nxt = i % n + 1
        return node(1, nxt, j) - node(2, i, j) if alpha == 9 else node(4, nxt, j) - node(3, i, j)

    ld = np.concatenate([slot_vector(name) for name in top.d_slots])
    np.testing.assert_allclose(top.R @ q, ld, atol=1e-12)
    np.testing.assert_allclose(top.R @ (top.Q @ l_vector), ld, atol=1e-12)  # (18.38)
    lo = np.concatenate([t[name] for name in top.o_slots])
    np.testing.assert_allclose(top.R_o @ q, lo, atol=1e-12)
    np.testing.assert_allclose((top.P @ q).reshape(-1, 3), p, atol=1e-15)


# -- the printed Q blocks (18.28)
_A = [[2, 1, 0, 0], [0, 1, 0, 0], [2, 2, -1, 2], [0, 0, 1, 0]]
_B = [[-2, 1, 0, 0], [0, 1, 0, 0], [-2, 2, -1, 2], [0, 0, 1, 0]]
_C = [[-1, 0, 0, 2], [1, 0, 0, 0], [0, -1, 2, 2], [0, 1, 0, 0]]
_D = [[2, 2, 0, 0], [0, 0, 0, 0], [2, 2, 0, 0], [0, 0, 0, 0]]
_E = [[-2, 2, 0, 0], [0, 0, 0, 0], [-2, 2, 0, 0], [0, 0, 0, 0]]
_F = [[2, 2, 0, 2], [0, 0, 0, 0], [2, 2, 0, 2], [0, 0, 0, 0]]
_J = [[0, 0, 2, 2], [0, 0, 0, 0], [0, 0, 2, 2], [0, 0, 0, 0]]
_G_PRINTED = [[-2, 2, 0, 2], [0, 0, 0, 0], [2, 2, 0, 2], [0, 0, 0, 0]]
_G_CORRECTED = [[-2, 2, 0, 2], [0, 0, 0, 0], [-2, 2, 0, 2], [0, 0, 0, 0]]


def printed_q(n, m, G):
    Q11 = lower_pattern(kron3(_A), kron3(_B), kron3(_D), kron3(_E), n)
    if m == 1:
        return Q11
    Q21 = lower_pattern(kron3(_F), kron3(G), kron3(_D), kron3(_E), n)
    Q22 = np.kron(np.eye(n), kron3(_C))
    Q32 = np.kron(np.eye(n), kron3(_J))
    return lower_pattern(Q11, Q22, Q21, Q32, m)


@pytest.mark.parametrize("n, m", [(3, 1), (4, 2), (5, 3), (3, 4), (8, 4)])
def test_q_has_the_printed_blocks_with_g_corrected(n, m):
    Q = shell_topology(n, m).Q.toarray()
    np.testing.assert_array_equal(Q, printed_q(n, m, _G_CORRECTED))
    if m > 1:  # the printed G (third row +2I in its first column) is not the topology's
        assert np.abs(Q - printed_q(n, m, _G_PRINTED)).max() == 4.0


# -- the printed E blocks of R (18.32-18.36, Appendix C), rows t2 t3 t4 t6 t7 t8 t9 t10, x 1/2
def _rows(**rows):
    order = ("t2", "t3", "t4", "t6", "t7", "t8", "t9", "t10")
    return 0.5 * kron3([rows.get(name, [0, 0, 0, 0]) for name in order])


_E1 = _rows(t2=[0, 0, -1, -1])
_E2 = _rows(t3=[0, 0, 1, -1], t4=[0, 0, -1, 1])
_E3 = _rows(
    t2=[1, -1, 0, 0],
    t3=[-1, 1, 0, 0],
    t4=[1, 1, 0, 0],
    t6=[0, 0, -1, -1],
    t7=[0, 0, 1, -1],
    t8=[1, 1, -1, 1],
    t9=[-1, -1, 0, 0],
    t10=[0, 0, -1, 1],
)
_E4 = _rows(t9=[1, -1, 0, 0], t10=[0, 0, 1, 1])
_E4_HAT = _rows(t2=[-1, 1, 0, 0], t9=[1, -1, 0, 0], t10=[0, 0, 1, 1])
_E4_BAR = _rows(t6=[0, 0, 1, 1], t7=[0, 0, -1, -1], t9=[1, -1, 0, 0], t10=[0, 0, 1, 1])
_E4_TILDE = _rows(
    t2=[-1, 1, 0, 0], t6=[0, 0, 1, 1], t7=[0, 0, -1, -1], t9=[1, -1, 0, 0], t10=[0, 0, 1, 1]
)
_E5 = _rows(t6=[1, -1, 0, 0], t7=[-1, 1, 0, 0])
_E6 = 0.5 * kron3([[-1, 1, 0, 0]])
_E7 = 0.5 * kron3([[1, 1, 0, 0]])


def printed_r(n, m):
    def circulant(diag, nxt, prev):
        out = np.zeros((24 * n, 12 * n))
        for i in range(n):
            out[24 * i : 24 * i + 24, 12 * i : 12 * i + 12] += diag
            out[24 * i : 24 * i + 24, 12 * ((i + 1) % n) : 12 * ((i + 1) % n) + 12] += nxt
            out[24 * i : 24 * i + 24, 12 * ((i - 1) % n) : 12 * ((i - 1) % n) + 12] += prev
        return out

    R12 = circulant(np.zeros((24, 12)), _E5, np.zeros((24, 12)))
    R21 = np.kron(np.eye(n), _E1)
    R = np.zeros((24 * n * m + 3, 12 * n * m))
    R[0:3, 0:12] = _E6
    R[0:3, 12 * (n - 1) : 12 * n] = _E7
    for j in range(m):
        if m == 1:
            diag = circulant(_E3, _E4_TILDE, _E2)
        else:
            diag = circulant(_E3, _E4_HAT if j == 0 else _E4_BAR if j == m - 1 else _E4, _E2)
        rows = slice(3 + 24 * n * j, 3 + 24 * n * (j + 1))
        R[rows, 12 * n * j : 12 * n * (j + 1)] = diag
        if j + 1 < m:
            R[rows, 12 * n * (j + 1) : 12 * n * (j + 2)] = R12
        if j > 0:
            R[rows, 12 * n * (j - 1) : 12 * n * j] = R21
    return R


@pytest.mark.parametrize("n, m, primal", [*SIZES, (3, 2, False), (6, 5, False)])
def test_r_has_the_printed_block_structure(n, m, primal):
    np.testing.assert_array_equal(shell_topology(n, m, primal).R.toarray(), printed_r(n, m))


# ------------------------------------------------------------------------------ T and u
def printed_t(n, m, *, sign, first_row_u1n1):
    """T of (18.55)-(18.56) / Appendix C, with the printed ``-1`` replaced by ``sign``."""
    nu_d = 6 * n if m == 1 else 14 * n + 8 * n * (m - 2)
    T = np.zeros((10 * n * m + 1, nu_d + 2 * n * m))
    T1 = np.zeros((8, 7))
    T1[:6, :6] = np.eye(6)
    T1[7, 6] = 1
    T2 = np.zeros((8, 7))
    T2[:7, :7] = np.eye(7)
    T2[7, 4] = sign
    T1p = np.zeros((8, 6))  # T'_1 of Appendix C
    T1p[:6, :6] = np.eye(6)
    T1p[7, 4] = sign
    S = np.zeros((8, 2))
    S[6, 1] = sign
    if first_row_u1n1:
        T[0, nu_d + 2 * (n - 1) + 1] = 1
    for i in range(n):
        r = 1 + 8 * i
        if m == 1:
            T[r : r + 8, 6 * i : 6 * i + 6] = T1p
        else:
            T[r : r + 8, 7 * i : 7 * i + 7] = T1
        T[r : r + 8, nu_d + 2 * i : nu_d + 2 * i + 2] = S
        for j in range(2, m):
            r = 1 + 8 * ((j - 1) * n + i)
            c = 7 * n + 8 * n * (j - 2) + 8 * i
            T[r : r + 8, c : c + 8] = np.eye(8)
        if m > 1:
            r = 1 + 8 * ((m - 1) * n + i)
            c = 7 * n + 8 * n * (m - 2) + 7 * i
            T[r : r + 8, c : c + 7] = T2
    for e in range(n * m):
        T[1 + 8 * n * m + 2 * e : 3 + 8 * n * m + 2 * e, nu_d + 2 * e : nu_d + 2 * e + 2] = np.eye(
            2
        )
    return T


@pytest.mark.parametrize("n, m", [(3, 1), (4, 2), (5, 3), (3, 4)])
def test_t_has_the_printed_blocks_with_corrected_signs(n, m):
    T = shell_topology(n, m).T.toarray()
    np.testing.assert_array_equal(T, printed_t(n, m, sign=+1, first_row_u1n1=True))
    assert np.any(T != printed_t(n, m, sign=-1, first_row_u1n1=False))


def test_every_slot_carries_the_force_of_its_tendon_and_the_printed_t_signs_break_that():
    """f^d = -K^d q + P^d T u (18.47) gives each slot +-(its tendon's force): the closure copies
    t9_i1 = -t1_i1 and t10_im = -t7_im carry minus the force of t1_i1, t7_im.  With the printed
    T (u9_i1 = -u1_i1, u10_im = -u7_im) they would not."""
    rng = np.random.default_rng(3)
    n, m = 4, 2
    structure, q, qdot = randomized_shell(n, m, False, rng)
    model = ShellMatrixModel(structure)
    top = model.topology
    L0 = model.control_from_structure(structure.tendon_rest_length)
    u = rng.uniform(-0.3, 0.3, size=L0.shape) * L0
    mats = model.evaluate(q, qdot, u)
    fd = (-mats.K_d @ q + mats.P_d @ mats.utilde[: len(top.d_slots)]).reshape(-1, 3)
    fo = (-mats.K_o @ q + mats.P_o @ mats.utilde[len(top.d_slots) :]).reshape(-1, 3)
    p = dynamics.nodes_from_coordinates(structure, q)
    forces = dynamics.tendon_forces(
        structure,
        p,
        np.zeros_like(p),
        dynamics.rest_lengths(structure, model.control_to_structure(u)),
    )
    F = dict(zip(structure.tendon_name, forces.tension[:, None] * forces.direction, strict=True))
    scale = max(np.abs(v).max() for v in F.values())
    for slots, tendons, signs, f in (
        (top.d_slots, top.d_tendon, top.d_sign, fd),
        (top.o_slots, top.o_tendon, top.o_sign, fo),
    ):
        for name, tendon, sign, value in zip(slots, tendons, signs, f, strict=True):
            np.testing.assert_allclose(value, sign * F[tendon], atol=1e-12 * scale, err_msg=name)
    printed = printed_t(n, m, sign=-1, first_row_u1n1=False) @ u
    copies = [k for k, name in enumerate(top.d_slots) if top.d_sign[k] < 0]
    assert copies
    assert np.any(printed[copies] != mats.utilde[copies])


def test_control_names_follow_the_papers_order():
    names = control_names(3, 1)
    assert names[:6] == ("t2_1_1", "t3_1_1", "t4_1_1", "t6_1_1", "t7_1_1", "t8_1_1")
    assert names[18:] == ("t5_1_1", "t1_1_1", "t5_2_1", "t1_2_1", "t5_3_1", "t1_3_1")
    names = control_names(3, 3)
    assert names[:7] == (
        "t2_1_1",
        "t3_1_1",
        "t4_1_1",
        "t6_1_1",
        "t7_1_1",
        "t8_1_1",
        "t10_1_1",
    )  # 18.57
    assert names[21:29] == tuple(f"t{a}_1_2" for a in (2, 3, 4, 6, 7, 8, 9, 10))
    assert names[45:52] == tuple(f"t{a}_1_3" for a in (2, 3, 4, 6, 7, 8, 9))  # 18.58
    assert names[66:68] == ("t5_1_1", "t1_1_1")
    for n, m, primal in SIZES:
        structure = class1_shell(n, m, primal=primal)
        assert sorted(control_names(n, m, primal)) == sorted(structure.tendon_name)
        model = ShellMatrixModel(structure)
        u = np.arange(model.topology.n_controls, dtype=float)
        control = model.control_to_structure(u)
        assert [structure.tendon_name[s] for s in model.control_index] == list(
            control_names(n, m, primal)
        )
        np.testing.assert_array_equal(model.control_from_structure(control), u)
    assert control_names(4, 1, True) == control_names(4, 1, False)  # m = 1: primal = full


# ------------------------------------------------------------------------------ B^d, B^o
#: Nodal force balances as printed in Appendix E (18.E.1-18.E.4) and Appendix C: node k of
#: element (i, j) gets sum(coef * f_alpha of element (i + di, j + dj)) + w.  "base" row p2 uses
#: +f5 (printed once -f5, a typo); "base" p4 includes -f10_(i-1)1 (printed for 1 < i <= n, left
#: out for i = 1).
NODE_BALANCE = {
    "base": {  # j = 1 < m (18.E.1)
        1: [(+1, 1, -1, 0), (+1, 2, -1, 0), (-1, 2, 0, 0), (+1, 3, 0, 0)],
        2: [(-1, 1, 0, 0), (-1, 4, 0, 0), (+1, 5, 0, 0), (-1, 8, 0, 0)],
        3: [(+1, 8, 0, 0), (-1, 7, 0, 0), (+1, 10, 0, 0), (-1, 3, 1, 0), (+1, 4, 1, 0)],
        4: [(-1, 5, 0, 0), (+1, 6, 0, 0), (-1, 10, -1, 0), (+1, 1, 0, 1), (+1, 2, 0, 1)],
    },
    "middle": {  # 1 < j < m (18.E.2, 18.E.3)
        1: [(-1, 6, -1, -1), (+1, 7, -1, -1), (-1, 9, -1, 0), (-1, 2, 0, 0), (+1, 3, 0, 0)],
        2: [(-1, 1, 0, 0), (-1, 4, 0, 0), (+1, 5, 0, 0), (-1, 8, 0, 0), (+1, 9, 0, 0)],
        3: [(-1, 7, 0, 0), (+1, 8, 0, 0), (+1, 10, 0, 0), (-1, 3, 1, 0), (+1, 4, 1, 0)],
        4: [(-1, 5, 0, 0), (+1, 6, 0, 0), (-1, 10, -1, 0), (+1, 1, 0, 1), (+1, 2, 0, 1)],
    },
    "top": {  # j = m > 1 (18.E.4)
        1: [(-1, 6, -1, -1), (+1, 7, -1, -1), (-1, 9, -1, 0), (-1, 2, 0, 0), (+1, 3, 0, 0)],
        2: [(-1, 1, 0, 0), (-1, 4, 0, 0), (+1, 5, 0, 0), (-1, 8, 0, 0), (+1, 9, 0, 0)],
        3: [(-1, 7, 0, 0), (+1, 8, 0, 0), (-1, 3, 1, 0), (+1, 4, 1, 0)],
        4: [(-1, 5, 0, 0), (-1, 6, -1, 0), (+1, 6, 0, 0), (+1, 7, -1, 0)],
    },
    "single": {  # m = 1 (Appendix C)
        1: [(-1, 2, 0, 0), (+1, 3, 0, 0), (+1, 1, -1, 0), (+1, 2, -1, 0)],
        2: [(+1, 5, 0, 0), (-1, 1, 0, 0), (-1, 4, 0, 0), (-1, 8, 0, 0)],
        3: [(+1, 8, 0, 0), (-1, 7, 0, 0), (-1, 3, 1, 0), (+1, 4, 1, 0)],
        4: [(+1, 6, 0, 0), (-1, 5, 0, 0), (-1, 6, -1, 0), (+1, 7, -1, 0)],
    },
}


@pytest.mark.parametrize("n, m, primal", [*SIZES, (3, 2, False), (3, 3, True)])
def test_bd_bo_reproduce_the_printed_nodal_force_balances(n, m, primal):
    rng = np.random.default_rng(17)
    structure = class1_shell(n, m, primal=primal)
    top = shell_topology(n, m, primal)
    F = {name: rng.normal(size=3) for name in structure.tendon_name}
    fd = np.concatenate(
        [
            np.zeros(3) if t is None else s * F[t]
            for t, s in zip(top.d_tendon, top.d_sign, strict=True)
        ]
    )
    fo = np.concatenate([s * F[t] for t, s in zip(top.o_tendon, top.o_sign, strict=True)])
    w = rng.normal(size=12 * n * m)
    got = (top.B_d @ fd + top.B_o @ fo + top.W_o @ w).reshape(-1, 4, 3)
    W = np.array([[1, 1, 0, 0], [1, -1, 0, 0], [0, 0, 1, 1], [0, 0, 1, -1]])
    for j in range(1, m + 1):
        case = "single" if m == 1 else "base" if j == 1 else "top" if j == m else "middle"
        for i in range(1, n + 1):
            e = (j - 1) * n + (i - 1)
            nodal = w.reshape(-1, 4, 3)[e].copy()
            for k, terms in NODE_BALANCE[case].items():
                for coef, alpha, di, dj in terms:
                    name = f"t{alpha}_{(i + di - 1) % n + 1}_{j + dj}"
                    nodal[k - 1] += coef * F.get(name, np.zeros(3))  # primal: no t9, t10
            np.testing.assert_allclose(got[e], W @ nodal, atol=1e-12, err_msg=f"element ({i},{j})")


@pytest.mark.parametrize("n, m", [(3, 1), (4, 2), (5, 3), (6, 4)])
def test_bd_bo_have_the_printed_block_layout(n, m):
    """B^d = [[B3, B4, 0 ..], [B5, B6, B4 ..], [0, B5bar, B6 ..], .., [.., B5bar, B8]] with B3,
    B6, B8 tridiagonal-circulant over i plus B3's f1_n1 column (rows 1 and n), B4 = BlockDiag,
    B5 = [0, B5bar], B5bar sub-diagonal-circulant; B^o = [[B1, B2 ..], [0, B7, B2 ..], ..] with
    B1 lower bidiagonal without a corner, B2 and B7 BlockDiag (18.15, 18.E.17-18.E.21)."""
    top = shell_topology(n, m)
    elements = [(i, j) for j in range(1, m + 1) for i in range(1, n + 1)]
    col = {e: k for k, e in enumerate(elements)}
    expected_d = np.zeros((n * m, 1 + n * m), dtype=bool)
    expected_o = np.zeros((n * m, n * m), dtype=bool)
    for r, (i, j) in enumerate(elements):
        nxt, prv = i % n + 1, (i - 2) % n + 1
        for e in [(i, j), (nxt, j), (prv, j)] + [(prv, j - 1)] * (j > 1) + [(i, j + 1)] * (j < m):
            expected_d[r, 1 + col[e]] = True
        expected_o[r, col[(i, j)]] = True
        if j < m:
            expected_o[r, col[(i, j + 1)]] = True
        if j == 1 and i > 1:
            expected_o[r, col[(i - 1, 1)]] = True
    expected_d[col[(1, 1)], 0] = expected_d[col[(n, 1)], 0] = True
    np.testing.assert_array_equal(
        block_pattern(top.B_d, [12] * n * m, [3] + [24] * n * m), expected_d
    )
    np.testing.assert_array_equal(block_pattern(top.B_o, [12] * n * m, [6] * n * m), expected_o)


def _block(matrix, row_element, col_offset, width):
    dense = matrix.toarray()
    return dense[12 * row_element : 12 * row_element + 12, col_offset : col_offset + width]


def test_bd_bo_blocks_of_element_nm_are_those_printed_in_18_E_16():
    n, m = 5, 3
    top = shell_topology(n, m)

    def e(i, j):
        return (j - 1) * n + (i - 1)

    def d(i, j):
        return 3 + 24 * e(i, j)

    row = e(n, m)
    blocks = {
        d(n - 1, m - 1): [[0, 0, 0, -1, 1, 0, 0, 0], [0, 0, 0, -1, 1, 0, 0, 0], [0] * 8, [0] * 8],
        d(n - 1, m): [
            [0, 0, 0, 0, 0, 0, -1, 0],
            [0, 0, 0, 0, 0, 0, -1, 0],
            [0, 0, 0, -1, 1, 0, 0, 0],
            [0, 0, 0, 1, -1, 0, 0, 0],
        ],
        d(n, m): [
            [-1, 1, -1, 0, 0, -1, 1, 0],
            [-1, 1, 1, 0, 0, 1, -1, 0],
            [0, 0, 0, 1, -1, 1, 0, 0],
            [0, 0, 0, -1, -1, 1, 0, 0],
        ],
        d(1, m): [[0] * 8, [0] * 8, [0, -1, 1, 0, 0, 0, 0, 0], [0, -1, 1, 0, 0, 0, 0, 0]],
    }
    for offset, printed in blocks.items():
        np.testing.assert_array_equal(_block(top.B_d, row, offset, 24), kron3(printed))
    nonzero = {
        k
        for k in range(1 + n * m)
        if np.any(_block(top.B_d, row, 0 if k == 0 else 3 + 24 * (k - 1), 3 if k == 0 else 24))
    }
    assert nonzero == {1 + e(n - 1, m - 1), 1 + e(n - 1, m), 1 + e(n, m), 1 + e(1, m)}
    np.testing.assert_array_equal(
        _block(top.B_o, row, 6 * e(n, m), 6), kron3([[1, -1], [-1, 1], [-1, 0], [1, 0]])
    )


def test_bd_bo_blocks_of_element_n1_are_those_printed_in_appendix_c():
    n = 4
    top = shell_topology(n, 1)
    row = n - 1

    def d(i):
        return 3 + 24 * (i - 1)

    blocks = {
        d(n - 1): [
            [1, 0, 0, 0, 0, 0, 0, 0],
            [1, 0, 0, 0, 0, 0, 0, 0],
            [0, 0, 0, -1, 1, 0, 0, 0],
            [0, 0, 0, 1, -1, 0, 0, 0],
        ],
        d(n): [
            [-1, 1, -1, 0, 0, -1, 0, 0],
            [-1, 1, 1, 0, 0, 1, 0, 0],
            [0, 0, 0, 1, -1, 1, 0, 0],
            [0, 0, 0, -1, -1, 1, 0, 0],
        ],
        d(1): [[0] * 8, [0] * 8, [0, -1, 1, 0, 0, 0, 0, 0], [0, -1, 1, 0, 0, 0, 0, 0]],
    }
    for offset, printed in blocks.items():
        np.testing.assert_array_equal(_block(top.B_d, row, offset, 24), kron3(printed))
    np.testing.assert_array_equal(
        _block(top.B_d, row, 0, 3), kron3([[-1], [1], [0], [0]])
    )  # Bbar_1n1
    np.testing.assert_array_equal(_block(top.B_d, 0, 0, 3), kron3([[1], [1], [0], [0]]))  # B_1n1
    np.testing.assert_array_equal(
        _block(top.B_o, row, 6 * (n - 2), 6), kron3([[0, 1], [0, 1], [0, 0], [0, 0]])
    )  # B^o_01
    np.testing.assert_array_equal(
        _block(top.B_o, row, 6 * (n - 1), 6), kron3([[1, 0], [-1, 0], [-1, 0], [1, 0]])
    )  # B^o_n1


def test_h_kr_d_are_block_diagonal():
    rng = np.random.default_rng(2)
    structure, q, qdot = randomized_shell(4, 2, False, rng)
    mats = ShellMatrixModel(structure).evaluate(q, qdot)
    rods = structure.n_rods
    for name in ("H", "K_r"):
        pattern = block_pattern(getattr(mats, name), [6] * rods, [6] * rods)
        assert not np.any(pattern & ~np.eye(rods, dtype=bool)), name
    pattern = block_pattern(mats.D, [12] * (rods // 2), [12] * (rods // 2))
    np.testing.assert_array_equal(pattern, np.eye(rods // 2, dtype=bool))
    H = mats.H.toarray()
    q2 = q[3:6]
    np.testing.assert_allclose(H[:3, :3], 2 / structure.rod_mass[0] * np.eye(3))
    np.testing.assert_allclose(
        H[3:6, 3:6], 6 / structure.rod_mass[0] * (np.outer(q2, q2) - q2 @ q2 * np.eye(3))
    )


# ------------------------------------------------------------------------------ errors
def test_rejects_what_the_matrix_model_cannot_represent():
    with pytest.raises(ValueError, match="damping"):
        ShellMatrixModel(dynamics.artificial_damping(class1_shell(3, 1)))
    assert ShellMatrixModel(dynamics.undamped(dynamics.artificial_damping(class1_shell(3, 1))))
    shell = class1_shell(4, 2)
    with pytest.raises(ValueError, match="tendons"):
        ShellMatrixModel(shell.replace(tendon_name=tuple(f"s{k}" for k in range(shell.n_tendons))))
    keep = [k for k, name in enumerate(shell.tendon_name) if name != "t3_2_2"]
    with pytest.raises(ValueError, match="t3_2_2"):
        shell_size(
            shell.replace(
                tendon_nodes=shell.tendon_nodes[keep],
                tendon_stiffness=shell.tendon_stiffness[keep],
                tendon_rest_length=shell.tendon_rest_length[keep],
                tendon_damping=shell.tendon_damping[keep],
                tendon_name=tuple(shell.tendon_name[k] for k in keep),
            )
        )
    assert shell_size(shell) == (4, 2, False)
    assert shell_size(class1_shell(4, 2, primal=True)) == (4, 2, True)
    model = ShellMatrixModel(shell)
    state = dynamics.initial_state(shell)
    u = np.zeros(model.topology.n_controls)
    u[5] = shell.tendon_rest_length[0] + 0.1
    with pytest.raises(ValueError, match="negative"):
        model.evaluate(state.q, state.qdot, u)
    with pytest.raises(ValueError, match="u: expected shape"):
        model.evaluate(state.q, state.qdot, np.zeros(3))
    with pytest.raises(ValueError, match="q: expected shape"):
        model.evaluate(state.q[:-1], state.qdot)


def test_topology_matrices_are_cached_and_read_only():
    top = shell_topology(3, 2)
    assert shell_topology(3, 2, primal=False) is top and shell_topology(np.int64(3), 2) is top
    assert shell_topology(3, 1, primal=True) is shell_topology(3, 1)
    with pytest.raises(ValueError):
        top.Q.data[0] = 5.0


# ------------------------------------------------------------------------------ files
def test_write_matrices(tmp_path):
    structure = class1_shell(3, 1)
    state = dynamics.initial_state(structure)
    rng = np.random.default_rng(0)
    qdot = rng.normal(size=state.q.shape)
    u = np.full(24, 0.01)
    out = tmp_path / "m"
    rows = write_matrices(out, structure, state.q, qdot, u=u, at="initial")
    model = ShellMatrixModel(structure)
    mats = model.evaluate(state.q, qdot, u)
    expected = {**model.topology.matrices(), **mats.matrices()}
    assert [name for name, _, _ in rows] == list(expected)
    for name, shape, nnz in rows:
        matrix = expected[name]
        assert shape == matrix.shape and nnz == matrix.nnz
        assert abs(sp.load_npz(out / f"{name}.npz") - matrix).max() == 0 if matrix.nnz else True
        from_mtx = sp.csr_matrix(scipy.io.mmread(out / f"{name}.mtx"))
        assert from_mtx.shape == shape
        assert (
            abs(from_mtx - matrix).max() <= 1e-15 * max(abs(matrix).max(), 1.0)
            if nnz
            else from_mtx.nnz == 0
        )
    index = json.loads((out / "matrices.json").read_text())
    assert index["shell"] == {
        "n": 3,
        "m": 1,
        "primal": False,
        "nodes": 12,
        "rods": 6,
        "tendons": 24,
    }
    assert index["at"] == "initial"
    assert index["u_tendon"] == list(control_names(3, 1))
    np.testing.assert_array_equal(index["state"]["q"], state.q)
    np.testing.assert_array_equal(index["state"]["qdot"], qdot)
    np.testing.assert_allclose(index["state"]["node_position"], structure.node_position, atol=1e-15)
    assert index["state"]["u"] == u.tolist()
    assert {entry["name"]: tuple(entry["shape"]) for entry in index["matrices"]} == {
        name: shape for name, shape, _ in rows
    }
    saved = np.load(out / "state.npz")
    np.testing.assert_array_equal(saved["q"], state.q)
    np.testing.assert_allclose(saved["qddot"], mats.qddot(), rtol=0, atol=0)
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]
    assert len(list(out.iterdir())) == 2 * len(rows) + 2


def test_write_matrices_from_a_size_at_the_initial_state(tmp_path):
    rows = write_matrices(tmp_path, (4, 2, True))
    shapes = {name: shape for name, shape, _ in rows}
    assert shapes["B"] == (96, 64) and shapes["T"] == (81, 64)
    index = json.loads((tmp_path / "matrices.json").read_text())
    assert index["shell"]["primal"] is True and index["at"] is None
    np.testing.assert_allclose(
        index["state"]["q"], dynamics.initial_state(class1_shell(4, 2, primal=True)).q
    )


# ------------------------------------------------------------------------------ outputs (18.60)
@pytest.mark.parametrize("n, m, primal", SIZES[:5], ids=SIZE_IDS[:5])
def test_outputs_are_the_tendon_vectors_lengths_tensions_and_their_jacobians(n, m, primal):
    rng = np.random.default_rng(60 + n + m)
    structure, q, qdot = randomized_shell(n, m, primal, rng)
    model = ShellMatrixModel(structure)
    u = rng.uniform(-0.05, 0.05, model.topology.n_controls)
    mats = model.evaluate(q, qdot, u)
    control = model.control_to_structure(u)
    # Tendon vectors, lengths and tensions measured on the node positions, in u order.
    p = dynamics.nodes_from_coordinates(structure, q)
    vectors = dynamics.tendon_vectors(structure, p)[model.control_index]
    np.testing.assert_allclose((mats.C_t @ q).reshape(-1, 3), vectors, rtol=0, atol=1e-13)
    np.testing.assert_allclose(mats.y_l, np.linalg.norm(vectors, axis=1), rtol=1e-14)
    tension = dynamics.tendon_tensions(structure, p, control=control)[model.control_index]
    np.testing.assert_allclose(mats.y_f, tension, rtol=1e-13, atol=1e-12)
    assert 0 < np.sum(mats.y_f == 0) < len(mats.y_f), "want both slack and taut tendons"
    # C_l and C_f against central differences of the outputs.
    h = 1e-6
    fd_l = np.empty((len(mats.y_l), q.size))
    fd_f = np.empty_like(fd_l)
    for k in range(q.size):
        dq = np.zeros_like(q)
        dq[k] = h
        plus, minus = model.evaluate(q + dq, qdot, u), model.evaluate(q - dq, qdot, u)
        fd_l[:, k] = (plus.y_l - minus.y_l) / (2 * h)
        fd_f[:, k] = (plus.y_f - minus.y_f) / (2 * h)
    np.testing.assert_allclose(mats.C_l.toarray(), fd_l, rtol=0, atol=1e-8)
    np.testing.assert_allclose(
        mats.C_f.toarray(), fd_f, rtol=0, atol=1e-6 * structure.tendon_stiffness.max()
    )
