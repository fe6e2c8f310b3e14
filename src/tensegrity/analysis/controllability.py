"""Controllability and observability of a linearization, with named inputs and outputs.

Inputs are rest-length changes of named tendons; outputs are named rows of the linearization's
``C`` (node positions ``p{i}_x``, tendon lengths ``length_{name}``, tensions ``tension_{name}``).
Sets of either are given by name patterns (``fnmatch``: ``"t5_*"``, ``"t1_1_1,t2_1_1"``,
``"length_*"``) or group names (``"all"``; ``"position"``, ``"length"``, ``"tension"``).

Tests, each with its tolerance stated in the result:

- **PBH test per mode** of the conservative (undamped) linearization ``M x'' + K x = B_f u``,
  whose eigenvalues are ``+-i omega_j`` (0 for rigid-body modes and mechanisms): a cluster of
  modes of equal frequency (multiplicity ``m``, ``M``-orthonormal shapes ``V_j``) is reachable
  from the inputs ``S`` iff ``rank(V_j^T B_S) = m`` -- equivalent to ``rank [A - i omega_j I,
  B_S] = n`` -- and seen by the outputs iff ``rank((C_x + i omega_j C_v) V_j) = m``.  Singular
  values below ``pbh_rtol`` times the norm of the mass-scaled input (output) matrix count as
  zero.  Rigid-body modes are never reachable by tendons (their forces are internal).
- **rank** of the controllable (observable) subspace from the same decomposition: every mode
  reached (seen) brings its two states (position and rate), so ``rank = 2 sum_j rank_j``.  This
  is the Kalman rank of ``(A, B)`` of the conservative model; the Kalman matrix
  ``[B, AB, A^2 B, ...]`` itself is numerically useless for 10R states (powers of A up to
  10R - 1), and even the orthogonal staircase (:func:`krylov_rank`) picks up spurious
  directions in long single-input chains (measured: a single tendon of the (4,2) shell); the
  tests check that the two agree where the staircase is reliable.
- **Gramians** of the non-rigid part (the ``M``-orthogonal complement of the rigid-body motions)
  with the linearization's own damping, by ``control.lyap``; undamped, the infinite-horizon
  Gramians do not exist and are not reported (linearize ``artificial_damping(structure)``).
"""

from __future__ import annotations

import builtins
import dataclasses
import fnmatch
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from tensegrity.analysis.linearize import OUTPUT_GROUPS, Linearization
from tensegrity.analysis.modes import RIGID, ModalAnalysis
from tensegrity.model.structure import Structure

#: :func:`krylov_rank` drops Krylov directions with singular value below ``RANK_RTOL * ||A||``.
RANK_RTOL = 1e-6
#: PBH singular values below ``PBH_RTOL * ||M^-1/2 B||`` count as zero.
PBH_RTOL = 1e-8
#: Modes whose frequencies agree to this relative tolerance form one cluster in the PBH test.
CLUSTER_RTOL = 1e-6


@dataclasses.dataclass(frozen=True)
class ModeTest:
    """The PBH test of one cluster of modes of equal frequency."""

    modes: tuple[int, ...]  #: indices in the :class:`ModalAnalysis`
    frequency_hz: float
    kind: str
    multiplicity: int
    rank: int  #: rank of the mode-input (mode-output) matrix
    margin: float  #: its smallest singular value over the scale (0 if rank-deficient to round-off)

    @property
    def deficit(self) -> int:
        """Number of modes of the cluster that cannot be reached (seen)."""
        return self.multiplicity - self.rank

    @property
    def full(self) -> bool:
        return self.rank == self.multiplicity


