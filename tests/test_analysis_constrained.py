"""The analysis package on structures with joints, supports, point masses and 2-D nodes.

Evidence that does not share the analysis code: closed forms (the compound pendulum, a mass on
two anchored springs, the tripod, Example 2's symmetric equilibrium), the independent SLSQP
minimization of ``tests/test_constraints.py``, damped simulations to rest, FFTs of undamped
simulations (the 2-D model itself for the planar structure), and central differences of the
dynamics' own constrained accelerations.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from tensegrity import Structure, artificial_damping, simulate
from tensegrity.analysis.coordinates import Chart, planar_coordinates, spatial_coordinates
from tensegrity.analysis.equilibrium import (
    compare_equilibria,
    equilibrium_by_simulation,
    find_equilibrium,
)
from tensegrity.analysis.linearize import finite_difference_check, linearize
from tensegrity.analysis.modes import (
    ELASTIC,
    RIGID,
    fft_peak,
    measure_frequency,
    modal_analysis,
    mode_initial_state,
)
from tensegrity.design.catalogue import prism
from tensegrity.model.planar import planar_two_rod, two_rod_equilibrium
from tensegrity.model.shell import class2_shell
from tensegrity.physics.constraints import constraints_of
from tensegrity.physics.dynamics import State
from test_constraints import GRAVITY, G, hanging_chain, pendulum, static_equilibrium


def fixed_base_prism(**options) -> Structure:
    """The 3-bar prism with its three bottom nodes fixed to ground."""
    s = prism(3, **options)
    bottom = np.argsort(s.node_position[:, 2])[:3]
    return s.replace(node_fixed=np.isin(np.arange(s.n_nodes), bottom))


def anchored_mass(k: float = 50.0, m: float = 0.3) -> Structure:
    """A point mass (node 2) on two collinear tendons from anchors at x = -2 and x = 2, rest
    length 1: tension ``k``, axial stiffness ``2k``, transverse ``2 T / l = k``."""
    return Structure(
        node_position=[[-2, 0, 0], [2, 0, 0], [0, 0, 0]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_fixed=[True, True, False],
        node_point_mass=[0, 0, m],
        tendon_nodes=[[0, 2], [2, 1]],
        tendon_stiffness=[k, k],
        tendon_rest_length=[1.0, 1.0],
    )


# ------------------------------------------------------------------------------ chart
def test_constraint_jacobian_and_point_mass_coordinates_match_finite_differences():
    """``G = dg/dx`` and ``J = dp/dx`` of the chart against central differences, on the hanging
    chain (joints, anchors, a joint to an anchor, a point mass); the chart inverts."""
    s = hanging_chain(damped=False)
    chart = Chart.at(s, np.asarray(find_equilibrium(s, gravity=GRAVITY).q))
    x = np.random.default_rng(1).normal(scale=0.1, size=chart.size)
    h = 1e-6
    G_fd = np.column_stack(
        [
            (chart.constraint_residual(x + h * e) - chart.constraint_residual(x - h * e)) / (2 * h)
            for e in np.eye(chart.size)
        ]
    )
    J_fd = np.column_stack(
        [
            (chart.nodes(x + h * e) - chart.nodes(x - h * e)).ravel() / (2 * h)
            for e in np.eye(chart.size)
        ]
    )
    np.testing.assert_allclose(chart.constraint_jacobian(x), G_fd, atol=1e-8)
    np.testing.assert_allclose(chart.jacobian_matrix(x), J_fd, atol=1e-8)
    np.testing.assert_allclose(chart.x(chart.q(x)), x, atol=1e-12)
    assert chart.size == 5 * 2 + 3


# ------------------------------------------------------------------------------ closed forms
@pytest.mark.parametrize("support", ["fixed", "anchor"])
def test_pinned_rod_swings_at_the_compound_pendulum_frequency(support):
    """A uniform rod (m, L) pinned at one end under gravity: ``omega^2 = 3 g / (2 L)``
    (``I = m L^2 / 3`` about the pivot, restoring moment ``m g L / 2``), twice (two swing
    planes); no rigid-body mode (gravity holds both turns about the pivot, the spin is no
    degree of freedom).  The pivot carries the weight at rest."""
    m, L = 2.0, 1.5
    s = pendulum(m, L, support=support, angle=0.4)
    eq = find_equilibrium(s, gravity=GRAVITY)
    assert eq.converged, eq.message
    np.testing.assert_allclose(eq.node_position[1], [0, 0, -L], atol=1e-12)
    # the support's force on the rod's end (with a joint to an anchor, the anchor takes -mg)
    np.testing.assert_allclose(eq.reaction_force[0], [0, 0, m * G], atol=1e-10)
    lin = linearize(s, eq)
    modes = modal_analysis(lin)
    assert modes.kind == (ELASTIC, ELASTIC)
    np.testing.assert_allclose(modes.omega_squared, 3 * G / (2 * L), rtol=1e-12)
    assert max(finite_difference_check(lin).values()) < 1e-7
    system = lin.statespace(outputs="position")  # a named control.StateSpace of the 2 swings
    assert system.nstates == 4 and system.ninputs == 0
    np.testing.assert_allclose(
        np.sort(np.abs(np.linalg.eigvals(system.A))), np.sqrt(3 * G / (2 * L))
    )
    # the nonlinear pendulum, small amplitude, by FFT
    check = measure_frequency(modes, 0, amplitude=1e-4, periods=30)
    assert check.relative_error < 1e-5, check.to_dict()
    # without gravity the two turns about the pivot cost nothing: rigid-body modes
    free = modal_analysis(linearize(s, find_equilibrium(s)))
    assert free.kind == (RIGID, RIGID)


def test_point_mass_between_anchors_has_the_spring_frequencies():
    """Axial ``omega^2 = 2k/m``, transverse ``k/m`` (twice): tension ``T = k (2 - 1)`` over
    length 2 on each side.  Anchors admit no rigid-body motion."""
    k, m = 50.0, 0.3
    s = anchored_mass(k, m)
    eq = find_equilibrium(s, start=[[-2, 0, 0], [2, 0, 0], [0.3, 0.2, -0.1]])
    assert eq.converged, eq.message
    np.testing.assert_allclose(eq.node_position[2], 0.0, atol=1e-12)
    lin = linearize(s, eq)
    modes = modal_analysis(lin)
    assert modes.n_rigid == 0
    np.testing.assert_allclose(modes.omega_squared, [k / m, k / m, 2 * k / m], rtol=1e-12)
    axial = int(np.argmax(modes.omega_squared))
    np.testing.assert_allclose(
        np.abs(modes.node_shapes[axial, 2]), [1 / np.sqrt(m), 0, 0], atol=1e-12
    )
    assert max(finite_difference_check(lin).values()) < 1e-7


def test_tripod_equilibrium_matches_its_closed_form():
    """The tripod of ``tests/test_constraints.py`` (class 3 apex joint, feet on a frictionless
    floor): tension ``T = m g rho / (2 sqrt(3) h)`` at the stable root, floor reaction ``m g``
    per foot, found by least squares from the start layout."""
    m, L, k, rest = 1.2, 1.0, 80.0, 0.9
    angles = 2 * np.pi * np.arange(3) / 3
    feet = 0.5 * np.stack([np.cos(angles), np.sin(angles), np.zeros(3)], axis=1)
    apex = np.array([0, 0, np.sqrt(L**2 - 0.25)])
    s = Structure(
        node_position=np.array([feet[0], apex, feet[1], apex, feet[2], apex]),
        rod_nodes=[[0, 1], [2, 3], [4, 5]],
        rod_mass=[m] * 3,
        rod_length=[L] * 3,
        joint_nodes=[[1, 3], [3, 5]],
        plane_nodes=[0, 2, 4],
        plane_normal=[[0, 0, 1.0]] * 3,
        tendon_nodes=[[0, 2], [2, 4], [4, 0]],
        tendon_stiffness=[k] * 3,
        tendon_rest_length=[rest] * 3,
    )
    eq = find_equilibrium(s, gravity=GRAVITY)
    assert eq.converged, eq.message
    root = brentq(
        lambda rho: (
            1.5 * m * G * rho / np.sqrt(L**2 - rho**2)
            - 3 * np.sqrt(3) * k * (np.sqrt(3) * rho - rest)
        ),
        rest / np.sqrt(3),
        0.8 * L,
    )
    h = np.sqrt(L**2 - root**2)
    p = eq.node_position
    np.testing.assert_allclose(
        np.linalg.norm(p[[0, 2, 4]] - p[[0, 2, 4]].mean(axis=0), axis=1), root, atol=1e-10
    )
    np.testing.assert_allclose(eq.tension, m * G * root / (2 * np.sqrt(3) * h), rtol=1e-9)
    np.testing.assert_allclose(eq.reaction_force[[0, 2, 4]], [[0, 0, m * G]] * 3, atol=1e-9)
    # the floor admits turning about the vertical and sliding: 3 rigid-body modes
    assert modal_analysis(linearize(s, eq)).n_rigid == 3


# ------------------------------------------------------------------------------ two routes
def test_hanging_chain_equilibrium_matches_the_energy_minimum_and_the_simulation():
    s = hanging_chain(damped=True)
    eq = find_equilibrium(s, gravity=GRAVITY)
    assert eq.converged, eq.message
    np.testing.assert_allclose(eq.node_position, static_equilibrium(s), atol=1e-6)
    sim = equilibrium_by_simulation(
        s,
        damping="as-is",
        gravity=GRAVITY,
        velocity_tol=1e-8,
        acceleration_tol=1e-8,
        rtol=1e-9,
        atol=1e-12,
    )
    assert sim.converged, sim.message
    agreement = compare_equilibria(eq, sim)
    assert agreement["node_distance"] < 1e-7 and agreement["tension_difference"] < 1e-5, agreement


@pytest.mark.parametrize("case", ["prism, fixed base, gravity", "class 2 shell"])
def test_constrained_equilibria_by_least_squares_and_by_simulation_agree(case):
    if case == "class 2 shell":
        s, loads = class2_shell(3, 2), {}
    else:
        s, loads = fixed_base_prism(), {"gravity": GRAVITY}
    eq = find_equilibrium(s, **loads)
    assert eq.converged, eq.message
    assert eq.residual_acceleration < 1e-9
    sim = equilibrium_by_simulation(
        s, **loads, velocity_tol=1e-9, acceleration_tol=1e-9, rtol=1e-10, atol=1e-12
    )
    assert sim.converged, sim.message
    agreement = compare_equilibria(eq, sim)
    assert agreement["node_distance"] < 1e-7 and agreement["tension_difference"] < 1e-5, agreement
    # the supports and joints hold
    assert np.max(np.abs(constraints_of(s).residual(eq.q))) < 1e-12
    if "fixed" in case:
        np.testing.assert_allclose(
            eq.node_position[s.node_fixed], s.node_position[s.node_fixed], atol=1e-14
        )


# ------------------------------------------------------------------------------ planar
@pytest.mark.parametrize(("rest_a", "rest_b"), [(0.4, 0.4), (0.5, 0.4)])
def test_planar_example2_equilibrium_matches_the_closed_form(rest_a, rest_b):
    """Example 2 with rest ``rest_a`` on t2, t5 and ``rest_b`` on t1, t3: side lengths, angle
    between the rods, tensions and rod compressions of ``two_rod_equilibrium``; the result is in
    2-D."""
    lengths = (1.0, 0.8)
    s = planar_two_rod(rod_length=lengths, rest_length=(rest_b, rest_a, rest_b, rest_a))
    eq = find_equilibrium(s)
    assert eq.converged, eq.message
    assert eq.node_position.shape == (4, 2) and eq.q.shape == (8,)
    ref = two_rod_equilibrium(lengths, 100.0, rest_a, rest_b)
    np.testing.assert_allclose(
        eq.tendon_length, [ref["b"], ref["a"], ref["b"], ref["a"]], rtol=1e-10
    )
    np.testing.assert_allclose(eq.tension, [ref["tension_b"], ref["tension_a"]] * 2, rtol=1e-10)
    np.testing.assert_allclose(
        eq.rod_compression, [ref["compression_1"], ref["compression_2"]], rtol=1e-10
    )
    r1 = eq.node_position[1] - eq.node_position[0]
    r2 = eq.node_position[3] - eq.node_position[2]
    assert r1 @ r2 / (lengths[0] * lengths[1]) == pytest.approx(ref["cos_phi"], abs=1e-10)


def test_planar_example2_frequency_against_the_fft_of_the_planar_simulation():
    """The 3-D form's linearization (3 rigid motions of the plane, 3 elastic modes) against an
    FFT of the 2-D model's own undamped simulation from the mode's shape."""
    s = planar_two_rod(rest_length=(0.4, 0.5, 0.4, 0.5))
    eq = find_equilibrium(s)
    lin = linearize(s, eq)
    modes = modal_analysis(lin)
    assert modes.kind == (RIGID,) * 3 + (ELASTIC,) * 3
    mode = modes.best_separated()
    shape = modes.shapes[:, mode]
    start = mode_initial_state(lin, shape, 1e-4)
    f_lin = float(modes.frequency_hz[mode])
    run = simulate(
        s,
        (0.0, 40 / f_lin),
        initial=State(0.0, planar_coordinates(s, start.q), np.zeros(8)),
        sample_dt=1 / (16 * f_lin),
        rtol=1e-10,
        atol=1e-14,
    )
    assert run.success, run.message
    eta = lin.to_eta(lin.chart.x(spatial_coordinates(s, run.q)))
    measured = fft_peak(run.t, eta @ (lin.mass * shape), near=f_lin)
    assert measured == pytest.approx(f_lin, rel=1e-5)


# ------------------------------------------------------------------------------ linearization
@pytest.mark.parametrize(
    "case", ["joints", "fixed base", "point mass", "planar", "planar supported"]
)
def test_linearization_is_the_derivative_of_the_constrained_dynamics(case):
    """A, B, D, C, F against central differences of the dynamics' constrained accelerations
    (perturbations projected back onto the constraints), damped."""
    loads = {}
    if case == "joints":
        s = class2_shell(3, 2)
    elif case == "fixed base":
        s, loads = fixed_base_prism(), {"gravity": GRAVITY}
    elif case == "point mass":
        s, loads = hanging_chain(damped=True), {"gravity": GRAVITY}
    elif case == "planar":
        s = planar_two_rod(rest_length=(0.4, 0.5, 0.4, 0.5))
    else:  # a planar structure with a fixed node and a node on a line
        s = planar_two_rod(rest_length=(0.4, 0.5, 0.4, 0.5)).replace(
            node_fixed=[True, False, False, False], line_nodes=[2], line_direction=[[0.0, 1.0]]
        )
        loads = {"gravity": np.array([0.0, -G])}
    eq = find_equilibrium(s, **loads)
    assert eq.converged, eq.message
    s = artificial_damping(s)
    errors = finite_difference_check(linearize(s, eq))
    assert max(errors.values()) < 1e-7, errors


def test_fixed_base_frequency_against_the_fft_of_the_constrained_simulation():
    """The prism with its base fixed, under gravity: no rigid-body mode, and the
    best-separated frequency of the constrained linearization in the FFT of an undamped
    nonlinear simulation (constraint forces solved by the dynamics)."""
    s = fixed_base_prism()
    eq = find_equilibrium(s, gravity=GRAVITY)
    modes = modal_analysis(linearize(s, eq))
    assert modes.n_rigid == 0 and modes.stable and len(modes.kind) == 3 * 5 - 3 * 3
    check = measure_frequency(modes)
    assert check.relative_error < 1e-5, check.to_dict()


def test_rigid_body_modes_are_the_ones_the_supports_admit():
    """Free class 2 shell: 6; fixed base: none; planar: 3 (the plane's)."""
    free = class2_shell(3, 2)
    assert modal_analysis(linearize(free, find_equilibrium(free))).n_rigid == 6
    fixed = class2_shell(3, 2, fixed_base=True)
    lin = linearize(fixed, find_equilibrium(fixed))
    assert modal_analysis(lin).n_rigid == 0
    assert lin.n_dof == 12 * 5 - 3 * (2 * 3 * 1) - 3 * 6  # 12 rods, 6 joints, 6 fixed nodes


# ------------------------------------------------------------------------------ command line
def _cli(argv, capsys):
    from tensegrity.cli.main import main

    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_cli_analysis_verbs_take_a_planar_structure_file(tmp_path, capsys):
    """``export --kind planar`` then ``equilibrium`` (both routes, 2-D node positions, tensions
    of the closed form) and ``modes`` (3 rigid motions of the plane, the library's frequencies);
    ``control`` (3-D outputs) refuses it in one line and writes nothing."""
    import json

    path = tmp_path / "planar.json"
    assert _cli(["export", "--kind", "planar", "-o", path], capsys)[0] == 0
    code, _, err = _cli(["equilibrium", "--structure", path, "--out", tmp_path / "eq"], capsys)
    assert code == 0, err
    data = json.loads((tmp_path / "eq" / "equilibrium.json").read_text())
    s = Structure.from_dict(json.loads(path.read_text()))
    rest_a, rest_b = s.tendon_rest_length[1], s.tendon_rest_length[0]
    ref = two_rod_equilibrium(tuple(s.rod_length), float(s.tendon_stiffness[0]), rest_a, rest_b)
    for route in ("least_squares", "simulation"):
        assert data[route]["converged"]
        assert np.shape(data[route]["node_position_m"]) == (4, 2)
        tension = [t["tension_N"] for t in data[route]["tendons"]]
        np.testing.assert_allclose(tension, [ref["tension_b"], ref["tension_a"]] * 2, rtol=1e-5)
    assert data["agreement"]["node_distance"] < 1e-5
    code, _, err = _cli(["modes", "--structure", path, "--out", tmp_path / "modes"], capsys)
    assert code == 0, err
    modes = json.loads((tmp_path / "modes" / "modes.json").read_text())
    expected = modal_analysis(linearize(s, find_equilibrium(s)))
    assert modes["rigid_body_modes"] == 3 and modes["stable"]
    np.testing.assert_allclose(
        [m["frequency_hz"] for m in modes["modes"]], expected.frequency_hz, rtol=1e-9, atol=1e-9
    )
    code, _, err = _cli(["control", "--structure", path, "--out", tmp_path / "control"], capsys)
    assert code == 2 and not (tmp_path / "control").exists()
    assert err.strip().count("\n") == 0 and "shape control: supports only 3-D structures" in err


def test_cli_modes_and_controllability_of_a_fixed_base_class2_shell(tmp_path, capsys):
    """A class 2 shell with its base fixed (joints and supports): no rigid-body mode, the
    library's frequencies; a fixed node's position is observable from nothing, all node
    positions see every mode."""
    import json

    path = tmp_path / "c2.json"
    assert (
        _cli(["export", "--kind", "class2-shell", "--m", "2", "--fixed-base", "-o", path], capsys)[
            0
        ]
        == 0
    )
    s = Structure.from_dict(json.loads(path.read_text()))
    code, _, err = _cli(["modes", "--structure", path, "--out", tmp_path / "modes"], capsys)
    assert code == 0, err
    modes = json.loads((tmp_path / "modes" / "modes.json").read_text())
    expected = modal_analysis(linearize(s, find_equilibrium(s)))
    assert modes["rigid_body_modes"] == 0 and len(modes["modes"]) == 24
    np.testing.assert_allclose(
        [m["frequency_hz"] for m in modes["modes"]], expected.frequency_hz, rtol=1e-9
    )
    code, _, err = _cli(
        [
            "controllability",
            "--structure",
            path,
            "--inputs",
            "all",
            "--outputs",
            "position",
            "p0_*",
            "--out",
            tmp_path / "ctrl",
        ],
        capsys,
    )
    assert code == 0, err
    data = json.loads((tmp_path / "ctrl" / "controllability.json").read_text())
    assert data["states"] == 48
    assert data["controllability"][0]["rank"] == 48
    position, node0 = data["observability"]
    assert s.node_fixed[0] and position["rank"] == 48 and node0["rank"] == 0


# ------------------------------------------------------------------------------ prestress
def test_self_stress_and_prestress_with_supports():
    """The 3-bar prism with its base fixed: the free prism's self-stress stays one; the three
    base tendons (between fixed nodes) add one state each; Maxwell's rule with the admitted
    motions (``s - m = S - k``, no rigid motion left).  The LP prestress, realized by rest
    lengths, leaves Theorem 18.1 with its constraint forces at rest in the layout."""
    from tensegrity.analysis.prestress import (
        feasible_prestress,
        rest_lengths_for_tensions,
        self_stress,
    )
    from tensegrity.physics import dynamics

    free, s = prism(3), fixed_base_prism()
    states = self_stress(s)
    k = states.matrix.shape[0]
    assert k == 15 - 9 and states.n_states == 4 and states.n_states - states.n_mechanisms == 9 - k
    T0 = dynamics.tendon_tensions(free, free.node_position)
    np.testing.assert_allclose(states.states @ (states.states.T @ T0), T0, atol=1e-12)
    prestress = feasible_prestress(s, mean_tension=5.0)
    assert prestress.feasible and prestress.residual < 1e-10
    rest, _ = rest_lengths_for_tensions(s, None, prestress.tension)
    held = s.replace(tendon_rest_length=rest)
    q = dynamics.coordinates_from_nodes(held, held.node_position)
    assert np.max(np.abs(dynamics.accelerations(held, q, np.zeros_like(q)))) < 1e-9
    # the best one: the base tendons (free to take anything) as tight as the top ring, i.e. the
    # free prism's own self-stress, which needs no reaction: the rods carry what they carry free
    np.testing.assert_allclose(prestress.tension, T0, rtol=1e-9)
    np.testing.assert_allclose(
        prestress.rod_compression,
        feasible_prestress(free, mean_tension=5.0).rod_compression,
        rtol=1e-9,
    )


def test_planar_self_stress_is_the_closed_form_one():
    """Example 2: one self-stress, with ``T_a / a = T_b / b`` (equal force densities)."""
    from tensegrity.analysis.prestress import self_stress

    s = planar_two_rod(rest_length=(0.4, 0.5, 0.4, 0.5))
    eq = find_equilibrium(s)
    states = self_stress(s, eq.q)
    assert states.n_states == 1 and states.n_mechanisms == 0 and states.matrix.shape == (6, 4)
    ref = two_rod_equilibrium((1.0, 0.8), 100.0, 0.5, 0.4)
    expected = np.array([ref["b"], ref["a"], ref["b"], ref["a"]])
    np.testing.assert_allclose(
        np.abs(states.states[:, 0]), expected / np.linalg.norm(expected), rtol=1e-10
    )


def test_form_finding_keeps_the_supports():
    """Form-finding of the fixed-base prism from loosened rest lengths: stable, every tendon
    taut at the requested mean tension, the base where it was."""
    from tensegrity.analysis.prestress import form_find

    s = fixed_base_prism()
    found = form_find(s.replace(tendon_rest_length=1.3 * s.tendon_rest_length), mean_tension=5.0)
    assert found.stable, found.verdict
    assert found.equilibrium.tension.mean() == pytest.approx(5.0, rel=1e-6)
    np.testing.assert_allclose(
        found.equilibrium.node_position[s.node_fixed], s.node_position[s.node_fixed], atol=1e-14
    )


def test_prestress_rod_force_includes_the_support_reaction():
    """A rod pinned at its foot, a tendon from its top to an anchor straight above: the tendon's
    pull along the rod is a self-stress (the pin takes it), and the rod is in tension ``T``
    (compression ``-T``; without the pin's reaction it would read ``-T/2``)."""
    from tensegrity.analysis.prestress import feasible_prestress, self_stress

    s = Structure(
        node_position=[[0, 0, 0], [0, 0, 1.0], [0, 0, 2.0]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        node_fixed=[True, False, True],
        tendon_nodes=[[1, 2]],
        tendon_stiffness=[10.0],
        tendon_rest_length=[0.5],
    )
    assert self_stress(s).n_states == 1
    prestress = feasible_prestress(s, mean_tension=3.0, compressed_rods=False)
    assert prestress.feasible and prestress.tension == pytest.approx([3.0])
    np.testing.assert_allclose(prestress.rod_compression, [-3.0], rtol=1e-12)


# ------------------------------------------------------------------------------ shape control
def test_shape_sensitivities_with_supports_match_re_solved_equilibria():
    """``dy/du`` and ``dT/du`` of the fixed-base class 2 shell against central differences of
    equilibria solved again with the rest lengths changed."""
    from tensegrity.analysis.shape_control import height_twist, sensitivities
    from tensegrity.cli.control import rings

    s = class2_shell(3, 2, fixed_base=True)
    eq = find_equilibrium(s)
    output = height_twist(eq.node_position, *rings(s, eq.node_position))
    dydu, dTdu, _ = sensitivities(eq, output, eq.node_position)
    h = 1e-6
    for j in (0, 5, 17):
        du = h * np.eye(s.n_tendons)[j]
        plus, minus = (
            find_equilibrium(s, eq.q, control=sign * du, gauge_reference=eq.node_position)
            for sign in (1, -1)
        )
        dT = (plus.tension - minus.tension) / (2 * h)
        dy = (output.value(plus.node_position) - output.value(minus.node_position)) / (2 * h)
        np.testing.assert_allclose(dT, dTdu[:, j], atol=1e-6 * np.abs(dT).max())
        np.testing.assert_allclose(dy, dydu[:, j], atol=1e-6 * np.abs(dy).max())


def test_shape_control_of_a_shell_on_a_fixed_base():
    """The (4,2) shell with its bottom ring fixed: shortened by 20% with the t1 tendons, twisted
    back with all; the open loop reaches the targets, and so does the LQR closed loop on the
    nonlinear model (constraint forces, projection), with the base where it was."""
    from tensegrity import class1_shell
    from tensegrity.analysis.shape_control import (
        Bounds,
        closed_loop,
        height_twist,
        quasi_static,
        shell_rings,
    )

    bottom, top = shell_rings(4, 2)
    s = class1_shell(4, 2)
    s = s.replace(node_fixed=np.isin(np.arange(s.n_nodes), bottom))
    eq = find_equilibrium(s)
    output = height_twist(eq.node_position, bottom, top)
    h0 = output.value(eq.node_position)[0]
    plan = quasi_static(
        s,
        output,
        [{"targets": (0.8 * h0, None), "actuators": "t1_*"}, (0.8 * h0, 0.0)],
        start=eq,
        steps=[4, 2],
        bounds=Bounds(),
        tolerance=[1e-6, 1e-6],
    )
    assert plan.reached, plan.message
    run = closed_loop(plan, move_time=2.0, settle_time=3.0)
    assert run.reached, run.message
    np.testing.assert_allclose(
        run.node_position[:, bottom],
        np.broadcast_to(s.node_position[bottom], (run.t.size, len(bottom), 3)),
        atol=1e-12,
    )
    y = output.value(run.node_position[-1])  # measured from the simulated nodes themselves
    np.testing.assert_allclose(y, [0.8 * h0, 0.0], atol=1e-6)


def test_cli_modes_of_point_masses_only(tmp_path, capsys):
    """A structure without rods (a mass on two anchored tendons): ``modes`` prints and draws
    the spring frequencies ``sqrt(k/m)`` (twice) and ``sqrt(2k/m)`` [rad/s]."""
    import json

    k, m = 50.0, 0.3
    path = tmp_path / "mass.json"
    path.write_text(json.dumps(anchored_mass(k, m).to_dict()))
    code, _, err = _cli(["modes", "--structure", path, "--out", tmp_path / "modes"], capsys)
    assert code == 0, err
    data = json.loads((tmp_path / "modes" / "modes.json").read_text())
    np.testing.assert_allclose(
        [mode["frequency_hz"] for mode in data["modes"]],
        np.sqrt([k / m, k / m, 2 * k / m]) / (2 * np.pi),
        rtol=1e-12,
    )
    assert (tmp_path / "modes" / "mode_shapes.png").stat().st_size > 10_000


def test_default_input_sets_for_tendon_names_without_families():
    """Tendon names like the prism's ``b0, t0, s0`` (no ``_``) form the families ``b*``, ``t*``,
    ``s*`` (before, ``b0_*`` matched nothing and the default table failed)."""
    from tensegrity.analysis.controllability import controllability_table, default_input_sets

    s = fixed_base_prism()
    lin = linearize(artificial_damping(s), find_equilibrium(s))
    sets = default_input_sets(lin)
    assert {name: len(v) for name, v in sets.items()} == {
        "all": 9,
        "b*": 3,
        "t*": 3,
        "s*": 3,
        "b0": 1,
    }
    reach, _ = controllability_table(lin, modal_analysis(lin))
    assert reach[0].rank == 2 * lin.n_dof


def test_cli_gravity_hangs_a_pinned_rod_and_swings_it_at_the_pendulum_frequency(tmp_path, capsys):
    """``--gravity``: ``equilibrium`` hangs the pinned rod straight down (both routes),
    ``modes`` gives the compound pendulum ``sqrt(3 g / (2 L)) / (2 pi)`` [Hz] twice, and
    ``simulate`` lets it fall; a number and the vector ``0,0,-g`` mean the same."""
    import json

    m, L = 2.0, 1.5
    path = tmp_path / "pendulum.json"
    path.write_text(json.dumps(pendulum(m, L, support="fixed", angle=0.4).to_dict()))
    for gravity in (str(G), f"0,0,{-G}"):
        out = tmp_path / f"eq{len(gravity)}"
        code, _, err = _cli(
            [
                "equilibrium",
                "--structure",
                path,
                "--gravity",
                gravity,
                "--method",
                "least_squares",
                "--out",
                out,
            ],
            capsys,
        )
        assert code == 0, err
        data = json.loads((out / "equilibrium.json").read_text())
        np.testing.assert_allclose(
            data["least_squares"]["node_position_m"][1], [0, 0, -L], atol=1e-12
        )
        assert data["least_squares"]["gravity_m_s2"] == [0.0, 0.0, -G]
    code, _, err = _cli(
        ["modes", "--structure", path, "--gravity", str(G), "--out", tmp_path / "modes"], capsys
    )
    assert code == 0, err
    data = json.loads((tmp_path / "modes" / "modes.json").read_text())
    np.testing.assert_allclose(
        [mode["frequency_hz"] for mode in data["modes"]],
        [np.sqrt(3 * G / (2 * L)) / (2 * np.pi)] * 2,
        rtol=1e-12,
    )
    # without --gravity the same file has two rigid-body turns about the pivot instead
    code, _, err = _cli(["modes", "--structure", path, "--out", tmp_path / "free"], capsys)
    assert code == 0, err
    free = json.loads((tmp_path / "free" / "modes.json").read_text())
    assert [mode["kind"] for mode in free["modes"]] == ["rigid", "rigid"]
    code, _, err = _cli(
        [
            "simulate",
            "--structure",
            path,
            "--gravity",
            str(G),
            "--t-end",
            "0.2",
            "--no-steady-state",
            "--out",
            tmp_path / "sim",
        ],
        capsys,
    )
    assert code == 0, err
    from tensegrity.io.trajectory import read_trajectory

    tip = read_trajectory(tmp_path / "sim" / "trajectory.h5").node_position[:, 1, 2]
    assert tip[-1] < tip[0] - 0.05 and np.all(np.diff(tip) <= 1e-12)  # falls from rest
    for bad in ("down", "1,2"):
        code, _, err = _cli(
            ["modes", "--structure", path, "--gravity", bad, "--out", tmp_path / "bad"], capsys
        )
        assert code == 2 and err.count("\n") == 1 and "gravity" in err, err
    assert not (tmp_path / "bad").exists()


def test_info_counts_the_degrees_of_freedom_the_supports_leave(tmp_path, capsys):
    """Counted by hand: a rod pinned at one end turns about it (2); with both ends fixed it
    cannot move (0: six support rows, five degrees of freedom); a point mass between two
    anchors moves freely in space (3); a class 2 shell (3, 2) has 12 rods (60) and 6 ball joints
    (3 each): 42; the planar two-rod tensegrity, free, 3 per rod (6)."""
    import json

    from tensegrity.analysis.coordinates import admitted_dof

    both_fixed = pendulum(support="fixed").replace(node_fixed=[True, True])
    from tensegrity.model.shell import class2_shell

    cases = {
        "pinned": (pendulum(support="fixed"), 2),
        "both ends fixed": (both_fixed, 0),
        "point mass": (anchored_mass(), 3),
        "class 2 shell": (class2_shell(3, 2), 42),
        "planar": (planar_two_rod(), 6),
    }
    for name, (structure, expected) in cases.items():
        assert admitted_dof(structure) == expected, name
        path = tmp_path / f"{name.replace(' ', '_')}.json"
        path.write_text(json.dumps(structure.to_dict()))
        code, out, err = _cli(["info", "--structure", path], capsys)
        assert code == 0, err
        line = next(row for row in out.splitlines() if row.startswith("degrees of freedom"))
        assert line.split()[3] == str(expected), (name, line)
        if structure.has_constraints:
            assert f"less {structure.n_dof - expected} held by the joints and supports" in line
