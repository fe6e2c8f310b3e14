"""The explicit matrix model of the class 1 shell (Skelton, Pinaud, Mingori, §18.4-18.5, App. B-E)::

    q'' + (K_r(q') + K_p(q)) q = B(q) u + D(q) w                                   (18.59)

    K_p = H K~,   K~ = B^d K^d + B^o K^o,   B = H [B^d P^d, B^o P^o] T,   D = H W^o

Every matrix is built from the shell's topology (:func:`tensegrity.model.shell.shell_tendons`, i.e.
the table of ``shared/spec/shell-topology.md``), never typed in from the printed blocks, and is a
``scipy.sparse.csr_matrix`` in the paper's orderings.  ``tests/test_matrices.py`` checks the
blocks against the printed forms and the accelerations against :func:`dynamics.accelerations`.
``docs/matrix-model.md`` describes the model and every place where the printed equations are
inconsistent (and what this module does there).

Orderings (``e = (j-1) n + (i-1)`` is the element index, elements stacked ``(1,1) .. (n,1),
(1,2) .. (n,m)``; every entry of a "vector" ordering below is a 3-vector):

- ``q`` (12nm): per element ``[q1, q2, q3, q4] = [p1+p2, p2-p1, p3+p4, p4-p3]`` (18.24).
- ``w`` (12nm): per element the external forces on ``[p1, p2, p3, p4]`` (18.16), i.e. node order.
- ``f`` (12nm): per element ``[f1+f2, f1-f2, f3+f4, f3-f4]`` of the nodal forces (18.20).
- ``l`` (12nm): the independent vectors (18.28): ``[rho_11, r1, r2, t5]`` for (1,1),
  ``[t1_(i-1)1, r1, r2, t5]`` for (i,1), ``[r1, r2, t5, t1]`` for j > 1.
- ``l^d``, ``f^d`` (24nm+3): ``t1_n1``, then per element ``t2 t3 t4 t6 t7 t8 t9 t10`` (18.37).
- ``f^o`` (6nm): per element ``[t5, t1]`` (18.16).
- ``u~`` (10nm+1, scalars): one per slot of ``f^d`` then of ``f^o`` (18.54).
- ``u`` (n(10m-2) scalars, 8nm for the primal shell): per element the tendons of ``f^d`` that
  exist (``t9`` left out at j = 1, ``t10`` at j = m), then per element ``[u5, u1]`` (18.57-18.58,
  Appendix C); :attr:`ShellTopology.u_names` names the tendon of each entry.

A "slot" of ``l^d``/``f^d``/``f^o`` is a tendon vector the paper carries; ``t9_i1`` and
``t10_im`` are closure copies (``t9_i1 = -t1_i1``, ``t10_im = -t7_im``) and ``t1_n1`` appears in
both ``f^d`` and ``f^o``: such a copy holds the force of its tendon (with the vector's sign) but its
column of ``B^d``/``B^o`` is zero, so that each tendon acts once (as in Appendices C and E).

The state-dependent matrices are evaluated without Python loops over elements
(:meth:`ShellMatrixModel.evaluate`); the topology matrices are built once per ``(n, m, primal)``
and cached (read-only).  The matrix model is undamped, like the paper's.
"""

from __future__ import annotations

import dataclasses
import functools
import re
from collections import deque
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from tensegrity.model.shell import shell_node_index, shell_tendons
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

#: Tendons of ``f^d_ij`` / ``l^d`` slots, in the paper's order (18.16, 18.31).
D_ALPHAS = (2, 3, 4, 6, 7, 8, 9, 10)
#: Tendons of ``f^o_ij``, in the paper's order (18.16).
O_ALPHAS = (5, 1)

_TENDON_NAME = re.compile(r"t(\d+)_(\d+)_(\d+)")
_I3 = sp.identity(3, format="csr")

#: W of Appendices C/E: per element ``[f1+f2, f1-f2, f3+f4, f3-f4] = W [f1, f2, f3, f4]``.
_W_ELEMENT = np.array([[1, 1, 0, 0], [1, -1, 0, 0], [0, 0, 1, 1], [0, 0, 1, -1]], dtype=float)


