"""Feedback design on the part of the linear model that rest-length inputs reach.

``control.lqr`` on the whole of :meth:`Linearization.statespace
<tensegrity.analysis.linearize.Linearization.statespace>` fails ("Failed to find a finite
solution"): a free structure's six rigid-body motions, and every mode that the chosen tendons'
rest-length changes do not move, are not stabilizable.  :func:`reachable` reduces the model to
the modes the inputs reach (:class:`ReachableModel`: a named ``control.StateSpace`` and the list
of the modes left out, each with its reason); :func:`lqr` and :func:`place` design on it
(``control.lqr``; scipy's ``place_poles``, as ``control.place``) and return the gain in the
structure's own coordinates as a :class:`~tensegrity.engine.feedback.LinearFeedback`
(:class:`Design`).

Coordinates (``k`` degrees of freedom, ``M`` the mass diagonal of the linearization):

- ``x``: the chart coordinates of :class:`~tensegrity.analysis.coordinates.Chart` (per rod the
  centre displacement and two angles, point-mass displacements).
- ``eta`` of :meth:`Linearization.to_eta`: the linearization's own state coordinates,
  ``z = [eta, eta']`` of ``A``, ``B``, ``C``.  ``eta = x`` without joints and supports; with
  them ``eta = Z_c^T M x``, the coordinates of the admitted motions ``x = Z_c eta``.
- ``eta_e`` of :meth:`Linearization.elastic_part`: coordinates of the non-rigid part *inside*
  ``eta``, ``eta = Z_e eta_e`` with ``Z_e`` the ``M``-orthonormal complement of the rigid-body
  motions (``eta_e = Z_e^T M eta``).  So ``to_eta`` and ``elastic_part`` are two stages of one
  chain ``x -> eta -> eta_e``, not two names of one thing.
- ``a``: this module's reduced coordinates, the amplitudes of the reached mode shapes ``V_r``
  (columns of :class:`~tensegrity.analysis.modes.ModalAnalysis`'s ``shapes``, ``M``-orthonormal,
  in ``eta``): ``a = V_r^T M eta`` (:attr:`ReachableModel.projection`), ``eta = V_r a`` on the
  reached part.  The reduced state is ``[a, a']``.

Which modes are reached: a cluster of modes of equal frequency is reached in as many directions
as the rank of its shapes' projection on the inputs' force pattern ``V_j^T dQ/du`` (the PBH test
of :func:`~tensegrity.analysis.controllability.controllability`, same tolerance); a cluster
reached in fewer directions is split by that projection's singular vectors (the reached directions
carry the cluster's first mode numbers).  Rigid-body motions are never reached: tendon forces are
internal.  A damping that couples a mode left out to a reached one (``V_u^T C V_r != 0``, e.g. the
damping of tendons that are not inputs) moves it into the reduced model, until none couples: the
modes left out are then exactly invariant and decoupled, so the closed loop of the whole model is
that of the reduced model plus the modes left out, unchanged.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from tensegrity.analysis.controllability import (
    PBH_RTOL,
    ModeTest,
    controllability,
    resolve_inputs,
)
from tensegrity.analysis.linearize import Linearization
from tensegrity.analysis.modes import ELASTIC, RIGID, ModalAnalysis, modal_analysis
from tensegrity.engine.feedback import LinearFeedback

__all__ = ["Design", "LeftOut", "ReachableModel", "lqr", "place", "reachable"]


@dataclasses.dataclass(frozen=True)
class LeftOut:
    """A mode the inputs do not reach (or a direction of a cluster of equal frequency)."""

    mode: int  #: its number in the :class:`ModalAnalysis` (the cluster's, for a split one)
    frequency_hz: float  #: [Hz]
    kind: str  #: ``"rigid"``, ``"mechanism"``, ``"elastic"`` or ``"unstable"``
    reason: str  #: why no input reaches it

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


@dataclasses.dataclass(frozen=True, eq=False)
class ReachableModel:
    """The linear model reduced to the modes that the inputs reach.

    Attributes
    ----------
    linearization, modes : the model reduced and its modes.
    tendons : the A input tendons' names (the columns of ``B``).
    system : ``control.StateSpace`` with states ``[a, a']`` (2r,), named
        ``mode{j}_{f}mHz`` and ``mode{j}_{f}mHz_rate`` (``f`` the frequency in millihertz), the
        tendons' rest-length changes [m] as inputs and the linearization's outputs (node
        positions, tendon lengths, tensions).
    shapes : ``V_r`` (k, r), the reached mode shapes in ``eta``, ``M``-orthonormal.
    frequency_hz : (r,) their frequencies [Hz].  mode_index : (r,) their numbers in ``modes``.
    left_out : the modes not in the reduced model, each with its reason.
    damping_moved : modes that no input reaches but the damping couples to reached ones (moved
        into the reduced model).
    """

    linearization: Linearization
    modes: ModalAnalysis
    tendons: tuple[str, ...]
    system: Any
    shapes: np.ndarray
    frequency_hz: np.ndarray
    mode_index: np.ndarray
    left_out: tuple[LeftOut, ...]
    damping_moved: tuple[int, ...]

    @property
    def projection(self) -> np.ndarray:
        """``W = V_r^T M`` (r, k): the reduced coordinates ``a = W eta`` of ``eta``."""
        return self.shapes.T * self.linearization.mass

    def reduce(self, z: np.ndarray) -> np.ndarray:
        """The reduced state ``[a, a']`` (2r,) of a linearization state ``z = [eta, eta']``
        (2k,)."""
        k = self.linearization.n_dof
        W = self.projection
        return np.concatenate([W @ z[:k], W @ z[k:]])

    def node_map(self) -> np.ndarray:
        """``W J^+`` (r, N * dim): the reduced coordinates of a change of the node positions
        (node by node, x, y[, z]) [m], exact for changes on the constraints' tangent
        (``dp = J deta``, ``J`` the linearization's ``position_jacobian``)."""
        return self.projection @ np.linalg.pinv(_node_jacobian(self.linearization))


@dataclasses.dataclass(frozen=True, eq=False)
class Design:
    """A feedback design on a :class:`ReachableModel`.

    Attributes
    ----------
    model : the reduced model designed on.
    gain : ``K_r`` (A, 2r), ``du = -K_r [a, a']``.
    feedback : the same law on the node positions and velocities
        (``u = u_ref - K (y - y_ref)``, exact for states on the constraints' tangent).
    closed_loop_poles : (2r,) eigenvalues of ``A_r - B_r K_r`` [1/s].
    uncontrolled : the modes left out (:attr:`ReachableModel.left_out`): the closed loop leaves
        them as they are.
    """

    model: ReachableModel
    gain: np.ndarray
    feedback: LinearFeedback
    closed_loop_poles: np.ndarray

    @property
    def uncontrolled(self) -> tuple[LeftOut, ...]:
        return self.model.left_out

    @property
    def slowest_decay(self) -> float:
        """The smallest decay rate ``-Re(lambda)`` of the closed-loop poles [1/s]."""
        return float(np.min(-self.closed_loop_poles.real))


def reachable(
    lin: Linearization,
    inputs: str | Sequence[str] = "all",
    *,
    modes: ModalAnalysis | None = None,
    pbh_rtol: float = PBH_RTOL,
) -> ReachableModel:
    """The linear model ``lin`` reduced to the modes that the tendons ``inputs`` reach.

    Parameters
    ----------
    lin : the linearization about an equilibrium.
    inputs : the actuated tendons: ``"all"``, comma-separated names or fnmatch patterns, or a
        list (:func:`~tensegrity.analysis.controllability.resolve_inputs`).
    modes : the modes of ``lin`` (default :func:`~tensegrity.analysis.modes.modal_analysis`).
    pbh_rtol : singular values of ``V_j^T dQ/du`` below this times the mass-scaled input norm
        count as zero (the PBH test's tolerance).

    Returns
    -------
    ReachableModel
        ``KeyError`` if ``inputs`` matches no tendon.
    """
    modes = modal_analysis(lin) if modes is None else modes
    names = resolve_inputs(lin, inputs)
    cols = lin.input_indices(names)
    Bf = lin.force_input[:, cols]
    test = controllability(lin, modes, names, pbh_rtol=pbh_rtol)
    reached: list[tuple[np.ndarray, int]] = []  # (shape, mode number)
    out: list[tuple[np.ndarray, int, ModeTest]] = []
    for t in test.mode_tests:
        V = modes.shapes[:, list(t.modes)]
        rank = 0 if t.kind == RIGID else t.rank
        U, _, _ = np.linalg.svd(V.T @ Bf)  # reached directions first
        V = V @ U
        reached += [(V[:, i], t.modes[i]) for i in range(rank)]
        out += [(V[:, i], t.modes[i], t) for i in range(rank, len(t.modes))]
    moved = _damping_closure(lin, reached, out, pbh_rtol)
    reached.sort(key=lambda item: item[1])
    shapes = np.column_stack([v for v, _ in reached]) if reached else np.zeros((lin.n_dof, 0))
    index = np.array([j for _, j in reached], dtype=int)
    left = tuple(_left_out(lin, modes, v, j, t) for v, j, t in out)
    system = _system(lin, names, shapes, modes.frequency_hz[index], index)
    return ReachableModel(
        lin, modes, names, system, shapes, modes.frequency_hz[index], index, left, moved
    )


def _damping_closure(
    lin: Linearization,
    reached: list[tuple[np.ndarray, int]],
    out: list[tuple[np.ndarray, int, ModeTest]],
    rtol: float,
) -> tuple[int, ...]:
    """Move from ``out`` to ``reached`` (in place) every direction that the damping couples to
    a reached one, until none does; returns the mode numbers moved."""
    C = lin.damping
    scale = float(np.linalg.norm(C / np.sqrt(np.outer(lin.mass, lin.mass)), 2))
    moved: list[int] = []
    while reached and out and scale > 0:
        R = np.column_stack([v for v, _ in reached])
        coupled = [i for i, (v, _, _) in enumerate(out) if np.linalg.norm(v @ C @ R) > rtol * scale]
        if not coupled:
            break
        for i in reversed(coupled):
            v, j, _ = out.pop(i)
            reached.append((v, j))
            moved.append(j)
    return tuple(sorted(moved))


def _left_out(
    lin: Linearization, modes: ModalAnalysis, v: np.ndarray, j: int, t: ModeTest
) -> LeftOut:
    """Why the direction ``v`` (mode ``j``, of the cluster tested by ``t``) is left out."""
    f = float(modes.frequency_hz[j])
    if t.kind == RIGID:
        reason = "rigid-body motion: tendon forces are internal"
    else:
        # lengths changed by v, against the largest a unit modal motion can change
        stretch = np.linalg.norm(lin.equilibrium_matrix.T @ v)
        reference = np.linalg.norm(lin.equilibrium_matrix.T / np.sqrt(lin.mass), 2)
        if stretch <= PBH_RTOL * reference:
            reason = "changes no tendon length to first order: a mechanism of rods and tendons" + (
                ", stiffened by the prestress" if t.kind == ELASTIC else ""
            )
        else:
            reason = "the actuated tendons' forces do not move it (other tendons would)"
    return LeftOut(int(j), f, str(t.kind), reason)


def _node_jacobian(lin: Linearization) -> np.ndarray:
    """``dp/deta`` (N * dim, k) in the node coordinates of the structure as given (a planar
    one's x, y)."""
    J = lin.position_jacobian
    dim = lin.source.dim
    if dim == 3:
        return J
    return J.reshape(-1, 3, J.shape[1])[:, :dim].reshape(-1, J.shape[1])


def _mode_names(frequency_hz: np.ndarray, index: np.ndarray) -> list[str]:
    names = [f"mode{j}_{round(1e3 * f)}mHz" for j, f in zip(index, frequency_hz, strict=True)]
    return names + [f"{name}_rate" for name in names]


def _system(
    lin: Linearization,
    names: tuple[str, ...],
    shapes: np.ndarray,
    frequency_hz: np.ndarray,
    index: np.ndarray,
) -> Any:
    """The named ``control.StateSpace`` of the reduced model (see :class:`ReachableModel`)."""
    import control

    full = lin.statespace(list(names))
    k, r = lin.n_dof, shapes.shape[1]
    W = shapes.T * lin.mass
    T = np.zeros((2 * k, 2 * r))
    T[:k, :r], T[k:, r:] = shapes, shapes
    P = np.zeros((2 * r, 2 * k))
    P[:r, :k], P[r:, k:] = W, W
    A = P @ lin.A @ T
    A[r:, :r] = 0.5 * (A[r:, :r] + A[r:, :r].T)  # a symmetric stiffness, to round-off
    return control.ss(
        A,
        P @ full.B,
        full.C @ T,
        full.D,
        inputs=full.input_labels,
        outputs=full.output_labels,
        states=_mode_names(frequency_hz, index),
    )


def _design(model: ReachableModel, gain: np.ndarray, period: float) -> Design:
    """The :class:`Design` of the reduced gain ``gain`` (A, 2r), the law run every ``period``."""
    lin = model.linearization
    r = model.shapes.shape[1]
    node = model.node_map()
    K = np.hstack([gain[:, :r] @ node, gain[:, r:] @ node])
    eq = lin.equilibrium
    p_ref = eq.node_position[:, : lin.source.dim].ravel()
    cols = lin.input_indices(list(model.tendons))
    feedback = LinearFeedback(
        K,
        np.concatenate([p_ref, np.zeros_like(p_ref)]),
        eq.control[cols],
        period,
        ("position", "velocity"),
        model.tendons,
    )
    A = np.asarray(model.system.A)
    B = np.asarray(model.system.B)
    return Design(model, gain, feedback, np.linalg.eigvals(A - B @ gain))


def lqr(
    model: ReachableModel,
    *,
    period: float,
    Q: np.ndarray | None = None,
    R: np.ndarray | None = None,
) -> Design:
    """LQR state feedback on the reduced model (``control.lqr``).

    Minimizes ``integral of [a, a']^T Q [a, a'] + du^T R du`` on the reduced model.

    Parameters
    ----------
    model : from :func:`reachable`.
    period : the law's update period [s] (the :class:`LinearFeedback`'s).
    Q : (2r, 2r) weight of the reduced states (default ``diag(Omega^2 + omega_1^2, 1)``: the
        modes' stiffness, each raised by the lowest reached frequency squared so that a reached
        mechanism is weighted too, and their rates; ``a`` in sqrt(kg) m, ``a'`` in sqrt(kg) m/s).
    R : (A, A) weight of the inputs (default ``diag(k)`` [N/m], the actuated tendons'
        stiffness: with the default ``Q``, twice the energy of the motion against twice the
        energy a rest-length change ``du`` stores in its tendon).

    Returns
    -------
    Design
        ``ValueError`` naming ``Q`` or ``R`` if their shape does not fit.
    """
    import control

    Q, R = _weights(model, Q, R)
    K, _, _ = control.lqr(model.system.A, model.system.B, Q, R, method="scipy")
    return _design(model, np.asarray(K), period)


def _weights(
    model: ReachableModel, Q: np.ndarray | None, R: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray]:
    """``lqr``'s weights, their defaults filled in and their shapes checked."""
    lin = model.linearization
    r, n_in = model.shapes.shape[1], len(model.tendons)
    if Q is None:
        omega2 = (2 * np.pi * model.frequency_hz) ** 2
        low = float(np.min(omega2[omega2 > 0], initial=1.0))
        Q = np.diag(np.concatenate([omega2 + low, np.ones(r)]))
    if R is None:
        R = np.diag(lin.structure.tendon_stiffness[lin.input_indices(list(model.tendons))])
    Q, R = np.asarray(Q, dtype=float), np.asarray(R, dtype=float)
    if Q.shape != (2 * r, 2 * r):
        raise ValueError(
            f"Q: expected shape ({2 * r}, {2 * r}) (the reduced states), got {Q.shape}"
        )
    if R.shape != (n_in, n_in):
        raise ValueError(f"R: expected shape ({n_in}, {n_in}) (the inputs), got {R.shape}")
    return Q, R


#: Iterations of the YT method's search for well-conditioned closed-loop eigenvectors in
#: :func:`place`.  python-control's ``place`` asks scipy for up to 30: 143 s for the (3,1)
#: shell's 46 states on a loaded 2-core machine.  Measured there with one BLAS thread: 1, 2 and
#: 5 iterations take 0.6, 1.5 and 2.1 s; the eigenvectors' condition numbers are 48.6, 47.2
#: and 47.2, the poles the same to 5e-10 relative.
PLACE_ITERATIONS = 2


def place(model: ReachableModel, poles: Sequence[complex], *, period: float) -> Design:
    """Pole placement on the reduced model (scipy's ``place_poles``, the method of
    ``control.place``, with :data:`PLACE_ITERATIONS` iterations).

    ``poles`` (2r,) are the closed-loop eigenvalues [1/s], complex ones in conjugate pairs, none
    repeated more often than the rank of the input matrix.  More tendons than the modes they
    reach give an input matrix without full column rank, which ``place_poles`` refuses: the
    placement is made with the input directions of its singular value decomposition (its rank's
    worth) and mapped back to the tendons (the gain of least norm in those directions).

    ``ValueError`` naming ``poles`` if their number is not the reduced model's state count, or
    scipy's ``ValueError`` if they cannot be placed.  The closed-loop poles reached are in the
    result (:attr:`Design.closed_loop_poles`); the method's warning that its search for
    well-conditioned eigenvectors did not converge is not shown (the poles are placed all the
    same).
    """
    import scipy.signal

    wanted = np.asarray(poles, dtype=complex)
    n = 2 * model.shapes.shape[1]
    if wanted.shape != (n,):
        raise ValueError(f"poles: expected {n} (the reduced model's states), got {wanted.size}")
    A, B = np.asarray(model.system.A), np.asarray(model.system.B)
    U, sv, Vt = np.linalg.svd(B, full_matrices=False)
    rank = int(np.sum(sv > PBH_RTOL * sv[0])) if sv.size else 0
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", "Convergence was not reached", UserWarning)
        placed = scipy.signal.place_poles(
            A, U[:, :rank] * sv[:rank], wanted, method="YT", maxiter=PLACE_ITERATIONS
        )
    return _design(model, Vt[:rank].T @ placed.gain_matrix, period)
