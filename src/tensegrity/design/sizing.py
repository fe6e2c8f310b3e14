"""Minimal-mass sizing of rods and tendons under yield and buckling (``docs/design.md``).

Given a structure's geometry and topology (its node positions, rods, tendons, supports and
joints), the members' materials, a prestress level and load cases, :func:`size_members` finds
member forces for every case and member areas of least total mass ``sum rho L A`` such that in
every case

- every node is in equilibrium: ``P (H_rod C + H_ten T + w + g m(A)) = 0``, with ``H`` the
  nodal equilibrium matrix of the members' unit forces, ``P`` the directions the supports and
  joints leave free (a fixed node's rows dropped, a plane's normal, a line's perpendiculars;
  joined nodes added together), ``w`` the case's nodal forces and ``g m(A)`` the weight of the
  members (lumped as the simulated structure lumps it);
- no tendon pushes: ``T >= 0``, and ``T >= prestress`` in the prestressed state (the case
  ``"prestress"``, no load, added when ``prestress > 0``);
- no tendon yields: ``T <= A sigma_y / strength_factor``; no rod yields:
  ``|C| <= A sigma_y / strength_factor``;
- no rod buckles: ``C <= pi^2 E I / (gamma L^2)`` with ``I = kappa A^2`` for the rod's section
  shape (a solid round bar ``kappa = 1 / (4 pi)``; a round tube of fixed ratio ``t / D``,
  ``kappa = (1 + xi^2) / (4 pi (1 - xi^2))``, ``xi = 1 - 2 t / D``), that is
  ``A >= beta sqrt(C)``, ``beta = L sqrt(gamma / (pi^2 E kappa))``.

Each case's forces are free (a lower-bound, equilibrium design: compatibility with the
members' stiffness is not imposed; a statically determinate structure has one set of forces
anyway).  All is linear except the buckling constraint, whose right-hand side is concave in
``C``: the problem is solved as a sequence of linear programs (``scipy.optimize.linprog``,
HiGHS), the first without buckling (yield only), each next one with the buckling constraint
replaced by its tangent at the previous forces, ``A >= beta (sqrt(c0) / 2 + C / (2
sqrt(c0)))``, which lies above ``beta sqrt(C)`` everywhere: every iterate is feasible, and the
mass does not increase from one to the next (the convex-concave procedure).  It stops at a
stationary point, a local optimum; with the forces fixed (a statically determinate structure,
or the forces found) the areas are the exact minimum, ``A = max(A_min, yield, buckling)``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import scipy.optimize
import scipy.sparse as sp

from tensegrity.analysis.equilibrium import EquilibriumResult
from tensegrity.design.materials import (
    Cable,
    Material,
    MemberProperties,
    member_properties,
    per_member,
    round_section,
    with_members,
)
from tensegrity.design.utilisation import Utilisation, utilisation
from tensegrity.model.structure import Structure

__all__ = [
    "LoadCase",
    "Sizing",
    "buckling_coefficient",
    "equilibrium_rows",
    "nodal_equilibrium_matrix",
    "size_members",
]

#: Relative tolerance of a constraint's check (and of the end of the iterations).
RTOL = 1e-7


@dataclasses.dataclass(frozen=True, eq=False)
class LoadCase:
    """A load case: nodal forces ``force`` (N, dim) [N] and gravity ``gravity`` (dim,)
    [m/s^2] (on the members' own mass and the structure's point masses), either may be None."""

    name: str
    force: np.ndarray | None = None
    gravity: np.ndarray | None = None


def second_moment_factor(wall_ratio: float | None) -> float:
    """``kappa`` of ``I = kappa A^2`` [-] for a round section: solid (``wall_ratio`` None) or a
    tube of wall thickness ``t = wall_ratio * D`` (``0 < wall_ratio <= 1/2``)."""
    if wall_ratio is None:
        return 1.0 / (4.0 * math.pi)
    if not 0 < wall_ratio <= 0.5:
        raise ValueError(f"wall_ratio: must be in (0, 0.5] (t / D), got {wall_ratio!r}")
    xi = 1.0 - 2.0 * wall_ratio
    return (1.0 + xi**2) / (4.0 * math.pi * (1.0 - xi**2))


def buckling_coefficient(
    length: np.ndarray,
    modulus: np.ndarray,
    *,
    wall_ratio: float | None = None,
    safety_factor: float = 1.0,
) -> np.ndarray:
    """``beta`` (R,) [m^2 / sqrt(N)] of the buckling area ``A >= beta sqrt(C)`` of rods of
    length (R,) [m] and Young's modulus (R,) [Pa]: ``beta = L sqrt(gamma / (pi^2 E kappa))``."""
    kappa = second_moment_factor(wall_ratio)
    return np.asarray(length * np.sqrt(safety_factor / (math.pi**2 * modulus * kappa)))


