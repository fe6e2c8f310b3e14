"""Compiled (numba) physics for every structure ``simulate`` accepts.

:mod:`tensegrity.physics.kernel` compiles Theorem 18.1 for free 3-D class 1 structures.  This
module adds, around the same compiled passes, what the NumPy reference
:func:`tensegrity.physics.dynamics.evaluate` does for the others:

- *point masses* (nodes of no rod, not fixed): ``x'' = (f + w) / m + g``, their positions
  ``x`` following the rods' coordinates in ``q`` (``q`` has ``6R + 3M`` entries);
- *anchors* (fixed nodes of no rod): tendon ends that never move;
- *joints and supports* (:mod:`tensegrity.physics.constraints`, ``docs/constraints.md``): the linear
  constraints ``A q = b`` (``A = A_n P``, each row touching at most two nodes) add the forces
  ``A_n^T lambda`` with ``K lambda = -A q''_free``, ``K = A G(q) A_n^T``, ``G(q)`` the
  accelerations per unit nodal force (eqs. 18.17, 18.20), and the mass-weighted Gauss-Newton
  projection of :meth:`LinearConstraints.project` keeps the state on them;
- *planar structures* (``dim == 2``, Appendix A): :func:`embed_planar` gives the 3-D structure
  with ``z = 0``, whose forces have no ``z`` component, so that ``z`` stays exactly 0.

``K`` and the projection's normal matrix ``J W^-1 J^T`` are assembled in compiled code from
their sparsity (two rows couple only through a rod or point mass that both touch) into *envelope*
(skyline) storage, rows in reverse Cuthill-McKee order, and solved by an envelope Cholesky
factorization of ``K + delta I`` with two refinements against ``K``, as
:func:`tensegrity.physics.constraints.solve_psd` does.

Every compiled function takes the records of :mod:`tensegrity.physics.records` (made by
:func:`make_records`).  A free class 1 structure has ``model.constraints = None``; every function
here then compiles to exactly the kernel's code (:func:`kernel.rhs`, :func:`kernel.project`,
:func:`kernel.energies`): the same numbers bit for bit.

Usage::

    from tensegrity.physics.kernel_system import make_records, pack_system, system_rhs

    system = pack_system(structure)          # 3-D; planar: pack_system(embed_planar(structure))
    model, data = make_records(system, rest=system.packed.to_kernel_order(rest)[None],
                               gravity=gravity)
    dissipated, external = system_rhs(model, data, 0, q, qdot, qddot)

Like :mod:`tensegrity.physics.kernel`, import this module lazily (it imports numba).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numba import njit

from tensegrity.model.structure import Structure
from tensegrity.physics.compiling import (
    JIT_OPTIONS,
    ROD_C1,
    ROD_C2,
    ROD_LENGTH,
    ROD_MASS,
    compiled_only,
)
from tensegrity.physics.constraints import (
    PROJECTION_FLOOR_RTOL,
    PROJECTION_RTOL,
    REGULARIZATION,
    LinearConstraints,
    constraints_of,
)
from tensegrity.physics.contact import contact_energy, contact_work, mass_stick_pass
from tensegrity.physics.kernel import (
    PackedStructure,
    copy_values,
    end_values,
    energies,
    pack,
    project,
    rhs_passes,
    stage_row,
)
from tensegrity.physics.records import Constraints, ConstraintWork, Contacts, Data, Model

if TYPE_CHECKING:  # (scipy is imported where a structure with constraints needs it)
    import scipy.sparse as sp

__all__ = [
    "MAX_ITER",
    "SystemArrays",
    "all_finite",
    "drop_coordinates",
    "embed_planar",
    "lift_coordinates",
    "make_records",
    "pack_system",
    "system_energies",
    "system_errors",
    "system_nodes",
    "system_project",
    "system_rhs",
]

#: Gauss-Newton iterations of :func:`system_project` (``LinearConstraints.project``'s max_iter).
MAX_ITER = 50


# --------------------------------------------------------------------------- planar structures
def embed_planar(structure: Structure) -> Structure:
    """A 3-D copy of a planar (``dim == 2``) structure in the plane ``z = 0``.

    Node positions and velocities (N, 2) and line directions (Q, 2) get a zero ``z``; everything
    else is unchanged.  A node fixed, joined or held on a line is then also held in ``z``, where
    no force acts: the 3-D dynamics keep ``z = 0`` exactly and agree with the 2-D ones.
    """
    if structure.dim != 2:
        raise ValueError(f"structure: expected a planar (dim 2) structure, got dim {structure.dim}")

    def pad(values: np.ndarray) -> np.ndarray:
        return np.concatenate([values, np.zeros((values.shape[0], 1))], axis=1)

    return structure.replace(
        node_position=pad(structure.node_position),
        node_velocity=pad(structure.node_velocity),
        plane_normal=pad(structure.plane_normal),
        line_direction=pad(structure.line_direction),
    )


def _coordinate_count(structure2d: Structure, x: np.ndarray, per_vector: int, name: str) -> int:
    """Number of 2-vectors in ``x``'s last axis (rods' ``q1``, ``q2``, then point masses)."""
    if structure2d.dim != 2:
        raise ValueError(
            f"structure2d: expected a planar (dim 2) structure, got dim {structure2d.dim}"
        )
    count = 2 * structure2d.n_rods + structure2d.point_mass_nodes.size
    if x.ndim == 0 or x.shape[-1] != per_vector * count:
        raise ValueError(
            f"{name}: expected a last axis of {per_vector * count}, got shape {x.shape}"
        )
    return count


def lift_coordinates(structure2d: Structure, x: np.ndarray) -> np.ndarray:
    """``q`` or ``q'`` (..., 4R + 2M) of a planar structure as the (..., 6R + 3M) of
    :func:`embed_planar`'s structure, with zeros in ``z`` (a new array)."""
    x = np.asarray(x, dtype=np.float64)
    count = _coordinate_count(structure2d, x, 2, "x")
    out = np.zeros((*x.shape[:-1], count, 3))
    out[..., :2] = x.reshape((*x.shape[:-1], count, 2))
    return out.reshape((*x.shape[:-1], 3 * count))


