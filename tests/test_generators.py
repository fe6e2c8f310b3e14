"""Generated structures against closed forms: the prism's twist and self-stress, the octahedron's.

The regular n-bar prism, derived here from nodal equilibrium (the result is Kenner's, 1976, and
in Skelton & de Oliveira, *Tensegrity Systems*, 2009, ch. 2; see docs/networks.md).

Bottom node ``b_i`` at angle ``2 pi i/n``, height 0; top node ``t_i`` at angle ``2 pi i/n + alpha``,
height ``h``; all at radius ``r``.  Bar ``b_i t_i`` (force density ``q_b``, compression),
bottom-ring strings ``b_i b_{i+-1}`` (``q_r``), side string ``b_i t_j`` (``q_s``).  Equilibrium
of ``b_i`` (tensions pull, the bar pushes, force = density x member vector):

    q_b (b_i - t_i) + q_s (t_j - b_i) + q_r (b_{i+1} + b_{i-1} - 2 b_i) = 0.

- ``z``: ``-q_b h + q_s h = 0``, so ``q_s = q_b``; the horizontal part is then
  ``q_b (t_j - t_i) + q_r (b_{i+1} + b_{i-1} - 2 b_i) = 0``.
- The ring term is radial (inward, ``4 r q_r sin^2(pi/n)``), so ``t_j - t_i`` must be radial
  too.  With ``b_i`` on the ``x`` axis, its ``y`` part is ``r (sin(alpha +- 2pi/n) - sin alpha)``,
  zero for ``alpha = pi/2 -+ pi/n`` (side string to ``t_{i+-1}``).  Of the two, only
  ``j = i - 1``, ``alpha = pi/2 + pi/n`` gives an outward ``t_j - t_i`` (``x`` part
  ``r (cos(alpha - 2pi/n) - cos alpha) = 2 r sin(pi/n) > 0``), i.e. ring strings in tension.
- The side string then sweeps ``alpha - 2 pi/n = pi/2 - pi/n``: the top polygon is turned by
  ``phi = pi/2 - pi/n`` relative to the bottom (30 degrees for n = 3, 45 for n = 4), measured
  from a bottom node to the top node its side string reaches, in the sense of the bars' sweep.
- ``x``: ``q_b 2 r sin(pi/n) = q_r 4 r sin^2(pi/n)``, so ``q_r = q_b / (2 sin(pi/n))``.

Forces (density x length): ring ``T_r = q_r 2 r sin(pi/n) = q_b r``, side ``T_s = q_b l_s``, bar
compression ``F_b = q_b l_b``: **T_r : T_s : F_b = r : l_s : l_b**, the top ring alike by symmetry.

The expanded octahedron (bars ``L`` long in three parallel pairs ``s`` apart, 24 strings of one
force density ``q``, bars ``q_b``): at node ``(L/2, 0, s/2)`` the four strings sum to
``q (s - 2L, 0, L - 2s)`` and the bar gives ``q_b (L, 0, 0)``: ``s = L/2`` and ``q_b = 3q/2``;
strings are ``sqrt(6)/4 L`` long, so **F_b / T = (3/2) L / (sqrt(6)/4 L) = sqrt(6)**.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tensegrity.analysis.equilibrium import equilibrium_by_simulation, find_equilibrium
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import modal_analysis
from tensegrity.analysis.prestress import feasible_prestress, self_stress
from tensegrity.design import catalogue as generators
from tensegrity.design.catalogue import (
    octahedron,
    prism,
    prism_layout,
    prism_members,
    prism_twist,
    tower,
)
from tensegrity.model.connectivity import from_connectivity, incidence
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics


def polygon_twist(p: np.ndarray, n: int) -> np.ndarray:
    """Angles (n,) [rad] from bottom node i to top node i-1 about the axis through the polygons'
    centres, signed by the right-hand rule about the bottom-to-top axis; blind to rigid motion."""
    bottom, top = p[:n], p[n : 2 * n]
    cb, ct = bottom.mean(axis=0), top.mean(axis=0)
    e = (ct - cb) / np.linalg.norm(ct - cb)
    u = bottom - cb
    w = np.roll(top - ct, 1, axis=0)  # w[i] = t[i-1] - ct
    u -= np.outer(u @ e, e)
    w -= np.outer(w @ e, e)
    return np.arctan2(np.cross(u, w) @ e, np.sum(u * w, axis=1))


# ----------------------------------------------------------------------------- the prism
@pytest.mark.parametrize("n", [3, 4, 5, 6])
def test_prism_twist_found_by_damped_simulation_and_by_the_solver(n):
    """From a twist 12 degrees short of the closed form, with rest lengths that know nothing of
    it (70 % of the start's string lengths), the damped structure comes to rest at
    ``pi/2 - pi/n``; the static solver lands there too.  Measured deviations: 1e-11..3e-11 rad
    (simulation, at rest to 1e-9 m/s), 7e-16 rad (solver)."""
    start = prism_layout(n, twist=prism_twist(n) - math.radians(12))
    rods, tendons, names = prism_members(n)
    length = np.linalg.norm(start[tendons[:, 1]] - start[tendons[:, 0]], axis=1)
    s = from_connectivity(
        start.T,
        incidence(rods, 2 * n),
        incidence(tendons, 2 * n),
        tendon_rest_length=0.7 * length,
        tendon_name=names,
    )
    assert np.all(np.abs(polygon_twist(start, n) - (math.pi / 2 - math.pi / n)) > math.radians(11))
    by_simulation = equilibrium_by_simulation(
        s, t_end=60.0, velocity_tol=1e-9, acceleration_tol=1e-9
    )
    assert by_simulation.converged, by_simulation.message
    assert not by_simulation.slack.any()
    by_solver = find_equilibrium(s)
    assert by_solver.converged and not by_solver.slack.any()
    for eq, tol in ((by_simulation, 1e-9), (by_solver, 1e-12)):
        np.testing.assert_allclose(
            polygon_twist(eq.node_position, n), math.pi / 2 - math.pi / n, rtol=0, atol=tol
        )
    assert prism_twist(3) == pytest.approx(math.radians(30), abs=1e-15)
    assert prism_twist(4) == pytest.approx(math.radians(45), abs=1e-15)


@pytest.mark.parametrize("n", [3, 4, 5, 8])
def test_prism_self_stress_is_the_analytic_one(n):
    """One self-stress state at the closed-form twist, proportional to ring : side = r : l_s and
    bar compression l_b (per unit q_b); none at another twist."""
    s = prism(n)
    states = self_stress(s)
    assert states.n_states == 1
    p = s.node_position
    r = np.linalg.norm(p[0, :2])
    l_s = np.linalg.norm(p[n - 1 + n] - p[0])  # side string: bottom 0 -> top n-1
    l_b = float(s.rod_length[0])
    analytic = np.concatenate([np.full(2 * n, r), np.full(n, l_s)])  # names b*, t*, s*
    T = states.states[:, 0] * np.sign(states.states[-1, 0])
    np.testing.assert_allclose(
        T / np.linalg.norm(T), analytic / np.linalg.norm(analytic), rtol=0, atol=1e-12
    )
    # The generator's prestress (the LP's): the same ratios, bars compressed l_b / l_s x side.
    tension = dynamics.tendon_tensions(s, p)
    np.testing.assert_allclose(tension / tension[-1], analytic / l_s, rtol=1e-10)
    assert tension.mean() == pytest.approx(5.0, rel=1e-12)
    compression = feasible_prestress(s, mean_tension=5.0).rod_compression
    np.testing.assert_allclose(compression, tension[-1] * l_b / l_s, rtol=1e-9)
    # Off the closed-form twist, no self-stress at all.
    off = s.replace(node_position=prism_layout(n, twist=prism_twist(n) + 0.05))
    assert self_stress(off).n_states == 0


def test_prism_height_is_a_free_parameter_of_the_equilibrium():
    for height in (0.3, 0.5, 0.9):
        s = prism(3, height=height)
        assert np.ptp(s.node_position[3:, 2]) == 0 and s.node_position[3, 2] == pytest.approx(
            height
        )
        np.testing.assert_allclose(polygon_twist(s.node_position, 3), math.pi / 6, atol=1e-14)
        assert self_stress(s).n_states == 1
    with pytest.raises(ValueError, match=r"^height: must be < rod_length"):
        prism(3, height=1.0)
    with pytest.raises(ValueError, match=r"^n: must be an integer >= 3"):
        prism(2)


# ---------------------------------------------------------------------- the octahedron
def test_octahedron_matches_the_closed_form():
    s = octahedron(rod_length=2.0, tension=3.0)
    assert (s.n_nodes, s.n_rods, s.n_tendons) == (12, 6, 24)
    lengths = dynamics.tendon_lengths(s, s.node_position)
    np.testing.assert_allclose(lengths, math.sqrt(6) / 4 * 2.0, rtol=1e-14)
    # bar pairs L/2 apart, parallel
    a, b = s.rod_nodes.T
    centre = 0.5 * (s.node_position[a] + s.node_position[b])
    np.testing.assert_allclose(np.linalg.norm(centre, axis=1), 0.5, rtol=1e-14)
    assert np.all(np.bincount(s.tendon_nodes.ravel()) == 4)
    states = self_stress(s)
    assert states.n_states == 1
    T = dynamics.tendon_tensions(s, s.node_position)
    np.testing.assert_allclose(T, 3.0, rtol=1e-9)
    compression = feasible_prestress(s, mean_tension=3.0).rod_compression
    np.testing.assert_allclose(compression, math.sqrt(6) * 3.0, rtol=1e-9)


# ---------------------------------------------------------------------- all generators
STRUCTURES = {
    "simplex": lambda: prism(3),
    "4-bar prism": lambda: prism(4, stiffness=300.0, tension=8.0),
    "octahedron": octahedron,
    "tower 3x3": tower,
    "tower 4x2": lambda: tower(4, 2, overlap=0.2),
}


@pytest.fixture(scope="module", params=list(STRUCTURES))
def generated(request):
    return request.param, STRUCTURES[request.param]()


def test_generated_layout_is_a_stable_taut_equilibrium(generated):
    """At rest in its layout (accelerations ~0), every tendon taut, every rod 1 m, stable by
    modal analysis (no mechanism, no negative stiffness)."""
    name, s = generated
    assert isinstance(s, Structure)
    np.testing.assert_allclose(s.rod_length, 1.0, rtol=1e-14)
    a, b = s.rod_nodes.T
    np.testing.assert_allclose(
        np.linalg.norm(s.node_position[b] - s.node_position[a], axis=1), 1.0, rtol=1e-12
    )
    state = dynamics.initial_state(s)
    acceleration = dynamics.accelerations(s, state.q, state.qdot)
    assert np.abs(acceleration).max() < 1e-9, name
    tension = dynamics.tendon_tensions(s, s.node_position)
    assert tension.min() > 0.1 * tension.mean() and tension.mean() > 0
    modes = modal_analysis(linearize(s))
    assert modes.stable, (name, modes.verdict)


def test_a_disturbed_generated_structure_returns(generated):
    """Kicked (random velocities consistent with the rods), the damped structure comes back to
    its layout (up to a rigid motion: compared by shape, the distances between all nodes)."""
    name, s = generated
    rng = np.random.default_rng(2)
    kicked = s.replace(node_velocity=0.2 * rng.normal(size=(s.n_nodes, 3)))
    eq = equilibrium_by_simulation(kicked, t_end=60.0)
    assert eq.converged, (name, eq.message)

    def distances(p):
        return np.linalg.norm(p[:, None] - p[None], axis=2)

    np.testing.assert_allclose(distances(eq.node_position), distances(s.node_position), atol=1e-5)


def test_tower_topology():
    s = tower(3, 4)
    # rings 2n, sides n m, saddles and verticals 4n per interface
    assert (s.n_nodes, s.n_rods, s.n_tendons) == (24, 12, 6 + 12 + 3 * 12)
    strings_per_node = np.bincount(s.tendon_nodes.ravel()).reshape(4, 2, 3)
    assert np.all(strings_per_node[[0, -1]] == 4) and np.all(strings_per_node[1:-1] == 5)
    # stages overlap: each stage's bottom ring lies below the top ring of the stage under it
    z = s.node_position[:, 2].reshape(4, 2, 3).mean(axis=2)  # (stage, bottom/top)
    assert np.all(z[1:, 0] < z[:-1, 1]) and np.all(np.diff(z[:, 0]) > 0)
    with pytest.raises(ValueError, match=r"^overlap: must be in \[0, 1\)"):
        tower(3, 2, overlap=1.0)


# ------------------------------------------------------------------------------ registry
def test_registry_generates_every_kind_and_names_bad_options():
    assert {"shell", "prism", "octahedron", "tower"} <= set(generators.KINDS)
    assert generators.generate("shell", n=4, m=2).n_rods == 16
    assert generators.generate("prism", n=4).n_rods == 4
    assert "tension" in generators.options("octahedron")
    with pytest.raises(ValueError, match=r"^m: not an option of kind 'prism' \(its options: n, "):
        generators.generate("prism", m=2)
    with pytest.raises(ValueError, match=r"^kind: unknown 'cube' \(expected one of shell, prism"):
        generators.generate("cube")
    generators.register("my-simplex", "tensegrity.design.catalogue:prism", "a test registration")
    try:
        assert generators.generate("my-simplex").n_rods == 3
    finally:
        del generators.KINDS["my-simplex"]
