"""The class 1 shell generator against ``shared/spec/shell-topology.md``.

The expected connectivity below is transcribed by hand from the spec's table (one ``if`` per
column of each row); it does not use the module's own table.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from tensegrity.model.shell import class1_shell, shell_node_index, shell_tendons
from tensegrity.model.structure import Structure

SIZES = [(n, m) for n in range(3, 9) for m in range(1, 6)]


# ------------------------------------------------------------ the spec's table
def node(k: int, i: int, j: int, n: int) -> int:
    """Spec: node ``p_k,ij`` has index ``4((j-1)n + (i-1)) + (k-1)``, ``i`` cyclic (0 = n)."""
    i = (i - 1) % n + 1
    return 4 * ((j - 1) * n + (i - 1)) + (k - 1)


def expected_tendons(n: int, m: int, primal: bool) -> list[tuple[str, int, int]]:
    """The spec's table as ``(name, tail, head)``: a row ``head - tail`` is ``t = head - tail``."""
    result = []
    for j in range(1, m + 1):
        for i in range(1, n + 1):

            def add(alpha, head, tail, i=i, j=j):
                result.append((f"t{alpha}_{i}_{j}", node(*tail, n=n), node(*head, n=n)))

            # t1: j = 1: p2(i,1) - p1(i+1,1); 1 < j <= m: p2(i,j) - p4(i,j-1)
            if j == 1:
                add(1, (2, i, 1), (1, i + 1, 1))
            else:
                add(1, (2, i, j), (4, i, j - 1))
            # t2: j = 1: p1(i,1) - p1(i+1,1); 1 < j <= m: p1(i,j) - p4(i,j-1)
            if j == 1:
                add(2, (1, i, 1), (1, i + 1, 1))
            else:
                add(2, (1, i, j), (4, i, j - 1))
            # t3: p3(i-1,j) - p1(i,j), every stage
            add(3, (3, i - 1, j), (1, i, j))
            # t4: p2(i,j) - p3(i-1,j), every stage
            add(4, (2, i, j), (3, i - 1, j))
            # t5: p4(i,j) - p2(i,j), every stage
            add(5, (4, i, j), (2, i, j))
            # t6: j < m: p1(i+1,j+1) - p4(i,j); j = m: p4(i+1,m) - p4(i,m)
            if j < m:
                add(6, (1, i + 1, j + 1), (4, i, j))
            else:
                add(6, (4, i + 1, m), (4, i, m))
            # t7: j < m: p3(i,j) - p1(i+1,j+1); j = m: p3(i,m) - p4(i+1,m)
            if j < m:
                add(7, (3, i, j), (1, i + 1, j + 1))
            else:
                add(7, (3, i, m), (4, i + 1, m))
            # t8: p2(i,j) - p3(i,j), every stage
            add(8, (2, i, j), (3, i, j))
            if primal:
                continue  # Definition 18.6: no t9, no t10
            # t9: absent at j = 1 (it is -t1); j > 1: p1(i+1,j) - p2(i,j)
            if j > 1:
                add(9, (1, i + 1, j), (2, i, j))
            # t10: j < m: p4(i+1,j) - p3(i,j); absent at j = m (it is -t7)
            if j < m:
                add(10, (4, i + 1, j), (3, i, j))
    return result


def as_set(tendons):
    return {(name, (tail, head)) for name, tail, head in tendons}


def structure_tendons(s: Structure):
    return {
        (name, (int(a), int(b))) for name, (a, b) in zip(s.tendon_name, s.tendon_nodes, strict=True)
    }


def describe_difference(got: set, want: set) -> str:
    return f"missing {sorted(want - got)[:6]}, unexpected {sorted(got - want)[:6]}"


# --------------------------------------------------------------- connectivity
@pytest.mark.parametrize("primal", [False, True], ids=["full", "primal"])
@pytest.mark.parametrize("n, m", SIZES)
def test_shell_tendons_match_spec_table(n, m, primal):
    got = as_set(shell_tendons(n, m, primal=primal))
    want = as_set(expected_tendons(n, m, primal))
    assert got == want, describe_difference(got, want)


