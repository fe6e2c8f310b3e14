"""Generators of the class 1 structures people test with, and the registry the CLI uses.

- :func:`prism`: the regular ``n``-bar prism (``n = 3``: the simplex; ``n = 4``: the 4-bar prism)
  at its equilibrium twist ``pi/2 - pi/n``;
- :func:`octahedron`: the 6-bar expanded octahedron;
- :func:`tower`: a tower of stacked, interlaced ``n``-bar prisms (Snelson's Needle Tower,
  the paper's Figure 18.3);
- :func:`six_bar_robot` and :func:`three_bar_robot`: the octahedron and the simplex as robots,
  with named cables (:func:`face_cables`), a choice of actuated ones (:func:`actuated_cables`)
  and, for the six-bar, an optional payload at the centre;
- the class 1 shell :func:`tensegrity.model.shell.class1_shell` (kind ``shell``).

Every generator returns a validated :class:`~tensegrity.model.structure.Structure` with rods of
``rod_length`` (default 1 m) and ``rod_mass`` (default 1 kg), tendons of ``stiffness`` (default
100 N/m), all taut and prestressed: the rest lengths realize a self-stress of the generated
geometry with mean tendon tension ``tension`` [N] (found by the linear program of
:func:`tensegrity.analysis.prestress.feasible_prestress`), so the generated layout is an
equilibrium of the free structure (its stability is checked in the tests by modal analysis and
damped simulation).

Registry: :data:`KINDS` maps a kind name to its generator function and a one-line summary;
another generator is added with one line in :data:`KINDS` or one call to :func:`register`.

Node numbering of the prisms: bottom nodes ``0..n-1``, top nodes ``n..2n-1``; bar ``i`` joins
bottom node ``i`` (tail) to top node ``n + i`` (head).
"""

from __future__ import annotations

import importlib
import inspect
import itertools
import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from tensegrity.model.connectivity import from_connectivity, incidence
from tensegrity.model.planar import planar_rod, planar_two_rod
from tensegrity.model.shell import class1_shell, class2_shell
from tensegrity.model.structure import Structure, check_member_count


# ----------------------------------------------------------------------------- helpers
def _positive(value: Any, name: str) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a number, got {value!r}") from None
    if not (math.isfinite(x) and x > 0):
        raise ValueError(f"{name}: must be > 0, got {value!r}")
    return x


def _count(value: Any, name: str, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"{name}: must be an integer >= {low}, got {value!r}")
    return int(value)


def _draft(
    position: np.ndarray,
    rods: np.ndarray,
    tendons: np.ndarray,
    names: tuple[str, ...],
    *,
    rod_mass: Any,
    stiffness: Any,
    damping: Any,
    rest_fraction: float = 1.0,
) -> Structure:
    """The structure of a layout (via :func:`~tensegrity.io.formats.from_connectivity`), with every
    rest length ``rest_fraction`` times the tendon's length in the layout."""
    n = position.shape[0]
    return from_connectivity(
        position.T,
        incidence(rods, n),
        incidence(tendons, n),
        rod_mass=_positive(rod_mass, "rod_mass"),
        tendon_stiffness=_positive(stiffness, "stiffness"),
        tendon_prestrain=1.0 / rest_fraction - 1.0,
        tendon_damping=float(damping),
        tendon_name=names,
    )


def _prestressed(draft: Structure, tension: Any) -> Structure:
    """``draft`` with rest lengths that realize its layout's best self-stress (mean ``tension``).

    The self-stress maximizing the smallest tendon tension (a linear program) is scaled to the
    mean ``tension`` [N] and realized by rest lengths ``l - T / k``; the layout is then an
    equilibrium.  ``ValueError`` if the layout has no self-stress with every tendon taut.
    """
    from tensegrity.analysis.prestress import feasible_prestress, rest_lengths_for_tensions

    prestress = feasible_prestress(draft, mean_tension=_positive(tension, "tension"))
    if not prestress.feasible:
        raise ValueError(f"layout: no self-stress with every tendon taut ({prestress.message})")
    rest, _ = rest_lengths_for_tensions(draft, None, prestress.tension)
    return draft.replace(tendon_rest_length=rest)


