"""Class k networks (bars that share a node: ball joints), supports, point masses, plane and line
constraints and planar structures in N, C_b, C_s and in every file format."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.io.formats import read_network, write_network
from tensegrity.model.connectivity import from_connectivity, merge_joints, to_connectivity
from tensegrity.model.planar import planar_two_rod
from tensegrity.model.shell import class2_shell
from tensegrity.model.structure import Structure

SUFFIXES = ["json", "yaml", "toml", "npz"]


def tripod_network():
    """Three bars meeting at an apex (node 0: a class 3 joint), feet 1-3 tied by a string
    triangle, a string from the apex to a fixed anchor (node 4) and a point mass on foot 2."""
    h, rho = 1.0, 0.6
    feet = [[rho * np.cos(a), rho * np.sin(a), 0.0] for a in 2 * np.pi * np.arange(3) / 3]
    N = np.array([[0, 0, h], *feet, [0, 0, 2.0]]).T
    C_b = np.array(
        [[1, -1, 0, 0, 0], [1, 0, -1, 0, 0], [-1, 0, 0, 1, 0]]
    )  # bar 2 starts at the apex
    C_s = np.array([[0, -1, 1, 0, 0], [0, 0, -1, 1, 0], [0, 1, 0, -1, 0], [-1, 0, 0, 0, 1]])
    return N, C_b, C_s


def test_shared_node_becomes_joined_rod_ends():
    N, C_b, C_s = tripod_network()
    with pytest.raises(
        ValueError,
        match=r"^bars: node 0 is an end of bars \[0, 1, 2\]; .*class 2 joint"
        r".*pass ball_joints=True",
    ):
        from_connectivity(N, C_b, C_s, tendon_rest_length=0.5, node_fixed=np.arange(5) == 4)
    mass = np.array([0, 0, 2.5, 0, 0.0])
    s = from_connectivity(
        N,
        C_b,
        C_s,
        tendon_rest_length=0.5,
        node_fixed=np.arange(5) == 4,
        node_point_mass=mass,
        ball_joints=True,
    )
    # node 0 -> nodes 0, 1, 2 (heads of bars 0, 1, tail of bar 2); node 2 -> foot end 4 and the
    # point mass 5; the others one node each, in N's order
    assert s.n_nodes == 8
    np.testing.assert_array_equal(s.rod_nodes, [[3, 0], [4, 1], [2, 6]])
    np.testing.assert_array_equal(s.joint_nodes, [[0, 1], [0, 2], [4, 5]])
    assert s.node_point_mass.tolist() == [0, 0, 0, 0, 0, 2.5, 0, 0]
    assert np.flatnonzero(s.node_fixed).tolist() == [7] and s.anchor_nodes.tolist() == [7]
    # strings go to the first node of a shared node: the end of its lowest-numbered bar
    np.testing.assert_array_equal(s.tendon_nodes, [[3, 4], [4, 6], [6, 3], [0, 7]])
    np.testing.assert_array_equal(s.node_position, N.T[[0, 0, 0, 1, 2, 2, 3, 4]])
    # and back: each joined group is one node again, in N's order
    back = to_connectivity(s)
    for got, want in zip(back, (N, C_b, C_s), strict=True):
        np.testing.assert_array_equal(got, want)
    merged = merge_joints(s)
    assert merged.node_fixed.tolist() == [False] * 4 + [True]
    assert merged.node_point_mass.tolist() == mass.tolist()
    # without the option a point mass on a bar's node is an error naming the field
    with pytest.raises(
        ValueError,
        match=r"^node_point_mass\[2\]: node 2 is an end of bars \[1\]; .*ball_joints=True",
    ):
        from_connectivity(
            N[:, :4],
            [[1, -1, 0, 0], [0, 0, -1, 1]],
            C_s[:1, :4],
            tendon_rest_length=0.5,
            node_point_mass=mass[:4],
        )


def test_class2_shell_round_trips_its_connectivity():
    """Lemma 18.1's merged nodes: 4nm - 2n(m-1) nodes, each joined node the end of two bars."""
    n, m = 4, 3
    s = class2_shell(n, m, fixed_base=True)
    N, C_b, C_s = to_connectivity(s)
    assert N.shape == (3, 4 * n * m - 2 * n * (m - 1)) and C_b.shape == (s.n_rods, N.shape[1])
    bars_at = np.abs(C_b).sum(axis=0)
    assert np.sum(bars_at == 2) == 2 * n * (m - 1) and np.all(bars_at >= 1)
    # the member vectors are the structure's, every library node sits on its merged node
    merged = merge_joints(s)
    np.testing.assert_allclose(N[:, merged.node_map].T, s.node_position, atol=1e-15)
    p = s.node_position
    np.testing.assert_allclose(
        (N @ C_b.T).T, p[s.rod_nodes[:, 1]] - p[s.rod_nodes[:, 0]], atol=1e-15
    )
    again = from_connectivity(
        N,
        C_b,
        C_s,
        tendon_rest_length=s.tendon_rest_length,
        node_fixed=merged.node_fixed,
        ball_joints=True,
    )
    assert again.joint_nodes.shape == s.joint_nodes.shape
    for got, want in zip(to_connectivity(again), (N, C_b, C_s), strict=True):
        np.testing.assert_array_equal(got, want)


