"""The robot generators: the six-bar (expanded octahedron, named faces, payload) and the three-bar.

The evidence does not reuse the generators' code: equilibrium is checked node by node from the
tendon law ``T = k (l - Lbar)`` (every rod's end forces equal, opposite and along the rod, a point
mass's net force zero) and by the NumPy reference dynamics at rest; stability by modal analysis;
the faces by the cables' nodes (three cables closing a triangle in the octant the face names).
"""

from __future__ import annotations

import fnmatch
import math

import numpy as np
import pytest

from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import modal_analysis
from tensegrity.cli.main import main
from tensegrity.design import catalogue
from tensegrity.design.catalogue import (
    PASSIVE,
    SIX_BAR_FACES,
    actuated_cables,
    face_cables,
    six_bar_robot,
    three_bar_robot,
)
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

ROBOTS = {
    "six-bar": lambda: six_bar_robot(),
    "six-bar, payload": lambda: six_bar_robot(payload_mass=0.5),
    "six-bar, stiff heavy payload": lambda: six_bar_robot(
        rod_length=2.0, payload_mass=3.0, payload_stiffness=800.0, payload_tension=12.0
    ),
    "three-bar": lambda: three_bar_robot(),
    "three-bar, tall": lambda: three_bar_robot(height=0.9, tension=9.0, stiffness=400.0),
}


@pytest.fixture(scope="module", params=list(ROBOTS))
def robot(request):
    return request.param, ROBOTS[request.param]()


def tendon_forces_at_nodes(s: Structure) -> np.ndarray:
    """Net tendon force on each node (N, 3) [N], from ``T = k (l - Lbar)`` (all taut here)."""
    p = s.node_position
    tail, head = s.tendon_nodes.T
    vector = p[head] - p[tail]
    length = np.linalg.norm(vector, axis=1)
    tension = s.tendon_stiffness * (length - s.tendon_rest_length)
    pull = tension[:, None] * vector / length[:, None]  # on the tail, towards the head
    force = np.zeros_like(p)
    np.add.at(force, tail, pull)
    np.add.at(force, head, -pull)
    return force


def test_a_robot_is_a_taut_stable_equilibrium(robot):
    """Rods in pure compression between balanced ends, point masses balanced (1e-12 N), the
    reference dynamics at rest (accelerations < 1e-11), every cable taut, and stable: modal
    analysis finds 6 rigid-body modes and the lowest other frequency > 0."""
    name, s = robot
    p = s.node_position
    tail, head = s.tendon_nodes.T
    length = np.linalg.norm(p[head] - p[tail], axis=1)
    assert np.all(length > s.tendon_rest_length), name  # taut
    force = tendon_forces_at_nodes(s)
    a, b = s.rod_nodes.T
    axis = (p[b] - p[a]) / np.linalg.norm(p[b] - p[a], axis=1)[:, None]
    np.testing.assert_allclose(force[a] + force[b], 0, atol=1e-12)  # the rod carries it
    np.testing.assert_allclose(np.cross(force[a], axis), 0, atol=1e-12)  # along the rod
    assert np.all(np.sum(force[a] * axis, axis=1) > 0.1), (
        name
    )  # cables pull a towards b: compression
    np.testing.assert_allclose(force[s.point_mass_nodes], 0, atol=1e-12)
    state = dynamics.initial_state(s)
    assert np.abs(dynamics.accelerations(s, state.q, state.qdot)).max() < 1e-11, name
    modes = modal_analysis(linearize(s))
    assert modes.stable, (name, modes.verdict)
    assert modes.n_rigid == 6 and modes.n_mechanisms == 0 and modes.n_unstable == 0
    assert np.sort(modes.frequency_hz)[6] > 0.5, name


def test_names_are_unique_and_the_actuated_cables_are_some_of_them(robot):
    name, s = robot
    assert len(set(s.tendon_name)) == s.n_tendons
    actuated = actuated_cables(s)
    assert set(actuated) <= set(s.tendon_name) and actuated, name
    assert all(n.endswith(PASSIVE) for n in set(s.tendon_name) - set(actuated))


