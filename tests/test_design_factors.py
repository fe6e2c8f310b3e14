"""The strength factor in the utilisation, and the design travelling with the structure.

A member sized to its limit with a strength factor ``s`` has utilisation 1, in the library
(``Sizing.utilisation``), in ``tensegrity design``'s report and in ``--check-dynamics``'s static
figure (before the factor reached the utilisation, a tendon sized with ``s = 1.5`` reported
0.667); the tendons' ultimate ratio stays the raw one.  ``tensegrity design`` writes its
structure in the material form with the factors it sized with (``factors``), supports and point
masses kept; ``simulate`` and ``view`` of it report the utilisation with those factors (options
override them); bad ``factors`` entries are one-line errors naming the field."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from structures import crane
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism
from tensegrity.design.files import read_design, write_design
from tensegrity.design.loaded import size
from tensegrity.design.materials import Cable, Factors, MemberDesign, SolidRod, material
from tensegrity.design.sizing import LoadCase, size_members
from tensegrity.design.utilisation import utilisation
from tensegrity.io.formats import write_structure
from tensegrity.model.structure import Structure
from tensegrity.plots.viewer import read_viewer_data

#: The crane of tests/test_cli_design.py: a 1 m rod pinned at node 0, its head (node 1) held
#: by tendons to anchors (0, +-1, 1).
CRANE = crane()
DOWN = np.array([[0, 0, 0], [0, 0, -1000.0], [0, 0, 0], [0, 0, 0]])


def _row(out: str, name: str) -> str:
    match = re.search(rf"^{name}\s+(.*)$", out, re.MULTILINE)
    assert match, out
    return match.group(1)


@pytest.mark.parametrize("strength", [1.0, 1.5, 3.0])
def test_a_member_sized_to_its_limit_has_utilisation_one(strength):
    """Both tendons of the crane are sized to yield (``T = A sigma_y / s``) and its rod to
    buckling: the utilisation is 1 at any strength factor; the ultimate ratio is ``T / (A
    sigma_u)``, not multiplied by ``s``."""
    sizing = size_members(
        CRANE,
        rod_material=material("steel"),
        tendon_material=material("dyneema"),
        load_cases=[LoadCase("down", DOWN)],
        strength_factor=strength,
    )
    u = sizing.utilisation
    np.testing.assert_allclose(u.tendon[0], [1.0, 1.0], rtol=1e-9)
    assert u.largest == pytest.approx(1.0, rel=1e-9)
    T = sizing.tendon_tension[0]
    ultimate = T / (sizing.tendon_area * material("dyneema").ultimate_strength)
    np.testing.assert_allclose(u.tendon_ultimate[0], ultimate, rtol=1e-12)
    # the rods' yield utilisation is divided by the factor as the tendons' is
    plain = utilisation(
        sizing.structure,
        sizing.members,
        tension=T,
        compression=sizing.rod_compression[0],
    )
    np.testing.assert_allclose(u.rod_yield[0], strength * plain.rod_yield, rtol=1e-12)
    np.testing.assert_allclose(u.tendon_yield[0], strength * plain.tendon_yield, rtol=1e-12)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda u: u(strength_factor=0.5), "strength_factor: must be >= 1, got 0.5"),
        (lambda u: u(strength_factor=math.inf), "strength_factor: must be >= 1, got inf"),
        (lambda u: u(strength_factor=True), "strength_factor: must be a number >= 1"),
        (lambda u: u(safety_factor=0.9), "safety_factor: must be >= 1, got 0.9"),
        (lambda u: Factors(strength=0.5), "strength: must be >= 1, got 0.5"),
        (lambda u: Factors(safety="2"), "safety: must be a number >= 1, got '2'"),
    ],
)
def test_bad_factors_are_refused_naming_the_argument(call, message):
    sizing = size_members(
        CRANE,
        rod_material=material("steel"),
        tendon_material=material("dyneema"),
        load_cases=[LoadCase("down", DOWN)],
    )

    def u(**factors):
        return utilisation(
            sizing.structure,
            sizing.members,
            tension=sizing.tendon_tension[0],
            compression=sizing.rod_compression[0],
            **factors,
        )

    with pytest.raises(ValueError, match=re.escape(message)):
        call(u)


def test_design_reports_one_for_a_tendon_sized_with_a_strength_factor(tmp_path, capsys):
    """``tensegrity design --strength-factor 1.5``: the printed largest tendon utilisation, the
    report's, and ``--check-dynamics``'s static figure are 1 (they were 0.667)."""
    path = write_structure(tmp_path / "crane.json", CRANE)
    out = tmp_path / "out"
    argv = ["design", "--structure", str(path), "--material", "steel,dyneema"]
    argv += ["--load", "down:1:0,0,-1000", "--strength-factor", "1.5", "--check-dynamics"]
    assert main([*argv, "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "case 'down': largest utilisation rods 1, tendons 1\n" in printed
    report = json.loads((out / "design.json").read_text())
    for tendon in report["tendons"]:
        assert tendon["yield_utilisation"] == pytest.approx([1.0], rel=1e-9)
    assert report["largest_utilisation"] == pytest.approx(1.0, rel=1e-9)
    (case,) = report["dynamic"]["cases"]
    assert case["static_largest_utilisation"] == pytest.approx(1.0, rel=1e-9)
    # in motion, the step load's overshoot (about 2, damped), not 2 / 1.5
    assert 1.5 < max(case["tendon_peak"]) < 2.05


def _supported_crane() -> Structure:
    """The crane with every kind of support: a second rod joined to its head (a joint), held
    by a tendon to a fixed anchor; one anchor on a plane (normal along its tendon, with a point
    mass) and a payload on a vertical line, hung from the head."""
    r = 1 / math.sqrt(3)
    p = [[0, 0, 0], [1, 0, 0], [0, 1, 1], [0, -1, 1], [1, 0, -0.5], [1, 0, 0], [2, 0, 0], [2, 0, 1]]
    return Structure(
        node_position=p,
        rod_nodes=[[0, 1], [5, 6]],
        rod_mass=[1.0, 1.0],
        rod_length=[1.0, 1.0],
        tendon_nodes=[[1, 2], [1, 3], [1, 4], [6, 7]],
        tendon_stiffness=[1.0] * 4,
        tendon_rest_length=[1.0] * 4,
        node_fixed=[True, False, True, False, False, False, False, True],
        node_point_mass=[0, 0, 0, 0.5, 2.0, 0, 0, 0],
        joint_nodes=[[1, 5]],
        plane_nodes=[3],
        plane_normal=[[r, r, -r]],
        line_nodes=[4],
        line_direction=[[0, 0, 1]],
    )


def test_design_writes_the_material_form_with_its_factors_and_supports(tmp_path, capsys):
    """``out/structure.json`` is the sized structure by material and section, bit for bit,
    with its fixed nodes, plane, line, joint and point masses, and the factors it was sized
    with."""
    s = _supported_crane()
    path = write_structure(tmp_path / "crane.json", s)
    out = tmp_path / "out"
    argv = ["design", "--structure", str(path), "--material", "steel,dyneema"]
    argv += ["--load", "down:1:0,0,-1000", "--load", "down:4:0,0,-100"]
    argv += ["--safety-factor", "1.5", "--strength-factor", "2", "-o", str(out)]
    assert main(argv) == 0
    capsys.readouterr()
    force = np.zeros((8, 3))
    force[1, 2], force[4, 2] = -1000.0, -100.0
    sizing = size(  # the crane has mechanisms (a node on a plane): sized at equilibrium
        s,
        rod_material=material("steel"),
        tendon_material=material("dyneema"),
        load_cases=[LoadCase("down", force)],
        safety_factor=1.5,
        strength_factor=2.0,
    )
    written = read_design(out / "structure.json")
    assert written.design is not None
    assert written.design.factors == Factors(safety=1.5, strength=2.0)
    assert written.structure.to_dict() == sizing.structure.to_dict()
    for name in ("node_fixed", "node_point_mass", "joint_nodes", "plane_nodes", "plane_normal",
                 "line_nodes", "line_direction"):  # fmt: skip
        np.testing.assert_array_equal(getattr(written.structure, name), getattr(s, name))
    text = (out / "structure.json").read_text()
    assert '"factors"' in text and '"stiffness"' not in text


def _designed_crane_run(tmp_path, capsys, *extra):
    """The crane designed with safety factor 1.5 and strength factor 2, then simulated from its
    ``structure.json`` under the design load ramped in over 0.5 s, damped to rest; the printed
    summary."""
    path = write_structure(tmp_path / "crane.json", CRANE)
    sized = tmp_path / "sized"
    argv = ["design", "--structure", str(path), "--material", "steel,dyneema"]
    argv += ["--load", "down:1:0,0,-1000", "--safety-factor", "1.5", "--strength-factor", "2"]
    if not (sized / "structure.json").exists():
        assert main([*argv, "-o", str(sized)]) == 0
    table = tmp_path / "down.npz"
    np.savez(table, time=[0.0, 0.5], force=np.stack([np.zeros((4, 3)), DOWN]))
    run = tmp_path / ("run" + "".join(extra).replace("-", "_"))
    code = main(["simulate", "--structure", str(sized / "structure.json"), "--force-table",
                 str(table), "--t-end", "3", "--sample-dt", "0.01", "--damping", "artificial",
                 "--no-animation", "--out", str(run), *extra])  # fmt: skip
    assert code == 0
    return capsys.readouterr().out, run


def test_simulate_of_the_design_reports_utilisation_with_its_factors(tmp_path, capsys):
    """``simulate --structure out/structure.json`` of a design: the utilisation lines, with the
    design's factors (its tendons near 1 at the design load with strength factor 2, not 0.5;
    its rod's buckling near 1 with safety factor 1.5); ``--strength-factor 1`` overrides the
    file's: half the tendons' utilisation, the rods' buckling unchanged."""
    printed, run = _designed_crane_run(tmp_path, capsys)
    assert _row(printed, "utilisation factors") == (
        "safety 1.5 (divides the Euler load), strength 2 (divides the yield strengths)"
    )
    tendon = float(_row(printed, "largest tendon utilisation").split()[1])
    buckling = float(_row(printed, "largest rod utilisation").split()[1])
    assert 0.95 < tendon < 1.05 and 0.95 < buckling < 1.05
    overridden, _ = _designed_crane_run(tmp_path, capsys, "--strength-factor", "1")
    assert _row(overridden, "utilisation factors").startswith("safety 1.5 (")
    assert "strength 1 (" in _row(overridden, "utilisation factors")
    half = float(_row(overridden, "largest tendon utilisation").split()[1])
    assert half == pytest.approx(tendon / 2, rel=1e-3)
    assert float(_row(overridden, "largest rod utilisation").split()[1]) == buckling
    # the run's own structure-material.json carries the factors it was run with
    again = read_design(run / "structure-material.json").design
    assert again is not None and again.factors == Factors(1.5, 2.0)