def test_class2_shell_from_its_own_connectivity_moves_identically():
    """Built from N, C_b, C_s (strings on the other rod's end at some joints, other node
    numbering), the fixed-base shell under gravity follows class2_shell's trajectory."""
    s = class2_shell(3, 2, fixed_base=True)
    N, C_b, C_s = to_connectivity(s)
    merged = merge_joints(s)
    t = from_connectivity(
        N,
        C_b,
        C_s,
        rod_length=s.rod_length,
        tendon_rest_length=s.tendon_rest_length,
        node_fixed=merged.node_fixed,
        ball_joints=True,
    )
    assert not np.array_equal(t.tendon_nodes, s.tendon_nodes)  # a different layout, same structure
    options = dict(method="rk4", dt=1e-3, sample_dt=0.01, gravity=np.array([0.0, 0.0, -9.81]))
    a, b = simulate(s, (0.0, 0.3), **options), simulate(t, (0.0, 0.3), **options)
    assert a.status == 0 and b.status == 0
    lead_s = [np.flatnonzero(merged.node_map == i)[0] for i in range(N.shape[1])]
    lead_t = [np.flatnonzero(merge_joints(t).node_map == i)[0] for i in range(N.shape[1])]
    pa, pb = a.node_position[:, lead_s], b.node_position[:, lead_t]
    assert np.ptp(pa, axis=0).max() > 0.3  # it moves
    assert np.abs(pa - pb).max() < 1e-12


def supported_structure(dim=3):
    """No joints: a fixed rod end, an anchor, a point mass, a plane (3-D) and lines, velocities."""
    p = np.array([[0, 0, 0], [0, 1, 1], [1, 0, 0], [1.5, 0.5, 1], [2, 0, 2], [0.5, 1.0, 0.5]])[
        :, :dim
    ]
    lengths = np.linalg.norm(p[[1, 3]] - p[[0, 2]], axis=1)
    rng = np.random.default_rng(1)
    return Structure(
        node_position=p,
        node_velocity=np.where(np.arange(6)[:, None] < 4, rng.normal(size=(6, dim)), 0),
        rod_nodes=[[0, 1], [2, 3]],
        rod_mass=[1.0, 2.0],
        rod_length=lengths,
        tendon_nodes=[[4, 1], [5, 2], [5, 3], [1, 3], [0, 2]],
        tendon_stiffness=[50, 60, 70, 80, 90.0],
        tendon_rest_length=[0.5, 0.6, 0.7, 0.8, 0.9],
        tendon_damping=[0, 0.1, 0, 0, 0.2],
        node_fixed=np.arange(6) == 4,
        node_point_mass=[0, 0, 0, 0, 0, 0.3],
        **({"plane_nodes": [1], "plane_normal": [[0, 0, 1.0]]} if dim == 3 else {}),
        line_nodes=[3, 5],
        line_direction=np.eye(dim)[:2],
    )


def jointed_structure():
    """Two rods joined end to end, the first joined to an anchor, a payload point mass joined to
    the second's free end (as in docs/constraints.md), a plane on the joined node."""
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 0, 0], [1, 0, -1], [0, 0, 0], [1, 0, -1], [2, 0, 1.0]])
    return Structure(
        node_position=p,
        rod_nodes=[[0, 1], [2, 3]],
        rod_mass=[1.0, 1.5],
        rod_length=[1.0, 1.0],
        tendon_nodes=[[6, 2], [5, 6]],
        tendon_stiffness=[40.0, 50.0],
        tendon_rest_length=[0.5, 1.0],
        node_fixed=np.isin(np.arange(7), [4, 6]),
        node_point_mass=[0, 0, 0, 0, 0, 0.7, 0],
        joint_nodes=[[1, 2], [4, 0], [3, 5]],
        plane_nodes=[2],
        plane_normal=[[0, 1.0, 0]],
    )


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize(
    "make",
    [supported_structure, lambda: supported_structure(2), planar_two_rod],
    ids=["supports", "supports-2d", "planar-two-rod"],
)
def test_every_format_round_trips_structures_without_joints_exactly(make, suffix, tmp_path):
    s = make()
    path = tmp_path / f"s.{suffix}"
    write_network(path, s)
    assert read_network(path).to_dict() == s.to_dict()
    N, _, _ = to_connectivity(s)
    assert N.shape == (s.dim, s.n_nodes)


