"""Files: structure JSON and HDF5 trajectories round-trip exactly, writes are atomic, and bad
files give one-line ValueErrors that start with the file name."""

from __future__ import annotations

import dataclasses
import json
import os

import h5py
import numpy as np
import pytest

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.engine.result import SimulationResult
from tensegrity.io.files import atomic_path
from tensegrity.io.formats import read_structure, write_structure
from tensegrity.io.trajectory import (
    ENERGY_COLUMNS,
    read_dataset,
    read_trajectory,
    write_trajectory,
)


@pytest.fixture(scope="module")
def result():
    """A short damped (3,1) shell run (a few samples, a few slack switches)."""
    return simulate(artificial_damping(class1_shell(3, 1)), (0.0, 0.2), sample_dt=0.05)


def leftovers(directory):
    return sorted(p.name for p in directory.iterdir() if p.name.endswith(".tmp"))


def assert_one_line_naming(exc_info, path, *words):
    message = str(exc_info.value)
    assert message.startswith(str(path)), message
    assert "\n" not in message
    for word in words:
        assert word in message, message


# ----------------------------------------------------------------------------- structures
def test_structure_json_round_trip_is_exact(tmp_path):
    structure = artificial_damping(class1_shell(4, 2, rod_mass=1.3, stiffness=123.456))
    path = tmp_path / "s.json"
    assert write_structure(path, structure) == path
    text = path.read_text()
    assert text == json.dumps(structure.to_dict(), indent=2) + "\n"
    again = read_structure(path)
    assert again.to_dict() == structure.to_dict()
    for field in (
        "node_position",
        "node_velocity",
        "rod_nodes",
        "rod_mass",
        "rod_length",
        "rod_damping",
        "tendon_nodes",
        "tendon_stiffness",
        "tendon_rest_length",
        "tendon_damping",
    ):
        assert np.array_equal(getattr(again, field), getattr(structure, field)), field
    assert again.tendon_name == structure.tendon_name
    assert leftovers(tmp_path) == []
    # accepts str paths too
    assert read_structure(str(path)).to_dict() == structure.to_dict()


@pytest.mark.parametrize(
    "content, words",
    [
        (None, ["no such file"]),
        (b'{"nodes": [[0, 0, 0],\n  [1, 0 0]]}', ["invalid JSON", "line 2", "column"]),
        (b"", ["invalid JSON", "line 1"]),
        (b"\xff\xfe garbage", ["not UTF-8"]),
        (b"[1, 2, 3]", ["expected a JSON object"]),
        (b'{"nodes": [[0, 0, 0], [1, 0, 0]], "rods": []}', ["missing key 'tendons'"]),
    ],
)
def test_bad_structure_file_is_a_one_line_value_error_naming_it(tmp_path, content, words):
    path = tmp_path / "bad.json"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(ValueError) as exc_info:
        read_structure(path)
    assert_one_line_naming(exc_info, path, *words)


def test_invalid_structure_names_file_and_element(tmp_path):
    data = class1_shell(3, 1).to_dict()
    data["tendons"][2]["stiffness"] = -5
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError) as exc_info:
        read_structure(path)
    assert_one_line_naming(exc_info, path, "tendons[2]", "stiffness", "must be > 0")


def test_malformed_value_is_still_a_value_error(tmp_path):
    data = class1_shell(3, 1).to_dict()
    data["tendons"][0]["nodes"] = [0, 10**30]  # OverflowError deep inside NumPy
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ValueError) as exc_info:
        read_structure(path)
    assert_one_line_naming(exc_info, path)


def test_directory_instead_of_structure_file(tmp_path):
    with pytest.raises(ValueError) as exc_info:
        read_structure(tmp_path)
    assert_one_line_naming(exc_info, tmp_path, "directory")


