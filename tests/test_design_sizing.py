"""Materials and sections, member utilisation, and minimal-mass sizing (tensegrity.design).

Closed forms: a string's yield area ``T / sigma_y``; a pinned-pinned bar's buckling area
``2 L sqrt(gamma C / (pi E))`` (solid) and the tube's from ``pi^2 E I / L^2 = gamma C`` with the
tube's own ``I``; a statically determinate structure's forces from the node balance by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from structures import crane
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.design.catalogue import prism
from tensegrity.design.materials import (
    MATERIALS,
    Cable,
    HollowTube,
    Material,
    SolidRod,
    material,
    member_properties,
    member_table,
    parse_section,
    with_members,
)
from tensegrity.design.sizing import LoadCase, size_members
from tensegrity.design.utilisation import run_utilisation, utilisation
from tensegrity.model.structure import Structure

STEEL, DYNEEMA, ALUMINIUM = material("steel"), material("dyneema"), material("aluminium")


# --------------------------------------------------------------------------- materials
def test_table_has_the_eight_materials_with_positive_numbers():
    assert set(MATERIALS) == {
        "steel",
        "stainless",
        "aluminium",
        "titanium",
        "cfrp",
        "dyneema",
        "kevlar",
        "nylon",
    }
    for m in MATERIALS.values():
        assert m.source
        assert 0 < m.yield_strength <= m.ultimate_strength
        assert m.youngs_modulus > 1e9 and 900 < m.density < 9000


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Material("x", -1.0, 1.0, 1.0, 1.0), "material 'x'.youngs_modulus: must be > 0"),
        (lambda: Material("x", 1.0, 1.0, 2.0, 1.0), "ultimate_strength 1 Pa is below"),
        (lambda: material("wood"), "material: unknown 'wood'; one of aluminium, cfrp"),
        (lambda: HollowTube(0.01, 0.006), "more than half the outer diameter"),
        (lambda: parse_section("tube:40"), "expected rod:D, tube:D:T or cable:D"),
        (lambda: parse_section("rod:x"), "expected numbers (millimetres)"),
    ],
)
def test_bad_materials_and_sections_are_one_line(make, message):
    with pytest.raises(ValueError, match=r"^[^\n]*$") as info:
        make()
    assert message in str(info.value)


def test_sections_areas_and_second_moments_by_hand():
    tube = parse_section("tube:40:2")
    assert isinstance(tube, HollowTube)
    D, d = 0.040, 0.036
    assert tube.area == pytest.approx(math.pi * (D**2 - d**2) / 4, rel=1e-14)
    assert tube.second_moment == pytest.approx(math.pi * (D**4 - d**4) / 64, rel=1e-14)
    rod = parse_section("rod:20")
    assert rod.area == pytest.approx(math.pi * 0.02**2 / 4, rel=1e-14)
    assert rod.second_moment == pytest.approx(math.pi * 0.02**4 / 64, rel=1e-14)
    assert parse_section("cable:3").second_moment == 0.0


def test_stiffness_and_mass_from_material_and_section_equal_the_hand_values():
    s = prism(3)
    members = member_properties(
        s,
        rod_material=ALUMINIUM,
        rod_section=HollowTube(0.02, 0.001),
        tendon_material=DYNEEMA,
        tendon_section=Cable(0.002),
    )
    sized = with_members(s, members)
    A_rod = math.pi * (0.02**2 - 0.018**2) / 4
    A_ten = math.pi * 0.002**2 / 4
    np.testing.assert_allclose(sized.rod_mass, 2700.0 * A_rod * s.rod_length, rtol=1e-14)
    np.testing.assert_allclose(
        sized.tendon_stiffness, 116e9 * A_ten / s.tendon_rest_length, rtol=1e-14
    )
    np.testing.assert_array_equal(sized.tendon_rest_length, s.tendon_rest_length)
    rows = member_table(s, members)
    assert [r["kind"] for r in rows] == ["rod"] * 3 + ["tendon"] * 9
    assert rows[3]["stiffness_N_per_m"] == pytest.approx(sized.tendon_stiffness[0], rel=1e-14)
    assert rows[0]["mass_kg"] == pytest.approx(sized.rod_mass[0], rel=1e-14)
    # the tendons' mass, lumped: the structure weighs the rods plus the tendons (free prism)
    heavy = with_members(s, members, tendon_mass=True)
    tendon_mass = 970.0 * A_ten * s.tendon_rest_length
    assert heavy.total_mass == pytest.approx(sized.total_mass + tendon_mass.sum(), rel=1e-13)
    assert heavy.node_mass.sum() == pytest.approx(heavy.total_mass, rel=1e-13)


def test_a_cable_cannot_be_a_rod():
    s = prism(3)
    with pytest.raises(ValueError, match=r"rod_section\[0\]: a cable cannot be a rod"):
        member_properties(
            s,
            rod_material=STEEL,
            rod_section=Cable(0.01),
            tendon_material=STEEL,
            tendon_section=Cable(0.001),
        )


# --------------------------------------------------------------------------- utilisation
def test_utilisation_of_given_forces_by_hand():
    s = prism(3)
    members = member_properties(
        s,
        rod_material=STEEL,
        rod_section=SolidRod(0.01),
        tendon_material=DYNEEMA,
        tendon_section=Cable(0.001),
    )
    T = np.linspace(0.0, 800.0, 9)
    C = np.array([1000.0, -500.0, 0.0])
    u = utilisation(s, members, tension=T, compression=C, safety_factor=2.0)
    A_t, A_r = math.pi * 0.001**2 / 4, math.pi * 0.01**2 / 4
    np.testing.assert_allclose(u.tendon_yield, T / A_t / 3.4e9, rtol=1e-14)
    np.testing.assert_array_equal(u.slack, T <= 0)
    P_euler = math.pi**2 * 210e9 * math.pi * 0.01**4 / 64 / 1.0**2
    np.testing.assert_allclose(u.rod_buckling, [1000.0 / (P_euler / 2), 0.0, 0.0], rtol=1e-14)
    np.testing.assert_allclose(u.rod_yield, np.abs(C) / A_r / 355e6, rtol=1e-14)


def _hand_compression(structure: Structure, p: np.ndarray, tension: np.ndarray) -> np.ndarray:
    """Each rod's ``(f_a - f_b) . n / 2`` with the nodal forces of the tendons, by loops."""
    force = np.zeros_like(p)
    for (tail, head), T in zip(structure.tendon_nodes, tension, strict=True):
        e = (p[head] - p[tail]) / np.linalg.norm(p[head] - p[tail])
        force[tail] += T * e
        force[head] -= T * e
    out = []
    for a, b in structure.rod_nodes:
        n = (p[b] - p[a]) / np.linalg.norm(p[b] - p[a])
        out.append(0.5 * float(np.dot(force[a] - force[b], n)))
    return np.array(out)