def _with_base(structure: Structure, base: Any, fixed_base: bool) -> Structure:
    """``structure`` with the nodes ``base`` fixed to ground if ``fixed_base`` (the generated
    layout is an equilibrium of the free structure, so the supports carry no force there)."""
    if not fixed_base:
        return structure
    fixed = np.zeros(structure.n_nodes, bool)
    fixed[base] = True
    return structure.replace(node_fixed=fixed)


def _pairs(tails: np.ndarray, heads: np.ndarray) -> np.ndarray:
    return np.column_stack([tails, heads]).astype(np.int64)


# --------------------------------------------------------------------------------- prism
def prism_twist(n: int) -> float:
    """Equilibrium twist ``pi/2 - pi/n`` [rad] of the regular ``n``-bar prism (see
    :func:`prism`)."""
    return math.pi / 2 - math.pi / _count(n, "n", 3)


def prism_layout(
    n: int, *, rod_length: float = 1.0, height: float | None = None, twist: float | None = None
) -> np.ndarray:
    """Node positions (2n, 3) [m] of an ``n``-bar prism about the ``z`` axis.

    Bottom node ``i`` at angle ``2 pi i / n``, height 0; top node ``n + i`` at angle
    ``2 pi i / n + twist + 2 pi / n``, height ``h``: bar ``i`` (bottom ``i`` -> top ``n + i``)
    sweeps ``twist + 2 pi / n`` about the axis, and the side string from bottom node ``i`` to top
    node ``n + i - 1`` sweeps ``twist``.  All nodes at one radius ``r``, with
    ``L^2 = h^2 + 2 r^2 (1 - cos(twist + 2 pi / n))``.

    Parameters
    ----------
    height : float, optional
        ``h`` [m] at the equilibrium twist, in ``(0, L)``; default ``L / sqrt(2)`` (bars at 45
        degrees to the axis).  It fixes the radius ``r``.
    twist : float, optional
        [rad], default :func:`prism_twist` ``(n)``, the equilibrium.  Another twist keeps ``r``
        and changes the height (a start away from equilibrium).
    """
    n = _count(n, "n", 3)
    check_member_count(4 * n, f"n = {n}")  # n bars, 3 n strings
    L = _positive(rod_length, "rod_length")
    h0 = L / math.sqrt(2) if height is None else _positive(height, "height")
    if not h0 < L:
        raise ValueError(f"height: must be < rod_length = {L}, got {height!r}")
    r = math.sqrt((L**2 - h0**2) / (2 * (1 - math.cos(prism_twist(n) + 2 * math.pi / n))))
    sweep = (prism_twist(n) if twist is None else float(twist)) + 2 * math.pi / n
    chord2 = 2 * r**2 * (1 - math.cos(sweep))
    if not (math.isfinite(sweep) and chord2 < L**2):
        raise ValueError(f"twist: a bar of length {L} cannot sweep {sweep!r} rad at radius {r!r}")
    h = math.sqrt(L**2 - chord2)
    angle = 2 * math.pi * np.arange(n) / n
    bottom = np.column_stack([r * np.cos(angle), r * np.sin(angle), np.zeros(n)])
    top = np.column_stack([r * np.cos(angle + sweep), r * np.sin(angle + sweep), np.full(n, h)])
    return np.vstack([bottom, top])


