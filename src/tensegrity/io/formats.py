"""Any network (class 1 or class k): the field's ``N, C_b, C_s`` convention, readable YAML / TOML.

Conventions (Skelton & de Oliveira, *Tensegrity Systems*, 2009, ch. 2)
----------------------------------------------------------------------
- ``N`` is the **3 x n** node matrix: column ``i`` is node ``i``'s position [m] (**2 x n**:
  a planar structure).
- ``C_b`` (bars x n) and ``C_s`` (strings x n) are connectivity matrices: row ``k`` has exactly
  one ``-1`` (the member's tail node) and one ``+1`` (its head node), zeros elsewhere, so the
  member vectors are the columns of ``B = N C_b^T`` and ``S = N C_s^T`` (head minus tail).
- Bars are the library's rods (``Structure.rod_nodes[k] = (tail, head)``), strings its tendons
  (``Structure.tendon_nodes[k] = (tail, head)``): the same orientation as
  :class:`~tensegrity.model.structure.Structure`.  A class 1 structure has every node at the end of
  exactly one bar; a node shared by ``k`` bars is a class k ball joint, which the library holds
  as joined rod ends (``Structure.joint_nodes``): :func:`from_connectivity` with
  ``ball_joints=True`` splits such a node, :func:`to_connectivity` (:func:`merge_joints`) merges
  joined nodes back into one.

File formats (:func:`read_network`, :func:`write_network`, chosen by the file's suffix)
---------------------------------------------------------------------------------------
- ``.json``: the JSON form of :meth:`Structure.to_dict`.
- ``.yaml`` / ``.yml`` and ``.toml``: the readable form of :func:`network_to_dict` (named nodes,
  shared parameters under ``defaults``, rest length or prestrain per tendon, supports).
- ``.npz``: the connectivity form, arrays ``N``, ``C_b``, ``C_s``, per-member parameters and
  supports (:data:`NPZ_ARRAYS`).
- The readable and connectivity forms are class k (joined nodes merged, supports on merged
  nodes): a structure without joints reads back identical, a jointed one with the same
  ``N, C_b, C_s``, supports and parameters in the layout of :func:`from_connectivity`.
- ``.xml`` (write only): MuJoCo MJCF (:func:`tensegrity.io.mjcf.to_mjcf`).

The scene (:class:`~tensegrity.model.ground.Scene`: the planes the rods' ends touch, their contact
radius, gravity) is not part of the structure: a JSON, YAML or TOML file may carry one under its
optional top-level ``scene`` key (:meth:`Scene.to_dict <tensegrity.model.ground.Scene.to_dict>`),
which :func:`read_scene` reads (an empty scene without it), the structure readers check and
pass over, and the writers write when given ``scene=``; the connectivity form carries none, and
MJCF writes it as MuJoCo's floor and gravity.

SI units throughout: m, kg, s, N.
"""

from __future__ import annotations

import contextlib
import json
import tomllib
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tensegrity.io.checked import ArrayKind, npz_arrays, open_npz
from tensegrity.io.files import PathLike, atomic_path, file_error, read_input, regular_file
from tensegrity.model.connectivity import (
    DEFAULT_ROD_MASS,
    DEFAULT_STIFFNESS,
    connectivity_of,
    from_connectivity,
    incidence,
    merge_joints,
    rest_from_prestrain,
)
from tensegrity.model.ground import Scene
from tensegrity.model.structure import (
    Structure,
    check_keys,
    node_dimension,
    parse_number,
    parse_vector,
)

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
#: Arrays of the connectivity file (``.npz``): name -> (required, meaning).
NPZ_ARRAYS = {
    "N": (True, "(d, n) node positions [m], one column per node (d = 3, or 2: planar)"),
    "C_b": (True, "(R, n) bar connectivity, -1 at the tail and +1 at the head of each row"),
    "C_s": (True, "(S, n) string connectivity, same rule"),
    "rod_mass": (False, f"(R,) [kg], default {DEFAULT_ROD_MASS}"),
    "rod_length": (False, "(R,) [m], default the bar's length in N"),
    "rod_damping": (False, "(R,) mass-proportional damping to ground [1/s], default 0"),
    "rod_relative_damping": (
        False,
        "(R,) mass-proportional damping relative to the rigid-body motion [1/s], default 0",
    ),
    "tendon_stiffness": (False, f"(S,) [N/m], default {DEFAULT_STIFFNESS}"),
    "tendon_rest_length": (False, "(S,) [m]; this or tendon_prestrain is required"),
    "tendon_prestrain": (False, "(S,) strain (l - L0) / L0 in N"),
    "tendon_damping": (False, "(S,) [N s/m], default 0"),
    "tendon_name": (False, "(S,) unicode names"),
    "node_name": (False, "(n,) unicode names, default n0, n1, ..."),
    "node_velocity": (False, "(d, n) [m/s], default 0"),
    "node_fixed": (False, "(n,) bool, nodes held at their position (supports, anchors)"),
    "node_point_mass": (False, "(n,) [kg], a point mass at a node (> 0), default 0"),
    "plane_nodes": (False, "(P,) int, nodes held on a plane through their position"),
    "plane_normal": (False, "(P, 3) the planes' normals"),
    "line_nodes": (False, "(Q,) int, nodes held on a line through their position"),
    "line_direction": (False, "(Q, d) the lines' directions"),
    "joint_nodes": (
        False,
        "(J, 2) int, pairs of nodes joined by a ball joint (besides shared nodes)",
    ),
}

