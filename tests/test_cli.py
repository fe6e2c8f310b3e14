"""The command line: the main job on its default example, info, export, and its errors."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import numpy as np
import pytest

from tensegrity.cli.main import main
from tensegrity.io.formats import read_structure
from tensegrity.io.trajectory import read_trajectory

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
cli_main = importlib.import_module("tensegrity.cli.simulate_summary")


@pytest.fixture(scope="module")
def default_run(tmp_path_factory):
    """``tensegrity simulate`` with no options but the output folder: the paper's example."""
    out = tmp_path_factory.mktemp("results")
    code = main(["simulate", "--out", str(out)])
    return code, out


def test_default_example_writes_every_promised_file(default_run):
    code, out = default_run
    assert code == 0
    for name in (
        "trajectory.h5",
        "structure.json",
        "initial.png",
        "equilibrium.png",
        "tendon_lengths.png",
    ):
        path = out / name
        assert path.is_file() and path.stat().st_size > 0, name
        if name.endswith(".png"):
            assert path.read_bytes()[:8] == PNG_SIGNATURE
    assert not list(out.glob("*.tmp")), "temporary files left behind"


def test_default_example_reaches_a_taut_steady_state(default_run):
    _, out = default_run
    trajectory = read_trajectory(out / "trajectory.h5")
    structure = read_structure(out / "structure.json")
    # The paper's (3,1) shell: 12 nodes, 6 rods, 24 tendons, all alike, critically damped.
    assert (structure.n_nodes, structure.n_rods, structure.n_tendons) == (12, 6, 24)
    assert np.ptp(structure.tendon_stiffness) == 0 and np.ptp(structure.tendon_rest_length) == 0
    assert np.all(structure.tendon_damping > 0)
    assert trajectory.status == 1, trajectory.message
    assert trajectory.residual_acceleration[-1] < 1e-6
    assert np.abs(trajectory.node_velocity[-1]).max() < 1e-6
    assert np.all(trajectory.tendon_tension[-1] > 0), "a tendon is slack at equilibrium"
    # It moved: the equilibrium is not the initial layout.
    assert np.abs(trajectory.node_position[-1] - trajectory.node_position[0]).max() > 0.05
    # Rod lengths held, energy accounted for.
    p = trajectory.node_position
    rods = structure.rod_nodes
    lengths = np.linalg.norm(p[:, rods[:, 1]] - p[:, rods[:, 0]], axis=-1)
    assert np.abs(lengths - 1.0).max() < 1e-9
    e = trajectory.energy
    total = e["kinetic"] + e["elastic"] + e["dissipated"]
    assert np.abs(total - total[0]).max() < 1e-6 * total[0]


def test_default_example_settles_into_the_expanded_octahedron(default_run):
    """Closed form: the (3,1) shell has the connectivity of the expanded octahedron (6 rods,
    4 tendons at every node), whose equilibrium with equal tendons has every tendon
    ``sqrt(6)/4`` times the rod length long (e.g. Tibert & Pellegrino 2003)."""
    _, out = default_run
    trajectory = read_trajectory(out / "trajectory.h5")
    structure = read_structure(out / "structure.json")
    assert np.all(np.bincount(structure.tendon_nodes.ravel()) == 4)
    lengths = trajectory.tendon_length[-1]
    assert np.abs(lengths / structure.rod_length[0] - np.sqrt(6) / 4).max() < 1e-6
    assert (
        np.abs(trajectory.tendon_length[0] / structure.rod_length[0] - np.sqrt(6) / 4).max() > 0.1
    )


def test_default_example_prints_a_summary(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path), "--t-end", "0.5", "--sample-dt", "0.05"]) == 0
    printed = capsys.readouterr().out
    for words in (
        "final residual acceleration",
        "largest rod-length error",
        "energy dissipated",
        "slack tendons",
        "wall time",
    ):
        assert words in printed