def nodal_equilibrium_matrix(structure: Structure) -> tuple[np.ndarray, np.ndarray]:
    """``(H_rod, H_ten)``, (N dim, R) and (N dim, S): the nodal forces of a unit compression in
    each rod (pushing its ends apart) and of a unit tension in each tendon (pulling its ends
    together), node by node (rows ``dim * node + axis``), at the structure's node positions."""
    p = structure.node_position
    N, d = p.shape

    def unit_pairs(pairs: np.ndarray, sign: float) -> np.ndarray:
        e = p[pairs[:, 1]] - p[pairs[:, 0]]
        e = e / np.linalg.norm(e, axis=1)[:, None]
        H = np.zeros((N, d, len(pairs)))
        k = np.arange(len(pairs))
        for axis in range(d):
            np.add.at(H[:, axis, :], (pairs[:, 0], k), sign * e[:, axis])
            np.add.at(H[:, axis, :], (pairs[:, 1], k), -sign * e[:, axis])
        return H.reshape(N * d, len(pairs))

    # a compressed rod pushes its tail away from its head (-n on a); a taut tendon pulls its
    # tail toward its head (+t on the tail)
    return unit_pairs(structure.rod_nodes, -1.0), unit_pairs(structure.tendon_nodes, 1.0)


def equilibrium_rows(structure: Structure) -> sp.csr_matrix:
    """``P`` (k, N dim): the components of nodal forces the supports and joints leave to the
    members -- per group of joined nodes (their forces added), an orthonormal basis of the
    directions it may move in (none if a node of it is fixed; in its plane; along its line)."""
    N, d = structure.node_position.shape
    parent = list(range(N))

    def root(k: int) -> int:
        while parent[k] != k:
            parent[k] = parent[parent[k]]
            k = parent[k]
        return k

    for a, b in structure.joint_nodes:
        parent[root(int(a))] = root(int(b))
    basis = {k: np.eye(d) for k in range(N) if root(k) == k}
    for node in np.flatnonzero(structure.node_fixed):
        basis[root(int(node))] = np.zeros((d, 0))
    for nodes, vectors, keep in (
        (structure.plane_nodes, structure.plane_normal, False),
        (structure.line_nodes, structure.line_direction, True),
    ):
        for node, v in zip(nodes, vectors, strict=True):
            B = basis[root(int(node))]
            B = np.outer(v, v @ B) if keep else B - np.outer(v, v @ B)
            u, sv, _ = np.linalg.svd(B, full_matrices=False)
            basis[root(int(node))] = u[:, sv > 1e-9]
    start, row = {}, 0
    for group, B in basis.items():
        start[group] = row
        row += B.shape[1]
    rows: list[int] = []
    cols: list[int] = []
    data: list[float] = []
    for k in range(N):
        g = root(k)
        B = basis[g]
        for j in range(B.shape[1]):
            rows += [start[g] + j] * d
            cols += [d * k + axis for axis in range(d)]
            data += B[:, j].tolist()
    return sp.csr_matrix((data, (rows, cols)), shape=(row, N * d))


