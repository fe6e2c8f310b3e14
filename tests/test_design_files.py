"""Structure files in the material form (tensegrity.design.files): members given by material
and section build stiffness ``E A / Lbar`` and rod mass ``rho A L`` equal to the hand values;
files round-trip in YAML, TOML and JSON; mixed or doubled forms are one-line errors naming the
member; the numeric reader points at the design reader."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tensegrity.design.catalogue import prism
from tensegrity.design.files import read_design, write_design
from tensegrity.design.materials import (
    Cable,
    HollowTube,
    Material,
    MemberDesign,
    SolidRod,
    material,
)
from tensegrity.io.formats import read_network, read_structure

DOC = """
nodes:
  a: [0, 0, 0]
  b: [0, 0, 2]
  c: [1, 0, 0]
  d: [1, 0, 2]
fixed: [a, c]
defaults:
  rod: {material: steel, section: {diameter: 0.01}}
  tendon:
    material: {name: fibre, youngs_modulus: 1.0e+11, density: 1000, yield_strength: 1.0e+9}
    section: {diameter: 0.002}
rods:
  - {nodes: [a, b]}
  - {nodes: [c, d], section: {diameter: 0.04, wall: 0.003}}
tendons:
  - {name: top, nodes: [b, d], rest_length: 0.8}
  - {name: cross, nodes: [a, d], prestrain: 0.01, material: kevlar}
"""


def test_stiffness_and_mass_equal_the_hand_values(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(DOC)
    structure, design = read_design(path)
    steel = material("steel")
    solid = math.pi * 0.01**2 / 4
    tube = math.pi * (0.04**2 - 0.034**2) / 4
    np.testing.assert_allclose(
        structure.rod_mass, [steel.density * solid * 2, steel.density * tube * 2], rtol=1e-14
    )
    cable = math.pi * 0.002**2 / 4
    cross_rest = math.sqrt(5) / 1.01
    np.testing.assert_allclose(
        structure.tendon_stiffness,
        [1e11 * cable / 0.8, material("kevlar").youngs_modulus * cable / cross_rest],
        rtol=1e-14,
    )
    np.testing.assert_allclose(structure.tendon_rest_length, [0.8, cross_rest], rtol=1e-15)
    assert design.rod_section == (SolidRod(0.01), HollowTube(0.04, 0.003))
    assert design.tendon_material[0] == Material("fibre", 1e11, 1000.0, 1e9, 1e9)
    assert design.tendon_material[1] == material("kevlar")
    assert design.tendon_section == (Cable(0.002), Cable(0.002))
    assert not design.tendon_mass
    # the numbers utilisation needs
    props = design.properties(structure)
    np.testing.assert_allclose(props.tendon_yield, [1e9, material("kevlar").yield_strength])


def test_tendon_mass_goes_to_the_nodes(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(DOC + "tendon_mass: true\n")
    with_mass, _ = read_design(path)
    path.write_text(DOC)
    without, _ = read_design(path)
    cable = math.pi * 0.002**2 / 4
    top = 1000 * cable * 0.8  # both ends on rods, none fixed
    cross = material("kevlar").density * cable * math.sqrt(5) / 1.01  # tail a is fixed
    # rod 0 (a-b): half of top at b; rod 1 (c-d): half of top and half of cross at d
    np.testing.assert_allclose(
        with_mass.rod_mass - without.rod_mass, [top / 2, top / 2 + cross / 2], rtol=1e-12
    )


@pytest.fixture
def designed():
    """A prism with one material per member kind, a tube for one rod, a payload hung by a
    tendon (a point mass on a tendon's end) and the tendons' mass lumped."""
    s = prism()
    rods = [material("aluminium"), material("cfrp"), material("aluminium")]
    design = MemberDesign.of(
        s,
        rod_material=rods,
        rod_section=[HollowTube(0.02, 0.002), SolidRod(0.012), SolidRod(0.012)],
        tendon_material=Material("rope", 5e10, 1100.0, 2e8, 3e8, "a test rope"),
        tendon_section=Cable(0.003),
        tendon_mass=True,
    )
    return design.apply(s), design


@pytest.mark.parametrize("suffix", [".yaml", ".toml", ".json"])
def test_material_form_round_trips(tmp_path, designed, suffix):
    structure, design = designed
    path = write_design(tmp_path / f"s{suffix}", structure, design)
    back = read_design(path)
    assert back.design == design
    assert back.structure.to_dict() == structure.to_dict()
    text = path.read_text()
    assert "stiffness" not in text and "mass:" not in text.replace("tendon_mass", "")


def test_payload_round_trips_with_tendon_mass(tmp_path):
    """A point mass hung from an anchor by a tendon: the file keeps the payload, the structure
    the payload plus half the tendon's mass."""
    import yaml

    doc = {
        "nodes": {"top": [0, 0, 1], "load": [0, 0, 0], "r0": [1, 0, 0], "r1": [1, 0, 1]},
        "fixed": ["top"],
        "point_masses": [{"node": "load", "mass": 0.3}],
        "tendon_mass": True,
        "defaults": {
            "rod": {"material": "steel", "section": {"diameter": 0.01}},
            "tendon": {"material": "steel", "section": {"diameter": 0.001}},
        },
        "rods": [{"nodes": ["r0", "r1"]}],
        "tendons": [
            {"name": "hang", "nodes": ["top", "load"], "rest_length": 1.0},
            {"name": "tie", "nodes": ["load", "r0"], "rest_length": 1.0},
        ],
    }
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(doc))
    structure, design = read_design(path)
    steel = material("steel")
    tendon = steel.density * math.pi * 0.001**2 / 4 * 1.0
    load = structure.point_mass_nodes[0]
    assert structure.node_point_mass[load] == pytest.approx(0.3 + tendon, rel=1e-14)
    again = read_design(write_design(tmp_path / "t.yaml", structure, design))
    assert again.structure.to_dict() == structure.to_dict()
    assert yaml.safe_load((tmp_path / "t.yaml").read_text())["point_masses"][0]["mass"] == (
        pytest.approx(0.3, rel=1e-14)
    )