def drop_coordinates(structure2d: Structure, x: np.ndarray) -> np.ndarray:
    """The inverse of :func:`lift_coordinates`: (..., 6R + 3M) to (..., 4R + 2M), dropping
    ``z`` (a new array)."""
    x = np.asarray(x, dtype=np.float64)
    count = _coordinate_count(structure2d, x, 3, "x")
    return np.ascontiguousarray(x.reshape((*x.shape[:-1], count, 3))[..., :2]).reshape(
        (*x.shape[:-1], 2 * count)
    )


# --------------------------------------------------------------------------- packing
class SystemArrays(NamedTuple):
    """:func:`pack_system`'s result."""

    packed: PackedStructure  #: ``kernel.pack(structure, general=True)``
    constraints: Constraints | None  #: None for a free class 1 structure
    #: lengths of the envelopes of ``K`` and ``J W^-1 J^T`` and of the solver's vectors (the
    #: sizes of its :class:`~tensegrity.physics.records.ConstraintWork`)
    work_sizes: tuple[int, int, int]
    n_coordinates: int  #: ``6R + 3M``


def _envelope(pattern: sp.csr_matrix) -> tuple[np.ndarray, np.ndarray]:
    """``(first, offset)`` of the lower envelope of a symmetric pattern with its diagonal."""
    import scipy.sparse as sp

    pattern = sp.csr_matrix(pattern)
    pattern.sort_indices()
    n = pattern.shape[0]
    first = (pattern.indices[pattern.indptr[:-1]] if n else np.zeros(0)).astype(np.int64)
    offset = np.concatenate([[0], np.cumsum(np.arange(n) - first + 1)]).astype(np.int64)
    return first, offset


def _entries(structure: Structure, constraints: LinearConstraints) -> tuple[np.ndarray, ...]:
    """The constraint rows' nodes off anchors: ``(row, body, sign, coef)`` per entry, and ``b``
    (``constraints``: ``constraints_of(structure)``)."""
    node_matrix = constraints.node_matrix.tocoo()
    R = structure.n_rods
    body = np.full(structure.n_nodes, -1)
    sign = np.zeros(structure.n_nodes)
    body[structure.rod_nodes[:, 0]], sign[structure.rod_nodes[:, 0]] = np.arange(R), -1.0
    body[structure.rod_nodes[:, 1]], sign[structure.rod_nodes[:, 1]] = np.arange(R), 1.0
    body[structure.point_mass_nodes] = R + np.arange(structure.point_mass_nodes.size)
    node = node_matrix.col // 3
    keys, where = np.unique(np.stack([node_matrix.row, node]), axis=1, return_inverse=True)
    coef = np.zeros((keys.shape[1], 3))
    np.add.at(coef, (where.ravel(), node_matrix.col % 3), node_matrix.data)
    keep = body[keys[1]] >= 0  # anchors: constant, in b
    row, nodes, coef = keys[0][keep], keys[1][keep], coef[keep]
    return row, body[nodes], sign[nodes], coef, np.array(constraints.rhs, dtype=np.float64)


