"""Prestress and form-finding: self-stress states, feasible tensions, rest lengths, form-finding.

At a configuration ``q`` the *equilibrium matrix* ``A`` (5R, S) maps tendon tensions to the
generalized forces on the rods (reduced coordinates of
:mod:`~tensegrity.analysis.coordinates`, so the rods' own axial forces -- whatever they must
be -- never appear): ``Q = A T + J^T w``.  Then

- the *self-stress states* are the null space of ``A`` (tensions in equilibrium with no load),
  of dimension ``s = S - rank A``; the *infinitesimal mechanisms* are the non-rigid motions that
  stretch no tendon to first order, ``m = 5R - 6 - rank A`` (Maxwell's rule
  ``s - m = S - (5R - 6)``);
- a *feasible prestress* is a self-stress with every tendon in tension: the linear program
  ``max t`` subject to ``A T = 0``, ``T_s >= t``, ``mean T = 1`` (``scipy.optimize.linprog``);
  it exists iff the optimum ``t* > 0``;
- the *rest lengths that realize* tensions ``T`` with stiffnesses ``k`` are ``Lbar = l - T / k``;
- *form-finding* (:func:`form_find`) goes from rough geometry to a stable equilibrium.

With joints and supports, ``A`` is restricted to the motions they admit, ``Z^T A`` (``x = Z
eta``, :meth:`~tensegrity.analysis.coordinates.Chart.admitted_motions`): a self-stress may then
push on the supports, whose reactions balance it; Maxwell's rule reads ``s - m = S - (k - r)``
with ``k`` the admitted motions and ``r`` the admitted rigid-body motions, and a rod's axial
force includes the reactions at its ends.  A planar structure is treated in its 3-D form.
"""

from __future__ import annotations

import dataclasses
from typing import Any, NamedTuple

import numpy as np
import scipy.optimize

from tensegrity.analysis.coordinates import (
    Chart,
    admitted_rigid_motions,
    configuration,
    drop_roundoff,
    spatial,
    spatial_coordinates,
)
from tensegrity.analysis.equilibrium import EquilibriumResult, find_equilibrium
from tensegrity.analysis.statics import (
    equilibrium_matrix,
    rod_compression,
    tendon_state,
    unit_tension_forces,
)
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics
from tensegrity.physics.constraints import constraints_of

#: Singular values of the (column-scaled) equilibrium matrix below ``SVD_RTOL`` times the largest
#: count as zero.
SVD_RTOL = 1e-9


class _Equilibrium(NamedTuple):
    """The equilibrium matrix at a configuration (:func:`_equilibrium_matrix`)."""

    q: np.ndarray  #: the configuration, as the structure's ``q``
    chart: Chart  #: based there (of the 3-D form of a planar structure)
    direction: np.ndarray  #: tendon unit vectors (S, 3)
    matrix: np.ndarray  #: ``A`` (k, S) in the admitted motions (``Z^T A_x``; ``A_x`` if free)
    full: np.ndarray  #: ``A_x`` (5R + 3M, S) in the chart's coordinates
    basis: np.ndarray | None  #: ``Z`` of the admitted motions, None without joints and supports


def _equilibrium_matrix(structure: Structure, q: Any) -> _Equilibrium:
    """The equilibrium matrix :func:`~tensegrity.analysis.statics.equilibrium_matrix` at a
    configuration (node positions, ``q`` or None), restricted to the motions the joints and
    supports admit (:meth:`Chart.admitted_motions`): the reactions take up the rest."""
    q = configuration(structure, q)
    s, q3 = spatial(structure), spatial_coordinates(structure, q)
    chart = Chart.at(s, q3)
    p = dynamics.nodes_from_coordinates(s, q3)
    direction = tendon_state(s, p, s.tendon_rest_length).direction
    full = equilibrium_matrix(chart, direction)
    Z = chart.admitted_motions()
    return _Equilibrium(
        q, chart, direction, full if Z is None else drop_roundoff(Z.T @ full), full, Z
    )


@dataclasses.dataclass(frozen=True, eq=False)
class SelfStress:
    """The equilibrium matrix at a configuration and its null spaces.

    Attributes
    ----------
    matrix : ``A`` (k, S) [generalized force per N of tension]; ``k = 5R`` for a free class 1
        structure, in general the admitted motions' count (``Z^T A_x``: with joints and
        supports a self-stress may load them, the reactions balance it).
    singular_values : of ``A`` (descending).  rank : with ``SVD_RTOL``.
    states : (S, s) orthonormal basis of the self-stress states (tensions [N], any sign).
    mechanisms : (k, m) basis of the infinitesimal mechanisms (non-rigid, in the reduced
        coordinates, or in ``eta`` of the admitted motions; Euclidean-orthonormal).
    Maxwell's rule: ``s - m = S - (k - r)``, ``r`` the admitted rigid-body motions.
    """

    structure: Structure
    q: np.ndarray
    matrix: np.ndarray
    singular_values: np.ndarray
    rank: int
    states: np.ndarray
    mechanisms: np.ndarray
    rtol: float

    @property
    def n_states(self) -> int:
        return self.states.shape[1]

    @property
    def n_mechanisms(self) -> int:
        return self.mechanisms.shape[1]


