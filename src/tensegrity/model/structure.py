"""The immutable model of a class 1 tensegrity structure: topology and parameters.

A :class:`Structure` plays the part of MuJoCo's ``MjModel``: it holds everything that does not
change during a simulation (node layout at rest, rods, tendons and their parameters) as flat,
read-only NumPy arrays named ``<object>_<property>``.  The time-varying state lives in
:class:`tensegrity.physics.dynamics.State`.

Conventions (SI units throughout)
---------------------------------
- ``N`` nodes, ``R`` rods, ``S`` tendons (strings).
- Rod ``r`` joins nodes ``rod_nodes[r] = (a, b)``; its vector is ``r = p_b - p_a`` (the paper's
  ``r_1ij = p_2ij - p_1ij``).  In a class 1 structure every node belongs to exactly one rod.
- Tendon ``s`` joins ``tendon_nodes[s] = (tail, head)``; its vector is ``t = p_head - p_tail``
  (the paper's tendon vector, head minus tail).  Its tension pulls both ends toward each other.
- Supports and joints (``docs/constraints.md``): a node may be fixed to ground (``node_fixed``),
  held on a plane (``plane_nodes``, ``plane_normal``) or a line (``line_nodes``,
  ``line_direction``) through its initial position, or joined to another node by a ball joint
  (``joint_nodes``: rods that share a node, class 2 and class k).  A node that belongs to no rod
  is either fixed (an anchor, e.g. a tendon's attachment point in space) or a point mass
  (``node_point_mass``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from tensegrity.model.limits import environment_limit

if TYPE_CHECKING:
    import scipy.sparse as sp

#: Relative tolerance on ``| |p_b - p_a| - L | / L`` accepted for the node positions of a rod.
ROD_LENGTH_RTOL = 1e-6
#: Tolerance on the distance between joined nodes, relative to the longest rod.
JOINT_RTOL = 1e-6

#: The default of an optional :class:`Structure` field: "not given".  ``__post_init__`` replaces
#: it by the field's filled-in value, so the field is typed as that value (typed ``Any`` here so
#: that a ``None`` default fits the field's type; the constructor's own signature, for type
#: checkers, says which arguments may be ``None``).
_NOT_GIVEN: Any = None


def _shown(value: Any) -> str:
    """``repr(value)`` for a message: on one line (a NumPy array's repr has several), at most 80
    characters."""
    return " ".join(repr(value).split())[:80]


def _readonly(array: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


def _float_array(value: Any, field: str, shape: tuple[int | None, ...]) -> np.ndarray:
    """Convert ``value`` to a finite float array of the given shape (``None`` = any length);
    complex numbers are refused (NumPy would drop their imaginary parts)."""
    try:
        complex_ = np.iscomplexobj(value)
    except (TypeError, ValueError):  # a ragged list: refused below
        complex_ = False
    if complex_:
        raise ValueError(f"{field}: expected real numbers, got complex {_shown(value)}")
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{field}: expected numbers, got {_shown(value)}") from exc
    if array.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(array.shape, shape, strict=True)
    ):
        pretty = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{field}: expected shape {pretty}, got {array.shape}")
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        index = ",".join(str(i) for i in bad[0])
        raise ValueError(f"{field}[{index}]: must be finite, got {array[tuple(bad[0])]}")
    return array


def _index_array(value: Any, field: str, n_nodes: int) -> np.ndarray:
    """Convert ``value`` to an ``(n, 2)`` int array of node indices in ``[0, n_nodes)``."""
    try:
        array = np.array(value)
    except (TypeError, ValueError):
        raise ValueError(f"{field}: expected shape (n, 2) of node indices") from None
    if array.size == 0:
        array = array.reshape(0, 2)
    if array.ndim != 2 or array.shape[1] != 2:
        raise ValueError(f"{field}: expected shape (n, 2) of node indices, got {array.shape}")
    if array.dtype.kind not in "biuf" or not (
        np.issubdtype(array.dtype, np.integer) or np.all(np.mod(array, 1) == 0)
    ):
        raise ValueError(f"{field}: node indices must be integers")
    array = array.astype(np.int64)
    for k, (a, b) in enumerate(array):
        for node in (a, b):
            if not 0 <= node < n_nodes:
                raise ValueError(f"{field}[{k}]: node index {node} out of range [0, {n_nodes - 1}]")
        if a == b:
            raise ValueError(f"{field}[{k}]: joins node {a} to itself")
    return array


def _check_sign(
    label: Callable[[int], str], field: str, values: np.ndarray, *, strict: bool
) -> None:
    """Raise ``{label(k)}.{field}: must be > 0`` (``>= 0`` unless ``strict``) for the first
    element ``k`` of ``values`` that is not."""
    bad = np.flatnonzero(values <= 0 if strict else values < 0)
    if bad.size:
        k = bad[0]
        raise ValueError(
            f"{label(k)}.{field}: must be {'>' if strict else '>='} 0, got {values[k]}"
        )


def _check_rod_lengths(position: np.ndarray, rod_nodes: np.ndarray, rod_length: np.ndarray) -> None:
    """Raise unless the nodes (N, d) [m] of each rod (R, 2) are its length (R,) [m] apart, to
    within ``ROD_LENGTH_RTOL``."""
    distance = np.linalg.norm(position[rod_nodes[:, 1]] - position[rod_nodes[:, 0]], axis=1)
    bad = np.flatnonzero(np.abs(distance - rod_length) > ROD_LENGTH_RTOL * rod_length)
    if bad.size:
        r = bad[0]
        raise ValueError(
            f"rods[{r}].length: is {float(rod_length[r])!r} m but nodes {rod_nodes[r, 0]} and "
            f"{rod_nodes[r, 1]} are {float(distance[r])!r} m apart (relative tolerance "
            f"{ROD_LENGTH_RTOL:g})"
        )


def _check_tendon_pairs(tendon_nodes: np.ndarray, names: Sequence[str]) -> None:
    """Raise if two tendons (S, 2) join the same two nodes (either way round)."""
    pairs: dict[tuple[int, int], int] = {}
    for k, (a, b) in enumerate(tendon_nodes):
        key = (min(a, b), max(a, b))
        if key in pairs:
            raise ValueError(
                f"tendons[{k}] ({names[k]!r}).nodes: joins nodes {a} and {b}, as does "
                f"tendons[{pairs[key]}] ({names[pairs[key]]!r})"
            )
        pairs[key] = k


def _checked_names(given: Any, count: int, field: str, items: str, prefix: str) -> tuple[str, ...]:
    """The names ``given`` of ``count`` tendons or nodes (default ``f"{prefix}0"``,
    ``f"{prefix}1"``, ...), checked: one non-empty string each, no two alike, no NUL character.
    Errors name the argument ``field`` (``tendon_name``) or an element ``{items}[k].name``
    (``tendons[3].name``; ``node_name[3]`` for ``items`` ``"node_name"``)."""
    if isinstance(given, (str, bytes)):  # (not a sequence of one-letter names)
        raise ValueError(f"{field}: expected a sequence of names, got the text {_shown(given)}")
    whole = f"{items}.name" if items != field else field
    try:
        names = tuple(f"{prefix}{k}" for k in range(count)) if given is None else tuple(given)
    except TypeError:
        raise ValueError(f"{whole}: expected {count} names, got {_shown(given)}") from None
    if len(names) != count:
        raise ValueError(f"{whole}: expected {count} names, got {len(names)}")
    seen: dict[str, int] = {}
    for k, name in enumerate(names):
        where = f"{items}[{k}]" + (".name" if items != field else "")
        if not isinstance(name, str) or not name:
            raise ValueError(f"{where}: must be a non-empty string, got {_shown(name)}")
        if "\x00" in name:  # .npz and HDF5 text ends at one (the name would not read back)
            raise ValueError(f"{where}: must not contain a NUL character, got {name!r}")
        if name in seen:
            other = f"{items}[{seen[name]}]"
            raise ValueError(f"{where}: {name!r} is also the name of {other}")
        seen[name] = k
    return names


def require_structure(value: Any, argument: str = "structure") -> None:
    """Raise ``TypeError`` naming ``argument`` unless ``value`` is a :class:`Structure`: at the
    call of a function that takes one, not as an ``AttributeError`` deep inside it."""
    if not isinstance(value, Structure):
        raise TypeError(f"{argument}: expected a Structure, got {type(value).__name__}")


#: Environment variable: the most members (rods + tendons) a generator builds.
MAX_MEMBERS_VARIABLE = "TENSEGRITY_MAX_MEMBERS"
#: The limit when the variable is not set: about 10 GB of model and run buffers.
DEFAULT_MAX_MEMBERS = 10_000_000


def check_member_count(members: int, what: str) -> None:
    """Refuse, before building anything, a generated structure of more than the limit of
    members (``TENSEGRITY_MAX_MEMBERS``, default :data:`DEFAULT_MAX_MEMBERS`): a size typed by
    mistake (``--n 1000000000``) otherwise runs until memory runs out.

    Parameters
    ----------
    members : int
        The members the generator would build (an upper bound will do).
    what : str
        The request, as the message names it: ``"n = 1000000000, m = 1"``.

    Raises
    ------
    ValueError
        One line with the number, the limit and how to raise it.
    """
    limit = environment_limit(MAX_MEMBERS_VARIABLE, DEFAULT_MAX_MEMBERS)
    if members > limit:
        raise ValueError(
            f"{what}: about {members:,} members (rods and tendons), more than the limit of "
            f"{limit:,}; set {MAX_MEMBERS_VARIABLE} to a larger number to build it"
        )


@dataclasses.dataclass(frozen=True, eq=False)
class Structure:
    """A class 1 tensegrity structure (rigid rods, elastic tendons), validated at construction.

    Parameters
    ----------
    node_position : array_like, shape (N, 3)
        Node positions of the initial configuration [m].
    rod_nodes : array_like of int, shape (R, 2)
        Node indices ``(a, b)`` of each rod; the rod vector is ``p_b - p_a``.
    rod_mass : array_like, shape (R,)
        Rod masses [kg], > 0.  Mass is uniform along the rod (inertia ``m L^2 / 12``).
    rod_length : array_like, shape (R,)
        Rod lengths [m], > 0.  ``node_position`` must agree to within ``ROD_LENGTH_RTOL``.
    tendon_nodes : array_like of int, shape (S, 2)
        Node indices ``(tail, head)`` of each tendon; the tendon vector is ``p_head - p_tail``.
    tendon_stiffness : array_like, shape (S,)
        Axial stiffness ``k`` [N/m], > 0.
    tendon_rest_length : array_like, shape (S,)
        Rest length ``L0`` before control [m], >= 0.
    tendon_damping : array_like, shape (S,), optional
        Viscous damping ``c`` [N s/m], >= 0, acting only while the tendon is taut.  Default 0.
    tendon_name : sequence of str, optional
        Unique tendon names.  Default ``"s0", "s1", ...``.
    node_velocity : array_like, shape (N, 3), optional
        Initial node velocities [m/s].  Default zero.
    rod_damping : array_like, shape (R,), optional
        Mass-proportional ("artificial", to ground) damping rate ``alpha`` [1/s], >= 0: adds
        ``-alpha q'`` to the rod's accelerations, i.e. a force ``-alpha dm v`` on every mass
        element.  It drags the structure against the world frame (a free fall settles at
        ``g / alpha``).  Default 0.
    rod_relative_damping : array_like, shape (R,), optional
        Mass-proportional damping rate ``beta`` [1/s], >= 0, of each rod's motion *relative to
        the structure's rigid-body motion*: a force ``-beta dm (v - v_rigid)`` on every mass
        element, ``v_rigid`` the rigid-body velocity field that best fits the damped rods'
        motion (weights ``beta m``), so that it removes deformation only: it conserves linear and
        angular momentum, and a free fall or a spin goes on undamped.  A structure held by
        supports (fixed nodes, plane or line nodes) is damped relative to the ground instead
        (``physics.coordinates.rod_damping_rates``).  Default 0.
    node_fixed : array_like of bool, shape (N,), optional
        Nodes held at their ``node_position`` (supports; anchors of tendons).  Default none.
    node_point_mass : array_like, shape (N,), optional
        Mass [kg] of a point mass at each node that belongs to no rod and is not fixed (> 0
        there, 0 elsewhere).  Default 0.
    joint_nodes : array_like of int, shape (J, 2), optional
        Pairs of nodes held together by a ball joint (they must coincide initially); a node
        shared by ``k`` rods is ``k - 1`` pairs.  Default none.
    plane_nodes : array_like of int, shape (P,), optional
        Nodes held on the plane through their initial position with normal ``plane_normal``
        (P, 3) (any length, not zero).
    line_nodes : array_like of int, shape (Q,), optional
        Nodes held on the line through their initial position along ``line_direction`` (Q, 3).
    node_name : sequence of str, shape (N,), optional
        Unique node names (loads and files refer to nodes by them, :meth:`node_index`).
        Default ``"n0", "n1", ...``.

    Raises
    ------
    ValueError
        Naming the field and element, e.g. ``tendons[3] ('t5_1_1').stiffness: must be > 0``.
    """

    # The fields have the types of the validated, read-only values ``__post_init__`` stores; the
    # constructor takes any array_like (see its signature below, for type checkers).
    node_position: npt.NDArray[np.float64]
    rod_nodes: npt.NDArray[np.int64]
    rod_mass: npt.NDArray[np.float64]
    rod_length: npt.NDArray[np.float64]
    tendon_nodes: npt.NDArray[np.int64]
    tendon_stiffness: npt.NDArray[np.float64]
    tendon_rest_length: npt.NDArray[np.float64]
    tendon_damping: npt.NDArray[np.float64] = _NOT_GIVEN
    tendon_name: tuple[str, ...] = _NOT_GIVEN
    node_velocity: npt.NDArray[np.float64] = _NOT_GIVEN
    rod_damping: npt.NDArray[np.float64] = _NOT_GIVEN
    rod_relative_damping: npt.NDArray[np.float64] = _NOT_GIVEN
    node_fixed: npt.NDArray[np.bool_] = _NOT_GIVEN
    node_point_mass: npt.NDArray[np.float64] = _NOT_GIVEN
    joint_nodes: npt.NDArray[np.int64] = _NOT_GIVEN
    plane_nodes: npt.NDArray[np.int64] = _NOT_GIVEN
    plane_normal: npt.NDArray[np.float64] = _NOT_GIVEN
    line_nodes: npt.NDArray[np.int64] = _NOT_GIVEN
    line_direction: npt.NDArray[np.float64] = _NOT_GIVEN
    node_name: tuple[str, ...] = _NOT_GIVEN

    if TYPE_CHECKING:
        # The signature of the generated ``__init__`` as the caller sees it: the arguments are
        # array_like, not yet the arrays the fields hold, and the optional ones may be None.

        def __init__(
            self,
            node_position: npt.ArrayLike,
            rod_nodes: npt.ArrayLike,
            rod_mass: npt.ArrayLike,
            rod_length: npt.ArrayLike,
            tendon_nodes: npt.ArrayLike,
            tendon_stiffness: npt.ArrayLike,
            tendon_rest_length: npt.ArrayLike,
            tendon_damping: npt.ArrayLike | None = None,
            tendon_name: Sequence[str] | None = None,
            node_velocity: npt.ArrayLike | None = None,
            rod_damping: npt.ArrayLike | None = None,
            rod_relative_damping: npt.ArrayLike | None = None,
            node_fixed: npt.ArrayLike | None = None,
            node_point_mass: npt.ArrayLike | None = None,
            joint_nodes: npt.ArrayLike | None = None,
            plane_nodes: npt.ArrayLike | None = None,
            plane_normal: npt.ArrayLike | None = None,
            line_nodes: npt.ArrayLike | None = None,
            line_direction: npt.ArrayLike | None = None,
            node_name: Sequence[str] | None = None,
        ) -> None: ...

    def __post_init__(self) -> None:
        # Until the end of ``__post_init__``, the fields hold the arguments as given (array_like,
        # or None for an optional one): the ``_check*`` methods read them as such.
        position, velocity = self._checked_positions()
        n_nodes = position.shape[0]
        rod_nodes, rod_mass, rod_length, rod_damping, rod_relative_damping = self._checked_rods(
            n_nodes
        )
        fixed, point_mass = self._check_nodes(rod_nodes, n_nodes)
        _check_rod_lengths(position, rod_nodes, rod_length)
        tendon_nodes = _index_array(self.tendon_nodes, "tendons", n_nodes)
        names = _checked_names(
            self.tendon_name, tendon_nodes.shape[0], "tendon_name", "tendons", "s"
        )
        node_names = _checked_names(self.node_name, n_nodes, "node_name", "node_name", "n")
        _check_tendon_pairs(tendon_nodes, names)
        stiffness, rest_length, damping = self._checked_tendon_parameters(names)

        def set_(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        for name, value in (
            ("node_position", position),
            ("node_velocity", velocity),
            ("rod_nodes", rod_nodes),
            ("rod_mass", rod_mass),
            ("rod_length", rod_length),
            ("rod_damping", rod_damping),
            ("rod_relative_damping", rod_relative_damping),
            ("tendon_nodes", tendon_nodes),
            ("tendon_stiffness", stiffness),
            ("tendon_rest_length", rest_length),
            ("tendon_damping", damping),
            ("node_fixed", fixed),
            ("node_point_mass", point_mass),
        ):
            set_(name, _readonly(value))
        set_("tendon_name", names)
        set_("node_name", node_names)
        self._set_constraints(position, set_)

    def _checked_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """``(node_position, node_velocity)``, (N, 3) [m] and [m/s] ((N, 2) if planar), checked:
        at least one node, finite numbers; velocities default to zero."""
        try:
            shape = np.shape(self.node_position)
        except ValueError:  # a ragged list: _float_array names it
            shape = ()
        dim = shape[1] if len(shape) == 2 and shape[1] == 2 else 3  # 2: a planar structure
        position = _float_array(self.node_position, "nodes", (None, dim))
        n_nodes = position.shape[0]
        if n_nodes == 0:
            raise ValueError("nodes: a structure needs at least one node")
        velocity = (
            np.zeros_like(position)
            if self.node_velocity is None
            else _float_array(self.node_velocity, "velocities", (n_nodes, dim))
        )
        return position, velocity

    def _checked_rods(self, n_nodes: int) -> tuple[np.ndarray, ...]:
        """``(rod_nodes (R, 2), rod_mass [kg], rod_length [m], rod_damping [1/s],
        rod_relative_damping [1/s])``, checked: nodes in range, masses and lengths > 0, damping
        rates >= 0 (default 0)."""
        rod_nodes = _index_array(self.rod_nodes, "rods", n_nodes)
        n_rods = rod_nodes.shape[0]
        rod_mass = _float_array(self.rod_mass, "rods.mass", (n_rods,))
        rod_length = _float_array(self.rod_length, "rods.length", (n_rods,))
        rod_damping, rod_relative_damping = (
            _float_array(np.zeros(n_rods) if given is None else given, f"rods.{field}", (n_rods,))
            for given, field in (
                (self.rod_damping, "damping"),
                (self.rod_relative_damping, "relative_damping"),
            )
        )
        for field, values, strict in (
            ("mass", rod_mass, True),
            ("length", rod_length, True),
            ("damping", rod_damping, False),
            ("relative_damping", rod_relative_damping, False),
        ):
            _check_sign(lambda r: f"rods[{r}]", field, values, strict=strict)
        return rod_nodes, rod_mass, rod_length, rod_damping, rod_relative_damping

    def _checked_tendon_parameters(
        self, names: tuple[str, ...]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(stiffness [N/m], rest_length [m], damping [N s/m])`` of the tendons ``names``,
        checked: stiffness > 0, rest length and damping >= 0 (damping default 0)."""
        n_tendons = len(names)
        stiffness = _float_array(self.tendon_stiffness, "tendons.stiffness", (n_tendons,))
        rest_length = _float_array(self.tendon_rest_length, "tendons.rest_length", (n_tendons,))
        damping = _float_array(
            np.zeros(n_tendons) if self.tendon_damping is None else self.tendon_damping,
            "tendons.damping",
            (n_tendons,),
        )
        for field, values, strict in (
            ("stiffness", stiffness, True),
            ("rest_length", rest_length, False),
            ("damping", damping, False),
        ):
            _check_sign(lambda k: f"tendons[{k}] ({names[k]!r})", field, values, strict=strict)
        return stiffness, rest_length, damping

    def _check_nodes(self, rod_nodes: np.ndarray, n_nodes: int) -> tuple[np.ndarray, np.ndarray]:
        """Every node is the end of at most one rod (joints are explicit, ``joint_nodes``), and
        a node of no rod is fixed or carries a point mass.  Returns ``(node_fixed,
        node_point_mass)``."""
        owner = np.full(n_nodes, -1)
        for r, (a, b) in enumerate(rod_nodes):
            for node in (a, b):
                if owner[node] >= 0:
                    raise ValueError(
                        f"rods[{r}].nodes: node {node} is already an end of rods[{owner[node]}] "
                        "(every node belongs to one rod; rods that share a node are joined "
                        "nodes, joint_nodes)"
                    )
                owner[node] = r
        if self.node_fixed is None:
            fixed = np.zeros(n_nodes, bool)
        else:
            try:
                fixed = np.array(self.node_fixed)
            except (TypeError, ValueError):  # (ragged: numpy's "inhomogeneous shape")
                fixed = np.array(None)
            if fixed.shape != (n_nodes,) or fixed.dtype != bool:
                raise ValueError(
                    f"node_fixed: expected {n_nodes} booleans, got {fixed.dtype} of shape "
                    f"{fixed.shape}"
                )
        point_mass = _float_array(
            np.zeros(n_nodes) if self.node_point_mass is None else self.node_point_mass,
            "node_point_mass",
            (n_nodes,),
        )
        in_rod = owner >= 0
        for rule, message in (
            (point_mass < 0, "node_point_mass[{k}]: must be >= 0, got {m}"),
            (
                (point_mass > 0) & in_rod,
                "node_point_mass[{k}]: node {k} is an end of rods[{r}]; a payload on a rod goes on "
                "its own node, joined to the rod's end (joint_nodes)",
            ),
            (
                (point_mass > 0) & fixed,
                "node_point_mass[{k}]: node {k} is fixed; it cannot carry a mass",
            ),
            (
                ~in_rod & ~fixed & (point_mass == 0),
                "nodes[{k}]: belongs to no rod; fix it (node_fixed) or give it a mass "
                "(node_point_mass): a massless free node has no dynamics",
            ),
        ):
            bad = np.flatnonzero(rule)
            if bad.size:
                k = bad[0]
                raise ValueError(message.format(k=k, m=point_mass[k], r=owner[k]))
        return fixed, point_mass

    def _set_constraints(self, position: np.ndarray, set_: Callable[[str, Any], None]) -> None:
        """Validate and store ``joint_nodes`` and the plane and line constraints."""
        n_nodes, dim = position.shape
        joints = _index_array(
            np.zeros((0, 2), int) if self.joint_nodes is None else self.joint_nodes,
            "joint_nodes",
            n_nodes,
        )
        gap = np.linalg.norm(position[joints[:, 1]] - position[joints[:, 0]], axis=1)
        scale = max(float(self.rod_length.max(initial=0.0)), 1.0)
        bad = np.flatnonzero(gap > JOINT_RTOL * scale)
        if bad.size:
            k = bad[0]
            raise ValueError(
                f"joint_nodes[{k}]: nodes {joints[k, 0]} and {joints[k, 1]} are "
                f"{float(gap[k])!r} m apart; joined nodes must coincide"
            )
        set_("joint_nodes", _readonly(joints))
        for kind, vector in (("plane", "normal"), ("line", "direction")):
            nodes_field, vector_field = f"{kind}_nodes", f"{kind}_{vector}"
            given = getattr(self, nodes_field)
            try:
                nodes = np.array([] if given is None else given)
            except (TypeError, ValueError):  # (ragged: numpy's "inhomogeneous shape")
                raise ValueError(
                    f"{nodes_field}: expected a list of node indices, got {_shown(given)}"
                ) from None
            if nodes.ndim != 1 or (nodes.size and not np.issubdtype(nodes.dtype, np.integer)):
                raise ValueError(
                    f"{nodes_field}: expected a list of node indices, got {_shown(nodes)}"
                )
            nodes = nodes.astype(np.int64)
            bad = np.flatnonzero((nodes < 0) | (nodes >= n_nodes))
            if bad.size:
                raise ValueError(
                    f"{nodes_field}[{bad[0]}]: node index {nodes[bad[0]]} out of range "
                    f"[0, {n_nodes - 1}]"
                )
            if nodes.size and kind == "plane" and dim == 2:
                raise ValueError(
                    f"{nodes_field}: a planar structure has no plane constraints "
                    "(hold a node on a line with line_nodes)"
                )
            value = getattr(self, vector_field)
            vectors = _float_array(
                np.zeros((0, dim)) if value is None else value, vector_field, (nodes.size, dim)
            )
            norm = np.linalg.norm(vectors, axis=1)
            bad = np.flatnonzero(norm == 0)
            if bad.size:
                raise ValueError(f"{vector_field}[{bad[0]}]: must not be zero")
            # A vector already of unit length (to rounding: a normalized vector's norm is within
            # 2 ulp of 1) is kept as it is, so that a structure read back is bit for bit the one
            # written (normalizing again would move a unit vector by an ulp).
            norm[np.abs(norm - 1.0) <= 4 * np.finfo(float).eps] = 1.0
            set_(nodes_field, _readonly(nodes))
            set_(vector_field, _readonly(vectors / norm[:, None]))

    # ------------------------------------------------------------------ sizes
    @property
    def n_nodes(self) -> int:
        """Number of nodes ``N``."""
        return self.node_position.shape[0]

    @property
    def n_rods(self) -> int:
        """Number of rods ``R``."""
        return self.rod_nodes.shape[0]

    @property
    def n_tendons(self) -> int:
        """Number of tendons ``S``."""
        return self.tendon_nodes.shape[0]

    @cached_property
    def dim(self) -> int:
        """Space dimension: 3, or 2 for a planar structure (Appendix A's planar form)."""
        return self.node_position.shape[1]

    @property
    def n_coordinates(self) -> int:
        """Length of the generalized coordinate vector ``q``: ``6 R`` (``12 nm`` for a shell),
        plus 3 per point mass (``4 R + 2 M`` in 2-D)."""
        return self.dim * (2 * self.n_rods + self.point_mass_nodes.size)

    @property
    def n_dof(self) -> int:
        """Degrees of freedom before constraints: 5 per rod (spin about a rod's own axis is not
        one) and 3 per point mass; 3 and 2 in 2-D."""
        return (2 * self.dim - 1) * self.n_rods + self.dim * self.point_mass_nodes.size

    @cached_property
    def point_mass_nodes(self) -> np.ndarray:
        """Nodes that carry a point mass, ascending, shape (M,); their positions follow the
        rods' coordinates in ``q``."""
        return _readonly(np.flatnonzero(self.node_point_mass > 0))

    @cached_property
    def anchor_nodes(self) -> np.ndarray:
        """Fixed nodes that belong to no rod (not in ``q``: they never move), shape (F,)."""
        in_rod = np.zeros(self.n_nodes, bool)
        in_rod[self.rod_nodes] = True
        return _readonly(np.flatnonzero(self.node_fixed & ~in_rod))

    @cached_property
    def is_free_class1(self) -> bool:
        """True for a 3-D class 1 structure without supports, joints or point masses: every
        node the end of exactly one rod, ``q`` the rods' coordinates only."""
        return self.dim == 3 and not (
            self.is_supported or self.point_mass_nodes.size or self.joint_nodes.size
        )

    @cached_property
    def is_supported(self) -> bool:
        """True if some node is fixed or held on a plane or line: the supports then hold the
        structure against (some) rigid-body motion, the ground being its reference."""
        return bool(self.node_fixed.any() or self.plane_nodes.size or self.line_nodes.size)

    @cached_property
    def has_constraints(self) -> bool:
        """True if some node is fixed to a rod's end, joined, or held on a plane or line."""
        return bool(
            self.joint_nodes.size
            or self.plane_nodes.size
            or self.line_nodes.size
            or np.any(self.node_fixed[self.rod_nodes])
        )

    def require_free_class1(self, what: str) -> None:
        """Raise ``ValueError`` if this structure is not a free class 1 structure
        (:attr:`is_free_class1`): for the parts of the library that support only those."""
        if not self.is_free_class1:
            raise ValueError(
                f"{what}: supports only free 3-D class 1 structures (every node the end of one "
                "rod; no fixed nodes, joints, plane or line constraints or point masses)"
            )

    # ------------------------------------------------------------ derived data
    @cached_property
    def tendon_incidence(self) -> sp.csr_matrix:
        """Sparse incidence ``C`` (S, N) with ``t = C p``: +1 at the head, -1 at the tail."""
        import scipy.sparse as sp  # (0.15 s to import: only for the structures that need it)

        s = np.arange(self.n_tendons)
        rows = np.concatenate([s, s])
        cols = np.concatenate([self.tendon_nodes[:, 1], self.tendon_nodes[:, 0]])
        data = np.concatenate([np.ones(self.n_tendons), -np.ones(self.n_tendons)])
        return sp.csr_matrix((data, (rows, cols)), shape=(self.n_tendons, self.n_nodes))

    @cached_property
    def tendon_incidence_transpose(self) -> sp.csr_matrix:
        """``C^T`` (N, S) in CSR form, for assembling nodal forces ``f = -C^T (T t_hat)``."""
        return self.tendon_incidence.T.tocsr()

    @cached_property
    def node_mass(self) -> np.ndarray:
        """Half of the owning rod's mass at each node, or its point mass (0 at an anchor) [kg],
        shape (N,)."""
        mass = self.node_point_mass.copy()
        mass[self.rod_nodes[:, 0]] = self.rod_mass / 2
        mass[self.rod_nodes[:, 1]] = self.rod_mass / 2
        return _readonly(mass)

    @property
    def total_mass(self) -> float:
        """Sum of rod masses and point masses [kg]."""
        return float(self.rod_mass.sum() + self.node_point_mass.sum())

    def tendon_index(self, name: str) -> int:
        """Index of the tendon called ``name``."""
        try:
            return self.tendon_name.index(name)
        except ValueError:
            raise KeyError(f"no tendon named {name!r}") from None

    def node_index(self, node: str | int) -> int:
        """Index of a node given by its name or its 0-based index.

        A name wins: ``"3"`` is the node called ``"3"`` if there is one, else node 3 (a string
        of digits is read as an index only when no node has that name); an ``int`` is an index.

        Raises
        ------
        KeyError
            One line for an unknown name or an index out of range, listing a few names.
        """
        if isinstance(node, str):
            index = self._node_number.get(node)
            if index is not None:
                return index
            if not (node.isascii() and node.isdigit()):
                shown = ", ".join(self.node_name[:5]) + (", ..." if self.n_nodes > 5 else "")
                raise KeyError(f"no node named {node!r} (the nodes are {shown})")
            number = int(node)
        elif isinstance(node, (int, np.integer)) and not isinstance(node, bool):
            number = int(node)
        else:
            raise TypeError(f"node: expected a node name or index, got {_shown(node)}")
        if not 0 <= number < self.n_nodes:
            raise KeyError(
                f"node {number} out of range [0, {self.n_nodes - 1}]"
                + (f" (and no node is named {node!r})" if isinstance(node, str) else "")
            )
        return number

    @cached_property
    def _node_number(self) -> dict[str, int]:
        """The index of each node name."""
        return {name: k for k, name in enumerate(self.node_name)}

    @cached_property
    def has_default_node_names(self) -> bool:
        """True if the nodes have the default names ``n0, n1, ...`` (files then omit them)."""
        return self.node_name == tuple(f"n{k}" for k in range(self.n_nodes))

    def replace(self, **changes: Any) -> Structure:
        """A copy with some fields changed, validated again (``dataclasses.replace``)."""
        return dataclasses.replace(self, **changes)

    def __repr__(self) -> str:
        """One short line whatever the size, as NumPy's and xarray's: the dimension, the counts
        of nodes, rods and tendons, of supports, joints and point masses (those present) and the
        total mass, e.g. ``Structure(dim=3, 6 nodes, 3 rods, 9 tendons, mass 3 kg)``."""
        counts = [
            (self.n_nodes, "node", "nodes"),
            (self.n_rods, "rod", "rods"),
            (self.n_tendons, "tendon", "tendons"),
            (int(np.count_nonzero(self.node_fixed)), "fixed node", "fixed nodes"),
            (self.point_mass_nodes.size, "point mass", "point masses"),
            (self.joint_nodes.shape[0], "joint", "joints"),
            (self.plane_nodes.size, "node on a plane", "nodes on planes"),
            (self.line_nodes.size, "node on a line", "nodes on lines"),
        ]
        shown = [
            f"{n} {one if n == 1 else many}"
            for i, (n, one, many) in enumerate(counts)
            if n or i < 3  # (nodes, rods and tendons always)
        ]
        return f"Structure(dim={self.dim}, {', '.join(shown)}, mass {self.total_mass:.4g} kg)"

    # -------------------------------------------------------------- JSON form
    def to_dict(self) -> dict[str, Any]:
        """The JSON form: ``{"nodes", "velocities", "rods", "tendons"}`` with 0-based indices,
        and, only when present, ``"node_names"`` (when not the default ``n0, n1, ...``),
        ``"fixed"`` (node indices), ``"point_masses"`` (``{"node",
        "mass"}``), ``"joints"`` (node pairs), ``"planes"`` (``{"node", "normal"}``) and
        ``"lines"`` (``{"node", "direction"}``)."""
        extra: dict[str, Any] = {}
        if not self.has_default_node_names:
            extra["node_names"] = list(self.node_name)
        if self.node_fixed.any():
            extra["fixed"] = np.flatnonzero(self.node_fixed).tolist()
        if self.point_mass_nodes.size:
            extra["point_masses"] = [
                {"node": int(k), "mass": float(self.node_point_mass[k])}
                for k in self.point_mass_nodes
            ]
        if self.joint_nodes.size:
            extra["joints"] = self.joint_nodes.tolist()
        for key, nodes, vectors, name in (
            ("planes", self.plane_nodes, self.plane_normal, "normal"),
            ("lines", self.line_nodes, self.line_direction, "direction"),
        ):
            if nodes.size:
                extra[key] = [
                    {"node": int(k), name: v.tolist()} for k, v in zip(nodes, vectors, strict=True)
                ]
        return (
            extra
            | {
                "nodes": self.node_position.tolist(),
                "velocities": self.node_velocity.tolist(),
                "rods": [
                    {
                        "nodes": [int(a), int(b)],
                        "mass": float(m),
                        "length": float(L),
                        "damping": float(c),
                        "relative_damping": float(beta),
                    }
                    for (a, b), m, L, c, beta in zip(
                        self.rod_nodes,
                        self.rod_mass,
                        self.rod_length,
                        self.rod_damping,
                        self.rod_relative_damping,
                        strict=True,
                    )
                ],
                "tendons": [
                    {
                        "name": name,
                        "nodes": [int(a), int(b)],
                        "stiffness": float(k),
                        "rest_length": float(L0),
                        "damping": float(c),
                    }
                    for name, (a, b), k, L0, c in zip(
                        self.tendon_name,
                        self.tendon_nodes,
                        self.tendon_stiffness,
                        self.tendon_rest_length,
                        self.tendon_damping,
                        strict=True,
                    )
                ],
            }
            | extra
        )

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Structure:
        """Build from the JSON form; a malformed document raises ``ValueError`` naming the key.

        Unknown keys are errors at every level, as in the network files (a typo such as
        ``"stifness"`` is not silently ignored): ``rods[0]: unknown key 'mas' (expected one of
        nodes, mass, length, damping)``.
        """
        if not isinstance(data, Mapping):
            raise ValueError(f"structure: expected a JSON object, got {type(data).__name__}")
        check_keys(data, _JSON_KEYS["structure"], "structure")
        nodes = _require(data, "nodes", "structure", Sequence)
        rods = _require(data, "rods", "structure", Sequence)
        tendons = _require(data, "tendons", "structure", Sequence)
        rows = {"nodes": nodes}
        if data.get("velocities") is not None:
            rows["velocities"] = _require(data, "velocities", "structure", Sequence)
        dim = node_dimension(nodes)
        points = {
            key: [parse_vector(row, f"{key}[{k}]", dim) for k, row in enumerate(value)]
            for key, value in rows.items()
        }
        rod_items = [_require_item(rod, f"rods[{k}]") for k, rod in enumerate(rods)]
        tendon_items = [_require_item(t, f"tendons[{k}]") for k, t in enumerate(tendons)]
        for kind, items in (("rods", rod_items), ("tendons", tendon_items)):
            for k, item in enumerate(items):
                check_keys(item, _JSON_KEYS[kind], f"{kind}[{k}]")

        return cls(
            node_position=points["nodes"] or np.zeros((0, 3)),
            node_velocity=points.get("velocities"),
            rod_nodes=_node_pairs(rod_items, "rods"),
            rod_mass=_numbers(rod_items, "rods", "mass"),
            rod_length=_numbers(rod_items, "rods", "length"),
            rod_damping=_numbers(rod_items, "rods", "damping", default=0.0),
            rod_relative_damping=_numbers(rod_items, "rods", "relative_damping", default=0.0),
            tendon_nodes=_node_pairs(tendon_items, "tendons"),
            tendon_stiffness=_numbers(tendon_items, "tendons", "stiffness"),
            tendon_rest_length=_numbers(tendon_items, "tendons", "rest_length"),
            tendon_damping=_numbers(tendon_items, "tendons", "damping", default=0.0),
            tendon_name=tuple(t.get("name", f"s{k}") for k, t in enumerate(tendon_items)),
            node_name=_names_from_dict(data, len(points["nodes"])),
            **_supports_from_dict(data, len(points["nodes"]), dim),
        )


#: The keys of the JSON form (:meth:`Structure.to_dict`), at each level.
_JSON_KEYS: dict[str, tuple[str, ...]] = {
    "structure": (
        "nodes",
        "velocities",
        "rods",
        "tendons",
        "node_names",
        "fixed",
        "point_masses",
        "joints",
        "planes",
        "lines",
    ),
    "rods": ("nodes", "mass", "length", "damping", "relative_damping"),
    "tendons": ("name", "nodes", "stiffness", "rest_length", "damping"),
    "point_masses": ("node", "mass"),
    "planes": ("node", "normal"),
    "lines": ("node", "direction"),
}


def check_keys(data: Mapping[Any, Any], allowed: Sequence[str], where: str) -> None:
    """``ValueError`` naming the first key of ``data`` not in ``allowed``: ``"<where>: unknown
    key 'mas' (expected one of nodes, mass, length, damping, relative_damping)"``."""
    for key in data:
        if key not in allowed:
            raise ValueError(
                f"{where}: unknown key {_shown(key)} (expected one of {', '.join(allowed)})"
            )


def _names_from_dict(data: Mapping[str, Any], n_nodes: int) -> tuple[str, ...] | None:
    """The optional ``"node_names"`` key of the JSON form (``None``: the default names)."""
    if data.get("node_names") is None:
        return None
    names = _require(data, "node_names", "structure", Sequence)
    if len(names) != n_nodes:
        raise ValueError(f"structure.node_names: expected {n_nodes} names, got {len(names)}")
    return tuple(names)


def _supports_from_dict(data: Mapping[str, Any], n_nodes: int, dim: int) -> dict[str, Any]:
    """The optional ``"fixed"``, ``"point_masses"``, ``"joints"``, ``"planes"``, ``"lines"``
    keys of the JSON form as :class:`Structure` fields."""
    fields: dict[str, Any] = {}
    if data.get("fixed") is not None:
        fixed = np.zeros(n_nodes, bool)
        for k, node in enumerate(_require(data, "fixed", "structure", Sequence)):
            fixed[_node_index(node, f"fixed[{k}]", n_nodes)] = True
        fields["node_fixed"] = fixed
    if data.get("point_masses") is not None:
        mass = np.zeros(n_nodes)
        items = [
            _require_item(item, f"point_masses[{k}]")
            for k, item in enumerate(_require(data, "point_masses", "structure", Sequence))
        ]
        for k, item in enumerate(items):
            check_keys(item, _JSON_KEYS["point_masses"], f"point_masses[{k}]")
            node = _node_index(
                _require(item, "node", f"point_masses[{k}]"), f"point_masses[{k}].node", n_nodes
            )
            mass[node] = parse_number(
                _require(item, "mass", f"point_masses[{k}]"), f"point_masses[{k}].mass"
            )
        fields["node_point_mass"] = mass
    if data.get("joints") is not None:
        joints = _require(data, "joints", "structure", Sequence)
        fields["joint_nodes"] = [_node_pair(pair, f"joints[{k}]") for k, pair in enumerate(joints)]
    for key, vector, prefix in (("planes", "normal", "plane"), ("lines", "direction", "line")):
        if data.get(key) is None:
            continue
        items = [
            _require_item(item, f"{key}[{k}]")
            for k, item in enumerate(_require(data, key, "structure", Sequence))
        ]
        for k, item in enumerate(items):
            check_keys(item, _JSON_KEYS[key], f"{key}[{k}]")
        fields[f"{prefix}_nodes"] = [
            _node_index(_require(item, "node", f"{key}[{k}]"), f"{key}[{k}].node", n_nodes)
            for k, item in enumerate(items)
        ]
        fields[f"{prefix}_{vector}"] = [
            parse_vector(_require(item, vector, f"{key}[{k}]"), f"{key}[{k}].{vector}", dim)
            for k, item in enumerate(items)
        ] or None
    return fields


def _node_index(value: Any, where: str, n_nodes: int) -> int:
    """A JSON integer node index in ``[0, n_nodes)``."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < n_nodes:
        raise ValueError(
            f"{where}: expected a node index in [0, {n_nodes - 1}], got {_shown(value)}"
        )
    return value


def parse_number(value: Any, where: str) -> float:
    """A JSON number (not a string, a bool or a list)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where}: expected a number, got {_shown(value)}")
    try:
        return float(value)
    except OverflowError:  # an integer beyond the floats
        raise ValueError(f"{where}: expected a number, got {_shown(value)} (too large)") from None


