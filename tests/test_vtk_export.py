"""VTK/ParaView export: read the files back with a small XML reader and compare with the run."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from tensegrity import artificial_damping, simulate
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism
from tensegrity.io import vtk as vtk_export
from tensegrity.io.trajectory import read_trajectory, write_trajectory
from tensegrity.io.vtk import polydata, write_vtk


def read_pvd(path):
    """[(time, file name)] of a ParaView collection."""
    root = ET.parse(path).getroot()
    assert root.get("type") == "Collection"
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def read_vtp(path):
    """Points (N, 3), lines (L, 2), cell arrays and point arrays of an ASCII PolyData file."""
    piece = ET.parse(path).getroot().find("PolyData/Piece")

    def array(element, name=None):
        for d in element.iter("DataArray"):
            if name is None or d.get("Name") == name:
                values = np.array(d.text.split(), dtype=float)
                components = int(d.get("NumberOfComponents", "1"))
                return values.reshape(-1, components) if components > 1 else values
        raise KeyError(name)

    points = array(piece.find("Points"))
    connectivity = array(piece.find("Lines"), "connectivity").astype(int)
    offsets = array(piece.find("Lines"), "offsets").astype(int)
    assert np.all(np.diff(np.concatenate([[0], offsets])) == 2)  # two-point lines
    assert int(piece.get("NumberOfPoints")) == points.shape[0]
    assert int(piece.get("NumberOfLines")) == offsets.size
    cells = {
        d.get("Name"): array(piece.find("CellData"), d.get("Name"))
        for d in piece.find("CellData").iter("DataArray")
    }
    point_data = piece.find("PointData")
    velocity = None if point_data is None else array(point_data, "velocity")
    return points, connectivity.reshape(-1, 2), cells, velocity


@pytest.fixture(scope="module")
def run():
    """A kicked simplex, some tendons going slack (a hard kick), damped: 0.5 s."""
    s = prism(3)
    rng = np.random.default_rng(5)
    s = artificial_damping(s.replace(node_velocity=2.0 * rng.normal(size=(s.n_nodes, 3))))
    result = simulate(s, (0.0, 0.5), sample_dt=0.05)
    assert result.success and result.slack_count.max() > 0
    return result


def test_files_hold_the_trajectory(run, tmp_path):
    written = write_vtk(tmp_path / "out", run, name="simplex")
    s = run.structure
    assert written[-1] == tmp_path / "out" / "simplex.pvd"
    entries = read_pvd(written[-1])
    assert [t for t, _ in entries] == run.t.tolist()
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(p.name for p in written)
    for k, (_, name) in enumerate(entries):
        points, lines, cells, velocity = read_vtp(tmp_path / "out" / name)
        np.testing.assert_array_equal(points, run.node_position[k])
        np.testing.assert_array_equal(velocity, run.node_velocity[k])
        np.testing.assert_array_equal(lines, np.vstack([s.rod_nodes, s.tendon_nodes]))
        np.testing.assert_array_equal(cells["is_tendon"], [0] * s.n_rods + [1] * s.n_tendons)
        np.testing.assert_array_equal(cells["tension"][s.n_rods :], run.tendon_tension[k])
        np.testing.assert_array_equal(cells["tension"][: s.n_rods], 0.0)
        np.testing.assert_array_equal(cells["slack"][s.n_rods :], run.tendon_tension[k] <= 0)
    # tendon lengths from the file's points = the run's
    p = points[lines[s.n_rods :]]
    np.testing.assert_allclose(
        np.linalg.norm(p[:, 1] - p[:, 0], axis=1),
        np.linalg.norm(
            run.node_position[-1][s.tendon_nodes[:, 1]]
            - run.node_position[-1][s.tendon_nodes[:, 0]],
            axis=1,
        ),
        rtol=1e-15,
    )


def test_every_keeps_the_last_sample_and_bad_options(run, tmp_path):
    written = write_vtk(tmp_path, run, every=4)
    times = [t for t, _ in read_pvd(written[-1])]
    assert times == run.t[[0, 4, 8, 10]].tolist()
    for options, message in (
        ({"every": 0}, "^every: must be an integer >= 1"),
        ({"name": "a/b"}, "^name: must be a plain file name stem"),
    ):
        with pytest.raises(ValueError, match=message):
            write_vtk(tmp_path / "x", run, **options)
    assert not (tmp_path / "x").exists()


def test_a_failed_write_leaves_nothing(run, tmp_path, monkeypatch):
    """Inconsistent arrays are refused up front; an error half way (the third file) writes no file
    at all, and the folder created for them is gone."""
    broken = type(
        "Broken",
        (),
        {
            "structure": run.structure,
            "t": run.t,
            "node_position": run.node_position,
            "node_velocity": None,
            "tendon_tension": run.tendon_tension[:, :-1],
        },
    )()
    with pytest.raises(
        ValueError, match=r"^tendon_tension: expected shape \(11, 9\) for 11 samples"
    ):
        write_vtk(tmp_path / "out", broken)
    calls = []

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise OSError("disk full")
        return polydata(*args, **kwargs)

    monkeypatch.setattr(vtk_export, "polydata", failing)
    with pytest.raises(OSError, match="disk full"):
        write_vtk(tmp_path / "out", run)
    assert not (tmp_path / "out").exists()
    (tmp_path / "old").mkdir()
    (tmp_path / "old" / "keep.txt").write_text("x")
    with pytest.raises(OSError):
        calls.clear()
        write_vtk(tmp_path / "old", run)
    assert sorted(p.name for p in (tmp_path / "old").iterdir()) == ["keep.txt"]


def test_cli_vtk_verb_and_simulate_vtk(run, tmp_path, capsys):
    write_trajectory(tmp_path / "run.h5", run)
    assert main(["vtk", str(tmp_path / "run.h5"), "-o", str(tmp_path / "v"), "--every", "5"]) == 0
    assert "wrote 3 VTK files" in capsys.readouterr().out
    trajectory = read_trajectory(tmp_path / "run.h5")
    entries = read_pvd(tmp_path / "v" / "tensegrity.pvd")
    points, _, cells, _ = read_vtp(tmp_path / "v" / entries[1][1])
    np.testing.assert_array_equal(points, trajectory.node_position[5])
    np.testing.assert_array_equal(cells["tension"][3:], trajectory.tendon_tension[5])

    out = tmp_path / "sim"
    assert (
        main(
            [
                "simulate",
                "--kind",
                "prism",
                "--t-end",
                "0.2",
                "--no-steady-state",
                "--sample-dt",
                "0.1",
                "--vtk",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert [t for t, _ in read_pvd(out / "vtk" / "tensegrity.pvd")] == pytest.approx([0, 0.1, 0.2])
    printed = capsys.readouterr().out
    assert f"{out / 'vtk' / 'tensegrity.pvd'}" in printed and ".vtp" not in printed
    # again into the same folder: the files are replaced
    assert (
        main(
            [
                "simulate",
                "--kind",
                "prism",
                "--t-end",
                "0.1",
                "--no-steady-state",
                "--sample-dt",
                "0.1",
                "--vtk",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert [t for t, _ in read_pvd(out / "vtk" / "tensegrity.pvd")] == pytest.approx([0, 0.1])
    assert not [p for p in out.rglob("*") if p.name.startswith(".staging")]
    assert main(["vtk", str(tmp_path / "missing.h5"), "-o", str(tmp_path / "w")]) == 2
    assert "missing.h5: no such file" in capsys.readouterr().err
    assert not (tmp_path / "w").exists()


def test_write_staged_keeps_subfolders_and_cleans_up(tmp_path):
    from tensegrity.io.files import write_staged

    def write(staging):
        (staging / "sub").mkdir()
        files = [staging / "sub" / "a.txt", staging / "b.txt"]
        for f in files:
            f.write_text(f.name)
        return files

    out = tmp_path / "new" / "out"
    assert write_staged(out, write) == [out / "sub" / "a.txt", out / "b.txt"]
    assert (out / "sub" / "a.txt").read_text() == "a.txt"
    assert sorted(p.name for p in out.iterdir()) == ["b.txt", "sub"]

    def failing(staging):
        write(staging)
        raise RuntimeError("late failure")

    with pytest.raises(RuntimeError):
        write_staged(tmp_path / "other" / "out", failing)
    assert not (tmp_path / "other").exists()  # every folder it created is gone
