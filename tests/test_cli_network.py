"""The command line with any structure: export --kind/--format, simulate/info on every format,
--force-table, and one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity.cli.main import main
from tensegrity.design import catalogue as generators
from tensegrity.io.formats import read_network
from tensegrity.io.trajectory import read_trajectory

FORMATS = {
    "json": ".json",
    "yaml": ".yaml",
    "toml": ".toml",
    "connectivity": ".npz",
    "mjcf": ".xml",
}
KIND_OPTIONS = {
    "shell": ["--n", "4", "--m", "2"],
    "prism": ["--n", "4", "--set", "tension=8"],
    "octahedron": [],
    "tower": ["--n", "3", "--m", "2", "--set", "overlap=0.2"],
}


@pytest.mark.parametrize("kind", list(KIND_OPTIONS))
def test_export_every_kind_in_every_format(kind, tmp_path, capsys):
    """Each file reads back to the structure the generator makes (MJCF: loads in MuJoCo)."""
    options = {
        "prism": {"n": 4, "tension": 8},
        "shell": {"n": 4, "m": 2},
        "tower": {"n": 3, "m": 2, "overlap": 0.2},
    }.get(kind, {})
    expected = generators.generate(kind, **options)
    for fmt, suffix in FORMATS.items():
        path = tmp_path / f"{kind}{suffix}"
        assert main(["export", "--kind", kind, *KIND_OPTIONS[kind], "-o", str(path)]) == 0
        assert f"({fmt}: {expected.n_nodes} nodes" in capsys.readouterr().out
        if fmt == "mjcf":
            mujoco = pytest.importorskip("mujoco")
            model = mujoco.MjModel.from_xml_path(str(path))
            assert model.nbody == expected.n_rods + 1 and model.ntendon == expected.n_tendons
            continue
        assert read_network(path).to_dict() == expected.to_dict()
    # --format overrides the suffix
    path = tmp_path / "model.txt"
    assert (
        main(["export", "--kind", kind, *KIND_OPTIONS[kind], "--format", "yaml", "-o", str(path)])
        == 0
    )
    assert read_network(path, format="yaml").to_dict() == expected.to_dict()


def test_existing_export_options_still_work(tmp_path):
    path = tmp_path / "s.json"
    assert (
        main(
            [
                "export",
                "--n",
                "4",
                "--m",
                "2",
                "--primal",
                "--stiffness",
                "50",
                "--rest-length",
                "0.2",
                "--damping",
                "artificial",
                "-o",
                str(path),
            ]
        )
        == 0
    )
    s = read_network(path)
    assert (s.n_rods, s.n_tendons) == (16, 64) and np.all(s.tendon_stiffness == 50)
    assert np.all(s.tendon_rest_length == 0.2) and np.all(s.rod_damping > 0)


@pytest.mark.parametrize("suffix", [".yaml", ".toml", ".npz", ".json"])
def test_simulate_and_info_take_every_format(suffix, tmp_path, capsys):
    path = tmp_path / f"p{suffix}"
    assert main(["export", "--kind", "prism", "-o", str(path)]) == 0
    assert main(["info", "--structure", str(path)]) == 0
    assert "initially slack tendons  0" in capsys.readouterr().out
    out = tmp_path / "run"
    assert (
        main(
            [
                "simulate",
                "--structure",
                str(path),
                "--t-end",
                "0.1",
                "--no-steady-state",
                "--sample-dt",
                "0.05",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    trajectory = read_trajectory(out / "trajectory.h5")
    assert trajectory.node_position.shape == (3, 6, 3)
    # at its equilibrium, the prism does not move
    assert np.abs(trajectory.node_position[-1] - trajectory.node_position[0]).max() < 1e-9


def test_simulate_with_a_force_table(tmp_path):
    """A csv table pushing every node of the octahedron along x: the centre of mass accelerates
    at F_total / M for the table's (constant) force."""
    force = np.zeros((2, 12, 3))
    force[:, :, 0] = 0.5  # 6 N in total on 6 kg
    rows = np.column_stack([[0.0, 1.0], force.reshape(2, -1)])
    np.savetxt(tmp_path / "f.csv", rows, delimiter=",", header="t, f0x, f0y, f0z, ...")
    out = tmp_path / "run"
    assert (
        main(
            [
                "simulate",
                "--kind",
                "octahedron",
                "--damping",
                "none",
                "--t-end",
                "0.4",
                "--no-steady-state",
                "--sample-dt",
                "0.1",
                "--force-table",
                str(tmp_path / "f.csv"),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    trajectory = read_trajectory(out / "trajectory.h5")
    centre = trajectory.node_position.mean(axis=1)  # equal node masses
    np.testing.assert_allclose(centre[:, 0] - centre[0, 0], 0.5 * 1.0 * trajectory.t**2, atol=1e-9)
    np.testing.assert_allclose(
        trajectory.energy["external_work"][-1], 6 * 0.5 * 1.0 * 0.4**2, rtol=1e-6
    )


@pytest.mark.parametrize(
    "argv, words",
    [
        (
            ["export", "--kind", "prism", "--m", "2", "-o", "x.json"],
            "--m: not an option of --kind prism",
        ),
        (
            ["export", "--kind", "prism", "--set", "colour=red", "-o", "x.json"],
            "--set colour: not an option",
        ),
        (
            ["export", "--kind", "prism", "--set", "n=two", "-o", "x.json"],
            "n: must be an integer >= 3",
        ),
        (["export", "--kind", "cube", "-o", "x.json"], "--kind: invalid choice: 'cube'"),
        (["export", "--kind", "prism", "--set", "oops", "-o", "x.json"], "expected NAME=VALUE"),
        (
            ["export", "--kind", "prism", "--format", "vtk", "-o", "x.json"],
            "--format: invalid choice",
        ),
        (["export", "--damping", "artificial", "-o", "x.xml"], "rods[0].damping"),
        (["export", "--damping", "internal", "-o", "x.xml"], "rods[0].relative_damping"),
        (["info", "--structure", "x.yaml", "--kind", "prism"], "--kind: generator options cannot"),
        (["info", "--structure", "missing.toml"], "missing.toml: no such file"),
        (["info", "--structure", "s.txt"], "unknown structure file suffix '.txt'"),
        (["simulate", "--kind", "prism", "--force-table", "f.npz"], "f.npz: no such file"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(
    argv, words, tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.txt").write_text("")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tensegrity: error:"), err
    assert words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.txt"]


def test_force_table_for_another_structure_is_refused(tmp_path, capsys):
    np.savez(tmp_path / "f.npz", time=[0.0], force=np.zeros((1, 5, 3)))
    assert (
        main(
            [
                "simulate",
                "--kind",
                "prism",
                "--force-table",
                str(tmp_path / "f.npz"),
                "--out",
                str(tmp_path / "out"),
            ]
        )
        == 2
    )
    assert "has forces for 5 nodes, the structure has 6" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("fmt", ["yaml", "toml", "connectivity"])
def test_class_k_forms_carry_a_class2_shell_to_simulate(fmt, tmp_path, capsys):
    """The readable and connectivity forms write the fixed-base class 2 shell with shared nodes
    (class k) and a fixed base; the file reads back to the same N, C_b, C_s and supports, and
    simulate takes it (the base stays put, the joints hold)."""
    from tensegrity.model.connectivity import merge_joints, to_connectivity

    path = tmp_path / f"s{FORMATS[fmt]}"
    assert main(["export", "--kind", "class2-shell", "--fixed-base", "-o", str(path)]) == 0
    expected = generators.generate("class2-shell", fixed_base=True)
    got = read_network(path)
    for a, b in zip(to_connectivity(got), to_connectivity(expected), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(merge_joints(got).node_fixed, merge_joints(expected).node_fixed)
    out = tmp_path / "run"
    capsys.readouterr()
    assert (
        main(
            [
                "simulate",
                "--structure",
                str(path),
                "--t-end",
                "0.1",
                "--no-steady-state",
                "--sample-dt",
                "0.05",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    nodes = read_trajectory(out / "trajectory.h5").node_position
    assert nodes.shape == (3, got.n_nodes, 3)
    fixed = np.flatnonzero(got.node_fixed)
    assert fixed.size and np.abs(nodes[:, fixed] - got.node_position[fixed]).max() < 1e-12
    gap = nodes[:, got.joint_nodes[:, 0]] - nodes[:, got.joint_nodes[:, 1]]
    assert np.abs(gap).max() < 1e-9 and np.abs(nodes[-1] - nodes[0]).max() > 1e-3


def test_export_keep_joints_writes_the_structure_s_own_layout(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    assert (
        main(["export", "--kind", "class2-shell", "--fixed-base", "--keep-joints", "-o", str(path)])
        == 0
    )
    assert (
        read_network(path).to_dict()
        == generators.generate("class2-shell", fixed_base=True).to_dict()
    )
    assert "joints:" in path.read_text()