def test_view_of_a_designed_run_colours_by_utilisation_with_the_design_factors(tmp_path, capsys):
    """``simulate`` of the design writes a ``view.html`` coloured by utilisation (no option
    needed); ``view run/trajectory.h5`` with no option gives the page ``view --structure
    sized/structure.json`` (the design file, its factors) gives: the trajectory carries the
    design and its factors; both the run's tendon utilisation (the rods' differ: ``view`` leaves
    out the run's force table, which the trajectory does not hold); ``--strength-factor 1``
    halves it, with or without ``--structure``."""
    _, run = _designed_crane_run(tmp_path, capsys)
    written = read_viewer_data((run / "view.html").read_text())["utilisation"]
    page = tmp_path / "page.html"
    trajectory = str(run / "trajectory.h5")
    design = ["--structure", str(tmp_path / "sized" / "structure.json")]
    assert main(["view", trajectory, "-o", str(page), *design]) == 0
    again = read_viewer_data(page.read_text())["utilisation"]
    np.testing.assert_array_equal(again["tendons"], written["tendons"])
    assert np.shape(again["rods"]) == np.shape(written["rods"])
    assert 0.95 < np.max(written["tendons"]) < 1.05
    own = tmp_path / "own.html"
    assert main(["view", trajectory, "-o", str(own)]) == 0
    carried = read_viewer_data(own.read_text())["utilisation"]
    for key in ("rods", "tendons", "high"):
        np.testing.assert_array_equal(carried[key], again[key])
    for given in (design, []):
        assert main(["view", trajectory, "-o", str(page), *given, "--strength-factor", "1"]) == 0
        half = read_viewer_data(page.read_text())["utilisation"]
        np.testing.assert_allclose(half["tendons"], np.asarray(written["tendons"]) / 2, rtol=1e-6)
    capsys.readouterr()