#: Arrays of node indices in the connectivity file.
NPZ_INDEX_ARRAYS = ("plane_nodes", "line_nodes", "joint_nodes")
#: What each array of the connectivity file may hold, checked before it is read: real numbers
#: (integers too, of any width: ``C_b`` and ``C_s`` hold -1, 0 and +1), node indices (integers,
#: or floats of whole numbers), booleans, text; never complex numbers, and booleans or text only
#: where they belong.
NPZ_KINDS = {
    **{name: ArrayKind("iuf", "real numbers") for name in NPZ_ARRAYS},
    **{name: ArrayKind("iuf", "node indices") for name in NPZ_INDEX_ARRAYS},
    "node_fixed": ArrayKind("b", "booleans"),
    "tendon_name": ArrayKind("U", "text"),
    "node_name": ArrayKind("U", "text"),
}

_ROD_KEYS = ("mass", "length", "damping", "relative_damping")
_TENDON_KEYS = ("stiffness", "rest_length", "prestrain", "damping")
#: Keys of the material form (members and ``defaults``: ``material``, ``section``; the top
#: level: ``tendon_mass``, ``factors``), read by :func:`tensegrity.design.files.read_design`,
#: not here.
MATERIAL_FORM_KEYS = ("material", "section", "tendon_mass", "factors")


# -------------------------------------------------------------------- readable form
#: The support keys of the readable form whose items are ``{node, ...}``: key -> the value each
#: item carries.
_ITEM_KEYS = {"point_masses": "mass", "planes": "normal", "lines": "direction"}
#: Optional support keys of the readable form (as in :meth:`Structure.to_dict`): key -> the
#: value each ``{node, ...}`` item carries (``None``: a plain list of nodes, or of node pairs).
_SUPPORT_KEYS: dict[str, str | None] = {"fixed": None, **_ITEM_KEYS, "joints": None}