@dataclasses.dataclass(frozen=True, eq=False)
class ReachResult:
    """Controllability from one set of inputs, or observability from one set of outputs."""

    property: str  #: ``"controllability"`` or ``"observability"``
    name: str  #: the set's name (its pattern)
    signals: tuple[str, ...]  #: input (tendon) names or output names
    n_states: int
    rank: int  #: of the controllable (observable) subspace, ``2 sum_j rank_j``
    rank_rtol: float
    elastic_states: int  #: states of the non-rigid part, ``2 (5R - k_rigid)``
    elastic_rank: int
    mode_tests: tuple[ModeTest, ...]
    pbh_rtol: float
    gramian_eigenvalues: np.ndarray | None  #: of the non-rigid part (damped systems only)
    gramian_note: str

    # ``builtins.property``: the field ``property`` above shadows the builtin in this class body
    # for a type checker (at run time an annotation without a value binds no name).
    @builtins.property
    def full_rank(self) -> bool:
        return self.rank == self.n_states

    @builtins.property
    def elastic_full_rank(self) -> bool:
        return self.elastic_rank == self.elastic_states

    def missed_modes(self, *, include_rigid: bool = False) -> list[int]:
        """Mode indices of the clusters that fail the PBH test (rigid-body modes only if asked)."""
        out: list[int] = []
        for test in self.mode_tests:
            if not test.full and (include_rigid or test.kind != RIGID):
                out.extend(test.modes)
        return out

    def to_dict(self) -> dict[str, Any]:
        g = self.gramian_eigenvalues
        return {
            "property": self.property,
            "name": self.name,
            "signals": list(self.signals),
            "states": self.n_states,
            "rank": self.rank,
            "rank_rtol": self.rank_rtol,
            "elastic_states": self.elastic_states,
            "elastic_rank": self.elastic_rank,
            "pbh_rtol": self.pbh_rtol,
            "missed_modes": [
                {
                    "modes": list(t.modes),
                    "frequency_hz": t.frequency_hz,
                    "kind": t.kind,
                    "multiplicity": t.multiplicity,
                    "rank": t.rank,
                }
                for t in self.mode_tests
                if not t.full
            ],
            "gramian": None
            if g is None
            else {
                "min_eigenvalue": float(g.min()),
                "max_eigenvalue": float(g.max()),
                "condition": float(g.max() / g.min()) if g.min() > 0 else float("inf"),
            },
            "gramian_note": self.gramian_note,
        }


# ---------------------------------------------------------------------------- sets
def resolve_inputs(lin: Linearization, pattern: str | Sequence[str]) -> tuple[str, ...]:
    """Tendon names matching ``pattern`` (``"all"``, comma-separated fnmatch patterns, or a
    list)."""
    return match_tendons(lin.structure, pattern)


def match_tendons(structure: Structure, pattern: str | Sequence[str]) -> tuple[str, ...]:
    """Names of ``structure``'s tendons matching ``pattern`` (see :func:`resolve_inputs`);
    ``KeyError`` if none does."""
    names = structure.tendon_name
    parts = split_patterns(pattern)
    if parts == ["all"]:
        return tuple(names)
    chosen = [n for n in names if any(fnmatch.fnmatchcase(n, p) for p in parts)]
    if not chosen:
        raise KeyError(f"no tendon matches {pattern!r}")
    return tuple(chosen)


def resolve_outputs(lin: Linearization, pattern: str | Sequence[str]) -> tuple[str, ...]:
    """Output names matching ``pattern``: group names, ``"all"`` or fnmatch patterns."""
    parts = split_patterns(pattern)
    chosen: list[str] = []
    for p in parts:
        if p == "all":
            chosen.extend(lin.output_names)
        elif p in OUTPUT_GROUPS:
            chosen.extend(lin.output_names[i] for i in lin.output_indices(p))
        else:
            chosen.extend(n for n in lin.output_names if fnmatch.fnmatchcase(n, p))
    chosen = list(dict.fromkeys(chosen))
    if not chosen:
        raise KeyError(f"no output matches {pattern!r}")
    return tuple(chosen)


def split_patterns(pattern: str | Sequence[str]) -> list[str]:
    """The names and patterns of ``pattern``: comma-separated text (spaces around each item
    ignored) or a list; ``ValueError`` naming ``pattern`` if an item is empty (``"all,"``,
    ``"a,,b"``)."""
    parts = [p.strip() for p in pattern.split(",")] if isinstance(pattern, str) else list(pattern)
    if not parts or not all(isinstance(p, str) and p.strip() for p in parts):
        raise ValueError(f"an empty name or pattern in {pattern!r}")
    return parts