def prism_members(n: int) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Rods (n, 2), tendons (3n, 2) and tendon names of the ``n``-bar prism.

    Tendons: bottom ring ``b{i}`` (bottom ``i`` -> ``i+1``), top ring ``t{i}`` (top ``i`` ->
    ``i+1``), side ``s{i}`` (bottom ``i`` -> top ``i-1``), in that order.
    """
    i = np.arange(n)
    rods = _pairs(i, n + i)
    tendons = np.vstack(
        [_pairs(i, (i + 1) % n), _pairs(n + i, n + (i + 1) % n), _pairs(i, n + (i - 1) % n)]
    )
    names = tuple(f"{kind}{k}" for kind in "bts" for k in range(n))
    return rods, tendons, names


def prism(
    n: int = 3,
    *,
    rod_length: float = 1.0,
    rod_mass: float = 1.0,
    height: float | None = None,
    stiffness: float = 100.0,
    tension: float = 5.0,
    damping: float = 0.0,
    fixed_base: bool = False,
) -> Structure:
    """The regular ``n``-bar prism at its equilibrium twist (``n = 3``: the simplex).

    ``n`` bars between a bottom and a top ``n``-gon of ring strings, ``n`` side strings
    (:func:`prism_members`), laid out by :func:`prism_layout` with the twist ``pi/2 - pi/n``
    (30 degrees for ``n = 3``, 45 for ``n = 4``), the only twist at which the prism has a
    self-stress with all strings in tension (derivation and source: ``docs/networks.md``).  Rest
    lengths realize that self-stress with mean tendon tension ``tension`` [N].

    Parameters
    ----------
    rod_length : float
        [m].  rod_mass : [kg].  stiffness : tendon stiffness [N/m].  damping : tendon [N s/m].
    height : float, optional
        Prism height [m] in ``(0, rod_length)``; default ``rod_length / sqrt(2)``.
    tension : float
        Mean tendon tension of the prestress [N].
    fixed_base : bool
        Fix the bottom nodes ``0..n-1`` (at ``z = 0``) to ground; the prestress is that of the
        free prism, so the layout stays an equilibrium with no reactions.
    """
    layout = prism_layout(n, rod_length=rod_length, height=height)
    draft = _draft(
        layout, *prism_members(n), rod_mass=rod_mass, stiffness=stiffness, damping=damping
    )
    return _with_base(_prestressed(draft, tension), np.arange(n), fixed_base)


# ---------------------------------------------------------------------------- octahedron
def octahedron(
    *,
    rod_length: float = 1.0,
    rod_mass: float = 1.0,
    stiffness: float = 100.0,
    tension: float = 5.0,
    damping: float = 0.0,
    fixed_base: bool = False,
) -> Structure:
    """The 6-bar expanded octahedron: three pairs of parallel bars, 24 equal strings.

    Bars of length ``L`` in pairs parallel to ``x`` (at ``z = +-L/4``), ``y`` (at ``x = +-L/4``)
    and ``z`` (at ``y = +-L/4``): a pair is ``L/2`` apart, the symmetric equilibrium (every
    string ``sqrt(6)/4 L`` long, bar force ``sqrt(6)`` times the string tension; derivation in
    ``docs/networks.md``).  Each node has four strings, to the nearest ends of the two bar pairs
    it is not parallel to: the 24 edges of the 8 triangles around the octahedron's faces.
    Nodes ``2r, 2r+1`` are the ends of rod ``r`` (``-`` end first).

    ``fixed_base`` stands it on the string triangle that faces ``(-1, -1, -1)`` (nodes 0, 4, 8:
    the ``-`` ends of the bars at ``z = -L/4``, ``x = -L/4``, ``y = -L/4``): the layout is
    turned so that this face's normal points down (coordinates in the basis
    ``(1, -1, 0)/sqrt(2)``, ``(1, 1, -2)/sqrt(6)``, ``(1, 1, 1)/sqrt(3)``) and raised to put
    it at ``z = 0``, and its three nodes are fixed to ground; the prestress is the free
    structure's, so the layout stays an equilibrium with no reactions.
    """
    L = _positive(rod_length, "rod_length")
    a = L / 4
    nodes = []
    for axis in range(3):  # bar pairs parallel to x, y, z
        for offset in (-a, a):
            for end in (-L / 2, L / 2):
                p = np.zeros(3)
                p[axis] = end
                p[(axis + 2) % 3] = offset  # x-bars offset in z, y-bars in x, z-bars in y
                nodes.append(p)
    position = np.array(nodes)
    base = [0, 4, 8]  # the string triangle facing (-1, -1, -1)
    if fixed_base:
        basis = np.array([[1, -1, 0], [1, 1, -2], [1, 1, 1]]) / np.sqrt([[2], [6], [3]])
        position = position @ basis.T
        position[:, 2] -= position[base, 2].mean()
    rods = _pairs(np.arange(0, 12, 2), np.arange(1, 12, 2))
    distance = np.linalg.norm(position[:, None] - position[None], axis=2)
    string = math.sqrt(6) / 4 * L
    tails, heads = np.nonzero(np.triu(np.isclose(distance, string, rtol=1e-12)))
    tendons = _pairs(tails, heads)
    names = tuple(f"s{k}" for k in range(tendons.shape[0]))
    draft = _draft(
        position, rods, tendons, names, rod_mass=rod_mass, stiffness=stiffness, damping=damping
    )
    return _with_base(_prestressed(draft, tension), base, fixed_base)


# --------------------------------------------------------------------------------- tower
def tower_members(n: int, m: int) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Rods and tendons of ``m`` stacked ``n``-bar prisms, stage ``j`` on nodes ``2nj .. 2nj+2n-1``.

    Each stage is a prism (:func:`prism_members` numbering, side strings ``side{i}_{j}``); the
    bottom ring ``base{i}`` closes stage 0 and the top ring ``top{i}`` stage ``m-1``.  Between
    stages ``j`` and ``j+1`` the rings are replaced by a zig-zag of ``2n`` saddle strings (bottom
    node ``i`` of stage ``j+1`` to top nodes ``i``, ``saddle{i}a_{j}``, and ``i+1``,
    ``saddle{i}b_{j}``, of stage ``j``) and ``2n`` vertical strings that hold the stages
    interlaced: bottom node ``i`` of stage ``j`` to bottom node ``i`` of stage ``j+1``
    (``low{i}_{j}``) and top to top (``high{i}_{j}``).  Without these the saddle strings would
    pull the stages apart until they merely touch (no overlap).
    """
    i = np.arange(n)
    rods: list[np.ndarray] = []
    tendons: list[np.ndarray] = []
    names: list[str] = []

    def add(pairs: np.ndarray, label: str) -> None:
        tendons.append(pairs)
        names.extend(label.format(k) for k in range(n))

    for j in range(m):
        low, high = 2 * n * j, 2 * n * j + n  # first bottom and first top node of stage j
        rods.append(_pairs(low + i, high + i))
        add(_pairs(low + i, high + (i - 1) % n), f"side{{}}_{j}")
        if j == 0:
            add(_pairs(low + i, low + (i + 1) % n), "base{}")
        if j == m - 1:
            add(_pairs(high + i, high + (i + 1) % n), "top{}")
        else:
            add(_pairs(high + i, high + n + i), f"saddle{{}}a_{j}")
            add(_pairs(high + (i + 1) % n, high + n + i), f"saddle{{}}b_{j}")
            add(_pairs(low + i, low + 2 * n + i), f"low{{}}_{j}")
            add(_pairs(high + i, high + 2 * n + i), f"high{{}}_{j}")
    return np.vstack(rods), np.vstack(tendons), tuple(names)