# ============================================================================ topology
@dataclasses.dataclass(frozen=True, eq=False)
class ShellTopology:
    """The constant matrices of an ``(n, m)`` shell, in the paper's orderings (read-only CSR).

    Attributes
    ----------
    Q : (12nm, 12nm)
        ``q = Q l`` (18.28).
    Q_inv : (12nm, 12nm)
        ``l = Q^-1 q``, computed with the block formulas of Appendix B.
    R : (24nm+3, 12nm)
        ``l^d = R q`` (18.37): the vectors of the ``f^d`` slots.
    R_o : (6nm, 12nm)
        ``[t5; t1]`` of every element ``= R_o q``: the rows of ``Q^-1`` for ``t5_ij`` and
        ``t1_ij`` (the paper's choice below 18.42), and ``R_0`` (the ``t1_n1`` row of ``R``) for
        ``t1_n1``, which is not in ``l``.
    T : (10nm+1, n(10m-2)) or (10nm+1, 8nm) primal
        ``u~ = T u`` (18.55): every slot gets the rest-length change of its tendon.
    W_o : (12nm, 12nm)
        ``BlockDiag[W]`` (18.15): ``f = W^o f_nodes``.
    B_d : (12nm, 24nm+3), B_o : (12nm, 6nm)
        ``f = B^d f^d + B^o f^o + W^o w`` (18.15, Appendix E).
    P : (12nm, 12nm)
        ``p = P q`` (18.26), node positions in node order.
    """

    n: int
    m: int
    primal: bool
    Q: sp.csr_matrix
    Q_inv: sp.csr_matrix
    R: sp.csr_matrix
    R_o: sp.csr_matrix
    T: sp.csr_matrix
    W_o: sp.csr_matrix
    B_d: sp.csr_matrix
    B_o: sp.csr_matrix
    P: sp.csr_matrix
    #: label of each 3-vector of ``l``: ``rho_1_1``, ``r1_i_j``, ``r2_i_j``, ``t5_i_j``, ``t1_i_j``
    l_labels: tuple[str, ...]
    #: slot label of each 3-vector of ``l^d`` / ``f^d`` (``t1_n_1``, then ``t{alpha}_i_j``)
    d_slots: tuple[str, ...]
    #: tendon whose force a ``f^d`` slot carries (``None``: no tendon, primal ``t9``/``t10``)
    d_tendon: tuple[str | None, ...]
    #: ``+1`` if the slot vector is its tendon's vector (head - tail), ``-1`` if its negative
    d_sign: np.ndarray
    #: whether the slot's column of ``B^d`` is non-zero (false for the closure copies)
    d_counted: np.ndarray
    o_slots: tuple[str, ...]
    o_tendon: tuple[str | None, ...]
    o_sign: np.ndarray
    o_counted: np.ndarray
    #: tendon name of each entry of ``u``
    u_names: tuple[str, ...]

    @property
    def n_coordinates(self) -> int:
        """``12nm``."""
        return 12 * self.n * self.m

    @property
    def n_controls(self) -> int:
        """Length of ``u``: ``n(10m-2)``, or ``8nm`` for the primal shell."""
        return len(self.u_names)

    @property
    def utilde_slots(self) -> tuple[str, ...]:
        """Slot of each entry of ``u~`` (``f^d`` slots, then ``f^o`` slots)."""
        return self.d_slots + self.o_slots

    def matrices(self) -> dict[str, sp.csr_matrix]:
        """The constant matrices by name."""
        return {name: getattr(self, name) for name in _TOPOLOGY_MATRICES}


_TOPOLOGY_MATRICES = ("Q", "Q_inv", "R", "R_o", "T", "W_o", "B_d", "B_o", "P")


def _frozen_csr(matrix: Any) -> sp.csr_matrix:
    """A CSR copy without explicit zeros, sorted, with read-only arrays."""
    out = sp.csr_matrix(matrix, dtype=float, copy=True)
    out.eliminate_zeros()
    out.sort_indices()
    for array in (out.data, out.indices, out.indptr):
        array.setflags(write=False)
    return out


def _kron3(scalar: Any) -> sp.csr_matrix:
    """``scalar (x) I3``: a matrix on 3-vectors from its scalar pattern."""
    return sp.kron(sp.csr_matrix(scalar), _I3, format="csr")


def _parse(name: str) -> tuple[int, int, int]:
    match = _TENDON_NAME.fullmatch(name)
    if match is None:
        raise ValueError(f"{name!r} is not a shell tendon name t<alpha>_<i>_<j>")
    alpha, i, j = (int(g) for g in match.groups())
    return alpha, i, j


def control_names(n: int, m: int, primal: bool = False) -> tuple[str, ...]:
    """Tendon name of each entry of ``u`` (the paper's order, 18.54-18.58 / Appendix C)."""
    return shell_topology(n, m, primal).u_names


def shell_topology(n: int, m: int, primal: bool = False) -> ShellTopology:
    """The constant matrices of the ``(n, m)`` shell (cached; the matrices are read-only).

    For ``m = 1`` the primal and the full shell coincide (t9 and t10 are closure copies of t1 and
    t7 there), and ``primal`` is ignored.
    """
    return _build_topology(int(n), int(m), bool(primal) and m > 1)


class _Slot(NamedTuple):
    """A slot of ``l^d``/``f^d``/``f^o``: a tendon vector ``p_head - p_tail`` the paper carries."""

    ends: tuple[int, int]  #: (tail, head) node indices of the slot vector
    tendon: str | None  #: the tendon whose force it carries (None: no tendon, primal t9/t10)
    sign: int  #: +1 if the slot vector is its tendon's vector (head - tail), -1 if its negative
    counted: bool  #: whether the slot's column of ``B^d``/``B^o`` is non-zero