def test_writer_refuses_a_structure_the_design_did_not_make(tmp_path, designed):
    structure, design = designed
    changed = structure.replace(tendon_stiffness=structure.tendon_stiffness * 1.001)
    with pytest.raises(ValueError, match=r"tendons\[0\] \('b0'\): stiffness .* is not the design"):
        write_design(tmp_path / "s.yaml", changed, design)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            ("  - {nodes: [a, b]}", "  - {nodes: [a, b], mass: 2}"),
            r"rods\[0\]: gives both mass and a material and section; give one form",
        ),
        (
            ("  tendon:\n", "  tendon:\n    stiffness: 50\n"),
            r"tendons\[0\] \('top'\): gives both stiffness \(under defaults.tendon\)",
        ),
        (
            ("    section: {diameter: 0.002}\n", ""),
            r"tendons\[0\] \('top'\): no section \(other members are given by material",
        ),
        (("material: kevlar", "material: kevlr"), r"tendons\[1\] \('cross'\).material: unknown"),
        (("wall: 0.003", "wall: 0.03"), r"rods\[1\].section: tube wall_thickness"),
        (("yield_strength: 1.0e+9", "yield_strength: -1"), r"defaults.tendon.material: .*> 0"),
        (("diameter: 0.01}", "diametr: 0.01}"), r"defaults.rod.section: unknown key 'diametr'"),
    ],
)
def test_one_line_errors_name_the_member(tmp_path, change, message):
    path = tmp_path / "s.yaml"
    text = DOC.replace(*change)
    assert text != DOC
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        read_design(path)
    assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)


def test_a_member_without_material_among_members_with_is_refused(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(
        DOC.replace("  rod: {material: steel, section: {diameter: 0.01}}\n", "").replace(
            "  - {nodes: [c, d], section:", "  - {nodes: [c, d], material: steel, section:"
        )
    )
    with pytest.raises(ValueError, match=r"rods\[0\]: no material and no section"):
        read_design(path)


def test_numeric_reader_points_at_the_design_reader(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text(DOC)
    with pytest.raises(ValueError, match=r"defaults.rod: 'material' is the material form, read by"):
        read_network(path)


def test_numeric_files_read_without_a_design(tmp_path):
    s = prism()
    from tensegrity.io.formats import write_network

    for suffix in (".yaml", ".json", ".npz"):
        path = write_network(tmp_path / f"s{suffix}", s)
        structure, design = read_design(path)
        assert design is None and structure.to_dict() == s.to_dict()


def test_json_readable_form_is_read_by_the_numeric_reader(tmp_path):
    """The readable form as JSON (``"format": "tensegrity-network"``): read by read_structure
    and read_network as YAML is; Structure.to_dict's JSON is unchanged."""
    import json

    from tensegrity.io.formats import network_to_dict

    s = prism()
    path = tmp_path / "s.json"
    path.write_text(json.dumps(network_to_dict(s)))
    assert read_structure(path).to_dict() == s.to_dict()
    assert read_network(path).to_dict() == s.to_dict()


def test_keep_tension_keeps_the_prestress():
    """``apply(keep_tension=True)``: each taut tendon's tension at the node positions is the
    structure's before (the rest lengths change); a slack tendon keeps its rest length."""
    s = prism(tension=7)
    slack = s.tendon_rest_length.copy()
    slack[0] *= 2  # longer than its length: slack
    s = s.replace(tendon_rest_length=slack)
    design = MemberDesign.of(
        s,
        rod_material=material("steel"),
        rod_section=SolidRod(0.01),
        tendon_material=material("dyneema"),
        tendon_section=Cable(0.001),
    )
    kept = design.apply(s, keep_tension=True)
    p = s.node_position
    length = np.linalg.norm(p[s.tendon_nodes[:, 1]] - p[s.tendon_nodes[:, 0]], axis=1)
    before = np.maximum(s.tendon_stiffness * (length - s.tendon_rest_length), 0)
    after = np.maximum(kept.tendon_stiffness * (length - kept.tendon_rest_length), 0)
    np.testing.assert_allclose(after, before, rtol=1e-9)
    assert kept.tendon_rest_length[0] == s.tendon_rest_length[0] and after[0] == 0
    assert design.apply(s).tendon_rest_length.tolist() == s.tendon_rest_length.tolist()