def tower(
    n: int = 3,
    m: int = 3,
    *,
    rod_length: float = 1.0,
    rod_mass: float = 1.0,
    overlap: float = 0.3,
    stiffness: float = 100.0,
    tension: float = 5.0,
    damping: float = 0.0,
    fixed_base: bool = False,
) -> Structure:
    """A tower of ``m`` stacked ``n``-bar prisms (Snelson's Needle Tower, Figure 18.3).

    Stage ``j`` is the prism of :func:`prism_layout` turned by ``j (twist + 3 pi / n)`` about the
    axis (so its bottom nodes sit midway, in angle, between the top nodes of the stage below)
    and raised by ``j (1 - overlap) h``: consecutive stages overlap by ``overlap`` of a stage's
    height ``h``.  Members: :func:`tower_members`.  That rough layout is not an equilibrium;
    form-finding (:func:`tensegrity.analysis.prestress.form_find`, from rest lengths of 0.9 times
    the initial lengths) moves it to a stable equilibrium with every tendon taut, and the rest
    lengths are set to realize the self-stress of that geometry with mean tension ``tension``
    [N].  The returned structure's nodes are at that equilibrium.  ``fixed_base`` then fixes
    the bottom nodes of stage 0 (``0..n-1``) to ground, where form-finding left them: the
    equilibrium of the free tower, with no reactions.

    Raises
    ------
    ValueError
        If form-finding ends without a stable, all-taut equilibrium (it names the verdict).
    """
    from tensegrity.analysis.prestress import form_find

    n, m = _count(n, "n", 3), _count(m, "m", 1)
    check_member_count(6 * n * m, f"n = {n}, m = {m}")  # per stage n bars, at most 5 n strings
    if not 0 <= overlap < 1:
        raise ValueError(f"overlap: must be in [0, 1), got {overlap!r}")
    stage = prism_layout(n, rod_length=rod_length)
    turn = prism_twist(n) + 3 * math.pi / n
    pitch = (1 - overlap) * stage[n, 2]
    layout = []
    for j in range(m):
        c, s = math.cos(j * turn), math.sin(j * turn)
        layout.append(stage @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) + [0, 0, j * pitch])
    draft = _draft(
        np.vstack(layout),
        *tower_members(n, m),
        rod_mass=rod_mass,
        stiffness=stiffness,
        damping=damping,
        rest_fraction=0.9,
    )
    found = form_find(draft, mean_tension=_positive(tension, "tension"))
    if not found.stable:
        raise ValueError(
            f"tower: form-finding found no stable all-taut equilibrium ({found.verdict})"
        )
    return _with_base(found.structure, np.arange(n), fixed_base)