@functools.lru_cache(maxsize=32)
def _build_topology(n: int, m: int, primal: bool) -> ShellTopology:
    """The :class:`ShellTopology` of :func:`shell_topology` (``primal`` already normalized)."""
    full = {name: (tail, head) for name, tail, head in shell_tendons(n, m)}  # validates n, m
    present = {name for name, _, _ in shell_tendons(n, m, primal=primal)}
    n_nodes = 4 * n * m
    elements = [(i, j) for j in range(1, m + 1) for i in range(1, n + 1)]
    # l and Q (18.27-18.28): node positions from the independent vectors along a tree.
    l_vectors = _independent_vectors(n, elements, full)
    G = _positions_along_tree(n_nodes, l_vectors)  # p = G l (scalar pattern)
    M, P = _rod_coordinate_maps(n_nodes)
    Q = _frozen_csr(_kron3(M @ G))
    Q_inv = _frozen_csr(_appendix_b_inverse(Q, n, m))
    # slots of l^d / f^d (18.31-18.37) and f^o (18.16)
    d_slots = [f"t1_{n}_1"] + [f"t{a}_{i}_{j}" for i, j in elements for a in D_ALPHAS]
    o_slots = [f"t{a}_{i}_{j}" for i, j in elements for a in O_ALPHAS]
    d_info = [_slot(name, full, present, m) for name in d_slots]
    o_info = [_slot(name, full, present, m) for name in o_slots]
    last = o_slots.index(f"t1_{n}_1")  # t1_n1 acts once, through f^d
    o_info[last] = o_info[last]._replace(counted=False)
    R = _frozen_csr(_kron3(np.array([P[head] - P[tail] for (tail, head), *_ in d_info])))
    R_o = _o_slot_vectors(o_slots, [label for label, _, _ in l_vectors], R, Q_inv, n)
    # u (18.54-18.58)
    u_names = [name for name in d_slots[1:] if name in present]
    u_names += o_slots
    # B^d, B^o, W^o (18.15)
    W = np.kron(np.eye(n * m), _W_ELEMENT)
    return ShellTopology(
        n=n,
        m=m,
        primal=primal,
        Q=Q,
        Q_inv=Q_inv,
        R=R,
        R_o=R_o,
        T=_control_spread(d_info + o_info, u_names),
        W_o=_frozen_csr(_kron3(W)),
        B_d=_frozen_csr(_kron3(W @ _incidence(d_info, n_nodes))),
        B_o=_frozen_csr(_kron3(W @ _incidence(o_info, n_nodes))),
        P=_frozen_csr(_kron3(P)),
        l_labels=tuple(label for label, _, _ in l_vectors),
        d_slots=tuple(d_slots),
        d_tendon=tuple(info.tendon for info in d_info),
        d_sign=_readonly(np.array([info.sign for info in d_info], dtype=float)),
        d_counted=_readonly(np.array([info.counted for info in d_info])),
        o_slots=tuple(o_slots),
        o_tendon=tuple(info.tendon for info in o_info),
        o_sign=_readonly(np.array([info.sign for info in o_info], dtype=float)),
        o_counted=_readonly(np.array([info.counted for info in o_info])),
        u_names=tuple(u_names),
    )


def _independent_vectors(
    n: int, elements: Sequence[tuple[int, int]], full: dict[str, tuple[int, int]]
) -> list[tuple[str, int | None, int]]:
    """The vectors of ``l`` (18.27-18.28), ``(label, tail, head)`` node indices, element by
    element: ``[rho_11, r1, r2, t5]`` for (1,1) (``rho_11`` the position of node 1: no tail),
    ``[t1_(i-1)1, r1, r2, t5]`` for (i,1), ``[r1, r2, t5, t1]`` for j > 1.

    ``full`` maps every tendon name of the full shell to its ``(tail, head)``.
    """

    def node(k: int, i: int, j: int) -> int:
        return shell_node_index(k, i, j, n)

    l_vectors: list[tuple[str, int | None, int]] = []
    for i, j in elements:
        r1 = (f"r1_{i}_{j}", node(1, i, j), node(2, i, j))
        r2 = (f"r2_{i}_{j}", node(3, i, j), node(4, i, j))
        t5 = (f"t5_{i}_{j}", *full[f"t5_{i}_{j}"])
        if j == 1:
            first = (
                ("rho_1_1", None, node(1, 1, 1))
                if i == 1
                else (f"t1_{i - 1}_1", *full[f"t1_{i - 1}_1"])
            )
            l_vectors += [first, r1, r2, t5]
        else:
            l_vectors += [r1, r2, t5, (f"t1_{i}_{j}", *full[f"t1_{i}_{j}"])]
    return l_vectors


