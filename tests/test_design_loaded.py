"""Sizing at the loaded equilibrium (``design.loaded``): a fixed-base prism under top loads and
its own weight, checked at an equilibrium found independently (a damped simulation to rest); a
statically determinate structure, whose forces are fixed by the statics of the geometry it
deforms to; limit points and loads the supports cannot hold refused in one line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from structures import crane
from tensegrity.analysis.equilibrium import equilibrium_by_simulation, find_equilibrium
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import modal_analysis
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism, tower
from tensegrity.design.loaded import (
    LoadPathError,
    ServiceabilityError,
    _stiffened,
    follow_load,
    mechanism_count,
    size,
    size_at_equilibrium,
    unheld_load,
)
from tensegrity.design.materials import material
from tensegrity.design.sizing import LoadCase, size_members, sized_structure
from tensegrity.design.utilisation import utilisation
from tensegrity.io.formats import write_structure
from tensegrity.model.structure import Structure

GRAVITY = np.array([0.0, 0.0, -9.81])
STEEL, DYNEEMA = material("steel"), material("dyneema")
RTOL = 1e-6  # size_at_equilibrium's default


def _fixed_base_prism(**options) -> Structure:
    s = prism(3, **options)
    return s.replace(node_fixed=np.arange(6) < 3)


def _top_load(P: float) -> np.ndarray:
    w = np.zeros((6, 3))
    w[3:, 2] = -P
    return w


@pytest.fixture(scope="module")
def sized_prism():
    s = _fixed_base_prism()
    case = LoadCase("top", _top_load(100.0), GRAVITY)
    sizing = size_at_equilibrium(
        s, rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[case], prestress=50.0
    )
    return s, case, sizing


def test_the_linear_sizing_refuses_the_loaded_prism_and_counts_its_mechanism():
    s = _fixed_base_prism()
    assert mechanism_count(s) == 1  # the twist-and-sink mechanism; free: 6 rigid motions more
    assert mechanism_count(prism(3)) == 7
    with pytest.raises(ValueError, match="no member forces balance it"):
        size_members(
            s,
            rod_material=STEEL,
            tendon_material=DYNEEMA,
            load_cases=[LoadCase("top", _top_load(100.0), GRAVITY)],
            prestress=50.0,
        )


def test_the_prism_is_sized_at_its_loaded_equilibrium(sized_prism):
    s, _, sizing = sized_prism
    assert sizing.statics == "equilibrium"
    assert sizing.message.startswith("converged after")
    assert sizing.cases == ("prestress", "top")
    u = sizing.utilisation
    assert u.largest <= 1.0  # the areas are rounded up by rtol: no excess from the tolerance
    for k in range(2):  # a member at its limit in every case
        assert max(u.rod[k].max(), u.tendon[k].max()) == pytest.approx(1.0, abs=2 * RTOL)
    # fully stressed: every member is at 1 in the case that governs it
    governing = np.concatenate([u.rod.max(axis=0), u.tendon.max(axis=0)])
    np.testing.assert_allclose(governing, 1.0, atol=2 * RTOL)
    assert set(sizing.governs) == {"yield", "buckling"}
    assert sizing.governs[:3] == ("buckling",) * 3  # the rods
    # the prestress is held at the given geometry, which the load moves
    assert sizing.tendon_tension[0].min() == pytest.approx(50.0, rel=1e-9)
    top = sizing.equilibria[0].node_position[3:, 2]
    assert np.all(top < s.node_position[3:, 2] - 0.01)
    assert sizing.displacement[0] == pytest.approx(
        np.linalg.norm(sizing.equilibria[0].node_position - s.node_position, axis=1).max()
    )
    # the sized structure's rods weigh what their areas make, and carry the weight
    np.testing.assert_allclose(
        sizing.structure.rod_mass, 7850.0 * sizing.rod_area * s.rod_length, rtol=1e-12
    )


def test_a_damped_simulation_to_rest_finds_the_same_loaded_state(sized_prism):
    """The independent check: the sized structure, loaded and damped to rest by the engine
    (no least squares, no reduced coordinates), is where the sizing put it, and every member
    is within its limits there, one at its limit."""
    _, case, sizing = sized_prism
    rest = equilibrium_by_simulation(
        sizing.structure, external_force=case.force, gravity=case.gravity, t_end=20.0
    )
    assert rest.converged
    expected = sizing.equilibria[0]
    assert np.abs(rest.node_position - expected.node_position).max() < 1e-7
    u = utilisation(
        sizing.structure, sizing.members, tension=rest.tension, compression=rest.rod_compression
    )
    assert 1 - 1e-5 <= u.largest <= 1.0


def test_a_statically_determinate_structure_gets_the_statics_of_its_deformed_geometry():
    """For the crane (a pinned rod held by two tendons) forces follow from statics alone: the
    areas sized at the loaded equilibrium are those the linear sizing gives at the geometry
    the structure deforms to (an LP on the nodal equilibrium matrix, no shared solver); and
    ``size(statics="auto")`` keeps the linear sizing for it, the same as today."""
    s = crane()
    w = np.zeros((4, 3))
    w[1] = [0, 300.0, -1000.0]
    options = dict(rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[LoadCase("d", w)])
    assert mechanism_count(s) == 0
    linear = size_members(s, **options)
    auto = size(s, **options)
    assert auto.statics == "linear"
    np.testing.assert_array_equal(auto.tendon_area, linear.tendon_area)
    np.testing.assert_array_equal(auto.rod_area, linear.rod_area)
    loaded = size(s, statics="equilibrium", **options)
    moved = loaded.equilibria[0].node_position
    assert np.abs(moved - s.node_position).max() > 1e-3  # the tendons stretch (Dyneema, ~3 %)
    at_moved = size_members(s.replace(node_position=moved), **options)
    np.testing.assert_allclose(loaded.tendon_area, at_moved.tendon_area, rtol=3 * RTOL)
    np.testing.assert_allclose(loaded.rod_area, at_moved.rod_area, rtol=3 * RTOL)
    # and the deformation matters: at the given geometry the areas differ by more
    assert np.abs(loaded.tendon_area / linear.tendon_area - 1).max() > 100 * RTOL


def test_a_limit_point_ends_the_load_path_where_the_prism_loses_its_prestress():
    """The default prism (k = 100 N/m, 5 N of mean prestress) under 100 N on each top node
    snaps through (found at rest inverted, its top below its base).  The path stops where the
    load has taken the tension out of the side strings, whose prestress is what stiffens the
    prism's mechanism: a little more load and they go slack, and the equilibrium near the path
    is unstable."""
    s = _fixed_base_prism()
    case = LoadCase("top", _top_load(100.0))
    with pytest.raises(LoadPathError) as caught:
        follow_load(s, case)
    reached = caught.value.reached
    assert 0.2 < reached < 0.3
    assert str(caught.value).startswith("load case 'top': no stable equilibrium near the path at")
    side = [s.tendon_name.index(f"s{i}") for i in range(3)]
    at_rest, _ = follow_load(s, LoadCase("none", 0 * case.force))
    at_limit, _ = follow_load(s, LoadCase("limit", reached * case.force))
    assert np.all(at_rest.tension[side] > 4.0)
    assert np.all(at_limit.tension[side] < 0.05 * at_rest.tension[side])
    beyond = find_equilibrium(
        s, at_limit.q, external_force=(reached + 0.01) * case.force, descend=False
    )
    assert np.all(beyond.tension[side] < 1e-3 * at_rest.tension[side])
    assert not (beyond.converged and modal_analysis(linearize(s, beyond)).stable)
    # a load a little below the limit is carried, stably
    follow_load(s, LoadCase("below", 0.9 * reached * case.force))


def test_loads_the_supports_cannot_hold_are_refused_in_one_line():
    free = prism(3)
    case = LoadCase("top", _top_load(100.0))
    assert unheld_load(free, case) > 1.0  # its weight-free load pushes it down
    assert unheld_load(_fixed_base_prism(), case) == 0.0
    balanced = np.zeros((6, 3))
    balanced[3], balanced[4] = [0, 0, -100.0], [0, 0, 100.0]  # no net force, a net moment
    assert unheld_load(free, LoadCase("pair", balanced)) > 1.0
    with pytest.raises(ValueError, match="the supports leave the structure free to move"):
        size_at_equilibrium(
            free, rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[case], prestress=5.0
        )


def test_a_prism_without_prestress_is_stiffened_by_its_load():
    """Without prestress the prism's mechanism has no stiffness at the given geometry, but a
    load pressing its top twists it until the strings are taut: the load path is stable, and
    the strings carry the load there (their tensions balance it, summed over the top)."""
    s = _fixed_base_prism()
    w = _top_load(10.0)
    sizing = size_at_equilibrium(
        s, rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[LoadCase("top", w)]
    )
    eq = sizing.equilibria[0]
    assert sizing.cases == ("top",) and eq.converged
    assert np.all(eq.tension[[s.tendon_name.index(f"s{i}") for i in range(3)]] > 1.0)
    assert modal_analysis(linearize(sizing.structure, eq)).stable
    assert eq.node_position[3:, 2].max() < s.node_position[3:, 2].min() - 1e-3


def test_a_path_through_unstable_equilibria_is_refused():
    """A rod standing upright on a pin, pressed down at its top: every load on the path is
    balanced in place (the rod carries it), but the equilibrium has negative stiffness (an
    inverted pendulum), so the path is refused at its start; a mechanism the load does not
    move (zero stiffness: the same rod unloaded) is neutral and accepted."""
    s = Structure(
        node_position=[[0, 0, 0], [0, 0, 1]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
        node_fixed=[True, False],
    )
    down = np.array([[0, 0, 0], [0, 0, -10.0]])
    eq = find_equilibrium(s, external_force=down, descend=False)
    assert eq.converged and modal_analysis(linearize(s, eq)).n_unstable == 2
    with pytest.raises(LoadPathError, match="no stable equilibrium near the path at its start"):
        follow_load(s, LoadCase("down", down))
    unloaded, _ = follow_load(s, LoadCase("none", 0 * down))
    assert np.array_equal(unloaded.node_position, s.node_position)


@pytest.fixture(scope="module")
def sized_tower():
    s = tower(3, 3)
    s = s.replace(node_fixed=np.arange(s.n_nodes) < 3)
    w = np.zeros((s.n_nodes, 3))
    w[-3:, 2] = -100.0
    cases = [LoadCase("gravity", None, GRAVITY), LoadCase("top", w, GRAVITY)]
    sizing = size_at_equilibrium(
        s, rod_material=STEEL, tendon_material=DYNEEMA, load_cases=cases, prestress=50.0
    )
    return s, cases, sizing


def test_tendons_are_stiffened_where_their_force_areas_reach_a_limit_point(sized_tower):
    """The fixed-base 3-stage tower under its weight and 100 N on each top node: with tendons of
    the areas their forces need, the top load's path reaches a limit point; the design
    stiffens them (``stability`` governs) and carries every case on a stable path."""
    s, cases, sizing = sized_tower
    assert "stability" in sizing.governs
    assert {sizing.governing_case[k] for k, g in enumerate(sizing.governs) if g == "stability"} == {
        "top"
    }
    for case in cases:  # the sized structure's paths hold, found afresh
        follow_load(sizing.structure, case)
    assert sizing.utilisation.largest <= 1 + 2 * RTOL
    weaker = _at_least_areas(s, sizing)
    assert np.all(weaker.tendon_stiffness <= sizing.structure.tendon_stiffness * (1 + 2 * RTOL))
    follow_load(weaker, cases[0])  # its weight alone is carried
    with pytest.raises(LoadPathError, match="load case 'top'"):
        follow_load(weaker, cases[1])


def test_a_stiffening_the_final_areas_do_not_need_is_dropped():
    """The fixed-base prism under 1000 N per top node: the tendons sized for the prestress
    alone reach a limit point, so the first iteration stiffens them; the areas the forces then
    need hold the load on their own, and no member is left governed by that first stiffening."""
    s = _fixed_base_prism()
    case = LoadCase("top", _top_load(1000.0))
    options = dict(rod_material=STEEL, tendon_material=DYNEEMA, prestress=50.0)
    prestressed = size_members(s, **options)
    with pytest.raises(LoadPathError):
        follow_load(prestressed.structure, case)
    sizing = size_at_equilibrium(s, load_cases=[case], **options)
    assert "stability" not in sizing.governs
    follow_load(sizing.structure, case)
    assert sizing.utilisation.largest == pytest.approx(1.0, abs=2 * RTOL)


def test_a_limit_point_no_stiffening_removes_is_one_line():
    """The message names the limit as met with the stiffest tendons tried: 2^20 times the
    area while each doubling takes the path further, 16 times when four doublings took it no
    further (a mechanism that area does not stiffen)."""
    reached = iter(np.linspace(0.6, 0.9, 20))

    def creeps(area):
        raise LoadPathError("top", float(next(reached)), "no stable equilibrium near the path")

    def stays(area):
        raise LoadPathError("top", 0.25, "no stable equilibrium near the path")

    first = LoadPathError("top", 0.5, "no stable equilibrium near the path")
    for acceptable, factor, at in ((creeps, "1.05e+06", "0.9"), (stays, "16", "0.25")):
        with pytest.raises(LoadPathError) as caught:
            _stiffened(acceptable, np.ones(4), 1, first)
        assert str(caught.value) == (
            f"load case 'top': no stable equilibrium near the path even with tendons {factor} "
            f"times the area at {at} of its load (a limit point, where the structure would snap "
            "through, or a mechanism the load moves and nothing stiffens); raise the prestress, "
            "or change the geometry"
        )


def test_the_cli_sizes_the_prism_at_its_loaded_equilibrium(tmp_path, capsys, sized_prism):
    s, _, sizing = sized_prism
    path = write_structure(tmp_path / "prism.json", s)
    out = tmp_path / "out"
    argv = ["design", "--structure", str(path), "--material", "steel,dyneema"]
    argv += ["--prestress", "50", "--gravity", "9.81", "-o", str(out)]
    argv += [f"--load=top:{k}:0,0,-100" for k in (3, 4, 5)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "forces at each case's loaded equilibrium" in text
    assert "members governed: 3 by buckling, 9 by yield" in text
    report = json.loads((out / "design.json").read_text())
    assert report["statics"] == "equilibrium"
    assert report["settings"]["statics"] == "equilibrium"
    assert report["largest_displacement_m"]["top"] == pytest.approx(sizing.displacement[0])
    assert report["total_mass_kg"] == pytest.approx(sizing.total_mass, rel=1e-12)
    assert [r["governed_by"] for r in report["rods"]] == ["buckling"] * 3
    # --statics linear refuses it as before: one line, exit 2, nothing written
    again = tmp_path / "again"
    linear = [str(again) if a == str(out) else a for a in argv] + ["--statics", "linear"]
    assert main(linear) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no member forces balance it" in err
    assert not again.exists()


def test_the_least_area_governing_is_reported(tmp_path, capsys):
    s = _fixed_base_prism()
    path = write_structure(tmp_path / "prism.json", s)
    argv = ["design", "--structure", str(path), "--material", "steel,dyneema"]
    argv += ["--prestress", "50", "--min-area", "1e-3", "-o", str(tmp_path / "out")]
    argv += [f"--load=top:{k}:0,0,-100" for k in (3, 4, 5)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "members governed: 12 by the least area (--min-area)" in text


def _at_least_areas(s: Structure, sizing) -> Structure:
    """The structure of ``sizing``'s members shrunk to the areas their forces need (utilisation
    1 in their governing case): without the stiffening a limit asked for."""
    R = s.n_rods
    area = np.concatenate([sizing.rod_area, sizing.tendon_area])
    u = np.concatenate([sizing.utilisation.rod.max(axis=0), sizing.utilisation.tendon.max(axis=0)])
    least = np.maximum(area * u, 1e-8)
    weaker, _ = sized_structure(
        s,
        rod_material=[STEEL] * R,
        tendon_material=[DYNEEMA] * s.n_tendons,
        rod_area=least[:R],
        tendon_area=least[R:],
        wall_ratio=None,
        prestress_tension=sizing.tendon_tension[0],
        tendon_mass=False,
    )
    return weaker


def test_a_displacement_limit_stiffens_the_tendons_just_enough(sized_prism):
    """The prism sinks 75 mm under its loads when sized for strength alone; limited to 30 mm,
    its tendons are stiffened (``displacement`` governs them) to within the search's 2^(1/8)
    of the limit, and without that stiffening it would sink more than 30 mm."""
    s, case, strength_only = sized_prism
    assert strength_only.displacement[0] > 0.07
    sizing = size_at_equilibrium(
        s,
        rod_material=STEEL,
        tendon_material=DYNEEMA,
        load_cases=[case],
        prestress=50.0,
        max_displacement=0.03,
    )
    assert 0.8 * 0.03 < sizing.displacement[0] <= 0.03
    assert set(sizing.governs[3:]) == {"displacement"} and sizing.governs[:3] == ("buckling",) * 3
    assert sizing.utilisation.largest <= 1 + 2 * RTOL
    assert sizing.total_mass > strength_only.total_mass
    weaker = _at_least_areas(s, sizing)
    eq, _ = follow_load(weaker, case)
    assert np.linalg.norm(eq.node_position - s.node_position, axis=1).max() > 0.03


def test_a_frequency_limit_needs_prestress_and_the_search_finds_the_least(sized_prism):
    """The prestressed prism's lowest mode is its mechanism, stiffened only by the prestress:
    no tendon area raises it (one line saying so), and a prestress range is searched for the
    lightest design that meets the limit, found at the edge where the limit binds."""
    s, case, strength_only = sized_prism
    options = dict(
        rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[case], min_frequency=14.0
    )
    assert strength_only.frequency[0] < 14.0
    with pytest.raises(ServiceabilityError, match="the prestressed state: lowest natural freq"):
        size_at_equilibrium(s, prestress=50.0, **options)
    sizing = size_at_equilibrium(s, prestress=(10.0, 1000.0), **options)
    assert sizing.frequency.min() >= 14.0
    assert sizing.frequency.min() < 14.0 * 1.05
    assert "the lightest of" in sizing.message and 50.0 < sizing.prestress < 1000.0
    with pytest.raises(ServiceabilityError, match="frequency"):
        size_at_equilibrium(s, prestress=0.95 * sizing.prestress, **options)
    heavier = size_at_equilibrium(s, prestress=1.2 * sizing.prestress, **options)
    assert heavier.total_mass > sizing.total_mass


def test_the_cli_takes_serviceability_limits_and_a_prestress_range(tmp_path, capsys):
    path = write_structure(tmp_path / "prism.json", _fixed_base_prism())
    out = tmp_path / "out"
    argv = ["design", "--structure", str(path), "--material", "steel,dyneema", "-o", str(out)]
    argv += ["--gravity", "9.81", "--max-displacement", "0.03", "--prestress", "10:1000"]
    argv += [f"--load=top:{k}:0,0,-100" for k in (3, 4, 5)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    report = json.loads((out / "design.json").read_text())
    assert report["largest_displacement_m"]["top"] <= 0.03
    assert report["settings"]["prestress_N"] == [10.0, 1000.0]
    assert 10.0 < report["prestress_N"] < 1000.0
    assert f"prestress {report['prestress_N']:.4g} N, the lightest of" in text
    assert "lowest frequency" in text
    for bad, message in (
        (["--prestress", "5:2"], "a range must be 0 < LOW < HIGH"),
        (["--max-displacement", "0"], "--max-displacement"),
        (["--statics", "linear"], "prestress: a range is searched only at the loaded"),
    ):
        again = tmp_path / "again"
        code = main([str(again) if a == str(out) else a for a in argv] + bad)
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and message in err
        assert not again.exists()


def test_auto_sizes_a_mechanism_at_equilibrium_even_under_a_load_its_geometry_balances():
    """Two top nodes of the fixed-base prism pulled apart by 500 N: the given geometry balances
    the load (the linear sizing accepts it), but the prism deforms under it and its forces
    change, so the linear design is overstressed at its real equilibrium; ``auto`` sizes a
    structure with a mechanism at the loaded equilibrium, and that design holds there."""
    s = _fixed_base_prism()
    w = np.zeros((6, 3))
    w[3] = (
        500.0
        * (s.node_position[3] - s.node_position[4])
        / np.linalg.norm(s.node_position[3] - s.node_position[4])
    )
    w[4] = -w[3]
    case = LoadCase("apart", w)
    options = dict(rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[case], prestress=50.0)
    linear = size_members(s, **options)
    eq, _ = follow_load(linear.structure, case)
    at_linear = utilisation(
        linear.structure, linear.members, tension=eq.tension, compression=eq.rod_compression
    )
    assert at_linear.largest > 1.01  # measured 1.084
    auto = size(s, **options)
    assert auto.statics == "equilibrium"
    eq, _ = follow_load(auto.structure, case)
    held = utilisation(
        auto.structure, auto.members, tension=eq.tension, compression=eq.rod_compression
    )
    assert held.largest <= 1.0


def test_the_analysis_verbs_report_the_designed_members_utilisation(tmp_path, capsys):
    """``tensegrity design`` writes the material form; ``equilibrium`` and ``modes`` of that
    file report the members' utilisation at the equilibrium with the design's factors: under
    gravity alone, the sizing's own values for its case ``self`` (the same equilibrium, found
    again), and with ``--strength-factor 2`` the tendons' twice as much."""
    path = write_structure(tmp_path / "prism.json", _fixed_base_prism())
    sized = tmp_path / "sized"
    argv = ["design", "--structure", str(path), "--material", "steel,dyneema", "-o", str(sized)]
    argv += ["--prestress", "50", "--gravity", "9.81", "--load", "self:3:0,0,0"]
    argv += [f"--load=top:{k}:0,0,-100" for k in (3, 4, 5)]
    assert main(argv) == 0
    report = json.loads((sized / "design.json").read_text())
    k = report["cases"].index("self")
    expected = [t["yield_utilisation"][k] for t in report["tendons"]]
    capsys.readouterr()
    structure = str(sized / "structure.json")
    for verb, extra in (("equilibrium", ["--method", "least_squares"]), ("modes", [])):
        out = tmp_path / verb
        assert (
            main([verb, "--structure", structure, "--gravity", "9.81", "--out", str(out), *extra])
            == 0
        )
        text = capsys.readouterr().out
        assert "largest tendon utilisation" in text and "utilisation factors" in text
        found = json.loads((out / f"{verb}.json").read_text())["utilisation"]
        np.testing.assert_allclose(found["tendon_yield"], expected, rtol=1e-6)
    out = tmp_path / "doubled"
    assert main(["equilibrium", "--structure", structure, "--gravity", "9.81", "--method",
                 "least_squares", "--strength-factor", "2", "--out", str(out)]) == 0  # fmt: skip
    doubled = json.loads((out / "equilibrium.json").read_text())["utilisation"]
    np.testing.assert_allclose(doubled["tendon_yield"], 2 * np.array(expected), rtol=1e-6)


def test_an_analysis_verb_refuses_factors_without_a_design(tmp_path, capsys):
    code = main(
        ["equilibrium", "--kind", "prism", "--safety-factor", "2", "--out", str(tmp_path / "o")]
    )
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "--safety-factor: needs members with a design" in err
