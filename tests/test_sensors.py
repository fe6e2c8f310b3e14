"""Sensors (engine.sensors), their files (io.measurements) and ``simulate --sensors``: noise,
bias, delay and rate as asked, seeds, an IMU on a spinning rod against the closed form, the
online reader against the offline measurement, contact states of a robot at rest, files read
back, and one-line errors naming the field."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism, six_bar_robot
from tensegrity.design.rolling import stand_on_face
from tensegrity.engine.sensors import Sensor, SensorReader, measure
from tensegrity.io.measurements import (
    read_markers,
    read_measurements,
    read_sensors,
    write_markers,
    write_measurements,
)
from tensegrity.io.trajectory import read_trajectory
from tensegrity.model.ground import FREE, STICK, ground
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import initial_state, tendon_lengths

RADIUS, G, SAMPLE_DT = 0.01, 9.81, 0.01


@pytest.fixture(scope="module")
def ground_run():
    """The six-bar robot set on its face on the ground under gravity for 1 s, sampled every
    10 ms: it settles (moving, tensions and contacts changing) onto three sticking feet."""
    robot = six_bar_robot(stiffness=2000.0, tension=100.0, damping=20.0)
    face = np.argsort(robot.node_position @ np.ones(3))[:3]
    robot = stand_on_face(robot, face, contact_radius=RADIUS)
    run = simulate(
        robot,
        (0.0, 1.0),
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.8, kinetic_friction=0.6),
        contact_radius=RADIUS,
        sample_dt=SAMPLE_DT,
    )
    assert run.status == 0, run.message
    return run, face


def every_kind(**options) -> list[Sensor]:
    """A sensor of each kind with the same ``options`` (contacts without noise or bias)."""
    plain = {k: v for k, v in options.items() if k not in ("noise", "bias")}
    return [
        Sensor("position", nodes=("n0", "n5"), **options),
        Sensor("velocity", nodes=(3,), **options),
        Sensor("length", tendons=(0, 7), **options),
        Sensor("tension", **options),
        Sensor("orientation", rods=(1, 4), **options),
        Sensor("angular_rate", rods=(["n0", "n1"],), **options),
        Sensor("contact", **plain),
    ]


def test_noise_has_the_asked_mean_and_standard_deviation():
    """20,000 samples of 9 tendon lengths, each channel its own sigma (1 to 9 mm): the errors'
    mean is within 4 standard errors of 0 and their standard deviation within 3% of sigma (its
    standard error is 0.5%); channels are uncorrelated (|r| < 0.05)."""
    structure = prism()
    state = initial_state(structure)
    sigma = np.arange(1, 10) * 1e-3
    reader = SensorReader(structure, [Sensor("length", noise=tuple(sigma))], seed=11)
    N = 20_000
    values = np.array([reader(k * 1e-3, state.q, state.qdot).value for k in range(N)])
    truth = tendon_lengths(structure, structure.node_position)
    error = values - truth
    assert np.all(np.abs(error.mean(axis=0)) < 4 * sigma / math.sqrt(N))
    np.testing.assert_allclose(error.std(axis=0, ddof=1), sigma, rtol=0.03)
    correlation = np.corrcoef(error.T) - np.eye(sigma.size)
    assert np.abs(correlation).max() < 0.05


def test_a_bias_shifts_the_measurements_by_exactly_it(ground_run):
    """Without noise a sensor reads the signal itself (positions: the run's); with a bias,
    that plus the bias, bit for bit (one for all channels, or one per channel)."""
    run, _ = ground_run
    plain = measure(run, every_kind())
    nodes = [run.structure.node_index(n) for n in ("n0", "n5")]
    assert np.array_equal(plain.series[0].value, run.node_position[:, nodes].reshape(-1, 6))
    biased = measure(run, every_kind(bias=0.25))
    for before, after in zip(plain.series, biased.series, strict=True):
        bias = 0.0 if after.sensor.kind == "contact" else 0.25
        assert np.array_equal(after.value, before.value + bias), after.sensor.kind
    per_channel = (1.0, -2.0, 3.0)
    (before,) = measure(run, [Sensor("angular_rate", rods=(2,))]).series
    (after,) = measure(run, [Sensor("angular_rate", rods=(2,), bias=per_channel)]).series
    assert np.array_equal(after.value, before.value + per_channel)


@pytest.fixture(scope="module")
def fine_run(ground_run):
    """The same run sampled 6 times as often: the motion between the first's samples."""
    run, _ = ground_run
    fine = simulate(
        run.structure,
        (0.0, 1.0),
        gravity=[0.0, 0.0, -G],
        ground=ground(friction=0.8, kinetic_friction=0.6),
        contact_radius=RADIUS,
        sample_dt=SAMPLE_DT / 6,
    )
    assert fine.status == 0, fine.message
    return fine


def test_a_delay_shifts_the_signal_by_exactly_that_time(ground_run, fine_run):
    """A delay of 5 sample intervals shows the position 5 samples back (the first one before
    the run's start), bit for bit; a delay of 2.5 intervals the position between two samples,
    2.5 intervals back: that of the same run sampled 6 times as often (interpolated between
    the samples by cubic Hermite; to 1e-7 m but where a contact's kink falls between them)."""
    run, _ = ground_run
    nodes = ("n0", "n5", "n9")
    index = [run.structure.node_index(n) for n in nodes]
    truth = run.node_position[:, index].reshape(run.t.size, -1)
    (series,) = measure(run, [Sensor("position", nodes=nodes, delay=5 * SAMPLE_DT)]).series
    np.testing.assert_array_equal(series.t, run.t)
    assert np.array_equal(series.value, truth[np.maximum(np.arange(run.t.size) - 5, 0)])
    (series,) = measure(run, [Sensor("position", nodes=nodes, delay=2.5 * SAMPLE_DT)]).series
    fine = fine_run.node_position[:, index].reshape(fine_run.t.size, -1)
    back = fine[np.maximum(6 * np.arange(run.t.size) - 15, 0)]
    error = np.max(np.abs(series.value - back), axis=1)
    # measured: median 4e-8 m; 1.9e-5 m where a foot lands between two samples (a kink)
    assert np.median(error) < 1e-7 and error.max() < 1e-4
    held = truth[np.maximum(np.arange(run.t.size) - 3, 0)]  # the online reader's hold
    assert np.median(np.max(np.abs(held - back), axis=1)) > 1e-4  # measured: 7e-4 m


def test_a_rate_samples_at_its_own_times_and_holds_between(ground_run, fine_run):
    """At 20 Hz (a sample every 5 of the run's): the sample times ``k / rate``, the signal there
    bit for bit, held until the next; at 30 Hz (between the run's samples) the signal between
    them: that of the run sampled 6 times as often, to 1e-6 m."""
    run, _ = ground_run
    truth = run.tendon_length
    for rate in (20.0, 30.0):
        measured = measure(run, [Sensor("length", rate=rate)])
        (series,) = measured.series
        np.testing.assert_allclose(series.t, np.arange(series.t.size) / rate, rtol=0, atol=1e-12)
        assert series.t.size == math.floor(run.t[-1] * rate + 1e-9) + 1
        held = measured.held(run.t)
        latest = np.floor(run.t * rate + 1e-9).astype(int)
        assert np.array_equal(held, series.value[latest])
        if rate == 20.0:
            source = np.searchsorted(run.t, series.t + 1e-9, side="right") - 1
            assert np.array_equal(series.value, truth[source])
        else:
            fine = fine_run.tendon_length[20 * np.arange(series.t.size)]
            assert np.max(np.abs(series.value - fine)) < 1e-6  # measured: 2.8e-7 m


def test_the_same_seed_gives_the_same_measurements_and_another_seed_others(ground_run):
    run, _ = ground_run
    sensors = every_kind(noise=0.01, rate=50.0)
    first = measure(run, sensors, seed=7)
    again = measure(run, sensors, seed=7)
    other = measure(run, sensors, seed=8)
    for a, b, c in zip(first.series, again.series, other.series, strict=True):
        assert np.array_equal(a.value, b.value)
        if a.sensor.kind != "contact":
            assert np.all(a.value != c.value)
    # a sensor added after the others leaves their noise as it was
    more = measure(run, [*sensors, Sensor("tension", name="spare", noise=1.0)], seed=7)
    for a, b in zip(first.series, more.series, strict=False):
        assert np.array_equal(a.value, b.value)
    # the reader: reset(seed) starts the same noise again, reset() goes on
    reader = SensorReader(run.structure, sensors[:1], seed=7)
    state = initial_state(run.structure)
    a = reader(0.0, state.q, state.qdot).value
    reader.reset(7)
    assert np.array_equal(reader(0.0, state.q, state.qdot).value, a)
    reader.reset()
    assert np.all(reader(0.0, state.q, state.qdot).value != a)


def test_an_imu_on_a_spinning_rod_gives_the_closed_form():
    """A free rod of 2 m (no gravity, no members) spinning at 3 rad/s about an axis n normal to it
    keeps its angular velocity: the IMU gives ``omega = 3 n`` [rad/s] and the direction
    ``b(t) = cos(3t) b0 + sin(3t) n x b0``, at each sample and at its own rate."""
    b0 = np.array([2.0, -1.0, 2.0]) / 3.0
    n = np.cross(b0, [0.0, 0.0, 1.0])
    n /= np.linalg.norm(n)
    rate = 3.0
    centre = np.array([0.3, 0.1, 0.5])
    ends = centre + np.outer([-1.0, 1.0], b0)
    spin = np.outer([-1.0, 1.0], rate * np.cross(n, b0))
    rod = Structure(
        node_position=ends,
        node_velocity=spin,
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[2.0],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
    )
    run = simulate(rod, (0.0, 2.0), sample_dt=0.01, rtol=1e-12, atol=1e-12)
    assert run.status == 0, run.message
    imu = [Sensor("orientation"), Sensor("angular_rate", rate=40.0)]
    direction, omega = measure(run, imu).series
    np.testing.assert_allclose(omega.value, np.tile(rate * n, (omega.t.size, 1)), atol=1e-9)
    assert omega.channel == ("angular_rate.rod0.x", "angular_rate.rod0.y", "angular_rate.rod0.z")
    t = direction.t[:, None]
    expected = np.cos(rate * t) * b0 + np.sin(rate * t) * np.cross(n, b0)
    np.testing.assert_allclose(direction.value, expected, atol=1e-8)


def test_the_online_reader_and_the_offline_measurement_agree_sample_for_sample(ground_run):
    """Every kind of sensor with noise, delays and rates: a reader called at each of the run's
    samples (with its tensions and contact modes) reads what ``measure`` gives, bit for bit;
    called only at every other sample, its sensors at 50 Hz take the same samples."""
    run, _ = ground_run
    sensors = [
        *every_kind(noise=0.01, bias=0.1, delay=0.02, rate=50.0)[:4],
        *every_kind(noise=0.02, rate=None)[4:6],
        Sensor("contact", delay=0.03, rate=25.0),
    ]
    offline = measure(run, sensors, seed=3)
    reader = SensorReader(run.structure, sensors, planes=1, seed=3)
    assert reader.channel == offline.channel
    online = []
    for t, q, qdot, tension, mode in zip(
        run.t, run.q, run.qdot, run.tendon_tension, run.contact_mode, strict=True
    ):
        reading = reader(t, q, qdot, tension=tension, contact_mode=mode)
        assert reading.channel is reader.channel
        online.append(reading.value)
    assert np.array_equal(np.array(online), offline.held(run.t))
    for a, b in zip(reader.measurements().series, offline.series, strict=True):
        assert np.array_equal(a.t, b.t) and np.array_equal(a.value, b.value)
    rated = every_kind(noise=0.01, rate=50.0)
    reader = SensorReader(run.structure, rated, planes=1, seed=5)
    for t, q, qdot, tension, mode in list(
        zip(run.t, run.q, run.qdot, run.tendon_tension, run.contact_mode, strict=True)
    )[::2]:
        reader(t, q, qdot, tension=tension, contact_mode=mode)
    for a, b in zip(reader.measurements().series, measure(run, rated, seed=5).series, strict=True):
        assert np.array_equal(a.t, b.t) and np.array_equal(a.value, b.value)


def test_a_contact_sensor_reports_stick_under_a_robot_at_rest(ground_run):
    """The six-bar on its face: in its last half second the three feet stick (2) and the
    other rod ends are free (0), as the contact sensor reads them at 10 Hz."""
    run, face = ground_run
    (series,) = measure(run, [Sensor("contact", rate=10.0)]).series
    assert len(series.channel) == 12
    feet = [series.channel.index(f"contact.{run.structure.node_name[i]}") for i in face]
    late = series.t >= 0.5
    expected = np.full(len(series.channel), float(FREE))
    expected[feet] = STICK
    assert late.sum() == 6
    assert np.array_equal(series.value[late], np.tile(expected, (6, 1)))


def test_measurement_files_round_trip(ground_run, tmp_path):
    run, _ = ground_run
    measured = measure(run, every_kind(noise=0.01, rate=30.0), seed=1)
    path = write_measurements(tmp_path / "measurements.csv", measured)
    assert path.read_text().splitlines()[0] == "time,channel,value"
    channels = read_measurements(path)
    expected = measured.channels()
    assert list(channels) == list(expected)
    for name, (t, value) in expected.items():
        assert np.array_equal(channels[name].t, t) and np.array_equal(channels[name].value, value)
    markers = read_markers(write_markers(tmp_path / "markers.csv", measured))
    (positions,) = [s for s in measured.series if s.sensor.kind == "position"]
    assert list(markers) == ["n0", "n5"]
    for k, name in enumerate(markers):
        assert np.array_equal(markers[name].t, positions.t)
        assert np.array_equal(markers[name].position, positions.value[:, 3 * k : 3 * k + 3])
    sensors = every_kind(noise=0.5, bias=(0.1, 0.2, 0.3), delay=0.01, rate=100.0)[:2]
    file = tmp_path / "sensors.json"
    file.write_text(
        json.dumps(
            {
                "seed": 4,
                "sensors": [
                    {"kind": "position", "nodes": ["n0", "n5"], "noise": 0.5,
                     "bias": [0.1, 0.2, 0.3], "delay": 0.01, "rate": 100},
                    {"kind": "velocity", "nodes": [3], "noise": 0.5, "bias": [0.1, 0.2, 0.3],
                     "delay": 0.01, "rate": 100},
                ],
            }
        )
    )  # fmt: skip
    assert read_sensors(file) == (tuple(sensors), 4)


@pytest.mark.parametrize(
    ("fields", "field"),
    [
        (dict(kind="gyro"), "kind"),
        (dict(kind="position", noise=-0.1), "noise"),
        (dict(kind="position", noise=(0.1, math.nan)), "noise[1]"),
        (dict(kind="length", bias="x"), "bias"),
        (dict(kind="length", delay=-1.0), "delay"),
        (dict(kind="length", rate=0.0), "rate"),
        (dict(kind="length", nodes=("n0",)), "nodes"),
        (dict(kind="position", nodes="n0"), "nodes"),
        (dict(kind="contact", noise=0.1), "noise"),
        (dict(kind="length", name="a b"), "name"),
    ],
)
def test_a_bad_sensor_is_a_one_line_error_naming_the_field(fields, field):
    with pytest.raises(ValueError, match=rf"^{re.escape(field)}: ") as error:
        Sensor(**fields)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize(
    ("sensors", "planes", "message"),
    [
        ([Sensor("position", nodes=("nope",))], 0, r"^sensors\[0\]\.nodes: no node named 'nope'"),
        (
            [Sensor("length"), Sensor("length", name="l", tendons=(99,))],
            0,
            r"^sensors\[1\]\.tendons: ",
        ),
        ([Sensor("orientation", rods=(["n0", "n2"],))], 0, r"^sensors\[0\]\.rods: no rod joins"),
        ([Sensor("tension"), Sensor("tension")], 0, r"^sensors\[1\]\.name: 'tension' is"),
        ([Sensor("contact")], 0, r"^sensors\[0\]\.kind: a contact sensor needs a plane"),
        ([Sensor("position", bias=(1.0, 2.0))], 0, r"^sensors\[0\]\.bias: expected one number"),
        (
            [Sensor("position", nodes=(0, 1)), Sensor("position", name="p", nodes=(1,))],
            0,
            r"^sensors\[1\]\.nodes: node 'n1' is a marker of sensors\[0\]",
        ),
    ],
)
def test_sensors_that_do_not_fit_the_structure_name_the_sensor_and_field(sensors, planes, message):
    with pytest.raises(ValueError, match=message):
        SensorReader(prism(), sensors, planes=planes)


def test_a_reader_missing_what_its_sensors_read_or_going_back_in_time_says_so():
    structure = prism()
    state = initial_state(structure)
    reader = SensorReader(structure, [Sensor("tension")])
    with pytest.raises(ValueError, match=r"^tension: a sensor reads it"):
        reader(0.0, state.q, state.qdot)
    reader(1.0, state.q, state.qdot, tension=np.ones(9))
    with pytest.raises(ValueError, match=r"^t: 0\.5 is before the last time read, 1\.0"):
        reader(0.5, state.q, state.qdot, tension=np.ones(9))
    with pytest.raises(ValueError, match=r"^seed: expected a whole number >= 0"):
        reader.reset(-1)
    with pytest.raises(ValueError, match=r"^q, qdot: expected shape \(18,\)"):
        reader(2.0, state.q[:3], state.qdot, tension=np.ones(9))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("time,channel\n0,a\n", r"line 1: expected the header 'time,channel,value'"),
        ("time,channel,value\n0,a,1\n0.1,a,x\n", r"line 3, column value: expected a finite"),
        ("time,channel,value\n0,a,1\n\n# c\n0,a,2\n", r"line 5, column time: 0\.0 is not after"),
        ("time,channel,value\n0,a,1,2\n", r"line 2: expected 3 values"),
        ("time,channel,value\nnan,a,1\n", r"line 2, column time: expected a finite"),
    ],
)
def test_a_bad_measurements_file_names_the_file_line_and_column(tmp_path, text, message):
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(ValueError, match=rf"^{re.escape(str(path))}: {message}") as error:
        read_measurements(path)
    assert "\n" not in str(error.value)