@pytest.mark.parametrize("primal", [False, True], ids=["full", "primal"])
@pytest.mark.parametrize("n, m", SIZES)
def test_class1_shell_structure_matches_spec_table(n, m, primal):
    s = class1_shell(n, m, primal=primal)
    got = structure_tendons(s)
    want = as_set(expected_tendons(n, m, primal))
    assert got == want, describe_difference(got, want)


@pytest.mark.parametrize("n, m", [(3, 1), (4, 3), (7, 5)])
def test_tendons_listed_element_by_element_alpha_ascending(n, m):
    names = [name for name, _, _ in shell_tendons(n, m)]
    assert names == [name for name, _, _ in expected_tendons(n, m, False)]
    assert list(class1_shell(n, m).tendon_name) == names


# A few entries computed by hand from the spec (so that a slip in ``node`` above cannot hide
# a slip in the generator): (n, m, name) -> (tail, head).
HAND_ENTRIES = {
    (3, 1, "t1_1_1"): (4, 1),  # p2(1,1)=1 - p1(2,1)=4
    (3, 1, "t2_3_1"): (0, 8),  # p1(3,1)=8 - p1(4=1,1)=0
    (3, 1, "t3_1_1"): (0, 10),  # p3(0=3,1)=10 - p1(1,1)=0
    (3, 1, "t6_3_1"): (11, 3),  # top: p4(4=1,1)=3 - p4(3,1)=11
    (3, 1, "t7_3_1"): (3, 10),  # top: p3(3,1)=10 - p4(1,1)=3
    (4, 3, "t6_4_2"): (31, 32),  # p1(1,3)=32 - p4(4,2)=31
    (4, 3, "t7_2_3"): (43, 38),  # top: p3(2,3)=38 - p4(3,3)=43
    (4, 3, "t9_1_2"): (17, 20),  # p1(2,2)=20 - p2(1,2)=17
    (4, 3, "t10_4_1"): (14, 3),  # p4(1,1)=3 - p3(4,1)=14
    (4, 3, "t2_3_2"): (11, 24),  # p1(3,2)=24 - p4(3,1)=11
    (4, 3, "t1_2_3"): (23, 37),  # p2(2,3)=37 - p4(2,2)=23
    (4, 3, "t4_1_3"): (46, 33),  # p2(1,3)=33 - p3(0=4,3)=46
    (4, 3, "t5_2_1"): (5, 7),  # p4(2,1)=7 - p2(2,1)=5
    (4, 3, "t8_3_2"): (26, 25),  # p2(3,2)=25 - p3(3,2)=26
}


@pytest.mark.parametrize(
    "key", list(HAND_ENTRIES), ids=[f"{k[0]}x{k[1]}-{k[2]}" for k in HAND_ENTRIES]
)
def test_hand_computed_entries(key):
    n, m, name = key
    table = {nm: (tail, head) for nm, tail, head in shell_tendons(n, m)}
    assert table[name] == HAND_ENTRIES[key]
    s = class1_shell(n, m)
    k = s.tendon_index(name)
    assert tuple(int(x) for x in s.tendon_nodes[k]) == HAND_ENTRIES[key]


@pytest.mark.parametrize("n, m", [(3, 1), (5, 2), (4, 4)])
def test_absent_tendons(n, m):
    names = {name for name, _, _ in shell_tendons(n, m)}
    for i in range(1, n + 1):
        assert f"t9_{i}_1" not in names  # t9(i,1) = -t1(i,1)
        assert f"t10_{i}_{m}" not in names  # t10(i,m) = -t7(i,m)
        for j in range(2, m + 1):
            assert f"t9_{i}_{j}" in names
        for j in range(1, m):
            assert f"t10_{i}_{j}" in names
    primal = {name for name, _, _ in shell_tendons(n, m, primal=True)}
    assert not {x for x in primal if x.startswith(("t9_", "t10_"))}
    assert primal == {x for x in names if not x.startswith(("t9_", "t10_"))}