def network_to_dict(
    structure: Structure, *, keep_joints: bool = False, scene: Scene | None = None
) -> dict[str, Any]:
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
    shortest round-trip form, so reading it back is exact.  A ``scene`` (not empty) is written
    last, under ``"scene"`` (:meth:`Scene.to_dict <tensegrity.model.ground.Scene.to_dict>`).
    """
    merged = merge_joints(structure, keep_joints=keep_joints)
    names = list(merged.node_name or (f"n{i}" for i in range(merged.N.shape[1])))
    data: dict[str, Any] = {
        "format": NETWORK_FORMAT,
        "version": NETWORK_VERSION,
        "units": "SI: m, kg, s, N",
        "nodes": {name: p.tolist() for name, p in zip(names, merged.N.T, strict=True)},
    }
    if np.any(merged.node_velocity != 0):
        data["velocities"] = {
            name: v.tolist() for name, v in zip(names, merged.node_velocity.T, strict=True)
        }
    if merged.node_fixed.any():
        data["fixed"] = [names[i] for i in np.flatnonzero(merged.node_fixed)]
    for key, nodes, values in (
        (
            "point_masses",
            np.flatnonzero(merged.node_point_mass),
            merged.node_point_mass[merged.node_point_mass > 0],
        ),
        ("planes", merged.plane_nodes, merged.plane_normal),
        ("lines", merged.line_nodes, merged.line_direction),
    ):
        if nodes.size:
            data[key] = [
                {"node": names[i], _ITEM_KEYS[key]: v.tolist()}
                for i, v in zip(nodes, values, strict=True)
            ]
    if merged.joint_nodes.size:
        data["joints"] = [[names[a], names[b]] for a, b in merged.joint_nodes]
    rods, tendons = merged.node_map[structure.rod_nodes], merged.node_map[structure.tendon_nodes]
    defaults: dict[str, dict[str, float]] = {"rod": {}, "tendon": {}}
    members: dict[str, list[dict[str, Any]]] = {
        "rod": [{"nodes": [names[a], names[b]]} for a, b in rods],
        "tendon": [
            {"name": name, "nodes": [names[a], names[b]]}
            for name, (a, b) in zip(structure.tendon_name, tendons, strict=True)
        ],
    }
    columns = {
        "rod": {
            "mass": structure.rod_mass,
            "length": structure.rod_length,
            "damping": structure.rod_damping,
            "relative_damping": structure.rod_relative_damping,
        },
        "tendon": {
            "stiffness": structure.tendon_stiffness,
            "rest_length": structure.tendon_rest_length,
            "damping": structure.tendon_damping,
        },
    }
    for kind, table in columns.items():
        for key, values in table.items():
            if values.size and np.all(values == values[0]):
                defaults[kind][key] = float(values[0])
            else:
                for item, value in zip(members[kind], values, strict=True):
                    item[key] = float(value)
    data["defaults"] = {kind: table for kind, table in defaults.items() if table}
    data["rods"] = members["rod"]
    data["tendons"] = members["tendon"]
    return with_scene(data, scene)


def with_scene(data: dict[str, Any], scene: Scene | None) -> dict[str, Any]:
    """``data`` (a document of a structure file) with ``scene`` under its ``"scene"`` key, last
    (nothing for None or an empty scene)."""
    data.pop("scene", None)
    if scene is not None and scene != Scene():
        data["scene"] = scene.to_dict()
    return data


def scene_from_dict(data: Any) -> Scene:
    """The scene of a structure file's document: its ``"scene"`` key (absent or null: an empty
    scene), for a structure of the dimension of its ``nodes`` (``ValueError`` naming the key,
    :meth:`Scene.from_dict <tensegrity.model.ground.Scene.from_dict>`)."""
    if not isinstance(data, Mapping) or data.get("scene") is None:
        return Scene()
    nodes = data.get("nodes")
    rows = list(nodes.values()) if isinstance(nodes, Mapping) else nodes
    dim = node_dimension(rows) if isinstance(rows, Sequence) and not isinstance(rows, str) else 3
    return Scene.from_dict(data["scene"], dim=dim)


def network_from_dict(data: Any) -> Structure:
    """Build a structure from the readable form of :func:`network_to_dict`.

    ``nodes`` is a mapping name -> ``[x, y, z]`` (members refer to nodes by name) or a list
    (members refer to 0-based indices); ``[x, y]`` nodes make a planar structure.  A node shared
    by rods is a ball joint (class k: :func:`from_connectivity` with ``ball_joints=True``).
    Per member, a key missing falls back to ``defaults``, then to the library default (rod
    ``mass`` 1 kg, ``length`` the distance of its nodes, ``damping`` 0; tendon ``stiffness``
    100 N/m, ``damping`` 0); a tendon needs ``rest_length`` [m] or ``prestrain``
    ``(l - L0) / L0``.  Optional ``fixed`` (nodes), ``point_masses`` (``{node, mass}``),
    ``planes`` (``{node, normal}``), ``lines`` (``{node, direction}``).  A ``scene`` is checked
    (:func:`scene_from_dict`) but not part of the structure.  Unknown keys are errors (a typo is
    not ignored).

    Raises
    ------
    ValueError
        Naming the key: ``tendons[3] ('s3').nodes: no node named 'x7'``,
        ``rods[0]: unknown key 'mas' (expected one of nodes, mass, length, damping,
        relative_damping)``, ...
    """
    _refuse_material_form(data)
    _check_header(data)
    names, position, dim = _named_points(data["nodes"], "nodes")
    scene_from_dict(data)
    for key in ("rods", "tendons"):
        if key not in data:
            raise ValueError(f"network: missing key {key!r}")
    velocity = _velocities(data.get("velocities"), names, dim)
    rod_default, tendon_default = _member_defaults(data.get("defaults") or {})
    index = {name: i for i, name in enumerate(names)}
    rods = _members(data["rods"], "rods", ("nodes", *_ROD_KEYS), index)
    tendons = _members(data["tendons"], "tendons", ("name", "nodes", *_TENDON_KEYS), index)
    rod_nodes, tendon_nodes = _member_nodes(rods), _member_nodes(tendons)
    p = np.array(position, dtype=float).reshape(-1, dim)
    rod_distance, tendon_distance = _distances(p, rod_nodes), _distances(p, tendon_nodes)
    rest = _tendon_rest_lengths(tendons, tendon_default, tendon_distance)
    zero = np.flatnonzero(rod_distance == 0)
    if zero.size:
        k = zero[0]
        raise ValueError(
            f"rods[{k}].nodes: {names[rod_nodes[k, 0]]!r} and "
            f"{names[rod_nodes[k, 1]]!r} coincide (zero length)"
        )
    zeros = np.zeros(len(rods)), np.zeros(len(tendons))
    n = len(names)
    return from_connectivity(
        p.T,
        incidence(rod_nodes, n),
        incidence(tendon_nodes, n),
        ball_joints=True,
        node_velocity=None if velocity is None else velocity.T,
        **_supports(data, index, dim),
        rod_mass=_column(rods, "rods", "mass", rod_default, np.full(len(rods), DEFAULT_ROD_MASS)),
        rod_length=_column(rods, "rods", "length", rod_default, rod_distance),
        rod_damping=_column(rods, "rods", "damping", rod_default, zeros[0]),
        rod_relative_damping=_column(rods, "rods", "relative_damping", rod_default, zeros[0]),
        tendon_stiffness=_column(
            tendons,
            "tendons",
            "stiffness",
            tendon_default,
            np.full(len(tendons), DEFAULT_STIFFNESS),
        ),
        tendon_rest_length=rest,
        tendon_damping=_column(tendons, "tendons", "damping", tendon_default, zeros[1]),
        tendon_name=tuple(item.get("name", f"s{k}") for k, (_, item) in enumerate(tendons)),
        node_name=_node_names(names) if isinstance(data["nodes"], Mapping) else None,
    )


def _node_names(names: Sequence[Any]) -> tuple[str, ...] | None:
    """The structure's names of the readable form's named nodes ``names`` (an integer name is
    its text); ``None`` (the default names) for the names ``n0, n1, ...``."""
    text = tuple(str(name) for name in names)
    return None if text == tuple(f"n{i}" for i in range(len(names))) else text


def _refuse_material_form(data: Any) -> None:
    """``ValueError`` naming the first place of ``data`` that uses the material form (members
    given by material and section, ``docs/design.md``), which the design layer reads."""
    if not isinstance(data, Mapping):
        return
    places: list[tuple[str, Any]] = [("network", data)]
    defaults = data.get("defaults")
    if isinstance(defaults, Mapping):
        places += [(f"defaults.{kind}", defaults.get(kind)) for kind in ("rod", "tendon")]
    for kind in ("rods", "tendons"):
        items = data.get(kind)
        if isinstance(items, Sequence) and not isinstance(items, str):
            places += [(f"{kind}[{k}]", item) for k, item in enumerate(items)]
    for where, item in places:
        if isinstance(item, Mapping):
            found = [key for key in MATERIAL_FORM_KEYS if key in item]
            if found:
                raise ValueError(
                    f"{where}: {found[0]!r} is the material form, read by "
                    "tensegrity.design.files.read_design (every CLI command reads both forms)"
                )


def _check_header(data: Any) -> None:
    """The top level of the readable form: a mapping of known keys, its ``format`` and
    ``version`` (if given) this library's, with ``nodes``."""
    if not isinstance(data, Mapping):
        raise ValueError(f"network: expected a mapping at the top level, got {type(data).__name__}")
    check_keys(
        data,
        (
            "format",
            "version",
            "units",
            "nodes",
            "velocities",
            *_SUPPORT_KEYS,
            "defaults",
            "rods",
            "tendons",
            "scene",
        ),
        "network",
    )
    if data.get("format", NETWORK_FORMAT) != NETWORK_FORMAT:
        raise ValueError(f"format: expected {NETWORK_FORMAT!r}, got {data['format']!r:.80}")
    version = data.get("version", NETWORK_VERSION)
    if not isinstance(version, int) or isinstance(version, bool) or version > NETWORK_VERSION:
        raise ValueError(
            f"version: this library reads version <= {NETWORK_VERSION}, got {version!r:.80}"
        )
    if "nodes" not in data:
        raise ValueError("network: missing key 'nodes'")


