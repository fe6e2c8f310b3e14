"""Shape control by rest-length changes: quasi-static (open-loop) and LQR (closed-loop).

Outputs ``y = h(p)`` are functions of the node positions ``p = P q`` (eq. 18.60) with analytic
Jacobians: node coordinates (``y_p = C P q``, :func:`node_outputs`) or the height and twist of a
ring-to-ring structure such as a shell (:func:`height_twist`).  A free structure has no fixed
frame, so every configuration is first moved rigidly onto a reference (the initial equilibrium)
by a mass-weighted Kabsch fit -- the equilibria of the sequence are solved directly in that frame
(Eckart's conditions, :func:`~tensegrity.analysis.equilibrium.find_equilibrium`'s
``gauge_reference``), and simulated states are aligned the same way before outputs or feedback
are evaluated.

Control ``u`` is the rest-length change of every tendon (``Lbar = L0 - u``) within bounds
(:class:`~tensegrity.analysis.bounds.Bounds`): ``Lbar >= min_rest_length``,
``|u| <= max_change``, and every tendon kept taut with at least ``min_tension``.

- :func:`quasi_static` -- an open-loop sequence of equilibria: per step, the sensitivity
  ``dy/du`` of the equilibrium (from the tangent stiffness with the gauge), a minimum-norm
  change ``du`` that moves the outputs to the next target under the bounds and the linearized
  tension floor (a small QP, SLSQP), then the exact nonlinear equilibrium for the new ``u``;
  the remaining error is corrected by the next step, and the last target by Newton iterations.
- :func:`closed_loop` -- the sequence played in time as a feed-forward ``u_ff(t)``, ``x_ff(t)``,
  plus LQR state feedback (:func:`tensegrity.analysis.control_design.lqr` on the modes the
  tendons reach, at scheduled equilibria of the sequence), simulated on the nonlinear model
  (Theorem 18.1 with the slack law; DOP853, rod constraints projected at every sample).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import scipy.optimize

from tensegrity.analysis.bounds import Bounds
from tensegrity.analysis.controllability import match_tendons
from tensegrity.analysis.coordinates import Chart, align, has_supports, kabsch, mass_matrix
from tensegrity.analysis.equilibrium import EquilibriumResult, find_equilibrium
from tensegrity.analysis.statics import equilibrium_matrix, force_jacobian, statics, with_reactions
from tensegrity.engine.loop import Feedback
from tensegrity.engine.simulate import STATUS_END, SimulationResult, simulate
from tensegrity.model.actuators import Actuators
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics


def require_spatial(structure: Structure) -> None:
    """``ValueError`` for a planar structure (the outputs, rings and alignment here are 3-D;
    joints, supports and point masses are fine)."""
    if structure.dim != 3:
        raise ValueError("shape control: supports only 3-D structures (this one is planar)")


# ------------------------------------------------------------------------------ outputs
@dataclasses.dataclass(frozen=True)
class ShapeOutput:
    """Outputs ``y = value(p)`` (ny,) with Jacobian ``jacobian(p)`` (ny, 3N), and their
    names/units."""

    names: tuple[str, ...]
    units: tuple[str, ...]
    value: Callable[[np.ndarray], np.ndarray]
    jacobian: Callable[[np.ndarray], np.ndarray]


def node_outputs(structure: Structure, nodes: Sequence[int], axes: str = "xyz") -> ShapeOutput:
    """Coordinates ``axes`` of the nodes ``nodes``: ``y_p = C P q`` with a selection ``C``."""
    rows = [3 * int(i) + "xyz".index(a) for i in nodes for a in axes]
    C = np.zeros((len(rows), 3 * structure.n_nodes))
    C[np.arange(len(rows)), rows] = 1.0
    return ShapeOutput(
        tuple(f"p{i}_{a}" for i in nodes for a in axes),
        ("m",) * len(rows),
        lambda p: C @ p.reshape(-1),
        lambda p: C,
    )


def shell_rings(n: int, m: int) -> tuple[list[int], list[int]]:
    """Node indices of a shell's bottom ring (``p1`` of stage 1) and top ring (``p4`` of stage
    m)."""
    from tensegrity.model.shell import shell_node_index

    return (
        [shell_node_index(1, i, 1, n) for i in range(1, n + 1)],
        [shell_node_index(4, i, m, n) for i in range(1, n + 1)],
    )


def height_twist(reference: np.ndarray, bottom: Sequence[int], top: Sequence[int]) -> ShapeOutput:
    """Height ``H`` [m] and twist ``Theta`` [rad] of the top ring relative to the bottom ring.

    ``H`` = mean z of ``top`` minus mean z of ``bottom``.  ``Theta`` = mean change of the
    azimuth (about the vertical axis through the reference's centroid) of the ``top`` nodes
    minus that of the ``bottom`` nodes, relative to ``reference`` (N, 3): 0 there.
    """
    bottom_nodes, top_nodes = np.asarray(bottom, int), np.asarray(top, int)
    axis = reference.mean(axis=0)[:2]
    ref_angle = np.arctan2(reference[:, 1] - axis[1], reference[:, 0] - axis[0])

    def value(p: np.ndarray) -> np.ndarray:
        angle = np.arctan2(p[:, 1] - axis[1], p[:, 0] - axis[0])
        turn = np.angle(np.exp(1j * (angle - ref_angle)))
        return np.array(
            [
                p[top_nodes, 2].mean() - p[bottom_nodes, 2].mean(),
                turn[top_nodes].mean() - turn[bottom_nodes].mean(),
            ]
        )

    def jacobian(p: np.ndarray) -> np.ndarray:
        J = np.zeros((2, p.shape[0], 3))
        J[0, top_nodes, 2] = 1.0 / top_nodes.size
        J[0, bottom_nodes, 2] = -1.0 / bottom_nodes.size
        d = p[:, :2] - axis
        r2 = np.sum(d**2, axis=1)
        dtheta = np.stack([-d[:, 1] / r2, d[:, 0] / r2], axis=1)  # (N, 2)
        J[1, top_nodes, :2] = dtheta[top_nodes] / top_nodes.size
        J[1, bottom_nodes, :2] = -dtheta[bottom_nodes] / bottom_nodes.size
        return J.reshape(2, -1)

    return ShapeOutput(("height", "twist"), ("m", "rad"), value, jacobian)


# ------------------------------------------------------------------------------ sensitivities
def sensitivities(
    eq: EquilibriumResult, output: ShapeOutput, reference: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(dy/du, dT/du, dx/du)`` of the equilibrium with Eckart's gauge to ``reference``.

    From ``dQ/dx dx + dQ/du du = 0`` and the 6 linearized gauge conditions (solved in the least
    squares sense; consistent, so exact), tensions ``T = k (l - L0 + u)``.  With joints and
    supports, in the admitted motions ``x = Z eta`` (``dQ/dx`` the Hessian of the Lagrangian, as
    in :func:`~tensegrity.analysis.linearize.linearize`) and with the gauge of the rigid-body
    motions they admit.
    """
    from tensegrity.analysis.equilibrium import eckart_gauge, force_scales

    s = eq.structure
    require_spatial(s)
    chart = Chart.at(s, eq.q)
    x0 = np.zeros(chart.size)
    st = statics(chart, x0, eq.rest_length)
    st = with_reactions(chart, st)  # the reactions' share of the rods' geometric stiffness
    dQdx = force_jacobian(chart, x0, st)
    A_eq = equilibrium_matrix(chart, st.tendons.direction)
    taut = st.tendons.length > eq.rest_length
    k = np.where(taut, s.tendon_stiffness, 0.0)
    dQdu = A_eq * k
    J = chart.jacobian_matrix(x0)
    gauge = eckart_gauge(s, eq.q, reference, True, force_scales(s)[0])
    G = np.zeros((0, chart.size)) if gauge is None else gauge.jacobian(J)
    Z = chart.admitted_motions()
    if Z is not None:  # in the admitted motions x = Z eta
        dQdx, dQdu, A_eq, J, G = Z.T @ dQdx @ Z, Z.T @ dQdu, Z.T @ A_eq, J @ Z, G @ Z
    lhs = np.vstack([dQdx, G])
    rhs = -np.vstack([dQdu, np.zeros((G.shape[0], s.n_tendons))])
    dxdu, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    dydu = output.jacobian(eq.node_position) @ J @ dxdu
    dldu = -A_eq.T @ dxdu
    dTdu = k[:, None] * (dldu + np.eye(s.n_tendons))
    if Z is not None:
        dxdu = Z @ dxdu
    return dydu, dTdu, dxdu


# ------------------------------------------------------------------------------ open loop
@dataclasses.dataclass(frozen=True, eq=False)
class QuasiStatic:
    """An open-loop sequence of equilibria (``K`` steps, the initial equilibrium first).

    Attributes
    ----------
    equilibria : the K equilibria (all in the frame of the first).
    control : (K, S) rest-length changes ``u`` [m].  outputs : (K, ny) achieved.
    targets : (K, ny) wanted (NaN where an output is free in that phase).
    phase : (K,) index of the phase of each step.  min_tension : (K,) [N].
    final_error : (ny,) achieved minus wanted at the end.  reached : within ``tolerance``.
    """

    structure: Structure
    output: ShapeOutput
    bounds: Bounds
    equilibria: tuple[EquilibriumResult, ...]
    control: np.ndarray
    outputs: np.ndarray
    targets: np.ndarray
    phase: np.ndarray
    min_tension: np.ndarray
    final_error: np.ndarray
    tolerance: np.ndarray
    reached: bool
    message: str

    @property
    def reference(self) -> np.ndarray:
        return self.equilibria[0].node_position


def _step_control(dydu, dTdu, want_dy, free, T, u, bounds: Bounds, low, high, active):
    """Minimum-norm ``du`` with ``dydu du = want_dy`` (constrained outputs), ``u + du`` within
    ``[low, high]`` and ``T + dTdu du >= min_tension`` (SLSQP); only the ``active`` tendons move."""
    fixed = ~free
    du = np.zeros(u.size)
    dydu, dTdu, u, low, high = (
        dydu[:, active],
        dTdu[:, active],
        u[active],
        low[active],
        high[active],
    )
    S = u.size
    constraints = [
        {"type": "ineq", "fun": lambda d: T + dTdu @ d - bounds.min_tension, "jac": lambda d: dTdu}
    ]
    if fixed.any():
        Af, bf = dydu[fixed], want_dy[fixed]
        constraints.append({"type": "eq", "fun": lambda d: Af @ d - bf, "jac": lambda d: Af})
        d0, *_ = np.linalg.lstsq(Af, bf, rcond=None)
    else:
        d0 = np.zeros(S)
    fit = scipy.optimize.minimize(
        lambda d: 0.5 * float(d @ d),
        np.clip(d0, low - u, high - u),
        jac=lambda d: d,
        bounds=list(zip(low - u, high - u, strict=True)),
        constraints=constraints,
        method="SLSQP",
        options={"maxiter": 200, "ftol": 1e-14},
    )
    du[active] = fit.x
    return du, fit


def quasi_static(
    structure: Structure,
    output: ShapeOutput,
    phases: Sequence[Sequence[float | None] | dict[str, Any]],
    *,
    start: EquilibriumResult | None = None,
    steps: int | Sequence[int] = 10,
    bounds: Bounds = Bounds(),
    tolerance: Sequence[float] | None = None,
    max_corrections: int = 8,
) -> QuasiStatic:
    """Drive the outputs through ``phases`` by a sequence of equilibria.

    Parameters
    ----------
    phases : one per phase: its final targets, one entry per output (``None``: free in that
        phase), or a dict ``{"targets": [...], "actuators": "t1_*"}`` to move only the tendons
        matching a pattern (see :func:`~tensegrity.analysis.controllability.resolve_inputs`;
        the others keep their ``u``).  Within a phase the constrained outputs move linearly from
        their values at the phase's start to its targets in ``steps`` equal steps.
    start : the initial equilibrium (default :func:`find_equilibrium` from the structure).
    tolerance : per output, for ``reached`` (default 1e-6 m / 1e-6 rad).
    """
    require_spatial(structure)
    eq = find_equilibrium(structure) if start is None else start
    ny = len(output.names)
    tol = np.full(ny, 1e-6) if tolerance is None else np.asarray(tolerance, float)
    steps_list = [steps] * len(phases) if isinstance(steps, int) else list(steps)
    stepper = _Stepper(structure, output, eq.node_position, bounds, *bounds.u_limits(structure))
    plan = _Sequence(
        [eq], [eq.control.copy()], [output.value(eq.node_position)], [np.full(ny, np.nan)], [0]
    )
    u = eq.control.copy()
    message = "reached every target"
    # a ``steps`` list shorter than ``phases`` ends the sequence early (unchecked, as it was)
    for k, (spec, n_steps) in enumerate(zip(phases, steps_list, strict=False)):
        eq, u, failure = _run_phase(stepper, plan, eq, u, k, spec, n_steps, tol, max_corrections)
        if failure is not None:
            message = failure
        if not eq.converged:
            break
    return plan.result(stepper, tol, message)


@dataclasses.dataclass(frozen=True)
class _Stepper:
    """One step of :func:`quasi_static`: a control change towards the wanted outputs, then the
    equilibrium for it (in the frame of ``reference``)."""

    structure: Structure
    output: ShapeOutput
    reference: np.ndarray
    bounds: Bounds
    low: np.ndarray
    high: np.ndarray

    def advance(
        self,
        eq: EquilibriumResult,
        u: np.ndarray,
        want: np.ndarray,
        free: np.ndarray,
        active: np.ndarray,
    ) -> tuple[EquilibriumResult, np.ndarray]:
        """The equilibrium and control after a step from ``eq``, ``u`` towards ``want``."""
        y = self.output.value(eq.node_position)
        dydu, dTdu, _ = sensitivities(eq, self.output, self.reference)
        du, _ = _step_control(
            dydu,
            dTdu,
            np.where(free, 0.0, want - y),
            free,
            eq.tension,
            u,
            self.bounds,
            self.low,
            self.high,
            active,
        )
        u_new = np.clip(u + du, self.low, self.high)
        new = find_equilibrium(self.structure, eq.q, control=u_new, gauge_reference=self.reference)
        return new, u_new

    def correct(
        self,
        eq: EquilibriumResult,
        u: np.ndarray,
        want: np.ndarray,
        free: np.ndarray,
        active: np.ndarray,
        tol: np.ndarray,
        max_corrections: int,
    ) -> tuple[EquilibriumResult, np.ndarray]:
        """Newton-like steps to ``want`` until within a tenth of ``tol`` (at most
        ``max_corrections``)."""
        for _ in range(max_corrections):
            err = np.where(free, 0.0, self.output.value(eq.node_position) - want)
            if np.all(np.abs(err) <= 0.1 * tol):
                break
            eq, u = self.advance(eq, u, want, free, active)
        return eq, u


def _actuated(structure: Structure, spec: Sequence[float | None] | dict[str, Any]) -> np.ndarray:
    """(S,) the tendons a phase moves: its ``"actuators"`` pattern's, or every tendon."""
    active = np.ones(structure.n_tendons, bool)
    if isinstance(spec, dict) and spec.get("actuators") is not None:
        active[:] = False
        for name in match_tendons(structure, spec["actuators"]):
            active[structure.tendon_index(name)] = True
    return active


def _run_phase(
    stepper: _Stepper,
    plan: _Sequence,
    eq: EquilibriumResult,
    u: np.ndarray,
    k: int,
    spec: Sequence[float | None] | dict[str, Any],
    n_steps: int,
    tol: np.ndarray,
    max_corrections: int,
) -> tuple[EquilibriumResult, np.ndarray, str | None]:
    """Phase ``k`` of :func:`quasi_static` from ``eq``, ``u``: its steps added to ``plan``; the
    last equilibrium and control, and why the phase stopped short (None if it did not)."""
    targets = spec["targets"] if isinstance(spec, dict) else spec
    active = _actuated(stepper.structure, spec)
    free = np.array([t is None for t in targets])
    final = np.array([np.nan if t is None else float(t) for t in targets])
    y_start = stepper.output.value(eq.node_position)
    for j in range(1, n_steps + 1):
        want = np.where(free, np.nan, y_start + (final - y_start) * j / n_steps)
        eq, u = stepper.advance(eq, u, want, free, active)
        if not eq.converged:
            return eq, u, f"phase {k}, step {j}: equilibrium not found ({eq.message})"
        # corrections at the end of the phase
        if j == n_steps:
            eq, u = stepper.correct(eq, u, want, free, active, tol, max_corrections)
        plan.add(eq, u, stepper.output.value(eq.node_position), want, k)
    return eq, u, None


@dataclasses.dataclass
class _Sequence:
    """The steps of :func:`quasi_static` so far: equilibria, controls, outputs, targets, phases."""

    eqs: list[EquilibriumResult]
    controls: list[np.ndarray]
    ys: list[np.ndarray]
    wants: list[np.ndarray]
    phase_of: list[int]

    def add(
        self, eq: EquilibriumResult, u: np.ndarray, y: np.ndarray, want: np.ndarray, k: int
    ) -> None:
        self.eqs.append(eq)
        self.controls.append(u.copy())
        self.ys.append(y)
        self.wants.append(want)
        self.phase_of.append(k)

    def result(self, stepper: _Stepper, tol: np.ndarray, message: str) -> QuasiStatic:
        """The sequence with its final error and verdict (``message`` explains a miss)."""
        eqs, bounds = self.eqs, stepper.bounds
        ys_a, wants_a = np.array(self.ys), np.array(self.wants)
        final_targets = wants_a[-1]
        err = np.where(np.isnan(final_targets), 0.0, ys_a[-1] - final_targets)
        min_t = np.array([e.tension.min() for e in eqs])
        rest_ok = all(np.all(e.rest_length >= bounds.min_rest_length - 1e-12) for e in eqs)
        reached = bool(
            np.all(np.abs(err) <= tol)
            and min_t.min() >= bounds.min_tension * (1 - 1e-6)
            and rest_ok
            and all(e.converged for e in eqs)
            and message.startswith("reached")
        )
        if not reached and message.startswith("reached"):
            message = (
                f"missed: error {err.tolist()} (tolerance {tol.tolist()}), min tension "
                f"{min_t.min():.4g} N, rest lengths within bounds: {rest_ok}"
            )
        return QuasiStatic(
            stepper.structure,
            stepper.output,
            bounds,
            tuple(eqs),
            np.array(self.controls),
            ys_a,
            wants_a,
            np.array(self.phase_of),
            min_t,
            err,
            tol,
            reached,
            message,
        )


# ------------------------------------------------------------------------------ closed loop
@dataclasses.dataclass(frozen=True, eq=False)
class ClosedLoop:
    """A closed-loop run on the nonlinear model.

    Attributes
    ----------
    t : (T,) [s].  q, qdot : (T, 6R).  node_position : (T, N, 3) aligned onto the reference.
    control : (T, S) commanded ``u`` [m] (applied as commanded without actuators).
    tension : (T, S) [N].  outputs : (T, ny).
    reference_outputs : (T, ny) of the feed-forward path.  final_error : (ny,) vs. the last target.
    min_tension : smallest tension over the run [N].  min_rest_length : smallest ``Lbar`` [m].
    reached : final error within tolerance, no tendon slack at any sample, bounds respected.
    """

    structure: Structure
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    node_position: np.ndarray
    control: np.ndarray
    tension: np.ndarray
    outputs: np.ndarray
    reference_outputs: np.ndarray
    final_error: np.ndarray
    tolerance: np.ndarray
    min_tension: float
    min_rest_length: float
    max_rod_length_error: float
    saturated: bool
    reached: bool
    message: str
    gains: int
    nfev: int


class _Schedule:
    """Feed-forward and LQR gains along the quasi-static sequence, played at ``times``."""

    def __init__(
        self,
        plan: QuasiStatic,
        times: np.ndarray,
        gain_steps: Sequence[int],
        weights: tuple[float, float, float, float],
        period: float,
    ):
        self.plan, self.times = plan, times
        s = plan.structure
        self.gain_steps = list(gain_steps)
        self.gains = {}
        for k in self.gain_steps:
            self.gains[k] = _lqr_gain(s, plan.equilibria[k], plan.output, weights, period)
        self.charts = {k: Chart.at(s, plan.equilibria[k].q) for k in range(len(plan.equilibria))}
        #: the next equilibrium in the chart of each step
        self.x_next = {
            k: self.charts[k].x(plan.equilibria[k + 1].q) for k in range(len(plan.equilibria) - 1)
        }

    def segment(self, t: float) -> tuple[int, float]:
        k = int(np.clip(np.searchsorted(self.times, t, side="right") - 1, 0, len(self.times) - 1))
        if k == len(self.times) - 1:
            return k, 0.0
        return k, (t - self.times[k]) / (self.times[k + 1] - self.times[k])

    def feedforward(self, t: float):
        """``(u_ff, chart, x_ff, xdot_ff, gain)`` at time ``t`` (chart of the segment's start)."""
        k, frac = self.segment(t)
        chart = self.charts[k]
        u = self.plan.control
        if frac == 0.0 and k == len(self.times) - 1:
            return u[k], chart, np.zeros(chart.size), np.zeros(chart.size), self._gain(k)
        x_next = self.x_next[k]
        dt = self.times[k + 1] - self.times[k]
        return (
            u[k] + frac * (u[k + 1] - u[k]),
            chart,
            frac * x_next,
            x_next / dt,
            self._gain(k + (frac >= 0.5)),
        )

    def _gain(self, k: int):
        nearest = min(self.gain_steps, key=lambda g: abs(g - k))
        return self.gains[nearest]


def _lqr_gain(
    s: Structure,
    eq: EquilibriumResult,
    output: ShapeOutput,
    weights: tuple[float, float, float, float],
    period: float,
) -> tuple[np.ndarray, np.ndarray]:
    """LQR gain on the modes the tendons reach at ``eq``
    (:func:`~tensegrity.analysis.control_design.lqr` on
    :func:`~tensegrity.analysis.control_design.reachable`), as ``(Kx, Kv)`` on the chart
    coordinates: ``du = -K [a; a'] = -Kx dx - Kv dx'`` with ``a = W eta`` the reached modes'
    amplitudes and ``eta = Z_c^T M dx`` for joints and supports (``Z_c`` their admitted motions),
    ``eta = dx`` otherwise.  Weights ``(q_out, q_state, q_rate, r_u)``: the outputs, the modes'
    amplitudes and rates, the controls."""
    from tensegrity.analysis.control_design import lqr, reachable
    from tensegrity.analysis.linearize import linearize

    lin = linearize(s, eq)
    model = reachable(lin)
    r = model.shapes.shape[1]
    Cy = output.jacobian(eq.node_position) @ lin.position_jacobian @ model.shapes
    q_out, q_state, q_rate, r_u = weights
    Q = np.zeros((2 * r, 2 * r))
    Q[:r, :r] = q_out * Cy.T @ Cy + q_state * np.eye(r)
    Q[r:, r:] = q_rate * np.eye(r)
    K = lqr(model, period=period, Q=0.5 * (Q + Q.T), R=r_u * np.eye(s.n_tendons)).gain
    T = model.projection
    if lin.basis is not None:
        T = T @ (lin.basis.T * mass_matrix(s))
    return K[:, :r] @ T, K[:, r:] @ T


def closed_loop(
    plan: QuasiStatic,
    *,
    move_time: float = 2.0,
    settle_time: float = 3.0,
    gain_every: int | None = None,
    weights: tuple[float, float, float, float] = (1e3, 0.0, 0.1, 10.0),
    sample_dt: float = 0.02,
    control_dt: float = 0.005,
    rtol: float = 1e-8,
    plant: Structure | None = None,
    actuators: Actuators | None = None,
) -> ClosedLoop:
    """Play the quasi-static plan in time with LQR feedback, on the nonlinear model.

    The K - 1 steps of the plan share ``move_time`` [s] per phase equally; then ``settle_time``
    [s] at the final target.  ``u = u_ff(t) - K_k [W (x - x_ff(t)); W (x' - x'_ff(t))]``
    (``W``: the reached modes' amplitudes of ``to_eta(x)``, ``ReachableModel.projection``)
    with ``x`` the reduced coordinates of the (aligned) state in the chart of the current step,
    and ``K_k`` the LQR gain (weights ``(q_out, q_state, q_rate, r_u)``: outputs, the modes'
    amplitudes and rates, controls) at the nearest of every ``gain_every``-th equilibrium
    (default: one gain, designed at the final equilibrium; ``control.lqr`` costs about 4 s for
    a (4,2) shell).  The controller runs every ``control_dt`` [s] with zero-order hold, through
    the engine's controller hook (:func:`tensegrity.engine.simulate.simulate` with
    ``controller=``; DOP853 at ``rtol``, steps ending at the updates).  ``u`` is clipped to the
    bounds (``saturated`` tells if it ever was).  ``plant``: the structure simulated (default
    the plan's; e.g. with damping).  ``actuators``: between the law and the tendons, as the
    hardware has them (:func:`tensegrity.model.actuators.actuators`: rate limits [m/s], lags
    [s]; default none, ``u`` applied as commanded); ``saturated`` then also tells if an
    actuator ever reached a limit (the run's :meth:`~SimulationResult.saturations`).
    """
    s = plan.structure
    plant = s if plant is None else plant
    times = _plan_times(plan, move_time)
    t_end = times[-1] + settle_time
    gain_steps = sorted(
        {len(plan.equilibria) - 1}
        if gain_every is None
        else set(range(0, len(plan.equilibria), gain_every)) | {len(plan.equilibria) - 1}
    )
    law = _FeedbackLaw(plan, _Schedule(plan, times, gain_steps, weights, control_dt))
    q0 = plan.equilibria[0].q
    run = simulate(
        plant,
        (0.0, t_end),
        initial=dynamics.State(0.0, q0, np.zeros_like(q0)),
        controller=Feedback(law, control_dt),
        actuators=actuators,
        sample_dt=sample_dt,
        rtol=rtol,
        atol=1e-10,
    )
    return _closed_loop_result(plan, plant, run, law, times, len(gain_steps))


def _plan_times(plan: QuasiStatic, move_time: float) -> np.ndarray:
    """When the plan reaches each of its equilibria [s]: ``move_time`` per phase, shared
    equally by the phase's steps."""
    phase = plan.phase
    per_phase = {k: int(np.sum(phase[1:] == k)) for k in np.unique(phase[1:])}
    durations = [move_time / per_phase[phase[k]] for k in range(1, len(plan.equilibria))]
    return np.concatenate([[0.0], np.cumsum(durations)])


class _FeedbackLaw:
    """The LQR law along the plan, clipped to the bounds; keeps every update ``(t, u)``."""

    def __init__(self, plan: QuasiStatic, schedule: _Schedule) -> None:
        s = plan.structure
        self.plan, self.schedule = plan, schedule
        self.low, self.high = plan.bounds.u_limits(s)
        self.supported = has_supports(s)
        self.saturated = False
        self.times: list[float] = []
        self.controls: list[np.ndarray] = []

    def __call__(self, t: float, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
        s = self.plan.structure
        u_ff, chart, x_ff, v_ff, (Kx, Kv) = self.schedule.feedforward(t)
        if self.supported:  # the supports hold the frame
            qa, va = q, qdot
        else:
            p = dynamics.nodes_from_coordinates(s, q)
            v = dynamics.nodes_from_coordinates(s, qdot)
            pa, R = kabsch(p, self.plan.reference, s.node_mass)
            qa = dynamics.coordinates_from_nodes(s, pa)
            va = dynamics.coordinates_from_nodes(s, v @ R)
        u = u_ff - Kx @ (chart.x(qa) - x_ff) - Kv @ (chart.velocity_x(qa, va) - v_ff)
        clipped = np.clip(u, self.low, self.high)
        self.saturated = self.saturated or bool(np.any(clipped != u))
        self.times.append(t)
        self.controls.append(clipped)
        return clipped

    def held_at(self, t: np.ndarray) -> np.ndarray:
        """The control in effect at the sample times ``t`` (T,): the last update before each
        (a sample at an update time is recorded before the update)."""
        index = np.searchsorted(np.array(self.times), t, side="left") - 1
        return np.array(self.controls)[np.clip(index, 0, len(self.times) - 1)]


def _closed_loop_result(
    plan: QuasiStatic,
    plant: Structure,
    run: SimulationResult,
    law: _FeedbackLaw,
    times: np.ndarray,
    gains: int,
) -> ClosedLoop:
    """The :class:`ClosedLoop` of an engine run: outputs, errors, bounds and the verdict."""
    s = plan.structure
    P = run.node_position
    aligned = P if law.supported else align(P, plan.reference, s.node_mass)
    controls = law.held_at(run.t)
    ys = np.array([plan.output.value(p) for p in aligned])
    ref_ys = np.array([_interp_outputs(plan, times, tt) for tt in run.t])
    final_target = plan.targets[-1]
    err = np.where(np.isnan(final_target), 0.0, ys[-1] - final_target)
    rest = plant.tendon_rest_length - controls
    tension = run.tendon_tension
    complete = run.status == STATUS_END
    reached = bool(
        complete
        and np.all(np.abs(err) <= plan.tolerance)
        and tension.min() > 0
        and rest.min() >= plan.bounds.min_rest_length - 1e-12
    )
    message = (
        f"{'reached' if reached else 'missed'}: final error {np.abs(err).tolist()} "
        f"(tolerance {plan.tolerance.tolist()}), min tension {tension.min():.4g} N, "
        f"min rest length {rest.min():.4g} m"
        + ("" if complete else f"; integration failed: {run.message}")
    )
    return ClosedLoop(
        s,
        run.t,
        run.q,
        run.qdot,
        aligned,
        controls,
        tension,
        ys,
        ref_ys,
        err,
        plan.tolerance,
        float(tension.min()),
        float(rest.min()),
        run.max_rod_length_error,
        law.saturated or bool(run.saturations()),
        reached,
        message,
        gains,
        run.nfev,
    )


def _interp_outputs(plan: QuasiStatic, times: np.ndarray, t: float) -> np.ndarray:
    y = plan.outputs
    return np.array([np.interp(t, times, y[:, j]) for j in range(y.shape[1])])


def describe_plan(plan: QuasiStatic) -> dict[str, Any]:
    """JSON-ready summary of an open-loop plan."""
    return {
        "outputs": list(plan.output.names),
        "units": list(plan.output.units),
        "steps": len(plan.equilibria),
        "reached": plan.reached,
        "message": plan.message,
        "initial_outputs": plan.outputs[0].tolist(),
        "final_outputs": plan.outputs[-1].tolist(),
        "final_targets": [None if np.isnan(v) else float(v) for v in plan.targets[-1]],
        "final_error": plan.final_error.tolist(),
        "tolerance": plan.tolerance.tolist(),
        "min_tension_N": float(plan.min_tension.min()),
        "min_rest_length_m": float(min(e.rest_length.min() for e in plan.equilibria)),
        "final_control_m": dict(
            zip(plan.structure.tendon_name, plan.control[-1].tolist(), strict=True)
        ),
    }