# ----------------------------------------------------------------- counts
@pytest.mark.parametrize("n, m", SIZES)
def test_counts(n, m):
    s = class1_shell(n, m)
    assert s.n_nodes == 4 * n * m
    assert s.n_rods == 2 * n * m
    assert s.n_tendons == n * (10 * m - 2)
    assert len(shell_tendons(n, m)) == n * (10 * m - 2)
    assert s.n_coordinates == 12 * n * m
    assert s.n_dof == 10 * n * m
    p = class1_shell(n, m, primal=True)
    assert p.n_tendons == 8 * n * m
    assert len(shell_tendons(n, m, primal=True)) == 8 * n * m


def test_paper_example_has_24_tendons():
    assert class1_shell(3, 1).n_tendons == 24
    assert class1_shell().n_tendons == 24  # defaults n = 3, m = 1


@pytest.mark.parametrize("n, m", [(3, 1), (4, 2), (8, 5)])
def test_tendon_names_unique_and_well_formed(n, m):
    for primal in (False, True):
        names = [name for name, _, _ in shell_tendons(n, m, primal=primal)]
        assert len(set(names)) == len(names)
        for name in names:
            alpha, i, j = (int(x) for x in name[1:].split("_"))
            assert name == f"t{alpha}_{i}_{j}"
            assert 1 <= alpha <= 10 and 1 <= i <= n and 1 <= j <= m


@pytest.mark.parametrize("n, m", SIZES)
def test_no_tendon_doubles_a_rod_or_another_tendon(n, m):
    s = class1_shell(n, m)
    pairs = [frozenset(map(int, row)) for row in s.tendon_nodes]
    assert len(set(pairs)) == len(pairs)
    rods = {frozenset(map(int, row)) for row in s.rod_nodes}
    assert not rods & set(pairs)
    assert all(len(p) == 2 for p in pairs)


# ------------------------------------------------------------ node numbering
@pytest.mark.parametrize("n, m", [(3, 1), (3, 4), (6, 2), (8, 5)])
def test_node_index_follows_stacking_order(n, m):
    # q = [q_11 ... q_n1, q_12 ... q_n2, ...], each q_ij over p1..p4: k fastest, then i, then j.
    order = [
        shell_node_index(k, i, j, n)
        for j in range(1, m + 1)
        for i in range(1, n + 1)
        for k in range(1, 5)
    ]
    assert order == list(range(4 * n * m))


@pytest.mark.parametrize("n, m", [(3, 2), (5, 3), (8, 5)])
def test_node_index_formula(n, m):
    for k, i, j in itertools.product(range(1, 5), range(1, n + 1), range(1, m + 1)):
        assert shell_node_index(k, i, j, n) == 4 * ((j - 1) * n + (i - 1)) + (k - 1)


def test_node_index_examples_and_cyclic_i():
    assert shell_node_index(1, 1, 1, 3) == 0
    assert shell_node_index(4, 3, 1, 3) == 11
    assert shell_node_index(1, 1, 2, 3) == 12
    assert shell_node_index(3, 2, 3, 5) == 4 * (2 * 5 + 1) + 2
    # i is cyclic: i + n = i, 0 = n
    assert shell_node_index(2, 0, 2, 4) == shell_node_index(2, 4, 2, 4) == 4 * (4 + 3) + 1
    assert shell_node_index(3, 5, 1, 4) == shell_node_index(3, 1, 1, 4) == 2
    assert shell_node_index(1, -1, 1, 4) == shell_node_index(1, 3, 1, 4) == 8


@pytest.mark.parametrize("n, m", SIZES)
def test_rods_join_p1_p2_and_p3_p4(n, m):
    s = class1_shell(n, m)
    rods = [tuple(int(x) for x in row) for row in s.rod_nodes]
    assert rods == [(2 * r, 2 * r + 1) for r in range(2 * n * m)]
    for i, j in itertools.product(range(1, n + 1), range(1, m + 1)):
        e = (j - 1) * n + (i - 1)
        assert rods[2 * e] == (node(1, i, j, n), node(2, i, j, n))  # r1 = p2 - p1
        assert rods[2 * e + 1] == (node(3, i, j, n), node(4, i, j, n))  # r2 = p4 - p3
    counts = np.bincount(s.rod_nodes.ravel(), minlength=s.n_nodes)
    assert np.all(counts == 1)