# -------------------------------------------------------------------------- atomic writes
def test_atomic_path_replaces_on_success_and_keeps_permissions(tmp_path):
    path = tmp_path / "f.txt"
    old_umask = os.umask(0o022)
    try:
        with atomic_path(path) as tmp:
            assert tmp.parent == tmp_path and tmp.exists() and tmp != path
            assert not path.exists()
            tmp.write_text("new")
    finally:
        os.umask(old_umask)
    assert path.read_text() == "new"
    assert os.stat(path).st_mode & 0o777 == 0o644  # not mkstemp's 0o600
    os.chmod(path, 0o640)
    with atomic_path(path) as tmp:
        tmp.write_text("newer")
    assert path.read_text() == "newer" and os.stat(path).st_mode & 0o777 == 0o640
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("existing", [False, True])
def test_atomic_path_failure_leaves_nothing_or_the_old_file(tmp_path, existing):
    path = tmp_path / "f.txt"
    if existing:
        path.write_text("old")
    with pytest.raises(RuntimeError, match="boom"), atomic_path(path) as tmp:
        tmp.write_text("partial")
        raise RuntimeError("boom")
    assert leftovers(tmp_path) == []
    assert path.read_text() == "old" if existing else not path.exists()


def test_atomic_path_cleans_up_on_keyboard_interrupt(tmp_path):
    with pytest.raises(KeyboardInterrupt), atomic_path(tmp_path / "f.txt") as tmp:
        tmp.write_text("partial")
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_write_structure_failure_keeps_old_file(tmp_path, monkeypatch):
    path = tmp_path / "s.json"
    path.write_text("old")

    def failing_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", failing_replace)
    with pytest.raises(OSError, match="disk full"):
        write_structure(path, class1_shell(3, 1))
    assert path.read_text() == "old"
    assert leftovers(tmp_path) == []


# --------------------------------------------------------------------------- trajectories
def test_trajectory_round_trip_is_exact(tmp_path, result):
    path = tmp_path / "run.h5"
    assert write_trajectory(path, result) == path
    assert leftovers(tmp_path) == []
    tr = read_trajectory(path)
    assert isinstance(tr, SimulationResult)  # the type of the result in memory
    pairs = {
        "t": result.t,
        "node_position": result.node_position,
        "node_velocity": result.node_velocity,
        "tendon_length": result.tendon_length,
        "tendon_tension": result.tendon_tension,
        "q": result.q,
        "qdot": result.qdot,
        "residual_acceleration": result.residual_acceleration,
    }
    for name, expected in pairs.items():
        got = getattr(tr, name)
        assert got.dtype == np.float64 and np.array_equal(got, expected), name
    assert tuple(tr.energy) == ENERGY_COLUMNS == tuple(result.energy)
    for name in ENERGY_COLUMNS:
        assert np.array_equal(tr.energy[name], result.energy[name]), name
    assert tr.structure.to_dict() == result.structure.to_dict()
    assert tr.settings == result.settings
    for name in (
        "status",
        "message",
        "nfev",
        "nsteps",
        "nswitches",
        "nprojections",
        "max_rod_length_error",
        "wall_time",
    ):
        assert getattr(tr, name) == getattr(result, name), name
    assert tr.success and tr.tendon_name == result.structure.tendon_name


def test_trajectory_file_layout(tmp_path, result):
    path = tmp_path / "run.h5"
    write_trajectory(path, result)
    T, S, R = result.t.size, result.structure.n_tendons, 6
    with h5py.File(path, "r") as f:
        assert f.attrs["format"] == "tensegrity-trajectory" and f.attrs["version"] == 3
        assert json.loads(f.attrs["structure"]) == result.structure.to_dict()
        assert json.loads(f.attrs["settings"]) == result.settings
        assert list(f.attrs["tendon_name"]) == list(result.structure.tendon_name)
        assert list(f["energy"].attrs["columns"]) == list(ENERGY_COLUMNS)
        shapes = {
            "t": (T,),
            "tendon_tension": (T, S),
            "energy": (T, 6),
            "q": (T, 6 * R),
            "qdot": (T, 6 * R),
            "residual_acceleration": (T,),
        }
        for name, shape in shapes.items():
            assert f[name].shape == shape, name
        for name in ("node_position", "node_velocity", "tendon_length"):  # (computed from q, qdot)
            assert name not in f, name
        assert f["switch_times"].shape == (result.nswitches,)
        for name in ("q", "qdot", "tendon_tension"):
            assert f[name].compression == "gzip" and f[name].chunks is not None, name


def test_large_structure_attributes_fit(tmp_path):
    """A (20,20) shell's structure JSON and 3,120 tendon names exceed HDF5's 64 KiB compact
    attribute limit; the file must still be written and read."""
    structure = class1_shell(20, 20)
    run = simulate(structure, (0.0, 1e-3), method="rk4", dt=1e-3, sample_dt=1e-3)
    path = tmp_path / "big.h5"
    write_trajectory(path, run)
    tr = read_trajectory(path)
    assert tr.structure.to_dict() == structure.to_dict() and tr.node_position.shape == (2, 1600, 3)


