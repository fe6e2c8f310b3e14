"""``tensegrity simulate --control-table``: the tendons' rest-length changes ``u(t)`` from a
``.csv`` or ``.npz`` table, the same input as the library's ``simulate(control=...)``, and
one-line errors naming the option, the file and the column or row at fault (issue 29)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from tensegrity.design.catalogue import three_bar_robot
from tensegrity.io.tables import read_control_table, write_control_table

ROBOT = three_bar_robot(actuated="side_*")
CSV = "# two side cables pulled in and let out\nt,side_0,side_1\n0,0,0\n0.2,0.1,0.05\n0.5,0,0.08\n"


def test_a_csv_table_names_tendons_and_the_others_keep_u_zero(tmp_path):
    path = tmp_path / "u.csv"
    path.write_text(CSV)
    table = read_control_table(path, ROBOT)
    k0, k1 = ROBOT.tendon_name.index("side_0"), ROBOT.tendon_name.index("side_1")
    assert table.control.shape == (3, ROBOT.n_tendons)
    assert np.array_equal(table.control[:, [k0, k1]], [[0, 0], [0.1, 0.05], [0, 0.08]])
    assert not np.delete(table.control, [k0, k1], axis=1).any()
    assert np.allclose(table(0.1)[[k0, k1]], [0.05, 0.025]) and table(9.0)[k1] == 0.08  # (held)
    np.savez(tmp_path / "named.npz", time=[0, 0.2, 0.5], names=["side_0", "side_1"],
             control=[[0, 0], [0.1, 0.05], [0, 0.08]])  # fmt: skip
    np.savez(tmp_path / "full.npz", time=table.time, control=table.control)
    for name in ("named.npz", "full.npz"):
        again = read_control_table(tmp_path / name, ROBOT)
        assert np.array_equal(again.control, table.control) and np.array_equal(
            again.time, table.time
        )


def test_a_written_table_reads_back_exactly_with_only_its_moving_columns(tmp_path):
    path = tmp_path / "u.csv"
    path.write_text(CSV)
    table = read_control_table(path, ROBOT)
    table = type(table)(table.time, table.control / 3.0)  # (numbers with many digits)
    write_control_table(tmp_path / "out.csv", table, ROBOT)
    assert (tmp_path / "out.csv").read_text().splitlines()[0] == "t,side_0,side_1"
    again = read_control_table(tmp_path / "out.csv", ROBOT)
    assert np.array_equal(again.time, table.time)
    assert np.array_equal(again.control, table.control)
    with pytest.raises(ValueError, match=r"^table: has 2 columns"):
        write_control_table(tmp_path / "bad.csv", type(table)([0.0, 1.0], np.zeros((2, 2))), ROBOT)
    assert not (tmp_path / "bad.csv").exists()


def test_the_command_s_table_is_the_library_s_control(tmp_path):
    """The command's run with ``--control-table`` is the library's streamed run with
    ``control=read_control_table(...)`` (the same segments), bit for bit, and ``simulate()``'s
    in one go to round-off (the segment ends are extra step ends); the table moves the robot
    (centimetres against the run without it)."""
    from tensegrity import simulate
    from tensegrity.cli.main import main
    from tensegrity.io.stream import simulate_to_file
    from tensegrity.io.trajectory import read_trajectory
    from tensegrity.physics.dynamics import internal_damping

    path = tmp_path / "u.csv"
    path.write_text(CSV)
    argv = ["simulate", "--kind", "three-bar", "--set", "actuated=side_*", "--control-table"]
    argv += [str(path), "--t-end", "1", "--no-steady-state", "--no-view", "--no-animation"]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 0
    command = read_trajectory(tmp_path / "out" / "trajectory.h5")
    robot = internal_damping(ROBOT)  # (a generated structure's damping in the command)
    control = read_control_table(path, robot)
    simulate_to_file(robot, (0.0, 1.0), tmp_path / "lib.h5", control=control, sample_dt=0.01,
                     segment=0.1)  # fmt: skip
    library = read_trajectory(tmp_path / "lib.h5")
    assert np.array_equal(command.t, library.t)
    assert np.array_equal(command.node_position, library.node_position)
    whole = simulate(robot, (0.0, 1.0), control=control, sample_dt=0.01)
    assert np.abs(whole.node_position - command.node_position).max() < 1e-9
    still = simulate(robot, (0.0, 1.0), sample_dt=0.01)
    assert np.abs(still.node_position - command.node_position).max() > 1e-2


@pytest.mark.parametrize(
    ("name", "content", "words"),
    [
        ("u.csv", "t,sid_0\n0,0\n", r"column 2 'sid_0': no tendon named so \(close: 'side_0'"),
        ("u.csv", "t,wheel\n0,0\n", r"column 2 'wheel': no tendon named so \(the structure's"),
        ("u.csv", "t,side_0,side_0\n0,0,0\n", r"column 3 'side_0': named twice"),
        ("u.csv", "time,side_0\n0,0\n", r"column 1 of the header: expected 't'"),
        (
            "u.csv",
            "t,side_0\n0,0\n1,x\n",
            r"line 3, column 'side_0': expected a finite number, got 'x",
        ),
        ("u.csv", "t,side_0\n0,0\n1,nan\n", r"line 3, column 'side_0': expected a finite number"),
        ("u.csv", "t,side_0\n0,0\n1\n", r"line 3: expected 2 values \(t and 1 tendons"),
        ("u.csv", "t,side_0\n0,0\n0,1\n", r"time: must increase strictly"),
        ("u.csv", "t,side_0\n", r"no rows of numbers after the header"),
        ("u.txt", "t,side_0\n0,0\n", r"unknown control table suffix '.txt'"),
        ("u.npz", {"time": [0], "control": [[0.1]]}, r"array 'control': expected shape \(T, 9\)"),
        (
            "u.npz",
            {"time": [0], "names": ["sid_1"], "control": [[0.1]]},
            r"names\[0\] 'sid_1': no tendon named so \(close: 'side_1'",
        ),
        ("u.npz", {"time": [0], "u": [[0.1]]}, r"unknown array 'u'"),
        ("u.npz", {"control": [[0.1] * 9]}, r"missing array 'time'"),
    ],
)
def test_a_bad_table_is_one_line_naming_the_option_the_file_and_the_column(
    tmp_path, capsys, name, content, words
):
    from tensegrity.cli.main import main

    path = tmp_path / name
    if isinstance(content, str):
        path.write_text(content)
    else:
        with open(path, "wb") as handle:
            np.savez(handle, **content)
    argv = ["simulate", "--kind", "three-bar", "--control-table", str(path)]
    code = main([*argv, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert err.startswith(f"tensegrity: error: --control-table: {path}: "), err
    assert re.search(words, err), err
    assert not (tmp_path / "out").exists()