def same_merged(a: Structure, b: Structure) -> None:
    for got, want in zip(to_connectivity(a), to_connectivity(b), strict=True):
        np.testing.assert_array_equal(got, want)
    for got, want in zip(merge_joints(a)[1:], merge_joints(b)[1:], strict=True):
        np.testing.assert_array_equal(got, want)
    for field in (
        "rod_mass",
        "rod_length",
        "rod_damping",
        "tendon_stiffness",
        "tendon_rest_length",
        "tendon_damping",
    ):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert a.tendon_name == b.tendon_name and a.total_mass == b.total_mass


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize(
    "make",
    [lambda: class2_shell(3, 2, fixed_base=True), jointed_structure],
    ids=["class2-shell", "jointed"],
)
def test_every_format_round_trips_jointed_structures(make, suffix, tmp_path):
    """JSON keeps the library layout; the class k forms the same merged N, C_b, C_s, supports
    and parameters, and reading again what they read is exact."""
    s = make()
    path = tmp_path / f"s.{suffix}"
    write_network(path, s)
    once = read_network(path)
    if suffix == "json":
        assert once.to_dict() == s.to_dict()
        return
    same_merged(once, s)
    assert once.joint_nodes.size and once.has_constraints
    write_network(path, once)
    assert read_network(path).to_dict() == once.to_dict()


def test_jointed_structure_read_back_hangs_like_the_original(tmp_path):
    """The jointed structure from its YAML file (payload and anchor merged into the rods' nodes)
    follows the original's motion under gravity."""
    s = jointed_structure()
    write_network(tmp_path / "s.yaml", s)
    t = read_network(tmp_path / "s.yaml")
    assert t.n_nodes != s.n_nodes  # the anchor joined to node 0 is now node 0 fixed
    options = dict(method="rk4", dt=1e-3, sample_dt=0.01, gravity=np.array([0.0, 0.0, -9.81]))
    a, b = simulate(s, (0.0, 0.3), **options), simulate(t, (0.0, 0.3), **options)
    assert a.status == 0 and b.status == 0
    ms, mt = merge_joints(s), merge_joints(t)

    def lead(m):
        return [np.flatnonzero(m.node_map == i)[0] for i in range(m.N.shape[1])]

    pa, pb = a.node_position[:, lead(ms)], b.node_position[:, lead(mt)]
    assert np.ptp(pa, axis=0).max() > 0.05
    assert np.abs(pa - pb).max() < 1e-12


def test_what_the_class_k_forms_cannot_hold_is_refused_by_name(tmp_path):
    s = jointed_structure()
    zero = s.replace(
        tendon_nodes=[[6, 2], [1, 2]], tendon_name=("a", "b")
    )  # a string inside a joint
    twice = s.replace(
        tendon_nodes=[[6, 2], [1, 6]], tendon_name=("a", "b")
    )  # both to the same pair
    for bad, words in (
        (zero, "tendons[1] ('b'): joins nodes 1 and 2, which are joined by a ball joint"),
        (twice, "tendons[1] ('b'): joins the same joined nodes as tendons[0] ('a')"),
    ):
        for suffix in ("yaml", "toml", "npz"):
            path = tmp_path / f"s.{suffix}"
            with pytest.raises(ValueError) as info:
                write_network(path, bad)
            assert words in str(info.value) and "\n" not in str(info.value)
            assert not path.exists()
        write_network(tmp_path / "s.json", bad)  # the JSON form keeps it
        assert read_network(tmp_path / "s.json").to_dict() == bad.to_dict()


def test_planar_connectivity_has_two_rows():
    s = planar_two_rod()
    N, C_b, C_s = to_connectivity(s)
    assert N.shape == (2, 4)
    again = from_connectivity(
        N,
        C_b,
        C_s,
        rod_mass=s.rod_mass,
        rod_length=s.rod_length,
        tendon_rest_length=s.tendon_rest_length,
        tendon_name=s.tendon_name,
    )
    assert again.to_dict() == s.to_dict()


@pytest.mark.parametrize("suffix", SUFFIXES)
@pytest.mark.parametrize(
    "make",
    [lambda: class2_shell(3, 2, fixed_base=True), jointed_structure],
    ids=["class2-shell", "jointed"],
)
def test_keep_joints_round_trips_jointed_structures_exactly(make, suffix, tmp_path):
    """With keep_joints every rod keeps its end nodes and the joints are listed: identical."""
    s = make()
    path = tmp_path / f"s.{suffix}"
    write_network(path, s, keep_joints=True)
    assert read_network(path).to_dict() == s.to_dict()


def test_joints_and_shared_nodes_combine():
    """Explicit joint_nodes (pairs of N's nodes) join the first nodes of what they name."""
    N, C_b, C_s = tripod_network()
    N = np.hstack([N, N[:, [4]]])  # a second anchor on top of the first, joined to it
    s = from_connectivity(
        N,
        np.hstack([C_b, np.zeros((3, 1))]),
        np.hstack([C_s, np.zeros((4, 1))]),
        tendon_rest_length=0.5,
        node_fixed=np.arange(6) >= 4,
        joint_nodes=[[5, 4]],
        ball_joints=True,
    )
    np.testing.assert_array_equal(s.joint_nodes, [[0, 1], [0, 2], [7, 6]])
    with pytest.raises(ValueError, match=r"^joint_nodes\[1\]: node index 9 out of range \[0, 5\]"):
        from_connectivity(
            N,
            np.hstack([C_b, np.zeros((3, 1))]),
            np.hstack([C_s, np.zeros((4, 1))]),
            tendon_rest_length=0.5,
            node_fixed=np.arange(6) >= 4,
            joint_nodes=[[5, 9]],
            ball_joints=True,
        )