def mass_matrix(structure: Structure, *, tendon_mass: bool) -> np.ndarray:
    """``M`` (N, R + S) [m]: node masses per unit area of each member, times its density, as
    :func:`~tensegrity.design.materials.with_members` lumps them (a rod's mass half at each
    end; a tendon's, with ``tendon_mass``, half to each end: to the rod there, half to each of
    its ends, or to a point mass; dropped at a fixed node)."""
    N, R, S = structure.n_nodes, structure.n_rods, structure.n_tendons
    M = np.zeros((N, R + S))
    r = np.arange(R)
    a, b = structure.rod_nodes[:, 0], structure.rod_nodes[:, 1]
    M[a, r] += structure.rod_length / 2
    M[b, r] += structure.rod_length / 2
    if tendon_mass and S:
        owner = np.full(N, -1)
        owner[a], owner[b] = r, r
        length = np.linalg.norm(
            structure.node_position[structure.tendon_nodes[:, 1]]
            - structure.node_position[structure.tendon_nodes[:, 0]],
            axis=1,
        )
        for s, ends in enumerate(structure.tendon_nodes):
            for k in ends:
                if structure.node_fixed[k]:
                    continue
                if owner[k] >= 0:
                    M[structure.rod_nodes[owner[k]], R + s] += length[s] / 4
                else:
                    M[k, R + s] += length[s] / 2
    return M