def self_stress(structure: Structure, q: Any = None, *, rtol: float = SVD_RTOL) -> SelfStress:
    """Self-stress states and infinitesimal mechanisms at ``q`` (default: the structure's nodes)."""
    q, chart, _, A, _, Z = _equilibrium_matrix(structure, q)
    u, sv, vt = np.linalg.svd(A)
    rank = int(np.sum(sv > rtol * (sv[0] if sv.size else 0.0)))
    states = vt[rank:].T
    # Mechanisms: motions dx with A^T dx = 0 (no tendon stretches), not rigid.
    rigid = admitted_rigid_motions(chart, Z)
    left = u[:, rank:]  # null space of A^T (k, k - rank), contains the rigid motions
    if rigid.size:
        # remove the rigid part: orthonormal complement of span(rigid) within span(left)
        r, _ = np.linalg.qr(rigid)
        rest = left - r @ (r.T @ left)
        uu, ss, _ = np.linalg.svd(rest, full_matrices=False)
        mechanisms = uu[:, ss > 1e-8]
    else:
        mechanisms = left
    return SelfStress(structure, q, A, sv, rank, states, mechanisms, rtol)


@dataclasses.dataclass(frozen=True, eq=False)
class Prestress:
    """A feasible (all-tendons-taut) self-stress found by linear programming.

    ``tension`` [N] is scaled to the requested mean; ``min_ratio`` is the LP optimum ``t*``, the
    smallest tension over the mean (> 0 iff every tendon can be taut); ``residual`` is
    ``max |A T|`` [N] and ``rod_compression`` the rods' axial forces [N] (> 0 compressed).
    """

    tension: np.ndarray
    min_ratio: float
    feasible: bool
    residual: float
    rod_compression: np.ndarray
    message: str


def feasible_prestress(
    structure: Structure,
    q: Any = None,
    *,
    mean_tension: float = 1.0,
    compressed_rods: bool = True,
    tol: float = 1e-9,
) -> Prestress:
    """The self-stress maximizing the smallest tendon tension (a linear program).

    ``max t`` subject to ``A T = 0``, ``T_s - t >= 0`` for every tendon, ``sum T = S`` and, if
    ``compressed_rods``, every rod in compression (``>= 0``).  Solved by ``linprog`` (HiGHS).
    The result is scaled so that the mean tension is ``mean_tension`` [N].
    """
    q, chart, direction, A, full, Z = _equilibrium_matrix(structure, q)
    S = structure.n_tendons
    # variables [T (S), t]; minimize -t
    cost = np.zeros(S + 1)
    cost[-1] = -1.0
    A_eq = np.vstack(
        [np.hstack([A, np.zeros((A.shape[0], 1))]), np.hstack([np.ones((1, S)), np.zeros((1, 1))])]
    )
    b_eq = np.concatenate([np.zeros(A.shape[0]), [float(S)]])
    A_ub = [np.hstack([-np.eye(S), np.ones((S, 1))])]  # t - T_s <= 0
    b_ub = [np.zeros(S)]
    s = chart.structure
    forces = unit_tension_forces(s, direction)  # (N, 3, S) per unit tension
    if Z is not None:  # plus the reactions that balance each tendon's pull
        constraints = constraints_of(s)
        assert constraints is not None  # Z (the admitted motions) is None without constraints
        multiplier, *_ = np.linalg.lstsq(chart.constraint_jacobian().T, -full, rcond=None)
        forces = forces + (constraints.node_matrix_t @ multiplier).reshape(forces.shape)
    unit = rod_compression(s, forces, chart.direction)  # (R, S) per unit tension
    if compressed_rods:
        A_ub.append(np.hstack([-unit, np.zeros((structure.n_rods, 1))]))  # -compression <= 0
        b_ub.append(np.zeros(structure.n_rods))
    fit = scipy.optimize.linprog(
        cost,
        A_ub=np.vstack(A_ub),
        b_ub=np.concatenate(b_ub),
        A_eq=A_eq,
        b_eq=b_eq,
        bounds=[(None, None)] * (S + 1),
        method="highs",
    )
    if fit.status != 0:
        return Prestress(
            np.zeros(S),
            0.0,
            False,
            float("nan"),
            np.zeros(structure.n_rods),
            f"no self-stress with every tendon in tension: {fit.message}",
        )
    T = fit.x[:S] * mean_tension
    t_star = float(fit.x[-1])
    feasible = t_star > tol
    return Prestress(
        T,
        t_star,
        feasible,
        float(np.max(np.abs(A @ T))),
        unit @ T,
        (
            f"feasible: every tendon in tension, smallest {t_star:.4g} x the mean"
            if feasible
            else f"infeasible: the best self-stress leaves a tendon at {t_star:.3g} x the mean"
        ),
    )


