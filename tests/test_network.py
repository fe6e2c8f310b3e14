"""Any class 1 network: N, C_b, C_s in and out, the readable YAML/TOML form, the .npz form,
errors."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest
import yaml

from tensegrity import artificial_damping, class1_shell
from tensegrity.io.formats import network_from_dict, network_to_dict, read_network, write_network
from tensegrity.model.connectivity import from_connectivity, to_connectivity
from tensegrity.physics import dynamics


def varied_shell():
    """A damped (3,2) shell with per-member masses, stiffnesses, rest lengths and velocities."""
    rng = np.random.default_rng(4)
    shell = artificial_damping(class1_shell(3, 2))
    return shell.replace(
        rod_mass=rng.uniform(0.5, 2.0, shell.n_rods),
        tendon_stiffness=rng.uniform(50, 150, shell.n_tendons),
        tendon_rest_length=rng.uniform(0.2, 0.4, shell.n_tendons),
        node_velocity=rng.normal(size=(shell.n_nodes, 3)),
    )


def test_connectivity_matrices_reproduce_the_member_vectors():
    """B = N C_b^T and S = N C_s^T are the rod and tendon vectors (head minus tail)."""
    s = varied_shell()
    N, C_b, C_s = to_connectivity(s)
    assert N.shape == (3, s.n_nodes) and C_b.shape == (s.n_rods, s.n_nodes)
    assert C_s.shape == (s.n_tendons, s.n_nodes)
    p = s.node_position
    np.testing.assert_array_equal((N @ C_b.T).T, p[s.rod_nodes[:, 1]] - p[s.rod_nodes[:, 0]])
    np.testing.assert_array_equal((N @ C_s.T).T, dynamics.tendon_vectors(s, p))
    # every row: one -1, one +1
    for C in (C_b, C_s):
        assert np.all(np.sort(C, axis=1)[:, [0, -1]] == [-1, 1])
        assert np.all(np.abs(C).sum(axis=1) == 2)
    # C_b^T C_b is the bar "Laplacian": each node in exactly one bar (class 1)
    assert np.all(np.diag(C_b.T @ C_b) == 1)


def test_from_connectivity_round_trip():
    s = varied_shell()
    N, C_b, C_s = to_connectivity(s)
    again = from_connectivity(
        N,
        C_b,
        C_s,
        rod_mass=s.rod_mass,
        rod_length=s.rod_length,
        rod_damping=s.rod_damping,
        tendon_stiffness=s.tendon_stiffness,
        tendon_rest_length=s.tendon_rest_length,
        tendon_damping=s.tendon_damping,
        tendon_name=s.tendon_name,
        node_velocity=s.node_velocity.T,
    )
    assert again.to_dict() == s.to_dict()
    # Defaults: bar lengths from N (to round-off), scalars broadcast.
    import scipy.sparse as sp

    sparse = from_connectivity(N, sp.csr_matrix(C_b), s.tendon_incidence, tendon_rest_length=0.3)
    assert np.array_equal(sparse.tendon_nodes, s.tendon_nodes)
    plain = from_connectivity(N, C_b, C_s, tendon_rest_length=0.3)
    np.testing.assert_allclose(plain.rod_length, s.rod_length, rtol=1e-15)
    assert np.all(plain.rod_mass == 1.0) and np.all(plain.tendon_stiffness == 100.0)
    assert np.all(plain.tendon_rest_length == 0.3) and plain.tendon_name[0] == "s0"


def test_prestrain_sets_rest_lengths():
    """eps = (l - L0) / L0 in the configuration N: the tension is k l eps / (1 + eps)."""
    s = class1_shell(3, 1)
    N, C_b, C_s = to_connectivity(s)
    eps = np.linspace(0.01, 0.2, s.n_tendons)
    p = from_connectivity(N, C_b, C_s, tendon_prestrain=eps, tendon_stiffness=80.0)
    length = dynamics.tendon_lengths(p, p.node_position)
    np.testing.assert_allclose(
        (length - p.tendon_rest_length) / p.tendon_rest_length, eps, rtol=1e-12
    )
    tension = dynamics.tendon_tensions(p, p.node_position)
    np.testing.assert_allclose(tension, 80.0 * length * eps / (1 + eps), rtol=1e-12)


@pytest.mark.parametrize("suffix", ["json", "yaml", "yml", "toml", "npz"])
def test_every_format_round_trips_exactly(tmp_path, suffix):
    s = varied_shell()
    path = tmp_path / f"s.{suffix}"
    assert write_network(path, s) == path
    assert read_network(path).to_dict() == s.to_dict()
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name]  # no temporary left


def test_readable_form_is_readable_and_uses_defaults(tmp_path):
    """Shared values go to defaults; YAML and TOML hold the same document."""
    s = class1_shell(3, 1)
    data = network_to_dict(s)
    assert data["defaults"]["tendon"] == {
        "stiffness": 100.0,
        "rest_length": s.tendon_rest_length[0],
        "damping": 0.0,
    }
    assert data["tendons"][0] == {"name": "t1_1_1", "nodes": ["n4", "n1"]}
    assert "velocities" not in data  # all zero
    write_network(tmp_path / "s.yaml", s)
    write_network(tmp_path / "s.toml", s)
    text = (tmp_path / "s.yaml").read_text()
    assert "  n0: [0.6123724356957946, 0.0, 0.0]\n" in text
    assert "- {name: t1_1_1, nodes: [n4, n1]}\n" in text
    assert yaml.safe_load(text) == data
    toml_text = (tmp_path / "s.toml").read_text()
    assert '[[tendons]]\nname = "t1_1_1"\nnodes = [\n    "n4",\n    "n1",\n]\n' in toml_text
    assert tomllib.loads(toml_text) == data


def test_hand_written_yaml_with_names_prestrain_and_list_nodes():
    doc = """
