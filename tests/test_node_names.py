"""Node names: ``Structure.node_name``, checked like the tendon names, kept by every structure
file (JSON, the readable YAML/TOML form, the connectivity ``.npz``, the material form, the
trajectory), and ``Structure.node_index`` (a name, or a 0-based index when no node has that
name)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from structures import crane
from tensegrity import class1_shell
from tensegrity.design.catalogue import prism
from tensegrity.design.files import read_design, write_design
from tensegrity.design.materials import MATERIALS, Cable, MemberDesign, SolidRod
from tensegrity.io.formats import read_network, write_network
from tensegrity.model.shell import class2_shell
from tensegrity.model.structure import Structure

LEGACY = __import__("pathlib").Path(__file__).parent / "data" / "legacy"


def named(structure: Structure, prefix: str = "p") -> Structure:
    return structure.replace(node_name=[f"{prefix}{k}" for k in range(structure.n_nodes)])


def test_default_names_and_a_given_name_kept_by_replace():
    s = prism(3)
    assert s.node_name == ("n0", "n1", "n2", "n3", "n4", "n5")
    t = named(s)
    assert t.node_name[4] == "p4"
    assert t.replace(rod_mass=[2.0, 2.0, 2.0]).node_name == t.node_name
    assert "node_names" not in s.to_dict()  # the default: the JSON form of before


@pytest.mark.parametrize(
    ("names", "message"),
    [
        (
            ["a", "b", "c", "d", "e", "a"],
            r"^node_name\[5\]: 'a' is also the name of node_name\[0\]",
        ),
        (["a", "b", "", "d", "e", "f"], r"^node_name\[2\]: must be a non-empty string"),
        (["a", "b", 3, "d", "e", "f"], r"^node_name\[2\]: must be a non-empty string"),
        (["a", "b"], r"^node_name: expected 6 names, got 2"),
        ("abcdef", r"^node_name: expected a sequence of names, got the text"),
        (["a", "b\x00", "c", "d", "e", "f"], r"^node_name\[1\]: must not contain a NUL"),
    ],
)
def test_bad_node_names_name_the_field(names, message):
    with pytest.raises(ValueError, match=message):
        prism(3).replace(node_name=names)


def test_node_index_prefers_a_name_to_an_index():
    s = prism(3).replace(node_name=["top", "5", "a", "b", "c", "d"])
    assert s.node_index("top") == 0
    assert s.node_index("5") == 1  # the node called "5", not node 5
    assert s.node_index("4") == 4  # no node called "4": index 4
    assert s.node_index(5) == 5
    with pytest.raises(
        KeyError, match=r"no node named 'x' \(the nodes are top, 5, a, b, c, \.\.\.\)"
    ):
        s.node_index("x")
    with pytest.raises(
        KeyError, match=r"node 6 out of range \[0, 5\] \(and no node is named .6.\)"
    ):
        s.node_index("6")
    with pytest.raises(KeyError, match=r"out of range"):
        s.node_index(-1)


@pytest.mark.parametrize("suffix", ["json", "yaml", "toml", "npz"])
def test_every_format_keeps_node_names(tmp_path, suffix):
    s = named(class1_shell(3, 2))
    path = tmp_path / f"s.{suffix}"
    write_network(path, s)
    back = read_network(path)
    assert back.node_name == s.node_name
    assert back.to_dict() == s.to_dict()


@pytest.mark.parametrize("suffix", ["yaml", "npz"])
def test_joined_nodes_keep_the_first_name(tmp_path, suffix):
    """A node shared by k rods (merged in the file) is named by the first of its nodes; the
    others read back as NAME.1, ..."""
    s = named(class2_shell(3, 2))
    path = tmp_path / f"s.{suffix}"
    write_network(path, s)
    back = read_network(path)
    where = dict(zip(back.node_name, back.node_position, strict=True))
    for a, b in np.sort(s.joint_nodes, axis=1):  # (pairs: a the lower node)
        lead = s.node_name[a]
        assert lead + ".1" in where and s.node_name[b] not in where
        np.testing.assert_array_equal(where[lead], s.node_position[a])
        np.testing.assert_array_equal(where[lead + ".1"], s.node_position[a])  # merged there
    assert len(set(back.node_name) & set(s.node_name)) == s.n_nodes - s.joint_nodes.shape[0]


def test_readable_file_keeps_hand_written_names(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(
        "nodes: {base: [0, 0, 0], tip: [0, 0, 1], 7: [1, 0, 0], right: [1, 0, 1]}\n"
        "rods: [{nodes: [base, tip]}, {nodes: [7, right]}]\n"
        "tendons: [{nodes: [base, 7], rest_length: 0.5}, {nodes: [tip, right], rest_length: 0.5}]\n"
    )
    s = read_network(path)
    assert s.node_name == ("base", "tip", "7", "right")
    assert s.node_index("7") == 2
    write_network(tmp_path / "t.yaml", s)
    assert "  base: [0.0, 0.0, 0.0]\n" in (tmp_path / "t.yaml").read_text()


def test_old_json_without_names_reads_with_the_default_names():
    data = json.loads((LEGACY / "shell31.json").read_text())
    assert "node_names" not in data
    s = Structure.from_dict(data)
    assert s.node_name == tuple(f"n{k}" for k in range(s.n_nodes))


def test_json_form_refuses_a_wrong_count_of_names():
    data = named(prism(3)).to_dict()
    data["node_names"] = data["node_names"][:2]
    with pytest.raises(ValueError, match=r"^structure.node_names: expected 6 names, got 2"):
        Structure.from_dict(data)


def test_material_form_keeps_node_names(tmp_path):
    s = named(prism(3))
    design = MemberDesign.of(
        s,
        rod_material=MATERIALS["steel"],
        rod_section=SolidRod(0.01),
        tendon_material=MATERIALS["dyneema"],
        tendon_section=Cable(0.002),
    )
    built = design.apply(s)
    write_design(tmp_path / "d.yaml", built, design)
    assert read_design(tmp_path / "d.yaml").structure.node_name == s.node_name


def test_trajectory_keeps_node_names(tmp_path):
    from tensegrity import simulate
    from tensegrity.io.trajectory import read_trajectory, write_trajectory

    s = named(prism(3))
    write_trajectory(tmp_path / "t.h5", simulate(s, (0.0, 0.01), sample_dt=0.01))
    assert read_trajectory(tmp_path / "t.h5").structure.node_name == s.node_name


def _crane(tmp_path, names):
    """A 1 m rod pinned at node 0, its head (node 1) held by tendons to anchors (0, +-1, 1)."""
    s = crane(node_name=names)
    path = tmp_path / "crane.yaml"
    write_network(path, s)
    return path


def test_design_loads_by_node_name_or_index(tmp_path, capsys):
    """``design --load CASE:NODE:F``: NODE a name of the file's nodes or an index; digits are
    the node of that name if there is one ("3" below is node 1, the head), else an index."""
    from tensegrity.cli.main import main

    path = _crane(tmp_path, ["pin", "3", "left", "right"])
    reports = []
    for node in ("3", "1"):  # the node named "3"; index 1 (no node is named "1")
        out = tmp_path / f"out{node}"
        argv = ["design", "--structure", str(path), "--material", "steel,dyneema"]
        assert main([*argv, "--load", f"down:{node}:0,0,-1000", "-o", str(out)]) == 0
        reports.append(json.loads((out / "design.json").read_text()))
    capsys.readouterr()
    assert reports[0]["total_mass_kg"] == reports[1]["total_mass_kg"] > 0
    for node, message in (
        ("head", "--load down:head: no node named 'head' (the nodes are pin, 3, left, right)"),
        ("7", "--load down:7: node 7 out of range [0, 3] (and no node is named '7')"),
    ):
        argv = ["design", "--structure", str(path), "--material", "steel,dyneema"]
        assert main([*argv, "--load", f"down:{node}:0,0,-1", "-o", str(tmp_path / "x")]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err, err
        assert not (tmp_path / "x").exists()