def _velocities(value: Any, names: list[Any], dim: int) -> np.ndarray | None:
    """The ``velocities`` key (n, dim) [m/s], which lists the nodes ``names`` in their order;
    None without it."""
    if value is None:
        return None
    v_names, v, _ = _named_points(value, "velocities", dim)
    if v_names != names:
        raise ValueError("velocities: must list the same nodes as nodes, in the same order")
    return np.array(v, dtype=float).reshape(-1, dim)


def _member_defaults(defaults: Any) -> tuple[dict[str, Any], dict[str, Any]]:
    """The rod and tendon parameters under ``defaults`` (``{}`` for a kind without)."""
    if not isinstance(defaults, Mapping):
        raise ValueError(f"defaults: expected a mapping, got {type(defaults).__name__}")
    check_keys(defaults, ("rod", "tendon"), "defaults")
    return (
        _defaults(defaults.get("rod"), _ROD_KEYS, "defaults.rod"),
        _defaults(defaults.get("tendon"), _TENDON_KEYS, "defaults.tendon"),
    )


def _member_nodes(members: list) -> np.ndarray:
    """The ``(tail, head)`` node indices (k, 2) of :func:`_members`' output."""
    return np.array([pair for pair, _ in members], dtype=np.int64).reshape(-1, 2)