@pytest.mark.parametrize(
    "t_end, sample_dt, shown",
    [
        ("0.01", "0.01", "1 segment of up to 1 sample"),
        ("0.5", "0.05", "10 segments of up to 1 sample"),
    ],
)
def test_the_summary_counts_checkpoints_in_the_singular_and_plural(
    t_end, sample_dt, shown, tmp_path, capsys
):
    """Not "1 segments" (issue 27)."""
    argv = ["simulate", "--out", str(tmp_path), "--t-end", t_end, "--sample-dt", sample_dt]
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    assert next(x for x in lines if x.startswith("checkpoints")).split(None, 1)[1] == shown


def test_the_summary_counts_steps_and_switches_in_the_singular_and_plural(tmp_path, capsys):
    """Not "1 steps" (issue 27): one RK4 step of four evaluations, no switch."""
    argv = ["simulate", "--method", "rk4", "--dt", "0.001", "--t-end", "0.001"]
    argv += ["--sample-dt", "0.001", "--no-steady-state", "--no-view", "--no-animation"]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert next(x for x in lines if x.startswith("integration")).split(None, 1)[1] == (
        "rk4: 1 step, 4 evaluations, 0 slack/taut switches located"
    )
    assert cli_main._counted(1, "slack/taut switch", "slack/taut switches") == (
        "1 slack/taut switch"
    )


def test_the_command_s_help_says_what_it_does_in_whole_sentences(capsys):
    """Not the module docstring's first line, cut in the middle of its list of verbs (issue
    27)."""
    with pytest.raises(SystemExit) as exit_:
        main(["--help"])
    assert exit_.value.code == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert (
        "Nonlinear dynamics of tensegrity structures (rigid rods, elastic tendons): simulate, "
        "analyse, design, view and export them. 'tensegrity VERB --help' describes a verb. "
        "positional arguments:" in printed
    )