def default_input_sets(lin: Linearization) -> dict[str, tuple[str, ...]]:
    """``all``, each tendon family (``t1_*``, ... by the name before its first ``_``; ``b*``, ...
    by the name without its trailing digits if it has no ``_``), and the first tendon alone."""
    names = lin.structure.tendon_name
    sets = {"all": tuple(names)}
    # t1_1_1 -> t1_* (shells); b0 -> b* (prisms: no '_')
    families = dict.fromkeys(
        n.split("_")[0] + "_*" if "_" in n else n.rstrip("0123456789") + "*" for n in names
    )
    if len(families) > 1:
        for family in families:
            sets[family] = resolve_inputs(lin, family)
    sets[names[0]] = (names[0],)
    return sets


def default_output_sets(lin: Linearization) -> dict[str, tuple[str, ...]]:
    """Node positions, tendon lengths, tensions, and the position of node 0 alone."""
    return {g: resolve_outputs(lin, g) for g in OUTPUT_GROUPS} | {
        "p0_*": resolve_outputs(lin, "p0_*")
    }


# ---------------------------------------------------------------------------- algorithms
def krylov_rank(A: np.ndarray, B: np.ndarray, rtol: float = RANK_RTOL) -> int:
    """Dimension of the controllable subspace of ``(A, B)`` by the orthogonal staircase method:
    an orthonormal basis grown by ``A`` times the newest block, re-orthogonalized twice, keeping
    directions whose singular value exceeds ``rtol * ||A||_2`` (``rtol * ||B||_2`` at the start)."""
    n = A.shape[0]
    norm_a = np.linalg.norm(A, 2) or 1.0
    u, sv, _ = np.linalg.svd(B, full_matrices=False)
    if sv.size == 0 or sv[0] == 0:
        return 0
    basis = u[:, sv > rtol * sv[0]]
    new = basis
    while new.shape[1] and basis.shape[1] < n:
        W = A @ new
        for _ in range(2):
            W -= basis @ (basis.T @ W)
        u, sv, _ = np.linalg.svd(W, full_matrices=False)
        new = u[:, sv > rtol * norm_a]
        basis = np.hstack([basis, new])
    return int(basis.shape[1])


def _balance(lin: Linearization) -> tuple[np.ndarray, float]:
    """``(T, w)``: the diagonal ``T`` of the balanced state ``T z = [w sqrt(M) x, sqrt(M) x']``,
    with ``w = sqrt(max |eig(M^-1 K)|)`` the largest natural frequency [rad/s] (1 if none)."""
    root = np.sqrt(lin.mass)
    w = np.sqrt(np.max(np.abs(np.linalg.eigvalsh((lin.stiffness / root[:, None]) / root[None, :]))))
    w = float(w) if w > 0 else 1.0
    return np.concatenate([w * root, root]), w


def _clusters(modes: ModalAnalysis) -> list[list[int]]:
    out: list[list[int]] = []
    rigid = [i for i, k in enumerate(modes.kind) if k == RIGID]
    if rigid:
        out.append(rigid)
    rest = [i for i, k in enumerate(modes.kind) if k != RIGID]
    for i in rest:
        w = np.sqrt(abs(modes.omega_squared[i]))
        if out and out[-1][0] in rest:
            w0 = np.sqrt(abs(modes.omega_squared[out[-1][0]]))
            if abs(w - w0) <= CLUSTER_RTOL * max(w, w0, np.sqrt(modes.zero_tol)):
                out[-1].append(i)
                continue
        out.append([i])
    return out


def _mode_tests(
    modes: ModalAnalysis,
    matrix_of: Callable[[np.ndarray, float], np.ndarray],
    scale: float,
    rtol: float,
) -> tuple[ModeTest, ...]:
    tests = []
    for cluster in _clusters(modes):
        w = float(np.sqrt(max(modes.omega_squared[cluster[0]], 0.0)))
        G = matrix_of(modes.shapes[:, cluster], w)
        sv = np.linalg.svd(G, compute_uv=False) if G.size else np.zeros(0)
        rank = int(np.sum(sv > rtol * scale))
        margin = float(sv.min() / scale) if sv.size >= len(cluster) and scale > 0 else 0.0
        tests.append(
            ModeTest(
                tuple(cluster),
                float(modes.frequency_hz[cluster[0]]),
                modes.kind[cluster[0]],
                len(cluster),
                min(rank, len(cluster)),
                margin,
            )
        )
    return tuple(tests)