# -------------------------------------------------------------- the layout
def rod_lengths(s: Structure) -> np.ndarray:
    p = s.node_position
    return np.linalg.norm(p[s.rod_nodes[:, 1]] - p[s.rod_nodes[:, 0]], axis=1)


def tendon_lengths(s: Structure) -> np.ndarray:
    p = s.node_position
    return np.linalg.norm(p[s.tendon_nodes[:, 1]] - p[s.tendon_nodes[:, 0]], axis=1)


def rotation_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


LAYOUTS = [
    {},
    {"rod_length": 2.5},
    {"radius": 1.3},
    {"stage_height": 0.4},
    {"twist": 0.3},
    {"rod_length": 0.7, "radius": 0.9, "stage_height": 1.1, "twist": -0.2},
]


@pytest.mark.parametrize("params", LAYOUTS, ids=[str(p) for p in LAYOUTS])
@pytest.mark.parametrize("n, m", [(3, 1), (4, 2), (6, 3), (8, 5)])
def test_nodes_on_one_cylinder_and_rods_exact(n, m, params):
    s = class1_shell(n, m, **params)
    p = s.node_position
    radius = np.hypot(p[:, 0], p[:, 1])
    np.testing.assert_allclose(radius, radius[0], rtol=0, atol=1e-12)
    if "radius" in params:
        np.testing.assert_allclose(radius, params["radius"], rtol=0, atol=1e-12)
    L = params.get("rod_length", 1.0)
    np.testing.assert_array_equal(s.rod_length, np.full(2 * n * m, L))
    np.testing.assert_allclose(rod_lengths(s), L, rtol=0, atol=1e-12)


@pytest.mark.parametrize("primal", [False, True], ids=["full", "primal"])
@pytest.mark.parametrize("n, m", SIZES)
def test_every_tendon_taut_with_default_rest_length(n, m, primal):
    s = class1_shell(n, m, primal=primal)
    lengths = tendon_lengths(s)
    assert np.all(lengths > s.tendon_rest_length)
    assert np.all(s.tendon_rest_length > 0)
    # documented default: half the shortest tendon of the initial layout
    np.testing.assert_allclose(s.tendon_rest_length, 0.5 * lengths.min(), rtol=1e-12)


@pytest.mark.parametrize("params", LAYOUTS[1:], ids=[str(p) for p in LAYOUTS[1:]])
def test_every_tendon_taut_with_other_layouts(params):
    s = class1_shell(5, 3, **params)
    assert np.all(tendon_lengths(s) > s.tendon_rest_length)


@pytest.mark.parametrize("params", LAYOUTS, ids=[str(p) for p in LAYOUTS])
@pytest.mark.parametrize("n, m", [(3, 1), (4, 3), (7, 2), (8, 5)])
def test_n_fold_symmetry(n, m, params):
    p = class1_shell(n, m, **params).node_position
    rotate = rotation_z(2 * math.pi / n)
    for k, i, j in itertools.product(range(1, 5), range(1, n + 1), range(1, m + 1)):
        np.testing.assert_allclose(
            rotate @ p[node(k, i, j, n)],
            p[node(k, i + 1, j, n)],
            rtol=0,
            atol=1e-12,
            err_msg=f"p{k}({i},{j})",
        )


@pytest.mark.parametrize("n, m", [(3, 2), (5, 4)])
def test_symmetry_test_would_catch_a_broken_layout(n, m):
    # control: rotating by a wrong angle does not map the layout onto itself
    p = class1_shell(n, m).node_position
    rotate = rotation_z(2 * math.pi / n + 0.01)
    assert not np.allclose(rotate @ p[node(1, 1, 1, n)], p[node(1, 2, 1, n)], atol=1e-6)


