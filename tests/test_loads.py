"""Tabulated nodal forces: interpolation, validation, files, and the impulse they deliver."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.design.catalogue import prism
from tensegrity.io.tables import read_force_table
from tensegrity.model.loads import ForceTable


def table(n_nodes=6):
    rng = np.random.default_rng(0)
    return ForceTable([0.0, 0.1, 0.3], rng.normal(size=(3, n_nodes, 3)))


def test_linear_between_rows_held_or_zero_outside():
    f = table()
    F = f.force
    np.testing.assert_array_equal(f(0.0), F[0])
    np.testing.assert_array_equal(f(0.1), F[1])
    np.testing.assert_array_equal(f(0.3), F[2])
    np.testing.assert_allclose(f(0.05), 0.5 * (F[0] + F[1]), rtol=1e-15)
    np.testing.assert_allclose(f(0.25), 0.25 * F[1] + 0.75 * F[2], rtol=1e-14)
    np.testing.assert_array_equal(f(-1.0), F[0])
    np.testing.assert_array_equal(f(7.0), F[2])
    zero = ForceTable(f.time, F, outside="zero")
    assert not zero(-1e-9).any() and not zero(0.3 + 1e-9).any()
    np.testing.assert_array_equal(zero(0.3), F[2])
    constant = ForceTable([1.0], F[:1])
    np.testing.assert_array_equal(constant(0.0), F[0])
    np.testing.assert_array_equal(constant(5.0), F[0])
    assert f.n_nodes == 6 and not f.force.flags.writeable


@pytest.mark.parametrize(
    ("time", "force", "message"),
    [
        (
            [0.0, 0.2, 0.2],
            np.zeros((3, 2, 3)),
            r"^time: must increase strictly, but time\[2\] = 0\.2 <= time\[1\] = 0\.2",
        ),
        (
            [0.0, 0.1],
            np.zeros((3, 2, 3)),
            r"^force: expected shape \(T, N, 3\) with T = 2 rows like time, got \(3, 2, 3\)",
        ),
        ([0.0, 0.1], np.zeros((2, 2)), r"^force: expected shape \(T, N, 3\)"),
        ([], np.zeros((0, 2, 3)), r"^time: expected a non-empty 1-D array"),
        ([0.0, np.nan], np.zeros((2, 2, 3)), r"^time\[1\]: must be finite"),
        ([0.0, 1.0], np.full((2, 2, 3), np.inf), r"^force\[0, 0, 0\]: must be finite"),
    ],
)
def test_bad_tables_name_the_field(time, force, message):
    with pytest.raises(ValueError, match=message):
        ForceTable(time, force)
    with pytest.raises(ValueError, match=r"^outside: expected 'hold' or 'zero'"):
        ForceTable([0.0], np.zeros((1, 2, 3)), outside="wrap")


def test_files_npz_and_csv(tmp_path):
    f = table()
    np.savez(tmp_path / "f.npz", time=f.time, force=f.force)
    rows = np.column_stack([f.time, f.force.reshape(3, -1)])
    np.savetxt(tmp_path / "f.csv", rows, delimiter=",", header="t, f0x, f0y, f0z, ...")
    for name in ("f.npz", "f.csv"):
        again = read_force_table(tmp_path / name)
        np.testing.assert_array_equal(again.time, f.time)
        np.testing.assert_array_equal(again.force, f.force)
    names = ",".join(["t"] + [f"f{k}{x}" for k in range(f.force.shape[1]) for x in "xyz"])
    (tmp_path / "named.csv").write_text(  # (as a spreadsheet saves it: a byte-order mark first)
        "\ufeff" + names + "\n" + "\n".join(",".join(map(str, row.tolist())) for row in rows) + "\n"
    )
    again = read_force_table(tmp_path / "named.csv")  # (a first row of column names, skipped)
    np.testing.assert_array_equal(again.force, f.force)
    (tmp_path / "bad.csv").write_text("0, 1, 2\n")
    (tmp_path / "blank.csv").write_text(",0,0,0\n1,0,0,0\n")
    (tmp_path / "names.csv").write_text("t,f0x,f0y,f0z\n")
    np.savez(tmp_path / "bad.npz", time=f.time)
    for name, words in (
        ("bad.csv", "expected rows of 1 + 3N numbers"),
        ("blank.csv", "row 0, column 1"),
        ("names.csv", "no rows of numbers"),
        ("bad.npz", "missing array 'force'"),
        ("none.csv", "no such file"),
        ("f.txt", "unknown force table suffix"),
    ):
        with pytest.raises(ValueError) as info:
            read_force_table(tmp_path / name)
        assert str(info.value).startswith(str(tmp_path / name)) and words in str(info.value)


def test_simulation_receives_the_impulse_of_the_table():
    """A free prism pushed by a tabulated force: its momentum changes by the integral of the
    total force (trapezoids of the table's rows, exact for a piecewise-linear force), and the
    run is the same as with the equivalent Python function."""
    s = prism(3)
    rng = np.random.default_rng(3)
    time = np.array([0.0, 0.05, 0.12, 0.2])
    force = rng.normal(scale=2.0, size=(4, s.n_nodes, 3))
    f = ForceTable(time, force, outside="zero")
    result = simulate(s, (0.0, 0.3), external_force=f, rtol=1e-11, atol=1e-13, sample_dt=0.01)
    assert result.success, result.message
    momentum = np.einsum("n,tnk->tk", s.node_mass, result.node_velocity)
    impulse = np.trapezoid(force.sum(axis=1), time, axis=0)
    np.testing.assert_allclose(momentum[-1] - momentum[0], impulse, rtol=0, atol=1e-8)
    assert np.abs(impulse).max() > 0.1
    # mid-table: the integral up to t = 0.1 (inside the second interval)
    k = np.flatnonzero(np.isclose(result.t, 0.1))[0]
    grid = np.linspace(0, 0.1, 2001)
    partial = np.trapezoid(np.array([f(t).sum(axis=0) for t in grid]), grid, axis=0)
    np.testing.assert_allclose(momentum[k] - momentum[0], partial, rtol=0, atol=1e-6)
    # the energy balance counts the work of the table's forces
    assert np.ptp(result.total_energy) < 1e-8
    same = simulate(
        s, (0.0, 0.3), external_force=lambda t: f(t), rtol=1e-11, atol=1e-13, sample_dt=0.01
    )
    np.testing.assert_array_equal(same.node_position, result.node_position)
