"""The paper's matrices written to files (:func:`write_matrices`: ``.npz``, Matrix Market
``.mtx`` and a JSON index), from :mod:`tensegrity.physics.matrix_form`."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
import scipy.sparse as sp

from tensegrity.io.files import atomic_path
from tensegrity.model.shell import class1_shell
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics
from tensegrity.physics.matrix_form import STATE_MATRICES, ShellMatrixModel, StateMatrices

# ============================================================================ files
_DESCRIPTIONS = {
    "Q": ("18.28", "q = Q l: coordinates from the independent vectors l"),
    "Q_inv": ("App. B", "l = Q^-1 q, by the block formulas of Appendix B"),
    "R": (
        "18.37",
        "l^d = R q: the vectors of the f^d slots "
        "(t1_n1, then t2 t3 t4 t6 t7 t8 t9 t10 per element)",
    ),
    "R_o": ("18.43", "[t5; t1] per element = R_o q: rows of Q^-1 (R_0 for t1_n1)"),
    "T": ("18.55", "u~ = T u: the rest-length change of every slot from the independent u"),
    "W_o": ("18.15", "W^o = BlockDiag[W]: f = W^o (nodal forces)"),
    "B_d": ("18.15", "f = B^d f^d + B^o f^o + W^o w"),
    "B_o": ("18.15", "f = B^d f^d + B^o f^o + W^o w"),
    "P": ("18.26", "p = P q: node positions"),
    "H": ("18.20", "H = BlockDiag[H_ij], H = (2/m) diag(I, (3/L^2) skew(q2)^2) per rod"),
    "K_r": ("18.20", "K_r = BlockDiag[Omega_ij], |q2'|^2/L^2 on the q2 rows"),
    "K_d": ("18.47", "f^d = -K^d q + P^d u~^d (k = 0 for a slack tendon)"),
    "K_o": ("18.48", "f^o = -K^o q + P^o u~^o"),
    "P_d": ("18.47", "P^d = BlockDiag[b], b = k t/|t| for a taut tendon"),
    "P_o": ("18.48", "P^o = BlockDiag[b]"),
    "K_tilde": ("18.52", "K~ = B^d K^d + B^o K^o"),
    "B_tilde": ("18.52", "B~ = [B^d P^d, B^o P^o]"),
    "K_p": ("18.59", "K_p = H K~"),
    "B": ("18.59", "B = H B~ T: q'' = -(K_r + K_p) q + B u + D w"),
    "D": ("18.59", "D = H W^o"),
    "C_t": ("18.43", "tendon vectors t = C_t q, one 3-row block per entry of u"),
    "C_l": ("18.60", "d y_l / d q: linearized tendon-length output, y_l = |C_t q| per tendon"),
    "C_f": ("18.60", "d y_f / d q: linearized tension output, y_f = k (y_l - L0 + u) when taut"),
}


def write_matrices(
    out_dir: str | Path,
    structure_or_size: Structure | Sequence[int],
    q: np.ndarray | None = None,
    qdot: np.ndarray | None = None,
    u: np.ndarray | None = None,
    w: np.ndarray | None = None,
    *,
    at: str | None = None,
) -> list[tuple[str, tuple[int, int], int]]:
    """Write every matrix of the model as ``NAME.npz`` and ``NAME.mtx``, the state as
    ``state.npz`` and an index ``matrices.json``, each file atomically.

    Parameters
    ----------
    out_dir : path
        Output folder, created if needed.
    structure_or_size : Structure or (n, m) or (n, m, primal)
        An undamped class 1 shell, or the size of ``class1_shell(n, m, primal=primal)``.
    q, qdot : ndarray (12nm,), optional
        The state at which the state-dependent matrices are evaluated.  Default: the structure's
        initial state (:func:`dynamics.initial_state`).
    u : ndarray (n(10m-2),), optional
        Control in the paper's order (:func:`control_names`); default 0.
    w : ndarray (12nm,) or (4nm, 3), optional
        External nodal forces (only recorded; ``D`` does not depend on them); default 0.
    at : str, optional
        A label for the state (e.g. ``"initial"``, ``"equilibrium"``), recorded in the index.

    Returns
    -------
    list of (name, shape, nnz)
        One row per matrix, in the order written.
    """
    structure = _shell(structure_or_size)
    model = ShellMatrixModel(structure)
    state, w_vec = _evaluated_state(model, q, qdot, u, w)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows, entries = _write_matrix_files(out, {**model.topology.matrices(), **state.matrices()})
    p = dynamics.nodes_from_coordinates(structure, state.q)
    with _atomic_binary(out / "state.npz") as handle:
        np.savez(
            handle,
            q=state.q,
            qdot=state.qdot,
            node_position=p,
            u=state.u,
            utilde=state.utilde,
            w=w_vec,
            qddot=state.qddot(w_vec),
        )
    index = _index(model, state, p, w_vec, entries, at=at)
    with atomic_path(out / "matrices.json") as tmp:
        tmp.write_text(json.dumps(index, indent=1) + "\n", encoding="utf-8")
    return rows


def _shell(structure_or_size: Structure | Sequence[int]) -> Structure:
    """The structure given, or ``class1_shell(n, m, primal=primal)`` of a size (n, m[, primal])."""
    if isinstance(structure_or_size, Structure):
        return structure_or_size
    size = tuple(structure_or_size)
    if len(size) not in (2, 3):
        raise ValueError(
            f"structure_or_size: expected a Structure or (n, m[, primal]), got {size!r}"
        )
    return class1_shell(size[0], size[1], primal=bool(size[2]) if len(size) == 3 else False)


def _evaluated_state(
    model: ShellMatrixModel,
    q: np.ndarray | None,
    qdot: np.ndarray | None,
    u: np.ndarray | None,
    w: np.ndarray | None,
) -> tuple[StateMatrices, np.ndarray]:
    """The model's matrices at ``(q, q', u)`` (each default: the initial state, ``u = 0``) and
    the nodal forces ``w`` as a (12nm,) vector [N] (default 0), checked finite."""
    top = model.topology
    if q is None or qdot is None:
        state = dynamics.initial_state(model.structure)
        q = state.q if q is None else q
        qdot = state.qdot if qdot is None else qdot
    evaluated = model.evaluate(q, qdot, u)
    w_vec = np.zeros(top.n_coordinates) if w is None else np.asarray(w, dtype=float).reshape(-1)
    if w_vec.shape != (top.n_coordinates,):
        raise ValueError(f"w: expected {top.n_coordinates} numbers, got {w_vec.size}")
    if not (
        np.all(np.isfinite(evaluated.q))
        and np.all(np.isfinite(evaluated.qdot))
        and np.all(np.isfinite(w_vec))
    ):
        raise ValueError("q, qdot, w: must be finite")
    return evaluated, w_vec


@contextlib.contextmanager
def _atomic_binary(path: Path) -> Iterator[BinaryIO]:
    """A binary file to write that replaces ``path`` atomically when the ``with`` body ends
    (:func:`~tensegrity.io.files.atomic_path`)."""
    with atomic_path(path) as tmp, open(tmp, "wb") as handle:
        yield handle


def _write_matrix_files(
    out: Path, matrices: dict[str, sp.csr_matrix]
) -> tuple[list[tuple[str, tuple[int, int], int]], list[dict[str, Any]]]:
    """Write each matrix as ``NAME.npz`` and ``NAME.mtx`` in ``out``.

    Returns
    -------
    rows : list of (name, shape, nnz)
    entries : list of dict
        The index's description of each matrix (shape, nnz, equation, files).
    """
    import scipy.io

    rows, entries = [], []
    for name, matrix in matrices.items():
        with _atomic_binary(out / f"{name}.npz") as handle:
            sp.save_npz(handle, matrix, compressed=True)
        with _atomic_binary(out / f"{name}.mtx") as handle:
            scipy.io.mmwrite(
                handle, matrix, comment=f"tensegrity matrix {name} ({_DESCRIPTIONS[name][1]})"
            )
        shape = (int(matrix.shape[0]), int(matrix.shape[1]))
        rows.append((name, shape, int(matrix.nnz)))
        equation, description = _DESCRIPTIONS[name]
        entries.append(
            {
                "name": name,
                "shape": list(shape),
                "nnz": int(matrix.nnz),
                "equation": equation,
                "description": description,
                "npz": f"{name}.npz",
                "mtx": f"{name}.mtx",
                "state_dependent": name in STATE_MATRICES,
            }
        )
    return rows, entries


def _index(
    model: ShellMatrixModel,
    state: StateMatrices,
    node_position: np.ndarray,
    w: np.ndarray,
    entries: list[dict[str, Any]],
    *,
    at: str | None,
) -> dict[str, Any]:
    """The content of ``matrices.json``: the shell, the state (``node_position`` (4nm, 3) [m],
    ``w`` (12nm,) [N]) labelled ``at``, the orderings and the matrices' ``entries``."""
    structure, top = model.structure, model.topology
    return {
        "format": "tensegrity-matrices",
        "version": 1,
        "model": (
            "q'' + (K_r(q') + K_p(q)) q = B(q) u + D(q) w  (Skelton, Pinaud, Mingori, eq. 18.59)"
        ),
        "shell": {
            "n": top.n,
            "m": top.m,
            "primal": top.primal,
            "nodes": structure.n_nodes,
            "rods": structure.n_rods,
            "tendons": structure.n_tendons,
        },
        "at": at,
        "state": {
            "file": "state.npz",
            "q": state.q.tolist(),
            "qdot": state.qdot.tolist(),
            "node_position": node_position.tolist(),
            "u": state.u.tolist(),
            "w": w.tolist(),
        },
        "orderings": {
            "q": (
                "per element (i,j), e = (j-1) n + (i-1): [p1+p2, p2-p1, p3+p4, p4-p3], "
                "3 numbers each"
            ),
            "w": "per element: forces on nodes p1, p2, p3, p4 (node order), 3 numbers each",
            "u": "one tendon per entry (u_tendon); u = rest-length change [m], Lbar = L0 - u",
            "l": list(top.l_labels),
            "ld_slots": _slot_entries(top.d_slots, top.d_tendon, top.d_sign, top.d_counted),
            "fo_slots": _slot_entries(top.o_slots, top.o_tendon, top.o_sign, top.o_counted),
        },
        "u_tendon": list(top.u_names),
        "matrices": entries,
        "notes": "undamped model; see docs/matrix-model.md for the orderings and the departures "
        "from the printed equations",
    }


def _slot_entries(
    slots: Sequence[str], tendons: Sequence[str | None], signs: np.ndarray, counted: np.ndarray
) -> list[dict[str, Any]]:
    """One ``{"slot", "tendon", "sign", "counted"}`` per slot of ``l^d`` or ``f^o``."""
    return [
        {"slot": s, "tendon": t, "sign": int(g), "counted": bool(c)}
        for s, t, g, c in zip(slots, tendons, signs, counted, strict=True)
    ]