@pytest.mark.parametrize("h", [0.3, 1.0, 1.7])
@pytest.mark.parametrize("n, m", [(3, 1), (5, 4)])
def test_stage_height_respected(n, m, h):
    p = class1_shell(n, m, stage_height=h).node_position
    z = p[:, 2]
    for i, j in itertools.product(range(1, n + 1), range(1, m + 1)):
        # a stage spans one stage height from p1 (bottom) to p4 (top)
        assert z[node(4, i, j, n)] - z[node(1, i, j, n)] == pytest.approx(h, abs=1e-12)
        if j < m:
            assert z[node(1, i, j + 1, n)] - z[node(1, i, j, n)] == pytest.approx(h, abs=1e-12)
    assert z.max() - z.min() == pytest.approx(m * h, abs=1e-12)


@pytest.mark.parametrize("n, m", [(3, 1), (5, 4)])
def test_default_stage_height_is_rod_length(n, m):
    z = class1_shell(n, m, rod_length=1.7).node_position[:, 2]
    assert z.max() - z.min() == pytest.approx(m * 1.7, abs=1e-12)


@pytest.mark.parametrize("twist", [0.0, 0.25, -0.6, 2.0])
@pytest.mark.parametrize("n, m", [(3, 3), (6, 4)])
def test_twist_respected(n, m, twist):
    p = class1_shell(n, m, twist=twist).node_position
    angle = np.arctan2(p[:, 1], p[:, 0])
    for k, i, j in itertools.product(range(1, 5), range(1, n + 1), range(1, m)):
        step = angle[node(k, i, j + 1, n)] - angle[node(k, i, j, n)]
        # compare angles modulo 2 pi
        assert abs(np.exp(1j * step) - np.exp(1j * twist)) < 1e-12, (k, i, j)


@pytest.mark.parametrize("radius", [0.8, 1.0, 3.0])
def test_radius_respected(radius):
    p = class1_shell(4, 2, radius=radius).node_position
    np.testing.assert_allclose(np.hypot(p[:, 0], p[:, 1]), radius, rtol=0, atol=1e-12)


@pytest.mark.parametrize("n, m", [(3, 1), (4, 2), (6, 3), (8, 5)])
def test_default_layout_nodes_distinct(n, m):
    # spec: no two rods touch; at least no two nodes of the default layout coincide
    p = class1_shell(n, m).node_position
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)
    d[np.diag_indices_from(d)] = np.inf
    assert d.min() > 1e-3


def min_rod_distance(s: Structure, samples: int = 401) -> float:
    """Smallest distance between two rods: exact point-to-segment distance from points sampled
    along one rod (error at most the sample spacing)."""
    p = s.node_position
    a, b = p[s.rod_nodes[:, 0]], p[s.rod_nodes[:, 1]]
    u = np.linspace(0.0, 1.0, samples)
    best = np.inf
    for r in range(s.n_rods - 1):
        points = a[r] + u[:, None] * (b[r] - a[r])  # (samples, 3)
        q0, d = a[r + 1 :], b[r + 1 :] - a[r + 1 :]  # (others, 3)
        rel = points[None, :, :] - q0[:, None, :]
        t = np.clip(np.einsum("osk,ok->os", rel, d) / np.einsum("ok,ok->o", d, d)[:, None], 0, 1)
        gap = np.linalg.norm(rel - t[..., None] * d[:, None, :], axis=-1)
        best = min(best, float(gap.min()))
    return best


@pytest.mark.parametrize("n, m", [(3, 1), (4, 2), (6, 3), (8, 5)])
def test_default_layout_rods_do_not_touch(n, m):
    # spec: "Every node of the class 1 shell belongs to exactly one rod; no two rods touch."
    s = class1_shell(n, m)
    spacing = 1.0 / 400  # rod length 1
    assert min_rod_distance(s) > 10 * spacing