def rest_lengths_for_tensions(
    structure: Structure,
    q: Any,
    tension: np.ndarray,
    stiffness: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Rest lengths ``Lbar = l - T / k`` that give tensions ``T`` [N] at configuration ``q``.

    Returns ``(Lbar, u)`` with ``u = L0 - Lbar`` the control that realizes them on
    ``structure``.  ``stiffness`` defaults to the structure's.  Raises ``ValueError`` if a
    tension is negative or needs ``Lbar < 0`` (too stiff a demand for that tendon).
    """
    q = configuration(structure, q)
    T = np.asarray(tension, dtype=float)
    k = structure.tendon_stiffness if stiffness is None else np.asarray(stiffness, dtype=float)
    if np.any(T < 0):
        s = int(np.argmin(T))
        raise ValueError(f"tension[{s}] ({structure.tendon_name[s]!r}): {T[s]} N < 0")
    length = dynamics.tendon_lengths(structure, dynamics.nodes_from_coordinates(structure, q))
    rest = length - T / k
    if np.any(rest < 0):
        s = int(np.argmin(rest))
        raise ValueError(
            f"tendon {structure.tendon_name[s]!r}: tension {T[s]} N needs rest length "
            f"{rest[s]} m < 0 with k = {k[s]} N/m and length {length[s]} m"
        )
    return rest, structure.tendon_rest_length - rest


@dataclasses.dataclass(frozen=True, eq=False)
class FormFinding:
    """The result of :func:`form_find`: a structure (with the rest lengths found) at equilibrium."""

    structure: Structure  #: rest lengths set, node positions at the equilibrium
    equilibrium: EquilibriumResult
    prestress: Prestress
    stable: bool
    verdict: str
    iterations: int
    history: tuple[str, ...]


def form_find(
    structure: Structure,
    start: Any = None,
    *,
    mean_tension: float | None = None,
    taut_fraction: float = 0.9,
    max_iterations: int = 10,
) -> FormFinding:
    """From rough geometry to a stable equilibrium with every tendon taut.

    1. Solve for the equilibrium of ``structure`` from ``start`` (default its node positions;
       :func:`find_equilibrium` goes down the potential energy, so it finds a minimum).
    2. While some tendon is slack there, set its rest length to ``taut_fraction`` times its
       current length and solve again (at most ``max_iterations`` times).
    3. If ``mean_tension`` [N] is given, rescale the prestress: the LP self-stress of the
       geometry found (:func:`feasible_prestress`), scaled to that mean, realized by rest lengths
       (:func:`rest_lengths_for_tensions`); the geometry stays an equilibrium (the tensions are
       a self-stress), then it is polished once more.
    4. Check stability (:func:`~tensegrity.analysis.modes.modal_analysis`).
    """
    from tensegrity.analysis.linearize import linearize
    from tensegrity.analysis.modes import modal_analysis

    current = structure
    history = []
    eq = find_equilibrium(current, start)
    iterations = 1
    history.append(f"equilibrium: {eq.message}; {int(eq.slack.sum())} slack")
    while eq.slack.any() and iterations < max_iterations:
        rest = current.tendon_rest_length.copy()
        rest[eq.slack] = taut_fraction * eq.tendon_length[eq.slack]
        current = current.replace(tendon_rest_length=rest)
        eq = find_equilibrium(current, eq.q)
        iterations += 1
        history.append(f"tightened slack tendons; {eq.message}; {int(eq.slack.sum())} slack")
    prestress = feasible_prestress(current, eq.q, mean_tension=1.0)
    if mean_tension is not None and prestress.feasible:
        T = prestress.tension * mean_tension
        rest, _ = rest_lengths_for_tensions(current, eq.q, T)
        current = current.replace(tendon_rest_length=rest)
        eq = find_equilibrium(current, eq.q)
        iterations += 1
        history.append(f"prestress rescaled to a mean of {mean_tension:g} N; {eq.message}")
    current = current.replace(node_position=eq.node_position)
    eq = find_equilibrium(current, eq.q)
    modes = modal_analysis(linearize(current, eq))
    stable = bool(eq.converged and not eq.slack.any() and modes.stable)
    verdict = (
        f"{'stable' if stable else 'NOT stable'} equilibrium, {int(eq.slack.sum())} slack "
        f"tendons, residual {eq.residual_force:.3g} N; {modes.verdict}"
    )
    return FormFinding(current, eq, prestress, stable, verdict, iterations, tuple(history))
