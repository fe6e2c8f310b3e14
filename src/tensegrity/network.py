"""Any network (class 1 or class k): the field's ``N, C_b, C_s`` convention, readable YAML / TOML.

Conventions (Skelton & de Oliveira, *Tensegrity Systems*, 2009, ch. 2)
---------------------------------------------------------------------
- ``N`` is the **3 x n** node matrix: column ``i`` is node ``i``'s position [m] (**2 x n**:
  a planar structure).
- ``C_b`` (bars x n) and ``C_s`` (strings x n) are connectivity matrices: row ``k`` has exactly
  one ``-1`` (the member's tail node) and one ``+1`` (its head node), zeros elsewhere, so the
  member vectors are the columns of ``B = N C_b^T`` and ``S = N C_s^T`` (head minus tail).
- Bars are the library's rods (``Structure.rod_nodes[k] = (tail, head)``), strings its tendons
  (``Structure.tendon_nodes[k] = (tail, head)``): the same orientation as
  :class:`~tensegrity.structure.Structure`.  A class 1 structure has every node at the end of
  exactly one bar; a node shared by ``k`` bars is a class k ball joint, which the library holds
  as joined rod ends (``Structure.joint_nodes``): :func:`from_connectivity` with
  ``ball_joints=True`` splits such a node, :func:`to_connectivity` (:func:`merge_joints`) merges
  joined nodes back into one.

File formats (:func:`read_network`, :func:`write_network`, chosen by the file's suffix)
--------------------------------------------------------------------------------------
- ``.json``: the JSON form of :meth:`Structure.to_dict`.
- ``.yaml`` / ``.yml`` and ``.toml``: the readable form of :func:`network_to_dict` (named nodes,
  shared parameters under ``defaults``, rest length or prestrain per tendon, supports).
- ``.npz``: the connectivity form, arrays ``N``, ``C_b``, ``C_s``, per-member parameters and
  supports (:data:`NPZ_ARRAYS`).
- The readable and connectivity forms are class k (joined nodes merged, supports on merged
  nodes): a structure without joints reads back identical, a jointed one with the same
  ``N, C_b, C_s``, supports and parameters in the layout of :func:`from_connectivity`.
- ``.xml`` (write only): MuJoCo MJCF (:func:`tensegrity.mjcf.to_mjcf`).

SI units throughout: m, kg, s, N.
"""

from __future__ import annotations

import io as _io
import json
import math
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from tensegrity.io import (
    PathLike,
    _file_error,
    _os_problem,
    atomic_path,
    read_structure,
    write_structure,
)
from tensegrity.structure import Structure, _dimension, _number, _vector

#: Format name of each file suffix.
FORMATS = {
    ".json": "json",
    ".yaml": "yaml",
    ".yml": "yaml",
    ".toml": "toml",
    ".npz": "connectivity",
    ".xml": "mjcf",
}
#: ``format`` key of the readable form.
NETWORK_FORMAT = "tensegrity-network"
NETWORK_VERSION = 1
#: Default rod mass [kg] and tendon stiffness [N/m] (those of :func:`tensegrity.class1_shell`).
DEFAULT_ROD_MASS = 1.0
DEFAULT_STIFFNESS = 100.0
#: Arrays of the connectivity file (``.npz``): name -> (required, meaning).
NPZ_ARRAYS = {
    "N": (True, "(d, n) node positions [m], one column per node (d = 3, or 2: planar)"),
    "C_b": (True, "(R, n) bar connectivity, -1 at the tail and +1 at the head of each row"),
    "C_s": (True, "(S, n) string connectivity, same rule"),
    "rod_mass": (False, f"(R,) [kg], default {DEFAULT_ROD_MASS}"),
    "rod_length": (False, "(R,) [m], default the bar's length in N"),
    "rod_damping": (False, "(R,) mass-proportional damping [1/s], default 0"),
    "tendon_stiffness": (False, f"(S,) [N/m], default {DEFAULT_STIFFNESS}"),
    "tendon_rest_length": (False, "(S,) [m]; this or tendon_prestrain is required"),
    "tendon_prestrain": (False, "(S,) strain (l - L0) / L0 in N"),
    "tendon_damping": (False, "(S,) [N s/m], default 0"),
    "tendon_name": (False, "(S,) unicode names"),
    "node_velocity": (False, "(d, n) [m/s], default 0"),
    "node_fixed": (False, "(n,) bool, nodes held at their position (supports, anchors)"),
    "node_point_mass": (False, "(n,) [kg], a point mass at a node (> 0), default 0"),
    "plane_nodes": (False, "(P,) int, nodes held on a plane through their position"),
    "plane_normal": (False, "(P, 3) the planes' normals"),
    "line_nodes": (False, "(Q,) int, nodes held on a line through their position"),
    "line_direction": (False, "(Q, d) the lines' directions"),
    "joint_nodes": (False, "(J, 2) int, pairs of nodes joined by a ball joint (besides shared nodes)"),
}

_ROD_KEYS = ("mass", "length", "damping")
_TENDON_KEYS = ("stiffness", "rest_length", "prestrain", "damping")


class Connectivity(NamedTuple):
    """A structure in the field's convention: ``N`` (3, n) [m], ``C_b`` (R, n), ``C_s`` (S, n)."""

    N: np.ndarray
    C_b: np.ndarray
    C_s: np.ndarray