def test_other_parameters_are_applied():
    s = class1_shell(4, 2, rod_mass=2.5, stiffness=321.0, rest_length=0.05, damping=0.7)
    np.testing.assert_array_equal(s.rod_mass, np.full(16, 2.5))
    np.testing.assert_array_equal(s.tendon_stiffness, np.full(s.n_tendons, 321.0))
    np.testing.assert_array_equal(s.tendon_rest_length, np.full(s.n_tendons, 0.05))
    np.testing.assert_array_equal(s.tendon_damping, np.full(s.n_tendons, 0.7))


def test_numpy_integer_sizes_accepted():
    s = class1_shell(np.int64(4), np.int64(2))
    assert s.n_nodes == 32


# ------------------------------------------------------------- bad arguments
BAD_N = [2, 1, 0, -3, 3.0, 4.5, "4", None, True, False]
BAD_M = [0, -1, 1.0, 2.5, "2", None, True, False]


@pytest.mark.parametrize("bad", BAD_N, ids=[repr(b) for b in BAD_N])
def test_bad_n(bad):
    with pytest.raises(ValueError, match=r"\bn\b"):
        class1_shell(bad, 2)
    with pytest.raises(ValueError, match=r"\bn\b"):
        shell_tendons(bad, 2)


@pytest.mark.parametrize("bad", BAD_M, ids=[repr(b) for b in BAD_M])
def test_bad_m(bad):
    with pytest.raises(ValueError, match=r"\bm\b"):
        class1_shell(4, bad)
    with pytest.raises(ValueError, match=r"\bm\b"):
        shell_tendons(4, bad)


BAD_LAYOUT = [
    ("rod_length", 0.0),
    ("rod_length", -1.0),
    ("rod_length", math.nan),
    ("rod_length", math.inf),
    ("stage_height", 0.0),
    ("stage_height", -0.5),
    ("stage_height", 2.0),  # must be < 2 rod_length
    ("stage_height", 3.0),
    ("stage_height", math.nan),
    ("radius", 0.0),
    ("radius", -1.0),
    ("radius", 0.1),  # too small for a rod of length 1 to span a stage of height 1
    ("radius", math.nan),
    ("radius", math.inf),
    ("radius", 1e308),  # rods lost in the round-off of the coordinates (blamed rods[0].length)
    ("radius", 1e10),
    ("rod_length", 1e-320),  # its square underflows (blamed rods[0].length)
    ("twist", math.nan),
    ("twist", math.inf),
]


@pytest.mark.parametrize("param, bad", BAD_LAYOUT, ids=[f"{p}={b}" for p, b in BAD_LAYOUT])
def test_bad_layout_parameter_names_the_parameter(param, bad):
    with pytest.raises(ValueError, match=f"^{param}"):
        class1_shell(4, 2, **{param: bad})


BAD_PHYSICAL = [
    ("rod_mass", 0.0, "mass"),
    ("rod_mass", -1.0, "mass"),
    ("stiffness", 0.0, "stiffness"),
    ("stiffness", math.nan, "stiffness"),
    ("rest_length", -0.1, "rest_length"),
    ("damping", -0.1, "damping"),
]


@pytest.mark.parametrize(
    "param, bad, name", BAD_PHYSICAL, ids=[f"{p}={b}" for p, b, _ in BAD_PHYSICAL]
)
def test_bad_physical_parameter_names_the_field(param, bad, name):
    with pytest.raises(ValueError, match=name):
        class1_shell(4, 2, **{param: bad})


NON_NUMERIC_LAYOUT = [
    ("rod_length", "abc"),
    ("rod_length", None),
    ("stage_height", "h"),
    ("radius", "wide"),
    ("radius", [1.0]),
    ("twist", "x"),
]


@pytest.mark.parametrize(
    "param, bad", NON_NUMERIC_LAYOUT, ids=[f"{p}={b!r}" for p, b in NON_NUMERIC_LAYOUT]
)
def test_non_numeric_layout_parameter_names_the_parameter(param, bad):
    # a value that is not a number at all is a bad parameter too: ValueError naming it
    with pytest.raises(ValueError, match=param):
        class1_shell(4, 2, **{param: bad})
