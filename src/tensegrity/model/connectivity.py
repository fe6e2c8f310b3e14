"""Any network in the field's convention (Skelton & de Oliveira): node matrix ``N`` (3 x n),
bar and string connectivity ``C_b``, ``C_s`` (one row per member, -1 at the tail and +1 at the
head); :func:`from_connectivity` builds a :class:`~tensegrity.model.structure.Structure` from them
(class 1, or class k with joined nodes split into rod ends and ball joints), and
:func:`to_connectivity` goes back (joined rod ends merged into one node).  Files of this form:
:mod:`tensegrity.io.formats`."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np

from tensegrity.model.structure import Structure

#: Defaults of :func:`from_connectivity` [kg], [N/m].
DEFAULT_ROD_MASS = 1.0
DEFAULT_STIFFNESS = 100.0


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
        raise ValueError(
            f"{field}: has {C.shape[1]} columns but N has {n_nodes} nodes "
            "(a member on a missing node?)"
        )
    tails, heads = C == -1, C == 1
    bad = np.flatnonzero(
        (tails.sum(1) != 1) | (heads.sum(1) != 1) | np.any((C != 0) & ~tails & ~heads, axis=1)
    )
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


def rest_from_prestrain(
    length: np.ndarray, prestrain: Any, field: str = "tendon_prestrain"
) -> np.ndarray:
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
        raise ValueError(
            f"{field}[{bad[0]}]: node index {array[bad[0]]} out of range [0, {n_nodes - 1}]"
        )
    return array


def from_connectivity(
    N: Any,
    C_b: Any,
    C_s: Any,
    *,
    rod_mass: Any = DEFAULT_ROD_MASS,
    rod_length: Any = None,
    rod_damping: Any = 0.0,
    rod_relative_damping: Any = 0.0,
    tendon_stiffness: Any = DEFAULT_STIFFNESS,
    tendon_rest_length: Any = None,
    tendon_prestrain: Any = None,
    tendon_damping: Any = 0.0,
    tendon_name: Sequence[str] | None = None,
    node_name: Sequence[str] | None = None,
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
    rod_mass, rod_damping, rod_relative_damping : float or (R,)
        Bar masses [kg] (default 1) and mass-proportional damping rates [1/s] (default 0), to
        ground and relative to the rigid-body motion (:class:`Structure`).
    rod_length : float or (R,), optional
        Bar lengths [m]; default the lengths of ``N C_b^T`` (given, they must agree with ``N``).
    tendon_stiffness, tendon_damping : float or (S,)
        [N/m] (default 100) and [N s/m] (default 0).
    tendon_rest_length, tendon_prestrain : float or (S,)
        Exactly one: the rest lengths ``L0`` [m], or the strains ``eps = (l - L0) / L0`` in the
        configuration ``N`` (``eps > 0``: taut).
    tendon_name : sequence of str, optional
        Default ``"s0", "s1", ...``.
    node_name : sequence of str, shape (n,), optional
        Names of the nodes of ``N``; a node split into ``k`` nodes (``ball_joints``) gives its
        name to the first and ``"<name>.1"``, ..., ``"<name>.<k-1>"`` to the others.  Default
        the structure's default names ``"n0", "n1", ...`` (of the split nodes).
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
    network = _network(N, C_b, C_s)
    rest = _tendon_rest_lengths(network, tendon_rest_length, tendon_prestrain)
    velocity = _node_velocities(network, node_velocity)
    split = _split_nodes(network, node_fixed, node_point_mass, ball_joints=ball_joints)
    return Structure(
        node_name=_split_names(node_name, split),
        **_node_fields(
            network,
            split,
            velocity,
            joint_nodes=joint_nodes,
            plane_nodes=plane_nodes,
            plane_normal=plane_normal,
            line_nodes=line_nodes,
            line_direction=line_direction,
        ),
        **_member_fields(
            network,
            rest,
            rod_mass=rod_mass,
            rod_length=rod_length,
            rod_damping=rod_damping,
            rod_relative_damping=rod_relative_damping,
            tendon_stiffness=tendon_stiffness,
            tendon_damping=tendon_damping,
            tendon_name=tendon_name,
        ),
    )


class _Network(NamedTuple):
    """A network as read from ``N``, ``C_b``, ``C_s``."""

    position: np.ndarray  #: (n, d) node positions [m]: ``N.T``
    rods: np.ndarray  #: (R, 2) bars' (tail, head) nodes
    tendons: np.ndarray  #: (S, 2) strings' (tail, head) nodes
    length: np.ndarray  #: (R,) bar lengths [m] in ``N``


def _network(N: Any, C_b: Any, C_s: Any) -> _Network:
    """The nodes and members of :func:`from_connectivity`'s ``N`` (d, n), ``C_b`` (R, n) and
    ``C_s`` (S, n), checked (finite positions, one tail and one head per member, no bar of
    zero length)."""
    N = np.asarray(N, dtype=float)
    if N.ndim != 2 or N.shape[0] not in (2, 3):
        rows = N.ndim == 2 and N.shape[1] in (2, 3)
        hint = " (one column per node: pass N.T for positions in rows)" if rows else ""
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
        raise ValueError(
            f"C_b[{k}]: bar joins nodes {rods[k, 0]} and {rods[k, 1]}, which coincide (zero length)"
        )
    return _Network(position, rods, tendons, length)


def _tendon_rest_lengths(network: _Network, rest_length: Any, prestrain: Any) -> np.ndarray:
    """Rest lengths (S,) [m]: ``rest_length`` (a number or S), or from the ``prestrain`` of the
    strings in ``N`` (exactly one of them given)."""
    if (rest_length is None) == (prestrain is None):
        raise ValueError("tendon_rest_length, tendon_prestrain: give exactly one of them")
    position, tendons = network.position, network.tendons
    string_length = np.linalg.norm(position[tendons[:, 1]] - position[tendons[:, 0]], axis=1)
    return (
        rest_from_prestrain(string_length, prestrain)
        if rest_length is None
        else _per_member(rest_length, tendons.shape[0], "tendon_rest_length")
    )


def _node_velocities(network: _Network, node_velocity: Any) -> np.ndarray | None:
    """``node_velocity`` (d, n) [m/s], one column per node like ``N``, as rows (n, d)."""
    if node_velocity is None:
        return None
    velocity = np.asarray(node_velocity, dtype=float)
    shape = network.position.T.shape
    if velocity.shape != shape:
        raise ValueError(f"node_velocity: expected shape {shape} like N, got {velocity.shape}")
    return velocity.T


class _SplitNodes(NamedTuple):
    """How each node ``i`` of ``N`` becomes ``parts[i]`` consecutive nodes of the structure from
    ``start[i]`` (an anchor if fixed and in no bar, its bar ends from ``first_end[i]``, then its
    point mass; one node in a class 1 network)."""

    start: np.ndarray  #: (n,) int
    parts: np.ndarray  #: (n,) int
    first_end: np.ndarray  #: (n,) int
    fixed: np.ndarray  #: (n',) bool: supports of the structure's nodes
    mass: np.ndarray  #: (n',) point masses [kg] of the structure's nodes


def _split_nodes(
    network: _Network, node_fixed: Any, node_point_mass: Any, *, ball_joints: bool
) -> _SplitNodes:
    """The :class:`_SplitNodes` of a network with supports ``node_fixed`` (n,) bool and point
    masses ``node_point_mass`` (a number or n) [kg].  Without ``ball_joints``, a node in two
    bars, or a point mass on a bar's end or a support, is an error; a node in no bar must be
    fixed or carry a point mass."""
    rods, n_nodes = network.rods, network.position.shape[0]
    fixed, mass = _supports_and_point_masses(node_fixed, node_point_mass, n_nodes)
    count = np.bincount(rods.ravel(), minlength=n_nodes)
    if not ball_joints:
        check_class1(rods, n_nodes)
    free = np.flatnonzero((count == 0) & ~fixed & (mass == 0))
    if free.size:
        raise ValueError(
            f"nodes[{free[0]}]: belongs to no bar; fix it (node_fixed) or give it a "
            "mass (node_point_mass): a massless free node has no dynamics"
        )
    anchor = ((count == 0) & fixed).astype(np.int64)
    has_mass = (mass > 0).astype(np.int64)
    parts = anchor + count + has_mass
    if not ball_joints:
        both = np.flatnonzero(parts > 1)
        if both.size:
            i = both[0]
            where = (
                f"an end of bars {np.flatnonzero(np.any(rods == i, axis=1)).tolist()}"
                if count[i]
                else "fixed"
            )
            raise ValueError(
                f"node_point_mass[{i}]: node {i} is {where}; a point mass there needs "
                "ball_joints=True (it becomes its own node, joined to that one)"
            )
    start = np.cumsum(parts) - parts  # the first node of each node of N
    split_fixed = np.zeros(int(parts.sum()), bool)
    split_fixed[start[fixed]] = True
    split_mass = np.zeros(split_fixed.size)
    split_mass[(start + anchor + count)[mass > 0]] = mass[mass > 0]
    return _SplitNodes(start, parts, start + anchor, split_fixed, split_mass)


def _split_names(names: Sequence[str] | None, split: _SplitNodes) -> tuple[str, ...] | None:
    """The names of the split nodes: node ``i`` of ``N`` named ``names[i]`` becomes nodes named
    ``names[i]``, ``names[i].1``, ... (``None``: the default names)."""
    if names is None:
        return None
    if isinstance(names, (str, bytes)) or len(names) != split.parts.size:
        raise ValueError(
            f"node_name: expected {split.parts.size} names (one per node of N), got {names!r:.80}"
        )
    return tuple(
        name if j == 0 else f"{name}.{j}"
        for name, parts in zip(names, split.parts, strict=True)
        for j in range(parts)
    )


def _supports_and_point_masses(
    node_fixed: Any, node_point_mass: Any, n_nodes: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(fixed (n,) bool, point mass (n,) [kg])`` of :func:`from_connectivity`'s arguments,
    checked (booleans; finite masses >= 0)."""
    fixed = np.zeros(n_nodes, bool) if node_fixed is None else np.asarray(node_fixed)
    if fixed.shape != (n_nodes,) or fixed.dtype != bool:
        raise ValueError(
            f"node_fixed: expected {n_nodes} booleans, got {fixed.dtype} of shape {fixed.shape}"
        )
    mass = _per_member(
        0.0 if node_point_mass is None else node_point_mass, n_nodes, "node_point_mass"
    )
    bad = np.flatnonzero(~np.isfinite(mass) | (mass < 0))
    if bad.size:
        raise ValueError(f"node_point_mass[{bad[0]}]: must be finite and >= 0, got {mass[bad[0]]}")
    return fixed, mass