nodes:
  base: [0, 0, 0]
  tip: [0, 0, 1]
  left: [1, 0, 0]
  right: [1, 0, 1]
defaults:
  tendon: {stiffness: 50, prestrain: 0.1}
rods:
  - {nodes: [base, tip], mass: 2}
  - {nodes: [left, right]}
tendons:
  - {name: bottom, nodes: [base, left]}
  - {name: top, nodes: [tip, right], rest_length: 0.5, damping: 1.5}
"""
    s = network_from_dict(yaml.safe_load(doc))
    assert s.rod_mass.tolist() == [2.0, 1.0] and s.rod_length.tolist() == [1.0, 1.0]
    assert s.tendon_name == ("bottom", "top")
    np.testing.assert_allclose(s.tendon_rest_length, [1 / 1.1, 0.5], rtol=1e-15)
    assert s.tendon_stiffness.tolist() == [50.0, 50.0] and s.tendon_damping.tolist() == [0.0, 1.5]
    listed = network_from_dict(
        {
            "nodes": [[0, 0, 0], [0, 0, 1], [1, 0, 0], [1, 0, 1]],
            "rods": [{"nodes": [0, 1]}, {"nodes": [2, 3]}],
            "tendons": [{"nodes": [0, 2], "rest_length": 0.9}],
        }
    )
    assert listed.tendon_nodes.tolist() == [[0, 2]] and listed.tendon_name == ("s0",)
    # YAML reads a node called 1 as an integer: such names work too
    numbered = network_from_dict(
        yaml.safe_load(
            "nodes: {1: [0, 0, 0], 2: [0, 0, 1], 3: [1, 0, 0], 4: [1, 0, 1]}\n"
            "rods: [{nodes: [1, 2]}, {nodes: [3, 4]}]\n"
            "tendons: [{nodes: [1, 3], rest_length: 0.9}]\n"
        )
    )
    assert numbered.tendon_nodes.tolist() == [[0, 2]]


# ------------------------------------------------------------------------------- errors
def square():
    """Two parallel bars, two strings: N (3, 4), C_b, C_s."""
    N = np.array([[0, 0, 1, 1], [0, 0, 0, 0], [0, 1, 0, 1]], dtype=float)
    C_b = np.array([[-1, 1, 0, 0], [0, 0, -1, 1]])
    C_s = np.array([[-1, 0, 1, 0], [0, -1, 0, 1]])
    return N, C_b, C_s


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda N, B, S: (N.T, B, S),
            r"^N: expected shape \(3, n\) or \(2, n\), got \(4, 3\) \(one column per node",
        ),
        (
            lambda N, B, S: (N, B, np.hstack([S, [[1], [0]]])),
            r"^C_s: has 5 columns but N has 4 nodes",
        ),
        (
            lambda N, B, S: (N, B, np.array([[-1, 0, 1, 1], [0, -1, 0, 1]])),
            r"^C_s\[0\]: expected exactly one -1 and one \+1 \(zeros elsewhere\), got -1 at \[0\], "
            r"\+1 at \[2, 3\]",
        ),
        (
            lambda N, B, S: (N, np.array([[-1, 1, 0, 0], [0, 0, -1, 2]]), S),
            r"^C_b\[1\]: expected exactly one -1 and one \+1.*2\.0 at 3",
        ),
        (
            lambda N, B, S: (N, np.array([[-1, 1, 0, 0], [0, 1, -1, 0]]), S),
            r"^bars: node 1 is an end of bars \[0, 1\]; .*class 2 joint.*pass ball_joints=True",
        ),
        (lambda N, B, S: (N, B[:1], S), r"^nodes\[2\]: belongs to no bar"),
        (
            lambda N, B, S: (np.array([[0, 0, 1, 1], [0, 0, 0, 0], [0, 0, 0, 1.0]]), B, S),
            r"^C_b\[0\]: bar joins nodes 0 and 1, which coincide \(zero length\)",
        ),
    ],
)
def test_bad_connectivity_names_the_field(change, message):
    N, C_b, C_s = change(*square())
    with pytest.raises(ValueError, match=message):
        from_connectivity(N, C_b, C_s, tendon_rest_length=0.9)


def test_bad_parameters_name_the_field():
    N, C_b, C_s = square()
    with pytest.raises(
        ValueError, match=r"^tendon_rest_length, tendon_prestrain: give exactly one"
    ):
        from_connectivity(N, C_b, C_s)
    with pytest.raises(
        ValueError, match=r"^tendon_stiffness: expected a number or 2 values, got shape \(3,\)"
    ):
        from_connectivity(N, C_b, C_s, tendon_rest_length=0.9, tendon_stiffness=[1, 2, 3])
    with pytest.raises(ValueError, match=r"^tendon_prestrain\[1\]: must be finite and > -1"):
        from_connectivity(N, C_b, C_s, tendon_prestrain=[0.1, -1.0])
    with pytest.raises(ValueError, match=r"^rods\[1\]\.mass: must be > 0"):
        from_connectivity(N, C_b, C_s, tendon_rest_length=0.9, rod_mass=[1, 0])


BASE = {
    "nodes": {"a": [0, 0, 0], "b": [0, 0, 1], "c": [1, 0, 0], "d": [1, 0, 1]},
    "rods": [{"nodes": ["a", "b"]}, {"nodes": ["c", "d"]}],
    "tendons": [{"name": "s", "nodes": ["a", "c"], "rest_length": 0.9}],
}


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        (
            {"tendons": [{"name": "s", "nodes": ["a", "x7"], "rest_length": 0.9}]},
            r"^tendons\[0\] \('s'\)\.nodes: no node named 'x7'",
        ),
        (
            {
                "tendons": [{"name": "s", "nodes": ["a", "c"], "rest_length": 0.9}],
                "fixed": ["a", "x"],
            },
            r"^fixed\[1\]: no node named 'x'",
        ),
        (
            {"point_masses": [{"node": "a", "mas": 1}]},
            r"^point_masses\[0\]: unknown key 'mas' \(expected one of node, mass\)",
        ),
        (
            {"planes": [{"node": "a", "normal": [0, 1]}]},
            r"^planes\[0\]\.normal: expected a list of 3",
        ),
        (
            {"rods": [{"nodes": ["a", "b"]}, {"nodes": ["c", "d"], "mas": 1}]},
            r"^rods\[1\]: unknown key 'mas' \(expected one of nodes, mass, length, damping, "
            r"relative_damping\)",
        ),
        (
            {"tendons": [{"name": "s", "nodes": ["a", "c"]}]},
            r"^tendons\[0\]: needs exactly one of rest_length \[m\] or prestrain",
        ),
        (
            {"tendons": [{"nodes": ["a", "c"], "rest_length": 0.9, "prestrain": 0.1}]},
            r"^tendons\[0\]: needs exactly one of rest_length",
        ),
        (
            {"tendons": [{"nodes": ["a", "c"], "rest_length": "long"}]},
            r"^tendons\[0\]\.rest_length: expected a number",
        ),
        (
            {"nodes": {"a": [0, 0, 0], "b": [0, 0, 0], "c": [1, 0, 0], "d": [1, 0, 1]}},
            r"^rods\[0\]\.nodes: 'a' and 'b' coincide \(zero length\)",
        ),
        (
            {"nodes": {"a": [0, 0], "b": [0, 0, 1], "c": [1, 0, 0], "d": [1, 0, 1]}},
            r"^nodes\.b: expected a list of 2 numbers \[x, y\] \(planar, as the first node has two "
            r"coordinates\)",
        ),
        (
            {"tendons": [{"nodes": ["a", ["c"]], "rest_length": 0.9}]},
            r"^tendons\[0\]\.nodes: no node \['c'\]",
        ),
        (
            {"nodes": {"a": [0, 0, 0], True: [0, 0, 1], "c": [1, 0, 0], "d": [1, 0, 1]}},
            r"^nodes: node names must be non-empty strings \(or integers\), got True",
        ),
        ({"format": "other"}, r"^format: expected 'tensegrity-network'"),
        ({"version": 2}, r"^version: this library reads version <= 1"),
        ({"extra": 1}, r"^network: unknown key 'extra'"),
    ],
)
def test_bad_readable_form_names_the_key(patch, message):
    with pytest.raises(ValueError, match=message):
        network_from_dict({**BASE, **patch})


def test_bad_files_are_one_line_starting_with_the_name(tmp_path):
    cases = {
        "bad.yaml": ("nodes: [\n", "invalid YAML at line 2"),
        "bad.toml": ("nodes = [\n", "invalid TOML"),
        "missing.yaml": (None, "no such file"),
        "s.txt": ("", "unknown structure file suffix '.txt'"),
        "bad.npz": ("not a zip", "not a NumPy .npz archive"),
        "node.toml": (
            "[nodes]\na = [0, 0, 0]\nb = [0, 0, 1]\nrods = 1\n",
            "nodes.rods: expected a list of 3",
        ),
    }
    for name, (text, words) in cases.items():
        path = tmp_path / name
        if text is not None:
            path.write_text(text)
        with pytest.raises(ValueError) as info:
            read_network(path)
        message = str(info.value)
        assert message.startswith(str(path)) and words in message and "\n" not in message, message
    np.savez(tmp_path / "short.npz", N=np.zeros((3, 2)))
    with pytest.raises(ValueError, match=r"short\.npz: missing array 'C_b'"):
        read_network(tmp_path / "short.npz")
    with pytest.raises(ValueError, match="MJCF files are written for MuJoCo, not read back"):
        read_network(tmp_path / "model.xml")


def test_the_documented_yaml_and_toml_examples_describe_one_structure():
    import pathlib
    import re

    text = (pathlib.Path(__file__).parents[1] / "docs" / "networks.md").read_text()
    yaml_doc = re.search(r"```yaml\n(.*?)```", text, re.S).group(1)
    toml_doc = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    a = network_from_dict(yaml.safe_load(yaml_doc))
    b = network_from_dict(tomllib.loads(toml_doc))
    assert a.to_dict() == b.to_dict()
    assert a.tendon_name == ("bottom", "top") and a.rod_mass.tolist() == [2.0, 1.0]


def test_io_read_structure_reads_every_format(tmp_path):
    """Callers of io.read_structure (the analysis commands) take every structure file too."""
    from tensegrity.io.formats import read_structure

    s = varied_shell()
    for suffix in ("yaml", "toml", "npz"):
        write_network(tmp_path / f"s.{suffix}", s)
        assert read_structure(tmp_path / f"s.{suffix}").to_dict() == s.to_dict()


@pytest.mark.parametrize(
    "name, text",
    [
        ("deep.yaml", "a: " + "[" * 5000 + "]" * 5000 + "\n"),
        ("deep.toml", "a = " + "[" * 5000 + "]" * 5000 + "\n"),
        ("deep.json", '{"a": ' + "[" * 5000 + "]" * 5000 + "}\n"),
    ],
)
def test_a_document_nested_too_deeply_is_a_value_error_naming_the_file(tmp_path, name, text):
    """Deeper than the parsers recurse: a one-line ``ValueError`` from the reader itself
    (before: ``RecursionError`` for YAML and TOML; only the CLI named the problem)."""
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(ValueError, match=f"^{path}: nested too deeply$"):
        read_network(path)
