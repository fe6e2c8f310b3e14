"""The class 1 tensegrity shell of ``n x m`` two-rod elements (Skelton, Pinaud, Mingori, §18.2).

The connectivity is the table of ``shared/spec/shell-topology.md`` (read off eq. 18.31 and the
closure rules 18.2-18.14); see ``docs/paper-notes.md`` for where it departs from printed lines.

Numbering (0-based, the paper's stacking order of ``q``, eq. 18.24):

- element ``(i, j)``, ``i = 1..n`` around, ``j = 1..m`` up, has index ``e = (j-1) n + (i-1)``;
- node ``p_k,ij`` (``k = 1..4``) has index ``4 e + (k-1)``;
- rod 1 of the element (``p1 -> p2``) has index ``2 e``, rod 2 (``p3 -> p4``) has ``2 e + 1``;
- tendons are listed element by element, ``alpha`` ascending, named ``t{alpha}_{i}_{j}``.
"""

from __future__ import annotations

import math
import sys
from typing import Any

import numpy as np

from tensegrity.model.structure import Structure, check_member_count

#: Tendon ``alpha`` of element ``(i, j)`` as ``(boundary, at_boundary, elsewhere)``.  Each end pair
#: ``(head, tail)`` names node ``p_k`` of element ``(i + di, j + dj)`` as ``(k, di, dj)``; the
#: ``boundary`` ("base": ``j = 1``, "top": ``j = m``) is where the first pair applies instead of the
#: second, ``None`` where the tendon is absent.  This is the spec's table, column by column.
_TENDON_TABLE: dict[int, tuple] = {
    1: ("base", ((2, 0, 0), (1, 1, 0)), ((2, 0, 0), (4, 0, -1))),
    2: ("base", ((1, 0, 0), (1, 1, 0)), ((1, 0, 0), (4, 0, -1))),
    3: (None, None, ((3, -1, 0), (1, 0, 0))),
    4: (None, None, ((2, 0, 0), (3, -1, 0))),
    5: (None, None, ((4, 0, 0), (2, 0, 0))),
    6: ("top", ((4, 1, 0), (4, 0, 0)), ((1, 1, 1), (4, 0, 0))),
    7: ("top", ((3, 0, 0), (4, 1, 0)), ((3, 0, 0), (1, 1, 1))),
    8: (None, None, ((2, 0, 0), (3, 0, 0))),
    9: ("base", None, ((1, 1, 0), (2, 0, 0))),
    10: ("top", None, ((4, 1, 0), (3, 0, 0))),
}


def shell_node_index(k: int, i: int, j: int, n: int) -> int:
    """0-based index of node ``p_k,ij`` (``k = 1..4``; ``i`` is taken cyclically mod ``n``)."""
    return 4 * ((j - 1) * n + (i - 1) % n) + (k - 1)


def shell_tendons(n: int, m: int, *, primal: bool = False) -> list[tuple[str, int, int]]:
    """The shell's tendons as ``(name, tail, head)``, tendon vector ``p_head - p_tail``.

    For ``m = 1`` the element is both base and top: ``t1, t2`` take the base column, ``t6, t7``
    the top column, and ``t9, t10`` are absent (Appendix C).  The primal shell (Definition 18.6)
    has no ``t9``, ``t10``.  Counts: ``n (10 m - 2)``, or ``8 n m`` primal.
    """
    _check_size(n, m)
    tendons = []
    for j in range(1, m + 1):
        for i in range(1, n + 1):
            for alpha, (boundary, at_boundary, elsewhere) in _TENDON_TABLE.items():
                on_boundary = (boundary == "base" and j == 1) or (boundary == "top" and j == m)
                ends = at_boundary if on_boundary else elsewhere
                if ends is None or (primal and alpha >= 9):
                    continue
                (kh, dih, djh), (kt, dit, djt) = ends
                head = shell_node_index(kh, i + dih, j + djh, n)
                tail = shell_node_index(kt, i + dit, j + djt, n)
                tendons.append((f"t{alpha}_{i}_{j}", tail, head))
    return tendons


def _check_size(n: int, m: int) -> None:
    if not isinstance(n, (int, np.integer)) or isinstance(n, bool) or n < 3:
        raise ValueError(f"n: a shell needs n >= 3 elements around, got {n!r}")
    if not isinstance(m, (int, np.integer)) or isinstance(m, bool) or m < 1:
        raise ValueError(f"m: a shell needs m >= 1 stages, got {m!r}")
    # 2 rods and at most 12 tendons per element (Table 18.1)
    check_member_count(14 * int(n) * int(m), f"n = {n}, m = {m}")