# ----------------------------------------------------------------------- N, C_b, C_s
def member_nodes(C: Any, field: str, n_nodes: int) -> np.ndarray:
    """``(tail, head)`` node pairs (k, 2) of a connectivity matrix ``C`` (k, n_nodes), dense or
    ``scipy.sparse``.

    Raises
    ------
    ValueError
        ``C_b: has 5 columns but N has 6 nodes``, or ``C_s[3]: expected exactly one -1 and one
        +1 (zeros elsewhere), got -1 at [0, 2], +1 at []``.
    """
    if hasattr(C, "toarray"):  # a scipy.sparse matrix
        C = C.toarray()
    try:
        C = np.array(C, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{field}: expected a matrix of -1, 0, +1") from None
    if C.size == 0 and C.ndim <= 2:
        C = C.reshape(0, n_nodes)
    if C.ndim != 2:
        raise ValueError(f"{field}: expected a 2-D matrix (members x nodes), got shape {C.shape}")
    if C.shape[1] != n_nodes:
        raise ValueError(f"{field}: has {C.shape[1]} columns but N has {n_nodes} nodes "
                         "(a member on a missing node?)")
    tails, heads = C == -1, C == 1
    bad = np.flatnonzero((tails.sum(1) != 1) | (heads.sum(1) != 1) | np.any((C != 0) & ~tails & ~heads, axis=1))
    if bad.size:
        k = bad[0]
        other = np.flatnonzero((C[k] != 0) & ~tails[k] & ~heads[k])
        raise ValueError(
            f"{field}[{k}]: expected exactly one -1 and one +1 (zeros elsewhere), got -1 at "
            f"{np.flatnonzero(tails[k]).tolist()}, +1 at {np.flatnonzero(heads[k]).tolist()}"
            + (f", {float(C[k, other[0]])!r} at {other[0]}" if other.size else "")
        )
    return np.column_stack([tails.argmax(1), heads.argmax(1)]).astype(np.int64)


def check_class1(rod_nodes: np.ndarray, n_nodes: int) -> None:
    """No node at the end of two bars, or a ``ValueError`` that says what it is instead (a
    class 2 joint, which :func:`from_connectivity` takes with ``ball_joints=True``)."""
    count = np.bincount(rod_nodes.ravel(), minlength=n_nodes)
    shared = np.flatnonzero(count > 1)
    if shared.size:
        node = shared[0]
        bars = np.flatnonzero(np.any(rod_nodes == node, axis=1)).tolist()
        raise ValueError(
            f"bars: node {node} is an end of bars {bars}; bars that share a node form a "
            "class 2 joint, not a class 1 structure (pass ball_joints=True to join their ends "
            "by a ball joint)"
        )


def _per_member(value: Any, count: int, field: str) -> np.ndarray:
    """A scalar broadcast to ``(count,)``, or an array of that length (values checked later)."""
    array = np.asarray(value, dtype=float)
    if array.ndim == 0:
        return np.full(count, float(array))
    if array.shape != (count,):
        raise ValueError(f"{field}: expected a number or {count} values, got shape {array.shape}")
    return array


def rest_from_prestrain(length: np.ndarray, prestrain: Any, field: str = "tendon_prestrain") -> np.ndarray:
    """Rest lengths ``L0 = l / (1 + eps)`` [m] for strains ``eps = (l - L0) / L0`` (> -1)."""
    eps = _per_member(prestrain, length.size, field)
    bad = np.flatnonzero(~np.isfinite(eps) | (eps <= -1))
    if bad.size:
        raise ValueError(f"{field}[{bad[0]}]: must be finite and > -1, got {eps[bad[0]]}")
    return length / (1.0 + eps)


def _node_list(value: Any, field: str, n_nodes: int) -> np.ndarray:
    """A 1-D array of node indices in ``[0, n_nodes)`` (``None``: empty)."""
    array = np.asarray([] if value is None else value)
    if array.ndim != 1 or (array.size and not np.all(np.mod(array, 1) == 0)):
        raise ValueError(f"{field}: expected a list of node indices, got shape {array.shape}")
    array = array.astype(np.int64)
    bad = np.flatnonzero((array < 0) | (array >= n_nodes))
    if bad.size:
        raise ValueError(f"{field}[{bad[0]}]: node index {array[bad[0]]} out of range [0, {n_nodes - 1}]")
    return array


def from_connectivity(
    N: Any,
    C_b: Any,
    C_s: Any,
    *,
    rod_mass: Any = DEFAULT_ROD_MASS,
    rod_length: Any = None,
    rod_damping: Any = 0.0,
    tendon_stiffness: Any = DEFAULT_STIFFNESS,
    tendon_rest_length: Any = None,
    tendon_prestrain: Any = None,
    tendon_damping: Any = 0.0,
    tendon_name: Sequence[str] | None = None,
    node_velocity: Any = None,
    node_fixed: Any = None,
    node_point_mass: Any = None,
    plane_nodes: Any = None,
    plane_normal: Any = None,
    line_nodes: Any = None,
    line_direction: Any = None,
    joint_nodes: Any = None,
    ball_joints: bool = False,
) -> Structure:
    """A :class:`Structure` from the node matrix and the connectivity matrices.

    Parameters
    ----------
    N : array_like, shape (3, n) or (2, n)
        Node matrix [m], one column per node (Skelton & de Oliveira's convention; pass ``N.T``
        for an (n, 3) array of positions).  Two rows: a planar structure.
    C_b : array_like, shape (R, n)
        Bar connectivity: row ``k`` has ``-1`` at the tail node, ``+1`` at the head node.
    C_s : array_like, shape (S, n)
        String (tendon) connectivity, the same rule; the string vector is head minus tail.
    rod_mass, rod_damping : float or (R,)
        Bar masses [kg] (default 1) and mass-proportional damping rates [1/s] (default 0).
    rod_length : float or (R,), optional
        Bar lengths [m]; default the lengths of ``N C_b^T`` (given, they must agree with ``N``).
    tendon_stiffness, tendon_damping : float or (S,)
        [N/m] (default 100) and [N s/m] (default 0).
    tendon_rest_length, tendon_prestrain : float or (S,)
        Exactly one: the rest lengths ``L0`` [m], or the strains ``eps = (l - L0) / L0`` in the
        configuration ``N`` (``eps > 0``: taut).
    tendon_name : sequence of str, optional
        Default ``"s0", "s1", ...``.
    node_velocity : array_like, shape (d, n), optional
        Initial node velocities [m/s], one column per node.
    node_fixed : array_like of bool, shape (n,), optional
        Nodes held at their position in ``N`` (supports; a fixed node in no bar is an anchor).
    node_point_mass : float or (n,), optional
        Point masses [kg] at nodes (> 0), default 0.  A node in no bar must be fixed or carry one.
    plane_nodes, plane_normal : (P,) int and (P, 3), optional
        Nodes held on the plane through their position in ``N`` with the given normal.
    line_nodes, line_direction : (Q,) int and (Q, d), optional
        Nodes held on the line through their position in ``N`` along the given direction.
    joint_nodes : (J, 2) int, optional
        Pairs of (coinciding) nodes joined by a ball joint besides the shared nodes: rods that
        keep their own end nodes (``Structure.joint_nodes``), as the JSON form has them.
    ball_joints : bool
        Take a class k network: a node shared by ``k`` bars becomes ``k`` rod-end nodes joined
        by a ball joint (``Structure.joint_nodes``), and a point mass on a bar's node its own
        node joined to the bar's end.  Node ``i`` becomes consecutive nodes (an anchor if it is
        fixed and in no bar, the ends of its bars in bar order, then its point mass); strings,
        support and plane/line constraints go to the first, the end of the lowest-numbered
        bar if it has bars.  A class 1 network keeps its node
        numbering.  Default ``False``: a node in two bars is an error.

    Raises
    ------
    ValueError
        Naming the field: ``N``, ``C_b[k]``, ``C_s``, ``bars`` (a node in two bars: a class 2
        joint, without ``ball_joints``), ``C_b[k]: zero length``, ``nodes[i]`` (a node in no
        bar, neither fixed nor a point mass), the parameters.
    """
    N = np.asarray(N, dtype=float)
    if N.ndim != 2 or N.shape[0] not in (2, 3):
        hint = " (one column per node: pass N.T for positions in rows)" if N.ndim == 2 and N.shape[1] in (2, 3) else ""
        raise ValueError(f"N: expected shape (3, n) or (2, n), got {N.shape}{hint}")
    if not np.all(np.isfinite(N)):
        raise ValueError(f"N[:, {int(np.argwhere(~np.isfinite(N))[0, 1])}]: must be finite")
    n_nodes = N.shape[1]
    rods = member_nodes(C_b, "C_b", n_nodes)
    tendons = member_nodes(C_s, "C_s", n_nodes)
    position = N.T
    length = np.linalg.norm(position[rods[:, 1]] - position[rods[:, 0]], axis=1)
    zero = np.flatnonzero(length == 0)
    if zero.size:
        k = zero[0]
        raise ValueError(f"C_b[{k}]: bar joins nodes {rods[k, 0]} and {rods[k, 1]}, which coincide "
                         "(zero length)")
    R, S = rods.shape[0], tendons.shape[0]
    if (tendon_rest_length is None) == (tendon_prestrain is None):
        raise ValueError("tendon_rest_length, tendon_prestrain: give exactly one of them")
    string_length = np.linalg.norm(position[tendons[:, 1]] - position[tendons[:, 0]], axis=1)
    rest = (rest_from_prestrain(string_length, tendon_prestrain) if tendon_rest_length is None
            else _per_member(tendon_rest_length, S, "tendon_rest_length"))
    velocity = None
    if node_velocity is not None:
        velocity = np.asarray(node_velocity, dtype=float)
        if velocity.shape != N.shape:
            raise ValueError(f"node_velocity: expected shape {N.shape} like N, got {velocity.shape}")
        velocity = velocity.T
    fixed = np.zeros(n_nodes, bool) if node_fixed is None else np.asarray(node_fixed)
    if fixed.shape != (n_nodes,) or fixed.dtype != bool:
        raise ValueError(f"node_fixed: expected {n_nodes} booleans, got {fixed.dtype} of shape {fixed.shape}")
    mass = _per_member(0.0 if node_point_mass is None else node_point_mass, n_nodes, "node_point_mass")
    bad = np.flatnonzero(~np.isfinite(mass) | (mass < 0))
    if bad.size:
        raise ValueError(f"node_point_mass[{bad[0]}]: must be finite and >= 0, got {mass[bad[0]]}")
    count = np.bincount(rods.ravel(), minlength=n_nodes)
    if not ball_joints:
        check_class1(rods, n_nodes)
    free = np.flatnonzero((count == 0) & ~fixed & (mass == 0))
    if free.size:
        raise ValueError(f"nodes[{free[0]}]: belongs to no bar; fix it (node_fixed) or give it a mass "
                         "(node_point_mass): a massless free node has no dynamics")
    anchor = ((count == 0) & fixed).astype(np.int64)
    has_mass = (mass > 0).astype(np.int64)
    parts = anchor + count + has_mass
    if not ball_joints:
        both = np.flatnonzero(parts > 1)
        if both.size:
            i = both[0]
            where = (f"an end of bars {np.flatnonzero(np.any(rods == i, axis=1)).tolist()}"
                     if count[i] else "fixed")
            raise ValueError(f"node_point_mass[{i}]: node {i} is {where}; a point mass there needs "
                             "ball_joints=True (it becomes its own node, joined to that one)")
    start = np.cumsum(parts) - parts  # the first node of each node of N
    split_fixed = np.zeros(int(parts.sum()), bool)
    split_fixed[start[fixed]] = True
    split_mass = np.zeros(split_fixed.size)
    split_mass[(start + anchor + count)[mass > 0]] = mass[mass > 0]
    return Structure(
        node_position=np.repeat(position, parts, axis=0),
        node_velocity=None if velocity is None else np.repeat(velocity, parts, axis=0),
        rod_nodes=_split_rod_ends(rods, start + anchor),
        tendon_nodes=start[tendons],
        node_fixed=split_fixed,
        node_point_mass=split_mass,
        joint_nodes=np.vstack([_star_joints(start, parts), start[_node_pairs(joint_nodes, n_nodes)]]),
        plane_nodes=start[_node_list(plane_nodes, "plane_nodes", n_nodes)],
        plane_normal=plane_normal,
        line_nodes=start[_node_list(line_nodes, "line_nodes", n_nodes)],
        line_direction=line_direction,
        rod_mass=_per_member(rod_mass, R, "rod_mass"),
        rod_length=length if rod_length is None else _per_member(rod_length, R, "rod_length"),
        rod_damping=_per_member(rod_damping, R, "rod_damping"),
        tendon_stiffness=_per_member(tendon_stiffness, S, "tendon_stiffness"),
        tendon_rest_length=rest,
        tendon_damping=_per_member(tendon_damping, S, "tendon_damping"),
        tendon_name=None if tendon_name is None else tuple(tendon_name),
    )


def _node_pairs(value: Any, n_nodes: int) -> np.ndarray:
    """``joint_nodes`` of :func:`from_connectivity` as a (J, 2) array of node indices."""
    pairs = np.asarray(np.zeros((0, 2)) if value is None else value)
    if pairs.ndim != 2 or pairs.shape[1] != 2:
        raise ValueError(f"joint_nodes: expected shape (J, 2) of node indices, got {pairs.shape}")
    return _node_list(pairs.ravel(), "joint_nodes", n_nodes).reshape(-1, 2)


def _split_rod_ends(rods: np.ndarray, first_end: np.ndarray) -> np.ndarray:
    """Rod-end nodes (R, 2) after a split: the ends at node ``i`` are nodes ``first_end[i]``,
    ``first_end[i] + 1``, ... in bar order (a bar's tail before its head)."""
    ends = rods.ravel()  # bar 0 tail, bar 0 head, bar 1 tail, ...
    order = np.argsort(ends, kind="stable")
    rank = np.empty_like(ends)
    rank[order] = np.arange(ends.size) - np.searchsorted(ends[order], ends[order])
    return (first_end[ends] + rank).reshape(-1, 2)


def _star_joints(start: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """Joint pairs (J, 2) from the first node ``start[i]`` of each group of ``parts[i]``
    consecutive nodes to each of the others."""
    extra = parts - 1
    lead = np.repeat(start, extra)
    return np.column_stack([lead, lead + 1 + np.arange(lead.size) - np.repeat(np.cumsum(extra) - extra, extra)])


def incidence(pairs: np.ndarray, n_nodes: int) -> np.ndarray:
    """Dense connectivity matrix (k, n_nodes) of ``(tail, head)`` pairs: -1 at tail, +1 at head."""
    C = np.zeros((pairs.shape[0], n_nodes), dtype=np.int64)
    rows = np.arange(pairs.shape[0])
    C[rows, pairs[:, 0]] = -1
    C[rows, pairs[:, 1]] = 1
    return C


class MergedNodes(NamedTuple):
    """A structure's nodes with each group of joined nodes merged into one (:func:`merge_joints`).

    ``node_map`` (N,) is the merged node of each of the structure's nodes; the other fields are
    the keyword arguments of :func:`from_connectivity` for the merged nodes (``N`` and
    ``node_velocity`` (d, n), ``node_fixed`` (n,), ``node_point_mass`` (n,) [kg], the plane and
    line constraints on merged nodes).
    """

    node_map: np.ndarray
    N: np.ndarray
    node_velocity: np.ndarray
    node_fixed: np.ndarray
    node_point_mass: np.ndarray
    plane_nodes: np.ndarray
    plane_normal: np.ndarray
    line_nodes: np.ndarray
    line_direction: np.ndarray
    joint_nodes: np.ndarray


def merge_joints(structure: Structure, *, keep_joints: bool = False) -> MergedNodes:
    """Merge every group of nodes joined by ball joints (``joint_nodes``) into one node.

    Merged nodes are numbered in the order of each group's lowest node and take that node's
    position and velocity; a group is fixed if any of its nodes is, its point mass is the sum of
    theirs.  The inverse of the split of :func:`from_connectivity` with ``ball_joints=True``.
    With ``keep_joints`` nothing is merged (``node_map`` is the identity) and the joints stay
    in ``joint_nodes``, as :func:`from_connectivity` takes them: the structure's own layout.

    Raises
    ------
    ValueError
        ``tendons[k] ('name')`` for a tendon between two joined nodes (a string of zero length)
        or between the same two merged nodes as another tendon: ``C_s`` cannot keep them apart.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = structure.n_nodes
    joints = structure.joint_nodes
    graph = coo_matrix((np.ones(joints.shape[0]), (joints[:, 0], joints[:, 1])), shape=(n, n))
    label = np.arange(n) if keep_joints else connected_components(graph, directed=False)[1]
    lowest = np.full(label.max() + 1, n)
    np.minimum.at(lowest, label, np.arange(n))
    order = np.argsort(lowest)
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    node_map = rank[label]
    lead = lowest[order]
    tendons = node_map[structure.tendon_nodes]
    names = structure.tendon_name
    seen: dict[tuple[int, int], int] = {}
    for k, (a, b) in enumerate(tendons):
        tail, head = structure.tendon_nodes[k]
        if a == b:
            raise ValueError(f"tendons[{k}] ({names[k]!r}): joins nodes {tail} and {head}, which are "
                             "joined by a ball joint; C_s cannot hold a string of zero length")
        key = (min(a, b), max(a, b))
        if key in seen:
            raise ValueError(f"tendons[{k}] ({names[k]!r}): joins the same joined nodes as "
                             f"tendons[{seen[key]}] ({names[seen[key]]!r}); C_s cannot keep them apart")
        seen[key] = k
    fixed = np.zeros(lead.size, bool)
    np.logical_or.at(fixed, node_map, structure.node_fixed)
    return MergedNodes(
        node_map=node_map,
        N=structure.node_position[lead].T.copy(),
        node_velocity=structure.node_velocity[lead].T.copy(),
        node_fixed=fixed,
        node_point_mass=np.bincount(node_map, weights=structure.node_point_mass, minlength=lead.size),
        plane_nodes=node_map[structure.plane_nodes],
        plane_normal=structure.plane_normal.copy(),
        line_nodes=node_map[structure.line_nodes],
        line_direction=structure.line_direction.copy(),
        joint_nodes=(joints if keep_joints else np.zeros((0, 2), np.int64)).copy(),
    )


def to_connectivity(structure: Structure) -> Connectivity:
    """``N`` (d, n) [m], ``C_b`` (R, n) and ``C_s`` (S, n) of ``structure`` (dense integers).

    Each group of joined nodes (``joint_nodes``) is one node, shared by its bars (the class k
    convention; :func:`merge_joints` gives the order), so ``from_connectivity(N, C_b, C_s,
    ball_joints=True)`` gives back a structure with the same ``N, C_b, C_s``.  Supports, point
    masses and plane/line constraints are in :func:`merge_joints`.
    """
    return _connectivity(structure, merge_joints(structure))


def _connectivity(structure: Structure, merged: MergedNodes) -> Connectivity:
    n = merged.N.shape[1]
    return Connectivity(
        merged.N,
        incidence(merged.node_map[structure.rod_nodes], n),
        incidence(merged.node_map[structure.tendon_nodes], n),
    )


# -------------------------------------------------------------------- readable form
#: Optional support keys of the readable form (as in :meth:`Structure.to_dict`): key -> the
#: value each ``{node, ...}`` item carries (``None``: a plain list of nodes, or of node pairs).
_SUPPORT_KEYS = {"fixed": None, "point_masses": "mass", "planes": "normal", "lines": "direction",
                 "joints": None}


def network_to_dict(structure: Structure, *, keep_joints: bool = False) -> dict[str, Any]:
    """The readable form (for YAML and TOML): named nodes, shared parameters under ``defaults``.

    ``{"format": "tensegrity-network", "version": 1, "nodes": {"n0": [x, y, z], ...},
    "velocities": {...} (only if any is nonzero), "fixed": ["n4", ...], "point_masses":
    [{"node", "mass"}], "planes": [{"node", "normal"}], "lines": [{"node", "direction"}]
    (these four only when present, as in :meth:`Structure.to_dict`), "defaults": {"rod": {...},
    "tendon": {...}}, "rods": [{"nodes": ["n0", "n1"], ...}], "tendons": [{"name", "nodes",
    ...}]}``.  Joined nodes are one node shared by their rods (the class k convention,
    :func:`merge_joints`), or with ``keep_joints`` the structure's own nodes and ``"joints":
    [["n1", "n2"], ...]``; a planar structure has ``[x, y]`` nodes.  A parameter shared by every
    rod (tendon) is written once under ``defaults``, the others per member.  Floats keep their
    shortest round-trip form, so reading it back is exact.
    """
    merged = merge_joints(structure, keep_joints=keep_joints)
    names = [f"n{i}" for i in range(merged.N.shape[1])]
    data: dict[str, Any] = {
        "format": NETWORK_FORMAT,
        "version": NETWORK_VERSION,
        "units": "SI: m, kg, s, N",
        "nodes": {name: p.tolist() for name, p in zip(names, merged.N.T)},
    }
    if np.any(merged.node_velocity != 0):
        data["velocities"] = {name: v.tolist() for name, v in zip(names, merged.node_velocity.T)}
    if merged.node_fixed.any():
        data["fixed"] = [names[i] for i in np.flatnonzero(merged.node_fixed)]
    for key, nodes, values in (
        ("point_masses", np.flatnonzero(merged.node_point_mass), merged.node_point_mass[merged.node_point_mass > 0]),
        ("planes", merged.plane_nodes, merged.plane_normal),
        ("lines", merged.line_nodes, merged.line_direction),
    ):
        if nodes.size:
            data[key] = [{"node": names[i], _SUPPORT_KEYS[key]: v.tolist()} for i, v in zip(nodes, values)]
    if merged.joint_nodes.size:
        data["joints"] = [[names[a], names[b]] for a, b in merged.joint_nodes]
    rods, tendons = merged.node_map[structure.rod_nodes], merged.node_map[structure.tendon_nodes]
    defaults: dict[str, dict[str, float]] = {"rod": {}, "tendon": {}}
    members = {"rod": [{"nodes": [names[a], names[b]]} for a, b in rods],
               "tendon": [{"name": name, "nodes": [names[a], names[b]]}
                          for name, (a, b) in zip(structure.tendon_name, tendons)]}
    columns = {
        "rod": {"mass": structure.rod_mass, "length": structure.rod_length,
                "damping": structure.rod_damping},
        "tendon": {"stiffness": structure.tendon_stiffness,
                   "rest_length": structure.tendon_rest_length,
                   "damping": structure.tendon_damping},
    }
    for kind, table in columns.items():
        for key, values in table.items():
            if values.size and np.all(values == values[0]):
                defaults[kind][key] = float(values[0])
            else:
                for item, value in zip(members[kind], values):
                    item[key] = float(value)
    data["defaults"] = {kind: table for kind, table in defaults.items() if table}
    data["rods"] = members["rod"]
    data["tendons"] = members["tendon"]
    return data


def network_from_dict(data: Any) -> Structure:
    """Build a structure from the readable form of :func:`network_to_dict`.

    ``nodes`` is a mapping name -> ``[x, y, z]`` (members refer to nodes by name) or a list
    (members refer to 0-based indices); ``[x, y]`` nodes make a planar structure.  A node shared
    by rods is a ball joint (class k: :func:`from_connectivity` with ``ball_joints=True``).
    Per member, a key missing falls back to ``defaults``, then to the library default (rod
    ``mass`` 1 kg, ``length`` the distance of its nodes, ``damping`` 0; tendon ``stiffness``
    100 N/m, ``damping`` 0); a tendon needs ``rest_length`` [m] or ``prestrain``
    ``(l - L0) / L0``.  Optional ``fixed`` (nodes), ``point_masses`` (``{node, mass}``),
    ``planes`` (``{node, normal}``), ``lines`` (``{node, direction}``).  Unknown keys are
    errors (a typo is not ignored).

    Raises
    ------
    ValueError
        Naming the key: ``tendons[3] ('s3').nodes: no node named 'x7'``,
        ``rods[0]: unknown key 'mas' (expected one of nodes, mass, length, damping)``, ...
    """
    if not isinstance(data, Mapping):
        raise ValueError(f"network: expected a mapping at the top level, got {type(data).__name__}")
    _only(data, ("format", "version", "units", "nodes", "velocities", *_SUPPORT_KEYS, "defaults",
                 "rods", "tendons"), "network")
    if data.get("format", NETWORK_FORMAT) != NETWORK_FORMAT:
        raise ValueError(f"format: expected {NETWORK_FORMAT!r}, got {data['format']!r:.80}")
    version = data.get("version", NETWORK_VERSION)
    if not isinstance(version, int) or isinstance(version, bool) or version > NETWORK_VERSION:
        raise ValueError(f"version: this library reads version <= {NETWORK_VERSION}, got {version!r:.80}")
    if "nodes" not in data:
        raise ValueError("network: missing key 'nodes'")
    names, position, dim = _named_points(data["nodes"], "nodes")
    for key in ("rods", "tendons"):
        if key not in data:
            raise ValueError(f"network: missing key {key!r}")
    velocity = None
    if data.get("velocities") is not None:
        v_names, v, _ = _named_points(data["velocities"], "velocities", dim)
        if v_names != names:
            raise ValueError("velocities: must list the same nodes as nodes, in the same order")
        velocity = np.array(v, dtype=float).reshape(-1, dim)
    defaults = data.get("defaults") or {}
    if not isinstance(defaults, Mapping):
        raise ValueError(f"defaults: expected a mapping, got {type(defaults).__name__}")
    _only(defaults, ("rod", "tendon"), "defaults")
    rod_default = _defaults(defaults.get("rod"), _ROD_KEYS, "defaults.rod")
    tendon_default = _defaults(defaults.get("tendon"), _TENDON_KEYS, "defaults.tendon")
    index = {name: i for i, name in enumerate(names)}
    rods = _members(data["rods"], "rods", ("nodes", *_ROD_KEYS), index)
    tendons = _members(data["tendons"], "tendons", ("name", "nodes", *_TENDON_KEYS), index)
    rod_nodes = np.array([pair for pair, _ in rods], dtype=np.int64).reshape(-1, 2)
    tendon_nodes = np.array([pair for pair, _ in tendons], dtype=np.int64).reshape(-1, 2)
    p = np.array(position, dtype=float).reshape(-1, dim)
    rod_distance = np.linalg.norm(p[rod_nodes[:, 1]] - p[rod_nodes[:, 0]], axis=1)
    tendon_distance = np.linalg.norm(p[tendon_nodes[:, 1]] - p[tendon_nodes[:, 0]], axis=1)

    def column(items, kind, key, default, fallback):
        out = []
        for k, (_, item) in enumerate(items):
            value = item.get(key, default.get(key))
            out.append(fallback[k] if value is None else _number(value, f"{kind}[{k}].{key}"))
        return np.array(out, dtype=float)

    rest = []
    for k, (_, item) in enumerate(tendons):
        where = f"tendons[{k}]"
        given = {key: item[key] for key in ("rest_length", "prestrain") if key in item}
        if not given:
            given = {key: tendon_default[key] for key in ("rest_length", "prestrain")
                     if key in tendon_default}
        if len(given) != 1:
            raise ValueError(f"{where}: needs exactly one of rest_length [m] or prestrain "
                             f"(here or under defaults.tendon), got {sorted(given) or 'neither'}")
        (key, value), = given.items()
        value = _number(value, f"{where}.{key}")
        rest.append(value if key == "rest_length"
                    else float(rest_from_prestrain(tendon_distance[k:k + 1], value, f"{where}.prestrain")[0]))
    zero = np.flatnonzero(rod_distance == 0)
    if zero.size:
        k = zero[0]
        raise ValueError(f"rods[{k}].nodes: {names[rod_nodes[k, 0]]!r} and {names[rod_nodes[k, 1]]!r} "
                         "coincide (zero length)")
    zeros = np.zeros(len(rods)), np.zeros(len(tendons))
    n = len(names)
    return from_connectivity(
        p.T, incidence(rod_nodes, n), incidence(tendon_nodes, n), ball_joints=True,
        node_velocity=None if velocity is None else velocity.T, **_supports(data, index, dim),
        rod_mass=column(rods, "rods", "mass", rod_default, np.full(len(rods), DEFAULT_ROD_MASS)),
        rod_length=column(rods, "rods", "length", rod_default, rod_distance),
        rod_damping=column(rods, "rods", "damping", rod_default, zeros[0]),
        tendon_stiffness=column(tendons, "tendons", "stiffness", tendon_default,
                                np.full(len(tendons), DEFAULT_STIFFNESS)),
        tendon_rest_length=np.array(rest, dtype=float),
        tendon_damping=column(tendons, "tendons", "damping", tendon_default, zeros[1]),
        tendon_name=tuple(item.get("name", f"s{k}") for k, (_, item) in enumerate(tendons)),
    )


def _supports(data: Mapping[str, Any], index: Mapping[Any, int], dim: int) -> dict[str, Any]:
    """The optional ``fixed``, ``point_masses``, ``planes``, ``lines`` keys of the readable form
    as keyword arguments of :func:`from_connectivity` (on the file's nodes)."""
    out: dict[str, Any] = {}
    if data.get("fixed") is not None:
        nodes = data["fixed"]
        if not isinstance(nodes, Sequence) or isinstance(nodes, str):
            raise ValueError(f"fixed: expected a list of nodes, got {type(nodes).__name__}")
        fixed = np.zeros(len(index), bool)
        fixed[[_node_ref(end, f"fixed[{k}]", index) for k, end in enumerate(nodes)]] = True
        out["node_fixed"] = fixed
    if data.get("joints") is not None:
        pairs = data["joints"]
        if not isinstance(pairs, Sequence) or isinstance(pairs, str):
            raise ValueError(f"joints: expected a list of node pairs, got {type(pairs).__name__}")
        out["joint_nodes"] = np.array(
            [[_node_ref(end, f"joints[{k}]", index) for end in _pair(pair, f"joints[{k}]")]
             for k, pair in enumerate(pairs)], dtype=np.int64).reshape(-1, 2)
    for key, (nodes_field, value_field) in (("point_masses", ("node_point_mass", None)),
                                            ("planes", ("plane_nodes", "plane_normal")),
                                            ("lines", ("line_nodes", "line_direction"))):
        items = data.get(key)
        if items is None:
            continue
        if not isinstance(items, Sequence) or isinstance(items, str):
            raise ValueError(f"{key}: expected a list, got {type(items).__name__}")
        name = _SUPPORT_KEYS[key]
        nodes, values = [], []
        for k, item in enumerate(items):
            if not isinstance(item, Mapping):
                raise ValueError(f"{key}[{k}]: expected a mapping, got {type(item).__name__}")
            _only(item, ("node", name), f"{key}[{k}]")
            for field in ("node", name):
                if field not in item:
                    raise ValueError(f"{key}[{k}]: missing key {field!r}")
            nodes.append(_node_ref(item["node"], f"{key}[{k}].node", index))
            values.append(_number(item[name], f"{key}[{k}].{name}") if value_field is None
                          else _vector(item[name], f"{key}[{k}].{name}", 3 if key == "planes" else dim))
        if value_field is None:
            mass = np.zeros(len(index))
            mass[nodes] = values
            out[nodes_field] = mass
        else:
            out[nodes_field] = np.array(nodes, dtype=np.int64)
            out[value_field] = np.array(values, dtype=float).reshape(-1, 3 if key == "planes" else dim)
    return out


def _only(data: Mapping[str, Any], allowed: Sequence[str], where: str) -> None:
    for key in data:
        if key not in allowed:
            raise ValueError(f"{where}: unknown key {key!r} (expected one of {', '.join(allowed)})")


def _named_points(value: Any, where: str, dim: int | None = None) -> tuple[list[Any], list[list[float]], int]:
    """Names, vectors and their dimension of a mapping name -> [x, y, z] (or [x, y]: planar),
    or of a list (names 0, 1, ...); ``dim`` ``None``: that of the first vector."""
    if isinstance(value, Mapping):
        names = list(value)
        for name in names:
            if isinstance(name, bool) or not isinstance(name, (str, int)) or name == "":
                raise ValueError(f"{where}: node names must be non-empty strings (or integers), "
                                 f"got {name!r:.80}")
        rows, labels = [value[name] for name in names], [f"{where}.{name}" for name in names]
    elif isinstance(value, Sequence) and not isinstance(value, str):
        names = list(range(len(value)))
        rows, labels = list(value), [f"{where}[{k}]" for k in names]
    else:
        raise ValueError(f"{where}: expected a mapping name -> [x, y, z] or a list, got {type(value).__name__}")
    if dim is None:
        dim = _dimension(rows)
    return names, [_vector(row, label, dim) for row, label in zip(rows, labels)], dim


def _defaults(value: Any, keys: Sequence[str], where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected a mapping, got {type(value).__name__}")
    _only(value, keys, where)
    return {key: _number(x, f"{where}.{key}") for key, x in value.items()}


def _members(value: Any, kind: str, keys: Sequence[str], index: Mapping[Any, int]) -> list:
    """``[((tail, head), item), ...]`` with node references resolved through ``index``."""
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise ValueError(f"{kind}: expected a list, got {type(value).__name__}")
    out = []
    for k, item in enumerate(value):
        if not isinstance(item, Mapping):
            raise ValueError(f"{kind}[{k}]: expected a mapping, got {type(item).__name__}")
        label = f"{kind}[{k}]" + (f" ({item['name']!r})" if "name" in item else "")
        _only(item, keys, label)
        if "nodes" not in item:
            raise ValueError(f"{label}: missing key 'nodes'")
        ends = _pair(item["nodes"], f"{label}.nodes")
        pair = [_node_ref(end, f"{label}.nodes", index) for end in ends]
        if pair[0] == pair[1]:
            raise ValueError(f"{label}.nodes: joins node {ends[0]!r} to itself")
        out.append((tuple(pair), item))
    return out


def _pair(ends: Any, where: str) -> Sequence[Any]:
    """A list of two node references of the readable form."""
    if not isinstance(ends, Sequence) or isinstance(ends, str) or len(ends) != 2:
        raise ValueError(f"{where}: expected two node references, got {ends!r:.80}")
    return ends


def _node_ref(end: Any, where: str, index: Mapping[Any, int]) -> int:
    """The node index of a node name (or 0-based index) of the readable form."""
    if isinstance(end, bool) or not isinstance(end, (str, int)) or end not in index:
        raise ValueError(f"{where}: no node {'named ' if isinstance(end, str) else ''}{end!r:.80}")
    return index[end]


# ------------------------------------------------------------------------------- files
def _format(path: PathLike, format: str | None) -> str:
    if format is not None:
        if format not in set(FORMATS.values()):
            raise ValueError(f"format: expected one of {', '.join(sorted(set(FORMATS.values())))}, "
                             f"got {format!r}")
        return format
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise _file_error(path, f"unknown structure file suffix {suffix!r} (expected one of "
                                f"{', '.join(FORMATS)})")
    return FORMATS[suffix]


def read_network(path: PathLike, *, format: str | None = None) -> Structure:
    """Read a structure file in any format (by suffix, or ``format``): see the module docstring.

    Raises
    ------
    ValueError
        One line starting with the file name, naming the problem and the element.
    """
    kind = _format(path, format)
    if kind == "json":
        return read_structure(path)
    if kind == "mjcf":
        raise _file_error(path, "MJCF files are written for MuJoCo, not read back")
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        raise _file_error(path, _os_problem(exc)) from exc
    try:
        if kind == "connectivity":
            return _from_npz(raw)
        data = _parse_text(raw, kind)
        return network_from_dict(data)
    except ValueError as exc:
        raise _file_error(path, str(exc)) from exc
    except (TypeError, KeyError, OverflowError) as exc:
        raise _file_error(path, str(exc) or type(exc).__name__) from exc


def _parse_text(raw: bytes, kind: str) -> Any:
    import yaml

    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 text (byte {exc.start})") from exc
    if kind == "toml":
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"invalid TOML: {exc}") from exc
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise ValueError(f"invalid YAML{where}: {getattr(exc, 'problem', None) or exc}") from exc


def _from_npz(raw: bytes) -> Structure:
    try:
        archive = np.load(_io.BytesIO(raw), allow_pickle=False)
    except Exception as exc:  # numpy raises several types for a file that is not an archive
        raise ValueError(f"not a NumPy .npz archive ({type(exc).__name__})") from exc
    with archive:
        unknown = sorted(set(archive.files) - set(NPZ_ARRAYS))
        if unknown:
            raise ValueError(f"unknown array {unknown[0]!r} (expected some of {', '.join(NPZ_ARRAYS)})")
        arrays = {name: archive[name] for name in archive.files}
    for name, (required, _) in NPZ_ARRAYS.items():
        if required and name not in arrays:
            raise ValueError(f"missing array {name!r}")
    names = arrays.pop("tendon_name", None)
    N, C_b, C_s = arrays.pop("N"), arrays.pop("C_b"), arrays.pop("C_s")
    return from_connectivity(N, C_b, C_s, tendon_name=None if names is None else
                             tuple(str(x) for x in names), ball_joints=True, **arrays)


def write_network(path: PathLike, structure: Structure, *, format: str | None = None,
                  keep_joints: bool = False) -> Path:
    """Write ``structure`` in any format (by suffix, or ``format``), atomically.

    ``json``: :meth:`Structure.to_dict`; ``yaml``/``toml``: :func:`network_to_dict`;
    ``connectivity``: ``.npz`` of :data:`NPZ_ARRAYS`; ``mjcf``: :func:`tensegrity.mjcf.to_mjcf`.
    The readable and connectivity forms merge joined nodes (class k), or with ``keep_joints``
    keep every rod's end nodes and list the joints.  JSON, and every form with ``keep_joints``
    or for a structure without joints, reads back to an identical structure; a jointed
    structure written merged reads back with the same ``N, C_b, C_s``, supports and parameters
    in the layout of :func:`from_connectivity` (see ``docs/networks.md``).
    """
    kind = _format(path, format)
    if kind == "json":
        return write_structure(path, structure)
    if kind == "mjcf":
        from tensegrity.mjcf import write_mjcf

        return write_mjcf(path, structure)
    with atomic_path(path) as tmp:
        if kind == "connectivity":
            with open(tmp, "wb") as f:
                np.savez(f, **_npz_arrays(structure, keep_joints))
        else:
            tmp.write_text(_dump_text(structure, kind, keep_joints), encoding="utf-8")
    return Path(path)


def _npz_arrays(structure: Structure, keep_joints: bool) -> dict[str, np.ndarray]:
    merged = merge_joints(structure, keep_joints=keep_joints)
    N, C_b, C_s = _connectivity(structure, merged)
    supports = {"node_fixed": merged.node_fixed.any(), "node_point_mass": merged.node_point_mass.any(),
                "plane_nodes": merged.plane_nodes.size, "plane_normal": merged.plane_nodes.size,
                "line_nodes": merged.line_nodes.size, "line_direction": merged.line_nodes.size,
                "joint_nodes": merged.joint_nodes.size}
    return {
        "N": N, "C_b": C_b, "C_s": C_s, "node_velocity": merged.node_velocity,
        "rod_mass": structure.rod_mass, "rod_length": structure.rod_length,
        "rod_damping": structure.rod_damping, "tendon_stiffness": structure.tendon_stiffness,
        "tendon_rest_length": structure.tendon_rest_length,
        "tendon_damping": structure.tendon_damping,
        "tendon_name": np.array(structure.tendon_name, dtype=str),
    } | {name: getattr(merged, name) for name, present in supports.items() if present}


def _dump_text(structure: Structure, kind: str, keep_joints: bool) -> str:
    data = network_to_dict(structure, keep_joints=keep_joints)
    joined = (f" (the structure's {structure.n_nodes}, joined nodes merged: a node of k rods is a "
              "ball joint)" if structure.joint_nodes.size and not keep_joints else "")
    header = (f"# {len(data['nodes'])} nodes{joined}, {structure.n_rods} rods (bars), "
              f"{structure.n_tendons} tendons (strings); SI units\n")
    if kind == "toml":
        return header + dump_toml(data)
    import yaml

    class _Dumper(yaml.SafeDumper):
        pass

    def short_lists(dumper, value):  # [x, y, z] and [tail, head] on one line
        flow = all(not isinstance(x, (list, dict)) for x in value)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", value, flow_style=flow)

    def members(dumper, value):  # one line per rod / tendon
        flow = isinstance(value.get("nodes"), list)
        return dumper.represent_mapping("tag:yaml.org,2002:map", value.items(), flow_style=flow)

    _Dumper.add_representer(list, short_lists)
    _Dumper.add_representer(dict, members)
    return header + yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=120)


def dump_toml(data: Mapping[str, Any]) -> str:
    """TOML text of a two-level mapping of numbers, strings, lists and mappings (no dates).

    A small writer for the readable form, one line per node and per member: the top-level
    values that are not mappings come first (lists of mappings one item per line, as inline
    tables), then each mapping as a ``[table]`` (a mapping of mappings as ``[table.sub]``).
    Floats are written with ``repr`` (shortest round trip), strings and non-bare keys as JSON
    strings (a subset of TOML's basic strings).  ``tomllib.loads`` reads it back equal.
    """
    lines, tables = [], []
    for key, value in data.items():
        if isinstance(value, Mapping):
            tables.append((_toml_key(key), value))
        elif isinstance(value, list) and value and all(isinstance(x, Mapping) for x in value):
            lines += [f"{_toml_key(key)} = ["] + [f"    {_toml_value(x)}," for x in value] + ["]"]
        else:
            lines.append(f"{_toml_key(key)} = {_toml_value(value)}")
    while tables:
        name, table = tables.pop(0)
        plain = {k: v for k, v in table.items() if not isinstance(v, Mapping)}
        nested = [(f"{name}.{_toml_key(k)}", v) for k, v in table.items() if isinstance(v, Mapping)]
        if plain or not nested:
            lines += ["", f"[{name}]"] + [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in plain.items()]
        tables[:0] = nested
    return "\n".join(lines) + "\n"


def _toml_key(key: Any) -> str:
    key = str(key)
    return key if key and all(c.isascii() and (c.isalnum() or c in "_-") for c in key) else json.dumps(key)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ValueError(f"TOML: cannot write the non-finite number {value!r}")
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, Mapping):
        return "{" + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in value) + "]"
    raise ValueError(f"TOML: cannot write a {type(value).__name__}")
