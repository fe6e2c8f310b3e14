"""Linear constraints on the nodes: ball joints, fixed nodes, nodes on planes and lines.

Every support and joint of a :class:`~tensegrity.model.structure.Structure` is linear in the node
positions, and the node positions are linear in the coordinates (eq. 18.26: ``p_a = (q1 - q2)/2``,
``p_b = (q1 + q2)/2`` for a rod; a point mass's position is its own coordinate; an anchor is a
constant), so all of them together read

    A q = b,        A = A_n P  (c x n, constant, sparse),    b = d - A_n p_anchor,

with ``A_n p = d`` the constraints on the stacked node positions ``p`` (3N,).  Rows (node space):

- ball joint between nodes ``a`` and ``b``: ``p_a - p_b = 0`` (3 rows);
- a rod's end fixed to ground: ``p_a = p_a(0)`` (3 rows); an anchor (a fixed node of no rod) is
  not in ``q`` at all;
- node on a plane with unit normal ``n``: ``n . p_a = n . p_a(0)`` (1 row);
- node on a line along ``e``: ``u_k . p_a = u_k . p_a(0)`` for two unit ``u_k`` normal to ``e``.

Rows that depend on others (a cycle of joints, a fixed node that is also on a plane, a joint
between two anchors) are removed once, at construction, by a rank-revealing QR of each group of
coupled rows, so that ``A`` has full row rank.

Dynamics.  Theorem 18.1's accelerations are affine in the nodal forces: ``q'' = a0(q, q') + G(q) f``
(``G`` block-diagonal per rod, ``1/m`` per point mass).  The ideal constraint forces
``f_c = A_n^T lambda`` keep ``A q'' = 0`` (``A`` is constant, so ``d/dt (A q') = A q''``)::

    (A G(q) A_n^T) lambda = -A q''_free,        q'' = a0 + G (f + f_c).

``A G A_n^T = A_n (P G) A_n^T`` is symmetric positive semi-definite (``P G`` is the inverse mass
matrix in node space); it is singular when a constraint force can be taken up by a rod's axial
stiffness alone (a rod whose two ends are both held, a closed loop of jointed rods).  The
singular part changes no acceleration, and it is handled by a regularized sparse solve with
iterative refinement (:func:`solve_psd`).

Projection.  Integration drifts off the constraints; :meth:`LinearConstraints.project` restores
``A q = b`` and the rod lengths ``|q2| = L`` together by Gauss-Newton steps in the kinetic-energy
metric (the closest point in mass-weighted distance), and the rates onto ``A q' = 0``,
``q2 . q2' = 0`` by one mass-weighted linear projection.  See ``docs/constraints.md``.
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING

import numpy as np

from tensegrity.model.structure import Structure
from tensegrity.physics.coordinates import force_response, rod_coordinates

if TYPE_CHECKING:  # (SciPy is imported where a structure with constraints needs it)
    import scipy.sparse as sp

#: Structures with at most this many independent constraint rows solve for the constraint forces
#: with dense arrays (less overhead than sparse matrices), others with sparse ones.  Above it the
#: dense inverse goes through threaded LAPACK/BLAS, which on a busy machine stalls (measured: 6 to
#: 95 ms per evaluation of a (8,4) class 2 shell with 144-192 rows, against 1.2-1.4 ms sparse).
DENSE_ROWS = 64
#: Regularization of :func:`solve_psd`, relative to the largest diagonal entry.
REGULARIZATION = 1e-12
#: Rows whose QR pivot is below this (relative to the group's largest) depend on the others.
RANK_RTOL = 1e-10
#: :meth:`LinearConstraints.project` stops when ``|A q - b|`` [m] and the rod-length errors [m]
#: are below this times the structure's length scale (the longest rod, at least 1 m).
PROJECTION_RTOL = 1e-14
#: ... or, once Gauss-Newton stops converging (the error no longer halves: round-off in ``A q - b``
#: and ``|q2|`` sets a floor that grows with the coordinates' magnitude and the number of coupled
#: rows), when they are below this times the length scale.  Past it the projection has failed.
PROJECTION_FLOOR_RTOL = 1e-12


def solve_psd(
    matrix: sp.spmatrix | np.ndarray, rhs: np.ndarray, *, refinements: int = 2
) -> np.ndarray:
    """Solve ``K x = r`` for a symmetric positive semi-definite ``K`` (c x c), dense or sparse.

    Factorizes ``K + delta I`` (``delta = REGULARIZATION max(diag K)``) once (a dense ``K`` is
    small and inverted outright, a sparse one gets a sparse LU) and refines the
    solution ``refinements`` times against ``K`` itself, so that the bias of the regularization
    falls as ``(delta / sigma)^(refinements + 1)`` on the range of ``K``.  On ``K``'s null space
    the result is arbitrary (bounded by ``|r| / delta``); callers use it only through products
    that vanish there.
    """
    size = matrix.shape[0]
    if size == 0:
        return np.zeros(0)
    delta = REGULARIZATION * max(float(matrix.diagonal().max()), np.finfo(float).tiny)
    if isinstance(matrix, np.ndarray):
        # Products by einsum, not BLAS: a threaded BLAS call on a busy machine can stall for
        # milliseconds, far longer than the product of these small matrices takes.
        inverse = np.linalg.inv(matrix + delta * np.eye(size))
        # (lambdas: each branch binds the same two names, the other to library callables)
        solve = lambda r: np.einsum("ij,j->i", inverse, r)  # noqa: E731 - see above
        product = lambda x: np.einsum("ij,j->i", matrix, x)  # noqa: E731 - see above
    else:
        import scipy.sparse as sp
        from scipy.sparse.linalg import splu

        matrix = sp.csc_matrix(matrix)
        solve = splu(matrix + delta * sp.identity(size, format="csc")).solve
        product = matrix.__matmul__
    x = solve(rhs)
    for _ in range(refinements):
        x += solve(rhs - product(x))
    return x


def normals(direction: np.ndarray) -> np.ndarray:
    """Unit vectors normal to each unit ``direction`` (Q, d) and to each other: (Q, d - 1, d)."""
    if direction.shape[1] == 2:
        return np.stack([-direction[:, 1], direction[:, 0]], axis=1)[:, None, :]
    helper = np.where(
        (np.abs(direction[:, :1]) < 0.9), np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]])
    )
    u = np.cross(direction, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return np.stack([u, np.cross(direction, u)], axis=1)


class LinearConstraints:
    """The constraints ``A q = b`` of a structure, with their forces and projection.

    Built by :func:`constraints_of` (once per structure); its attributes are constant.

    Attributes
    ----------
    node_matrix : (c, dN) sparse
        ``A_n`` (independent rows only; ``d`` = ``Structure.dim``).
    matrix : (c, n) sparse
        ``A = A_n P``.
    rhs : (c,)
        ``b`` [m].
    inverse_mass : (n,)
        The kinetic-energy metric's inverse: ``4/m`` on a rod's ``q1``, ``12/m`` on its
        ``q2``, ``1/m`` on a point mass [1/kg].
    """

    def __init__(self, structure: Structure) -> None:
        import scipy.sparse as sp

        s = structure
        self.structure = s
        N, d = s.n_nodes, s.dim
        position = s.node_position
        blocks: list[tuple[int | np.integer, np.ndarray, int | np.integer, np.ndarray]] = []
        # (row node, row vectors (k, d), second node or -1, rhs (k,)) per constraint
        eye = np.eye(d)
        for a, b in s.joint_nodes:
            blocks.append((a, eye, b, np.zeros(d)))
        in_rod = np.zeros(N, bool)
        in_rod[s.rod_nodes] = True
        for a in np.flatnonzero(s.node_fixed & in_rod):
            blocks.append((a, eye, -1, position[a].copy()))
        for a, normal in zip(s.plane_nodes, s.plane_normal, strict=True):
            blocks.append((a, normal[None], -1, np.array([normal @ position[a]])))
        for a, pair in zip(s.line_nodes, normals(s.line_direction), strict=True):
            blocks.append((a, pair, -1, pair @ position[a]))

        rows, cols, data, rhs = [], [], [], []
        row = 0
        for a, vectors, b, value in blocks:
            for vector, v in zip(vectors, value, strict=True):
                for node, sign in ((a, 1.0), (b, -1.0)):
                    if node >= 0:
                        rows += [row] * d
                        cols += list(d * node + np.arange(d))
                        data += list(sign * vector)
                rhs.append(v)
                row += 1
        node_matrix = sp.csr_matrix((data, (rows, cols)), shape=(row, d * N))
        # p = P q + p_anchor
        anchor = np.zeros((N, d))
        anchor[s.anchor_nodes] = position[s.anchor_nodes]
        matrix = (node_matrix @ self._coordinate_map(s)).tocsr()
        matrix.eliminate_zeros()
        rhs = np.array(rhs) - node_matrix @ anchor.ravel()
        keep = self._independent_rows(matrix)
        self.node_matrix = node_matrix[keep].tocsr()
        self.node_matrix_t = self.node_matrix.T.tocsr()
        self.matrix = matrix[keep].tocsr()
        self.rhs = rhs[keep]
        mass = np.concatenate(
            [
                np.repeat(np.stack([4 / s.rod_mass, 12 / s.rod_mass], axis=1), d, axis=1).ravel(),
                np.repeat(1 / s.node_point_mass[s.point_mass_nodes], d),
            ]
        )
        self.inverse_mass = mass
        self.length_scale = max(float(s.rod_length.max(initial=0.0)), 1.0)
        self._g_pattern = self._acceleration_pattern(s)
        self.dense = self.matrix.shape[0] <= DENSE_ROWS
        if self.dense:
            self._dense_node_matrix = self.node_matrix.toarray()

    # ------------------------------------------------------------------ construction
    @staticmethod
    def _coordinate_map(s: Structure) -> sp.csr_matrix:
        """``P`` (dN, n): stacked node positions from ``q`` (zero rows at anchors; eq. 18.26)."""
        import scipy.sparse as sp

        d, R, M = s.dim, s.n_rods, s.point_mass_nodes.size
        axes = np.arange(d)
        q1 = 2 * d * np.arange(R)[:, None] + axes  # (R, d)
        q2 = q1 + d
        pa, pb = d * s.rod_nodes[:, :1] + axes, d * s.rod_nodes[:, 1:] + axes
        pm = d * s.point_mass_nodes[:, None] + axes
        x = 2 * d * R + d * np.arange(M)[:, None] + axes
        rows = np.concatenate([pa, pa, pb, pb, pm], axis=None)
        cols = np.concatenate([q1, q2, q1, q2, x], axis=None)
        half = np.full(d * R, 0.5)
        data = np.concatenate([half, -half, half, half, np.ones(d * M)])
        return sp.csr_matrix((data, (rows, cols)), shape=(d * s.n_nodes, s.n_coordinates))

    @staticmethod
    def _independent_rows(matrix: sp.csr_matrix) -> np.ndarray:
        """Indices of a maximal set of independent rows, found group by group (rows coupled
        through shared coordinates) by QR with column pivoting of each group's transpose."""
        from scipy.linalg import qr
        from scipy.sparse.csgraph import connected_components

        c = matrix.shape[0]
        if c == 0:
            return np.zeros(0, int)
        pattern = abs(matrix)
        _, labels = connected_components(pattern @ pattern.T, directed=False)
        order = np.argsort(labels, kind="stable")
        groups = np.split(order, np.flatnonzero(np.diff(labels[order])) + 1)
        keep = []
        for rows in groups:
            sub = matrix[rows]
            columns = np.unique(sub.indices)
            if columns.size == 0:
                continue  # rows on anchors only: always satisfied
            dense = sub[:, columns].toarray()
            _, r, pivot = qr(dense.T, mode="economic", pivoting=True)
            diag = np.abs(np.diag(r))
            rank = int(np.sum(diag > RANK_RTOL * diag[0]))
            keep.extend(rows[np.sort(pivot[:rank])])
        return np.sort(np.array(keep, dtype=int))

    @staticmethod
    def _acceleration_pattern(s: Structure) -> tuple[np.ndarray, np.ndarray]:
        """Row and column indices of ``G`` (n, dN) as d x d blocks: per rod ``(q1, a), (q1, b),
        (q2, a), (q2, b)``, then one block per point mass."""
        d, R = s.dim, s.n_rods
        slot_q1 = 2 * d * np.arange(R)
        a, b = d * s.rod_nodes[:, 0], d * s.rod_nodes[:, 1]
        row_slot = np.concatenate(
            [
                np.stack([slot_q1, slot_q1, slot_q1 + d, slot_q1 + d], 1).ravel(),
                2 * d * R + d * np.arange(s.point_mass_nodes.size),
            ]
        )
        col_slot = np.concatenate([np.stack([a, b, a, b], 1).ravel(), d * s.point_mass_nodes])
        rows, cols = np.meshgrid(np.arange(d), np.arange(d), indexing="ij")
        return ((row_slot[:, None, None] + rows).ravel(), (col_slot[:, None, None] + cols).ravel())

    # ------------------------------------------------------------------ dynamics
    def acceleration_matrix(self, q: np.ndarray) -> sp.csr_matrix:
        """``G(q)`` (n, dN) sparse: ``q''`` per unit nodal force (Theorem 18.1, eqs. 18.17,
        18.20; :func:`tensegrity.physics.dynamics.force_response` applies it without forming it)."""
        import scipy.sparse as sp

        s = self.structure
        eye = np.eye(s.dim)
        q2 = rod_coordinates(s, q)[:, 1]
        c = (6.0 / (s.rod_mass * s.rod_length**2))[:, None, None]
        skew2 = c * (q2[:, :, None] * q2[:, None, :] - np.sum(q2 * q2, axis=1)[:, None, None] * eye)
        translate = (2.0 / s.rod_mass)[:, None, None] * eye
        rod_blocks = np.stack([translate, translate, skew2, -skew2], axis=1)  # (R, 4, d, d)
        mass_blocks = (1.0 / s.node_point_mass[s.point_mass_nodes])[:, None, None] * eye
        data = np.concatenate([rod_blocks.ravel(), mass_blocks.ravel()])
        rows, cols = self._g_pattern
        return sp.csr_matrix((data, (rows, cols)), shape=(s.n_coordinates, s.dim * s.n_nodes))

    def coupling(self, q: np.ndarray) -> np.ndarray | sp.csr_matrix:
        """``K = A G(q) A_n^T`` (c, c): the accelerations ``A q''`` per unit multiplier.

        Small structures (:attr:`dense`) apply Theorem 18.1 to each column of ``A_n^T`` as a set
        of nodal forces and return a dense array; large ones multiply sparse matrices."""
        if not self.dense:
            return self.matrix @ (self.acceleration_matrix(q) @ self.node_matrix_t)

        unit_forces = self._dense_node_matrix.reshape(
            -1, self.structure.n_nodes, self.structure.dim
        )
        # sparse A times a dense array: single-threaded, unlike a BLAS product, which stalls
        # when the machine is busy
        return self.matrix @ force_response(self.structure, q, unit_forces).T

    def constraint_force(self, q: np.ndarray, qddot_free: np.ndarray) -> np.ndarray:
        """Nodal constraint forces ``f_c = A_n^T lambda`` [N], (N, d), that make ``A q'' = 0``
        given the accelerations ``qddot_free`` without them.  Forces on anchors (reactions)
        are included; they move nothing."""
        multiplier = solve_psd(self.coupling(q), -(self.matrix @ qddot_free))
        return (self.node_matrix_t @ multiplier).reshape(-1, self.structure.dim)

    # ------------------------------------------------------------------ drift
    def residual(self, q: np.ndarray) -> np.ndarray:
        """``A q - b`` [m], shape (c,)."""
        return self.matrix @ q - self.rhs

    def _jacobian(self, q: np.ndarray) -> sp.csr_matrix:
        """Rows of ``A`` and, per rod, ``q2^T`` on its ``q2`` (the gradient of ``|q2|^2 / 2``)."""
        import scipy.sparse as sp

        s = self.structure
        d, R = s.dim, s.n_rods
        q2 = rod_coordinates(s, q)[:, 1]
        cols = 2 * d * np.arange(R)[:, None] + d + np.arange(d)
        lengths = sp.csr_matrix(
            (q2.ravel(), (np.repeat(np.arange(R), d), cols.ravel())), shape=(R, s.n_coordinates)
        )
        return sp.vstack([self.matrix, lengths]).tocsr()

    def project(
        self, q: np.ndarray, qdot: np.ndarray, *, max_iter: int = 50
    ) -> tuple[np.ndarray, np.ndarray]:
        """Closest ``(q, q')`` in the kinetic-energy metric with ``A q = b``, ``|q2| = L``,
        ``A q' = 0`` and ``q2 . q2' = 0``.

        Positions: Gauss-Newton steps ``dq = -W^-1 J^T (J W^-1 J^T)^-1 c(q)`` on
        ``c = [A q - b; (|q2|^2 - L^2) / 2]`` until every error is below ``PROJECTION_RTOL``
        times the length scale, or below ``PROJECTION_FLOOR_RTOL`` times it once the steps stop
        converging (the round-off floor).  Raises ``FloatingPointError`` if that fails (the state
        is too far off the constraints to be projected).
        """

        s = self.structure
        L = s.rod_length
        tol = PROJECTION_RTOL * self.length_scale
        floor = PROJECTION_FLOOR_RTOL * self.length_scale
        q = np.array(q, dtype=float)
        previous = np.inf
        for _ in range(max_iter):
            q2 = rod_coordinates(s, q)[:, 1]
            length = np.linalg.norm(q2, axis=1)
            residual = self.residual(q)
            error = max(
                np.max(np.abs(residual), initial=0.0), np.max(np.abs(length - L), initial=0.0)
            )
            if error <= tol or (error <= floor and error > 0.5 * previous):
                break
            previous = error
            jacobian = self._jacobian(q)
            violation = np.concatenate([residual, 0.5 * (length**2 - L**2)])
            q = q - self._project_step(jacobian, violation)
        else:
            raise FloatingPointError(
                f"unstable: could not project onto the constraints (error {error:.3g} m after "
                f"{max_iter} iterations)"
            )
        jacobian = self._jacobian(q)
        qdot = np.asarray(qdot, dtype=float)
        return q, qdot - self._project_step(jacobian, jacobian @ qdot)

    def _project_step(self, jacobian: sp.csr_matrix, violation: np.ndarray) -> np.ndarray:
        """``W^-1 J^T (J W^-1 J^T)^-1 c``: the mass-weighted least-norm correction."""
        weighted = jacobian.multiply(self.inverse_mass[None, :]).tocsr()
        normal = weighted @ jacobian.T
        if normal.shape[0] <= DENSE_ROWS:  # small: an explicit inverse beats a sparse LU's set-up
            normal = normal.toarray()
        return weighted.T @ solve_psd(normal, violation)


_SOLVERS: weakref.WeakKeyDictionary[Structure, LinearConstraints] = weakref.WeakKeyDictionary()


def constraints_of(structure: Structure) -> LinearConstraints | None:
    """The linear constraints ``A q = b`` of ``structure`` (:class:`LinearConstraints`), built on
    first use and kept while the structure lives; ``None`` without joints or supports."""
    if not structure.has_constraints:
        return None
    solver = _SOLVERS.get(structure)
    if solver is None:
        solver = _SOLVERS[structure] = LinearConstraints(structure)
    return solver