def test_export_then_simulate_and_info_a_structure_file(tmp_path, capsys):
    path = tmp_path / "s.json"
    assert main(["export", "--n", "4", "--m", "2", "-o", str(path)]) == 0
    data = json.loads(path.read_text())
    assert len(data["nodes"]) == 32 and len(data["rods"]) == 16 and len(data["tendons"]) == 72
    assert main(["info", "--structure", str(path)]) == 0
    printed = capsys.readouterr().out
    assert "tendons" in printed and "72" in printed and "80 (5 per rod)" in printed
    out = tmp_path / "run"
    code = main(
        [
            "simulate",
            "--structure",
            str(path),
            "--t-end",
            "0.2",
            "--no-steady-state",
            "--method",
            "rk4",
            "--dt",
            "1e-3",
            "--sample-dt",
            "0.05",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    trajectory = read_trajectory(out / "trajectory.h5")
    assert trajectory.node_position.shape == (5, 32, 3)
    assert trajectory.t[-1] == pytest.approx(0.2)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["simulate", "--n", "2"], "n"),
        (["simulate", "--m", "0"], "m"),
        (["simulate", "--stiffness", "-1"], "--stiffness"),
        (["simulate", "--damping", "lots"], "--damping"),
        (["simulate", "--method", "rk4"], "--dt"),
        (["simulate", "--method", "euler"], "--method"),
        (["simulate", "--dt", "1e-3"], "--dt"),
        (["simulate", "--t-end", "nan"], "--t-end"),
        (["simulate", "--structure", "missing.json"], "missing.json"),
        (["simulate", "--structure", "x.json", "--n", "4"], "--n"),
        (["info", "--rest-length", "-0.5"], "--rest-length"),
        (["export", "--n", "3"], "--output"),
        (["bogus"], "bogus"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(
    argv, words, tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tensegrity: error:"), err
    assert words in err
    assert "Traceback" not in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize(
    "argv, words",
    [
        (["simulate", "--out", "afile"], "--out: afile exists and is not a folder"),
        (["simulate", "--out", "afile/sub"], "--out: afile exists and is not a folder"),
        (["matrices", "--at", "equilibrium", "--out", "afile"], "--out: afile exists"),
        (["export", "-o", "afile/s.json"], "--output: afile exists and is not a folder"),
        (["export", "-o", "afile/sub/s.json"], "--output: afile exists and is not a folder"),
        (["export", "-o", "."], "--output: . is a folder"),
    ],
)
def test_unusable_output_path_fails_before_any_work(argv, words, tmp_path, capsys, monkeypatch):
    """An output path that cannot be written is refused up front (no simulation is run), in one
    line naming the option, and the file in the way is left as it was."""
    import importlib

    module = importlib.import_module(
        "tensegrity.engine.simulate"
    )  # the package exports the function

    def no_simulation(*args, **kwargs):
        raise AssertionError("simulated although the output path is unusable")

    monkeypatch.setattr(module, "simulate", no_simulation)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("keep me")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("tensegrity: error:"), err
    assert words in err and "Errno" not in err and ".tmp" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]
    assert (tmp_path / "afile").read_text() == "keep me"


def test_export_makes_the_folders_of_its_output(tmp_path, capsys, monkeypatch):
    """As every verb (``sweep``, ``animate``, ``view``, the output folders): the missing
    folders of ``-o`` are made (before: refused, ``folder ... does not exist``), and removed
    again if the file cannot be written."""
    import errno

    out = tmp_path / "new" / "deeper" / "s.yaml"
    assert main(["export", "--kind", "prism", "-o", str(out)]) == 0
    assert out.is_file() and f"wrote {out}" in capsys.readouterr().out

    def full_disk(path, *args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr("tensegrity.io.formats.write_network", full_disk)
    other = tmp_path / "other" / "s.yaml"
    # a full disk fails the command (exit 1, as everywhere), it is not bad input
    assert main(["export", "--kind", "prism", "-o", str(other)]) == 1
    assert capsys.readouterr().err == f"tensegrity: error: {other}: No space left on device\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new"]


def test_bad_structure_file_names_the_element(tmp_path, capsys):
    path = tmp_path / "bad.json"
    main(["export", "-o", str(path)])
    data = json.loads(path.read_text())
    data["tendons"][2]["stiffness"] = -5
    path.write_text(json.dumps(data))
    capsys.readouterr()
    assert main(["simulate", "--structure", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "tendons[2]" in err and "stiffness" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_unstable_run_fails_with_exit_1_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(
        ["simulate", "--method", "rk4", "--dt", "0.05", "--damping", "none", "--out", str(out)]
    )
    assert code == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unstable" in err
    assert not out.exists() or not list(out.iterdir())


@pytest.mark.parametrize("module", ["tensegrity.cli", "tensegrity"])
def test_console_script_errors_without_traceback(tmp_path, module):
    completed = subprocess.run(
        [sys.executable, "-m", module, "simulate", "--n", "1"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert completed.returncode == 2
    assert completed.stderr.count("\n") == 1 and "Traceback" not in completed.stderr


def test_matrices_command_writes_the_model_at_the_equilibrium(tmp_path, capsys):
    import scipy.io

    out = tmp_path / "m"
    assert main(["matrices", "--n", "3", "--m", "1", "--at", "equilibrium", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "B " in printed and "36 x 24" in printed and "75 x 36" in printed
    index = json.loads((out / "matrices.json").read_text())
    assert index["at"] == "equilibrium"
    K_p = scipy.io.mmread(out / "K_p.mtx").tocsr()
    q = np.load(out / "state.npz")["q"]
    # (18.61) with u = 0, w = 0: the equilibrium satisfies K_p(q) q = 0.
    assert np.abs(K_p @ q).max() < 1e-6
    assert not list(out.glob("*.tmp")) and not list(out.glob(".staging-*"))


def test_export_kinds_write_the_generators_structures(tmp_path):
    from tensegrity.model.planar import planar_two_rod
    from tensegrity.model.shell import class2_shell

    path = tmp_path / "c2.json"
    assert (
        main(
            [
                "export",
                "--kind",
                "class2-shell",
                "--n",
                "4",
                "--m",
                "3",
                "--fixed-base",
                "-o",
                str(path),
            ]
        )
        == 0
    )
    assert read_structure(path).to_dict() == class2_shell(4, 3, fixed_base=True).to_dict()
    path = tmp_path / "planar.json"
    assert main(["export", "--kind", "planar", "--rest-length", "0.3", "-o", str(path)]) == 0
    assert read_structure(path).to_dict() == planar_two_rod(rest_length=0.3).to_dict()


def test_simulate_a_planar_structure_writes_its_files(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        main(
            [
                "simulate",
                "--kind",
                "planar",
                "--rest-length",
                "0.3",
                "--damping",
                "artificial",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    trajectory = read_trajectory(out / "trajectory.h5")
    assert trajectory.node_position.shape[1:] == (4, 2)
    assert (out / "equilibrium.png").read_bytes()[:8] == PNG_SIGNATURE


@pytest.mark.parametrize(
    "argv, message",
    [
        (
            ["export", "--kind", "rod", "--n", "4", "-o", "x.json"],
            "--n: not an option of --kind rod",
        ),
        (
            ["export", "--kind", "six-bar", "--fixed-base", "-o", "x.json"],
            "--fixed-base: not an option of --kind six-bar",
        ),
        (["info", "--kind", "class2-shell", "--m", "1"], "m: a class 2 shell needs m >= 2"),
        (
            ["simulate", "--kind", "rod", "--damping", "artificial"],
            "artificial damping needs at least one rod and one tendon",
        ),
        (
            ["simulate", "--damping", "critical"],
            "--damping: 'critical' is now 'artificial' (the paper's damping, to ground",
        ),
        (
            ["matrices", "--kind", "class2-shell"],
            "the matrix model: supports only free 3-D class 1",
        ),
    ],
)
def test_generator_option_errors_are_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not list(tmp_path.iterdir())


def test_simulate_class2_shell_reports_the_joint_error(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        main(
            [
                "simulate",
                "--kind",
                "class2-shell",
                "--fixed-base",
                "--t-end",
                "0.05",
                "--no-steady-state",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith("largest joint"))
    assert float(line.split()[-2]) < 1e-12
    trajectory = read_trajectory(out / "trajectory.h5")
    fixed = np.flatnonzero(trajectory.structure.node_fixed)
    assert (
        np.max(np.abs(trajectory.node_position[:, fixed] - trajectory.node_position[0, fixed]))
        < 1e-12
    )


def test_a_reader_that_closes_the_pipe_early_stops_the_command_quietly():
    """``tensegrity info | head -1``: the output pipe closes before the command writes; it
    stops with exit code 141 (128 + SIGPIPE) and nothing on stderr (no traceback, no error)."""
    child = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from tensegrity.cli.main import main; sys.exit(main(['info']))",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    child.stdout.close()  # long before the child has imported anything
    _, err = child.communicate(timeout=120)
    assert child.returncode == 141 and err == b"", err.decode()


def test_the_integration_options_are_made_from_the_fields_of_options(capsys):
    """``simulate``'s integration options take their defaults and help from the fields of
    ``Options``, and their check is the field's, made once (issue 28: before, argparse checked
    ``--rtol`` and ``Options`` again, and the help restated each default)."""
    from tensegrity.engine.options import OPTION_FIELDS, option_help

    parser = cli_main_parser()
    actions = {action.dest: action for action in parser._actions}
    for name in ("method", "dt", "rtol", "atol", "max_steps", "max_wall_time"):
        assert actions[name].default == OPTION_FIELDS[name].default, name
        assert actions[name].help == option_help(name), name
    assert actions["sample_dt"].help == "output spacing [s] (default 0.01)"
    assert main(["simulate", "--rtol", "0", "--out", "unused"]) == 2
    assert capsys.readouterr().err == "tensegrity: error: --rtol: must be > 0, got 0.0\n"


def cli_main_parser():
    """The ``simulate`` verb's parser."""
    from tensegrity.cli.main import build_parser

    commands = next(a for a in build_parser()._actions if a.dest == "command")
    return commands.choices["simulate"]