def node_dimension(nodes: Sequence[Any]) -> int:
    """2 if the first node of a JSON node list has two coordinates (a planar structure), else 3."""
    first = nodes[0] if len(nodes) else None
    return (
        2 if isinstance(first, Sequence) and not isinstance(first, str) and len(first) == 2 else 3
    )


def parse_vector(value: Any, where: str, dim: int) -> list[float]:
    """A JSON list of ``dim`` numbers (3, or 2 in a planar structure)."""
    if not isinstance(value, Sequence) or isinstance(value, str) or len(value) != dim:
        pretty = (
            "[x, y, z]" if dim == 3 else "[x, y] (planar, as the first node has two coordinates)"
        )
        raise ValueError(f"{where}: expected a list of {dim} numbers {pretty}, got {_shown(value)}")
    return [parse_number(x, f"{where}[{k}]") for k, x in enumerate(value)]


def _numbers(
    items: Sequence[Mapping[str, Any]], kind: str, key: str, *, default: float | None = None
) -> list[float]:
    """``item[key]`` of every item as a number; a missing key takes ``default`` or is an error."""
    values = []
    for k, item in enumerate(items):
        if key not in item and default is None:
            raise ValueError(f"{kind}[{k}]: missing key {key!r}")
        values.append(parse_number(item.get(key, default), f"{kind}[{k}].{key}"))
    return values