@dataclasses.dataclass(frozen=True, eq=False)
class Sizing:
    """The result of :func:`size_members`.

    Attributes
    ----------
    structure : Structure
        The sized structure, ready to simulate: tendon stiffness ``E A / Lbar``, rod mass ``rho
        A L``, rest lengths that give the prestressed state's tensions at the given geometry
        (no tension without a prestress).
    members : MemberProperties
        The members' materials and sections.
    cases : tuple of str
        Names of the cases (``"prestress"`` first when there is a prestress).
    rod_area, tendon_area : (R,), (S,) arrays
        [m^2].
    rod_mass, tendon_mass : (R,), (S,) arrays
        ``rho A L`` [kg], a tendon's at its length in the geometry.
    rod_compression, tendon_tension : (K, R), (K, S) arrays
        Each case's member forces [N].
    utilisation : (K, S) and (K, R) arrays
        Of every member in every case.
    iterations : int
        Linear programs solved (``statics="linear"``) or sizing iterations
        (``"equilibrium"``).
    message : str
        How it ended.
    statics : str
        ``"linear"`` (equilibrium at the given geometry, :func:`size_members`) or
        ``"equilibrium"`` (at each case's loaded equilibrium,
        :func:`~tensegrity.design.loaded.size_at_equilibrium`).
    governs, governing_case : (R + S,), rods first
        What sets each member's area (``"yield"``, ``"buckling"`` or ``"min_area"``) and in
        which case (None for ``"min_area"``).
    equilibria : tuple
        Each load case's loaded equilibrium (``"equilibrium"`` only; the prestress is the
        given geometry).
    displacement : (load cases,) array
        Each one's largest node displacement from the given geometry [m] (``"equilibrium"``
        only).
    frequency : (K,) array
        The lowest natural frequency [Hz] in each case, the prestressed state's about the given
        geometry (``"equilibrium"`` only).
    prestress : float
        The smallest tendon tension of the prestressed state [N] (chosen, or found in a range
        by :func:`~tensegrity.design.loaded.size_at_equilibrium`).
    """

    structure: Structure
    members: MemberProperties
    cases: tuple[str, ...]
    rod_area: np.ndarray
    tendon_area: np.ndarray
    rod_mass: np.ndarray
    tendon_mass: np.ndarray
    rod_compression: np.ndarray
    tendon_tension: np.ndarray
    utilisation: Utilisation
    iterations: int
    message: str
    statics: str = "linear"
    governs: tuple[str, ...] = ()
    governing_case: tuple[str | None, ...] = ()
    equilibria: tuple[EquilibriumResult, ...] = ()
    displacement: np.ndarray | None = None
    frequency: np.ndarray | None = None
    prestress: float = 0.0

    @property
    def total_mass(self) -> float:
        """Mass of all members [kg]."""
        return float(self.rod_mass.sum() + self.tendon_mass.sum())

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready report: totals, and per member its section, area, mass, force and
        utilisation in each case."""
        u = self.utilisation
        s = self.structure
        return dict(
            total_mass_kg=self.total_mass,
            rod_mass_kg=float(self.rod_mass.sum()),
            tendon_mass_kg=float(self.tendon_mass.sum()),
            cases=list(self.cases),
            largest_utilisation=u.largest,
            statics=self.statics,
            prestress_N=self.prestress,
            iterations=self.iterations,
            message=self.message,
            **(
                {}
                if self.displacement is None
                else dict(
                    largest_displacement_m=dict(
                        zip(
                            self.cases[-len(self.displacement) :],
                            self.displacement.tolist(),
                            strict=True,
                        )
                    ),
                    lowest_frequency_hz=dict(
                        zip(self.cases, np.asarray(self.frequency).tolist(), strict=True)
                    ),
                )
            ),
            rods=[
                dict(
                    rod=r,
                    section=self.members.rod_label[r],
                    area_m2=float(self.rod_area[r]),
                    mass_kg=float(self.rod_mass[r]),
                    **self._governing(r),
                    compression_N=u.rod_compression[:, r].tolist(),
                    yield_utilisation=u.rod_yield[:, r].tolist(),
                    buckling_utilisation=u.rod_buckling[:, r].tolist(),
                )
                for r in range(s.n_rods)
            ],
            tendons=[
                dict(
                    tendon=s.tendon_name[k],
                    section=self.members.tendon_label[k],
                    area_m2=float(self.tendon_area[k]),
                    mass_kg=float(self.tendon_mass[k]),
                    **self._governing(s.n_rods + k),
                    stiffness_N_per_m=float(s.tendon_stiffness[k]),
                    rest_length_m=float(s.tendon_rest_length[k]),
                    tension_N=self.tendon_tension[:, k].tolist(),
                    yield_utilisation=u.tendon_yield[:, k].tolist(),
                )
                for k in range(s.n_tendons)
            ],
        )

    def _governing(self, member: int) -> dict[str, Any]:
        """``governed_by`` and ``governing_case`` of member ``member`` (rods first) for
        :meth:`to_dict`."""
        if not self.governs:
            return {}
        return dict(governed_by=self.governs[member], governing_case=self.governing_case[member])


class LeastAreas(NamedTuple):
    """The least member areas for given forces, and what governs each (:func:`least_areas`)."""

    area: np.ndarray  #: (R + S,) [m^2], rods first
    governs: tuple[str, ...]  #: (R + S,) ``"yield"``, ``"buckling"`` or ``"min_area"``
    case: tuple[str | None, ...]  #: (R + S,) the governing case (None for ``"min_area"``)


def least_areas(
    compression: np.ndarray,
    tension: np.ndarray,
    *,
    strength: np.ndarray,
    beta: np.ndarray,
    min_area: float,
    cases: Sequence[str],
) -> LeastAreas:
    """The least areas that carry rod compressions ``compression`` (K, R) [N] (> 0 compressed)
    and tendon tensions ``tension`` (K, S) [N] of ``K`` cases named ``cases``: ``A = max(A_min,
    max_k |F_k| / strength, max_k beta sqrt(C_k+))``, with ``strength`` (R + S,) the design yield
    strengths [Pa] (over the strength factor) and ``beta`` (R,) [m^2 / sqrt(N)]
    (:func:`buckling_coefficient`); and which term governs each member, in which case."""
    R = compression.shape[1]
    need = np.concatenate([np.abs(compression), np.maximum(tension, 0.0)], axis=1) / strength
    buckle = beta * np.sqrt(np.maximum(compression, 0.0))
    kinds = np.stack([need, np.zeros_like(need)])  # (2, K, R + S): yield, buckling
    kinds[1, :, :R] = buckle
    flat = kinds.reshape(-1, kinds.shape[2])
    best = np.argmax(flat, axis=0)
    area = flat[best, np.arange(flat.shape[1])] if flat.size else np.zeros(flat.shape[1])
    K = compression.shape[0]
    governs = tuple(
        "min_area" if not a > min_area else ("yield", "buckling")[b // K]
        for a, b in zip(area, best, strict=True)
    )
    case = tuple(
        None if g == "min_area" else cases[b % K] for g, b in zip(governs, best, strict=True)
    )
    return LeastAreas(np.maximum(area, min_area), governs, case)


class _Problem:
    """The sizing problem in scaled units: forces over ``F`` [N], areas over ``A_ref`` [m^2].

    Variables ``x = [a_rod (R), a_ten (S), then per case: c (R), t (S)]``."""

    def __init__(
        self,
        structure: Structure,
        cases: list[LoadCase],
        minimum_tension: list[float],
        rod_density: np.ndarray,
        tendon_density: np.ndarray,
        rod_strength: np.ndarray,
        tendon_strength: np.ndarray,
        beta: np.ndarray,
        min_area: float,
        tendon_mass: bool,
    ) -> None:
        s = structure
        R, S, K = s.n_rods, s.n_tendons, len(cases)
        self.R, self.S, self.K = R, S, K
        self.names = [c.name for c in cases]
        d = s.dim
        self.P = equilibrium_rows(s)
        H_rod, H_ten = nodal_equilibrium_matrix(s)
        self.PH = sp.csr_matrix(self.P @ np.hstack([H_rod, H_ten]))
        tendon_length = np.linalg.norm(
            s.node_position[s.tendon_nodes[:, 1]] - s.node_position[s.tendon_nodes[:, 0]], axis=1
        )
        self.length = np.concatenate([s.rod_length, tendon_length])
        density = np.concatenate([rod_density, tendon_density])
        M = mass_matrix(s, tendon_mass=tendon_mass) * density  # (N, R + S) [kg/m^2]
        loads = []
        weights = []
        for case in cases:
            w = np.zeros((s.n_nodes, d)) if case.force is None else case.force
            g = np.zeros(d) if case.gravity is None else case.gravity
            loads.append(self.P @ (w + s.node_point_mass[:, None] * g).reshape(-1))
            # weight of the members per unit area: rows node * d + axis
            weights.append(self.P @ (M[:, None, :] * g[None, :, None]).reshape(s.n_nodes * d, -1))
        scale = max(
            [max(minimum_tension, default=0.0)] + [float(np.abs(b).max(initial=0.0)) for b in loads]
        )
        self.F = scale if scale > 0 else 1.0
        strength = np.concatenate([rod_strength, tendon_strength])
        self.A_ref = self.F / float(np.median(strength)) if strength.size else 1.0
        self.strength = strength * self.A_ref / self.F  # scaled: force per unit scaled area
        self.b = beta * math.sqrt(self.F) / self.A_ref
        self.cost = density * self.length * self.A_ref
        self.mass_scale = float(self.cost.max(initial=1.0)) or 1.0
        self.loads = [b / self.F for b in loads]
        self.weights = [sp.csr_matrix(W * self.A_ref / self.F) for W in weights]
        self.minimum_tension = [t / self.F for t in minimum_tension]
        self.min_area = min_area / self.A_ref

    @property
    def n(self) -> int:
        return (self.R + self.S) * (1 + self.K)

    def forces(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(C (K, R), T (K, S))`` [N] of a solution."""
        m = self.R + self.S
        f = x[m:].reshape(self.K, m) * self.F
        return f[:, : self.R], f[:, self.R :]

    def areas(self, C: np.ndarray, T: np.ndarray, beta: np.ndarray) -> np.ndarray:
        """The least areas (R + S,) [m^2] that carry forces ``C``, ``T`` (:func:`least_areas`)."""
        strength = self.strength * self.F / self.A_ref
        return least_areas(
            C,
            T,
            strength=strength,
            beta=beta,
            min_area=self.min_area * self.A_ref,
            cases=self.names,
        ).area

    def solve(self, tangent: np.ndarray | None) -> Any:
        """One linear program; ``tangent`` (K, R): the scaled compressions at which the
        buckling constraint is linearized (None: no buckling constraint)."""
        R, S, K, m = self.R, self.S, self.K, self.R + self.S
        eye_m = sp.identity(m, format="csr")
        eq_rows, eq_rhs, ub_rows, ub_rhs = [], [], [], []
        for k in range(K):
            row = [None] * (1 + K)
            row[0], row[1 + k] = self.weights[k], self.PH
            eq_rows.append(row)
            eq_rhs.append(-self.loads[k])
            # yield: +-c - s a <= 0 (rods), t - s a <= 0 (tendons)
            strength = sp.diags(self.strength)
            for sign, members in ((1.0, slice(0, m)), (-1.0, slice(0, R))):
                pick = eye_m[members]
                row = [None] * (1 + K)
                row[0], row[1 + k] = -(pick @ strength), sign * pick
                ub_rows.append(row)
                ub_rhs.append(np.zeros(pick.shape[0]))
            if tangent is not None and R:
                c0 = np.maximum(tangent[k], 1e-6)
                slope = self.b / (2 * np.sqrt(c0))
                pick = eye_m[:R]
                row = [None] * (1 + K)
                row[0], row[1 + k] = -pick, sp.diags(slope) @ pick
                ub_rows.append(row)
                ub_rhs.append(-self.b * np.sqrt(c0) / 2)
        bounds: list[tuple[float | None, None]] = [(self.min_area, None)] * m
        for k in range(K):
            bounds += [(None, None)] * R + [(self.minimum_tension[k], None)] * S
        cost = np.concatenate([self.cost / self.mass_scale, np.zeros(m * K)])
        return scipy.optimize.linprog(
            cost,
            A_ub=sp.bmat(ub_rows, format="csr") if ub_rows else None,
            b_ub=np.concatenate(ub_rhs) if ub_rhs else None,
            A_eq=sp.bmat(eq_rows, format="csr") if eq_rows else None,
            b_eq=np.concatenate(eq_rhs) if eq_rhs else None,
            bounds=bounds,
            method="highs",
        )

    def diagnose(self) -> str:
        """Why the problem has no solution, in one line naming the first case at fault."""
        m = self.R + self.S
        for k, name in enumerate(self.names):
            what = f"load case {name!r}" if name != "prestress" else "prestress"
            load = self.loads[k] + self.weights[k] @ np.full(m, self.min_area)
            if load.size and self.PH.shape[1]:
                f, *_ = np.linalg.lstsq(self.PH.toarray(), -load, rcond=None)
                residual = float(np.abs(self.PH @ f + load).max(initial=0.0))
            else:
                residual = float(np.abs(load).max(initial=0.0))
            if residual > 1e-8 * max(1.0, float(np.abs(load).max(initial=0.0))):
                return (
                    f"{what}: cannot be carried: no member forces balance it (it moves the "
                    "structure: a mechanism, or a rigid-body motion of an unsupported one; "
                    f"{residual * self.F:.3g} N left unbalanced)"
                )
            fit = scipy.optimize.linprog(
                np.zeros(m),
                A_eq=self.PH,
                b_eq=-load,
                bounds=[(None, None)] * self.R + [(self.minimum_tension[k], None)] * self.S,
                method="highs",
            )
            if fit.status == 2:
                if name == "prestress":
                    return (
                        f"prestress: no self-stress puts every tendon in tension "
                        f"(>= {self.minimum_tension[k] * self.F:g} N)"
                    )
                return (
                    f"{what}: cannot be carried: every balance of it needs a tendon to push "
                    "(a tendon in compression)"
                )
        return (
            "the load cases cannot be carried together (the members' own weight grows faster "
            "than their strength)"
        )


