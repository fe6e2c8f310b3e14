"""Static equilibria (eq. 18.61): directly by least squares / Newton, or by damped simulation.

Two routes, which agree (``tests/test_analysis_equilibrium.py``):

- :func:`find_equilibrium` solves ``Q(x) = 0`` -- the generalized forces in the reduced
  coordinates of :mod:`~tensegrity.analysis.coordinates`, so every rod keeps its length
  exactly -- with ``scipy.optimize.least_squares`` and the analytic Jacobian of
  :mod:`.statics`, then polishes
  with Newton steps.  A free structure's equilibria come in 6-dimensional families (rigid-body
  motions); the family is gauged by Eckart's conditions with respect to the starting
  configuration (6 extra residuals: same mass centre, no mass-weighted rotation), so the solution
  is isolated and the Jacobian has full column rank when the structure is stiff.  External
  forces or gravity fix the orientation themselves; then only the mass centre is gauged (and a
  free structure under a net force has no equilibrium: the solver reports its residual).
- :func:`equilibrium_by_simulation` runs the paper's route: the structure with artificial
  critical damping (:func:`tensegrity.physics.dynamics.artificial_damping`) is simulated until it
  is at rest.  Convergence test: every node speed below ``velocity_tol`` [m/s] *and* every node
  acceleration below ``acceleration_tol`` [m/s^2] at a sample (``simulate(steady_state=True)``).

Both report an :class:`EquilibriumResult`: node positions, tensions, slack tendons and residuals.

Joints and supports (``docs/constraints.md``) are the constraints ``g(x) = A q(x) - b = 0``
(:class:`~tensegrity.analysis.coordinates.Chart`); the direct route then solves ``Q(x) + G(x)^T
lambda = 0``, ``g(x) = 0`` for ``x`` and the multipliers ``lambda`` (the reactions are the nodal
forces ``A_n^T lambda``), its descent moves in ``null(G)`` and goes back onto ``g = 0`` by the
dynamics' projection, and the gauge covers only the rigid-body motions the supports admit.  A
planar structure is solved in its 3-D form (:func:`~tensegrity.analysis.coordinates.spatial`)
and reported in 2-D.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, Any

import numpy as np
import scipy.optimize

from tensegrity.analysis.coordinates import (
    Chart,
    align,
    configuration,
    cross_matrix,
    has_supports,
    planar_coordinates,
    rigid_body_basis,
    spatial,
    spatial_coordinates,
    spatial_vector,
)
from tensegrity.analysis.statics import (
    Statics,
    force_jacobian,
    rod_compression,
    statics,
    with_reactions,
)
from tensegrity.engine.options import Options
from tensegrity.engine.result import shortened
from tensegrity.model.structure import Structure, require_structure
from tensegrity.physics import dynamics
from tensegrity.physics.constraints import constraints_of

if TYPE_CHECKING:
    from tensegrity.engine.result import SimulationResult

#: Default force tolerance, relative to ``mean(k) * mean(rod length)`` (100 N for the default
#: shell: 1e-10 N there).
FORCE_RTOL = 1e-12


@dataclasses.dataclass(frozen=True, eq=False)
class EquilibriumResult:
    """An equilibrium of a structure (or the best attempt at one).

    Attributes
    ----------
    structure : Structure
    q : (6R,) coordinates [m] (n: point masses follow).  node_position : (N, 3) [m].
    control : (S,) rest-length changes ``u`` [m] (``Lbar = L0 - u``).
    rest_length : (S,) ``Lbar`` [m].  tendon_length : (S,) [m].
    tension : (S,) [N] (0 for slack tendons).  slack : (S,) bool, ``l <= Lbar``.
    rod_compression : (R,) axial compression of each rod [N] (> 0 compressed).
    residual_force : max ``|Q|``, the generalized forces (eq. 18.61 in reduced coordinates) [N];
        with joints and supports, of ``Q + G^T lambda``, what the best reactions leave.
    residual_acceleration : max ``|q''|`` of Theorem 18.1 at rest (``q' = 0``) [m/s^2].
    converged : whether the method's convergence test passed.
    method : ``"least_squares"`` or ``"simulation"``.
    message : how it ended.  nfev : evaluations (residuals, or right-hand sides).
    reaction_force : (N, 3) forces of the joints and supports on the nodes [N] (reactions at
        anchors included), or None for a structure without any.
    A planar structure's result is in 2-D: ``q`` (4R + 2M), ``node_position`` (N, 2).
    """

    structure: Structure
    q: np.ndarray
    node_position: np.ndarray
    control: np.ndarray
    rest_length: np.ndarray
    tendon_length: np.ndarray
    tension: np.ndarray
    slack: np.ndarray
    rod_compression: np.ndarray
    residual_force: float
    residual_acceleration: float
    converged: bool
    method: str
    message: str
    nfev: int
    external_force: np.ndarray | None = None
    gravity: np.ndarray | None = None
    reaction_force: np.ndarray | None = None
    #: the damped run that settled (:func:`equilibrium_by_simulation`; None for least squares)
    trajectory: SimulationResult | None = None

    def __repr__(self) -> str:
        """A few hundred characters at most whatever the size: converged or not, the method and
        the start of its message, the residual force, slack tendons, the tension range and the
        structure (its ``repr``)."""
        S = self.structure.n_tendons
        tensions = f", tensions {self.tension.min():.4g}..{self.tension.max():.4g} N" if S else ""
        return (
            f"<EquilibriumResult: {'converged' if self.converged else 'not converged'} by "
            f"{self.method} ({shortened(self.message)}), residual force "
            f"{self.residual_force:.3g} N, {int(np.count_nonzero(self.slack))} of {S} tendons "
            f"slack{tensions}, {self.structure!r}>"
        )

    @property
    def slack_names(self) -> list[str]:
        """Names of the slack tendons."""
        return [n for n, sl in zip(self.structure.tendon_name, self.slack, strict=True) if sl]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary: node positions, tensions, slack tendons and residuals."""
        s = self.structure
        return (
            {
                "method": self.method,
                "converged": bool(self.converged),
                "message": self.message,
                "residual_force_N": float(self.residual_force),
                "residual_acceleration_m_s2": float(self.residual_acceleration),
                "node_position_m": self.node_position.tolist(),
                "tendons": [
                    {
                        "name": name,
                        "tension_N": float(T),
                        "length_m": float(length),
                        "rest_length_m": float(r),
                        "slack": bool(sl),
                    }
                    for name, T, length, r, sl in zip(
                        s.tendon_name,
                        self.tension,
                        self.tendon_length,
                        self.rest_length,
                        self.slack,
                        strict=True,
                    )
                ],
                "rod_compression_N": self.rod_compression.tolist(),
                "slack_tendons": self.slack_names,
            }
            | (
                {}
                if self.reaction_force is None
                else {"reaction_force_N": self.reaction_force.tolist()}
            )
            | ({} if self.gravity is None else {"gravity_m_s2": self.gravity.tolist()})
        )


def force_scales(structure: Structure, gravity: np.ndarray | None = None) -> tuple[float, float]:
    """``(stiffness [N/m], length [m])`` that scale forces and tolerances: the mean tendon
    stiffness and the mean rod length; without tendons, the total weight over that length (1 N/m
    without gravity either); without rods, 1 m."""
    length = float(np.mean(structure.rod_length)) if structure.n_rods else 1.0
    if structure.n_tendons:
        return float(np.mean(structure.tendon_stiffness)), length
    weight = structure.total_mass * (0.0 if gravity is None else float(np.linalg.norm(gravity)))
    return (weight / length if weight > 0 else 1.0), length


def make_result(
    structure: Structure,
    q: np.ndarray,
    control: np.ndarray | None,
    *,
    external_force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
    converged: bool,
    method: str,
    message: str,
    nfev: int,
) -> EquilibriumResult:
    """An :class:`EquilibriumResult` at ``q`` (residuals evaluated there)."""
    if structure.dim == 2:
        result = make_result(
            spatial(structure),
            spatial_coordinates(structure, q),
            control,
            external_force=spatial_vector(structure, external_force),
            gravity=spatial_vector(structure, gravity),
            converged=converged,
            method=method,
            message=message,
            nfev=nfev,
        )
        return planar_result(structure, result, external_force, gravity)
    u = np.zeros(structure.n_tendons) if control is None else np.asarray(control, dtype=float)
    rest = dynamics.rest_lengths(structure, u)
    chart = Chart.at(structure, q)
    x0 = np.zeros(chart.size)
    st = statics(chart, x0, rest, external_force, gravity)
    reaction, unbalanced = chart.reaction(st.generalized_force)
    qddot = dynamics.accelerations(
        structure,
        st.q,
        np.zeros_like(st.q),
        control=u,
        external_force=external_force,
        gravity=gravity,
    )
    return EquilibriumResult(
        structure=structure,
        q=st.q,
        node_position=st.p,
        control=u,
        rest_length=rest,
        tendon_length=st.tendons.length,
        tension=st.tendons.tension,
        slack=st.tendons.length <= rest,
        rod_compression=rod_compression(structure, st.force + reaction, chart.direction),
        residual_force=float(np.max(np.abs(unbalanced), initial=0.0)),
        residual_acceleration=float(np.max(np.abs(qddot), initial=0.0)),
        converged=converged,
        method=method,
        message=message,
        nfev=nfev,
        external_force=None if external_force is None else np.asarray(external_force, float),
        gravity=None if gravity is None else np.asarray(gravity, float),
        reaction_force=reaction if structure.has_constraints else None,
    )


def planar_result(
    planar: Structure,
    result: EquilibriumResult,
    external_force: np.ndarray | None,
    gravity: np.ndarray | None,
) -> EquilibriumResult:
    """A result of the 3-D form (:func:`~tensegrity.analysis.coordinates.spatial`) of the planar
    structure ``planar``, in 2-D (the loads as ``planar``'s: 2 numbers per vector)."""
    reaction = None
    if planar.has_constraints:  # so has its 3-D form: ``result`` has the reactions
        assert result.reaction_force is not None
        reaction = result.reaction_force[:, :2]
    return dataclasses.replace(
        result,
        structure=planar,
        q=planar_coordinates(planar, result.q),
        node_position=result.node_position[:, :2],
        reaction_force=reaction,
        external_force=None if external_force is None else np.asarray(external_force, float),
        gravity=None if gravity is None else np.asarray(gravity, float),
    )


class EckartGauge:
    """Eckart's conditions about a reference configuration ``p_ref``: 6 residuals [N], linear in
    ``p``, scaled by the mean tendon stiffness so that they weigh like forces.

    With supports, only the combinations ``rows`` (k, 6) of them that fix the admitted
    rigid-body motions (:meth:`restricted`)."""

    def __init__(
        self,
        structure: Structure,
        p_ref: np.ndarray,
        rotations: bool = True,
        scale: float | None = None,
    ) -> None:
        self.rotations = rotations
        self.w = structure.node_mass / structure.node_mass.sum()
        self.p_ref = p_ref
        self.arm = p_ref - self.w @ p_ref
        radius = np.sqrt(self.w @ np.sum(self.arm**2, axis=1)) or 1.0
        self.scale = float(np.mean(structure.tendon_stiffness)) if scale is None else scale
        self.rot_scale = self.scale / radius
        self.rows: np.ndarray | None = None

    def restricted(self, moves: np.ndarray) -> EckartGauge | None:
        """The gauge on the rigid-body motions ``moves`` (the gauge's rows' changes along
        them, (6, r)): an orthonormal basis of their range picks the conditions; None if the
        supports admit no rigid-body motion."""
        u, sigma, _ = np.linalg.svd(moves, full_matrices=False)
        keep = sigma > 1e-10 * max(sigma[0] if sigma.size else 0.0, np.finfo(float).tiny)
        if not keep.any():
            return None
        self.rows = u[:, keep].T
        return self

    def residual(self, p: np.ndarray) -> np.ndarray:
        d = p - self.p_ref
        parts = [self.scale * (self.w @ d)]
        if self.rotations:
            parts.append(self.rot_scale * (self.w @ np.cross(self.arm, d)))
        full = np.concatenate(parts)
        return full if self.rows is None else self.rows @ full

    def jacobian(self, J: np.ndarray) -> np.ndarray:
        """Rows (6, n) from ``J = dp/dx`` (3N, n)."""
        Jn = J.reshape(-1, 3, J.shape[1])
        translation = np.einsum("i,ikc->kc", self.w, Jn)
        if not self.rotations:
            full = self.scale * translation
        else:
            rotation = np.einsum("i,ikl,ilc->kc", self.w, cross_matrix(self.arm), Jn)
            full = np.vstack([self.scale * translation, self.rot_scale * rotation])
        return full if self.rows is None else self.rows @ full


def eckart_gauge(
    structure: Structure, q: np.ndarray, p_ref: np.ndarray, rotations: bool, scale: float
) -> EckartGauge | None:
    """Eckart's conditions for the rigid-body motions the supports of ``structure`` admit at
    ``q`` (all six for a free structure; None if there are none).  Without ``rotations`` (under
    loads, which fix the orientation) only the admitted pure translations are gauged."""
    gauge_scale = None if structure.n_tendons else scale
    eckart = EckartGauge(structure, p_ref, rotations, scale=gauge_scale)
    if not (structure.has_constraints or structure.anchor_nodes.size):
        return eckart
    chart = Chart.at(structure, q)
    full = EckartGauge(structure, p_ref, True, scale=gauge_scale)
    moves = full.jacobian(chart.jacobian_matrix()) @ rigid_body_basis(chart)  # (6, r)
    if not rotations:
        # pure translations: no change of the rotation conditions
        _, sigma, vt = np.linalg.svd(moves[3:])
        rank = int(np.sum(sigma > 1e-10 * max(np.max(np.abs(moves), initial=0.0), 1e-300)))
        moves = moves[:3] @ vt[rank:].T
    return eckart.restricted(moves)


def find_equilibrium(
    structure: Structure,
    start: Any = None,
    *,
    control: np.ndarray | None = None,
    external_force: np.ndarray | None = None,
    gravity: np.ndarray | None = None,
    gauge: bool = True,
    gauge_reference: np.ndarray | None = None,
    descend: bool = True,
    force_tol: float | None = None,
    max_rounds: int = 10,
    max_nfev: int = 2000,
) -> EquilibriumResult:
    """Solve ``K_p(q) q = B(q) u + D(q) w`` (eq. 18.61) with the rod-length constraints.

    Unknowns: the ``5R`` reduced coordinates of :class:`Chart` (rod centres and two angles per
    rod; 3 more per point mass), so the rod constraints hold exactly.  Residuals: the
    generalized forces ``Q`` [N, N m] and, if ``gauge``, Eckart's 6 conditions with respect to
    ``start`` (fixing the rigid-body motion).  ``scipy.optimize.least_squares``
    (Levenberg-Marquardt) with the analytic Jacobian; the chart is re-based at each round's
    solution (it is exact only within 90 degrees of its base), and rounds end with Newton steps.

    Joints and supports add the multipliers ``lambda`` (c,) [N] to the unknowns and the
    residuals ``Q + G^T lambda`` and ``k g(x)`` (``k`` the stiffness scale); the gauge then
    covers only the admitted rigid-body motions.  A planar structure is solved in its 3-D form
    and reported in 2-D (``start``, loads and ``gauge_reference`` in 2-D).

    Parameters
    ----------
    start : (N, 3) node positions or (6R,) q, optional
        Starting guess (rods are first projected onto their lengths); default the structure's
        node positions.
    control : (S,) rest-length changes ``u`` [m], optional.
    external_force : (N, 3) nodal forces ``w`` [N], optional.  gravity : (3,), optional.
    gauge_reference : (N, 3), optional
        The configuration Eckart's conditions refer to (default ``start``): pass the same one
        to a sequence of solves to keep them all in one frame.
    descend : bool
        First go down the potential energy (elastic, minus the work of ``w`` and gravity) from
        ``start`` by a modified Newton method (analytic gradient ``-Q`` and Hessian
        ``K = -dQ/dx``, eigenvalues made positive, line search; gauge added as a penalty), so
        that the root found is a minimum -- a stable equilibrium -- rather than whatever
        stationary point is nearest.  Without it, least squares alone converges to
        the nearest root, which may be a saddle (e.g. the (3,1) shell from its cylinder layout
        then lands on an equilibrium with 3 slack tendons).
    force_tol : float, optional
        Convergence: ``max |Q| <= force_tol`` [N].  Default ``1e-12 * mean(k) * mean(L_rod)``
        (without tendons, the total weight times ``mean(L_rod)``).

    Returns
    -------
    EquilibriumResult
        ``converged`` False (with a message) if the tolerance was not met; the residual is
        reported either way.
    """
    require_structure(structure)
    solve = _find_planar_equilibrium if structure.dim == 2 else _find_spatial_equilibrium
    return solve(
        structure,
        start,
        control=control,
        external_force=external_force,
        gravity=gravity,
        gauge=gauge,
        gauge_reference=gauge_reference,
        descend=descend,
        force_tol=force_tol,
        max_rounds=max_rounds,
        max_nfev=max_nfev,
    )


def _find_spatial_equilibrium(
    structure: Structure,
    start: Any,
    *,
    control: np.ndarray | None,
    external_force: np.ndarray | None,
    gravity: np.ndarray | None,
    gauge: bool,
    gauge_reference: np.ndarray | None,
    descend: bool,
    force_tol: float | None,
    max_rounds: int,
    max_nfev: int,
) -> EquilibriumResult:
    """:func:`find_equilibrium` of a 3-D structure: descent (if ``descend``), then rounds of
    least squares and Newton steps (:meth:`_EquilibriumProblem.solve`)."""
    q = configuration(structure, start, name="start")
    problem = _EquilibriumProblem.build(
        structure,
        q,
        control=control,
        external_force=external_force,
        gravity=gravity,
        gauge=gauge,
        gauge_reference=gauge_reference,
        force_tol=force_tol,
    )
    nfev = 0
    if descend:
        q, nfev = _descend(structure, q, problem.rest, external_force, gravity, problem.eckart)
    q, converged, message, used = problem.solve(q, max_rounds=max_rounds, max_nfev=max_nfev)
    return make_result(
        structure,
        q,
        problem.control,
        external_force=external_force,
        gravity=gravity,
        converged=converged,
        method="least_squares",
        message=message,
        nfev=nfev + used,
    )


def _find_planar_equilibrium(
    structure: Structure,
    start: Any,
    *,
    gravity: np.ndarray | None,
    external_force: np.ndarray | None,
    gauge_reference: np.ndarray | None,
    **options: Any,
) -> EquilibriumResult:
    """:func:`find_equilibrium` of a planar structure: solved in its 3-D form
    (:func:`~tensegrity.analysis.coordinates.spatial`), reported in 2-D.

    ``start``, ``external_force`` (N, 2) [N], ``gravity`` (2,) [m/s^2] and ``gauge_reference``
    (N, 2) [m] are in 2-D; ``options`` are :func:`find_equilibrium`'s others.
    """
    q2 = configuration(structure, start, name="start")
    result = _find_spatial_equilibrium(
        spatial(structure),
        spatial_coordinates(structure, q2),
        external_force=spatial_vector(structure, external_force),
        gravity=spatial_vector(structure, gravity),
        gauge_reference=spatial_vector(structure, gauge_reference),
        **options,
    )
    return planar_result(structure, result, external_force, gravity)


@dataclasses.dataclass(frozen=True, eq=False)
class _EquilibriumProblem:
    """The equations :func:`find_equilibrium` solves on a chart, and how it solves them.

    The unknowns are ``v = [x, lambda]``: ``x`` (n,) the chart's coordinates, ``lambda`` (c,)
    the multipliers of the joints and supports [N] (none without).  The residuals are
    ``[Q + G^T lambda; k g; gauge]``: the generalized forces [N, N m], the constraints ``g``
    [m] weighted by the stiffness scale ``k`` [N/m], and Eckart's conditions [N].

    Attributes
    ----------
    structure : Structure
    control : (S,) rest-length changes ``u`` [m].  rest : (S,) rest lengths ``Lbar`` [m].
    external_force : (N, 3) [N] or None.  gravity : (3,) [m/s^2] or None.
    k_scale : stiffness scale [N/m] (:func:`force_scales`).
    force_tol : convergence tolerance on ``max |Q + G^T lambda|`` [N].
    eckart : the gauge (:func:`eckart_gauge`), or None.
    """

    structure: Structure
    control: np.ndarray
    rest: np.ndarray
    external_force: np.ndarray | None
    gravity: np.ndarray | None
    k_scale: float
    force_tol: float
    eckart: EckartGauge | None

    @classmethod
    def build(
        cls,
        structure: Structure,
        q: np.ndarray,
        *,
        control: np.ndarray | None,
        external_force: np.ndarray | None,
        gravity: np.ndarray | None,
        gauge: bool,
        gauge_reference: np.ndarray | None,
        force_tol: float | None,
    ) -> _EquilibriumProblem:
        """The problem of :func:`find_equilibrium`'s arguments, gauged about ``gauge_reference``
        (N, 3) [m] (default the nodes at ``q``, the (6R,) start) if ``gauge``."""
        u = np.zeros(structure.n_tendons) if control is None else np.asarray(control, dtype=float)
        rest = dynamics.rest_lengths(structure, u)
        k_scale, length = force_scales(structure, gravity)
        tol = FORCE_RTOL * k_scale * length if force_tol is None else float(force_tol)
        p_ref = (
            dynamics.nodes_from_coordinates(structure, q)
            if gauge_reference is None
            else np.asarray(gauge_reference, dtype=float)
        )
        # Loads that are not invariant under rotation (external forces, gravity) fix the
        # orientation themselves: then only the translation is gauged.
        eckart = (
            eckart_gauge(structure, q, p_ref, external_force is None and gravity is None, k_scale)
            if gauge
            else None
        )
        return cls(structure, u, rest, external_force, gravity, k_scale, tol, eckart)

    def statics_at(self, chart: Chart, x: np.ndarray) -> Statics:
        """:func:`~tensegrity.analysis.statics.statics` at ``x`` (n,) under the problem's loads."""
        return statics(chart, x, self.rest, self.external_force, self.gravity)

    def residual(self, chart: Chart, v: np.ndarray) -> np.ndarray:
        """``[Q + G^T lambda; k g; gauge]`` at ``v = [x, lambda]``."""
        x = v[: chart.size]
        st = self.statics_at(chart, x)
        parts = [st.generalized_force]
        if chart.n_constraints:
            parts = [
                parts[0] + chart.constraint_jacobian(x).T @ v[chart.size :],
                self.k_scale * chart.constraint_residual(x),
            ]
        if self.eckart is not None:
            parts.append(self.eckart.residual(st.p))
        return np.concatenate(parts)

    def jacobian(self, chart: Chart, v: np.ndarray) -> np.ndarray:
        """The residual's derivative with respect to ``v = [x, lambda]``, (rows, n + c)."""
        x = v[: chart.size]
        st = self.statics_at(chart, x)
        if not chart.n_constraints:
            rows = [force_jacobian(chart, x, st)]
            if self.eckart is not None:
                rows.append(self.eckart.jacobian(chart.jacobian_matrix(x)))
            return np.vstack(rows)
        c = chart.n_constraints
        G = chart.constraint_jacobian(x)
        constraints = constraints_of(self.structure)
        assert constraints is not None  # the chart of this structure has constraints
        reaction = (constraints.node_matrix_t @ v[chart.size :]).reshape(-1, 3)
        rows = [
            np.hstack([force_jacobian(chart, x, st._replace(force=st.force + reaction)), G.T]),
            np.hstack([self.k_scale * G, np.zeros((c, c))]),
        ]
        if self.eckart is not None:
            gauge_rows = self.eckart.jacobian(chart.jacobian_matrix(x))
            rows.append(np.hstack([gauge_rows, np.zeros((gauge_rows.shape[0], c))]))
        return np.vstack(rows)

    def start(self, chart: Chart) -> np.ndarray:
        """``[x = 0, lambda]`` with the least-squares multipliers at the chart's base."""
        x0 = np.zeros(chart.size)
        if not chart.n_constraints:
            return x0
        Q = self.statics_at(chart, x0).generalized_force
        multiplier, *_ = np.linalg.lstsq(chart.constraint_jacobian().T, -Q, rcond=None)
        return np.concatenate([x0, multiplier])

    def unbalanced(self, q: np.ndarray) -> float:
        """max ``|Q + G^T lambda|`` [N] at ``q``, ``lambda`` the best reactions."""
        chart = Chart.at(self.structure, q)
        Q = self.statics_at(chart, np.zeros(chart.size)).generalized_force
        return float(np.max(np.abs(chart.reaction(Q)[1]), initial=0.0))

    def solve(
        self, q: np.ndarray, *, max_rounds: int, max_nfev: int
    ) -> tuple[np.ndarray, bool, str, int]:
        """Rounds of least squares from ``q`` (6R,), each on a chart based at the last round's
        solution and ended by Newton steps, until ``max |Q| <= force_tol``.

        Returns
        -------
        (q, converged, message, nfev)
        """
        message = "did not converge"
        nfev = 0
        for _ in range(max_rounds):
            chart = Chart.at(self.structure, q)
            fit = self.least_squares(chart, max_nfev=max_nfev)
            nfev += fit.nfev
            x = fit.x[: chart.size]
            q = chart.retract(x)
            if np.max(np.abs(chart.split(x)[1]), initial=0.0) > 1.0:
                continue  # far out on the chart: re-base
            q, force_residual, used = self.polish(q)
            nfev += used
            tol = self.force_tol
            if force_residual <= tol:
                return q, True, f"converged: max |Q| = {force_residual:.3g} N <= {tol:.3g} N", nfev
            message = (
                f"did not converge: max |Q| = {force_residual:.3g} N > {tol:.3g} N ({fit.message})"
            )
            if fit.status > 0 and force_residual > 1e3 * tol:
                break  # a least-squares minimum that is no equilibrium: going on will not help
        return q, False, message, nfev

    def least_squares(self, chart: Chart, *, max_nfev: int) -> scipy.optimize.OptimizeResult:
        """``scipy.optimize.least_squares`` on ``chart`` from :meth:`start`, with the analytic
        Jacobian (Levenberg-Marquardt unless the system is underdetermined)."""
        lm = self.eckart is not None or chart.size <= self.structure.n_coordinates
        return scipy.optimize.least_squares(
            lambda v: self.residual(chart, v),
            self.start(chart),
            jac=lambda v: self.jacobian(chart, v),
            method="lm" if lm else "trf",
            xtol=1e-15,
            ftol=1e-15,
            gtol=1e-15,
            max_nfev=max_nfev,
        )

    def polish(self, q: np.ndarray, steps: int = 5) -> tuple[np.ndarray, float, int]:
        """Up to ``steps`` Newton steps from ``q`` (6R,) on charts based at each iterate, while
        they reduce ``max |Q + G^T lambda|``.

        Returns
        -------
        (q, that residual there [N], the number of steps taken)
        """
        force_residual = self.unbalanced(q)
        nfev = 0
        for _ in range(steps):
            if force_residual <= self.force_tol:
                break
            chart = Chart.at(self.structure, q)
            v0 = self.start(chart)
            nfev += 1
            step, *_ = np.linalg.lstsq(
                self.jacobian(chart, v0), -self.residual(chart, v0), rcond=None
            )
            trial = chart.retract(step[: chart.size])
            trial_residual = self.unbalanced(trial)
            if trial_residual >= force_residual:
                break  # no progress (a near-singular Jacobian: zero-stiffness motions)
            q, force_residual = trial, trial_residual
        return q, force_residual, nfev


def potential_energy(structure, p, q, rest, external_force, gravity) -> float:
    """Elastic energy minus the work of constant external forces and gravity [J]."""
    energy = float(dynamics.elastic_energy(structure, p, rest))
    if external_force is not None:
        energy -= float(np.sum(np.asarray(external_force) * p))
    if gravity is not None:
        energy += float(dynamics.gravity_energy(structure, q, np.asarray(gravity, float)))
    return energy


def _descend(structure, q, rest, external_force, gravity, eckart, max_iter=500):
    """Newton descent of the potential energy plus the gauge penalty ``|g|^2 / (2 mean k)``.

    Each step solves ``|H| d = -grad`` with ``|H|`` the Hessian ``K = -dQ/dx`` (plus the
    penalty's) with its eigenvalues replaced by their absolute values (floored at ``1e-8`` of
    the largest), so that every step goes down even where ``K`` is indefinite; the step is
    capped at 0.25 (rad, or rod lengths) and halved until the energy decreases (Armijo).  The
    chart is re-based at every iterate.  Near a minimum this is Newton's method.

    With joints and supports the step is taken in the admitted motions ``x = Z eta``
    (:meth:`Chart.admitted_motions`), with the Hessian of the Lagrangian (the reactions' part of
    the rods' geometric term included), and each trial point is projected back onto them.
    """
    k_mean, length = force_scales(structure, gravity)
    nfev = 0

    def value(q):
        p = dynamics.nodes_from_coordinates(structure, q)
        v = potential_energy(structure, p, q, rest, external_force, gravity)
        if eckart is not None:
            g = eckart.residual(p)
            v += 0.5 * float(g @ g) / k_mean
        return v

    for _ in range(max_iter):
        chart = Chart.at(structure, q)
        x0 = np.zeros(chart.size)
        st = statics(chart, x0, rest, external_force, gravity)
        Z = chart.admitted_motions()
        grad = -st.generalized_force
        H = -force_jacobian(chart, x0, with_reactions(chart, st))
        H = 0.5 * (H + H.T)
        energy = potential_energy(structure, st.p, st.q, rest, external_force, gravity)
        if eckart is not None:
            g = eckart.residual(st.p)
            G = eckart.jacobian(chart.jacobian_matrix(x0))
            grad = grad + G.T @ g / k_mean
            H = H + G.T @ G / k_mean
            energy += 0.5 * float(g @ g) / k_mean
        nfev += 1
        # what the reactions cannot balance (all of it without joints and supports)
        if np.max(np.abs(chart.reaction(grad)[1]), initial=0.0) <= 1e-9 * k_mean * length:
            break
        if Z is not None:
            grad, H = Z.T @ grad, Z.T @ H @ Z
        lam, V = np.linalg.eigh(H)
        floor = 1e-8 * max(np.max(np.abs(lam), initial=0.0), k_mean * length**2)
        reduced = -V @ ((V.T @ grad) / np.maximum(np.abs(lam), floor))
        step = reduced if Z is None else Z @ reduced
        scale = np.concatenate(
            [np.full(3, length), np.ones(2)] * structure.n_rods
            + [np.full(3 * structure.point_mass_nodes.size, length)]
        )
        biggest = np.max(np.abs(step) / scale, initial=0.0) / 0.25
        if biggest > 1.0:
            step /= biggest
            if Z is not None:
                reduced = reduced / biggest
        slope = float(grad @ reduced)
        for _ in range(40):
            nfev += 1
            trial = chart.retract(step)
            if value(trial) <= energy + 1e-4 * slope:
                break
            step *= 0.5
        else:
            break  # no descent along a descent direction: at a minimum within round-off
        q = trial
    return q, nfev


@dataclasses.dataclass(frozen=True, eq=False)
class EquilibriumSensitivity:
    """How an equilibrium moves when parameters of its structure change
    (:func:`equilibrium_sensitivity`).

    Attributes
    ----------
    chart : the reduced coordinates based at the equilibrium (``x = 0`` there).
    direction : (n, P) ``dx/dp``: the change of the chart's coordinates per unit change of
        each of the ``P`` parameters (rod lengths and the joints and supports held to first
        order).
    """

    chart: Chart
    direction: np.ndarray

    def configuration(self, change: np.ndarray) -> np.ndarray:
        """The configuration ``q`` (6R,) the equilibrium moves to, to first order, when the
        parameters change by ``change`` (P,): ``x = direction @ change``, retracted onto the
        rods, joints and supports."""
        return self.chart.retract(self.direction @ np.asarray(change, dtype=float))


def equilibrium_sensitivity(
    eq: EquilibriumResult, perturbed: list[tuple[Structure, Structure]], step: float
) -> EquilibriumSensitivity:
    """The derivatives of the equilibrium ``eq`` with respect to ``P`` parameters of its
    structure, by the implicit function theorem on :func:`find_equilibrium`'s equations
    ``r(v, p) = [Q + G^T lambda; k g; gauge] = 0``: ``dv/dp = -J^+ dr/dp``, with ``J = dr/dv``
    analytic at the equilibrium (one factorisation for every parameter) and ``dr/dp`` by
    central differences at the fixed state (no equilibrium is solved again).

    Parameters
    ----------
    eq : a converged equilibrium of a 3-D structure (``eq.structure``), under its own
        external forces and gravity.
    perturbed : for each parameter ``p_j``, the structures at ``p_j - step`` and ``p_j + step``
        (the same topology and node positions; any of stiffness, rest length or mass changed).
    step : the parameters' change (the same unit as ``p``).

    Returns
    -------
    EquilibriumSensitivity
        ``dx/dp`` (n, P) in the chart based at ``eq``; the equilibrium's gauge (Eckart's
        conditions, where the loads and supports leave a rigid-body motion free) refers to
        ``eq`` itself.
    """
    structure = eq.structure
    if structure.dim != 3:
        raise ValueError(
            "equilibrium_sensitivity: a 3-D structure (a planar one: its spatial form)"
        )
    if not perturbed:
        raise ValueError("perturbed: give at least one parameter's pair of structures")
    if not (np.isfinite(step) and step > 0):
        raise ValueError(f"step: must be > 0, got {step!r}")

    def problem(s: Structure, gauge: bool) -> _EquilibriumProblem:
        return _EquilibriumProblem.build(
            s,
            eq.q,
            control=eq.control,
            external_force=eq.external_force,
            gravity=eq.gravity,
            gauge=gauge,
            gauge_reference=None,
            force_tol=None,
        )

    chart = Chart.at(structure, eq.q)
    base = problem(structure, True)
    v0 = base.start(chart)
    J = base.jacobian(chart, v0)

    def residual(s: Structure) -> np.ndarray:
        """The force and constraint rows at the fixed state ``v0`` (the gauge's do not depend
        on the parameters)."""
        return problem(s, False).residual(Chart.at(s, eq.q), v0)

    derivative = np.zeros((J.shape[0], len(perturbed)))
    for j, (minus, plus) in enumerate(perturbed):
        change = (residual(plus) - residual(minus)) / (2 * step)
        derivative[: change.size, j] = change
    dv, *_ = np.linalg.lstsq(J, -derivative, rcond=None)
    return EquilibriumSensitivity(chart, dv[: chart.size])


def equilibrium_by_simulation(
    structure: Structure,
    *,
    control: np.ndarray | None = None,
    initial: dynamics.State | None = None,
    damping: str = "artificial",
    t_end: float = 60.0,
    velocity_tol: float = Options.velocity_tol,
    acceleration_tol: float = Options.acceleration_tol,
    sample_dt: float = 0.01,
    **simulate_options: Any,
) -> EquilibriumResult:
    """The paper's route: simulate with damping until the structure is at rest.

    Convergence test: at some sample, every node speed ``< velocity_tol`` [m/s] and every node
    acceleration ``< acceleration_tol`` [m/s^2] (``simulate(..., steady_state=True)``);
    ``converged`` is False if ``t_end`` came first or the run failed.

    Parameters
    ----------
    damping : ``"artificial"`` (default: :func:`tensegrity.physics.dynamics.artificial_damping`,
        the paper's "artificial critical damping") or ``"as-is"`` (the structure's own damping).
    """
    from tensegrity.engine.simulate import STATUS_STEADY, simulate

    result = simulate(
        with_damping(structure, damping),
        (0.0, float(t_end)),
        initial=initial,
        control=control,
        steady_state=True,
        velocity_tol=velocity_tol,
        acceleration_tol=acceleration_tol,
        sample_dt=sample_dt,
        **simulate_options,
    )
    converged = result.status == STATUS_STEADY
    message = (
        f"{result.message} (node speeds < {velocity_tol:g} m/s, accelerations < "
        f"{acceleration_tol:g} m/s^2)"
        if converged
        else f"not at rest: {result.message}"
    )
    loads = {
        key: simulate_options[key]
        for key in ("gravity", "external_force")
        if isinstance(simulate_options.get(key), (list, tuple, np.ndarray))
    }
    settled = make_result(
        structure,
        result.q[-1],
        control,
        **loads,
        converged=converged,
        method="simulation",
        message=message,
        nfev=result.nfev,
    )
    return dataclasses.replace(settled, trajectory=result)


def with_damping(structure: Structure, damping: str) -> Structure:
    """``"artificial"``: :func:`tensegrity.physics.dynamics.artificial_damping` (the paper's
    artificial critical damping); ``"as-is"``: the structure's own damping."""
    if damping == "artificial":
        return dynamics.artificial_damping(structure)
    if damping == "as-is":
        return structure
    raise ValueError(f"damping: expected 'artificial' or 'as-is', got {damping!r}")


def compare_equilibria(a: EquilibriumResult, b: EquilibriumResult) -> dict[str, float]:
    """How far apart two equilibria of the same structure are, blind to rigid-body motion.

    Returns ``{"node_distance": max node distance after aligning b onto a (not aligned when
    supports hold the structure: then rigid-body motion is a difference) [m],
    "tension_difference": max |T_a - T_b| [N]}``.
    """
    w = a.structure.node_mass
    pa, pb = (np.pad(p, ((0, 0), (0, 3 - p.shape[1]))) for p in (a.node_position, b.node_position))
    aligned = pb if has_supports(a.structure) else align(pb, pa, w)
    return {
        "node_distance": float(np.max(np.linalg.norm(aligned - pa, axis=1))),
        "tension_difference": float(np.max(np.abs(a.tension - b.tension), initial=0.0)),
    }