def _fail_on(monkeypatch, dataset):
    real = h5py.Group.create_dataset

    def create_dataset(self, name, *args, **kwargs):
        if name == dataset:
            raise OSError(f"simulated failure writing {name!r}")
        return real(self, name, *args, **kwargs)

    monkeypatch.setattr(h5py.Group, "create_dataset", create_dataset)


def test_failed_trajectory_write_leaves_no_file(tmp_path, result, monkeypatch):
    _fail_on(monkeypatch, "tendon_tension")
    path = tmp_path / "run.h5"
    with pytest.raises(OSError, match="simulated failure"):
        write_trajectory(path, result)
    assert list(tmp_path.iterdir()) == []


def test_failed_trajectory_write_keeps_the_older_file(tmp_path, result, monkeypatch):
    path = tmp_path / "run.h5"
    older = simulate(class1_shell(3, 1), (0.0, 0.1), sample_dt=0.05)
    write_trajectory(path, older)
    before = path.read_bytes()
    _fail_on(monkeypatch, "q")
    with pytest.raises(OSError, match="simulated failure"):
        write_trajectory(path, result)
    assert path.read_bytes() == before
    assert leftovers(tmp_path) == []
    monkeypatch.undo()
    assert np.array_equal(read_trajectory(path).node_position, older.node_position)


def test_bad_trajectory_files_name_the_file(tmp_path, result):
    missing = tmp_path / "missing.h5"
    with pytest.raises(ValueError) as exc_info:
        read_trajectory(missing)
    assert_one_line_naming(exc_info, missing, "no such file")

    text = tmp_path / "text.h5"
    text.write_text("not hdf5")
    with pytest.raises(ValueError) as exc_info:
        read_trajectory(text)
    assert_one_line_naming(exc_info, text, "not an HDF5 file")

    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["time"] = np.arange(3.0)
    with pytest.raises(ValueError) as exc_info:
        read_trajectory(other)
    assert_one_line_naming(exc_info, other, "not a tensegrity trajectory")


def _edited_copy(tmp_path, result, edit):
    path = tmp_path / "edited.h5"
    write_trajectory(path, result)
    with h5py.File(path, "a") as f:
        edit(f)
    return path


@pytest.mark.parametrize(
    "edit, words",
    [
        (lambda f: f.__delitem__("qdot"), ["missing dataset 'qdot'"]),
        (lambda f: f.__delitem__("switch_times"), ["missing dataset 'switch_times'"]),
        (lambda f: f.attrs.__setitem__("version", 4), ["version 4", "newer"]),
        (lambda f: f.attrs.__delitem__("settings"), ["missing attribute 'settings'"]),
        (lambda f: f.attrs.__setitem__("structure", "{oops"), ["'structure'", "invalid JSON"]),
        (
            lambda f: (f.__delitem__("q"), f.create_dataset("q", data=np.zeros((2, 3)))),
            ["'q'", "shape"],
        ),
    ],
)
def test_incomplete_trajectory_names_the_file_and_problem(tmp_path, result, edit, words):
    path = _edited_copy(tmp_path, result, edit)
    with pytest.raises(ValueError) as exc_info:
        read_trajectory(path)
    assert_one_line_naming(exc_info, path, *words)


def test_trajectory_keeps_the_joint_error_and_marks_older_files_unknown(tmp_path, result):
    """``max_constraint_error`` (joints, supports) is stored; a file written before it was stored
    reads NaN for a structure with constraints and 0 for one without."""
    from tensegrity.model.shell import class2_shell

    jointed = simulate(class2_shell(3, 2), (0.0, 0.05), sample_dt=0.025)
    assert 0.0 < jointed.max_constraint_error < 1e-9
    for run, older in ((jointed, np.nan), (result, 0.0)):
        path = tmp_path / "run.h5"
        write_trajectory(path, run)
        assert read_trajectory(path).max_constraint_error == run.max_constraint_error
        with h5py.File(path, "a") as f:
            del f.attrs["max_constraint_error"]
        np.testing.assert_equal(read_trajectory(path).max_constraint_error, older)