def _row_order(
    row: np.ndarray, body: np.ndarray, c: int, R: int, n_bodies: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, sp.csr_matrix]:
    """Reverse Cuthill-McKee order of the projection rows (c constraint rows, then R rod rows)
    on the graph of rows sharing a body: ``(constraint_prow, rod_prow, k_rank, pattern)``."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    incidence = sp.csr_matrix(
        (
            np.ones(row.size + R),
            (np.concatenate([row, c + np.arange(R)]), np.concatenate([body, np.arange(R)])),
        ),
        shape=(c + R, n_bodies),
    )
    pattern = (incidence @ incidence.T + sp.identity(c + R)).tocsr()
    order = reverse_cuthill_mckee(pattern, symmetric_mode=True).astype(np.int64)
    position = np.empty(c + R, dtype=np.int64)
    position[order] = np.arange(c + R)
    k_rank = np.empty(c, dtype=np.int64)
    k_rank[np.argsort(position[:c], kind="stable")] = np.arange(c)
    return position[:c], position[c:], k_rank, pattern


def _constraint_rows(structure: Structure) -> dict[str, np.ndarray]:
    """The :class:`~tensegrity.physics.records.Constraints` fields of the joints and supports:
    the independent rows of
    ``constraints_of(structure)`` renumbered in the order of :func:`_row_order`, entries grouped by
    body, and the envelopes of ``K`` and ``J W^-1 J^T``."""
    R, M = structure.n_rods, structure.point_mass_nodes.size
    row, body, sign, coef = (
        np.zeros(0, np.int64),
        np.zeros(0, np.int64),
        np.zeros(0),
        np.zeros((0, 3)),
    )
    rhs_b = np.zeros(0)
    constraints = constraints_of(structure)  # None without joints and supports
    if constraints is not None:
        row, body, sign, coef, rhs_b = _entries(structure, constraints)
    c = rhs_b.size
    fields = dict(
        rod_prow=np.zeros(R, dtype=np.int64),
        constraint_prow=np.zeros(0, np.int64),
        k_first=np.zeros(0, np.int64),
        k_offset=np.zeros(1, np.int64),
        n_first=np.zeros(0, np.int64),
        n_offset=np.zeros(1, np.int64),
    )
    if c:
        constraint_prow, rod_prow, k_rank, pattern = _row_order(row, body, c, R, R + M)
        row = k_rank[row]
        k_order = np.argsort(k_rank)  # old row at each K position
        rhs_b, constraint_prow = rhs_b[k_order], constraint_prow[k_order]
        old = np.empty(c + R, dtype=np.int64)  # old row at each projection position
        old[np.concatenate([constraint_prow, rod_prow])] = np.concatenate(
            [k_order, c + np.arange(R)]
        )
        fields.update(rod_prow=rod_prow, constraint_prow=constraint_prow)
        fields["n_first"], fields["n_offset"] = _envelope(pattern[old][:, old])
        fields["k_first"], fields["k_offset"] = _envelope(pattern[k_order][:, k_order])
    by_body = np.lexsort((row, body))
    return fields | dict(
        body_start=np.searchsorted(body[by_body], np.arange(R + M + 1)).astype(np.int64),
        entry_row=np.array(row[by_body], dtype=np.int64),
        entry_sign=np.array(sign[by_body], dtype=np.float64),
        entry_coef=np.array(coef[by_body], dtype=np.float64, order="C"),
        constraint_rhs=np.array(rhs_b, dtype=np.float64),
    )


def pack_system(structure: Structure) -> SystemArrays:
    """The arrays of :func:`system_rhs` and the other compiled functions for a 3-D structure:
    ``kernel.pack(structure, general=True)``, and the
    :class:`~tensegrity.physics.records.Constraints` (None for a free class 1 structure, which
    the kernel simulates alone).

    Raises
    ------
    ValueError
        If ``structure`` is planar (``dim == 2``: pack ``embed_planar(structure)``).
    """
    if structure.dim != 3:
        raise ValueError(
            "structure: pack_system takes 3-D structures; embed a planar one with "
            "embed_planar(structure) first"
        )
    packed = pack(structure, general=True)
    n_coordinates = 6 * structure.n_rods + 3 * structure.point_mass_nodes.size
    if structure.is_free_class1:
        return SystemArrays(packed, None, (0, 0, 0), n_coordinates)
    slot = packed.layout.node_slot
    masses, anchors = structure.point_mass_nodes, structure.anchor_nodes
    rows = _constraint_rows(structure)
    constraints = Constraints(
        mass_slots=np.array(slot[masses], dtype=np.uint64),
        point_mass=np.array(structure.node_point_mass[masses], dtype=np.float64),
        anchor_slots=np.array(slot[anchors], dtype=np.uint64),
        anchor_position=np.array(structure.node_position[anchors].T, dtype=np.float64, order="C"),
        **rows,
    )
    sizes = (int(rows["k_offset"][-1]), int(rows["n_offset"][-1]), max(rows["n_first"].size, 1))
    return SystemArrays(packed, constraints, sizes, n_coordinates)


def make_records(
    system: SystemArrays,
    *,
    rest: np.ndarray,
    contacts: Contacts | None = None,
    rate: np.ndarray | None = None,
    force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
    tables: object = None,
    callback: int | None = None,
    limits: tuple[float, float, float] = (np.inf, np.inf, np.inf),
) -> tuple[Model, Data]:
    """The :class:`~tensegrity.physics.records.Model` and a
    :class:`~tensegrity.physics.records.Data` of a packed structure, with zeroed scratch.

    Parameters
    ----------
    rest : (K, S) array
        Rest lengths [m] per stage row, kernel order.
    rate : (K, S) array, optional
        Control rates [m/s], kernel order (None: no control rates).
    force : (K, 3, n_slots) array, optional
        External nodal forces [N] by slot (None: none).
    gravity : (3,) array, optional
        [m/s^2] (None: no gravity).
    tables : optional
        The engine's input tables (``tensegrity.engine.compiled.fill_stage_inputs``).
    callback : int, optional
        The handle of the Python function making the inputs
        (``tensegrity.engine.compiled.make_inputs``).
    limits : (3,) floats
        Max relative rod-length error, max constraint error [m], max energy growth.
    contacts : Contacts, optional
        Planes the rods' ends touch (:func:`tensegrity.physics.contact.pack_contacts`).
    """
    packed = system.packed
    n_slots, n_tendons = packed.layout.n_slots, packed.tendon_slots.shape[0]
    model = Model(
        rod_slots=packed.rod_slots,
        rod_param=packed.rod_param,
        tendon_slots=packed.tendon_slots,
        tendon_runs=packed.tendon_runs,
        tendon_stiffness=packed.tendon_stiffness,
        tendon_damping=packed.tendon_damping,
        constraints=system.constraints,
        has_gravity=gravity is not None,
        gravity=np.zeros(3) if gravity is None else np.array(gravity, dtype=np.float64),
        tables=tables,
        callback=None if callback is None else np.int64(callback),
        limits=np.array(limits, dtype=np.float64),
        contacts=contacts,
    )
    constraint_work = None
    if system.constraints is not None:
        k_size, n_size, n_vectors = system.work_sizes
        constraint_work = ConstraintWork(
            k_values=np.zeros(k_size),
            k_factor=np.zeros(k_size),
            n_values=np.zeros(n_size),
            n_factor=np.zeros(n_size),
            vectors=np.zeros((4, n_vectors)),
        )
    data = Data(
        rest=rest,
        rate=np.zeros((1, 1)) if rate is None else rate,
        has_rate=rate is not None,
        force=np.zeros((1, 3, 1)) if force is None else force,
        has_external=force is not None,
        node_position=np.zeros((3, n_slots)),
        node_velocity=np.zeros((3, n_slots)),
        node_force=np.zeros((3, n_slots)),
        tension=np.zeros(n_tendons),
        elastic_tension=np.zeros(n_tendons),
        damping_power=np.zeros(n_tendons),
        constraint_work=constraint_work,
        monitor=np.array([np.nan, 0.0, 0.0, 0.0]),
        contact_work=None if contacts is None else contact_work(contacts),
    )
    return model, data


# --------------------------------------------------------------------------- compiled: nodes
@compiled_only
def _extra_nodes(constraints, q, qdot, n_rods, p, v, with_velocity):  # pragma: no cover
    """Point-mass positions ``x`` (from ``q`` after the rods' ``6R``) and anchor positions into
    ``p`` (3, n_slots) [m]; with ``with_velocity`` the point-mass velocities and zero (anchors)
    into ``v`` [m/s].  Nothing when ``constraints`` (``model.constraints``) is None."""
    if constraints is None:
        return
    mass_slots = constraints.mass_slots
    for k in range(mass_slots.shape[0]):
        s = mass_slots[k]
        o = 6 * n_rods + 3 * k
        for i in range(3):
            p[i, s] = q[o + i]
            if with_velocity:
                v[i, s] = qdot[o + i]
    anchor_slots = constraints.anchor_slots
    for k in range(anchor_slots.shape[0]):
        s = anchor_slots[k]
        for i in range(3):
            p[i, s] = constraints.anchor_position[i, k]
            if with_velocity:
                v[i, s] = 0.0


@njit(**JIT_OPTIONS)
def system_nodes(model, q, qdot, p, v, with_velocity):  # pragma: no cover - compiled
    """Node positions ``p = P q`` (eq. 18.26) of every slot holding a node (rod ends, point
    masses, anchors) into ``p`` (3, n_slots) [m], and with ``with_velocity`` the node
    velocities into ``v`` (anchors at rest) [m/s], as ``dynamics.nodes_from_coordinates``.
    Slots that hold no node are not written."""
    end_values(q, model.rod_slots, p)
    if with_velocity:
        end_values(qdot, model.rod_slots, v)
    _extra_nodes(model.constraints, q, qdot, model.rod_slots.shape[0], p, v, with_velocity)


# --------------------------------------------------------------------------- compiled: rows
@njit(inline="always", **JIT_OPTIONS)
def _entry_value(x, n_rods, body, sign, i):  # pragma: no cover - compiled
    """Coordinate ``i`` of the position (or rate) of an entry's node from ``x``: ``(x1 + sign
    x2) / 2`` on a rod (eq. 18.26), ``x`` itself on a point mass."""
    if body < n_rods:
        o = 6 * body
        return 0.5 * (x[o + i] + sign * x[o + 3 + i])
    return x[6 * n_rods + 3 * (body - n_rods) + i]


@compiled_only
def constraint_rows_times(x, n_rods, constraints, out):  # pragma: no cover - compiled
    """``out = A x`` (c,) for ``x`` = ``q``, ``q'`` or ``q''`` (``A = A_n P``), row by entry."""
    out[:] = 0.0
    start, rows = constraints.body_start, constraints.entry_row
    sign, coef = constraints.entry_sign, constraints.entry_coef
    for body in range(start.shape[0] - 1):
        for e in range(start[body], start[body + 1]):
            total = 0.0
            for i in range(3):
                total += coef[e, i] * _entry_value(x, n_rods, body, sign[e], i)
            out[rows[e]] += total


