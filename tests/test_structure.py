"""Validation and JSON form of :class:`tensegrity.model.structure.Structure`.

Every promised error must be a ``ValueError`` whose message names the field and the element
(e.g. ``tendons[3] ('t5_1_1').stiffness: must be > 0``).  The messages are matched loosely:
each test requires a few fragments (group, element index, field, reason) in any order.
"""

from __future__ import annotations

import copy
import json
import math
import re

import numpy as np
import pytest

from tensegrity.model.structure import ROD_LENGTH_RTOL, Structure


def names(*parts: str) -> str:
    """A regex that matches a message containing every (regex) fragment, in any order."""
    return "".join(f"(?=.*(?:{part}))" for part in parts)


def at(k: int) -> str:
    """The element index ``[k]`` as a regex fragment."""
    return re.escape(f"[{k}]")


# A small hand-made class 1 structure: 3 rods (nodes (0,1), (2,3), (4,5)) of lengths 1, 1, 2,
# and 9 tendons on distinct node pairs.
NODES = [
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 1.0],
    [1.0, 0.0, 0.0],
    [1.0, 0.6, 0.8],
    [0.0, 1.0, 0.0],
    [0.0, 1.0, 2.0],
]
RODS = [[0, 1], [2, 3], [4, 5]]
ROD_LENGTHS = [1.0, 1.0, 2.0]
TENDONS = [[0, 2], [2, 4], [4, 0], [1, 3], [3, 5], [5, 1], [0, 3], [2, 5], [4, 1]]
TENDON_NAMES = ["a", "b", "c", "d", "e", "f", "g", "h", "i"]


def base_kwargs() -> dict:
    """Fresh, valid constructor arguments (plain lists, safe to mutate)."""
    return dict(
        node_position=copy.deepcopy(NODES),
        rod_nodes=copy.deepcopy(RODS),
        rod_mass=[1.5, 2.0, 0.25],
        rod_length=list(ROD_LENGTHS),
        tendon_nodes=copy.deepcopy(TENDONS),
        tendon_stiffness=[100.0 + k for k in range(9)],
        tendon_rest_length=[0.5 + 0.01 * k for k in range(9)],
        tendon_damping=[0.1 * k for k in range(9)],
        tendon_name=list(TENDON_NAMES),
        node_velocity=[[0.1 * k, -0.2 * k, 0.3] for k in range(6)],
        rod_damping=[0.0, 0.5, 1.25],
    )


def build(**changes) -> Structure:
    kwargs = base_kwargs()
    kwargs.update(changes)
    return Structure(**kwargs)


def with_item(field: str, index, value) -> dict:
    """Constructor arguments with one entry of one field replaced."""
    kwargs = base_kwargs()
    target = kwargs[field]
    if isinstance(index, tuple):
        target[index[0]][index[1]] = value
    else:
        target[index] = value
    return kwargs


# ---------------------------------------------------------------- valid input
def test_valid_structure_builds_with_expected_contents():
    s = build()
    assert (s.n_nodes, s.n_rods, s.n_tendons) == (6, 3, 9)
    assert s.n_coordinates == 18 and s.n_dof == 15
    np.testing.assert_array_equal(s.node_position, NODES)
    np.testing.assert_array_equal(s.rod_nodes, RODS)
    np.testing.assert_array_equal(s.tendon_nodes, TENDONS)  # rows stay (tail, head)
    assert s.tendon_name == tuple(TENDON_NAMES)
    assert s.tendon_index("e") == 4
    assert np.issubdtype(s.rod_nodes.dtype, np.integer)
    assert np.issubdtype(s.tendon_nodes.dtype, np.integer)
    np.testing.assert_allclose(s.node_mass, [0.75, 0.75, 1.0, 1.0, 0.125, 0.125])
    assert s.total_mass == pytest.approx(3.75)


def test_optional_fields_default():
    kwargs = base_kwargs()
    for key in ("tendon_damping", "tendon_name", "node_velocity", "rod_damping"):
        del kwargs[key]
    s = Structure(**kwargs)
    assert s.tendon_name == tuple(f"s{k}" for k in range(9))
    np.testing.assert_array_equal(s.tendon_damping, np.zeros(9))
    np.testing.assert_array_equal(s.rod_damping, np.zeros(3))
    np.testing.assert_array_equal(s.node_velocity, np.zeros((6, 3)))


