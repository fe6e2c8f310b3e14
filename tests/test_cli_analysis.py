"""The analysis verbs of the command line: equilibrium, modes, controllability, control.

Each runs on the paper's (3,1) shell (and on a structure file written by ``tensegrity export``)
and must write the files it promises with content that agrees with the library and with facts
known independently (all 24 tendons at 31.64 N, the lowest frequency 2.129 Hz, the one
uncontrollable mode); bad input is one line on stderr, a non-zero exit and no files.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tensegrity import class1_shell
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.shape_control import shell_rings
from tensegrity.cli.control import rings
from tensegrity.cli.main import main
from tensegrity.plots.viewer import read_viewer_data

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _run(argv, capsys):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _check_files(out, names):
    """Exactly ``names`` in ``out`` (no staging or temporary leftovers) and the verb's listing
    of them (``.VERB-outputs``, :func:`tensegrity.io.files.write_staged`), PNGs real images."""
    listings = [p for p in out.iterdir() if p.name.endswith("-outputs")]
    assert len(listings) == 1 and sorted(json.loads(listings[0].read_text())) == sorted(names)
    assert sorted(p.name for p in out.iterdir()) == sorted([*names, listings[0].name])
    for name in names:
        data = (out / name).read_bytes()
        if name.endswith(".png"):
            assert data[:8] == PNG_SIGNATURE and len(data) > 10_000, name
    return {n: json.loads((out / n).read_text()) for n in names if n.endswith(".json")}


@pytest.fixture(scope="module")
def shell_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("structure") / "shell31.json"
    assert main(["export", "-o", str(path)]) == 0
    return path


def test_equilibrium_writes_positions_tensions_and_residuals(tmp_path, capsys):
    out = tmp_path / "eq"
    code, text, err = _run(["equilibrium", "--out", str(out)], capsys)
    assert code == 0, err
    names = ["equilibrium.json", "equilibrium.png", "settling.html"]
    data = _check_files(out, names)["equilibrium.json"]
    direct, simulated = data["least_squares"], data["simulation"]
    _check_settling(out / "settling.html", np.array(simulated["node_position_m"]))
    assert direct["converged"] and simulated["converged"]
    p = np.array(direct["node_position_m"])
    assert p.shape == (12, 3)
    # rods keep their 1 m length; every tendon at the paper-example tension, none slack
    rods = class1_shell(3, 1).rod_nodes
    np.testing.assert_allclose(
        np.linalg.norm(p[rods[:, 1]] - p[rods[:, 0]], axis=1), 1.0, atol=1e-12
    )
    tensions = [t["tension_N"] for t in direct["tendons"]]
    assert len(tensions) == 24 and np.allclose(tensions, 31.64, atol=0.005)
    assert data["least_squares"]["slack_tendons"] == [] and direct["residual_force_N"] < 1e-9
    # the two routes agree (simulation stops at speeds < 1e-6 m/s)
    assert data["agreement"]["node_distance"] < 1e-6
    assert data["agreement"]["tension_difference"] < 1e-4
    assert "routes agree" in text and "t8_3_1" in text and "wrote" in text


def _check_settling(path, settled):
    """The settling page: the damped run's samples from the start to where it settled."""
    from tensegrity.analysis.equilibrium import equilibrium_by_simulation

    page = read_viewer_data(path.read_text())
    run = equilibrium_by_simulation(class1_shell(3, 1), t_end=60.0).trajectory
    assert 1 < page["n_frames"] <= 300 and np.all(np.diff(page["t"]) > 0)
    index = np.array(page["sample_index"])
    np.testing.assert_allclose(page["t"], run.t[index], rtol=1e-12)
    np.testing.assert_allclose(page["node_position"], run.node_position[index], atol=1e-6)
    np.testing.assert_allclose(
        page["tendon_tension"], run.tendon_tension[index], rtol=1e-5, atol=1e-4
    )
    assert index[0] == 0 and index[-1] == run.t.size - 1
    np.testing.assert_allclose(page["node_position"][-1], settled, atol=1e-6)