def _node_fields(
    network: _Network,
    split: _SplitNodes,
    velocity: np.ndarray | None,
    *,
    joint_nodes: Any,
    plane_nodes: Any,
    plane_normal: Any,
    line_nodes: Any,
    line_direction: Any,
) -> dict[str, Any]:
    """The :class:`Structure` fields of the split nodes (positions, velocities (n, d) [m/s] or
    None, supports, point masses, joints, planes and lines) and of the members' end nodes."""
    start, parts, n_nodes = split.start, split.parts, network.position.shape[0]
    return dict(
        node_position=np.repeat(network.position, parts, axis=0),
        node_velocity=None if velocity is None else np.repeat(velocity, parts, axis=0),
        rod_nodes=_split_rod_ends(network.rods, split.first_end),
        tendon_nodes=start[network.tendons],
        node_fixed=split.fixed,
        node_point_mass=split.mass,
        joint_nodes=np.vstack(
            [_star_joints(start, parts), start[_node_pairs(joint_nodes, n_nodes)]]
        ),
        plane_nodes=start[_node_list(plane_nodes, "plane_nodes", n_nodes)],
        plane_normal=plane_normal,
        line_nodes=start[_node_list(line_nodes, "line_nodes", n_nodes)],
        line_direction=line_direction,
    )