# -------------------------------------------------------------------------------- robots
#: Suffix of the name of a tendon that is not actuated (:func:`actuated_cables`).
PASSIVE = "_passive"

#: The 8 cable triangles of :func:`six_bar_robot`, named by the octant each faces: ``"f"`` and
#: the signs of ``x``, ``y``, ``z`` (``"f+-+"``: the face towards ``x > 0, y < 0, z > 0``).
SIX_BAR_FACES: tuple[str, ...] = tuple(
    "f" + "".join(signs) for signs in itertools.product("-+", repeat=3)
)


#: A face's cable by the axes of the two bars it joins (0, 1, 2: ``x``, ``y``, ``z``).
_FACE_EDGES = {frozenset((0, 1)): "xy", frozenset((1, 2)): "yz", frozenset((0, 2)): "zx"}


def actuated_cables(structure: Structure) -> tuple[str, ...]:
    """Names of ``structure``'s actuated tendons: those whose name does not end in
    :data:`PASSIVE`, in the structure's order.

    A control table (:class:`~tensegrity.model.loads.ControlTable`, one column per tendon) moves
    the rest lengths of these and keeps the other columns zero; the robots of
    :func:`six_bar_robot` and :func:`three_bar_robot` mark the cables their ``actuated`` keyword
    leaves out, and any structure (a file too) can mark its passive tendons the same way.
    """
    return tuple(name for name in structure.tendon_name if not name.endswith(PASSIVE))


def face_cables(structure: Structure, face: str) -> tuple[str, str, str]:
    """Names ``(xy, yz, zx)`` of the three cables around the triangle ``face`` of a
    :func:`six_bar_robot` (one of :data:`SIX_BAR_FACES`), actuated or not.

    ``ValueError`` naming ``face`` if it is not a face name or ``structure`` has not its cables.
    """
    if face not in SIX_BAR_FACES:
        raise ValueError(f"face: expected one of {', '.join(SIX_BAR_FACES)}, got {face!r}")
    names = set(structure.tendon_name)
    xy, yz, zx = (
        next((n for n in (f"{face}_{pair}", f"{face}_{pair}{PASSIVE}") if n in names), "")
        for pair in _FACE_EDGES.values()
    )
    if not (xy and yz and zx):
        raise ValueError(
            f"face: {structure!r} has no cables of face {face!r} (not a six-bar robot)"
        )
    return xy, yz, zx


