"""One vocabulary for a run's data: a trajectory file holds a :class:`SimulationResult` under
the result's own names, whatever wrote it (:func:`write_trajectory`, the streamed writer, the
``simulate`` command), with the switch times and one ``settings`` record, and reads back as the
run that was in memory, field by field."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import h5py
import numpy as np
import pytest

from tensegrity import SimulationResult, artificial_damping, class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.io.stream import simulate_to_file
from tensegrity.io.trajectory import (
    DERIVED,
    SAMPLE_DATASETS,
    read_dataset,
    read_trajectory,
    write_trajectory,
)
from tensegrity.model.planar import planar_two_rod
from tensegrity.model.shell import class2_shell
from test_kernel_system import point_mass_between_anchors

#: A damped (3,1) shell: tendons go slack and taut (located switches) from the start.
SHELL = class1_shell(3, 1, damping=0.5)
OPTIONS = dict(sample_dt=0.01, rtol=1e-6, atol=1e-9)
SPAN = (0.0, 0.5)


def assert_same_run(got: SimulationResult, want: SimulationResult, *, skip=()) -> None:
    """Every field of ``got`` equals the one of ``want`` (arrays bit for bit, with their dtype
    and shape), but those named in ``skip``."""
    for field in dataclasses.fields(SimulationResult):
        name = field.name
        a, b = getattr(got, name), getattr(want, name)
        if name in skip:
            continue
        if name == "structure":
            assert a.to_dict() == b.to_dict(), name
        elif name == "energy":
            assert list(a) == list(b), name
            for key in b:
                assert np.array_equal(a[key], b[key]), f"energy {key}"
        elif isinstance(b, np.ndarray):
            assert a.dtype == b.dtype and a.shape == b.shape, name
            assert np.array_equal(a, b), name
        else:
            assert a == b, name


def test_the_file_datasets_are_the_names_of_the_result(tmp_path):
    """The sampled datasets of a file are fields of the result under the same names; the node
    arrays are not stored (they are ``P q`` and ``P q'``) and read back all the same."""
    result = simulate(SHELL, SPAN, **OPTIONS)
    path = write_trajectory(tmp_path / "run.h5", result)
    names = {field.name for field in dataclasses.fields(SimulationResult)}
    with h5py.File(path, "r") as f:
        stored = {name for name in f if isinstance(f[name], h5py.Dataset)}
        assert list(f.attrs["tendon_name"]) == list(result.tendon_name)
    assert stored == {*SAMPLE_DATASETS, "switch_times"} and stored <= names
    assert set(DERIVED) <= names and not set(DERIVED) & stored
    rows = [*range(0, result.t.size, 3), result.t.size - 1]  # (every 3rd, and the last)
    for name in (*SAMPLE_DATASETS, *DERIVED):
        expected = getattr(result, name)
        if name == "energy":
            expected = np.column_stack(list(result.energy.values()))
        assert np.array_equal(read_dataset(path, name, every=3), expected[rows]), name


def test_a_streamed_file_and_a_written_file_read_back_as_the_run_in_memory(tmp_path):
    """The same run (one segment: one run of the engine) kept in memory, written by
    ``write_trajectory`` and streamed to a file: the two files read back as the result in
    memory, every field (the switch times included), but the wall time, which each run measures;
    the settings are the one record of the run, the streamed file adding its segments."""
    memory = simulate(SHELL, SPAN, **OPTIONS)
    assert memory.nswitches > 0 and memory.switch_times.size == memory.nswitches
    written = read_trajectory(write_trajectory(tmp_path / "written.h5", memory))
    summary = simulate_to_file(SHELL, SPAN, tmp_path / "streamed.h5", segment=1.0, **OPTIONS)
    streamed = read_trajectory(summary.path)
    assert_same_run(written, memory)
    assert_same_run(streamed, memory, skip=("wall_time", "settings"))
    assert streamed.wall_time == summary.wall_time
    segments = {"segment": 1.0, "samples_per_segment": 100, "n_segments": 1}
    assert streamed.settings == {**memory.settings, "stream": segments}


def test_the_cli_file_and_the_same_run_written_read_back_alike(tmp_path, capsys):
    """A file of ``tensegrity simulate`` (streamed in segments) and its run written again by
    ``write_trajectory`` read back into equal results, switch times included."""
    out = tmp_path / "out"
    argv = ["simulate", "--t-end", "0.5", "--sample-dt", "0.01", "--no-steady-state"]
    assert main([*argv, "--no-view", "--no-animation", "--out", str(out)]) == 0
    capsys.readouterr()
    cli = read_trajectory(out / "trajectory.h5")
    assert cli.nswitches > 0 and cli.switch_times.size == cli.nswitches
    assert np.all(np.diff(cli.switch_times) >= 0) and cli.t[0] <= cli.switch_times[0]
    again = read_trajectory(write_trajectory(tmp_path / "again.h5", cli))
    assert_same_run(again, cli)
    # the same run through the library, streamed on the command's segment grid
    segment = cli.settings["stream"]["segment"]
    options = {key: cli.settings[key] for key in ("rtol", "atol", "sample_dt", "steady_state")}
    library = simulate_to_file(
        cli.structure, (0.0, 0.5), tmp_path / "library.h5", segment=segment, **options
    )
    assert_same_run(read_trajectory(library.path), cli, skip=("wall_time",))


@pytest.mark.parametrize(
    "structure, options",
    [
        (artificial_damping(class2_shell(3, 2, fixed_base=True)), {"gravity": [0, 0, -9.81]}),
        (planar_two_rod(angle=1.1, rest_length=[0.3, 0.35, 0.4, 0.45]), {}),
        (point_mass_between_anchors(), {}),
    ],
    ids=["class 2 shell on supports", "planar", "point mass between anchors"],
)
def test_node_arrays_computed_on_read_are_those_recorded(tmp_path, structure, options):
    """Joints, supports, a planar structure, point masses and anchors: the node positions and
    velocities computed from ``q`` and ``qdot`` on read are bit for bit those the engine
    recorded."""
    result = simulate(structure, (0.0, 0.1), sample_dt=0.01, **options)
    back = read_trajectory(write_trajectory(tmp_path / "run.h5", result))
    assert_same_run(back, result)


def test_a_file_of_version_1_reads_by_the_new_names():
    """An old file (datasets ``time``, ``nodes``, ``velocities``) gives its arrays under the
    result's names, alone as in the whole result; it stored no switch times."""
    old = Path(__file__).parent / "data" / "legacy" / "shell31-v1.h5"
    with h5py.File(old, "r") as f:
        assert f.attrs["version"] == 1 and {"time", "nodes", "velocities"} <= set(f)
    whole = read_trajectory(old)
    assert whole.switch_times.size == 0 < whole.nswitches
    for name in ("t", "node_position", "node_velocity", "q"):
        assert np.array_equal(read_dataset(old, name, every=4), getattr(whole, name)[[0, 4, 8, 10]])
