"""Supports in the generators (``fixed_base``): the prism's and tower's bottom ring, the
octahedron stood on a string triangle, the class 1 shell's base ring are fixed to ground; the
prestress is the free structure's, so a prestressed layout stays an equilibrium with no
reactions, and a run under gravity keeps the fixed nodes still."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import class1_shell, simulate
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.cli.main import main
from tensegrity.design.catalogue import octahedron, prism, tower
from tensegrity.io.formats import read_structure
from tensegrity.physics.dynamics import internal_damping

GENERATORS = {
    "prism": (lambda **k: prism(3, **k), 3),
    "prism4": (lambda **k: prism(4, **k), 4),
    "tower": (lambda **k: tower(3, 2, **k), 3),
    "octahedron": (lambda **k: octahedron(**k), 3),
    "shell": (lambda **k: class1_shell(3, 2, **k), 3),
}


@pytest.mark.parametrize("kind", GENERATORS)
def test_the_fixed_nodes_are_the_base(kind):
    make, count = GENERATORS[kind]
    free, s = make(), make(fixed_base=True)
    assert not free.node_fixed.any()
    fixed = np.flatnonzero(s.node_fixed)
    assert fixed.size == count
    z = s.node_position[:, 2]
    assert np.ptp(z[fixed]) < 1e-12  # a horizontal ring (triangle) ...
    others = np.delete(z, fixed)
    assert z[fixed].max() < others.min() - 0.05  # ... below every other node
    # the same members and prestress; the octahedron only turned (its distances kept)
    d = np.linalg.norm(s.node_position[:, None] - s.node_position[None], axis=2)
    d0 = np.linalg.norm(free.node_position[:, None] - free.node_position[None], axis=2)
    np.testing.assert_allclose(d, d0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(s.tendon_rest_length, free.tendon_rest_length, rtol=1e-12)


def test_the_octahedron_stands_on_a_string_triangle():
    s = octahedron(fixed_base=True)
    base = set(np.flatnonzero(s.node_fixed).tolist())
    edges = {frozenset(pair) for pair in s.tendon_nodes.tolist()}
    assert {frozenset(pair) for pair in ([0, 4], [4, 8], [0, 8])} <= edges
    assert base == {0, 4, 8}
    assert np.all(s.node_position[:, 2] >= -1e-15)


@pytest.mark.parametrize("kind", ["prism", "prism4", "tower", "octahedron"])
def test_a_prestressed_generator_on_its_base_is_an_equilibrium_without_reactions(kind):
    """The solver stays at the layout and the supports carry nothing (to rounding; the
    tendons pull 5 N on average)."""
    s = GENERATORS[kind][0](fixed_base=True)
    eq = find_equilibrium(s)
    assert eq.converged, eq.message
    np.testing.assert_allclose(eq.node_position, s.node_position, rtol=0, atol=1e-12)
    assert eq.reaction_force is not None
    assert np.max(np.abs(eq.reaction_force)) < 1e-12 * 5.0 * s.n_tendons


@pytest.mark.parametrize("kind", GENERATORS)
def test_a_run_under_gravity_keeps_the_fixed_nodes_still(kind):
    """The free nodes sag (by centimetres), the fixed ones stay where they are (to 1e-12 m,
    the bound of the class 2 shell's fixed base, ``test_constraints``)."""
    s = internal_damping(GENERATORS[kind][0](fixed_base=True))
    run = simulate(s, (0.0, 0.5), gravity=[0.0, 0.0, -9.81], sample_dt=0.05)
    assert run.status == 0, run.message
    fixed = s.node_fixed
    assert np.max(np.abs(run.node_position[:, fixed] - s.node_position[fixed])) < 1e-12
    assert np.max(np.abs(run.node_velocity[:, fixed])) < 1e-10
    assert np.max(np.abs(run.node_position[-1] - s.node_position)) > 0.01


@pytest.mark.parametrize("kind", ["prism", "tower", "octahedron", "shell"])
def test_export_fixed_base_for_every_kind_with_the_option(tmp_path, kind):
    path = tmp_path / f"{kind}.json"
    assert main(["export", "--kind", kind, "--fixed-base", "-o", str(path)]) == 0
    got = read_structure(path)
    want = {"prism": prism, "tower": tower, "octahedron": octahedron, "shell": class1_shell}[kind]
    assert got.to_dict() == want(fixed_base=True).to_dict()
    assert got.node_fixed.any()