def _actuated(structure: Structure, actuated: Any, default: str) -> Structure:
    """``structure`` with :data:`PASSIVE` appended to the names of the tendons ``actuated`` (names
    or fnmatch patterns, comma-separated text or a sequence; ``"all"``: ``default``) does not
    match; ``ValueError`` naming ``actuated`` for a pattern that matches no tendon."""
    from tensegrity.analysis.controllability import match_tendons, split_patterns

    try:
        patterns = split_patterns(default if actuated == "all" else actuated)
    except (TypeError, AttributeError, ValueError):
        raise ValueError(f"actuated: expected cable names or patterns, got {actuated!r}") from None
    chosen: set[str] = set()
    for pattern in patterns:
        try:
            chosen.update(match_tendons(structure, [pattern]))
        except KeyError:
            raise ValueError(
                f"actuated: no cable matches {pattern!r} (cables: "
                f"{', '.join(structure.tendon_name)})"
            ) from None
    names = tuple(n if n in chosen else n + PASSIVE for n in structure.tendon_name)
    return structure.replace(tendon_name=names)


def _payload_offset(L: float, tension: float, payload_tension: float) -> float:
    """The offset ``a`` [m] of the six-bar's bars from the centre (``L/4`` without payload) at
    which 12 radial cables of tension ``payload_tension`` balance the shell's of ``tension``.

    At node ``(L/2, 0, a)``, with force densities ``q`` (shell) and ``q_p`` (radial), ``z``
    balance ``q (L - 4a) = q_p a`` (the bar is along ``x``) gives ``a`` in ``(0, L/4)``.
    """
    from scipy.optimize import brentq

    def excess(a: float) -> float:
        shell = math.sqrt((L / 2 - a) ** 2 + L**2 / 4 + a**2)
        radial = math.sqrt(L**2 / 4 + a**2)
        return payload_tension / radial * a - tension / shell * (L - 4 * a)

    return float(brentq(excess, 1e-9 * L, L / 4, xtol=1e-15 * L, rtol=4 * np.finfo(float).eps))