def _real(value: Any, name: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a number, got {value!r}") from None


#: Largest shell radius, in rod lengths: node coordinates of ``R`` [m] carry a round-off of
#: about ``2e-16 R``, which must stay far below a rod's length.
MAX_RADIUS_RATIO = 1e9


def shell_layout(
    n: int,
    m: int,
    *,
    rod_length: float = 1.0,
    radius: float | None = None,
    stage_height: float | None = None,
    twist: float | None = None,
) -> np.ndarray:
    """Node positions (4nm, 3) [m] on a cylinder about the z axis, ``n``-fold symmetric.

    Stage ``j`` spans heights ``(j-1) h .. j h``: ``p1`` at its bottom, ``p2`` and ``p3`` at
    mid-height, ``p4`` at its top, so each rod rises ``h/2`` and sweeps an angle
    ``dtheta = 2 asin(c / 2R)`` about the axis, with ``c = sqrt(L^2 - (h/2)^2)``.  In element
    ``i`` of stage ``j``: ``theta(p1) = 2 pi (i-1)/n + (j-1) twist``, ``theta(p2) = theta(p1) +
    dtheta``, ``theta(p3) = theta(p2) + pi/n``, ``theta(p4) = theta(p3) + dtheta``.

    Parameters
    ----------
    rod_length : float
        ``L`` [m]; every rod's end points are exactly ``L`` apart.
    radius : float, optional
        Cylinder radius ``R`` [m].  Default: each rod sweeps ``dtheta = 3 pi / (2n)``.
    stage_height : float, optional
        ``h`` [m], with ``0 < h < 2 L``.  Default ``L``.
    twist : float, optional
        Rotation [rad] of each stage relative to the one below.  Default ``2 dtheta``, which puts
        a stage's bottom ring midway between the top nodes of the stage below.
    """
    _check_size(n, m)
    L = _real(rod_length, "rod_length")
    h = L if stage_height is None else _real(stage_height, "stage_height")
    if not (math.isfinite(L) and L > 0):
        raise ValueError(f"rod_length: must be > 0, got {rod_length!r}")
    if not L * L >= sys.float_info.min:
        raise ValueError(
            f"rod_length: too small to compute with (its square underflows), got {L!r}"
        )
    if not (math.isfinite(h) and 0 < h < 2 * L):
        raise ValueError(f"stage_height: must be in (0, 2 rod_length) = (0, {2 * L}), got {h!r}")
    chord = math.sqrt(L**2 - (h / 2) ** 2)
    if radius is None:
        sweep = 3 * math.pi / (2 * n)
        R = chord / (2 * math.sin(sweep / 2))
    else:
        R = _real(radius, "radius")
        if not (math.isfinite(R) and R >= chord / 2):
            raise ValueError(
                f"radius: must be >= {chord / 2!r} m for rods of length {L} to fit a stage of "
                f"height {h}, got {radius!r}"
            )
        if R > MAX_RADIUS_RATIO * L:
            raise ValueError(
                f"radius: at most {MAX_RADIUS_RATIO:g} rod lengths ({MAX_RADIUS_RATIO * L:g} m): "
                f"farther out the rods are lost in the round-off of the node coordinates, got "
                f"{radius!r}"
            )
        sweep = 2 * math.asin(chord / (2 * R))
    stage_twist = 2 * sweep if twist is None else _real(twist, "twist")
    if not math.isfinite(stage_twist):
        raise ValueError(f"twist: must be finite, got {twist!r}")

    i = np.arange(n)
    j = np.arange(m)[:, None]
    theta1 = 2 * math.pi * i / n + j * stage_twist  # (m, n)
    angles = np.stack(
        [theta1, theta1 + sweep, theta1 + sweep + math.pi / n, theta1 + 2 * sweep + math.pi / n],
        axis=-1,
    )  # (m, n, 4)
    heights = np.stack([j * h, (j + 0.5) * h, (j + 0.5) * h, (j + 1) * h], axis=-1)
    heights = np.broadcast_to(heights, angles.shape)
    xyz = np.stack([R * np.cos(angles), R * np.sin(angles), heights], axis=-1)
    return xyz.reshape(4 * n * m, 3)


def class1_shell(
    n: int = 3,
    m: int = 1,
    *,
    primal: bool = False,
    rod_mass: float = 1.0,
    rod_length: float = 1.0,
    stiffness: float = 100.0,
    rest_length: float | None = None,
    damping: float = 0.0,
    radius: float | None = None,
    stage_height: float | None = None,
    twist: float | None = None,
    fixed_base: bool = False,
) -> Structure:
    """The class 1 shell of ``n x m`` two-rod elements, nodes on a cylinder (Figure 18.10).

    All rods share ``rod_mass`` [kg] and ``rod_length`` [m]; all tendons share ``stiffness``
    [N/m], ``rest_length`` [m] and ``damping`` [N s/m], as in the paper's example.  The default
    rest length is half the shortest tendon of the initial layout, so every tendon starts taut.
    Layout parameters are those of :func:`shell_layout`; ``fixed_base`` fixes the base ring
    (``p1`` of stage 1, at ``z = 0``) to ground.

    Returns
    -------
    Structure
        ``4nm`` nodes, ``2nm`` rods, ``n(10m-2)`` tendons (``8nm`` if ``primal``).
    """
    position = shell_layout(
        n, m, rod_length=rod_length, radius=radius, stage_height=stage_height, twist=twist
    )
    fixed = np.zeros(len(position), bool)
    if fixed_base:
        fixed[[shell_node_index(1, i, 1, n) for i in range(1, n + 1)]] = True
    return _shell_structure(
        position,
        shell_tendons(n, m, primal=primal),
        rod_mass=rod_mass,
        rod_length=rod_length,
        stiffness=stiffness,
        rest_length=rest_length,
        damping=damping,
        node_fixed=fixed,
    )


def _shell_structure(
    position: np.ndarray,
    tendons: list[tuple[str, int, int]],
    *,
    rod_mass: float,
    rod_length: float,
    stiffness: float,
    rest_length: float | None,
    damping: float,
    **extra: Any,
) -> Structure:
    """A shell's :class:`Structure`: rod ``r`` joins nodes ``2r, 2r+1``, uniform parameters, the
    default rest length half the shortest initial tendon; ``extra`` fields passed on."""
    tendon_nodes = np.array([(tail, head) for _, tail, head in tendons])
    if rest_length is None:
        lengths = np.linalg.norm(
            position[tendon_nodes[:, 1]] - position[tendon_nodes[:, 0]], axis=1
        )
        rest_length = 0.5 * float(lengths.min())
    n_rods, n_tendons = len(position) // 2, len(tendons)
    return Structure(
        node_position=position,
        rod_nodes=np.arange(2 * n_rods).reshape(n_rods, 2),
        rod_mass=np.full(n_rods, float(rod_mass)),
        rod_length=np.full(n_rods, float(rod_length)),
        tendon_nodes=tendon_nodes,
        tendon_stiffness=np.full(n_tendons, float(stiffness)),
        tendon_rest_length=np.full(n_tendons, float(rest_length)),
        tendon_damping=np.full(n_tendons, float(damping)),
        tendon_name=tuple(name for name, _, _ in tendons),
        **extra,
    )


#: Tendons that Lemma 18.1's constraints (18.1) make duplicates, with where they do: ``t3 = -t2``
#: and ``t4 = t1`` once ``p3(i-1,j) = p4(i,j-1)`` (``j > 1``); ``t6 = -t5`` and ``t8 = -t7`` once
#: ``p2(i,j) = p1(i+1,j+1)`` (``j < m``).  The class 2 shell keeps t1, t2, t5, t7.
_MERGED_TENDONS = {3: "above_base", 4: "above_base", 6: "below_top", 8: "below_top"}


def class2_joints(n: int, m: int) -> np.ndarray:
    """Lemma 18.1's ball joints as node pairs (J, 2): ``p2(i,j) = p1(i+1,j+1)`` for ``j < m``
    and ``p3(i-1,j) = p4(i,j-1)`` for ``j > 1`` (``shared/spec/shell-topology.md``), ``2n(m-1)``
    pairs."""
    _check_size(n, m)
    pairs = [
        (shell_node_index(2, i, j, n), shell_node_index(1, i + 1, j + 1, n))
        for j in range(1, m)
        for i in range(1, n + 1)
    ] + [
        (shell_node_index(3, i - 1, j, n), shell_node_index(4, i, j - 1, n))
        for j in range(2, m + 1)
        for i in range(1, n + 1)
    ]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def class2_layout(
    n: int, m: int, *, rod_length: float = 1.0, stage_height: float | None = None
) -> np.ndarray:
    """Node positions (4nm, 3) [m] of the class 2 shell on a cylinder about the z axis, in which
    the nodes that Lemma 18.1 joins coincide.

    Rings ``k = 0..m`` at heights ``k h``.  In stage ``j`` both rods rise from ring ``j-1`` to
    ring ``j``: rod 1 from angle ``phi_i = 2 pi (i-1)/n`` to ``phi_i + 2 pi/n`` (so that
    ``p2(i,j)`` meets ``p1(i+1,j+1)``), rod 2 from ``phi_i + pi/n`` to ``phi_i - pi/n`` (so that
    ``p4(i,j-1)`` meets ``p3(i-1,j)``).  Equal rod lengths force this (the two rods must sweep
    opposite angles ``+-2 pi/n``).  The radius follows from ``L^2 = (2 R sin(pi/n))^2 + h^2``.

    Parameters
    ----------
    rod_length : float
        ``L`` [m].
    stage_height : float, optional
        ``h`` [m], ``0 < h < L``.  Default ``L / 2``.
    """
    _check_size(n, m)
    L = _real(rod_length, "rod_length")
    if not (math.isfinite(L) and L > 0):
        raise ValueError(f"rod_length: must be > 0, got {rod_length!r}")
    if not L * L >= sys.float_info.min:
        raise ValueError(
            f"rod_length: too small to compute with (its square underflows), got {L!r}"
        )
    h = L / 2 if stage_height is None else _real(stage_height, "stage_height")
    if not (math.isfinite(h) and 0 < h < L):
        raise ValueError(
            f"stage_height: must be in (0, rod_length) = (0, {L}), got {stage_height!r}"
        )
    R = math.sqrt(L**2 - h**2) / (2 * math.sin(math.pi / n))
    phi = 2 * math.pi * np.arange(n) / n + np.zeros((m, 1))  # (m, n)
    step = 2 * math.pi / n
    angles = np.stack([phi, phi + step, phi + step / 2, phi - step / 2], axis=-1)  # (m, n, 4)
    j = np.arange(m)[:, None, None]
    heights = np.broadcast_to(np.concatenate([j, j + 1, j, j + 1], axis=-1) * h, angles.shape)
    xyz = np.stack([R * np.cos(angles), R * np.sin(angles), heights], axis=-1)
    return xyz.reshape(4 * n * m, 3)


def class2_shell(
    n: int = 3,
    m: int = 2,
    *,
    primal: bool = False,
    rod_mass: float = 1.0,
    rod_length: float = 1.0,
    stiffness: float = 100.0,
    rest_length: float | None = None,
    damping: float = 0.0,
    stage_height: float | None = None,
    fixed_base: bool = False,
) -> Structure:
    """The class 2 shell of Lemma 18.1: the class 1 shell with ``p2(i,j) = p1(i+1,j+1)`` and
    ``p3(i-1,j) = p4(i,j-1)`` joined by ball joints (:func:`class2_joints`).

    The rods keep their own end nodes (the class 1 numbering of this module); the joints are
    ``Structure.joint_nodes``.  Of each pair of tendons that (18.1) makes identical (they join
    the same two points), one is kept: ``t3``, ``t4`` are dropped for ``j > 1`` and ``t6``,
    ``t8`` for ``j < m``, leaving ``n (6m + 2)`` tendons (``n (4m + 4)`` primal).  Nodes are
    placed by :func:`class2_layout`; ``fixed_base`` fixes the base ring (``p1``, ``p3`` of
    stage 1) to ground.  Other parameters as :func:`class1_shell`.

    Raises
    ------
    ValueError
        For ``m < 2`` (no node is joined) and as :func:`class1_shell`.
    """
    _check_size(n, m)
    if m < 2:
        raise ValueError(
            f"m: a class 2 shell needs m >= 2 stages (with m = 1 no nodes join), got {m!r}"
        )
    position = class2_layout(n, m, rod_length=rod_length, stage_height=stage_height)
    tendons = []
    for name, tail, head in shell_tendons(n, m, primal=primal):
        alpha, _, j = (int(x) for x in name[1:].split("_"))
        where = _MERGED_TENDONS.get(alpha)
        if (where == "above_base" and j > 1) or (where == "below_top" and j < m):
            continue
        tendons.append((name, tail, head))
    fixed = np.zeros(4 * n * m, bool)
    if fixed_base:
        for i in range(1, n + 1):
            fixed[[shell_node_index(1, i, 1, n), shell_node_index(3, i, 1, n)]] = True
    return _shell_structure(
        position,
        tendons,
        rod_mass=rod_mass,
        rod_length=rod_length,
        stiffness=stiffness,
        rest_length=rest_length,
        damping=damping,
        joint_nodes=class2_joints(n, m),
        node_fixed=fixed,
    )
