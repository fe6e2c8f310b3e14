"""Files written before the package was reorganised into layers (commit 75dab28, the code of
2026-11-25 06:00 UTC) still read: a trajectory (HDF5, layout version 1) and structure files
(JSON, YAML, TOML, connectivity ``.npz``).  ``tests/data/legacy/`` holds them, with the arrays
the old code had in memory when it wrote the trajectory."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tensegrity import class1_shell, critical_damping
from tensegrity.io import read_network, read_structure, read_trajectory, write_network
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
    assert trajectory.structure.to_dict() == critical_damping(class1_shell(3, 1)).to_dict()


def test_old_structure_json_reads():
    assert (
        read_structure(LEGACY / "shell31.json").to_dict()
        == critical_damping(class1_shell(3, 1)).to_dict()
    )


@pytest.mark.parametrize("name", ["class2.yaml", "class2.toml", "class2.npz"])
def test_old_network_files_read_as_the_same_files_written_now(tmp_path, name):
    """An old file reads to the same structure as that file written by today's code."""
    now = tmp_path / name
    write_network(now, class2_shell(3, 2, fixed_base=True))
    assert read_network(LEGACY / name).to_dict() == read_network(now).to_dict()