def test_utilisation_over_a_run_equals_stress_recomputed_from_its_tensions():
    from tensegrity.engine.simulate import simulate

    s = prism(3, tension=50.0, stiffness=2000.0)
    members = member_properties(
        s,
        rod_material=ALUMINIUM,
        rod_section=HollowTube(0.01, 0.001),
        tendon_material=material("nylon"),
        tendon_section=Cable(0.0015),
    )
    kick = s.node_velocity.copy()
    kick[0] = [0.0, 0.0, 2.0]  # a node pushed: tensions and compressions vary over the run
    result = simulate(s.replace(node_velocity=kick), (0.0, 0.2), sample_dt=0.01)
    run = run_utilisation(result, members, safety_factor=1.5)
    A_t = math.pi * 0.0015**2 / 4
    stress = result.tendon_tension / A_t
    np.testing.assert_allclose(run.samples.tendon_stress, stress, rtol=1e-13)
    np.testing.assert_allclose(run.tendon_peak, (stress / 64e6).max(axis=0), rtol=1e-13)
    assert np.ptp(stress) > 0.1 * stress.max()  # the run did load the tendons unevenly
    compression = np.array(
        [
            _hand_compression(s, p, T)
            for p, T in zip(result.node_position, result.tendon_tension, strict=True)
        ]
    )
    np.testing.assert_allclose(run.samples.rod_compression, compression, rtol=1e-9, atol=1e-9)
    A_r = math.pi * (0.01**2 - 0.008**2) / 4
    I_r = math.pi * (0.01**4 - 0.008**4) / 64
    euler = math.pi**2 * 68.9e9 * I_r / (1.5 * s.rod_length**2)
    rod = np.maximum(np.abs(compression) / A_r / 276e6, np.maximum(compression, 0) / euler)
    np.testing.assert_allclose(run.rod_peak, rod.max(axis=0), rtol=1e-9)
    np.testing.assert_array_equal(run.rod_peak_time, result.t[np.argmax(rod, axis=0)])