def _distances(p: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Distances (k,) [m] between the nodes of each pair (k, 2), ``p`` (n, d) the positions."""
    return np.linalg.norm(p[pairs[:, 1]] - p[pairs[:, 0]], axis=1)


def _column(
    items: list, kind: str, key: str, default: Mapping[str, Any], fallback: np.ndarray
) -> np.ndarray:
    """Parameter ``key`` (k,) of each member of :func:`_members`' ``items``: its own, else the
    ``default`` of its kind, else ``fallback[k]``."""
    out = []
    for k, (_, item) in enumerate(items):
        value = item.get(key, default.get(key))
        out.append(fallback[k] if value is None else parse_number(value, f"{kind}[{k}].{key}"))
    return np.array(out, dtype=float)


def _tendon_rest_lengths(
    tendons: list, tendon_default: Mapping[str, Any], distance: np.ndarray
) -> np.ndarray:
    """Rest lengths (S,) [m]: each tendon's ``rest_length`` or ``prestrain`` (of its length
    ``distance`` (S,) [m] in the file), exactly one of them, its own or else the default's."""
    rest = []
    for k, (_, item) in enumerate(tendons):
        where = f"tendons[{k}]"
        given = {key: item[key] for key in ("rest_length", "prestrain") if key in item}
        if not given:
            given = {
                key: tendon_default[key]
                for key in ("rest_length", "prestrain")
                if key in tendon_default
            }
        if len(given) != 1:
            raise ValueError(
                f"{where}: needs exactly one of rest_length [m] or prestrain "
                f"(here or under defaults.tendon), got {sorted(given) or 'neither'}"
            )
        ((key, value),) = given.items()
        value = parse_number(value, f"{where}.{key}")
        rest.append(
            value
            if key == "rest_length"
            else float(rest_from_prestrain(distance[k : k + 1], value, f"{where}.prestrain")[0])
        )
    return np.array(rest, dtype=float)


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
            [
                [_node_ref(end, f"joints[{k}]", index) for end in _pair(pair, f"joints[{k}]")]
                for k, pair in enumerate(pairs)
            ],
            dtype=np.int64,
        ).reshape(-1, 2)
    for key, (nodes_field, value_field) in (
        ("point_masses", ("node_point_mass", None)),
        ("planes", ("plane_nodes", "plane_normal")),
        ("lines", ("line_nodes", "line_direction")),
    ):
        items = data.get(key)
        if items is None:
            continue
        if not isinstance(items, Sequence) or isinstance(items, str):
            raise ValueError(f"{key}: expected a list, got {type(items).__name__}")
        name = _ITEM_KEYS[key]
        nodes, values = [], []
        for k, item in enumerate(items):
            if not isinstance(item, Mapping):
                raise ValueError(f"{key}[{k}]: expected a mapping, got {type(item).__name__}")
            check_keys(item, ("node", name), f"{key}[{k}]")
            for field in ("node", name):
                if field not in item:
                    raise ValueError(f"{key}[{k}]: missing key {field!r}")
            nodes.append(_node_ref(item["node"], f"{key}[{k}].node", index))
            values.append(
                parse_number(item[name], f"{key}[{k}].{name}")
                if value_field is None
                else parse_vector(item[name], f"{key}[{k}].{name}", 3 if key == "planes" else dim)
            )
        if value_field is None:
            mass = np.zeros(len(index))
            mass[nodes] = values
            out[nodes_field] = mass
        else:
            out[nodes_field] = np.array(nodes, dtype=np.int64)
            out[value_field] = np.array(values, dtype=float).reshape(
                -1, 3 if key == "planes" else dim
            )
    return out


def _named_points(
    value: Any, where: str, dim: int | None = None
) -> tuple[list[Any], list[list[float]], int]:
    """Names, vectors and their dimension of a mapping name -> [x, y, z] (or [x, y]: planar),
    or of a list (names 0, 1, ...); ``dim`` ``None``: that of the first vector."""
    if isinstance(value, Mapping):
        names = list(value)
        for name in names:
            if isinstance(name, bool) or not isinstance(name, (str, int)) or name == "":
                raise ValueError(
                    f"{where}: node names must be non-empty strings (or integers), got {name!r:.80}"
                )
        rows, labels = [value[name] for name in names], [f"{where}.{name}" for name in names]
    elif isinstance(value, Sequence) and not isinstance(value, str):
        names = list(range(len(value)))
        rows, labels = list(value), [f"{where}[{k}]" for k in names]
    else:
        raise ValueError(
            f"{where}: expected a mapping name -> [x, y, z] or a list, got {type(value).__name__}"
        )
    if dim is None:
        dim = node_dimension(rows)
    return (
        names,
        [parse_vector(row, label, dim) for row, label in zip(rows, labels, strict=True)],
        dim,
    )


def _defaults(value: Any, keys: Sequence[str], where: str) -> dict[str, Any]:
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{where}: expected a mapping, got {type(value).__name__}")
    check_keys(value, keys, where)
    return {key: parse_number(x, f"{where}.{key}") for key, x in value.items()}