def _node_pairs(items: Sequence[Mapping[str, Any]], kind: str) -> Any:
    """``item["nodes"]`` of every item, checked to be two integer node indices."""
    pairs = [
        _node_pair(_require(item, "nodes", f"{kind}[{k}]"), f"{kind}[{k}].nodes")
        for k, item in enumerate(items)
    ]
    return pairs or np.zeros((0, 2), int)


def _node_pair(value: Any, where: str) -> list[int]:
    """A JSON list of two integer node indices."""
    if (
        not isinstance(value, Sequence)
        or isinstance(value, str)
        or len(value) != 2
        or any(isinstance(x, bool) or not isinstance(x, int) for x in value)
    ):
        raise ValueError(f"{where}: expected two integer node indices [a, b], got {_shown(value)}")
    if any(not 0 <= x < 2**62 for x in value):
        raise ValueError(f"{where}: node index out of range in {_shown(value)}")
    return list(value)


def _require_item(item: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(item, Mapping):
        raise ValueError(f"{where}: expected a JSON object, got {type(item).__name__}")
    return item


def _require(data: Mapping[str, Any], key: str, where: str, kind: type | None = None) -> Any:
    if key not in data:
        raise ValueError(f"{where}: missing key {key!r}")
    value = data[key]
    if kind is not None and (not isinstance(value, kind) or isinstance(value, str)):
        raise ValueError(f"{where}.{key}: expected a list, got {type(value).__name__}")
    return value