# -------------------------------------------------------------------------- the six-bar
def test_six_bar_faces_are_the_eight_cable_triangles_named_by_their_octant():
    """Every face's three cables close a triangle of three nodes on an ``x``, a ``y`` and a ``z``
    bar, centred in the octant of its name; the 8 faces hold each of the 24 cables once, every
    cable ``sqrt(6)/4 L`` long."""
    s = six_bar_robot(rod_length=2.0)
    assert (s.n_nodes, s.n_rods, s.n_tendons) == (12, 6, 24)
    lengths = np.linalg.norm(np.diff(s.node_position[s.tendon_nodes], axis=1)[:, 0], axis=1)
    np.testing.assert_allclose(lengths, math.sqrt(6) / 4 * 2.0, rtol=1e-14)
    bar_axis = {}
    for a, b in s.rod_nodes:
        direction = np.abs(s.node_position[b] - s.node_position[a])
        bar_axis[a] = bar_axis[b] = int(np.argmax(direction))
    seen: list[str] = []
    assert len(SIX_BAR_FACES) == 8 == len(set(SIX_BAR_FACES))
    for face in SIX_BAR_FACES:
        cables = face_cables(s, face)
        seen.extend(cables)
        nodes = s.tendon_nodes[[s.tendon_index(c) for c in cables]].ravel()
        assert sorted(np.bincount(nodes)[np.unique(nodes)]) == [2, 2, 2]  # a closed triangle
        corners = np.unique(nodes)
        assert sorted(bar_axis[k] for k in corners) == [0, 1, 2]
        centre = s.node_position[corners].mean(axis=0)
        assert "f" + "".join("+" if c > 0 else "-" for c in centre) == face
        for cable in cables:  # the suffix names the two bars' axes
            ends = s.tendon_nodes[s.tendon_index(cable)]
            assert {"xyz"[bar_axis[k]] for k in ends} == set(cable.split("_")[1])
    assert sorted(seen) == sorted(s.tendon_name)


def test_six_bar_payload_sits_at_the_centre_held_by_equal_cables():
    """Node 12 at the centroid, 12 payload cables of one length and tension, the 24 shell cables
    of one length and tension (the bars closer to the centre than L/4), payload cables passive by
    default; tensions from the tendon law."""
    s = six_bar_robot(payload_mass=0.7, payload_tension=8.0, tension=5.0)
    assert s.n_nodes == 13 and s.node_point_mass[12] == 0.7 and s.total_mass == pytest.approx(6.7)
    p = s.node_position
    np.testing.assert_allclose(p[12], 0, atol=1e-15)
    np.testing.assert_allclose(p[:12].mean(axis=0), 0, atol=1e-15)
    tension = dynamics.tendon_tensions(s, p)
    length = dynamics.tendon_lengths(s, p)
    payload = np.array([n.startswith("payload_") for n in s.tendon_name])
    assert payload.sum() == 12 and set(s.tendon_nodes[payload].ravel()) == set(range(13))
    np.testing.assert_allclose(tension[payload], 8.0, rtol=1e-12)
    np.testing.assert_allclose(tension[~payload], 5.0, rtol=1e-12)
    assert np.ptp(length[payload]) < 1e-14 and np.ptp(length[~payload]) < 1e-14
    rod_centres = p[s.rod_nodes].mean(axis=1)
    assert np.all(np.linalg.norm(rod_centres, axis=1) < 0.25)
    assert len(actuated_cables(s)) == 24 and all(
        n.endswith(PASSIVE) for n in np.array(s.tendon_name)[payload]
    )