def _members(value: Any, kind: str, keys: Sequence[str], index: Mapping[Any, int]) -> list:
    """``[((tail, head), item), ...]`` with node references resolved through ``index``."""
    if not isinstance(value, Sequence) or isinstance(value, str):
        raise ValueError(f"{kind}: expected a list, got {type(value).__name__}")
    out = []
    for k, item in enumerate(value):
        if not isinstance(item, Mapping):
            raise ValueError(f"{kind}[{k}]: expected a mapping, got {type(item).__name__}")
        label = f"{kind}[{k}]" + (f" ({item['name']!r})" if "name" in item else "")
        check_keys(item, keys, label)
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
def file_format(path: PathLike, format: str | None = None) -> str:
    """The format name (a value of :data:`FORMATS`) of ``path``: ``format`` if given (checked),
    else by the file's suffix; a one-line ``ValueError`` otherwise."""
    if format is not None:
        if format not in set(FORMATS.values()):
            raise ValueError(
                f"format: expected one of {', '.join(sorted(set(FORMATS.values())))}, "
                f"got {format!r}"
            )
        return format
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise file_error(
            path, f"unknown structure file suffix {suffix!r} (expected one of {', '.join(FORMATS)})"
        )
    return FORMATS[suffix]


def read_network(path: PathLike, *, format: str | None = None) -> Structure:
    """Read a structure file in any format (by suffix, or ``format``): see the module docstring.

    Raises
    ------
    ValueError
        One line starting with the file name, naming the problem and the element.
    """
    kind = file_format(path, format)
    if kind == "json":
        return read_structure(path)
    if kind == "mjcf":
        raise file_error(path, "MJCF files are written for MuJoCo, not read back")
    if kind == "connectivity":
        raw = read_input(path)
        with _blamed(path):
            return _from_npz(raw)
    data = read_document(path, format=kind)
    with _blamed(path):
        return network_from_dict(data)


def read_scene(path: PathLike, *, format: str | None = None) -> Scene:
    """The scene a structure file carries (by suffix, or ``format``): its ``scene`` key
    (:func:`scene_from_dict`); an empty :class:`~tensegrity.model.ground.Scene` for a file
    without one, and for the connectivity form (``.npz``), which carries none.

    ``simulate(read_network(path), t_span, **read_scene(path).simulate_options())`` runs the
    structure in its scene.

    Raises
    ------
    ValueError
        One line starting with the file name and naming the key: ``"s.yaml:
        scene.planes[0].normal: must not be zero, got [0.0, 0.0, 0.0]"``.
    """
    kind = file_format(path, format)
    if kind == "mjcf":
        raise file_error(path, "MJCF files are written for MuJoCo, not read back")
    if kind == "connectivity":
        regular_file(path)
        return Scene()
    data = read_document(path, format=kind)
    with _blamed(path):
        return scene_from_dict(data)


@contextlib.contextmanager
def _blamed(path: PathLike) -> Iterator[None]:
    """Errors of reading ``path`` as one-line ``ValueError``s that start with its name (a
    document nested deeper than the parsers recurse: ``nested too deeply``)."""
    try:
        yield
    except RecursionError as exc:
        raise file_error(path, "nested too deeply") from exc
    except ValueError as exc:
        raise file_error(path, str(exc)) from exc
    except (TypeError, KeyError, OverflowError) as exc:
        raise file_error(path, str(exc) or type(exc).__name__) from exc


def read_document(path: PathLike, *, format: str | None = None) -> Any:
    """The document of a YAML, TOML or JSON structure file (by suffix, or ``format``), parsed
    but not interpreted: mappings, lists, numbers, text.

    Raises
    ------
    ValueError
        One line starting with the file name (missing, not UTF-8, invalid syntax), or for a
        format without such a document (``.npz``, ``.xml``).
    """
    kind = file_format(path, format)
    if kind not in ("json", "yaml", "toml"):
        raise file_error(path, f"a {kind} file is not a YAML, TOML or JSON document")
    raw = read_input(path)
    with _blamed(path):
        if kind == "json":
            return _parse_json(raw)
        return _parse_text(raw, kind)


def _parse_json(raw: bytes) -> Any:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"not UTF-8 text (byte {exc.start})") from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(
            f"invalid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg}"
        ) from exc
    except ValueError as exc:  # an integer of more digits than Python converts (4300)
        raise ValueError(f"invalid JSON: {exc}") from exc