def test_trajectory_read_back_is_the_result_written(tmp_path):
    """One type in memory and on disk: every array field of the result read back equals the one
    written (same names, shapes and values); ``every`` reads every k-th sample and the last."""
    result = simulate(artificial_damping(class1_shell(3, 1)), (0.0, 0.3), sample_dt=0.01)
    path = write_trajectory(tmp_path / "run.h5", result)
    back = read_trajectory(path)
    for name in (
        "t",
        "q",
        "qdot",
        "node_position",
        "node_velocity",
        "tendon_length",
        "tendon_tension",
        "residual_acceleration",
    ):
        assert np.array_equal(getattr(back, name), getattr(result, name)), name
    assert back.energy.keys() == result.energy.keys()
    for name in result.energy:
        assert np.array_equal(back.energy[name], result.energy[name]), name
    some = read_trajectory(path, every=7)
    rows = [*range(0, result.t.size, 7), result.t.size - 1]
    assert np.array_equal(some.t, result.t[rows])
    assert np.array_equal(some.node_position, result.node_position[rows])
    assert np.array_equal(some.energy["elastic"], result.energy["elastic"][rows])
    with pytest.raises(ValueError, match="every"):
        read_trajectory(path, every=0)
    # one dataset alone, the same rows
    assert np.array_equal(read_dataset(path, "tendon_length", every=7), result.tendon_length[rows])
    assert np.array_equal(read_dataset(path, "t"), result.t)
    assert np.array_equal(read_dataset(path, "node_position", every=7), result.node_position[rows])
    with pytest.raises(ValueError, match=r"^name: expected one of t, q, qdot"):
        read_dataset(path, "tension")
    with pytest.raises(ValueError, match="no such file"):
        read_dataset(tmp_path / "missing.h5", "t")


def _without_samples(result):
    """``result`` cut to no samples (what a trajectory never holds: a run has its first state)."""
    rows = dict(
        t=result.t[:0],
        node_position=result.node_position[:0],
        node_velocity=result.node_velocity[:0],
        tendon_length=result.tendon_length[:0],
        tendon_tension=result.tendon_tension[:0],
        q=result.q[:0],
        qdot=result.qdot[:0],
        residual_acceleration=result.residual_acceleration[:0],
    )
    return dataclasses.replace(
        result, energy={name: e[:0] for name, e in result.energy.items()}, **rows
    )


def test_a_trajectory_without_samples_is_refused_by_the_reader_and_the_cli(
    tmp_path, result, capsys
):
    path = tmp_path / "empty.h5"
    write_trajectory(path, _without_samples(result))
    with pytest.raises(ValueError) as exc_info:
        read_trajectory(path)
    assert_one_line_naming(exc_info, path, "holds no samples")
    out = tmp_path / "vtk"
    assert main(["vtk", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{path}: holds no samples" in err, err
    assert "internal error" not in err and not out.exists()


@pytest.mark.parametrize("value", ["some string", None, {"t": [0.0]}])
def test_write_trajectory_of_something_else_is_a_type_error_naming_the_argument(tmp_path, value):
    path = tmp_path / "run.h5"
    with pytest.raises(TypeError, match=r"^result: expected a SimulationResult"):
        write_trajectory(path, value)
    assert not path.exists() and leftovers(tmp_path) == []


def flip_bytes_in_first_row(path, name):
    """Change 8 bytes of the first row of dataset ``name`` in the file (XOR 0x5A: Fletcher-32
    cannot tell a 16-bit word 0x0000 from 0xFFFF, so not an XOR with 0xFF)."""
    with h5py.File(path, "r") as f:
        offset = f[name].id.get_chunk_info(0).byte_offset
    with open(path, "r+b") as handle:
        handle.seek(offset + 8)
        data = bytearray(handle.read(8))
        handle.seek(offset + 8)
        handle.write(bytes(b ^ 0x5A for b in data))


def test_a_corrupted_trajectory_is_an_error_not_wrong_numbers(tmp_path, result, capsys):
    path = tmp_path / "run.h5"
    write_trajectory(path, result)
    with h5py.File(path, "r") as f:
        assert all(f[name].fletcher32 for name in ("t", "q", "qdot", "energy"))
    flip_bytes_in_first_row(path, "q")
    with pytest.raises(ValueError) as exc_info:
        read_trajectory(path)
    assert_one_line_naming(exc_info, path, "dataset 'q': corrupted", "damaged")
    assert main(["vtk", str(path), "-o", str(tmp_path / "vtk")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{path}: dataset 'q': corrupted" in err, err