def six_bar_robot(
    *,
    rod_length: float = 1.0,
    rod_mass: float = 1.0,
    stiffness: float = 100.0,
    tension: float = 5.0,
    damping: float = 0.0,
    actuated: str | tuple[str, ...] = "all",
    payload_mass: float | None = None,
    payload_stiffness: float | None = None,
    payload_tension: float | None = None,
) -> Structure:
    """The six-bar rolling robot: the expanded :func:`octahedron` with named cables, optionally
    a payload at its centre held by 12 cables.

    The 24 cables are the edges of the 8 cable triangles (:data:`SIX_BAR_FACES`), one triangle per
    octant: face ``f<sx><sy><sz>`` joins the ``sx`` end of the ``x`` bar at ``z = sz a``, the
    ``sy`` end of the ``y`` bar at ``x = sx a`` and the ``sz`` end of the ``z`` bar at
    ``y = sy a``; its cables are ``<face>_xy``, ``<face>_yz`` and ``<face>_zx`` by the two bars
    they join (``f+-+_xy``; :func:`face_cables`).  The robot rolls from one such face to the
    next.  Nodes and rods as :func:`octahedron`'s (nodes ``2r, 2r+1`` the ``-`` and ``+`` ends of
    rod ``r``; rods: ``x`` bars at ``z = -a, +a``, ``y`` bars at ``x = -a, +a``, ``z`` bars at
    ``y = -a, +a``), every shell cable at tension ``tension`` [N].

    Parameters
    ----------
    rod_length : float
        [m].  rod_mass : [kg].  stiffness : cable stiffness [N/m].  damping : cable [N s/m].
    tension : float
        Tension of every shell cable in the prestress [N].
    actuated : str or sequence of str
        The actuated cables: names or ``fnmatch`` patterns, comma-separated text or a sequence
        (``"f+++_*,f---_*"``: two opposite faces); ``"all"`` (default) is the 24 shell cables.
        The others' names end in :data:`PASSIVE`; :func:`actuated_cables` lists the actuated.
    payload_mass : float, optional
        A point mass [kg] at the centre (node 12), tied to every node ``k`` by a cable
        ``payload_<k>`` (passive unless ``actuated`` names it).  The bars then move closer to
        the centre, to the offset ``a < L/4`` at which the radial cables balance the shell (all
        shell cables still equal), and the rest lengths realize that self-stress.  Default: none
        (``a = L/4``, cables ``sqrt(6)/4 L``).
    payload_stiffness : float, optional
        Payload cable stiffness [N/m], default ``stiffness``; only with ``payload_mass``.
    payload_tension : float, optional
        Payload cable tension in the prestress [N], default ``tension``; only with
        ``payload_mass``.

    Raises
    ------
    ValueError
        Naming the keyword: a value not > 0, a payload keyword without ``payload_mass``, an
        ``actuated`` pattern that matches no cable.
    """
    from tensegrity.analysis.prestress import rest_lengths_for_tensions

    shell = octahedron(
        rod_length=rod_length,
        rod_mass=rod_mass,
        stiffness=stiffness,
        tension=tension,
        damping=damping,
    )
    p = shell.node_position
    rod_axis = np.repeat(np.arange(3), 4)  # node -> the axis its bar is parallel to
    tail, head = shell.tendon_nodes.T
    octant = np.sign(p[tail] + p[head]).astype(int)  # the face a cable belongs to
    names = [
        "f"
        + "".join("-+"[(sign + 1) // 2] for sign in octant[k])
        + "_"
        + _FACE_EDGES[frozenset((rod_axis[tail[k]], rod_axis[head[k]]))]
        for k in range(shell.n_tendons)
    ]
    robot = shell.replace(tendon_name=names)
    if payload_mass is None:
        for name, value in (
            ("payload_stiffness", payload_stiffness),
            ("payload_tension", payload_tension),
        ):
            if value is not None:
                raise ValueError(f"{name}: only with payload_mass, got {value!r}")
        return _actuated(robot, actuated, "f*")
    mass = _positive(payload_mass, "payload_mass")
    k_p = _positive(
        stiffness if payload_stiffness is None else payload_stiffness, "payload_stiffness"
    )
    T = float(tension)  # checked by octahedron()
    T_p = _positive(tension if payload_tension is None else payload_tension, "payload_tension")
    L = float(shell.rod_length[0])
    offset = np.isclose(np.abs(p), L / 4, rtol=1e-12)  # each node's coordinate across its bar
    position = np.vstack(
        [np.where(offset, p * _payload_offset(L, T, T_p) / (L / 4), p), np.zeros(3)]
    )
    n = shell.n_nodes
    radial = _pairs(np.full(n, n), np.arange(n))
    cables = np.vstack([shell.tendon_nodes, radial])
    draft = from_connectivity(
        position.T,
        incidence(shell.rod_nodes, n + 1),
        incidence(cables, n + 1),
        rod_mass=shell.rod_mass,
        tendon_stiffness=np.concatenate([shell.tendon_stiffness, np.full(n, k_p)]),
        tendon_prestrain=0.0,
        tendon_damping=np.concatenate([shell.tendon_damping, np.full(n, shell.tendon_damping[0])]),
        tendon_name=(*names, *(f"payload_{k}" for k in range(n))),
        node_point_mass=np.append(np.zeros(n), mass),
    )
    rest, _ = rest_lengths_for_tensions(
        draft, None, np.concatenate([np.full(shell.n_tendons, T), np.full(n, T_p)])
    )
    return _actuated(draft.replace(tendon_rest_length=rest), actuated, "f*")


#: Tendon names of :func:`three_bar_robot` by the prefix of :func:`prism_members`' names.
_THREE_BAR_CABLES = {"b": "bottom", "t": "top", "s": "side"}


def three_bar_robot(
    *,
    rod_length: float = 1.0,
    rod_mass: float = 1.0,
    height: float | None = None,
    stiffness: float = 100.0,
    tension: float = 5.0,
    damping: float = 0.0,
    actuated: str | tuple[str, ...] = "all",
) -> Structure:
    """The three-bar robot: the simplex (:func:`prism` ``(3)``) with named cables.

    Cables ``bottom_i`` (bottom ring, node ``i`` -> ``i+1``), ``top_i`` (top ring, node ``3+i``
    -> ``3+(i+1)``) and ``side_i`` (bottom node ``i`` -> top node ``3+(i-1)``), ``i = 0, 1, 2``
    mod 3; bar ``i`` joins bottom node ``i`` to top node ``3+i``.  Geometry, prestress and the
    keywords as :func:`prism`'s.

    Parameters
    ----------
    actuated : str or sequence of str
        The actuated cables: names or ``fnmatch`` patterns, comma-separated text or a sequence
        (``"side_*"``: the three side cables); ``"all"`` (default) is all nine.  The others'
        names end in :data:`PASSIVE`; :func:`actuated_cables` lists the actuated.
    """
    simplex = prism(
        3,
        rod_length=rod_length,
        rod_mass=rod_mass,
        height=height,
        stiffness=stiffness,
        tension=tension,
        damping=damping,
    )
    names = tuple(f"{_THREE_BAR_CABLES[n[0]]}_{n[1:]}" for n in simplex.tendon_name)
    return _actuated(simplex.replace(tendon_name=names), actuated, "*")


# ------------------------------------------------------------------------------ registry
class Kind(NamedTuple):
    """A registered generator: the function that builds the structure and a one-line summary."""

    function: Callable[..., Any]
    summary: str


#: Generator kinds of ``tensegrity export --kind``: name -> Kind.
KINDS: dict[str, Kind] = {
    "shell": Kind(class1_shell, "the paper's class 1 shell of n x m two-rod elements"),
    "prism": Kind(prism, "regular n-bar prism (n = 3: simplex), equilibrium twist"),
    "octahedron": Kind(octahedron, "6-bar expanded octahedron"),
    "tower": Kind(tower, "m stacked interlaced n-bar prisms (Needle Tower)"),
    "six-bar": Kind(six_bar_robot, "six-bar robot: expanded octahedron, named faces, payload"),
    "three-bar": Kind(three_bar_robot, "three-bar robot: simplex with named actuated cables"),
    "class2-shell": Kind(class2_shell, "the class 2 shell of Lemma 18.1 (ball joints)"),
    "planar": Kind(planar_two_rod, "planar two-rod tensegrity (Appendix A, Example 2)"),
    "rod": Kind(planar_rod, "a single planar rod (Appendix A, Example 1)"),
}


def register(kind: str, function: Callable[..., Any] | str, summary: str) -> None:
    """Register ``function`` (a callable, or ``"module:function"``, imported now) under ``kind``."""
    if not kind or not isinstance(kind, str):
        raise ValueError(f"kind: must be a non-empty string, got {kind!r}")
    if isinstance(function, str):
        module, _, name = function.partition(":")
        function = getattr(importlib.import_module(module), name)
    if not callable(function):
        raise TypeError(f"function: expected a callable or 'module:function', got {function!r}")
    KINDS[kind] = Kind(function, summary)


def generator(kind: str) -> Callable[..., Any]:
    """The function registered under ``kind`` (``ValueError`` listing the kinds if unknown)."""
    if kind not in KINDS:
        raise ValueError(f"kind: unknown {kind!r} (expected one of {', '.join(KINDS)})")
    return KINDS[kind].function


def options(kind: str) -> tuple[str, ...]:
    """The keyword options the generator of ``kind`` accepts."""
    parameters = inspect.signature(generator(kind)).parameters.values()
    return tuple(p.name for p in parameters if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD))


def generate(kind: str, **kwargs: Any) -> Any:
    """Call the generator of ``kind`` with ``kwargs``; an unknown option names the valid ones."""
    valid = options(kind)
    for name in kwargs:
        if name not in valid:
            raise ValueError(
                f"{name}: not an option of kind {kind!r} (its options: {', '.join(valid)})"
            )
    return generator(kind)(**kwargs)
