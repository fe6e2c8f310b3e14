"""Files written before the package was reorganised into layers (commit 75dab28, the code of
2026-11-25 06:00 UTC) still read: a trajectory (HDF5, layout version 1) and structure files
(JSON, YAML, TOML, connectivity ``.npz``), and a trajectory of layout version 2.
``tests/data/legacy/`` holds them, with the arrays the old code had in memory when it wrote the
trajectories."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.io import read_network, read_structure, read_trajectory, write_network
from tensegrity.io.trajectory import read_dataset
from tensegrity.model.shell import class2_shell

LEGACY = Path(__file__).parent / "data" / "legacy"


def test_old_trajectory_reads_with_the_values_it_was_written_with():
    trajectory = read_trajectory(LEGACY / "shell31-v1.h5")
    expected = np.load(LEGACY / "shell31-v1-expected.npz")
    assert trajectory.status == 0 and trajectory.t.size == 11
    for name in ("t", "node_position", "tendon_tension", "q"):
        assert np.array_equal(getattr(trajectory, name), expected[name]), name
    assert set(trajectory.energy) == {
        "kinetic",
        "elastic",
        "gravity",
        "dissipated",
        "external_work",
        "control_work",
    }
    assert trajectory.structure.to_dict() == artificial_damping(class1_shell(3, 1)).to_dict()


def test_a_version_2_trajectory_reads_with_its_stored_tendon_lengths():
    """Version 2 (the code of 2026-11-27 21:00 UTC, commit c0911f2) stored ``tendon_length``;
    version 3 computes it from ``q``."""
    trajectory = read_trajectory(LEGACY / "shell31-v2.h5")
    expected = np.load(LEGACY / "shell31-v2-expected.npz")
    assert trajectory.status == 0 and trajectory.t.size == 11 and trajectory.nswitches == 2
    for name in ("t", "q", "node_position", "tendon_length", "tendon_tension", "switch_times"):
        assert np.array_equal(getattr(trajectory, name), expected[name]), name
    assert np.array_equal(
        read_dataset(LEGACY / "shell31-v2.h5", "tendon_length"), expected["tendon_length"]
    )


@pytest.mark.parametrize("name", ["shell31-v1.h5", "shell31-v2.h5"])
def test_old_trajectories_read_without_a_design(name):
    """Files written before trajectories carried their members' design read as runs without
    one, with their structure."""
    from tensegrity.design.files import trajectory_design

    structure, design = trajectory_design(LEGACY / name)
    assert design is None
    assert structure.to_dict() == read_trajectory(LEGACY / name).structure.to_dict()


def test_old_structure_json_reads():
    assert (
        read_structure(LEGACY / "shell31.json").to_dict()
        == artificial_damping(class1_shell(3, 1)).to_dict()
    )


@pytest.mark.parametrize("name", ["class2.yaml", "class2.toml", "class2.npz"])
def test_old_network_files_read_as_the_same_files_written_now(tmp_path, name):
    """An old file reads to the same structure as that file written by today's code."""
    now = tmp_path / name
    write_network(now, class2_shell(3, 2, fixed_base=True))
    assert read_network(LEGACY / name).to_dict() == read_network(now).to_dict()


@pytest.mark.parametrize(
    "name, structure, t_end, options, tol",
    [
        # the main job; arithmetic changed only in where a switch is located (regula falsi
        # against bisection, both to 1e-13 s): measured 3.7e-14 m
        ("shell31-v1.h5", artificial_damping(class1_shell(3, 1)), 0.2, {}, 1e-12),
        # a class 2 shell under gravity with 7 switches: within the integration tolerance
        # (rtol 1e-9, nodes moving up to 0.94 m): measured 1.2e-10 m
        (
            "class2-gravity-v1.h5",
            class2_shell(3, 2, fixed_base=True),
            0.3,
            {"gravity": [0.0, 0.0, -9.81]},
            1e-8,
        ),
    ],
    ids=["main job", "class 2 shell"],
)
def test_trajectories_are_those_of_the_code_before(name, structure, t_end, options, tol):
    """The same runs as the code before the reorganisation made (its files, 75dab28): the same
    switches, node positions within the stated tolerance."""
    before = read_trajectory(LEGACY / name)
    now = simulate(structure, (0.0, t_end), sample_dt=t_end / 10, **options)
    assert now.status == before.status == 0
    assert now.nswitches == before.nswitches
    assert np.array_equal(now.t, before.t)
    assert np.max(np.abs(now.node_position - before.node_position)) < tol