def write_document(
    path: PathLike, data: Mapping[str, Any], *, format: str | None = None, header: str = ""
) -> Path:
    """Write a readable-form document ``data`` (e.g. :func:`network_to_dict`'s) as YAML, TOML
    or JSON (by suffix, or ``format``), atomically; ``header`` (lines of ``# ...``) heads YAML
    and TOML files."""
    kind = file_format(path, format)
    if kind == "json":
        text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    elif kind in ("yaml", "toml"):
        text = header + _dump_document(data, kind)
    else:
        raise file_error(path, f"a {kind} file is not a YAML, TOML or JSON document")
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


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
    with open_npz(raw) as archive:
        unknown = sorted(set(archive.files) - set(NPZ_ARRAYS))
        if unknown:
            raise ValueError(
                f"unknown array {unknown[0]!r} (expected some of {', '.join(NPZ_ARRAYS)})"
            )
        arrays = npz_arrays(archive, kinds=NPZ_KINDS)
    for name, (required, _) in NPZ_ARRAYS.items():
        if required and name not in arrays:
            raise ValueError(f"missing array {name!r}")
    for name in NPZ_INDEX_ARRAYS:
        _check_whole(arrays.get(name), name)
    names = arrays.pop("tendon_name", None)
    node_names = arrays.pop("node_name", None)
    N, C_b, C_s = arrays.pop("N"), arrays.pop("C_b"), arrays.pop("C_s")
    return from_connectivity(
        N,
        C_b,
        C_s,
        tendon_name=None if names is None else tuple(str(x) for x in names),
        node_name=None if node_names is None else tuple(str(x) for x in node_names),
        ball_joints=True,
        **arrays,
    )


def _check_whole(indices: np.ndarray | None, name: str) -> None:
    """``ValueError`` naming the array ``name`` of node indices if it holds a float that is not a
    whole number."""
    if indices is None or indices.dtype.kind != "f":
        return
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~(np.isfinite(indices) & (indices == np.round(indices))))
    if bad.size:
        value = indices.flat[bad[0]]
        raise ValueError(f"array {name!r}: node indices must be whole numbers, got {value}")


def write_network(
    path: PathLike,
    structure: Structure,
    *,
    format: str | None = None,
    keep_joints: bool = False,
    scene: Scene | None = None,
) -> Path:
    """Write ``structure`` in any format (by suffix, or ``format``), atomically.

    ``json``: :meth:`Structure.to_dict`; ``yaml``/``toml``: :func:`network_to_dict`;
    ``connectivity``: ``.npz`` of :data:`NPZ_ARRAYS`; ``mjcf``: :func:`tensegrity.io.mjcf.to_mjcf`.
    The readable and connectivity forms merge joined nodes (class k), or with ``keep_joints``
    keep every rod's end nodes and list the joints.  JSON, and every form with ``keep_joints``
    or for a structure without joints, reads back to an identical structure; a jointed
    structure written merged reads back with the same ``N, C_b, C_s``, supports and parameters
    in the layout of :func:`from_connectivity` (see ``docs/networks.md``).

    A ``scene`` (:class:`~tensegrity.model.ground.Scene`) goes under the file's ``scene`` key
    (JSON, YAML, TOML; :func:`read_scene` reads it back equal), or into MJCF as its floor
    planes and gravity; the connectivity form (``.npz``) carries none (``ValueError`` naming
    ``scene``).
    """
    kind = file_format(path, format)
    if kind == "json":
        return write_structure(path, structure, scene=scene)
    if kind == "mjcf":
        from tensegrity.io.mjcf import write_mjcf

        return write_mjcf(path, structure, **({} if scene is None else scene.simulate_options()))
    if kind == "connectivity" and scene is not None and scene != Scene():
        raise ValueError(
            "scene: the connectivity form (.npz) carries no scene; write .json, .yaml or .toml"
        )
    with atomic_path(path) as tmp:
        if kind == "connectivity":
            with open(tmp, "wb") as f:
                # numpy's stub lets a `**` mapping fill `allow_pickle: bool`; these keys are the
                # arrays' names (`_npz_arrays`), never that argument's.
                np.savez(f, **_npz_arrays(structure, keep_joints))  # type: ignore[arg-type]
        else:
            tmp.write_text(_dump_text(structure, kind, keep_joints, scene), encoding="utf-8")
    return Path(path)


def _npz_arrays(structure: Structure, keep_joints: bool) -> dict[str, np.ndarray]:
    merged = merge_joints(structure, keep_joints=keep_joints)
    N, C_b, C_s = connectivity_of(structure, merged)
    supports = {
        "node_fixed": merged.node_fixed.any(),
        "node_point_mass": merged.node_point_mass.any(),
        "plane_nodes": merged.plane_nodes.size,
        "plane_normal": merged.plane_nodes.size,
        "line_nodes": merged.line_nodes.size,
        "line_direction": merged.line_nodes.size,
        "joint_nodes": merged.joint_nodes.size,
    }
    return (
        {
            "N": N,
            "C_b": C_b,
            "C_s": C_s,
            "node_velocity": merged.node_velocity,
            "rod_mass": structure.rod_mass,
            "rod_length": structure.rod_length,
            "rod_damping": structure.rod_damping,
            "rod_relative_damping": structure.rod_relative_damping,
            "tendon_stiffness": structure.tendon_stiffness,
            "tendon_rest_length": structure.tendon_rest_length,
            "tendon_damping": structure.tendon_damping,
            "tendon_name": np.array(structure.tendon_name, dtype=str),
        }
        | {name: getattr(merged, name) for name, present in supports.items() if present}
        | _npz_node_names(merged.node_name)
    )