def sized_structure(
    structure: Structure,
    *,
    rod_material: Sequence[Material],
    tendon_material: Sequence[Material],
    rod_area: np.ndarray,
    tendon_area: np.ndarray,
    wall_ratio: float | None,
    prestress_tension: np.ndarray,
    tendon_mass: bool,
) -> tuple[Structure, MemberProperties]:
    """The structure of members of areas ``rod_area`` (R,) and ``tendon_area`` (S,) [m^2] and
    their properties: rods ``SolidRod`` (``wall_ratio`` None) or ``HollowTube(D, wall_ratio D)``,
    tendons ``Cable``; stiffness ``E A / Lbar``, rod mass ``rho A L``, and rest lengths ``Lbar = l
    E A / (E A + T)`` that give the tensions ``prestress_tension`` (S,) [N] at the structure's
    node positions (``l`` the tendons' lengths there)."""
    s = structure
    cables = [Cable(math.sqrt(4 * A / math.pi)) for A in tendon_area]
    members = member_properties(
        s,
        rod_material=rod_material,
        rod_section=[round_section(A, wall_ratio=wall_ratio) for A in rod_area],
        tendon_material=tendon_material,
        tendon_section=cables,
    )
    length = np.linalg.norm(
        s.node_position[s.tendon_nodes[:, 1]] - s.node_position[s.tendon_nodes[:, 0]], axis=1
    )
    EA = members.tendon_modulus * members.tendon_area
    rest = length * EA / (EA + prestress_tension)
    sized = with_members(s.replace(tendon_rest_length=rest), members, tendon_mass=tendon_mass)
    return sized, members