@compiled_only
def body_forces(constraints, multiplier, body, fa, fb):  # pragma: no cover - compiled
    """The forces ``A_n^T multiplier`` [N] on body ``body``'s nodes: at a rod's end a into
    ``fa`` and end b into ``fb`` (3,), at a point mass into ``fa``."""
    start, rows = constraints.body_start, constraints.entry_row
    sign, coef = constraints.entry_sign, constraints.entry_coef
    fa[:] = 0.0
    fb[:] = 0.0
    for e in range(start[body], start[body + 1]):
        lam = multiplier[rows[e]]
        for i in range(3):
            if sign[e] > 0.0:
                fb[i] += coef[e, i] * lam
            else:
                fa[i] += coef[e, i] * lam


@compiled_only
def add_constraint_response(
    q, multiplier, rod_param, constraints, qddot
):  # pragma: no cover - compiled
    """``qddot += G(q) A_n^T multiplier``: the constraint forces ``A_n^T lambda`` [N] applied by
    Theorem 18.1 (eqs. 18.17, 18.20: ``q1'' = (2/m)(f_a + f_b)``, ``q2'' = (6/(m L^2))
    skew(q2)^2 (f_a - f_b)``; ``x'' = f / m``); forces on anchors move nothing."""
    n_rods = rod_param.shape[0]
    fa = np.zeros(3)
    fb = np.zeros(3)
    for body in range(constraints.body_start.shape[0] - 1):
        body_forces(constraints, multiplier, body, fa, fb)
        if body < n_rods:
            o = 6 * body
            c1 = rod_param[body, ROD_C1]
            c2 = rod_param[body, ROD_C2]
            q2_dot_d = 0.0
            q2_sq = 0.0
            for i in range(3):
                q2_dot_d += q[o + 3 + i] * (fa[i] - fb[i])
                q2_sq += q[o + 3 + i] * q[o + 3 + i]
            for i in range(3):  # skew(q2)^2 d = q2 (q2 . d) - |q2|^2 d
                qddot[o + i] += c1 * (fa[i] + fb[i])
                qddot[o + 3 + i] += c2 * (q[o + 3 + i] * q2_dot_d - q2_sq * (fa[i] - fb[i]))
        else:
            o = 6 * n_rods + 3 * (body - n_rods)
            for i in range(3):
                qddot[o + i] += fa[i] / constraints.point_mass[body - n_rods]


# --------------------------------------------------------------------------- compiled: envelope
@njit(inline="always", **JIT_OPTIONS)
def _env_add(values, first, offset, i, j, value):  # pragma: no cover - compiled
    """``M[max(i, j), min(i, j)] += value`` in lower envelope storage."""
    if i < j:
        i, j = j, i
    values[offset[i] + j - first[i]] += value


@njit(**JIT_OPTIONS)
def _env_cholesky(values, factor, first, offset, delta):  # pragma: no cover - compiled
    """``L`` with ``L L^T = M + delta I`` into ``factor`` (envelope storage; fill-in stays in
    the envelope), each diagonal entry stored as its reciprocal ``1 / L_ii`` (multiplications
    instead of divisions, here and in :func:`_env_substitute`).  A non-positive pivot
    (round-off on an indefinite matrix) gives NaN."""
    for i in range(first.shape[0]):
        fi = first[i]
        oi = offset[i] - fi
        for j in range(fi, i + 1):
            fj = first[j]
            oj = offset[j] - fj
            s = values[oi + j]
            for k in range(max(fi, fj), j):
                s -= factor[oi + k] * factor[oj + k]
            if j < i:
                factor[oi + j] = s * factor[oj + j]
            else:
                s += delta
                factor[oi + i] = 1.0 / np.sqrt(s) if s > 0.0 else np.nan


