"""Fitting a structure's parameters to measured motion (``analysis.identification``,
``tensegrity fit``): synthetic markers made by the engine with known parameters (4 markers at
30 Hz with 1 mm noise, by the sensors of ``engine.sensors``) give them back within their
intervals; the 95 % intervals hold the true values in about 95 % of noisy trials; a long run
needs the growing horizons; parameters the data cannot separate are reported; bad data is a
one-line error naming the marker and row."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.analysis import identification
from tensegrity.analysis.identification import (
    Experiment,
    fit,
    parameter,
    simulated_measurements,
)
from tensegrity.cli.main import main
from tensegrity.design.catalogue import six_bar_robot, three_bar_robot
from tensegrity.engine.sensors import Sensor, measure
from tensegrity.io.formats import read_scene, write_structure
from tensegrity.io.measurements import write_markers, write_measurements
from tensegrity.io.trajectory import write_trajectory
from tensegrity.model.ground import Scene, ground
from tensegrity.model.shell import class1_shell
from tensegrity.physics.dynamics import State, coordinates_from_nodes, initial_state

GRAVITY = np.array([0.0, 0.0, -9.81])
MARKERS = ("n3", "n7", "n11", "n5")  # free nodes of the fixed-base (3,1) shell
NOISE = 1e-3  # [m]
TRUE = {"tendon_stiffness": 120.0, "tendon_damping": 0.8, "rod_mass": 1.3}


def _push() -> np.ndarray:
    """A known 5 N push on node 11: a force that does not scale with the masses (with gravity
    alone every stiffness, damping and mass scaled together moves the same)."""
    w = np.zeros((12, 3))
    w[11, 0] = 5.0
    return w


def _shell(**values: float):
    s = class1_shell(3, 1, fixed_base=True)
    return s.replace(
        **{field: np.full(len(getattr(s, field)), value) for field, value in values.items()}
    )


OPTIONS = {"gravity": GRAVITY, "external_force": _push()}


def _markers(t_end: float, seed: int, **truth: float) -> dict:
    """The markers of the true shell over ``t_end`` [s]: 30 Hz, 1 mm noise."""
    run = simulate(_shell(**(TRUE | truth)), (0.0, t_end), sample_dt=0.01, **OPTIONS)
    (series,) = measure(
        run, [Sensor("position", nodes=MARKERS, noise=NOISE, rate=30.0)], seed=seed
    ).series
    return {n: (series.t, series.value[:, 3 * i : 3 * i + 3]) for i, n in enumerate(MARKERS)}


def test_the_shells_stiffness_damping_and_rod_masses_are_recovered():
    """From 20 % off, within 1 % (and within their 95 % intervals)."""
    experiment = Experiment(_markers(1.0, seed=0), NOISE, options=OPTIONS)
    start = _shell(tendon_stiffness=100.0, tendon_damping=0.6, rod_mass=1.0)
    result = fit(start, experiment, list(TRUE))
    assert result.success
    truth = np.array(list(TRUE.values()))
    np.testing.assert_allclose(result.estimate, truth, rtol=0.01)
    assert np.all((result.interval[:, 0] <= truth) & (truth <= result.interval[:, 1]))
    assert 0.8 * NOISE < result.rms_error < 1.2 * NOISE  # the fit leaves the noise
    assert not result.undetermined()
    np.testing.assert_allclose(result.structure.rod_mass, result.estimate[2])


def test_the_95_percent_intervals_hold_the_true_values_in_about_95_percent_of_trials():
    """40 noisy data sets of one motion, each fitted (from the truth: the intervals' coverage
    is the question, not the search): each parameter's interval holds the truth 33 to 40
    times."""
    run = simulate(_shell(**TRUE), (0.0, 0.3), sample_dt=0.01, **OPTIONS)
    sensors = [Sensor("position", nodes=MARKERS, noise=NOISE, rate=30.0)]
    truth = np.array(list(TRUE.values()))
    held = np.zeros(3, dtype=int)
    for seed in range(40):
        (series,) = measure(run, sensors, seed=seed).series
        markers = {n: (series.t, series.value[:, 3 * i : 3 * i + 3]) for i, n in enumerate(MARKERS)}
        result = fit(
            _shell(**TRUE), Experiment(markers, NOISE, options=OPTIONS), list(TRUE), horizons=(1.0,)
        )
        held += (result.interval[:, 0] <= truth) & (truth <= result.interval[:, 1])
    assert np.all((33 <= held) & (held <= 40)), held


def test_a_long_run_is_fitted_over_growing_horizons():
    """Over 3 s of undamped motion the phase slips by whole swings between the start and the
    truth: a fit of all of it at once ends in another minimum; over a quarter, a half, then
    all, it finds the truth."""
    experiment = Experiment(_markers(3.0, seed=1, tendon_damping=0.0), NOISE, options=OPTIONS)
    start = _shell(tendon_stiffness=100.0, rod_mass=1.0)  # undamped, as the truth
    names = ["tendon_stiffness", "rod_mass"]
    grown = fit(start, experiment, names)
    np.testing.assert_allclose(grown.estimate, [120.0, 1.3], rtol=1e-3)
    assert grown.rms_error < 1.2 * NOISE
    at_once = fit(start, experiment, names, horizons=(1.0,))
    assert at_once.rms_error > 100 * NOISE


def test_parameters_the_data_cannot_separate_are_reported():
    """Without the known push (and without damping), stiffness and mass scaled together give
    the same motion."""
    gravity_only = {"gravity": GRAVITY}
    truth = TRUE | {"tendon_damping": 0.0}
    run = simulate(_shell(**truth), (0.0, 0.5), sample_dt=0.01, **gravity_only)
    sensors = [Sensor("position", nodes=MARKERS, noise=NOISE, rate=30.0)]
    (series,) = measure(run, sensors, seed=2).series
    markers = {n: (series.t, series.value[:, 3 * i : 3 * i + 3]) for i, n in enumerate(MARKERS)}
    result = fit(
        _shell(**truth),
        Experiment(markers, NOISE, options=gravity_only),
        ["tendon_stiffness", "rod_mass"],
        horizons=(1.0,),
    )
    said = " ".join(result.undetermined())
    assert "tendon_stiffness and rod_mass are not determined separately" in said
    assert "rod_mass is not determined by the data (standard error" in said
    json.dumps(result.to_dict(), allow_nan=False)


def test_a_parameter_names_members_by_pattern():
    s = _shell()
    p = parameter(s, "tendon_stiffness:t1_*,t2_1_1")
    assert [s.tendon_name[i] for i in p.members] == ["t1_1_1", "t2_1_1", "t1_2_1", "t1_3_1"]
    assert parameter(s, "rod_mass:0,5").members.tolist() == [0, 5]
    with pytest.raises(ValueError, match="unknown kind 'stiffness'"):
        parameter(s, "stiffness")
    with pytest.raises(ValueError, match="the structure has no nodes with a point mass"):
        parameter(s, "point_mass")
    robot = six_bar_robot(payload_mass=0.4)
    assert parameter(robot, "point_mass:n1*").members.tolist() == [12]  # (n12 alone)
    with pytest.raises(ValueError, match="no node with a point mass matches 'n3'"):
        parameter(robot, "point_mass:n3")
    with pytest.raises(ValueError, match="no tendon matches 'x\\*'"):
        parameter(s, "tendon_damping:x*")
    with pytest.raises(ValueError, match="'friction' and 'friction' share members"):
        fit(s, Experiment({}, options={"ground": ground()}), ["friction", "friction"])


@pytest.mark.parametrize(
    ("markers", "message"),
    [
        ({"n99": (np.array([0.1]), np.zeros((1, 3)))}, "marker 'n99': no node"),
        ({"n3": (np.array([0.1, 0.2]), np.array([[0, 0, 0], [0, np.nan, 0]]))}, "row 1 is not"),
        ({"n3": (np.array([-0.1, 0.2]), np.zeros((2, 3)))}, "row 0 at t = -0.1 s is before"),
        ({"n3": (np.array([0.2, 0.1]), np.zeros((2, 3)))}, "row 1: times must increase"),
        ({"n3": (np.array([0.1]), np.zeros((1, 3)))}, "3 measured values for 3 parameters"),
        ({"n3": (np.array([0.1]), np.zeros((1, 2)))}, "expected times \\(T,\\) and positions"),
    ],
)  # fmt: skip
def test_bad_data_is_one_line_naming_the_marker_and_row(markers, message):
    with pytest.raises(ValueError, match=message) as caught:
        fit(_shell(), Experiment(markers, options=OPTIONS), list(TRUE))
    assert "\n" not in str(caught.value)


def test_the_cli_fits_a_markers_file_and_writes_the_fitted_structure(tmp_path, capsys):
    run = simulate(_shell(**TRUE), (0.0, 1.0), sample_dt=0.01, **OPTIONS)
    measured = measure(run, [Sensor("position", nodes=MARKERS, noise=NOISE, rate=30.0)], seed=2)
    data = write_markers(tmp_path / "markers.csv", measured)
    model = write_structure(tmp_path / "model.json", _shell())
    out = tmp_path / "fitted"
    args = [
        "fit", "--structure", str(model), "--data", str(data), "--param", "tendon_stiffness",
        "--param", "tendon_damping", "--param", "rod_mass", "--gravity", "9.81",
        "--load", "n11:5,0,0", "-o", str(out),
    ]  # fmt: skip
    assert main(args) == 0
    printed = capsys.readouterr().out
    lines = printed.splitlines()
    assert [line.split(":")[0] for line in lines[:3]] == [
        "tendon_stiffness",
        "tendon_damping",
        "rod_mass",
    ]
    assert all(" ± " in line and "95 %" in line for line in lines[:3])
    report = json.loads((out / "fit.json").read_text())
    estimate = {p["name"]: p["estimate"] for p in report["parameters"]}
    assert abs(estimate["tendon_stiffness"] / 120 - 1) < 0.01
    assert abs(estimate["rod_mass"] / 1.3 - 1) < 0.01
    fitted = json.loads((out / "structure.json").read_text())
    assert fitted["tendons"][0]["stiffness"] == pytest.approx(estimate["tendon_stiffness"])
    assert (out / "fit.png").stat().st_size > 10_000
    bad = [*args[:-1], str(tmp_path / "bad")]
    bad[bad.index("rod_mass")] = "rod_masses"
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown kind 'rod_masses'" in err
    assert not (tmp_path / "bad").exists()


def test_lengths_tensions_and_their_derivatives(monkeypatch):
    """Tendon lengths and tensions read from a run at their own times (a constant control
    moves the rest lengths; one tendon goes slack at times): the tensions within 1e-5 N of a
    run sampled at those very times
    (the interpolation's error); their derivatives, and the lengths', within 1e-5 of central
    differences of runs with each parameter moved (the runs at rtol 1e-12: the check is of the
    measurements' derivatives, not of the engine's accuracy at the fit's 1e-10)."""
    monkeypatch.setattr(identification, "RTOL", 1e-12)
    monkeypatch.setattr(identification, "ATOL", 1e-15)
    shell = _shell(**TRUE)
    options = OPTIONS | {"control": np.full(shell.n_tendons, 0.01)}
    a, b, c = (shell.tendon_name[i] for i in (0, 5, 12))
    irregular = np.sort(np.random.default_rng(0).uniform(0.01, 0.6, 25))
    grid = np.arange(1, 18) / 30
    experiment = Experiment(
        lengths={a: (irregular, np.zeros(25)), b: (grid, np.zeros(17))},
        tensions={a: (irregular, np.zeros(25)), c: (grid, np.zeros(17))},
        options=options,
    )
    names = ["tendon_stiffness", f"tendon_damping:{b}", f"tendon_rest_length:{c}", "rod_mass"]
    simulated = simulated_measurements(shell, experiment, parameters=names)
    assert simulated.jacobian is not None and simulated.jacobian.shape == (84, 4)
    exact = simulate(shell, (0.0, 0.6), sample_dt=1 / 3000, **options)
    rows = np.rint(grid * 3000).astype(int)
    tension = exact.tendon_tension[rows, shell.tendon_index(c)]
    assert np.abs(simulated.values[67:] - tension).max() < 1e-5
    assert tension.min() > 0
    slack = simulated.values[42:67] == 0  # tendon a goes slack: there its derivatives are 0
    assert 0 < slack.sum() < 25 and not simulated.jacobian[42:67][slack].any()
    for j, name in enumerate(names):
        p = parameter(shell, name)
        value = float(np.mean(getattr(shell, p.field)[p.members]))
        h = 1e-5 * value
        up, down = (
            simulated_measurements(p.apply(shell, v), experiment).values
            for v in (value + h, value - h)
        )
        reference = (up - down) / (2 * h)
        error = np.abs(reference - simulated.jacobian[:, j]).max() / np.abs(reference).max()
        assert error < 1e-5, name


def test_the_cli_fits_lengths_and_tensions_from_a_measurements_file(tmp_path, capsys):
    """No markers: three cable encoders (1 mm) and three load cells (0.1 N) at 30 Hz, the
    file ``tensegrity simulate --sensors`` writes.  The shell's stiffness, damping and rod
    mass from 20 % off, within 1 %."""
    shell = _shell(**TRUE)
    run = simulate(shell, (0.0, 1.0), sample_dt=1 / 300, **OPTIONS)
    names = shell.tendon_name
    sensors = [
        Sensor("length", tendons=[names[i] for i in (3, 8, 16)], noise=NOISE, rate=30.0),
        Sensor("tension", tendons=[names[i] for i in (0, 5, 12)], noise=0.1, rate=30.0),
    ]
    data = write_measurements(tmp_path / "measurements.csv", measure(run, sensors, seed=4))
    start = _shell(tendon_stiffness=100.0, tendon_damping=0.6, rod_mass=1.0)
    model = write_structure(tmp_path / "model.json", start)
    out = tmp_path / "fitted"
    args = [
        "fit", "--structure", str(model), "--data", str(data), "--param", "tendon_stiffness",
        "--param", "tendon_damping", "--param", "rod_mass", "--gravity", "9.81",
        "--load", "n11:5,0,0", "--tension-noise", "0.1", "-o", str(out),
    ]  # fmt: skip
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert " m, " in printed and " N over 186 measured values" in printed  # 6 x 31 samples
    report = json.loads((out / "fit.json").read_text())
    estimate = np.array([p["estimate"] for p in report["parameters"]])
    np.testing.assert_allclose(estimate, list(TRUE.values()), rtol=0.01)
    assert 0.05 < report["rms_tension_error_n"] < 0.15
    assert (out / "fit.png").stat().st_size > 10_000


def test_bad_tendon_data_is_one_line_naming_the_tendon_or_channel(tmp_path, capsys):
    shell = _shell()
    t = np.array([0.1, 0.2])
    cases = [
        (Experiment(tensions={"zz": (t, np.ones(2))}), "tension 'zz': no tendon of the structure"),
        (Experiment(lengths={"t1_1_1": (t, np.ones(3))}), r"expected times \(T,\) and lengths"),
        (Experiment(tensions={"t1_1_1": (t, [1.0, np.nan])}), "tension 't1_1_1': row 1 is not"),
        (Experiment(tensions={"t1_1_1": (t, np.ones(2))}, tension_noise=0), "tension_noise must"),
        (Experiment({"n3": (np.zeros(0), np.zeros((0, 3)))}), "hold no sample after the start"),
        (
            Experiment(tensions={"t1_1_1": (t, np.ones(2))}, options={"controller": object()}),
            r"options\['controller'\]: a fit follows runs without a controller or actuators",
        ),
    ]
    for experiment, message in cases:
        with pytest.raises(ValueError, match=message):
            fit(shell, experiment, ["tendon_stiffness"])
    data = tmp_path / "measurements.csv"
    data.write_text("time,channel,value\n0.1,velocity.n3.x,0.5\n")
    model = write_structure(tmp_path / "model.json", shell)
    assert main(["fit", "--structure", str(model), "--data", str(data), "--param",
                 "rod_mass", "-o", str(tmp_path / "no")]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "channel 'velocity.n3.x': not one an identification reads" in err
    data.write_text("time,channel,value\n0.1,position.n3.w,0.5\n0.1,position.n3.x,0.5\n")
    assert main(["fit", "--structure", str(model), "--data", str(data), "--param",
                 "rod_mass", "-o", str(tmp_path / "no")]) == 2  # fmt: skip
    assert "channel 'position.n3.w': a marker's coordinates are x, y, z" in capsys.readouterr().err
    data.write_text("t,x\n")
    assert main(["fit", "--structure", str(model), "--data", str(data), "--param",
                 "rod_mass", "-o", str(tmp_path / "no")]) == 2  # fmt: skip
    assert "expected the header 'time,marker,x,y,z' (markers) or" in capsys.readouterr().err
    assert not (tmp_path / "no").exists()


def test_the_cli_fits_a_trajectory_file(tmp_path, capsys):
    """A run's own trajectory (every free node a marker, from its first sample): the
    stiffness it was made with, to 1e-6; a model with other node names is refused."""
    true = write_structure(tmp_path / "true.json", _shell(**TRUE))
    run = tmp_path / "run"
    common = ["--gravity", "9.81", "--load", "n11:5,0,0"]
    assert main(["simulate", "--structure", str(true), "--t-end", "0.5", *common, "--no-view",
                 "--no-animation", "--out", str(run)]) == 0  # fmt: skip
    model = write_structure(tmp_path / "model.json", _shell(**(TRUE | {"tendon_stiffness": 100})))
    out = tmp_path / "fitted"
    data = str(run / "trajectory.h5")
    assert main(["fit", "--structure", str(model), "--data", data, "--param",
                 "tendon_stiffness", "--noise", "1e-6", *common, "-o", str(out)]) == 0  # fmt: skip
    capsys.readouterr()
    (fitted,) = json.loads((out / "fit.json").read_text())["parameters"]
    assert abs(fitted["estimate"] / TRUE["tendon_stiffness"] - 1) < 1e-6
    shell = _shell()
    renamed = shell.replace(node_name=[f"p{i}" for i in range(shell.n_nodes)])
    other = write_structure(tmp_path / "other.json", renamed)
    assert main(["fit", "--structure", str(other), "--data", data, "--param", "rod_mass",
                 "--gravity", "9.81", "-o", str(tmp_path / "no")]) == 2  # fmt: skip
    assert "is a run of another structure" in capsys.readouterr().err
    assert not (tmp_path / "no").exists()


def test_a_rolling_robots_friction_and_cable_stiffness_are_recovered(tmp_path, capsys):
    """The three-bar robot standing on its base, thrown at 1 m/s and 10 rad/s about a
    horizontal axis: it tips over its base's edge and rolls onto a side, its ends touching
    down, sticking and slipping (events located by the engine).  From 3 markers at 30 Hz with
    1 mm noise, its kinetic friction and cable stiffness are recovered within 2 % (from 0.45
    and 250 N/m; truth 0.6 and 300 N/m), and so by ``tensegrity fit`` from a structure file
    whose scene holds the ground, written back with the fitted friction."""
    robot = three_bar_robot(stiffness=300.0, tension=20.0)
    robot = robot.replace(node_position=robot.node_position + np.array([0.0, 0.0, 0.005]))
    centre = robot.node_position.mean(axis=0)
    v = np.cross([0.0, -10.0, 0.0], robot.node_position - centre) + np.array([-1.0, 0.0, 0.0])
    start = State(0.0, initial_state(robot).q, coordinates_from_nodes(robot, v))
    true = {"gravity": GRAVITY, "ground": ground(friction=0.8, kinetic_friction=0.6)}
    run = simulate(robot, (0.0, 1.0), initial=start, sample_dt=0.01, **true)
    lowest = [set(np.argsort(p[:, 2])[:3].tolist()) for p in run.node_position[[0, -1]]]
    assert run.status == 0 and lowest == [{0, 1, 2}, {2, 3, 4}]  # from its base onto a side
    modes = {tuple(m) for m in run.contact_event_mode.tolist()}
    assert {(0, 1), (1, 2), (2, 1)} <= modes  # touch-downs, sticks, slips
    names = robot.node_name[:3]
    measured = measure(run, [Sensor("position", nodes=names, noise=NOISE, rate=30.0)], seed=0)
    (series,) = measured.series
    markers = {n: (series.t, series.value[:, 3 * i : 3 * i + 3]) for i, n in enumerate(names)}
    guess = {"gravity": GRAVITY, "ground": ground(friction=0.8, kinetic_friction=0.45)}
    model = robot.replace(tendon_stiffness=np.full(robot.n_tendons, 250.0))
    experiment = Experiment(markers, NOISE, start, options=guess)
    result = fit(model, experiment, ["kinetic_friction", "tendon_stiffness"])
    np.testing.assert_allclose(result.estimate, [0.6, 300.0], rtol=0.02)
    assert result.options[0]["ground"][0].kinetic_friction == result.estimate[0]
    # the CLI: the model's file carries the scene; the run's trajectory starts the fit
    scene = Scene(planes=(guess["ground"],), gravity=GRAVITY)
    model_file = write_structure(tmp_path / "model.json", model, scene=scene)
    data = write_trajectory(tmp_path / "run.h5", run)
    out = tmp_path / "fitted"
    params = ["--param", "kinetic_friction", "--param", "tendon_stiffness"]
    assert main(["fit", "--structure", str(model_file), "--data", str(data), *params,
                 "-o", str(out)]) == 0  # fmt: skip
    capsys.readouterr()
    written = read_scene(out / "structure.json")
    assert abs(written.planes[0].kinetic_friction / 0.6 - 1) < 0.02