def checked_cases(
    structure: Structure, load_cases: Sequence[LoadCase], prestress: float
) -> list[LoadCase]:
    """The cases to size for: ``"prestress"`` first when ``prestress`` > 0, then ``load_cases``
    with their loads as float arrays; a one-line ``ValueError`` naming the case otherwise."""
    d = structure.dim
    cases = ([LoadCase("prestress")] if prestress > 0 else []) + list(load_cases)
    if not cases:
        raise ValueError("load_cases: give at least one load case or a prestress > 0")
    seen = set()
    checked = []
    for case in cases:
        if case.name in seen:
            raise ValueError(f"load case {case.name!r}: named twice")
        seen.add(case.name)
        force = None if case.force is None else np.asarray(case.force, dtype=float)
        gravity = None if case.gravity is None else np.asarray(case.gravity, dtype=float)
        if force is not None and force.shape != (structure.n_nodes, d):
            raise ValueError(
                f"load case {case.name!r}: force has shape {force.shape}, expected "
                f"({structure.n_nodes}, {d})"
            )
        if gravity is not None and gravity.shape != (d,):
            raise ValueError(
                f"load case {case.name!r}: gravity has shape {gravity.shape}, expected ({d},)"
            )
        for loads in (force, gravity):
            if loads is not None and not np.all(np.isfinite(loads)):
                raise ValueError(f"load case {case.name!r}: loads must be finite")
        checked.append(LoadCase(case.name, force, gravity))
    return checked