@njit(**JIT_OPTIONS)
def _env_substitute(factor, first, offset, x):  # pragma: no cover - compiled
    """``x = (L L^T)^-1 x`` in place (forward then back substitution; ``factor`` from
    :func:`_env_cholesky`, reciprocal diagonal)."""
    n = first.shape[0]
    for i in range(n):
        oi = offset[i] - first[i]
        s = x[i]
        for k in range(first[i], i):
            s -= factor[oi + k] * x[k]
        x[i] = s * factor[oi + i]
    for i in range(n - 1, -1, -1):
        oi = offset[i] - first[i]
        x[i] = x[i] * factor[oi + i]
        for k in range(first[i], i):
            x[k] -= factor[oi + k] * x[i]


@njit(**JIT_OPTIONS)
def _env_residual(values, first, offset, x, rhs, out):  # pragma: no cover - compiled
    """``out = rhs - M x`` for the symmetric ``M`` stored as its lower envelope."""
    n = first.shape[0]
    copy_values(rhs, out, n)
    for i in range(n):
        oi = offset[i] - first[i]
        s = values[oi + i] * x[i]
        for k in range(first[i], i):
            s += values[oi + k] * x[k]
            out[k] -= values[oi + k] * x[i]
        out[i] -= s


@njit(**JIT_OPTIONS)
def solve_envelope_psd(
    values, factor, first, offset, rhs, x, scratch
):  # pragma: no cover - compiled
    """``x = M^-1 rhs`` for a symmetric positive semi-definite ``M`` (envelope storage), as
    :func:`tensegrity.physics.constraints.solve_psd`: factorize ``M + delta I`` (``delta =
    REGULARIZATION max(diag M)``) and refine twice against ``M``."""
    n = first.shape[0]
    largest = np.finfo(np.float64).tiny
    for i in range(n):
        d = values[offset[i + 1] - 1]
        if d > largest:
            largest = d
    _env_cholesky(values, factor, first, offset, REGULARIZATION * largest)
    copy_values(rhs, x, n)
    _env_substitute(factor, first, offset, x)
    for _ in range(2):
        _env_residual(values, first, offset, x, rhs, scratch)
        _env_substitute(factor, first, offset, scratch)
        for i in range(n):
            x[i] += scratch[i]


# --------------------------------------------------------------------------- compiled: dynamics
@compiled_only
def _assemble_coupling(model, data, q):  # pragma: no cover - compiled
    """``K = A G(q) A_n^T`` (c, c) into ``data.constraint_work.k_values``: rows ``i``, ``j``
    couple through
    each body both touch, by the node accelerations per unit node force (eqs. 18.17, 18.20,
    18.26): ``(1/m) I - (sigma_i sigma_j / 2) (6/(m L^2)) skew(q2)^2`` on a rod (``sigma`` = -1
    at end a, +1 at end b), ``I / m`` on a point mass."""
    constraints = model.constraints
    start, rows = constraints.body_start, constraints.entry_row
    sign, coef = constraints.entry_sign, constraints.entry_coef
    first, offset = constraints.k_first, constraints.k_offset
    values = data.constraint_work.k_values
    values[:] = 0.0
    rod_param = model.rod_param
    n_rods = rod_param.shape[0]
    for body in range(start.shape[0] - 1):
        x = y = z = q2_sq = half_c2 = 0.0
        if body < n_rods:
            o = 6 * body + 3
            x, y, z = q[o], q[o + 1], q[o + 2]
            q2_sq = x * x + y * y + z * z
            inv_m = 0.5 * rod_param[body, ROD_C1]
            half_c2 = 0.5 * rod_param[body, ROD_C2]
        else:
            inv_m = 1.0 / constraints.point_mass[body - n_rods]
        for e1 in range(start[body], start[body + 1]):
            c1q = coef[e1, 0] * x + coef[e1, 1] * y + coef[e1, 2] * z
            for e2 in range(e1, start[body + 1]):
                dot = (
                    coef[e1, 0] * coef[e2, 0]
                    + coef[e1, 1] * coef[e2, 1]
                    + coef[e1, 2] * coef[e2, 2]
                )
                c2q = coef[e2, 0] * x + coef[e2, 1] * y + coef[e2, 2] * z
                value = dot * inv_m - sign[e1] * sign[e2] * half_c2 * (c1q * c2q - q2_sq * dot)
                if e1 != e2 and rows[e1] == rows[e2]:
                    value *= 2.0  # (e1, e2) and (e2, e1) on the diagonal
                _env_add(values, first, offset, rows[e1], rows[e2], value)


@compiled_only
def _point_mass_pass(model, data, qdot, qddot, external_force):  # pragma: no cover - compiled
    """``x'' = (f + w) / m + g`` for every point mass from the tendon forces
    ``data.node_force``, which it leaves zero, as it leaves the anchors' (kernel.rhs's
    contract); ``external_force`` (3, n_slots) is the stage's row of ``data.force``.  Returns
    the power of ``w`` on the point masses [W]."""
    constraints = model.constraints
    has_external, has_gravity, gravity = data.has_external, model.has_gravity, model.gravity
    force = data.node_force
    n_rods = model.rod_slots.shape[0]
    power = 0.0
    for k in range(constraints.mass_slots.shape[0]):
        s = constraints.mass_slots[k]
        o = 6 * n_rods + 3 * k
        m = constraints.point_mass[k]
        for i in range(3):
            f = force[i, s]
            force[i, s] = 0.0
            if has_external:
                f += external_force[i, s]
                power += external_force[i, s] * qdot[o + i]
            qddot[o + i] = f / m
            if has_gravity:
                qddot[o + i] += gravity[i]
    for k in range(constraints.anchor_slots.shape[0]):
        for i in range(3):
            force[i, constraints.anchor_slots[k]] = 0.0
    return power