def _gramian(A_e: np.ndarray, BB: np.ndarray) -> tuple[np.ndarray | None, str]:
    import control

    decay = float(np.max(np.linalg.eigvals(A_e).real))
    if decay >= -1e-12:
        return None, (
            "no infinite-horizon Gramian: the non-rigid part is not asymptotically "
            "stable (undamped?); linearize a damped structure"
        )
    W = control.lyap(A_e, BB, method="scipy")
    W = 0.5 * (W + W.T)
    return np.linalg.eigvalsh(W), "Gramian of the non-rigid part (control.lyap)"


def _result(
    kind: str,
    lin: Linearization,
    name: str,
    signals: tuple[str, ...],
    tests: tuple[ModeTest, ...],
    pbh_rtol: float,
    A_e: np.ndarray,
    QQ: np.ndarray,
) -> ReachResult:
    """The :class:`ReachResult`: rank ``2 x`` modes reached (seen), Gramian of ``(A_e, QQ)``."""
    rank = sum(2 * t.rank for t in tests)
    rigid = sum(2 * t.rank for t in tests if t.kind == RIGID)
    gram, note = _gramian(A_e, QQ)
    return ReachResult(
        kind,
        name,
        signals,
        lin.A.shape[0],
        rank,
        pbh_rtol,
        A_e.shape[0],
        rank - rigid,
        tests,
        pbh_rtol,
        gram,
        note,
    )


def controllability(
    lin: Linearization,
    modes: ModalAnalysis,
    inputs: str | Sequence[str] = "all",
    *,
    name: str | None = None,
    pbh_rtol: float = PBH_RTOL,
) -> ReachResult:
    """Controllability from the rest-length changes of the tendons ``inputs`` (names/patterns)."""
    signals = resolve_inputs(lin, inputs)
    cols = lin.input_indices(signals)
    Bf = lin.force_input[:, cols]
    scale = float(np.linalg.norm(Bf / np.sqrt(lin.mass)[:, None], 2))
    tests = _mode_tests(modes, lambda V, w: V.T @ Bf, scale, pbh_rtol)
    A_e, Z = lin.elastic_part()
    B_e = np.vstack([np.zeros((Z.shape[1], cols.size)), Z.T @ Bf])
    return _result(
        "controllability", lin, name or _name(inputs), signals, tests, pbh_rtol, A_e, B_e @ B_e.T
    )


def observability(
    lin: Linearization,
    modes: ModalAnalysis,
    outputs: str | Sequence[str] = "position",
    *,
    name: str | None = None,
    pbh_rtol: float = PBH_RTOL,
) -> ReachResult:
    """Observability from the outputs ``outputs`` (names, patterns or groups)."""
    signals = resolve_outputs(lin, outputs)
    rows = lin.output_indices(signals)
    n = lin.n_dof
    Cx, Cv = lin.C[rows, :n], lin.C[rows, n:]
    _, w_ref = _balance(lin)
    root = np.sqrt(lin.mass)
    scale = float(np.linalg.norm(np.hstack([Cx / root[None, :] / w_ref, Cv / root[None, :]]), 2))
    tests = _mode_tests(
        modes, lambda V, w: (Cx @ V) / w_ref + 1j * (w / w_ref) * (Cv @ V), scale, pbh_rtol
    )
    A_e, Z = lin.elastic_part()
    C_e = np.hstack([Cx @ Z, Cv @ Z])
    return _result(
        "observability", lin, name or _name(outputs), signals, tests, pbh_rtol, A_e.T, C_e.T @ C_e
    )


def _name(pattern: str | Sequence[str]) -> str:
    return pattern if isinstance(pattern, str) else ",".join(pattern)


def controllability_table(
    lin: Linearization,
    modes: ModalAnalysis,
    input_sets: Mapping[str, str | Sequence[str]] | None = None,
    output_sets: Mapping[str, str | Sequence[str]] | None = None,
) -> tuple[list[ReachResult], list[ReachResult]]:
    """Controllability for every input set and observability for every output set (defaults:
    :func:`default_input_sets`, :func:`default_output_sets`)."""
    input_sets = default_input_sets(lin) if input_sets is None else input_sets
    output_sets = default_output_sets(lin) if output_sets is None else output_sets
    return (
        [controllability(lin, modes, v, name=k) for k, v in input_sets.items()],
        [observability(lin, modes, v, name=k) for k, v in output_sets.items()],
    )