def test_zero_damping_and_zero_rest_length_are_allowed():
    s = build(tendon_damping=[0.0] * 9, rod_damping=[0.0] * 3, tendon_rest_length=[0.0] * 9)
    assert np.all(s.tendon_rest_length == 0)


def test_tendon_incidence_is_head_minus_tail():
    s = build()
    t = s.tendon_incidence @ s.node_position
    expected = np.array([np.subtract(NODES[h], NODES[tl]) for tl, h in TENDONS])
    np.testing.assert_allclose(t, expected)


# ---------------------------------------------------------------- non-finite
NONFINITE_CASES = [
    # (field, index, group regex, element regex, field regex)
    ("node_position", (2, 1), "nodes", r"\[2\b", "nodes"),
    ("node_velocity", (4, 0), "velocit", r"\[4\b", "velocit"),
    ("rod_mass", 1, "rod", at(1), "mass"),
    ("rod_length", 2, "rod", at(2), "length"),
    ("rod_damping", 1, "rod", at(1), "damping"),
    ("tendon_stiffness", 3, "tendon", at(3), "stiffness"),
    ("tendon_rest_length", 5, "tendon", at(5), "rest_length"),
    ("tendon_damping", 7, "tendon", at(7), "damping"),
]


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf], ids=["nan", "inf", "-inf"])
@pytest.mark.parametrize("case", NONFINITE_CASES, ids=[c[0] for c in NONFINITE_CASES])
def test_non_finite_numbers_are_rejected_naming_field_and_element(case, bad):
    field, index, group, element, name = case
    kwargs = with_item(field, index, bad)
    with pytest.raises(ValueError, match=names(group, element, name, "finite|nan|inf")):
        Structure(**kwargs)


# ------------------------------------------------------- signs of parameters
SIGN_CASES = [
    # (field, index, bad value, group, field regex)
    ("rod_mass", 1, 0.0, "rod", "mass"),
    ("rod_mass", 2, -1.0, "rod", "mass"),
    ("rod_length", 1, 0.0, "rod", "length"),
    ("rod_length", 2, -2.0, "rod", "length"),
    ("rod_damping", 1, -0.1, "rod", "damping"),
    ("tendon_stiffness", 4, 0.0, "tendon", "stiffness"),
    ("tendon_stiffness", 6, -5.0, "tendon", "stiffness"),
    ("tendon_rest_length", 3, -1e-9, "tendon", "rest_length"),
    ("tendon_damping", 8, -0.5, "tendon", "damping"),
]


@pytest.mark.parametrize("case", SIGN_CASES, ids=[f"{c[0]}={c[2]}" for c in SIGN_CASES])
def test_out_of_range_parameters_are_rejected_naming_field_and_element(case):
    field, index, bad, group, name = case
    kwargs = with_item(field, index, bad)
    with pytest.raises(ValueError, match=names(group, at(index), name, ">|positive|negative")):
        Structure(**kwargs)


def test_tendon_error_names_the_tendon():
    kwargs = with_item("tendon_stiffness", 4, -1.0)
    with pytest.raises(ValueError, match=names(at(4), "stiffness", "'e'")):
        Structure(**kwargs)


# ------------------------------------------------------------- node indices
@pytest.mark.parametrize("bad", [6, 100, -1])
def test_tendon_node_index_out_of_range(bad):
    kwargs = with_item("tendon_nodes", (5, 1), bad)
    with pytest.raises(ValueError, match=names("tendon", at(5), re.escape(str(bad)), "range")):
        Structure(**kwargs)


@pytest.mark.parametrize("bad", [6, -1])
def test_rod_node_index_out_of_range(bad):
    kwargs = with_item("rod_nodes", (2, 1), bad)
    with pytest.raises(ValueError, match=names("rod", at(2), re.escape(str(bad)), "range")):
        Structure(**kwargs)


def test_tendon_from_a_node_to_itself():
    kwargs = with_item("tendon_nodes", 6, [3, 3])
    with pytest.raises(ValueError, match=names("tendon", at(6), r"\b3\b", "itself")):
        Structure(**kwargs)


def test_rod_from_a_node_to_itself():
    kwargs = with_item("rod_nodes", 2, [4, 4])
    with pytest.raises(ValueError, match=names("rod", at(2), r"\b4\b", "itself")):
        Structure(**kwargs)