def test_the_actuated_keyword_chooses_the_cables_by_name_or_pattern():
    s = six_bar_robot(actuated="f+++_*,f---_xy")
    assert set(actuated_cables(s)) == {"f+++_xy", "f+++_yz", "f+++_zx", "f---_xy"}
    assert face_cables(s, "f---") == ("f---_xy", "f---_yz" + PASSIVE, "f---_zx" + PASSIVE)
    s = six_bar_robot(payload_mass=1.0, actuated=("payload_*",))
    assert actuated_cables(s) == tuple(f"payload_{k}" for k in range(12))
    s = three_bar_robot(actuated="side_*")
    assert actuated_cables(s) == ("side_0", "side_1", "side_2")
    assert three_bar_robot().tendon_name == tuple(
        f"{ring}_{i}" for ring in ("bottom", "top", "side") for i in range(3)
    )


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: six_bar_robot(payload_mass=-1.0), r"^payload_mass: must be > 0, got -1.0$"),
        (lambda: six_bar_robot(payload_mass=0), r"^payload_mass: must be > 0"),
        (lambda: six_bar_robot(payload_tension=3.0), r"^payload_tension: only with payload_mass"),
        (
            lambda: six_bar_robot(payload_mass=1, payload_stiffness=-5),
            r"^payload_stiffness: must be > 0",
        ),
        (lambda: six_bar_robot(actuated="f+++_*,g*"), r"^actuated: no cable matches 'g\*'"),
        (lambda: three_bar_robot(actuated="a,,b"), r"^actuated: expected cable names"),
        (lambda: three_bar_robot(actuated=3), r"^actuated: expected cable names"),
        (lambda: face_cables(six_bar_robot(), "f+"), r"^face: expected one of f---"),
        (lambda: face_cables(three_bar_robot(), "f+++"), r"^face: .* has no cables of face"),
        (lambda: three_bar_robot(rod_mass=-2), r"^rod_mass: must be > 0"),
    ],
)
def test_bad_input_is_one_line_naming_the_keyword(call, message):
    with pytest.raises(ValueError, match=message) as error:
        call()
    assert "\n" not in str(error.value)


# -------------------------------------------------------------------------- the three-bar
def test_three_bar_has_equal_bars_and_rings():
    s = three_bar_robot(height=0.6)
    p = s.node_position
    lengths = dynamics.tendon_lengths(s, p)
    tension = dynamics.tendon_tensions(s, p)
    a, b = s.rod_nodes.T
    np.testing.assert_allclose(np.linalg.norm(p[b] - p[a], axis=1), 1.0, rtol=1e-12)
    for family in ("bottom_*", "top_*", "side_*"):
        chosen = [fnmatch.fnmatchcase(n, family) for n in s.tendon_name]
        assert sum(chosen) == 3 and np.ptp(lengths[chosen]) < 1e-14
        assert np.ptp(tension[chosen]) < 1e-12 and tension[chosen].min() > 0
    bottom = [s.tendon_index(f"bottom_{i}") for i in range(3)]
    top = [s.tendon_index(f"top_{i}") for i in range(3)]
    np.testing.assert_allclose(lengths[bottom], lengths[top], rtol=1e-14)
    assert set(s.tendon_nodes[bottom].ravel()) == {0, 1, 2}
    assert set(s.tendon_nodes[top].ravel()) == {3, 4, 5}
    np.testing.assert_allclose(p[:3, 2], 0, atol=1e-15)
    np.testing.assert_allclose(p[3:, 2], 0.6, rtol=1e-14)


# ------------------------------------------------------------------------ registry and CLI
def test_the_robots_are_registered_kinds():
    assert catalogue.generate("six-bar", payload_mass=0.2).n_nodes == 13
    assert catalogue.generate("three-bar").n_rods == 3
    assert {"actuated", "payload_mass"} <= set(catalogue.options("six-bar"))


@pytest.mark.parametrize(
    "options",
    [
        ["--kind", "six-bar"],
        ["--kind", "six-bar", "--set", "payload_mass=0.5", "--set", "actuated=f+++_*"],
        ["--kind", "three-bar", "--set", "actuated=side_*"],
    ],
)
def test_the_command_line_simulates_the_robots(options, tmp_path, capsys):
    argv = ["simulate", *options, "--t-end", "0.01", "--sample-dt", "0.01"]
    argv += ["--no-steady-state", "--no-view", "--no-animation", "--out", str(tmp_path)]
    assert main(argv) == 0, capsys.readouterr().err
    assert (tmp_path / "trajectory.h5").is_file()


def test_the_command_line_names_a_bad_robot_option_in_one_line(tmp_path, capsys):
    argv = ["simulate", "--kind", "six-bar", "--set", "payload_mass=-1", "--t-end", "0.01"]
    assert main([*argv, "--no-view", "--no-animation", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "payload_mass: must be > 0" in err and len(err.splitlines()) == 1