# --------------------------------------------------------------------------- sizing
def _string() -> Structure:
    """A tendon from an anchor (node 0) to a point mass (node 1), 2 m along x."""
    return Structure(
        node_position=[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        tendon_nodes=[[0, 1]],
        tendon_stiffness=[1.0],
        tendon_rest_length=[2.0],
        node_fixed=[True, False],
        node_point_mass=[0.0, 1.0],
    )


def _bar(length: float) -> Structure:
    """A rod along x, its tail (node 0) pinned."""
    return Structure(
        node_position=[[0.0, 0.0, 0.0], [length, 0.0, 0.0]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[length],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
        node_fixed=[True, False],
    )


def _load(structure: Structure, node: int, force: list[float]) -> np.ndarray:
    w = np.zeros((structure.n_nodes, 3))
    w[node] = force
    return w


def test_a_single_string_gets_its_yield_area():
    s = _string()
    P = 2000.0
    r = size_members(
        s,
        rod_material=[],
        tendon_material=DYNEEMA,
        load_cases=[LoadCase("pull", _load(s, 1, [P, 0, 0]))],
    )
    A = P / 3.4e9
    np.testing.assert_allclose(r.tendon_area, [A], rtol=1e-12)
    assert r.total_mass == pytest.approx(970.0 * 2.0 * A, rel=1e-12)
    assert r.utilisation.tendon_yield[0, 0] == pytest.approx(1.0, rel=1e-12)
    # a strength factor divides the yield strength
    safer = size_members(
        s,
        rod_material=[],
        tendon_material=DYNEEMA,
        load_cases=[LoadCase("pull", _load(s, 1, [P, 0, 0]))],
        strength_factor=2.0,
    )
    np.testing.assert_allclose(safer.tendon_area, [2 * A], rtol=1e-12)


@pytest.mark.parametrize(
    ("length", "force", "governs"),
    [(1.0, 1000.0, "buckling"), (0.01, 1e6, "yield")],
)
@pytest.mark.parametrize("safety", [1.0, 2.5])
def test_a_single_solid_bar_gets_its_yield_or_buckling_area(length, force, governs, safety):
    s = _bar(length)
    r = size_members(
        s,
        rod_material=STEEL,
        tendon_material=[],
        load_cases=[LoadCase("push", _load(s, 1, [-force, 0, 0]))],
        safety_factor=safety,
    )
    yield_area = force / 355e6
    buckling_area = 2 * length * math.sqrt(safety * force / (math.pi * 210e9))
    assert (buckling_area > yield_area) == (governs == "buckling")
    A = max(yield_area, buckling_area)
    np.testing.assert_allclose(r.rod_area, [A], rtol=1e-12)
    assert r.total_mass == pytest.approx(7850.0 * length * A, rel=1e-12)
    np.testing.assert_allclose(r.rod_compression, [[force]], rtol=1e-12)
    assert r.utilisation.rod.max() == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("wall_ratio", [0.05, 0.2, 0.5])
def test_a_single_hollow_bar_buckles_exactly_at_its_load(wall_ratio):
    s = _bar(1.5)
    C, gamma = 5000.0, 2.0
    r = size_members(
        s,
        rod_material=ALUMINIUM,
        tendon_material=[],
        load_cases=[LoadCase("push", _load(s, 1, [-C, 0, 0]))],
        wall_ratio=wall_ratio,
        safety_factor=gamma,
    )
    # independent of the sizing's I = kappa A^2: the tube's own I (pi (D^4 - d^4) / 64) at the
    # area found gives the Euler load gamma C
    A = float(r.rod_area[0])
    xi = 1 - 2 * wall_ratio
    D = math.sqrt(4 * A / (math.pi * (1 - xi**2)))
    tube = HollowTube(D, wall_ratio * D) if wall_ratio < 0.5 else SolidRod(D)
    assert tube.area == pytest.approx(A, rel=1e-12)
    euler = math.pi**2 * 68.9e9 * tube.second_moment / 1.5**2
    assert euler == pytest.approx(gamma * C, rel=1e-12)
    # the solid bar's mass, and thinner walls lighter
    solid = 2700.0 * 1.5 * 2 * 1.5 * math.sqrt(gamma * C / (math.pi * 68.9e9))
    if wall_ratio == 0.5:
        assert r.total_mass == pytest.approx(solid, rel=1e-12)
    else:
        assert r.total_mass < solid


def test_a_statically_determinate_structure_is_sized_to_the_closed_form_masses():
    s = crane()
    P = 1000.0
    r = size_members(
        s,
        rod_material=STEEL,
        tendon_material=DYNEEMA,
        load_cases=[LoadCase("down", _load(s, 1, [0, 0, -P]))],
    )
    # node 1 by hand: tendons along (-1, +-1, 1)/sqrt(3): T = sqrt(3) P / 2, C = P
    T = math.sqrt(3) * P / 2
    np.testing.assert_allclose(r.tendon_tension, [[T, T]], rtol=1e-9)
    np.testing.assert_allclose(r.rod_compression, [[P]], rtol=1e-9)
    rod = 7850.0 * 1.0 * 2 * 1.0 * math.sqrt(P / (math.pi * 210e9))
    tendons = 2 * 970.0 * math.sqrt(3) * T / 3.4e9
    assert r.total_mass == pytest.approx(rod + tendons, rel=1e-9)
    np.testing.assert_allclose(r.rod_mass, [rod], rtol=1e-9)
    # a second load case: the areas carry the larger of the two
    r2 = size_members(
        s,
        rod_material=STEEL,
        tendon_material=DYNEEMA,
        load_cases=[
            LoadCase("down", _load(s, 1, [0, 0, -P])),
            LoadCase("side", _load(s, 1, [0, -P, -P])),
        ],
    )
    # "side": y: (T1 - T2)/sqrt(3) = P, z: (T1 + T2)/sqrt(3) = P  ->  T1 = sqrt(3) P, T2 = 0
    np.testing.assert_allclose(r2.tendon_tension[1], [math.sqrt(3) * P, 0.0], atol=1e-6)
    np.testing.assert_allclose(r2.tendon_area, [math.sqrt(3) * P / 3.4e9, T / 3.4e9], rtol=1e-9)


def _prism_sizing(**options):
    s = prism(3, rod_length=1.0)
    w = np.zeros((s.n_nodes, 3))
    for k in range(3):  # pull the ends of the bottom tendons apart
        a, b = s.tendon_nodes[k]
        e = s.node_position[b] - s.node_position[a]
        e /= np.linalg.norm(e)
        w[a] -= 300 * e
        w[b] += 300 * e
    return s, size_members(
        s,
        rod_material=ALUMINIUM,
        tendon_material=DYNEEMA,
        load_cases=[LoadCase("pull", w)],
        prestress=50.0,
        wall_ratio=0.05,
        **options,
    )


def test_the_optimum_satisfies_every_constraint_and_is_active_where_it_should_be():
    s, r = _prism_sizing()
    u = r.utilisation
    assert u.largest <= 1 + 1e-9
    # every tendon and rod above the smallest area is fully used in some case
    rod, tendon = u.rod.max(axis=0), u.tendon.max(axis=0)
    np.testing.assert_allclose(rod[r.rod_area > 1.0001e-8], 1.0, rtol=1e-9)
    np.testing.assert_allclose(tendon[r.tendon_area > 1.0001e-8], 1.0, rtol=1e-9)
    # the prestressed state: every tendon at least the prestress, and balanced
    assert r.cases == ("prestress", "pull")
    assert r.tendon_tension[0].min() >= 50.0 * (1 - 1e-9)
    # the structure written is an equilibrium at the geometry with those tensions
    eq = find_equilibrium(r.structure)
    assert eq.converged
    np.testing.assert_allclose(eq.node_position, s.node_position, atol=1e-9)
    np.testing.assert_allclose(eq.tension, r.tendon_tension[0], rtol=1e-7)
    np.testing.assert_allclose(eq.rod_compression, r.rod_compression[0], rtol=1e-7)


def _mass(s: Structure, rod_density: float, rod_area: np.ndarray, tendon_area: np.ndarray):
    length = np.linalg.norm(
        s.node_position[s.tendon_nodes[:, 1]] - s.node_position[s.tendon_nodes[:, 0]], axis=1
    )
    return np.sum(rod_density * s.rod_length * rod_area) + np.sum(
        DYNEEMA.density * length * tendon_area
    )


def test_random_feasible_perturbations_of_the_sizes_never_weigh_less():
    s = crane()
    r = size_members(
        s,
        rod_material=STEEL,
        tendon_material=DYNEEMA,
        load_cases=[LoadCase("down", _load(s, 1, [0, 0, -1000.0]))],
    )
    rng = np.random.default_rng(18)
    feasible = 0
    for _ in range(400):
        rod_area = r.rod_area * (1 + rng.normal(0, 0.02, s.n_rods))
        tendon_area = r.tendon_area * (1 + rng.normal(0, 0.02, s.n_tendons))
        members = r.members._replace(
            rod_area=rod_area,
            rod_second_moment=r.members.rod_second_moment * (rod_area / r.rod_area) ** 2,
            tendon_area=tendon_area,
        )
        u = utilisation(s, members, tension=r.tendon_tension, compression=r.rod_compression)
        if u.largest > 1:
            continue
        feasible += 1
        assert _mass(s, STEEL.density, rod_area, tendon_area) >= r.total_mass * (1 - 1e-12)
    assert feasible >= 20  # some perturbations were feasible (and all of those heavier)


def test_random_feasible_perturbations_of_forces_and_sizes_never_weigh_less():
    """The prism's forces moved along its self-stress (the only freedom the balance leaves), in
    each case, the sizes the least for those forces and then some: never lighter."""
    from tensegrity.analysis.prestress import self_stress

    s, r = _prism_sizing()
    states = self_stress(s).states
    assert states.shape[1] == 1
    tension = states[:, 0] * np.sign(states[0, 0])
    compression = _hand_compression(s, s.node_position, tension)
    rng = np.random.default_rng(18)
    feasible = 0
    for _ in range(400):
        step = rng.normal(0, 2.0, size=(2, 1))  # [N] of self-stress, per case
        T = r.tendon_tension + step * tension
        C = r.rod_compression + step * compression
        if T[0].min() < 50.0 or T.min() < 0:  # the prestress, and no tendon pushes
            continue
        u = utilisation(s, r.members, tension=T, compression=C)
        grow_t = np.maximum(u.tendon.max(axis=0), 0.0)
        grow_r = np.maximum(u.rod_yield.max(axis=0), np.sqrt(u.rod_buckling.max(axis=0)))
        rod_area = np.maximum(r.rod_area * grow_r, 1e-8) * (1 + abs(rng.normal(0, 0.01, 3)))
        tendon_area = np.maximum(r.tendon_area * grow_t, 1e-8) * (1 + abs(rng.normal(0, 0.01, 9)))
        members = r.members._replace(
            rod_area=rod_area,
            rod_second_moment=r.members.rod_second_moment * (rod_area / r.rod_area) ** 2,
            tendon_area=tendon_area,
        )
        assert utilisation(s, members, tension=T, compression=C).largest <= 1 + 1e-12
        feasible += 1
        assert _mass(s, ALUMINIUM.density, rod_area, tendon_area) >= r.total_mass * (1 - 1e-12)
    assert feasible >= 20


def test_a_mechanism_load_is_refused_in_one_line_naming_the_case():
    s = prism(3, rod_length=1.0)
    w = np.zeros((s.n_nodes, 3))
    w[:3, 2], w[3:, 2] = 100.0, -100.0  # squeeze: twists the prism (its mechanism)
    with pytest.raises(ValueError) as info:
        size_members(
            s,
            rod_material=ALUMINIUM,
            tendon_material=DYNEEMA,
            load_cases=[LoadCase("squeeze", w)],
            prestress=10.0,
        )
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("load case 'squeeze': cannot be carried: no member forces balance")


def test_a_string_asked_to_push_is_refused_in_one_line():
    s = _string()
    with pytest.raises(ValueError) as info:
        size_members(
            s,
            rod_material=[],
            tendon_material=DYNEEMA,
            load_cases=[
                LoadCase("pull", _load(s, 1, [10.0, 0, 0])),
                LoadCase("push", _load(s, 1, [-10.0, 0, 0])),
            ],
        )
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith("load case 'push': cannot be carried: every balance of it needs a")


def test_a_prestress_without_a_self_stress_is_refused_in_one_line():
    s = crane()
    with pytest.raises(ValueError, match=r"^prestress: no self-stress puts every tendon in "):
        size_members(
            s,
            rod_material=STEEL,
            tendon_material=DYNEEMA,
            load_cases=[LoadCase("down", _load(s, 1, [0, 0, -10.0]))],
            prestress=5.0,
        )


def test_gravity_counts_the_members_own_weight():
    s = crane()
    g = np.array([0.0, 0.0, -9.81])
    r = size_members(
        s,
        rod_material=STEEL,
        tendon_material=DYNEEMA,
        load_cases=[LoadCase("own weight", _load(s, 1, [0, 0, -1000.0]), gravity=g)],
    )
    # the rod's head carries half its weight on top of the load: by hand, as above
    P = 1000.0 + r.rod_mass[0] * 9.81 / 2
    np.testing.assert_allclose(r.rod_compression, [[P]], rtol=1e-7)
    np.testing.assert_allclose(r.tendon_tension, [[math.sqrt(3) * P / 2] * 2], rtol=1e-7)
    assert r.utilisation.largest <= 1 + 1e-7
    assert r.structure.node_mass[1] == pytest.approx(r.rod_mass[0] / 2, rel=1e-12)


def test_run_utilisation_counts_the_forces_of_the_supports():
    """A sized prism held at a fixed node, on a plane and on a line stays at its prestressed
    equilibrium: at every sample its rods carry the compressions of the sizing's nodal balance,
    which the supports' reactions are part of."""
    from tensegrity.engine.simulate import simulate

    s = prism(3)
    fixed = np.zeros(6, bool)
    fixed[0] = True
    held = s.replace(
        node_fixed=fixed,
        plane_nodes=[1],
        plane_normal=[[0, 0, 1]],
        line_nodes=[2],
        line_direction=[[1, 1, 0]],
    )
    r = size_members(held, rod_material=STEEL, tendon_material=material("kevlar"), prestress=20.0)
    result = simulate(r.structure, (0.0, 0.01), sample_dt=0.005)
    run = run_utilisation(result, r.members)
    expected = np.broadcast_to(r.rod_compression[0], run.samples.rod_compression.shape)
    np.testing.assert_allclose(run.samples.rod_compression, expected, rtol=1e-8)
    np.testing.assert_allclose(run.rod_peak, r.utilisation.rod[0], rtol=1e-8)


def test_rod_forces_with_a_support_equal_the_equilibrium_solvers():
    """The crane's rod is pinned at its tail: the pin pushes back along the rod, so its
    compression is the load's P, not P / 2 from the head's forces alone.  The dynamics'
    constraint forces (rod_axial_forces) against the statics' reactions (find_equilibrium)."""
    from tensegrity.design.utilisation import rod_axial_forces

    s = crane()
    w = _load(s, 1, [0, 0, -1000.0])
    r = size_members(
        s, rod_material=STEEL, tendon_material=DYNEEMA, load_cases=[LoadCase("down", w)]
    )
    # rest lengths that give the loaded case's tensions at the geometry: it is an equilibrium
    EA = r.members.tendon_modulus * r.tendon_area
    length = np.full(2, math.sqrt(3))
    loaded = r.structure.replace(tendon_rest_length=length * EA / (EA + r.tendon_tension[0]))
    eq = find_equilibrium(loaded, external_force=w)
    assert eq.converged
    C = rod_axial_forces(loaded, eq.q, eq.tension, external_force=w)
    np.testing.assert_allclose(C, eq.rod_compression, rtol=1e-9)
    np.testing.assert_allclose(C, [1000.0], rtol=1e-6)
    head_only = _hand_compression(loaded, eq.node_position, eq.tension)
    assert abs(head_only[0] - C[0]) > 400.0


def test_a_shell_under_its_own_weight_alone_is_sized():
    """A form-found class 2 shell on a fixed base under gravity, without prestress: the yield
    program's rods carry almost nothing, and the buckling tangent at that compression is so
    steep that no rod carries its own weight within it; the first tangents are taken further
    out, and the sizing ends within every limit, some member at its limit (it failed with
    'linear program 2 failed: infeasible' before)."""
    from tensegrity.analysis.equilibrium import find_equilibrium
    from tensegrity.model.shell import class2_shell

    shell = class2_shell(3, 2, fixed_base=True)
    shell = shell.replace(node_position=find_equilibrium(shell).node_position)
    sizing = size_members(
        shell,
        rod_material=material("steel"),
        tendon_material=material("dyneema"),
        load_cases=[LoadCase("gravity", None, np.array([0.0, 0.0, -9.81]))],
    )
    assert sizing.message.startswith("converged")
    assert sizing.utilisation.largest == pytest.approx(1.0, abs=1e-6)