def _npz_node_names(names: tuple[str, ...] | None) -> dict[str, np.ndarray]:
    """The ``node_name`` array of the connectivity file (none for the default names)."""
    return {} if names is None else {"node_name": np.array(names, dtype=str)}


def _dump_text(structure: Structure, kind: str, keep_joints: bool, scene: Scene | None) -> str:
    data = network_to_dict(structure, keep_joints=keep_joints, scene=scene)
    joined = (
        f" (the structure's {structure.n_nodes}, joined nodes merged: a node of k rods is a "
        "ball joint)"
        if structure.joint_nodes.size and not keep_joints
        else ""
    )
    header = (
        f"# {len(data['nodes'])} nodes{joined}, {structure.n_rods} rods (bars), "
        f"{structure.n_tendons} tendons (strings); SI units\n"
    )
    return header + _dump_document(data, kind)


def _dump_document(data: Mapping[str, Any], kind: str) -> str:
    """``data`` as TOML or YAML text (members one a line in YAML)."""
    if kind == "toml":
        import tomli_w

        return tomli_w.dumps(data)
    import yaml

    class _Dumper(yaml.SafeDumper):
        pass

    def short_lists(dumper, value):  # [x, y, z] and [tail, head] on one line
        flow = all(not isinstance(x, (list, dict)) for x in value)
        return dumper.represent_sequence("tag:yaml.org,2002:seq", value, flow_style=flow)

    def members(dumper, value):  # one line per rod / tendon
        flow = isinstance(value.get("nodes"), list)
        return dumper.represent_mapping("tag:yaml.org,2002:map", value.items(), flow_style=flow)

    def text(dumper, value):  # PyYAML writes NEL (U+0085) raw, which reads back as a space
        style = '"' if "\x85" in value else None
        return dumper.represent_scalar("tag:yaml.org,2002:str", value, style=style)

    _Dumper.add_representer(list, short_lists)
    _Dumper.add_representer(dict, members)
    _Dumper.add_representer(str, text)
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, width=120)


# ----------------------------------------------------------------------------- structures
def read_structure(path: PathLike) -> Structure:
    """Read a structure file (the JSON form of :meth:`Structure.to_dict`).

    Parameters
    ----------
    path : str or os.PathLike
        A UTF-8 JSON file: ``{"nodes": [[x, y, z], ...] (N, 3) [m], "velocities": (N, 3) [m/s],
        "rods": [{"nodes", "mass" [kg], "length" [m], "damping" [1/s], "relative_damping"
        [1/s]}, ...],
        "tendons": [{"name", "nodes", "stiffness" [N/m], "rest_length" [m],
        "damping" [N s/m]}, ...]}``, and optionally a ``"scene"`` (checked, not returned:
        :func:`read_scene`).

    Returns
    -------
    Structure

    Raises
    ------
    ValueError
        One line starting with the file name: ``"s.json: no such file"``,
        ``"s.json: invalid JSON at line 3, column 5: Expecting ',' delimiter"``,
        ``"s.json: tendons[2] ('t3_1_1').stiffness: must be > 0, got -5.0"``, ...

    Notes
    -----
    A ``.yaml``, ``.yml``, ``.toml`` or ``.npz`` file is read by
    :func:`tensegrity.io.formats.read_network` instead (docs/networks.md); any other name as JSON.
    """
    if Path(path).suffix.lower() in (".yaml", ".yml", ".toml", ".npz"):
        return read_network(path)
    data = read_document(path, format="json")
    if isinstance(data, Mapping) and "format" in data:  # the readable form, as JSON
        with _blamed(path):
            return network_from_dict(data)
    return _structure_from_dict(data, path)


def _structure_from_dict(data: Any, path: PathLike) -> Structure:
    # (TypeError/KeyError/OverflowError: a malformed value that slipped past from_dict's own
    # checks, e.g. a string or a huge integer as a node index)
    with _blamed(path):
        if isinstance(data, Mapping) and "scene" in data:
            scene_from_dict(data)
            data = {key: value for key, value in data.items() if key != "scene"}
        return Structure.from_dict(data)


def write_structure(path: PathLike, structure: Structure, *, scene: Scene | None = None) -> Path:
    """Write ``structure`` as JSON (:meth:`Structure.to_dict`, indent 2), atomically, with
    ``scene`` (if given and not empty) under its ``"scene"`` key.

    Floats are written with Python's shortest round-trip representation, so
    ``read_structure(path).to_dict() == structure.to_dict()`` exactly.

    Parameters
    ----------
    path : str or os.PathLike
        Output file; its directory must exist.  An existing file is replaced only once the new
        one is complete.
    structure : Structure
    scene : Scene, optional
        The planes, contact radius and gravity of a run (:func:`read_scene` reads it back
        equal).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    data = with_scene(structure.to_dict(), scene)
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