@compiled_only
def _constraint_pass(model, data, q, qddot):  # pragma: no cover - compiled
    """``qddot += G(q) A_n^T lambda`` with ``K lambda = -A qddot`` (``K = A G(q) A_n^T``): the
    joint and support forces that make ``A q'' = 0``, as ``LinearConstraints.constraint_force``."""
    constraints, work = model.constraints, data.constraint_work
    rod_param = model.rod_param
    c = constraints.constraint_rhs.shape[0]
    vectors = work.vectors
    rhs_, multiplier, scratch = vectors[0, :c], vectors[1, :c], vectors[2, :c]
    constraint_rows_times(qddot, rod_param.shape[0], constraints, rhs_)
    for i in range(c):
        rhs_[i] = -rhs_[i]
    _assemble_coupling(model, data, q)
    solve_envelope_psd(
        work.k_values,
        work.k_factor,
        constraints.k_first,
        constraints.k_offset,
        rhs_,
        multiplier,
        scratch,
    )
    add_constraint_response(q, multiplier, rod_param, constraints, qddot)


@njit(inline="always", **JIT_OPTIONS)
def system_rhs(model, data, s, q, qdot, qddot):  # pragma: no cover - compiled
    """Theorem 18.1 for any 3-D structure: fills ``qddot`` (6R + 3M,) [m/s^2],
    ``data.tension`` and ``data.elastic_tension`` (S,) [N] and, with tendon damping,
    ``data.damping_power`` (S,) [W] (tendons in kernel order), with row ``s`` of the inputs in
    ``data``; returns ``(dissipated_power, external_power)`` [W], as ``dynamics.evaluate``.

    With ``model.constraints`` None this is :func:`kernel.rhs`.  Otherwise point masses and
    anchors join the tendon pass, point masses accelerate as ``x'' = (f + w) / m + g``, and the
    joint and support forces are added (:func:`_constraint_pass`).
    """
    return _system_rhs(
        model.constraints, model.tendon_damping, model.tendon_max_tension, model.contacts, model,
        data, s, q, qdot, qddot,
    )  # fmt: skip


@compiled_only
def _system_rhs(
    constraints, tendon_damping, tendon_cap, contacts, model, data, s, q, qdot, qddot
):  # pragma: no cover - compiled
    """:func:`system_rhs`, with the optional parts ``constraints``, ``tendon_damping`` and
    ``contacts`` (``model.constraints``, ``model.tendon_damping``, ``model.contacts``)
    arguments, so that numba compiles a free class 1 structure (None) without the rest,
    undamped tendons without the rates, and a run without planes without contacts; the
    kernel's passes are inlined here (one call per evaluation takes the records).  Contacts
    come with structures without joints or supports only (``CompiledSystem`` refuses the
    rest: a sticking end is held by its own rod, ``contact.stick_pass``, a sticking point mass
    by itself, ``contact.mass_stick_pass``)."""
    if constraints is None:
        return rhs_passes(tendon_damping, tendon_cap, contacts, model, data, s, q, qdot, qddot)
    damped = tendon_damping is not None
    n_rods = model.rod_slots.shape[0]
    _extra_nodes(constraints, q, qdot, n_rods, data.node_position, data.node_velocity, damped)
    dissipated, external = rhs_passes(
        tendon_damping, tendon_cap, contacts, model, data, s, q, qdot, qddot
    )
    external += _point_mass_pass(model, data, qdot, qddot, stage_row(data.force, s))
    if contacts is not None:  # (the point masses' sticks, once they have their accelerations)
        dissipated += mass_stick_pass(contacts, data, qdot, qddot)
    if constraints.constraint_rhs.shape[0]:
        _constraint_pass(model, data, q, qddot)
    return dissipated, external


# --------------------------------------------------------------------------- compiled: drift
@njit(inline="always", **JIT_OPTIONS)
def _rod_error(q, rod_param):  # pragma: no cover - compiled
    """Largest ``| |q2| / L - 1 |`` over the rods; NaN if some ``q2`` is not finite."""
    worst = 0.0
    for r in range(rod_param.shape[0]):
        o = 6 * r + 3
        norm = np.sqrt(q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2])
        error = abs(norm / rod_param[r, ROD_LENGTH] - 1.0)
        if not np.isfinite(error):
            return np.nan
        worst = max(worst, error)
    return worst


@compiled_only
def _constraint_error(q, n_rods, constraints, residual):  # pragma: no cover - compiled
    """``residual = A q - b`` (c,) [m]; returns ``max |A q - b|`` (NaN if not finite)."""
    constraint_rows_times(q, n_rods, constraints, residual)
    worst = 0.0
    for i in range(residual.shape[0]):
        residual[i] -= constraints.constraint_rhs[i]
        error = abs(residual[i])
        if not np.isfinite(error):
            return np.nan
        worst = max(worst, error)
    return worst


@njit(inline="always", **JIT_OPTIONS)
def system_errors(model, data, q):  # pragma: no cover - compiled
    """``(rod_error, constraint_error)``: the largest relative rod-length error ``| |q2|/L - 1 |``
    (NaN if not finite) and ``max |A q - b|`` [m] (0 without joints and supports), as
    ``dynamics.rod_length_error`` and ``dynamics.constraint_error``."""
    return _errors(model.constraints, data.constraint_work, model.rod_param, q)


@compiled_only
def _errors(constraints, work, rod_param, q):  # pragma: no cover - compiled
    """:func:`system_errors` with the constraints and their scratch arguments."""
    rod_error = _rod_error(q, rod_param)
    if constraints is None or constraints.constraint_rhs.shape[0] == 0:
        return rod_error, 0.0
    c = constraints.constraint_rhs.shape[0]
    residual = work.vectors[0, :c]
    return rod_error, _constraint_error(q, rod_param.shape[0], constraints, residual)