def size_members(
    structure: Structure,
    *,
    rod_material: Material | Sequence[Material],
    tendon_material: Material | Sequence[Material],
    load_cases: Sequence[LoadCase] = (),
    prestress: float = 0.0,
    wall_ratio: float | None = None,
    safety_factor: float = 1.0,
    strength_factor: float = 1.0,
    min_area: float = 1e-8,
    tendon_mass: bool = False,
    max_iterations: int = 50,
) -> Sizing:
    """The members of least total mass that carry the prestress and every load case.

    Parameters
    ----------
    structure : Structure
        Geometry (node positions [m]), topology, supports and joints; its stiffnesses, masses
        and rest lengths are not used.
    rod_material, tendon_material : Material or sequence of one per rod (tendon)
    load_cases : sequence of LoadCase
        Nodal forces (N, dim) [N] and gravity (dim,) [m/s^2] per case.
    prestress : float
        The smallest tendon tension [N] of the prestressed state (a case ``"prestress"`` with no
        load, added when > 0).  0: no prestress (then at least one load case).
    wall_ratio : float, optional
        Rods are round tubes of wall thickness ``wall_ratio * D`` (``0 < wall_ratio <= 1/2``);
        None: solid round bars.  Tendons are round cables.
    safety_factor : float
        ``gamma`` >= 1 dividing the Euler buckling load.
    strength_factor : float
        >= 1, dividing the yield strengths.
    min_area : float
        The smallest area of a member [m^2], > 0 (a member with no force still exists).
    tendon_mass : bool
        Count the tendons' weight in the load cases and the sized structure.
    max_iterations : int
        The most linear programs after the first.

    Returns
    -------
    Sizing

    Raises
    ------
    ValueError
        One line: a bad argument, or a case that cannot be carried (naming it: a mechanism for
        that load, or a tendon that would have to push, or no self-stress for the prestress).
    """
    s = structure
    for name, value, low in (
        ("safety_factor", safety_factor, 1.0),
        ("strength_factor", strength_factor, 1.0),
    ):
        if not (math.isfinite(value) and value >= low):
            raise ValueError(f"{name}: must be >= {low:g}, got {value!r}")
    if isinstance(max_iterations, bool) or not (
        isinstance(max_iterations, int) and max_iterations >= 1
    ):
        raise ValueError(f"max_iterations: must be an integer >= 1, got {max_iterations!r}")
    if not (math.isfinite(min_area) and min_area > 0):
        raise ValueError(f"min_area: must be > 0, got {min_area!r}")
    if not (math.isfinite(prestress) and prestress >= 0):
        raise ValueError(f"prestress: must be >= 0, got {prestress!r}")
    checked = checked_cases(s, load_cases, prestress)
    rm = per_member(rod_material, s.n_rods, "rod_material", Material)
    tm = per_member(tendon_material, s.n_tendons, "tendon_material", Material)
    rod_modulus = np.array([m.youngs_modulus for m in rm])
    beta = buckling_coefficient(
        s.rod_length, rod_modulus, wall_ratio=wall_ratio, safety_factor=safety_factor
    )
    problem = _Problem(
        s,
        checked,
        [prestress if c.name == "prestress" and prestress > 0 else 0.0 for c in checked],
        np.array([m.density for m in rm]),
        np.array([m.density for m in tm]),
        np.array([m.yield_strength for m in rm]) / strength_factor,
        np.array([m.yield_strength for m in tm]) / strength_factor,
        beta,
        min_area,
        tendon_mass,
    )
    fit = problem.solve(None)
    if fit.status == 2:
        raise ValueError(problem.diagnose())
    if fit.status != 0:
        raise ValueError(f"sizing: the linear program failed: {fit.message}")
    weighed = any(c.gravity is not None and np.any(c.gravity) for c in checked)
    density = problem.cost / (problem.length * problem.A_ref)

    def mass_of(x: np.ndarray) -> tuple[float, np.ndarray]:
        C, T = problem.forces(x)
        area = x[: problem.R + problem.S] * problem.A_ref
        if not weighed:  # the weight does not depend on the areas: the exact least areas
            area = problem.areas(C, T, beta)
        return float(np.sum(density * problem.length * area)), area

    # The yield-only program gives the first forces; every later program's solution is feasible
    # (its buckling tangents lie above the buckling curve), and the lightest is kept.
    best_x, best_mass = fit.x, math.inf
    iterations = 1
    message = "one linear program (no rods: no buckling)"
    for _ in range(max_iterations if s.n_rods else 0):
        C, _ = problem.forces(fit.x)
        tangent = C / problem.F
        fit = problem.solve(tangent)
        iterations += 1
        # With gravity, a tangent taken at a compression near zero is so steep that no areas
        # carry their own weight within it: take the first tangents further out (each one
        # still lies above the buckling curve) until a program is feasible.
        lift = 1e-4
        while fit.status == 2 and best_mass == math.inf and lift <= 1e8:
            fit = problem.solve(np.maximum(tangent, lift))
            iterations, lift = iterations + 1, 100 * lift
        if fit.status != 0:
            if best_mass == math.inf:
                raise ValueError(f"sizing: linear program {iterations} failed: {fit.message}")
            message = f"stopped: linear program {iterations} failed: {fit.message}"
            break
        mass, _ = mass_of(fit.x)
        improved = mass < best_mass * (1 - RTOL)
        if mass <= best_mass:
            best_x, best_mass = fit.x, mass
        if not improved:
            message = f"converged after {iterations} linear programs"
            break
    else:
        if s.n_rods:
            message = f"stopped after {iterations} linear programs (max_iterations)"
    C, T = problem.forces(best_x)
    _, area = mass_of(best_x)
    rod_area, tendon_area = area[: s.n_rods], area[s.n_rods :]
    length = problem.length[s.n_rods :]
    pre = T[0] if checked[0].name == "prestress" else np.zeros(s.n_tendons)
    sized, members = sized_structure(
        s,
        rod_material=rm,
        tendon_material=tm,
        rod_area=rod_area,
        tendon_area=tendon_area,
        wall_ratio=wall_ratio,
        prestress_tension=pre,
        tendon_mass=tendon_mass,
    )
    least = least_areas(
        C,
        T,
        strength=problem.strength * problem.F / problem.A_ref,
        beta=beta,
        min_area=min_area,
        cases=problem.names,
    )
    return Sizing(
        structure=sized,
        members=members,
        cases=tuple(c.name for c in checked),
        rod_area=rod_area,
        tendon_area=tendon_area,
        rod_mass=density[: s.n_rods] * s.rod_length * rod_area,
        tendon_mass=density[s.n_rods :] * length * tendon_area,
        rod_compression=C,
        tendon_tension=T,
        utilisation=utilisation(
            s,
            members,
            tension=T,
            compression=C,
            safety_factor=safety_factor,
            strength_factor=strength_factor,
        ),
        iterations=iterations,
        message=message,
        governs=least.governs,
        governing_case=least.case,
        prestress=prestress,
    )