def _member_fields(
    network: _Network,
    rest: np.ndarray,
    *,
    rod_mass: Any,
    rod_length: Any,
    rod_damping: Any,
    rod_relative_damping: Any,
    tendon_stiffness: Any,
    tendon_damping: Any,
    tendon_name: Sequence[str] | None,
) -> dict[str, Any]:
    """The :class:`Structure` fields of the bars and strings: each parameter a number or one
    value per member; ``rod_length`` [m] defaults to the lengths in ``N``, ``rest`` (S,) [m]."""
    R, S = network.rods.shape[0], network.tendons.shape[0]
    return dict(
        rod_mass=_per_member(rod_mass, R, "rod_mass"),
        rod_length=(
            network.length if rod_length is None else _per_member(rod_length, R, "rod_length")
        ),
        rod_damping=_per_member(rod_damping, R, "rod_damping"),
        rod_relative_damping=_per_member(rod_relative_damping, R, "rod_relative_damping"),
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
    return np.column_stack(
        [lead, lead + 1 + np.arange(lead.size) - np.repeat(np.cumsum(extra) - extra, extra)]
    )


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
    node_name: tuple[str, ...] | None


def merge_joints(structure: Structure, *, keep_joints: bool = False) -> MergedNodes:
    """Merge every group of nodes joined by ball joints (``joint_nodes``) into one node.

    Merged nodes are numbered in the order of each group's lowest node and take that node's
    position and velocity; a group is fixed if any of its nodes is, its point mass is the sum of
    theirs, its name is that node's (``node_name`` ``None`` if the structure has the default
    names: :func:`from_connectivity` then names the nodes again).  The inverse of the split of
    :func:`from_connectivity` with ``ball_joints=True``.  With ``keep_joints`` nothing is
    merged (``node_map`` is the identity) and the joints stay in ``joint_nodes``, as
    :func:`from_connectivity` takes them: the structure's own layout.

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
            raise ValueError(
                f"tendons[{k}] ({names[k]!r}): joins nodes {tail} and {head}, which are "
                "joined by a ball joint; C_s cannot hold a string of zero length"
            )
        key = (min(a, b), max(a, b))
        if key in seen:
            raise ValueError(
                f"tendons[{k}] ({names[k]!r}): joins the same joined nodes as "
                f"tendons[{seen[key]}] ({names[seen[key]]!r}); C_s cannot keep them apart"
            )
        seen[key] = k
    fixed = np.zeros(lead.size, bool)
    np.logical_or.at(fixed, node_map, structure.node_fixed)
    return MergedNodes(
        node_map=node_map,
        N=structure.node_position[lead].T.copy(),
        node_velocity=structure.node_velocity[lead].T.copy(),
        node_fixed=fixed,
        node_point_mass=np.bincount(
            node_map, weights=structure.node_point_mass, minlength=lead.size
        ),
        plane_nodes=node_map[structure.plane_nodes],
        plane_normal=structure.plane_normal.copy(),
        line_nodes=node_map[structure.line_nodes],
        line_direction=structure.line_direction.copy(),
        joint_nodes=(joints if keep_joints else np.zeros((0, 2), np.int64)).copy(),
        node_name=(
            None
            if structure.has_default_node_names
            else tuple(structure.node_name[k] for k in lead)
        ),
    )


def to_connectivity(structure: Structure) -> Connectivity:
    """``N`` (d, n) [m], ``C_b`` (R, n) and ``C_s`` (S, n) of ``structure`` (dense integers).

    Each group of joined nodes (``joint_nodes``) is one node, shared by its bars (the class k
    convention; :func:`merge_joints` gives the order), so ``from_connectivity(N, C_b, C_s,
    ball_joints=True)`` gives back a structure with the same ``N, C_b, C_s``.  Supports, point
    masses and plane/line constraints are in :func:`merge_joints`.
    """
    return connectivity_of(structure, merge_joints(structure))


def connectivity_of(structure: Structure, merged: MergedNodes) -> Connectivity:
    n = merged.N.shape[1]
    return Connectivity(
        merged.N,
        incidence(merged.node_map[structure.rod_nodes], n),
        incidence(merged.node_map[structure.tendon_nodes], n),
    )