@pytest.mark.parametrize("suffix", [".yaml", ".toml", ".json"])
def test_factors_round_trip(tmp_path, suffix):
    s = prism()
    design = MemberDesign.of(
        s,
        rod_material=material("steel"),
        rod_section=SolidRod(0.01),
        tendon_material=material("nylon"),
        tendon_section=Cable(0.001),
        factors=Factors(safety=1.5, strength=2.25),
    )
    structure = design.apply(s)
    back = read_design(write_design(tmp_path / f"s{suffix}", structure, design))
    assert back.design == design
    assert back.design is not None and back.design.factors == Factors(1.5, 2.25)
    # the default factors are not written, and read back as the default
    plain = MemberDesign.of(
        s,
        rod_material=material("steel"),
        rod_section=SolidRod(0.01),
        tendon_material=material("nylon"),
        tendon_section=Cable(0.001),
    )
    path = write_design(tmp_path / f"plain{suffix}", structure, plain)
    assert "factors" not in path.read_text()
    assert read_design(path).design == plain


DOC = """
nodes:
  a: [0, 0, 0]
  b: [0, 0, 2]
  c: [1, 0, 0]
  d: [1, 0, 2]
fixed: [a, c]
FACTORS
defaults:
  rod: {material: steel, section: {diameter: 0.01}}
  tendon: {material: dyneema, section: {diameter: 0.002}}
rods:
  - {nodes: [a, b]}
  - {nodes: [c, d]}
tendons:
  - {name: top, nodes: [b, d], rest_length: 0.8}
"""