def test_non_integer_node_indices_are_rejected():
    kwargs = base_kwargs()
    kwargs["tendon_nodes"] = np.array(TENDONS, dtype=float)
    kwargs["tendon_nodes"][2, 0] = 0.5
    with pytest.raises(ValueError, match=names("tendon", "integer")):
        Structure(**kwargs)


def test_integral_float_node_indices_are_accepted():
    s = build(tendon_nodes=np.array(TENDONS, dtype=float))
    np.testing.assert_array_equal(s.tendon_nodes, TENDONS)
    assert np.issubdtype(s.tendon_nodes.dtype, np.integer)


@pytest.mark.parametrize("pair", [[0, 2], [2, 0]], ids=["same-orientation", "reversed"])
def test_two_tendons_on_the_same_node_pair(pair):
    kwargs = base_kwargs()
    kwargs["tendon_nodes"].append(pair)  # tendons[0] is (0, 2)
    kwargs["tendon_stiffness"].append(1.0)
    kwargs["tendon_rest_length"].append(1.0)
    kwargs["tendon_damping"].append(0.0)
    kwargs["tendon_name"].append("j")
    with pytest.raises(ValueError, match=names("tendon", at(9), at(0))):
        Structure(**kwargs)


def test_a_tenth_tendon_on_a_fresh_pair_is_accepted():
    # Control for the test above: a tenth tendon on a fresh pair is accepted.
    kwargs = base_kwargs()
    kwargs["tendon_nodes"].append([1, 2])
    kwargs["tendon_stiffness"].append(1.0)
    kwargs["tendon_rest_length"].append(1.0)
    kwargs["tendon_damping"].append(0.0)
    kwargs["tendon_name"].append("j")
    assert Structure(**kwargs).n_tendons == 10


# ----------------------------------------------------------- class 1 checks
def test_node_in_two_rods():
    kwargs = base_kwargs()
    kwargs["rod_nodes"] = [[0, 1], [2, 3], [3, 4]]  # node 3 in rods 1 and 2 (node 5 free)
    with pytest.raises(ValueError, match=names("rod", at(2), r"\b3\b")):
        Structure(**kwargs)