def test_equilibrium_of_a_structure_file_matches_the_shell_options(tmp_path, capsys, shell_file):
    out = tmp_path / "eq"
    code, _, err = _run(
        [
            "equilibrium",
            "--structure",
            str(shell_file),
            "--method",
            "least_squares",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    data = json.loads((out / "equilibrium.json").read_text())
    assert "simulation" not in data and "agreement" not in data
    # the structure's vocabulary (``Structure.tendon_name``), as the result's
    assert data["structure"]["tendon_name"] == list(class1_shell(3, 1).tendon_name)
    page = read_viewer_data((out / "settling.html").read_text())  # no run: the structure at rest
    assert page["n_frames"] == 1
    np.testing.assert_allclose(
        page["node_position"][0], class1_shell(3, 1).node_position, atol=1e-6
    )
    reference = find_equilibrium(class1_shell(3, 1))
    np.testing.assert_allclose(
        [t["tension_N"] for t in data["least_squares"]["tendons"]], reference.tension, rtol=1e-9
    )


def test_modes_writes_frequencies_in_hz_with_mode_shapes(tmp_path, capsys, shell_file):
    out = tmp_path / "modes"
    code, text, err = _run(
        [
            "modes",
            "--structure",
            str(shell_file),
            "--shapes",
            "4",
            "--check-fft",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    clips = [f"mode_{i}.html" for i in range(6, 10)]  # the 4 lowest elastic modes
    names = ["modes.json", "frequencies.png", "mode_shapes.png", *clips]
    data = _check_files(out, names)["modes.json"]
    modes = data["modes"]
    assert len(modes) == 30 and data["rigid_body_modes"] == 6 and data["mechanisms"] == 0
    assert data["stable"] and data["verdict"].startswith("stable")
    f = np.array([m["frequency_hz"] for m in modes])
    w2 = np.array([m["omega_squared"] for m in modes])
    np.testing.assert_allclose(f, np.sqrt(np.maximum(w2, 0)) / (2 * np.pi), rtol=1e-12)
    assert np.all(np.diff(f) >= 0) and f[6] == pytest.approx(2.129, abs=1e-3)
    shape = np.array(modes[6]["node_shape_m"])
    assert shape.shape == (12, 3) and np.abs(shape).max() > 0
    # the FFT of the undamped nonlinear simulation agrees within 1%
    assert data["fft_check"]["relative_error"] < 0.01
    assert "FFT check" in text and "2.12942" in text
    _check_mode_clip(out / "mode_6.html", modes[6], 6)


def _check_mode_clip(path, mode, i):
    """The page of mode ``i`` (its ``modes.json`` entry ``mode``): one period of
    ``p0 + a sin(2 pi j / 48) phi`` at the mode's own period, largest displacement 10% of the
    structure's size, tensions of each displaced configuration."""
    from tensegrity.physics.dynamics import tendon_tensions

    page = read_viewer_data(path.read_text())
    structure = class1_shell(3, 1)
    p0 = find_equilibrium(structure).node_position
    phi = np.array(mode["node_shape_m"])
    a = 0.1 * np.ptp(p0, axis=0).max() / np.linalg.norm(phi, axis=1).max()
    j = np.arange(48)
    expected = p0 + a * np.sin(2 * np.pi * j / 48)[:, None, None] * phi
    assert page["n_frames"] == 48 and f"mode {i}" in page["title"]
    np.testing.assert_allclose(page["t"], j / 48 / mode["frequency_hz"], rtol=1e-12)
    np.testing.assert_allclose(page["node_position"], expected, rtol=0, atol=1e-6)
    displacement = np.linalg.norm(page["node_position"] - p0, axis=-1).max()
    assert displacement == pytest.approx(0.1 * np.ptp(p0, axis=0).max(), rel=1e-3)
    tension = tendon_tensions(structure, expected[12])
    np.testing.assert_allclose(page["tendon_tension"][12], tension, rtol=1e-5)


def test_controllability_ranks_per_input_set(tmp_path, capsys):
    out = tmp_path / "ctrl"
    code, text, err = _run(
        [
            "controllability",
            "--inputs",
            "all",
            "t1_1_1",
            "t1_*,t5_*",
            "--outputs",
            "position",
            "tension",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 0, err
    files = ["controllability.json", "controllability.png", "observability.png"]
    data = _check_files(out, files)["controllability.json"]
    ranks = {
        r["name"]: (r["rank"], r["states"], len(r["signals"])) for r in data["controllability"]
    }
    # the (3,1) shell: every tendon set misses one mode (the prestress-stiffened mechanism,
    # 3.24 Hz); a single tendon reaches one mode of each repeated frequency only
    assert ranks == {"all": (46, 60, 24), "t1_1_1": (18, 60, 1), "t1_*,t5_*": (46, 60, 6)}
    missed = data["controllability"][0]["missed_modes"]
    # tendon forces are internal: the rigid-body modes are never reached either
    assert [(m["modes"], m["kind"]) for m in missed] == [
        ([0, 1, 2, 3, 4, 5], "rigid"),
        ([9], "elastic"),
    ]
    assert missed[1]["frequency_hz"] == pytest.approx(3.2356, abs=1e-3)
    obs = {r["name"]: r["rank"] for r in data["observability"]}
    assert obs == {"position": 60, "tension": 46}
    assert data["pbh_rtol"] == 1e-8 and "relative tolerance 1e-08" in text
    assert all(r["gramian"]["max_eigenvalue"] > 0 for r in data["controllability"])


def test_control_reaches_the_targets_open_and_closed_loop(tmp_path, capsys):
    out = tmp_path / "control"
    code, text, err = _run(["control", "--steps", "4", "2", "--out", str(out)], capsys)
    assert code == 0, err
    files = ["control.json", "control_motion.png", "control_inputs.png", "control_shapes.png"]
    data = _check_files(out, [*files, "open_loop.html", "control.html"])["control.json"]
    plan, closed = data["open_loop"], data["closed_loop"]
    # the pages: the plan's equilibria one per step from the initial one; the closed loop's
    # samples from t = 0 to its end, taut throughout
    steps = read_viewer_data((out / "open_loop.html").read_text())
    p0 = find_equilibrium(class1_shell(3, 1)).node_position
    assert steps["n_frames"] >= 7 and steps["t"] == list(range(steps["n_frames"]))
    np.testing.assert_allclose(steps["node_position"][0], p0, atol=1e-5)
    run = read_viewer_data((out / "control.html").read_text())
    assert 1 < run["n_frames"] <= 300 and run["t"][0] == 0 and np.all(np.diff(run["t"]) > 0)
    np.testing.assert_allclose(run["node_position"][0], p0, atol=1e-5)
    assert run["tendon_tension"].min() > 0 and f"{run['t'][-1]:.3g} s" in text
    h0 = plan["initial_outputs"][0]
    assert plan["reached"] and closed["reached"]
    assert plan["final_outputs"][0] == pytest.approx(0.8 * h0, abs=1e-6)
    assert closed["final_outputs"][0] == pytest.approx(0.8 * h0, abs=1e-6)
    assert abs(closed["final_outputs"][1]) <= 1e-6
    assert plan["min_tension_N"] >= 1.0 and closed["min_tension_N"] > 0  # nothing went slack
    assert plan["min_rest_length_m"] >= 0.05 and closed["min_rest_length_m"] >= 0.05
    assert sorted(data["bottom"]) == sorted(shell_rings(3, 1)[0])
    assert sorted(data["top"]) == sorted(shell_rings(3, 1)[1])
    assert "closed loop (LQR" in text and "reached" in text


def test_control_that_misses_its_targets_exits_1_with_the_results(tmp_path, capsys):
    """Rest-length changes of at most 1 cm cannot shorten the shell by 20%: the plan says so,
    the files are written, and the exit code is 1 with a one-line reason."""
    out = tmp_path / "control"
    code, _, err = _run(
        [
            "control",
            "--max-change",
            "0.01",
            "--no-twist-back",
            "--steps",
            "1",
            "1",
            "--no-closed-loop",
            "--out",
            str(out),
        ],
        capsys,
    )
    assert code == 1
    assert err.count("\n") == 1 and "missed" in err and "results written" in err
    data = json.loads((out / "control.json").read_text())
    assert not data["open_loop"]["reached"] and "closed_loop" not in data
    assert max(abs(u) for u in data["open_loop"]["final_control_m"].values()) <= 0.01 + 1e-12


@pytest.mark.parametrize("n_m", [(3, 1), (4, 2)])
def test_default_rings_of_a_shell_are_its_bottom_and_top_rings(n_m):
    s = class1_shell(*n_m)
    bottom, top = rings(s, find_equilibrium(s).node_position)
    expected = shell_rings(*n_m)
    assert sorted(bottom) == sorted(expected[0]) and sorted(top) == sorted(expected[1])


@pytest.mark.parametrize(
    "argv, words",
    [
        (["controllability", "--inputs", "nope*"], "no tendon matches 'nope*'"),
        (["controllability", "--outputs", "speed"], "no output matches 'speed'"),
        (["controllability", "--damping", "lots"], "--damping"),
        (["control", "--bottom", "99"], "bottom: node 99 out of range 0..11"),
        (["control", "--actuators", "t99_*"], "no tendon matches 't99_*'"),
        (["control", "--height", "-0.2"], "--height"),
        (["control", "--steps", "0", "2"], "steps"),
        (["control", "--steps", "10", "1000000000"], "steps: expected two step counts from 1 to"),
        (["control", "--bottom", "0", "--top", "0"], "share nodes [0]"),
        (["equilibrium", "--method", "guess"], "--method"),
        (["equilibrium", "--structure", "missing.json"], "missing.json"),
        (["modes", "--structure", "x.json", "--m", "2"], "--m"),
        (["modes", "--n", "2"], "n"),
        # before: modes 6 to 28 drawn; an empty name or pattern silently dropped
        (["modes", "--shapes", "-1"], "modes: argument --shapes: must be >= 0, got '-1'"),
        (["controllability", "--inputs", "all,"], "argument --inputs: an empty name or pattern"),
        (["controllability", "--inputs", "b*,,s*"], "argument --inputs: an empty name or pattern"),
        (["controllability", "--outputs", ","], "argument --outputs: an empty name or pattern"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(
    argv, words, tmp_path, capsys, monkeypatch
):
    monkeypatch.chdir(tmp_path)
    code, _, err = _run(argv, capsys)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("tensegrity: error:"), err
    assert words in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


def _without_tendons(path):
    from tensegrity import Structure
    from tensegrity.design.catalogue import generate
    from tensegrity.io.formats import write_structure

    data = generate("prism").to_dict()
    write_structure(path, Structure.from_dict({**data, "tendons": []}))
    return path


def test_modes_of_zero_frequency_are_reported_without_warnings(tmp_path, capsys):
    """A structure without tendons: every non-rigid mode is a mechanism of zero frequency.
    No RuntimeWarning (before: division by zero for the period of each mode's page); each
    page says it shows a shape of zero frequency, not a period; the FFT check says it has
    nothing to measure (before: ``attempt to get argmax of an empty sequence``, exit 2)."""
    import warnings

    out = tmp_path / "m"
    structure = _without_tendons(tmp_path / "bare.json")
    argv = ["modes", "--structure", str(structure), "--shapes", "2", "--check-fft"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code, text, err = _run([*argv, "--out", str(out), "--debug"], capsys)
    assert code == 0 and err == "", err
    assert "FFT check: not done, no elastic mode (no non-zero frequency to measure)" in text
    modes = _check_files(
        out, ["modes.json", "frequencies.png", "mode_shapes.png", "mode_6.html", "mode_7.html"]
    )["modes.json"]["modes"]
    assert [m["kind"] for m in modes[6:]] == ["mechanism"] * 9
    page = read_viewer_data((out / "mode_6.html").read_text())
    assert page["title"] == "mode 6: mechanism, zero frequency (no period): its shape over 1 s"
    np.testing.assert_allclose(page["t"], np.arange(48) / 48, rtol=1e-12)
    assert np.all(np.isfinite(page["node_position"]))


def test_the_bounds_and_rest_tolerances_default_to_the_library_s():
    """``control``'s bounds are :class:`~tensegrity.analysis.bounds.Bounds`' defaults and
    ``equilibrium``'s rest tolerances ``Options``' (one source, shown in ``--help``)."""
    import dataclasses

    from tensegrity.analysis.bounds import Bounds
    from tensegrity.cli.main import build_parser
    from tensegrity.engine.options import Options

    control = vars(build_parser().parse_args(["control"]))
    assert {k: control[k] for k in ("min_rest_length", "max_change", "min_tension")} == (
        dataclasses.asdict(Bounds())
    )
    equilibrium = vars(build_parser().parse_args(["equilibrium"]))
    assert equilibrium["velocity_tol"] == Options().velocity_tol
    assert equilibrium["acceleration_tol"] == Options().acceleration_tol