#: The exponent bits of a float64: all set in an infinity or a NaN, and only there.
_EXPONENT_BITS = np.uint64(0x7FF0000000000000)


@njit(**JIT_OPTIONS)
def all_finite(x):  # pragma: no cover - compiled
    """Whether every element of the contiguous float64 vector ``x`` is finite.  A test of the
    exponent bits over the whole vector, with no early exit: a loop the compiler vectorizes
    (3x faster than ``np.isfinite`` element by element at (100,100), measured)."""
    bits = x.view(np.uint64)
    bad = False
    for i in range(bits.shape[0]):
        bad |= (bits[i] & _EXPONENT_BITS) == _EXPONENT_BITS
    return not bad


@compiled_only
def _violation(constraints, work, rod_param, q, out):  # pragma: no cover - compiled
    """``out`` (P,) = ``[A q - b; (|q2|^2 - L^2) / 2]`` in projection rows; returns the largest
    of ``|A q - b|`` and ``| |q2| - L |`` [m] (NaN if not finite)."""
    c = constraints.constraint_rhs.shape[0]
    residual = work.vectors[3, :c]
    error = _constraint_error(q, rod_param.shape[0], constraints, residual)
    for i in range(c):
        out[constraints.constraint_prow[i]] = residual[i]
    for r in range(rod_param.shape[0]):
        o = 6 * r + 3
        L = rod_param[r, ROD_LENGTH]
        q2_sq = q[o] * q[o] + q[o + 1] * q[o + 1] + q[o + 2] * q[o + 2]
        out[constraints.rod_prow[r]] = 0.5 * (q2_sq - L * L)
        gap = abs(np.sqrt(q2_sq) - L)
        error = max(error, gap) if np.isfinite(gap) else np.nan
    return error


@compiled_only
def _assemble_normal(constraints, work, rod_param, q):  # pragma: no cover - compiled
    """``J W^-1 J^T`` (P, P) into ``work.n_values``, ``J = [A; q2^T per rod]``
    (the gradient
    of ``|q2|^2 / 2``), ``W^-1`` = ``4/m`` on ``q1``, ``12/m`` on ``q2``, ``1/m`` on a point
    mass.  Two entries on a rod give ``(1 + 3 sigma_i sigma_j) (c_i . c_j) / m``, an entry and
    the rod's length row ``6 sigma (c . q2) / m``, the length row itself ``12 |q2|^2 / m``."""
    start, rows = constraints.body_start, constraints.entry_row
    sign, coef = constraints.entry_sign, constraints.entry_coef
    prow = constraints.constraint_prow
    first, offset = constraints.n_first, constraints.n_offset
    values = work.n_values
    values[:] = 0.0
    n_rods = rod_param.shape[0]
    for body in range(start.shape[0] - 1):
        x = y = z = 0.0
        own = 0
        if body < n_rods:
            o = 6 * body + 3
            x, y, z = q[o], q[o + 1], q[o + 2]
            inv_m = 1.0 / rod_param[body, ROD_MASS]
            own = constraints.rod_prow[body]
            _env_add(values, first, offset, own, own, 12.0 * inv_m * (x * x + y * y + z * z))
        else:
            inv_m = 1.0 / constraints.point_mass[body - n_rods]
        for e1 in range(start[body], start[body + 1]):
            if body < n_rods:
                c1q = coef[e1, 0] * x + coef[e1, 1] * y + coef[e1, 2] * z
                _env_add(values, first, offset, prow[rows[e1]], own, 6.0 * sign[e1] * c1q * inv_m)
            for e2 in range(e1, start[body + 1]):
                dot = (
                    coef[e1, 0] * coef[e2, 0]
                    + coef[e1, 1] * coef[e2, 1]
                    + coef[e1, 2] * coef[e2, 2]
                )
                value = (1.0 + 3.0 * sign[e1] * sign[e2]) * dot * inv_m
                if e1 != e2 and rows[e1] == rows[e2]:
                    value *= 2.0
                _env_add(values, first, offset, prow[rows[e1]], prow[rows[e2]], value)


@compiled_only
def _subtract_step(constraints, rod_param, target, q, y):  # pragma: no cover - compiled
    """``target -= W^-1 J(q)^T y`` (``y`` in projection rows): per rod ``q1 -= (2/m) sum c
    y``, ``q2 -= (6/m) sum sigma c y + (12/m) q2 y_length``; per point mass ``x -= sum c y / m``.
    ``target`` may be ``q`` itself (each rod's ``q2`` is read before it is written)."""
    start, rows = constraints.body_start, constraints.entry_row
    sign, coef = constraints.entry_sign, constraints.entry_coef
    prow = constraints.constraint_prow
    n_rods = rod_param.shape[0]
    d1 = np.zeros(3)
    d2 = np.zeros(3)
    for body in range(start.shape[0] - 1):
        d1[:] = 0.0
        d2[:] = 0.0
        for e in range(start[body], start[body + 1]):
            lam = y[prow[rows[e]]]
            for i in range(3):
                d1[i] += coef[e, i] * lam
                d2[i] += sign[e] * coef[e, i] * lam
        if body < n_rods:
            o = 6 * body
            m = rod_param[body, ROD_MASS]
            length_y = y[constraints.rod_prow[body]]
            for i in range(3):
                step2 = (6.0 / m) * d2[i] + (12.0 / m) * q[o + 3 + i] * length_y
                target[o + i] -= (2.0 / m) * d1[i]
                target[o + 3 + i] -= step2
        else:
            o = 6 * n_rods + 3 * (body - n_rods)
            for i in range(3):
                target[o + i] -= d1[i] / constraints.point_mass[body - n_rods]


@compiled_only
def _normal_solve(constraints, work, rod_param, q, violation, y):  # pragma: no cover - compiled
    """``y = (J W^-1 J^T)^-1 violation`` at ``q``."""
    _assemble_normal(constraints, work, rod_param, q)
    work = work
    solve_envelope_psd(
        work.n_values,
        work.n_factor,
        constraints.n_first,
        constraints.n_offset,
        violation,
        y,
        work.vectors[2],
    )