def test_node_in_no_rod():
    kwargs = base_kwargs()
    kwargs["node_position"].append([5.0, 5.0, 5.0])
    kwargs["node_velocity"].append([0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=names(r"nodes?\s*\[?6\b", "rod")):
        Structure(**kwargs)


@pytest.mark.parametrize("factor", [2.0, -2.0, 10.0, -10.0])
def test_node_positions_contradicting_rod_length_are_rejected(factor):
    kwargs = base_kwargs()
    a, b = np.array(NODES[2]), np.array(NODES[3])  # rod 1, length 1
    kwargs["node_position"][3] = list(a + (b - a) * (1 + factor * ROD_LENGTH_RTOL))
    with pytest.raises(ValueError, match=names("rod", at(1), "length")) as excinfo:
        Structure(**kwargs)
    # plain numbers for the user, not numpy reprs such as "np.float64(1.0)"
    message = str(excinfo.value)
    assert "is 1.0 m but nodes 2 and 3 are " in message and "np." not in message, message


@pytest.mark.parametrize("factor", [0.5, -0.5, 0.9, -0.9])
def test_node_positions_within_rod_length_tolerance_are_accepted(factor):
    kwargs = base_kwargs()
    a, b = np.array(NODES[4]), np.array(NODES[5])  # rod 2, length 2
    kwargs["node_position"][5] = list(a + (b - a) * (1 + factor * ROD_LENGTH_RTOL))
    s = Structure(**kwargs)
    assert s.rod_length[2] == 2.0


@pytest.mark.parametrize("factor", [2.0, 0.5])
def test_rod_length_tolerance_is_relative_to_length(factor):
    # rod 2 has length 2: the tolerance is RTOL * L = 2 RTOL in absolute terms.
    kwargs = base_kwargs()
    kwargs["rod_length"][2] = 2.0 * (1 + factor * ROD_LENGTH_RTOL)
    if factor > 1:
        with pytest.raises(ValueError, match=names("rod", at(2), "length")):
            Structure(**kwargs)
    else:
        Structure(**kwargs)


# ------------------------------------------------------------------- names
def test_duplicate_tendon_names():
    kwargs = with_item("tendon_name", 4, "b")
    with pytest.raises(ValueError, match=names("tendon", at(4), "name", "'b'")):
        Structure(**kwargs)


@pytest.mark.parametrize("bad", ["", 7, None])
def test_tendon_name_must_be_non_empty_string(bad):
    kwargs = with_item("tendon_name", 2, bad)
    with pytest.raises(ValueError, match=names("tendon", at(2), "name")):
        Structure(**kwargs)


def test_tendon_names_as_one_text_are_refused():
    """Nine one-letter names given as one text (before: the names ``a``, ..., ``i``)."""
    with pytest.raises(ValueError, match=r"^tendon_name: expected a sequence of names, got the"):
        build(tendon_name="".join(TENDON_NAMES))


@pytest.mark.parametrize(
    "field, name",
    [
        ("node_position", "nodes"),
        ("node_velocity", "velocities"),
        ("rod_mass", "rods.mass"),
        ("rod_length", "rods.length"),
        ("rod_damping", "rods.damping"),
        ("tendon_stiffness", "tendons.stiffness"),
        ("tendon_rest_length", "tendons.rest_length"),
        ("tendon_damping", "tendons.damping"),
    ],
)
@pytest.mark.parametrize("imaginary", [0.0, 1e-3])
def test_complex_numbers_are_refused_naming_the_field(field, name, imaginary):
    """A complex array (before: its imaginary part silently dropped, a ComplexWarning at
    most), even one whose imaginary parts are all zero."""
    kwargs = base_kwargs()
    kwargs[field] = np.asarray(kwargs[field], dtype=complex) + 1j * imaginary
    with pytest.raises(ValueError, match=f"^{re.escape(name)}: expected real numbers, got complex"):
        Structure(**kwargs)


# ------------------------------------------------------------------- shapes
SHAPE_CASES = [
    ("node_position", [[0.0, 0.0, 0.0, 0.0]] * 6, "nodes"),  # (2 columns would be planar)
    ("node_position", [0.0] * 18, "nodes"),
    ("node_position", np.zeros((6, 3, 1)), "nodes"),
    ("node_velocity", np.zeros((5, 3)), "velocit"),
    ("node_velocity", np.zeros((6, 2)), "velocit"),
    ("rod_nodes", [[0, 1, 2], [3, 4, 5]], "rod"),
    ("rod_nodes", [0, 1, 2, 3, 4, 5], "rod"),
    ("rod_mass", [1.0, 1.0], "mass"),
    ("rod_mass", [[1.0], [1.0], [1.0]], "mass"),
    ("rod_length", [1.0, 1.0, 2.0, 1.0], "length"),
    ("rod_damping", [0.0, 0.0], "damping"),
    ("tendon_nodes", np.zeros((9, 3), int), "tendon"),
    ("tendon_stiffness", [1.0] * 8, "stiffness"),
    ("tendon_rest_length", [1.0] * 10, "rest_length"),
    ("tendon_damping", np.zeros((9, 1)), "damping"),
    ("tendon_name", TENDON_NAMES[:8], "name"),
]


@pytest.mark.parametrize(
    "field, value, name",
    SHAPE_CASES,
    ids=[f"{c[0]}-{np.shape(c[1])}" for c in SHAPE_CASES],
)
def test_wrong_shapes_are_rejected_naming_the_field(field, value, name):
    kwargs = base_kwargs()
    kwargs[field] = value
    with pytest.raises(ValueError, match=name):
        Structure(**kwargs)


def test_no_nodes_is_rejected():
    kwargs = base_kwargs()
    kwargs.update(
        node_position=np.zeros((0, 3)),
        node_velocity=None,
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        rod_damping=[],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
        tendon_damping=[],
        tendon_name=[],
    )
    with pytest.raises(ValueError, match="nodes"):
        Structure(**kwargs)


# ------------------------------------------------------- read-only, immutable
ARRAY_FIELDS = [
    "node_position",
    "node_velocity",
    "rod_nodes",
    "rod_mass",
    "rod_length",
    "rod_damping",
    "tendon_nodes",
    "tendon_stiffness",
    "tendon_rest_length",
    "tendon_damping",
    "node_mass",
]


@pytest.mark.parametrize("field", ARRAY_FIELDS)
def test_arrays_are_read_only(field):
    s = build()
    array = getattr(s, field)
    assert isinstance(array, np.ndarray)
    before = array.copy()
    with pytest.raises(ValueError):
        array[(0,) * array.ndim] = 42
    with pytest.raises(ValueError):
        array[...] = 0
    np.testing.assert_array_equal(getattr(s, field), before)


def test_inputs_are_copied_not_aliased():
    kwargs = base_kwargs()
    arrays = {
        key: np.array(value, dtype=int if key.endswith("_nodes") else float)
        for key, value in kwargs.items()
        if key != "tendon_name"
    }
    kwargs.update(arrays)
    s = Structure(**kwargs)
    for key, array in arrays.items():
        assert array.flags.writeable, f"caller's {key} was made read-only"
        expected = getattr(s, key).copy()
        array[...] = 0 if key.endswith("_nodes") else 123.0
        np.testing.assert_array_equal(getattr(s, key), expected, err_msg=key)


def test_fields_cannot_be_reassigned():
    s = build()
    with pytest.raises(AttributeError):
        s.rod_mass = np.ones(3)  # frozen dataclass


def test_tendon_name_is_a_tuple():
    s = build()
    assert isinstance(s.tendon_name, tuple)


def test_tendon_index_unknown_name():
    with pytest.raises(KeyError, match="zz"):
        build().tendon_index("zz")


# ------------------------------------------------------------------ replace
def test_replace_revalidates():
    s = build()
    with pytest.raises(ValueError, match=names("rod", at(1), "mass")):
        s.replace(rod_mass=[1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match=names("tendon", at(2), "stiffness")):
        s.replace(tendon_stiffness=[1.0, 1.0, 0.0] + [1.0] * 6)
    moved = np.array(s.node_position)
    moved[1, 2] += 0.01  # rod 0 no longer length 1
    with pytest.raises(ValueError, match=names("rod", at(0), "length")):
        s.replace(node_position=moved)
    with pytest.raises(ValueError, match=names("tendon", "name")):
        s.replace(tendon_name=("a",) * 9)


def test_replace_returns_new_valid_structure_and_leaves_original():
    s = build()
    t = s.replace(tendon_stiffness=[7.0] * 9)
    assert t is not s
    np.testing.assert_array_equal(t.tendon_stiffness, np.full(9, 7.0))
    np.testing.assert_array_equal(s.tendon_stiffness, [100.0 + k for k in range(9)])
    assert not t.tendon_stiffness.flags.writeable
    np.testing.assert_array_equal(t.node_position, s.node_position)
    assert t.tendon_name == s.tendon_name


# --------------------------------------------------------------- JSON form
def awkward_structure() -> Structure:
    """Values whose floats do not survive a sloppy (e.g. %g) serialization."""
    kwargs = base_kwargs()
    kwargs["rod_mass"] = [0.1 + 0.2, 1 / 3, math.pi]
    kwargs["tendon_stiffness"] = [1e5 / 7 + k for k in range(9)]
    kwargs["tendon_rest_length"] = [math.sqrt(2) / (k + 1) for k in range(9)]
    kwargs["tendon_damping"] = [k / 3 for k in range(9)]
    kwargs["rod_damping"] = [0.0, 1 / 7, 2e-9]
    kwargs["node_velocity"] = [[math.e * k, -1 / (k + 3), 1e-300] for k in range(6)]
    kwargs["tendon_name"] = ["t1_1_1", "ü-name", "with space", "d", "e", "f", "g", "h", "i"]
    # rod 0 tilted so its end points have non-trivial coordinates, length still exactly-ish 1
    kwargs["node_position"][1] = [1 / 3, 2 / 3, 2 / 3]
    return Structure(**kwargs)


def assert_same_structure(a: Structure, b: Structure) -> None:
    for field in ARRAY_FIELDS[:-1]:
        x, y = getattr(a, field), getattr(b, field)
        assert x.shape == y.shape, field
        assert x.dtype.kind == y.dtype.kind, field
        np.testing.assert_array_equal(x, y, err_msg=field)
    assert a.tendon_name == b.tendon_name


def test_to_dict_round_trip_is_exact():
    s = awkward_structure()
    d = s.to_dict()
    r = Structure.from_dict(d)
    assert_same_structure(s, r)
    assert r.to_dict() == d


def test_to_dict_round_trip_through_json_text_is_exact():
    s = awkward_structure()
    text = json.dumps(s.to_dict(), allow_nan=False)
    r = Structure.from_dict(json.loads(text))
    assert_same_structure(s, r)


def test_to_dict_content():
    s = build()
    d = s.to_dict()
    assert {"nodes", "rods", "tendons"} <= set(d)
    assert d["nodes"] == NODES
    assert len(d["rods"]) == 3 and len(d["tendons"]) == 9
    assert d["rods"][1]["nodes"] == [2, 3]
    assert d["rods"][2]["mass"] == 0.25 and d["rods"][2]["length"] == 2.0
    assert d["rods"][2]["damping"] == 1.25
    t = d["tendons"][4]
    assert t["name"] == "e" and t["nodes"] == [3, 5]  # (tail, head) kept in order
    assert t["stiffness"] == 104.0 and t["rest_length"] == pytest.approx(0.54)
    assert t["damping"] == pytest.approx(0.4)
    assert d["velocities"][2] == pytest.approx([0.2, -0.4, 0.3])
    # plain JSON types only
    json.dumps(d, allow_nan=False)
    assert type(d["rods"][0]["nodes"][0]) is int
    assert type(d["tendons"][0]["stiffness"]) is float


@pytest.mark.parametrize(
    ("where", "key", "message"),
    [
        ((), "comment", r"^structure: unknown key 'comment' \(expected one of nodes, velocities,"),
        (("rods", 0), "mas", r"^rods\[0\]: unknown key 'mas' \(expected one of nodes, mass, "),
        (("tendons", 3), "stifness", r"^tendons\[3\]: unknown key 'stifness' \(expected one "),
        (("point_masses", 0), "mas", r"^point_masses\[0\]: unknown key 'mas' \(expected one of"),
        (("planes", 0), "norm", r"^planes\[0\]: unknown key 'norm' \(expected one of node, "),
    ],
)
def test_from_dict_refuses_unknown_keys_naming_them(where, key, message):
    """As the network files (YAML, TOML) do: a typo is not silently ignored (issue 16; the
    JSON form used to ignore every unknown key)."""
    s = build()
    d = s.to_dict()
    d["point_masses"] = [{"node": 0, "mass": 1.0}]
    d["planes"] = [{"node": 0, "normal": [0.0, 0.0, 1.0]}]
    target = d
    for step in where:
        target = target[step]
    target[key] = 1.0
    with pytest.raises(ValueError, match=message):
        Structure.from_dict(d)


def test_from_dict_optional_keys_default():
    d = build().to_dict()
    del d["velocities"]
    for rod in d["rods"]:
        del rod["damping"]
    for tendon in d["tendons"]:
        del tendon["damping"]
        del tendon["name"]
    s = Structure.from_dict(d)
    np.testing.assert_array_equal(s.node_velocity, np.zeros((6, 3)))
    np.testing.assert_array_equal(s.rod_damping, np.zeros(3))
    np.testing.assert_array_equal(s.tendon_damping, np.zeros(9))
    assert s.tendon_name == tuple(f"s{k}" for k in range(9))


@pytest.mark.parametrize("key", ["nodes", "rods", "tendons"])
def test_from_dict_missing_top_level_key(key):
    d = build().to_dict()
    del d[key]
    with pytest.raises(ValueError, match=names("missing", rf"\b{key}\b")):
        Structure.from_dict(d)


@pytest.mark.parametrize(
    "group, index, key",
    [
        ("rods", 1, "nodes"),
        ("rods", 2, "mass"),
        ("rods", 0, "length"),
        ("tendons", 2, "stiffness"),
        ("tendons", 5, "nodes"),
        ("tendons", 8, "rest_length"),
    ],
)
def test_from_dict_missing_element_key(group, index, key):
    d = build().to_dict()
    del d[group][index][key]
    with pytest.raises(ValueError, match=names(group, at(index), "missing", rf"'{key}'")):
        Structure.from_dict(d)


def test_from_dict_missing_key_message_format():
    d = build().to_dict()
    del d["tendons"][2]["stiffness"]
    with pytest.raises(ValueError, match=re.escape("tendons[2]: missing key 'stiffness'")):
        Structure.from_dict(d)


@pytest.mark.parametrize("bad", [[0, 1], "rod", 3, None])
def test_from_dict_rod_not_an_object(bad):
    d = build().to_dict()
    d["rods"][1] = bad
    with pytest.raises(ValueError, match=names("rods", at(1), "object")):
        Structure.from_dict(d)


@pytest.mark.parametrize("bad", [[0, 1], "t", 3.5])
def test_from_dict_tendon_not_an_object(bad):
    d = build().to_dict()
    d["tendons"][7] = bad
    with pytest.raises(ValueError, match=names("tendons", at(7), "object")):
        Structure.from_dict(d)


@pytest.mark.parametrize("key", ["nodes", "rods", "tendons"])
@pytest.mark.parametrize(
    "bad", [{"0": [0, 0, 0]}, "abc", 3, None], ids=["dict", "str", "int", "null"]
)
def test_from_dict_top_level_not_a_list(key, bad):
    d = build().to_dict()
    d[key] = bad
    with pytest.raises(ValueError, match=names(rf"\b{key}\b", "list")):
        Structure.from_dict(d)


@pytest.mark.parametrize("bad", [[1, 2], "structure", None, 3])
def test_from_dict_document_not_an_object(bad):
    with pytest.raises(ValueError):
        Structure.from_dict(bad)


def test_from_dict_validates_values_like_the_constructor():
    d = build().to_dict()
    d["tendons"][3]["stiffness"] = -1.0
    with pytest.raises(ValueError, match=names("tendons", at(3), "stiffness")):
        Structure.from_dict(d)
    d = build().to_dict()
    d["tendons"][6]["nodes"] = [4, 4]
    with pytest.raises(ValueError, match=names("tendons", at(6), "itself")):
        Structure.from_dict(d)
    d = build().to_dict()
    d["rods"][2]["nodes"] = [4, 9]
    with pytest.raises(ValueError, match=names("rods", at(2), "range")):
        Structure.from_dict(d)


# A value of the wrong type or shape inside one element of the JSON document must also be
# reported as a ValueError naming the element and its key (the promise of ``Structure`` and
# ``from_dict``), not as a bare NumPy message.
ELEMENT_TYPE_CASES = [
    ("rods", 1, "mass", "heavy"),
    ("rods", 2, "length", [2.0]),
    ("rods", 1, "nodes", [2, 3, 4]),
    ("rods", 1, "nodes", "ab"),
    ("tendons", 2, "nodes", 5),
    ("tendons", 4, "nodes", [3, 5, 1]),
    ("tendons", 2, "stiffness", [5.0]),
    ("tendons", 6, "rest_length", {"value": 1.0}),
    ("tendons", 3, "damping", "x"),
]


@pytest.mark.parametrize(
    "group, index, key, bad",
    ELEMENT_TYPE_CASES,
    ids=[f"{g}[{i}].{k}={b!r}" for g, i, k, b in ELEMENT_TYPE_CASES],
)
def test_from_dict_wrong_type_inside_element_names_element_and_key(group, index, key, bad):
    d = build().to_dict()
    d[group][index][key] = bad
    with pytest.raises(ValueError, match=names(group, at(index), key)):
        Structure.from_dict(d)


def test_from_dict_wrong_node_row_names_the_node():
    d = build().to_dict()
    d["nodes"][4] = [1.0, 2.0]
    with pytest.raises(ValueError, match=names("nodes", r"\[4\b")):
        Structure.from_dict(d)


# ------------------------------------------------------------------------------ repr
@pytest.mark.parametrize("size", [(3, 1), (10, 10)])
def test_repr_is_one_short_line_of_counts(size):
    """Not the arrays (a (10,10) shell's dataclass repr was 46,000 characters; issue 27)."""
    from tensegrity.model.shell import class1_shell

    s = class1_shell(*size)
    text = repr(s)
    assert len(text) < 200 and "\n" not in text
    assert text == (
        f"Structure(dim=3, {s.n_nodes} nodes, {s.n_rods} rods, {s.n_tendons} tendons, "
        f"mass {s.total_mass:.4g} kg)"
    )


def test_repr_counts_supports_joints_and_point_masses_in_the_singular_and_plural():
    from tensegrity.model.shell import class2_shell
    from test_kernel_system import crane, point_mass_between_anchors

    shell = class2_shell(4, 2, fixed_base=True)
    assert repr(shell) == (
        "Structure(dim=3, 32 nodes, 16 rods, 56 tendons, 8 fixed nodes, 8 joints, mass 16 kg)"
    )
    mass = point_mass_between_anchors()
    assert repr(mass) == (
        "Structure(dim=3, 3 nodes, 0 rods, 2 tendons, 2 fixed nodes, 1 point mass, mass 0.3 kg)"
    )
    assert repr(crane()) == (
        "Structure(dim=3, 4 nodes, 1 rod, 1 tendon, 2 fixed nodes, 1 point mass, 1 joint, "
        "mass 1.5 kg)"
    )