def test_a_bad_markers_file_names_the_column(tmp_path):
    path = tmp_path / "markers.csv"
    path.write_text("time,marker,x,y,z\n0,n0,1,2,3\n0,,1,2,3\n")
    with pytest.raises(ValueError, match=r"markers\.csv: line 3, column marker: empty"):
        read_markers(path)


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ({"seed": 1}, r"sensors: missing"),
        ({"seed": -1, "sensors": [{"kind": "length"}]}, r"seed: expected a whole number"),
        ({"sensors": [], "x": 1}, r"x: unknown field"),
        ([{"kind": "length"}, {"kind": "length", "rate": "fast"}], r"sensors\[1\]\.rate: "),
        ([{"kind": "length", "colour": 1}], r"sensors\[0\]\.colour: unknown field"),
        ([{"noise": 1}], r"sensors\[0\]\.kind: missing"),
        ([3], r"sensors\[0\]: expected an object"),
    ],
)
def test_a_bad_sensor_file_names_the_file_and_the_field(tmp_path, document, message):
    path = tmp_path / "sensors.json"
    path.write_text(json.dumps(document))
    with pytest.raises(ValueError, match=rf"^{re.escape(str(path))}: {message}"):
        read_sensors(path)


def test_simulate_with_sensors_writes_their_measurements_beside_the_trajectory(tmp_path):
    """``simulate --sensors``: measurements.csv and markers.csv in --out, the measurement of
    the trajectory written beside them with the file's seed."""
    sensors = {
        "seed": 9,
        "sensors": [
            {"kind": "position", "nodes": ["n0", "n2"], "noise": 0.001, "rate": 20},
            {"kind": "tension", "tendons": [0], "noise": 0.1, "delay": 0.02},
            {"kind": "contact", "rate": 10},
        ],
    }
    file = tmp_path / "sensors.json"
    file.write_text(json.dumps(sensors))
    out = tmp_path / "out"
    argv = ["simulate", "--kind", "prism", "--t-end", "0.2", "--no-steady-state", "--no-view"]
    argv += ["--no-animation", "--ground", "-0.5", "--sensors", str(file), "--out", str(out)]
    assert main(argv) == 0
    run = read_trajectory(out / "trajectory.h5")
    expected = measure(run, read_sensors(file).sensors, seed=9)
    channels = read_measurements(out / "measurements.csv")
    assert list(channels) == list(expected.channels())
    for name, (t, value) in expected.channels().items():
        assert np.array_equal(channels[name].t, t) and np.array_equal(channels[name].value, value)
    markers = read_markers(out / "markers.csv")
    assert list(markers) == ["n0", "n2"] and markers["n0"].t.size == 5


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ([{"kind": "length", "rate": -2}], "sensors[0].rate: expected a finite number > 0"),
        ([{"kind": "position", "nodes": ["nope"]}], "sensors[0].nodes: no node named 'nope'"),
    ],
)
def test_simulate_with_a_bad_sensor_file_fails_in_one_line_naming_the_field(
    tmp_path, capsys, document, message
):
    file = tmp_path / "sensors.json"
    file.write_text(json.dumps(document))
    out = tmp_path / "out"
    assert main(["simulate", "--kind", "prism", "--sensors", str(file), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("tensegrity: error: --sensors: ")
    assert message in err[0] and str(file) in err[0]
    assert not out.exists()


def test_markers_need_a_position_sensor_and_names_no_comma(ground_run, tmp_path):
    run, _ = ground_run
    lengths = measure(run, [Sensor("length", rate=10.0)])
    with pytest.raises(ValueError, match=r"^measurements: no position sensor"):
        write_markers(tmp_path / "markers.csv", lengths)
    odd = run.structure.replace(node_name=["a,b", *run.structure.node_name[1:]])
    state = initial_state(odd)
    reader = SensorReader(odd, [Sensor("position", nodes=(0,))])
    reader(0.0, state.q, state.qdot)
    with pytest.raises(ValueError, match=r"^measurements: the name 'a,b' has a comma"):
        write_markers(tmp_path / "markers.csv", reader.measurements())
    assert not (tmp_path / "markers.csv").exists()
