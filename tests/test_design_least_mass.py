"""The least mass at the loaded equilibrium (``design.least_mass``) and the sensitivities it
stands on (``analysis.equilibrium.equilibrium_sensitivity``): the sensitivities against
equilibria solved again at changed parameters; the least-mass prism under a displacement limit
checked at an equilibrium found independently (a damped simulation to rest), member by member
not lighter where a limit allows, and lighter than the fully stressed design; where the fully
stressed design is the least mass, the search keeps it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tensegrity.analysis.equilibrium import (
    equilibrium_by_simulation,
    equilibrium_sensitivity,
    find_equilibrium,
)
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism
from tensegrity.design.loaded import size_at_equilibrium
from tensegrity.design.materials import material
from tensegrity.design.sizing import LoadCase, sized_structure
from tensegrity.design.utilisation import utilisation
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

GRAVITY = np.array([0.0, 0.0, -9.81])
STEEL, DYNEEMA = material("steel"), material("dyneema")
LIMIT = 0.03  # [m] the top may sink this much


def _fixed_base_prism():
    return prism(3).replace(node_fixed=np.arange(6) < 3)


def _top(P: float) -> LoadCase:
    w = np.zeros((6, 3))
    w[3:, 2] = -P
    return LoadCase("top", w, GRAVITY)


def _sized(s, area: np.ndarray, T0: np.ndarray):
    R = s.n_rods
    return sized_structure(
        s,
        rod_material=[STEEL] * R,
        tendon_material=[DYNEEMA] * s.n_tendons,
        rod_area=area[:R],
        tendon_area=area[R:],
        wall_ratio=None,
        prestress_tension=T0,
        tendon_mass=False,
    )


def _design(**options):
    return size_at_equilibrium(
        _fixed_base_prism(),
        rod_material=STEEL,
        tendon_material=DYNEEMA,
        load_cases=[_top(100.0)],
        prestress=50.0,
        **options,
    )


@pytest.fixture(scope="module")
def designs():
    """The fully stressed and the least-mass prism under the displacement limit."""
    return _design(max_displacement=LIMIT), _design(max_displacement=LIMIT, least_mass=True)


def _areas(sizing) -> np.ndarray:
    return np.concatenate([sizing.rod_area, sizing.tendon_area])


def test_the_sensitivities_equal_equilibria_solved_again():
    """dq/d(log area) of the loaded prism, for every member: against central differences of
    equilibria solved at changed areas (nothing shared but the structure's construction)."""
    s, case = _fixed_base_prism(), _top(100.0)
    sizing = size_at_equilibrium(
        s, rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[case], prestress=50.0
    )
    area, T0 = _areas(sizing), sizing.tendon_tension[0]
    z = np.log(area)

    def structure(dz: np.ndarray):
        return _sized(s, np.exp(z + dz), T0)[0]

    def solved(dz: np.ndarray) -> np.ndarray:
        eq = find_equilibrium(
            structure(dz),
            sizing.equilibria[0].q,
            external_force=case.force,
            gravity=case.gravity,
            descend=False,
        )
        assert eq.converged
        return eq.node_position

    eq = find_equilibrium(
        structure(0 * z), sizing.equilibria[0].q, external_force=case.force, gravity=case.gravity
    )
    h, H = 1e-6, 1e-4
    eye = np.eye(z.size)
    sens = equilibrium_sensitivity(eq, [(structure(-h * e), structure(h * e)) for e in eye], h)
    worst, scale = 0.0, 0.0
    for e in eye:
        nodes = [
            dynamics.nodes_from_coordinates(eq.structure, sens.configuration(x * e))
            for x in (H, -H)
        ]
        analytic = (nodes[0] - nodes[1]) / (2 * H)
        numeric = (solved(H * e) - solved(-H * e)) / (2 * H)
        worst = max(worst, float(np.max(np.abs(analytic - numeric))))
        scale = max(scale, float(np.max(np.abs(numeric))))
    assert scale > 1e-4  # the areas move the loaded prism
    assert worst <= 1e-6 * scale


def test_the_sensitivities_of_a_free_structure_are_those_of_its_shape():
    """A free prism (gauged by Eckart's conditions): the tendon lengths' derivatives with
    respect to each tendon's stiffness, against equilibria solved again."""
    s = prism(3)
    eq = find_equilibrium(s)
    k = s.tendon_stiffness
    h, H = 1e-3, 1e-1  # [N/m]

    def with_k(j: int, dk: float):
        return s.replace(tendon_stiffness=k + dk * (np.arange(k.size) == j))

    sens = equilibrium_sensitivity(eq, [(with_k(j, -h), with_k(j, h)) for j in range(k.size)], h)
    for j in range(k.size):
        moved = [
            dynamics.tendon_lengths(s, dynamics.nodes_from_coordinates(s, sens.configuration(x)))
            for x in (H * np.eye(k.size)[j], -H * np.eye(k.size)[j])
        ]
        solved = [
            find_equilibrium(with_k(j, dk), eq.q, descend=False).tendon_length for dk in (H, -H)
        ]
        analytic = (moved[0] - moved[1]) / (2 * H)
        numeric = (solved[0] - solved[1]) / (2 * H)
        assert np.max(np.abs(numeric)) > 1e-6
        np.testing.assert_allclose(analytic, numeric, rtol=0, atol=1e-5 * np.max(np.abs(numeric)))


def test_the_least_mass_prism_is_lighter_and_meets_every_limit_at_rest(designs):
    stressed, lightest = designs
    assert lightest.message.count("least mass") == 1
    assert lightest.total_mass < 0.99 * stressed.total_mass
    s, case = _fixed_base_prism(), _top(100.0)
    at_rest = equilibrium_by_simulation(
        lightest.structure, external_force=case.force, gravity=case.gravity, t_end=20.0
    )
    assert at_rest.converged
    moved = np.linalg.norm(at_rest.node_position - s.node_position, axis=1).max()
    assert LIMIT * (1 - 1e-3) <= moved <= LIMIT * (1 + 1e-6)  # the limit is active
    u = utilisation(
        s, lightest.members, tension=at_rest.tension, compression=at_rest.rod_compression
    )
    assert u.largest <= 1 + 1e-5
    assert "displacement" in lightest.governs
    assert {"yield", "buckling"} & set(lightest.governs)


def test_no_member_of_the_least_mass_prism_can_be_lighter(designs):
    """Each member 1% lighter, the others kept: its own strength or the displacement limit
    fails at the equilibrium solved anew (a local minimum, member by member)."""
    _, lightest = designs
    s, case = _fixed_base_prism(), _top(100.0)
    area = _areas(lightest)
    T0 = lightest.tendon_tension[0]
    for j in range(area.size):
        trial = area * np.where(np.arange(area.size) == j, 0.99, 1.0)
        sized, members = _sized(s, trial, T0)
        eq = find_equilibrium(
            sized, lightest.equilibria[0].q, external_force=case.force, gravity=case.gravity
        )
        moved = np.linalg.norm(eq.node_position - s.node_position, axis=1).max()
        u = utilisation(s, members, tension=eq.tension, compression=eq.rod_compression)
        assert moved > LIMIT or u.largest > 1, f"member {j} can be 1% lighter"


def test_where_the_fully_stressed_design_is_lightest_the_search_keeps_it():
    """Without a serviceability limit the prism's members are each at their strength (a single
    self-stress): the least mass is the fully stressed design."""
    stressed, lightest = _design(), _design(least_mass=True)
    np.testing.assert_allclose(_areas(lightest), _areas(stressed), rtol=1e-5)
    assert set(lightest.governs) <= {"yield", "buckling"}


def test_the_cli_designs_the_least_mass(tmp_path, capsys):
    out = tmp_path / "prism"
    args = [
        "design", "--kind", "prism", "--fixed-base", "--material", "steel,dyneema",
        "--prestress", "50", "--gravity", "9.81", "--max-displacement", str(LIMIT),
        *[x for n in (3, 4, 5) for x in ("--load", f"top:{n}:0,0,-100")],
        "--least-mass", "-o", str(out),
    ]  # fmt: skip
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "least mass 1.45" in printed
    report = json.loads((out / "design.json").read_text())
    assert report["settings"]["least_mass"] is True
    assert report["total_mass_kg"] < 0.99 * 1.4511
    assert main(["design", "--kind", "prism", "--material", "steel", "--load", "a:0:0,0,-1",
                 "--stability-margin", "0.5", "-o", str(tmp_path / "x")]) == 2  # fmt: skip
    assert "--stability-margin: only with --least-mass" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()


def test_a_planar_structure_is_refused_in_one_line():
    s = Structure(
        node_position=[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        tendon_nodes=[[1, 2]],
        tendon_stiffness=[1000.0],
        tendon_rest_length=[1.0],
        node_fixed=[True, False, True],
    )
    w = np.zeros((3, 2))
    w[1, 1] = -10.0
    with pytest.raises(ValueError, match="least_mass: only for a 3-D structure"):
        size_at_equilibrium(
            s,
            rod_material=STEEL,
            tendon_material=DYNEEMA,
            load_cases=[LoadCase("down", w, None)],
            least_mass=True,
        )


def test_the_constraints_gradient_equals_finite_differences_of_designs():
    """The semi-analytic gradient (sensitivities, then differences along them) of every
    constraint -- yield, buckling, displacement, frequency, stability -- against central
    differences of designs whose load paths are solved again."""
    from tensegrity.design.least_mass import MassProblem, _Constraints
    from tensegrity.design.sizing import buckling_coefficient

    s, case = _fixed_base_prism(), _top(100.0)
    start = _design(max_displacement=LIMIT)
    area, T0 = _areas(start), start.tendon_tension[0]
    R, S = s.n_rods, s.n_tendons
    strength = np.array([STEEL.yield_strength] * R + [DYNEEMA.yield_strength] * S)
    length = np.concatenate([s.rod_length, dynamics.tendon_lengths(s, s.node_position)])
    problem = MassProblem(
        structure_at=lambda a: _sized(s, a, T0)[0],
        geometry=s,
        loads=[case],
        strength=strength,
        beta=buckling_coefficient(
            s.rod_length, np.full(R, STEEL.youngs_modulus), wall_ratio=None, safety_factor=1.0
        ),
        held=np.zeros(R, dtype=bool),
        mass_per_area=np.array([STEEL.density] * R + [DYNEEMA.density] * S) * length,
        lower=np.full(R + S, 1e-8),
        max_displacement=LIMIT,
        min_frequency=1.0,
    )
    constraints = _Constraints(problem, area)
    base = constraints.start
    assert {"tension", "yield", "buckling", "displacement", "frequency", "stability"} <= set(
        base.kinds
    )
    analytic = constraints.gradient(base)
    h = 1e-4
    numeric = np.stack(
        [
            (
                constraints.design(area * np.exp(h * e), base).values
                - constraints.design(area * np.exp(-h * e), base).values
            )
            / (2 * h)
            for e in np.eye(R + S)
        ],
        axis=1,
    )
    assert np.max(np.abs(numeric)) > 0.1
    np.testing.assert_allclose(analytic, numeric, rtol=0, atol=1e-5 * np.max(np.abs(numeric)))
