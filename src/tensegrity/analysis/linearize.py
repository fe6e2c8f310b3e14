"""Linearization of Theorem 18.1 about an equilibrium, in coordinates that respect the rods.

State ``z = [x, x']`` (10R,): the reduced coordinates ``x`` of :class:`Chart` (per rod the
centre displacement ``dc`` [m] and two angles ``phi`` [rad]) based at the equilibrium, and
their rates.  With the diagonal mass matrix ``M`` (``m`` and ``m L^2 / 12``), the tangent
stiffness ``K = -dQ/dx`` (tendons' material and geometric stiffness plus the rods' geometric
term; symmetric at an equilibrium), the damping ``C`` (taut tendons' ``c t t^T`` plus the rods'
mass-proportional ``alpha M``)::

    z' = A z + B du + D dw,   A = [[0, I], [-M^-1 K, -M^-1 C]],
                              B = [[0], [M^-1 dQ/du]],  D = [[0], [M^-1 J^T]]
    y  = C z + F du           (node positions, tendon lengths, tensions)

``u`` is the rest-length change of every tendon [m] (``Lbar = L0 - u``; a taut tendon's tension
grows by ``k du``), ``w`` the nodal forces [N] (the paper's ``B(q)``, ``D(q)`` of eq. 18.59).
Only taut tendons enter (a slack one has no stiffness, no damping and no control authority);
tendons exactly at their rest length count as taut with zero tension (``include_threshold``).

Point masses add their displacements (3 each) to ``x``.  With joints and supports
(``g(x) = A q(x) - b = 0``, tangent ``G``, :class:`Chart`) the state is ``z = [eta, eta']`` in the
admitted motions ``x = Z eta``, ``Z`` an ``M``-orthonormal basis of ``null(G)``
(:meth:`Chart.admitted_motions`), and every matrix above is restricted to it (``Z^T K Z``,
``Z^T C Z``, ``Z^T dQ/du``, ``Z^T J^T``, ``J Z``; ``M`` becomes ``I``).  ``K`` is then the
Hessian of the Lagrangian: the reactions ``f_c = A_n^T lambda`` at the equilibrium enter the
rods' geometric term as nodal forces do (that is the curvature of the constraint manifold; e.g.
it gives a pinned rod its pendulum stiffness ``m g L / 2``).  The reactions' changes are normal
to ``null(G)`` and drop out.  A planar structure is linearized as its 3-D form
(:func:`~tensegrity.analysis.coordinates.spatial`): positions and forces in 3-D, motion in
``z = 0``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from tensegrity.analysis.coordinates import (
    Chart,
    admitted_rigid_motions,
    drop_roundoff,
    has_supports,
    mass_complement,
    mass_matrix,
    planar_coordinates,
    rigid_body_basis,
    spatial,
    spatial_coordinates,
    spatial_vector,
)
from tensegrity.analysis.equilibrium import EquilibriumResult, make_result
from tensegrity.analysis.statics import (
    Statics,
    TendonState,
    equilibrium_matrix,
    force_jacobian,
    node_stiffness,
    statics,
    with_reactions,
)
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics
from tensegrity.physics.coordinates import rod_damping_rates

#: Output groups of :class:`Linearization`, in the order of ``C``'s rows.
OUTPUT_GROUPS = ("position", "length", "tension")
_AXES = "xyz"
_ROD_COORDS = ("cx", "cy", "cz", "phi1", "phi2")


@dataclasses.dataclass(frozen=True, eq=False)
class Linearization:
    """The linearized model about an equilibrium (see the module docstring).

    Sizes below for a free class 1 structure (``k = 5R`` coordinates); in general ``k`` is
    ``5R + 3M`` or, with joints and supports, the number of admitted motions ``dim null(G)``.

    Attributes
    ----------
    structure, equilibrium : the structure (3-D) and the :class:`EquilibriumResult` linearized
        about.  source : the structure as given (planar if it was: ``structure`` is then its
        3-D form).
    chart : the reduced coordinates, based at the equilibrium.
    basis : ``Z`` (5R + 3M, k), ``M``-orthonormal basis of the admitted motions (``x = Z eta``),
        or None without joints and supports (then ``eta = x``).
    mass : (k,) diagonal of ``M`` (``Z^T M Z = I`` with joints and supports).
    stiffness : ``K`` (k, k).  damping : ``C`` (k, k).
    force_input : ``dQ/du`` (k, S) [N/m].  equilibrium_matrix : (k, S), ``Q = A_eq T``.
    position_jacobian : ``dp/deta`` (3N, k).
    A : (2k, 2k).  B : (2k, S).  D : (2k, 3N).  C : (3N + 2S, 2k).  F : (3N + 2S, S).
    taut : (S,) bool, tendons that act in the linearization.
    state_names (``rod{r}_cx`` ... ``rod{r}_phi2``, ``mass{i}_x``..., then the same with ``_dot``;
    ``eta{j}`` with joints and supports), input_names (the tendon names), disturbance_names
    (``w{i}_x``...), output_names (``p{i}_x``..., ``length_{tendon}``, ``tension_{tendon}``).
    rigid_basis : (k, r) the rigid-body motions the supports admit (6 for a free structure),
        ``M``-orthonormal.
    """

    structure: Structure
    equilibrium: EquilibriumResult
    chart: Chart
    mass: np.ndarray
    stiffness: np.ndarray
    damping: np.ndarray
    force_input: np.ndarray
    equilibrium_matrix: np.ndarray
    A: np.ndarray
    B: np.ndarray
    D: np.ndarray
    C: np.ndarray
    F: np.ndarray
    taut: np.ndarray
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    disturbance_names: tuple[str, ...]
    output_names: tuple[str, ...]
    rigid_basis: np.ndarray
    source: Structure
    basis: np.ndarray | None
    position_jacobian: np.ndarray

    @property
    def n_dof(self) -> int:
        """``k``: ``5 R`` for a free class 1 structure."""
        return self.mass.size

    def __repr__(self) -> str:
        """One short line whatever the size: the degrees of freedom, the shapes of ``A``, ``B``
        and ``C``, the taut tendons and the structure (its ``repr``)."""
        return (
            f"<Linearization: {self.n_dof} degrees of freedom, A {self.A.shape}, B "
            f"{self.B.shape}, C {self.C.shape}, {int(np.count_nonzero(self.taut))} of "
            f"{self.taut.size} tendons taut, {self.source!r}>"
        )

    @property
    def aligned(self) -> bool:
        """True if the structure is free of supports: deformations are then measured after a
        rigid alignment (:func:`~tensegrity.analysis.coordinates.deformation`)."""
        return not has_supports(self.source)

    def to_eta(self, x: np.ndarray) -> np.ndarray:
        """Reduced coordinates ``eta = Z^T M x`` (..., k) of chart coordinates ``x`` (..., n)
        (``x`` itself without joints and supports)."""
        if self.basis is None:
            return x
        return (x * mass_matrix(self.structure)) @ self.basis

    def to_x(self, eta: np.ndarray) -> np.ndarray:
        """Chart coordinates ``x = Z eta`` (n,) of reduced ones."""
        return eta if self.basis is None else self.basis @ eta

    def elastic_part(self) -> tuple[np.ndarray, np.ndarray]:
        """``(A_e, Z)``: the state matrix (2k, 2k) of the non-rigid part in coordinates
        ``[eta, eta']`` with ``x = Z eta``, ``Z`` (5R, k) the ``M``-orthonormal complement of the
        rigid-body motions (``Z^T M Z = I``): ``A_e = [[0, I], [-Z^T K Z, -Z^T C Z]]``."""
        Z = mass_complement(self.rigid_basis, self.mass)
        n = Z.shape[1]
        A = np.block(
            [
                [np.zeros((n, n)), np.eye(n)],
                [-(Z.T @ self.stiffness @ Z), -(Z.T @ self.damping @ Z)],
            ]
        )
        return A, Z

    def output_indices(self, outputs: str | Sequence[str] | None) -> np.ndarray:
        """Row indices of ``C`` for output group names (``"position"``, ``"length"``,
        ``"tension"``), output names, or None (all)."""
        if outputs is None:
            return np.arange(len(self.output_names))
        if isinstance(outputs, str):
            outputs = [outputs]
        s = self.structure
        sizes = {"position": 3 * s.n_nodes, "length": s.n_tendons, "tension": s.n_tendons}
        starts = np.cumsum([0] + [sizes[g] for g in OUTPUT_GROUPS])
        lookup = {name: k for k, name in enumerate(self.output_names)}
        rows: list[int] = []
        for item in outputs:
            if item in sizes:
                g = OUTPUT_GROUPS.index(item)
                rows.extend(range(starts[g], starts[g + 1]))
            elif item in lookup:
                rows.append(lookup[item])
            else:
                raise KeyError(f"no output or output group named {item!r}")
        return np.array(rows, dtype=int)

    def input_indices(self, inputs: Sequence[str] | None) -> np.ndarray:
        """Column indices of ``B`` for tendon names (or None: all tendons)."""
        if inputs is None:
            return np.arange(self.structure.n_tendons)
        return np.array([self.structure.tendon_index(name) for name in inputs], dtype=int)

    def statespace(
        self,
        inputs: Sequence[str] | None = None,
        outputs: str | Sequence[str] | None = None,
        *,
        disturbances: bool = False,
    ):
        """A named ``control.StateSpace``: inputs are rest-length changes of the tendons named
        (default all), then the nodal forces if ``disturbances``; outputs as
        :meth:`output_indices`."""
        import control

        cols = self.input_indices(inputs)
        rows = self.output_indices(outputs)
        B, F = self.B[:, cols], self.F[np.ix_(rows, cols)]
        names = [_signal(self.input_names[c]) for c in cols]
        if disturbances:
            B = np.hstack([B, self.D])
            F = np.hstack([F, np.zeros((rows.size, self.D.shape[1]))])
            names += list(self.disturbance_names)
        return control.ss(
            self.A,
            B,
            self.C[rows],
            F,
            inputs=names,
            outputs=[_signal(self.output_names[r]) for r in rows],
            states=list(self.state_names),
        )

    def state(self, q: np.ndarray, qdot: np.ndarray | None = None) -> np.ndarray:
        """The linear state ``z = [x, x']`` (10R,) of a nonlinear state ``(q, q')``: ``x`` exact
        (chart inverse), ``x'`` to first order."""
        x = self.to_eta(self.chart.x(q))
        v = np.zeros_like(x) if qdot is None else self.to_eta(self.chart.velocity_x(q, qdot))
        return np.concatenate([x, v])

    def configuration(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(q, q')`` of a linear state ``z``: ``q`` exact on the rod constraints (and projected
        onto the joints and supports), ``q'`` the first-order map at the equilibrium (projected
        onto the velocity constraints)."""
        n = self.n_dof
        q = self.chart.q(self.to_x(z[:n]))
        qdot = self.chart.velocity_q(self.to_x(z[n:]))
        return dynamics.project_to_constraints(self.structure, q, qdot)


def _signal(name: str) -> str:
    """A python-control signal name (no '.' allowed there)."""
    return name.replace(".", "_")


def linearize(
    structure: Structure,
    equilibrium: EquilibriumResult | np.ndarray | None = None,
    *,
    control: np.ndarray | None = None,
    include_threshold: bool = True,
) -> Linearization:
    """Linearize about an equilibrium (an :class:`EquilibriumResult`, or its ``q``).

    ``control`` (with a bare ``q``) is the rest-length change ``u`` of the equilibrium.  The
    structure's own damping enters ``C``; pass ``internal_damping(structure)`` (or
    ``artificial_damping``) for a damped model.  External forces and gravity of an
    :class:`EquilibriumResult` are taken into account.  A planar structure is linearized as its
    3-D form (``equilibrium`` in 2-D).
    """
    eq = _spatial_equilibrium(structure, equilibrium, control)
    s = eq.structure
    chart = Chart.at(s, eq.q)
    x0 = np.zeros(chart.size)
    st = statics(chart, x0, eq.rest_length, eq.external_force, eq.gravity)
    st = with_reactions(chart, st)  # the reactions' share of the rods' geometric stiffness
    tendons = st.tendons
    active = tendons.taut | (tendons.at_threshold & include_threshold)
    J = chart.jacobian_matrix(x0)
    K = _tangent_stiffness(chart, st, J, include_threshold)
    mass = mass_matrix(s)
    damping = _damping_matrix(chart, tendons._replace(taut=active), J, mass)
    A_eq = equilibrium_matrix(chart, tendons.direction, x0)
    Z = chart.admitted_motions()
    rigid = admitted_rigid_motions(chart, Z)
    if Z is not None:  # restrict to the admitted motions x = Z eta (Z^T M Z = I)
        mass = np.einsum("ik,i,ik->k", Z, mass, Z)
        K, damping = Z.T @ K @ Z, Z.T @ damping @ Z
        A_eq, J = drop_roundoff(Z.T @ A_eq), drop_roundoff(J @ Z)
        rigid = _unloaded(rigid, K, mass)
    k_eff = np.where(active, s.tendon_stiffness, 0.0)
    c_eff = np.where(active, s.tendon_damping, 0.0)
    force_input = A_eq * k_eff
    A, B, D = _state_equation(mass, K, damping, force_input, J)
    C, F = _output_equation(J, A_eq, k_eff, c_eff)
    return Linearization(
        structure=s,
        equilibrium=eq,
        chart=chart,
        mass=mass,
        stiffness=K,
        damping=damping,
        force_input=force_input,
        equilibrium_matrix=A_eq,
        A=A,
        B=B,
        D=D,
        C=C,
        F=F,
        taut=active,
        state_names=_state_names(s, mass.size, restricted=Z is not None),
        input_names=tuple(s.tendon_name),
        disturbance_names=tuple(f"w{i}_{a}" for i in range(s.n_nodes) for a in _AXES),
        output_names=_output_names(s),
        rigid_basis=rigid,
        source=structure,
        basis=Z,
        position_jacobian=J,
    )


def _spatial_equilibrium(
    structure: Structure,
    equilibrium: EquilibriumResult | np.ndarray | None,
    control: np.ndarray | None,
) -> EquilibriumResult:
    """The equilibrium :func:`linearize` is given, as a result of the 3-D form of ``structure``
    (:func:`~tensegrity.analysis.coordinates.spatial`; the structure itself if not planar).

    ``equilibrium`` is a result (of ``structure``, or of another structure with the same
    coordinates), its ``q`` (default the structure's node positions) with the rest-length
    change ``control`` (S,) [m], or None.
    """
    if isinstance(equilibrium, EquilibriumResult):
        eq = equilibrium
        if eq.structure is not structure or structure.dim == 2:
            eq = make_result(
                spatial(structure),
                spatial_coordinates(structure, eq.q),
                eq.control,
                external_force=spatial_vector(structure, eq.external_force),
                gravity=spatial_vector(structure, eq.gravity),
                converged=eq.converged,
                method=eq.method,
                message=eq.message,
                nfev=eq.nfev,
            )
        return eq
    q = (
        dynamics.coordinates_from_nodes(structure, structure.node_position)
        if equilibrium is None
        else np.asarray(equilibrium, dtype=float)
    )
    return make_result(
        spatial(structure),
        spatial_coordinates(structure, q),
        control,
        converged=True,
        method="given",
        message="given configuration",
        nfev=0,
    )


def _tangent_stiffness(
    chart: Chart, st: Statics, J: np.ndarray, include_threshold: bool
) -> np.ndarray:
    """``K = -dQ/dx`` (n, n), symmetrized, at the chart's base (``st`` its statics, reactions
    included; ``J = dp/dx`` (3N, n)); with ``include_threshold``, tendons exactly at their rest
    length add their material stiffness."""
    x0 = np.zeros(chart.size)
    K = -force_jacobian(chart, x0, st)
    tendons = st.tendons
    if include_threshold and np.any(tendons.at_threshold):
        K_thr = node_stiffness(
            chart.structure,
            tendons._replace(taut=np.zeros_like(tendons.taut)),
            include_threshold=True,
        )
        K = K + J.T @ K_thr @ J
    return 0.5 * (K + K.T)


def _damping_matrix(
    chart: Chart, tendons: TendonState, J: np.ndarray, mass: np.ndarray
) -> np.ndarray:
    """``C`` (n, n): the damping of the tendons flagged taut in ``tendons`` (``c t t^T`` through
    ``J = dp/dx`` (3N, n)), the rods' mass-proportional damping to ground ``alpha M`` (``mass``
    (n,)) and relative to the rigid-body motion ``D - D Phi (Phi^T D Phi)^+ Phi^T D``, ``D =
    beta M`` and ``Phi`` the rigid-body motions (:func:`rigid_body_basis`): the force ``-beta M
    (x' - rigid)`` of :func:`tensegrity.physics.coordinates.rod_damping_acceleration`, whose
    rigid fit is linear in ``x'`` (its change with ``x`` multiplies ``x' = 0``)."""
    s = chart.structure
    C_node = node_stiffness(s, tendons, include_threshold=False, damping=True)
    alpha, beta = rod_damping_rates(s)
    per_rod = np.zeros(mass.size - 5 * s.n_rods)
    C = J.T @ C_node @ J + np.diag(np.concatenate([np.repeat(alpha, 5), per_rod]) * mass)
    if np.any(beta):
        D = np.concatenate([np.repeat(beta, 5), per_rod]) * mass
        Phi = rigid_body_basis(chart)
        D_Phi = D[:, None] * Phi
        fit = D_Phi @ np.linalg.pinv(Phi.T @ D_Phi, rcond=1e-12) @ D_Phi.T
        C = C + np.diag(D) - 0.5 * (fit + fit.T)
    return C


def _state_equation(
    mass: np.ndarray, K: np.ndarray, damping: np.ndarray, force_input: np.ndarray, J: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(A, B, D)`` of ``z' = A z + B du + D dw``: (2k, 2k), (2k, S), (2k, 3N), from the mass
    diagonal (k,), ``K`` and ``C`` (k, k), ``dQ/du`` (k, S) and ``J = dp/deta`` (3N, k)."""
    n = mass.size
    inv_m = 1.0 / mass
    A = np.zeros((2 * n, 2 * n))
    A[:n, n:] = np.eye(n)
    A[n:, :n] = -inv_m[:, None] * K
    A[n:, n:] = -inv_m[:, None] * damping
    B = np.vstack([np.zeros((n, force_input.shape[1])), inv_m[:, None] * force_input])
    D = np.vstack([np.zeros((n, J.shape[0])), inv_m[:, None] * J.T])
    return A, B, D


