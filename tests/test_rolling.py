"""The rolling example (issue 29): :func:`tensegrity.design.rolling.six_bar_roll` plans the
cable shortenings that tip a six-bar robot from face to face; simulated on the ground, the robot
rolls over the faces the plan predicts, along its heading, with the energy balance closed."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.design.catalogue import six_bar_robot
from tensegrity.design.rolling import six_bar_roll, support_faces
from tensegrity.io.formats import read_scene, read_structure
from tensegrity.io.tables import read_control_table

pytest.importorskip("numba")

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.fixture(scope="module")
def robot():
    return six_bar_robot(stiffness=2000.0, tension=100.0, damping=20.0)


@pytest.fixture(scope="module")
def plan(robot):
    return six_bar_roll(robot, steps=3)


def test_the_planned_control_rolls_the_six_bar_over_the_predicted_faces_along_its_heading(plan):
    # rtol 1e-12: at the default 1e-9 the control table's corners leave up to 1e-5 J in the
    # balance (8e-6 J measured over this run), the same faces
    run = simulate(
        plan.structure,
        (0.0, plan.t_end),
        control=plan.control,
        rtol=1e-12,
        sample_dt=0.01,
        **plan.scene.simulate_options(),
    )
    assert run.status == 0, run.message
    faces = support_faces(run)
    assert len(faces) >= 4  # the support face changes at least 3 times
    assert [nodes for _, nodes in faces] == list(plan.faces)
    # the centre of mass advances along the heading at every landing (the path zig-zags: a
    # cable triangle's edges are 120 degrees apart)
    com = run.node_position.mean(axis=1)  # equal rods: the nodes' mean
    landed = np.array([com[np.searchsorted(run.t, t), :2] for t, _ in faces])
    advance = np.diff((landed - landed[0]) @ plan.heading)
    assert advance.min() > 0.05, advance
    assert (landed[-1] - landed[0]) @ plan.heading > 0.8
    # no contact adds energy: the balance never grows
    energy = run.total_energy
    assert np.max(energy - np.minimum.accumulate(energy)) <= 1e-6
    # no centre sinks deeper than the contact law allows: all the kinetic energy in one
    # contact's spring, k d^2 / 2, plus the whole weight's static sag M g / k (measured: 1.3 mm
    # at a landing, of this bound's 8.1 mm and the radius's 10 mm)
    plane = plan.scene.planes[0]
    weight = plan.structure.rod_mass.sum() * 9.81
    allowed = np.sqrt(2.0 * run.energy["kinetic"].max() / plane.stiffness)
    allowed += weight / plane.stiffness
    assert allowed < plan.scene.contact_radius
    assert run.node_position[:, :, 2].min() >= plan.scene.contact_radius - allowed
    assert run.contact_penetration.max() <= allowed


def test_the_example_files_hold_the_plan(plan):
    structure = read_structure(EXAMPLES / "six_bar_roll.json")
    np.testing.assert_array_equal(structure.node_position, plan.structure.node_position)
    assert read_scene(EXAMPLES / "six_bar_roll.json") == plan.scene
    table = read_control_table(EXAMPLES / "six_bar_roll.csv", structure)
    np.testing.assert_array_equal(table.time, plan.control.time)
    np.testing.assert_array_equal(table.control, plan.control.control)


def test_the_example_script_writes_its_figure_and_tables_and_rolls_as_planned(tmp_path):
    """``examples/rolling_six_bar.py`` on one step (its default is three): it writes what its
    docstring says, and the faces of its run are the planned ones."""
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / "rolling_six_bar.py"), "--steps", "1", "--tables"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    written = {"rolling_six_bar.png", "six_bar_roll.json", "six_bar_roll.csv"}
    assert {path.name for path in tmp_path.iterdir()} == written
    planned = done.stdout.splitlines()[0].removeprefix("planned faces: ").split(" -> ")
    ran = done.stdout.splitlines()[1].removeprefix("faces in the run: ").split(" -> ")
    assert len(planned) == 3  # (the face it stands on, and a step tips it twice)
    assert [face.split(" at ")[0] for face in ran] == planned


def test_each_step_puts_the_centre_of_mass_past_its_edge_with_the_cables_taut(robot, plan):
    from tensegrity.analysis.equilibrium import find_equilibrium

    least = 0.5 * find_equilibrium(robot).tension.min()
    pairs = list(zip(plan.faces, plan.faces[1:], strict=False))
    starts = [  # each step starts on the face that it tips over its edge from
        next(a for a, b in pairs if set(edge) <= set(a) & set(b)) for edge in plan.edges
    ]
    for face, edge, u in zip(starts, plan.edges, plan.shortening, strict=True):
        eq = find_equilibrium(robot, control=u)
        p = eq.node_position
        centre = p.mean(axis=0)
        a, b, c = p[list(face)]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        foot = centre - np.dot(centre - a, n) * n
        P, Q = p[edge[0]], p[edge[1]]
        R = p[next(k for k in face if k not in edge)]
        e = (Q - P) / np.linalg.norm(Q - P)
        inward = (R - P) - np.dot(R - P, e) * e
        assert np.dot(foot - P, inward / np.linalg.norm(inward)) < -0.015
        assert eq.tension.min() >= least


@pytest.mark.parametrize(
    ("options", "name"),
    [
        ({"face": (0, 1, 2)}, "face"),
        ({"face": "f---"}, "face"),
        ({"edge": (0, 1)}, "edge"),
        ({"steps": 0}, "steps"),
        ({"hold": 0.0}, "hold"),
    ],
)
def test_bad_arguments_are_named(robot, options, name):
    with pytest.raises(ValueError, match=f"^{name}:"):
        six_bar_roll(robot, **options)