@pytest.mark.parametrize(
    ("factors", "message"),
    [
        ("factors: 2", "factors: expected a mapping {safety: GAMMA, strength: S}, got int"),
        ("factors: {safety: 0.5}", "factors.safety: must be >= 1, got 0.5"),
        ("factors: {strength: '2'}", "factors.strength: expected a number, got '2'"),
        ("factors: {strength: .inf}", "factors.strength: must be >= 1, got inf"),
        ("factors: {safty: 2}", "factors: unknown key 'safty' (expected one of safety, strength)"),
    ],
)
def test_bad_factors_are_one_line_errors_naming_the_field(tmp_path, capsys, factors, message):
    path = tmp_path / "s.yaml"
    path.write_text(DOC.replace("FACTORS", factors))
    with pytest.raises(ValueError) as info:
        read_design(path)
    text = str(info.value)
    assert text.startswith(str(path)) and message in text and "\n" not in text
    code = main(["info", "--structure", str(path)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err


def test_factors_need_the_material_form(tmp_path):
    path = tmp_path / "s.yaml"
    numeric = DOC.replace("FACTORS", "factors: {safety: 2}")
    numeric = numeric.replace("material: steel, section: {diameter: 0.01}", "mass: 1")
    numeric = numeric.replace("material: dyneema, section: {diameter: 0.002}", "stiffness: 100")
    path.write_text(numeric)
    with pytest.raises(ValueError, match=r"factors: only with members by material and section"):
        read_design(path)


@pytest.mark.parametrize("writer", ["write_trajectory", "simulate_to_file"])
def test_a_trajectory_carries_the_design_of_its_structure(tmp_path, writer):
    """A trajectory written with its structure in the material form (``material_form``, in
    memory or streamed) reads back with the same design: materials, sections (so areas),
    tendon mass and factors; the structure is the run's own.  Written without it, none."""
    from tensegrity import simulate
    from tensegrity.design.files import design_to_dict, trajectory_design
    from tensegrity.design.materials import HollowTube, Material
    from tensegrity.io.stream import simulate_to_file
    from tensegrity.io.trajectory import read_trajectory, write_trajectory

    base = prism()
    design = MemberDesign.of(
        base,
        rod_material=[material("aluminium"), material("cfrp"), material("aluminium")],
        rod_section=[HollowTube(0.02, 0.002), SolidRod(0.012), SolidRod(0.012)],
        tendon_material=Material("rope", 5e10, 1100.0, 2e8, 3e8, "a test rope"),
        tendon_section=Cable(0.003),
        tendon_mass=True,
        factors=Factors(1.5, 2.25),
    )
    s = design.apply(base, keep_tension=True)

    def written(name, form):
        path = tmp_path / name
        if writer == "write_trajectory":
            write_trajectory(path, simulate(s, (0.0, 0.04), sample_dt=0.01), material_form=form)
        else:
            simulate_to_file(s, (0.0, 0.04), path, sample_dt=0.01, material_form=form)
        return path

    path = written("designed.h5", design_to_dict(s, design, keep_joints=True))
    structure, back = trajectory_design(path)
    assert back == design
    assert structure.to_dict() == read_trajectory(path).structure.to_dict() == s.to_dict()
    ours, theirs = back.properties(structure), design.properties(s)
    for name in ("rod_area", "rod_second_moment", "tendon_area", "tendon_yield"):
        np.testing.assert_array_equal(getattr(ours, name), getattr(theirs, name))
    plain = trajectory_design(written("plain.h5", None))
    assert plain.design is None and plain.structure.to_dict() == s.to_dict()
    # the material form of another structure is a one-line error naming the file
    square = MemberDesign.of(
        prism(4),
        rod_material=material("steel"),
        rod_section=SolidRod(0.01),
        tendon_material=material("nylon"),
        tendon_section=Cable(0.001),
    )
    other = written("other.h5", design_to_dict(square.apply(prism(4)), square))
    with pytest.raises(ValueError) as info:
        trajectory_design(other)
    text = str(info.value)
    assert text.startswith(str(other)) and "structure_material" in text and "\n" not in text