@compiled_only
def _project_constrained(constraints, work, rod_param, q, qdot):  # pragma: no cover - compiled
    """``LinearConstraints.project`` in place: Gauss-Newton steps ``q -= W^-1 J^T (J W^-1
    J^T)^-1 c(q)`` until every error is below ``PROJECTION_RTOL`` times the length scale, or below
    ``PROJECTION_FLOOR_RTOL`` times it once the error stops halving; then ``q' -= W^-1 J^T
    (J W^-1 J^T)^-1 J q'``.  Returns False if it does not converge in :data:`MAX_ITER` steps."""
    vectors = work.vectors
    n_rods = rod_param.shape[0]
    scale = 1.0
    for r in range(n_rods):
        scale = max(scale, rod_param[r, ROD_LENGTH])
    tol = PROJECTION_RTOL * scale
    floor = PROJECTION_FLOOR_RTOL * scale
    n = constraints.n_first.shape[0]
    violation, y = vectors[0, :n], vectors[1, :n]
    previous = np.inf
    converged = False
    for _ in range(MAX_ITER):
        error = _violation(constraints, work, rod_param, q, violation)
        if not np.isfinite(error):
            return False
        if error <= tol or (error <= floor and error > 0.5 * previous):
            converged = True
            break
        previous = error
        _normal_solve(constraints, work, rod_param, q, violation, y)
        _subtract_step(constraints, rod_param, q, q, y)
    if not converged:
        return False
    c = constraints.constraint_rhs.shape[0]
    rates = vectors[3, :c]
    constraint_rows_times(qdot, n_rods, constraints, rates)
    for i in range(c):
        violation[constraints.constraint_prow[i]] = rates[i]
    for r in range(n_rods):
        o = 6 * r + 3
        violation[constraints.rod_prow[r]] = (
            q[o] * qdot[o] + q[o + 1] * qdot[o + 1] + q[o + 2] * qdot[o + 2]
        )
    _normal_solve(constraints, work, rod_param, q, violation, y)
    _subtract_step(constraints, rod_param, qdot, q, y)
    return all_finite(q) and all_finite(qdot)


@njit(inline="always", **JIT_OPTIONS)
def system_project(model, data, q, qdot):  # pragma: no cover - compiled
    """Project ``(q, q')`` in place onto the rod constraints ``|q2| = L``, ``q2 . q2' = 0`` and
    the joints and supports ``A q = b``, ``A q' = 0``, as ``dynamics.project_to_constraints``.

    Without joints and supports this is :func:`kernel.project` (point masses unchanged); with
    them the mass-weighted Gauss-Newton projection of ``LinearConstraints.project``
    (:func:`_project_constrained`).  Returns ``(rod_error, constraint_error, ok)`` before the
    projection: the largest relative rod-length error (NaN if the state is not finite), ``max
    |A q - b|`` [m], and False if the state is not finite or the projection did not converge (then
    ``q``, ``q'`` hold whatever the last step left).
    """
    return _project(model.constraints, data.constraint_work, model.rod_param, q, qdot)


@compiled_only
def _project(constraints, work, rod_param, q, qdot):  # pragma: no cover - compiled
    """:func:`system_project` with ``constraints`` (``constraints``) an argument."""
    if constraints is None:
        error = project(q, qdot, rod_param)
        finite = all_finite(q) and all_finite(qdot)
        return (error if finite else np.nan), 0.0, finite
    finite = all_finite(q) and all_finite(qdot)
    if constraints.constraint_rhs.shape[0] == 0:
        error = project(q, qdot, rod_param)
        return (error if finite else np.nan), 0.0, finite
    rod_error, constraint_error = _errors(constraints, work, rod_param, q)
    if not finite:
        return np.nan, constraint_error, False
    return rod_error, constraint_error, _project_constrained(constraints, work, rod_param, q, qdot)


# --------------------------------------------------------------------------- compiled: energy
@njit(inline="always", **JIT_OPTIONS)
def system_energies(model, data, rest, q, qdot):  # pragma: no cover - compiled
    """``(kinetic, elastic, gravity)`` energies [J], as ``dynamics.kinetic_energy``,
    ``elastic_energy`` and ``gravity_energy``, with the rest lengths ``rest`` (S,) [m]:
    :func:`kernel.energies` (which it is, with ``model.constraints`` None) plus ``m |x'|^2 / 2``
    and ``-m g . x`` per point mass, anchors and point masses taking part in the tendons'
    energy.  ``data.node_position`` receives the node positions."""
    return _energies(model.constraints, model.contacts, model, data, rest, q, qdot)


@compiled_only
def _energies(constraints, contacts, model, data, rest, q, qdot):  # pragma: no cover - compiled
    """:func:`system_energies` with ``constraints`` and ``contacts`` (``model.constraints``,
    ``model.contacts``) arguments; the contacts' springs are elastic energy."""
    if constraints is None:
        kinetic, elastic, potential = energies(model, data, rest, q, qdot)
        if contacts is not None:
            elastic += contact_energy(contacts, q)
        return kinetic, elastic, potential
    n_rods = model.rod_slots.shape[0]
    _extra_nodes(constraints, q, qdot, n_rods, data.node_position, data.node_velocity, False)
    kinetic, elastic, potential = energies(model, data, rest, q, qdot)
    if contacts is not None:
        elastic += contact_energy(contacts, q)
    gravity = model.gravity
    for k in range(constraints.point_mass.shape[0]):
        o = 6 * n_rods + 3 * k
        m = constraints.point_mass[k]
        speed_sq = qdot[o] * qdot[o] + qdot[o + 1] * qdot[o + 1] + qdot[o + 2] * qdot[o + 2]
        kinetic += 0.5 * m * speed_sq
        if model.has_gravity:
            potential -= m * (q[o] * gravity[0] + q[o + 1] * gravity[1] + q[o + 2] * gravity[2])
    return kinetic, elastic, potential