def _output_equation(
    J: np.ndarray, A_eq: np.ndarray, k_eff: np.ndarray, c_eff: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``(C, F)`` of ``y = C z + F du`` (node positions, tendon lengths, tensions): (3N + 2S, 2k)
    and (3N + 2S, S), from ``J = dp/deta`` (3N, k), ``A_eq`` (k, S) and the taut tendons'
    stiffness and damping (S,) [N/m, N s/m] (0 for slack ones)."""
    n_tendons, n = k_eff.size, J.shape[1]
    zeros = np.zeros((n_tendons, n))
    C = np.vstack(
        [
            np.hstack([J, np.zeros_like(J)]),
            np.hstack([-A_eq.T, zeros]),
            np.hstack([-(k_eff[:, None] * A_eq.T), -(c_eff[:, None] * A_eq.T)]),
        ]
    )
    F = np.vstack(
        [np.zeros((J.shape[0], n_tendons)), np.zeros((n_tendons, n_tendons)), np.diag(k_eff)]
    )
    return C, F


def _state_names(structure: Structure, n_dof: int, *, restricted: bool) -> tuple[str, ...]:
    """``rod{r}_cx`` ... ``rod{r}_phi2``, ``mass{i}_x``... (``eta{j}`` if ``restricted`` to the
    admitted motions), then the same with ``_dot``."""
    s = structure
    if restricted:
        states = [f"eta{j}" for j in range(n_dof)]
    else:
        states = [f"rod{r}_{c}" for r in range(s.n_rods) for c in _ROD_COORDS] + [
            f"mass{i}_{a}" for i in s.point_mass_nodes for a in _AXES
        ]
    return tuple(states + [f"{name}_dot" for name in states])


def _output_names(structure: Structure) -> tuple[str, ...]:
    """``p{i}_x``..., ``length_{tendon}``..., ``tension_{tendon}``..."""
    names = structure.tendon_name
    return tuple(
        [f"p{i}_{a}" for i in range(structure.n_nodes) for a in _AXES]
        + [f"length_{name}" for name in names]
        + [f"tension_{name}" for name in names]
    )


def _unloaded(rigid: np.ndarray, K: np.ndarray, mass: np.ndarray, rtol: float = 1e-8) -> np.ndarray:
    """The admitted rigid-body motions (columns of ``rigid``, ``M``-orthonormal) that the loads
    leave without stiffness (``omega^2`` below ``rtol`` times the largest of ``K``): a rod pinned
    at one end turns freely about the pivot without gravity, but swings as a pendulum with it."""
    if not rigid.size:
        return rigid
    root = np.sqrt(mass)
    largest = float(
        np.max(np.abs(np.linalg.eigvalsh(K / root[:, None] / root[None, :])), initial=0.0)
    )
    value, vector = np.linalg.eigh(rigid.T @ K @ rigid)
    return rigid @ vector[:, np.abs(value) <= rtol * largest]


def finite_difference_check(lin: Linearization, h: float = 1e-6) -> dict[str, float]:
    """Largest relative differences between the analytic ``A``, ``B``, ``D``, ``C``, ``F`` blocks
    and central differences of the nonlinear model (Theorem 18.1 accelerations and the outputs),
    at the equilibrium: a check that the linearization is the derivative of the simulated
    dynamics.  ``h`` is the step in every state, input [m] and nodal force [N].

    With joints and supports a perturbed state is put back onto them
    (:meth:`Linearization.configuration`: mass-weighted projection, a second-order change) and
    the accelerations are the dynamics' own constrained ones (constraint forces solved as in a
    simulation); a planar structure's accelerations are those of the planar (2-D) model.
    """
    s, eq, source = lin.structure, lin.equilibrium, lin.source
    n = lin.n_dof
    w0 = np.zeros((s.n_nodes, 3)) if eq.external_force is None else eq.external_force

    def accel(z: np.ndarray, u: np.ndarray, dw: np.ndarray | None = None) -> np.ndarray:
        q, qdot = lin.configuration(z)
        w = w0 if dw is None else w0 + dw.reshape(w0.shape)
        if source.dim == 2:  # the planar model itself
            qddot = dynamics.accelerations(
                source,
                planar_coordinates(source, q),
                planar_coordinates(source, qdot, rates=True),
                control=u,
                external_force=w[:, :2],
                gravity=None if eq.gravity is None else eq.gravity[:2],
            )
            qddot = spatial_coordinates(source, qddot, rates=True)
        else:
            qddot = dynamics.accelerations(
                s, q, qdot, control=u, external_force=w, gravity=eq.gravity
            )
        # x'' = (dc'', E^T q2''/L) at the base (the chart's second derivative vanishes at z = 0
        # for velocity-free perturbations, and is second order in the velocity otherwise)
        return lin.to_eta(lin.chart.velocity_x(q, qddot))

    def outputs(z: np.ndarray, u: np.ndarray) -> np.ndarray:
        q, qdot = lin.configuration(z)
        p = dynamics.nodes_from_coordinates(s, q)
        v = dynamics.nodes_from_coordinates(s, qdot, rates=True)
        forces = dynamics.tendon_forces(s, p, v, dynamics.rest_lengths(s, u))
        return np.concatenate(
            [(p - eq.node_position).ravel(), forces.length - eq.tendon_length, forces.tension]
        )

    def central(f, size: int) -> np.ndarray:
        """Columns ``(f(h e_j) - f(-h e_j)) / 2h`` for the unit vectors of length ``size``."""
        if not size:
            return np.zeros((f(np.zeros(0)).size, 0))
        return np.column_stack([(f(h * e) - f(-h * e)) / (2 * h) for e in np.eye(size)])

    z0, u0 = np.zeros(2 * n), eq.control
    A_fd = central(lambda dz: accel(z0 + dz, u0), 2 * n)
    B_fd = central(lambda du: accel(z0, u0 + du), s.n_tendons)
    D_fd = central(lambda dw: accel(z0, u0, dw), 3 * s.n_nodes)
    C_fd = central(lambda dz: outputs(z0 + dz, u0), 2 * n)
    F_fd = central(lambda du: outputs(z0, u0 + du), s.n_tendons)

    def rel(a: np.ndarray, b: np.ndarray) -> float:
        return float(
            np.max(np.abs(a - b), initial=0.0) / max(np.max(np.abs(b), initial=0.0), 1e-300)
        )

    return {
        "A": rel(lin.A[n:], A_fd),
        "B": rel(lin.B[n:], B_fd),
        "D": rel(lin.D[n:], D_fd),
        "C": rel(lin.C, C_fd),
        "F": rel(lin.F, F_fd),
    }


def describe(lin: Linearization) -> dict[str, Any]:
    """Sizes of the linearized model, for tables and JSON."""
    return {
        "states": int(lin.A.shape[0]),
        "inputs": int(lin.B.shape[1]),
        "disturbances": int(lin.D.shape[1]),
        "outputs": int(lin.C.shape[0]),
        "taut_tendons": int(np.sum(lin.taut)),
    }