def _rod_coordinate_maps(n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """``(M, P)``, scalar patterns (n_nodes, n_nodes) of ``q = M p`` (per rod ``q1 = p_a + p_b``,
    ``q2 = p_b - p_a``) and its inverse ``p = P q`` (18.26); rod ``r`` joins nodes
    ``(2r, 2r+1)``, as in ``class1_shell``."""
    rods = np.arange(n_nodes).reshape(-1, 2)
    M = np.zeros((n_nodes, n_nodes))
    P = np.zeros((n_nodes, n_nodes))
    for r, (a, b) in enumerate(rods):
        M[2 * r, [a, b]] = 1.0
        M[2 * r + 1, [a, b]] = (-1.0, 1.0)
        P[a, [2 * r, 2 * r + 1]] = (0.5, -0.5)
        P[b, [2 * r, 2 * r + 1]] = (0.5, 0.5)
    return M, P


def _slot(name: str, full: dict[str, tuple[int, int]], present: set[str], m: int) -> _Slot:
    """The slot ``name`` (``t{alpha}_{i}_{j}``) of an ``(n, m)`` shell whose tendons are
    ``full`` (name -> (tail, head)), ``present`` of them in this (possibly primal) shell.

    A tendon of the full shell is its own slot, counted (with no tendon if the primal shell
    leaves it out); ``t9_i1`` and ``t10_im`` are closure copies of ``-t1_i1`` and ``-t7_im``.
    """
    if name in full:
        return _Slot(full[name], (name if name in present else None), 1, True)
    alpha, i, j = _parse(name)
    if alpha == 9 and j == 1:  # (18.2): t9_i1 = -t1_i1
        partner = f"t1_{i}_1"
    elif alpha == 10 and j == m:  # (18.7): t10_im = -t7_im
        partner = f"t7_{i}_{m}"
    else:  # pragma: no cover - the table has no other gaps
        raise AssertionError(f"no geometry for slot {name}")
    tail, head = full[partner]
    return _Slot((head, tail), partner, -1, False)


def _o_slot_vectors(
    o_slots: Sequence[str], l_labels: Sequence[str], R: sp.csr_matrix, Q_inv: sp.csr_matrix, n: int
) -> sp.csr_matrix:
    """``R_o`` (6nm, 12nm): the rows of ``Q^-1`` for ``t5_ij`` and ``t1_ij`` (labels of ``l``:
    ``l_labels``), and ``R_0`` (the first three rows of ``R``) for ``t1_n1``, not in ``l``."""
    l_index = {label: k for k, label in enumerate(l_labels)}
    blocks = []
    for name in o_slots:
        rows = R[0:3] if name == f"t1_{n}_1" else Q_inv[3 * l_index[name] : 3 * l_index[name] + 3]
        blocks.append(rows)
    return _frozen_csr(sp.vstack(blocks))


def _control_spread(slots: Sequence[_Slot], u_names: Sequence[str]) -> sp.csr_matrix:
    """``T`` (slots, controls) of ``u~ = T u`` (18.55): every slot gets the rest-length change
    of its tendon (``u_names`` names the tendon of each entry of ``u``)."""
    u_column = {name: k for k, name in enumerate(u_names)}
    entries = [
        (r, u_column[info.tendon]) for r, info in enumerate(slots) if info.tendon is not None
    ]
    rows, columns = [r for r, _ in entries], [c for _, c in entries]
    return _frozen_csr(
        sp.csr_matrix((np.ones(len(rows)), (rows, columns)), shape=(len(slots), len(u_names)))
    )


def _incidence(slots: Sequence[_Slot], n_nodes: int) -> np.ndarray:
    """(n_nodes, slots): a counted slot's tendon pulls its tail toward its head (+f) and vice
    versa (18.15)."""
    N = np.zeros((n_nodes, len(slots)))
    for s, ((tail, head), _, _, counted) in enumerate(slots):
        if counted:
            N[tail, s] += 1.0
            N[head, s] -= 1.0
    return N


def _readonly(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


def _positions_along_tree(
    n_nodes: int, vectors: Sequence[tuple[str, int | None, int]]
) -> np.ndarray:
    """``G`` with ``p = G l``: walk the tree the vectors ``l_k = p_head - p_tail`` span.

    The one vector without a tail is the root's position.  Raises if the vectors do not form a
    spanning tree (then they would not be independent, or not determine every node).
    """
    adjacency: list[list[tuple[int, int, float]]] = [[] for _ in range(n_nodes)]
    roots = [k for k, (_, tail, _) in enumerate(vectors) if tail is None]
    if len(roots) != 1 or len(vectors) != n_nodes:
        raise ValueError("l: expected one position and n_nodes - 1 edge vectors")
    for k, (_, tail, head) in enumerate(vectors):
        if tail is not None:
            adjacency[tail].append((head, k, 1.0))
            adjacency[head].append((tail, k, -1.0))
    G = np.zeros((n_nodes, len(vectors)))
    root = vectors[roots[0]][2]
    G[root, roots[0]] = 1.0
    seen, used = {root}, {roots[0]}
    queue = deque([root])
    while queue:
        here = queue.popleft()
        for there, k, sign in adjacency[here]:
            if k in used:
                continue
            used.add(k)
            if there in seen:
                raise ValueError(f"l: {vectors[k][0]} closes a loop; the vectors are dependent")
            G[there] = G[here]
            G[there, k] += sign
            seen.add(there)
            queue.append(there)
    if len(seen) != n_nodes:
        raise ValueError("l: the vectors do not reach every node")
    return G


# ----------------------------------------------------------------- Appendix B
def _lower_pattern(first: Any, diag: Any, column: Any, below: Any, count: int) -> sp.csr_matrix:
    """``[[first], [column, diag], [column, below, diag], [column, below, below, diag], ...]``."""
    grid = [[None] * count for _ in range(count)]
    for r in range(count):
        grid[r][r] = first if r == 0 else diag
        if r >= 1:
            grid[r][0] = column
        for c in range(1, r):
            grid[r][c] = below
    return sp.bmat(grid, format="csr")


def _pattern_inverse(first_inv, diag_inv, column, below, count: int) -> sp.csr_matrix:
    """Inverse of :func:`_lower_pattern` by Appendix B's substitution (18.B.5-18.B.6).

    ``x_{j+1} = diag^-1 (y_{j+1} - y_j) + Theta x_j`` with ``Theta = I - diag^-1 below`` gives the
    blocks ``(1,1) = first^-1``, ``(j,j) = diag^-1``, ``(j,1) = Theta^{j-2} L21`` and
    ``(j,k) = Theta^{j-k-1} L32`` (``1 < k < j``), where ``L21 = -diag^-1 column first^-1`` and
    ``L32 = -diag^-1 below diag^-1``: Appendix B's ``Lambda_11, Lambda_22, Lambda_21, Lambda_32``
    and powers of ``Theta``.
    """
    size = diag_inv.shape[0]
    theta = sp.identity(size, format="csr") - diag_inv @ below
    lam21 = -(diag_inv @ column @ first_inv)
    lam32 = -(diag_inv @ below @ diag_inv)
    powers = [sp.identity(size, format="csr")]
    for _ in range(max(count - 2, 0)):
        powers.append(theta @ powers[-1])
    grid = [[None] * count for _ in range(count)]
    grid[0][0] = first_inv
    for r in range(1, count):
        grid[r][r] = diag_inv
        grid[r][0] = powers[r - 1] @ lam21
        for c in range(1, r):
            grid[r][c] = powers[r - c - 1] @ lam32
    return sp.bmat(grid, format="csr")


def _pattern_blocks(matrix: sp.csr_matrix, size: int, count: int, what: str):
    """The four blocks of a :func:`_lower_pattern` matrix; raises if it is not one."""

    def block(r: int, c: int) -> sp.csr_matrix:
        return sp.csr_matrix(matrix[r * size : (r + 1) * size, c * size : (c + 1) * size])

    first, diag = block(0, 0), block(1, 1) if count > 1 else None
    column = block(1, 0) if count > 1 else None
    below = block(2, 1) if count > 2 else sp.csr_matrix((size, size))
    rebuilt = _lower_pattern(first, diag, column, below, count)
    if count > 1 and abs(rebuilt - matrix).max() != 0:
        raise AssertionError(f"{what} does not have the block pattern of (18.29)")
    return first, diag, column, below


def _block_inverse(block: sp.csr_matrix) -> sp.csr_matrix:
    return sp.csr_matrix(np.linalg.inv(block.toarray()))


def _appendix_b_inverse(Q: sp.csr_matrix, n: int, m: int) -> sp.csr_matrix:
    """``Q^-1`` from Appendix B: only ``Q11^-1`` and ``Q22^-1`` need inverting, and ``Q11`` has
    the same block pattern (``A, B`` on the diagonal, ``D`` in the first column, ``E`` below) on
    12 x 12 blocks, so it is inverted the same way from ``A^-1`` and ``B^-1``."""
    Q11 = sp.csr_matrix(Q[: 12 * n, : 12 * n])
    A, B, D, E = _pattern_blocks(Q11, 12, n, "Q11")
    lam11 = _pattern_inverse(_block_inverse(A), _block_inverse(B), D, E, n)
    if m == 1:
        return lam11
    _, Q22, Q21, Q32 = _pattern_blocks(Q, 12 * n, m, "Q")
    C = sp.csr_matrix(Q22[:12, :12])
    if abs(sp.kron(sp.identity(n), C) - Q22).max() != 0:
        raise AssertionError("Q22 is not BlockDiag[C] (18.29)")
    lam22 = sp.kron(sp.identity(n), _block_inverse(C), format="csr")
    return _pattern_inverse(lam11, lam22, Q21, Q32, m)


# ============================================================================ a structure
def shell_size(structure: Structure) -> tuple[int, int, bool]:
    """``(n, m, primal)`` of a class 1 shell; ``ValueError`` if ``structure`` is not one.

    The structure must have the rods and tendons of ``class1_shell(n, m, primal=...)``: rod ``r``
    joining nodes ``2r, 2r+1`` and every tendon named ``t{alpha}_{i}_{j}`` joining the nodes of
    the topology table (in any order).  Parameters (masses, stiffnesses, ...) may differ.
    """
    structure.require_free_class1("the matrix model")
    try:
        parsed = [_parse(name) for name in structure.tendon_name]
    except ValueError as exc:
        raise ValueError(f"tendons: {exc}; the matrix model needs a class 1 shell") from None
    if not parsed:
        raise ValueError("tendons: a class 1 shell has tendons")
    n = max(i for _, i, _ in parsed)
    m = max(j for _, _, j in parsed)
    primal = m > 1 and all(alpha <= 8 for alpha, _, _ in parsed)
    try:
        expected = {name: (tail, head) for name, tail, head in shell_tendons(n, m, primal=primal)}
    except ValueError as exc:
        raise ValueError(f"tendons: names imply a shell with {exc}") from None
    if structure.n_rods != 2 * n * m or not np.array_equal(
        structure.rod_nodes, np.arange(4 * n * m).reshape(-1, 2)
    ):
        raise ValueError(
            f"rods: the tendon names imply an ({n},{m}) shell, whose rod r joins nodes 2r, 2r+1 "
            f"({2 * n * m} rods); the structure has {structure.n_rods} rods"
        )
    got = {
        name: (int(a), int(b))
        for name, (a, b) in zip(structure.tendon_name, structure.tendon_nodes, strict=True)
    }
    if got != expected:
        wrong = sorted(set(got.items()) ^ set(expected.items()))
        raise ValueError(
            f"tendons: not the ({n},{m}){' primal' if primal else ''} shell of the topology table; "
            f"first difference: {wrong[0][0]!r}"
        )
    return n, m, primal


@dataclasses.dataclass(frozen=True, eq=False)
class StateMatrices:
    """The state-dependent matrices of (18.59) at one ``(q, q', u)`` (CSR, no explicit zeros).

    ``K_d``, ``K_o``, ``P_d``, ``P_o`` are (18.45)-(18.50) with ``k = 0`` for a slack tendon
    (``|t| <= L0 - u``) or for a slot without tendon; ``K_tilde``, ``B_tilde`` (18.52);
    ``K_p = H K_tilde``, ``B = H B_tilde T``, ``D = H W^o`` (18.59); ``H``, ``K_r`` (18.20).
    """

    q: np.ndarray
    qdot: np.ndarray
    u: np.ndarray
    utilde: np.ndarray
    taut_d: np.ndarray  #: per ``f^d`` slot: its tendon is taut
    taut_o: np.ndarray  #: per ``f^o`` slot
    H: sp.csr_matrix
    K_r: sp.csr_matrix
    K_d: sp.csr_matrix
    K_o: sp.csr_matrix
    P_d: sp.csr_matrix
    P_o: sp.csr_matrix
    K_tilde: sp.csr_matrix
    B_tilde: sp.csr_matrix
    K_p: sp.csr_matrix
    B: sp.csr_matrix
    D: sp.csr_matrix
    C_t: sp.csr_matrix  #: tendon vectors ``t = C_t q`` (3 nu, 12nm), tendons in ``u`` order (18.43)
    y_l: np.ndarray  #: tendon lengths (nu,) [m] (18.60)
    y_f: np.ndarray  #: tensions (nu,) [N], 0 when slack (18.60)
    C_l: sp.csr_matrix  #: ``d y_l / d q`` (nu, 12nm): linearized length output
    C_f: sp.csr_matrix  #: ``d y_f / d q`` (nu, 12nm): linearized tension output

    def qddot(self, w: np.ndarray | None = None) -> np.ndarray:
        """``q'' = -(K_r + K_p) q + B u + D w`` (18.59); ``w`` (12nm,) or (4nm, 3), default 0."""
        acc = -(self.K_r @ self.q) - self.K_p @ self.q + self.B @ self.u
        if w is not None:
            acc = acc + self.D @ np.asarray(w, dtype=float).reshape(-1)
        return acc

    def matrices(self) -> dict[str, sp.csr_matrix]:
        """The state-dependent matrices by name."""
        return {name: getattr(self, name) for name in STATE_MATRICES}


STATE_MATRICES = (
    "H",
    "K_r",
    "K_d",
    "K_o",
    "P_d",
    "P_o",
    "K_tilde",
    "B_tilde",
    "K_p",
    "B",
    "D",
    "C_t",
    "C_l",
    "C_f",
)


class ShellMatrixModel:
    """The matrix model (18.59) of one class 1 shell structure.

    Built once per structure (slot-to-tendon maps, parameters); :meth:`evaluate` then forms the
    state-dependent matrices with vectorized NumPy and sparse products only.

    Raises
    ------
    ValueError
        If ``structure`` is not a class 1 shell (see :func:`shell_size`) or has damping (the
        paper's matrix model is undamped; see :func:`tensegrity.physics.dynamics.undamped`).
    """

    def __init__(self, structure: Structure) -> None:
        if any(
            np.any(values != 0)
            for values in (
                structure.tendon_damping,
                structure.rod_damping,
                structure.rod_relative_damping,
            )
        ):
            raise ValueError(
                "structure has tendon or rod damping, which the matrix model (18.59) does not "
                "represent; use tensegrity.physics.dynamics.undamped(structure)"
            )
        n, m, primal = shell_size(structure)
        self.structure = structure
        self.topology = top = shell_topology(n, m, primal)
        index = {name: s for s, name in enumerate(structure.tendon_name)}

        def slot_parameters(tendons: tuple[str | None, ...]) -> tuple[np.ndarray, np.ndarray]:
            idx = np.array([-1 if t is None else index[t] for t in tendons])
            has = idx >= 0
            k = np.where(has, structure.tendon_stiffness[np.where(has, idx, 0)], 0.0)
            rest = np.where(has, structure.tendon_rest_length[np.where(has, idx, 0)], 0.0)
            return k, rest

        self._k_d, self._L0_d = slot_parameters(top.d_tendon)
        self._k_o, self._L0_o = slot_parameters(top.o_tendon)
        #: structure tendon index of each entry of ``u``
        self.control_index = _readonly(np.array([index[name] for name in top.u_names]))
        incidence = structure.tendon_incidence[self.control_index]
        self._tendon_map = _clean(sp.kron(incidence, sp.identity(3)) @ top.P)
        self._k_u = structure.tendon_stiffness[self.control_index]
        self._L0_u = structure.tendon_rest_length[self.control_index]
        self._mass = structure.rod_mass
        self._length2 = structure.rod_length**2
        n_rods = structure.n_rods
        self._q2_rows = (6 * np.arange(n_rods)[:, None] + 3 + np.arange(3)).reshape(-1)

    # ------------------------------------------------------------------ controls
    def control_to_structure(self, u: np.ndarray) -> np.ndarray:
        """``u`` (paper order) as the ``control`` of :func:`dynamics.accelerations` (S,)."""
        u = self._check_u(u)
        control = np.zeros(self.structure.n_tendons)
        control[self.control_index] = u
        return control

    def control_from_structure(self, control: np.ndarray) -> np.ndarray:
        """The ``u`` (paper order) of a ``control`` array in structure tendon order."""
        control = np.asarray(control, dtype=float)
        if control.shape != (self.structure.n_tendons,):
            raise ValueError(
                f"control: expected shape ({self.structure.n_tendons},), got {control.shape}"
            )
        return control[self.control_index]

    def _check_u(self, u: np.ndarray | None) -> np.ndarray:
        nu = self.topology.n_controls
        if u is None:
            return np.zeros(nu)
        u = np.asarray(u, dtype=float)
        if u.shape != (nu,):
            raise ValueError(
                f"u: expected shape ({nu},) (tendons in the paper's order), got {u.shape}"
            )
        return u

    # ------------------------------------------------------------------ evaluation
    def evaluate(
        self, q: np.ndarray, qdot: np.ndarray, u: np.ndarray | None = None
    ) -> StateMatrices:
        """All state-dependent matrices of (18.59) at ``q``, ``q'`` and the control ``u``.

        ``u`` (paper order, default 0) enters ``K_p`` and ``B`` through which tendons are slack
        (``k = 0`` when ``|t| <= Lbar = L0 - u``, as in :func:`dynamics.tendon_forces`).

        Raises
        ------
        ValueError
            On a wrong shape, or a ``u`` that makes some rest length negative.
        """
        top = self.topology
        nq = top.n_coordinates
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        for name, value in (("q", q), ("qdot", qdot)):
            if value.shape != (nq,):
                raise ValueError(f"{name}: expected shape ({nq},), got {value.shape}")
        u = self._check_u(u)
        dynamics.rest_lengths(self.structure, self.control_to_structure(u))  # L0 - u >= 0
        utilde = top.T @ u
        nd = len(top.d_slots)
        K_d, P_d, taut_d = _tendon_terms(top.R, q, self._k_d, self._L0_d, utilde[:nd])
        K_o, P_o, taut_o = _tendon_terms(top.R_o, q, self._k_o, self._L0_o, utilde[nd:])
        H = self._h_matrix(q)
        K_r = self._kr_matrix(qdot)
        K_tilde = _clean(top.B_d @ K_d + top.B_o @ K_o)
        B_tilde = _clean(sp.hstack([top.B_d @ P_d, top.B_o @ P_o], format="csr"))
        t = (self._tendon_map @ q).reshape(-1, 3)
        y_l = np.linalg.norm(t, axis=1)
        taut = y_l > self._L0_u - u
        y_f = np.where(taut, self._k_u * (y_l - (self._L0_u - u)), 0.0)
        unit = t / np.where(y_l > 0, y_l, 1.0)[:, None]
        rows = sp.csr_matrix(
            (unit.reshape(-1), np.arange(3 * len(y_l)), 3 * np.arange(len(y_l) + 1)),
            shape=(len(y_l), 3 * len(y_l)),
        )  # BlockDiag[t_hat^T]: d|t|/dq = t_hat^T C_t
        C_l = _clean(rows @ self._tendon_map)
        return StateMatrices(
            q=q,
            qdot=qdot,
            u=u,
            utilde=utilde,
            taut_d=taut_d,
            taut_o=taut_o,
            H=H,
            K_r=K_r,
            K_d=K_d,
            K_o=K_o,
            P_d=P_d,
            P_o=P_o,
            K_tilde=K_tilde,
            B_tilde=B_tilde,
            K_p=_clean(H @ K_tilde),
            B=_clean(H @ B_tilde @ top.T),
            D=_clean(H @ top.W_o),
            C_t=self._tendon_map,
            y_l=y_l,
            y_f=y_f,
            C_l=C_l,
            C_f=_clean(sp.diags(np.where(taut, self._k_u, 0.0)) @ C_l),
        )

    def qddot(
        self,
        q: np.ndarray,
        qdot: np.ndarray,
        u: np.ndarray | None = None,
        w: np.ndarray | None = None,
    ) -> np.ndarray:
        """``q''`` from the matrix form (18.59)."""
        return self.evaluate(q, qdot, u).qddot(w)

    def _h_matrix(self, q: np.ndarray) -> sp.csr_matrix:
        """``H = BlockDiag[H_ij]``: per rod ``(2/m) [[I, 0], [0, (3/L^2) skew(q2)^2]]`` (18.20)."""
        q2 = q.reshape(-1, 2, 3)[:, 1]
        n_rods = q2.shape[0]
        blocks = np.empty((2 * n_rods, 3, 3))
        blocks[0::2] = (2.0 / self._mass)[:, None, None] * np.eye(3)
        skew2 = q2[:, :, None] * q2[:, None, :] - np.sum(q2 * q2, axis=1)[:, None, None] * np.eye(3)
        blocks[1::2] = (6.0 / (self._mass * self._length2))[:, None, None] * skew2
        diagonal = np.arange(2 * n_rods)
        H = sp.bsr_matrix(
            (blocks, diagonal, np.arange(2 * n_rods + 1)), shape=(6 * n_rods, 6 * n_rods)
        )
        return _clean(H.tocsr())

    def _kr_matrix(self, qdot: np.ndarray) -> sp.csr_matrix:
        """``K_r = BlockDiag[Omega_ij]``: ``|q2'|^2 / L^2`` on the ``q2`` rows (Theorem 18.1 with
        the proof's ``q2'^T q2'``, not the printed ``q2^T q2``)."""
        v2 = qdot.reshape(-1, 2, 3)[:, 1]
        rate = np.repeat(np.sum(v2 * v2, axis=1) / self._length2, 3)
        n = qdot.shape[0]
        return _clean(sp.csr_matrix((rate, (self._q2_rows, self._q2_rows)), shape=(n, n)))


def _tendon_terms(
    R: sp.csr_matrix, q: np.ndarray, k: np.ndarray, rest0: np.ndarray, utilde: np.ndarray
) -> tuple[sp.csr_matrix, sp.csr_matrix, np.ndarray]:
    """``K`` (18.45) and ``P = BlockDiag[b]`` (18.46) for slots with vectors ``t = R q``.

    ``f = -K q + P u~ = k (|t| - L0 + u~) t/|t|`` while taut, else 0.
    """
    t = (R @ q).reshape(-1, 3)
    length = np.linalg.norm(t, axis=1)
    taut = (k > 0) & (length - (rest0 - utilde) > 0)
    safe = np.where(taut, length, 1.0)
    scale = np.where(taut, k * (rest0 / safe - 1.0), 0.0)
    K = _clean(sp.diags(np.repeat(scale, 3)) @ R)
    b = np.where(taut[:, None], k[:, None] * t / safe[:, None], 0.0)
    n_slots = t.shape[0]
    P = sp.csr_matrix(
        (b.reshape(-1), np.repeat(np.arange(n_slots), 3), np.arange(3 * n_slots + 1)),
        shape=(3 * n_slots, n_slots),
    )
    return K, _clean(P), taut


def _clean(matrix: sp.spmatrix) -> sp.csr_matrix:
    """CSR in canonical form (no explicit zeros, sorted indices), so that later operations do not
    reorder it in place and every product is summed in one fixed order."""
    out = sp.csr_matrix(matrix)
    out.sum_duplicates()
    out.eliminate_zeros()
    out.sort_indices()
    return out
