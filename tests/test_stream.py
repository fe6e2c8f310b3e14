"""Streamed, resumable simulations (tensegrity.io.stream): an interrupted and resumed run stores
exactly the samples of an uninterrupted one, no sample is lost or repeated, memory does not grow
with the length of the run, the finished file is an ordinary trajectory, and a checkpoint made
with other settings is refused."""

from __future__ import annotations

import tempfile
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings, strategies as st

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.engine.options import sample_count
from tensegrity.engine.system import CompiledSystem
from tensegrity.io import stream as stream_module
from tensegrity.io.stream import (
    PARTIAL_SUFFIX,
    StreamProgress,
    read_checkpoint,
    segment_grid,
    simulate_to_file,
)
from tensegrity.io.trajectory import ENERGY_COLUMNS, read_trajectory
from test_io import flip_bytes_in_first_row

#: A damped (3,1) shell: tendons go slack and taut, energy is dissipated from the start.
SHELL = class1_shell(3, 1, damping=0.5)
#: Fast options: a short adaptive run at a loose tolerance (exactness is against other streamed
#: runs, which is independent of the tolerance).
FAST = dict(sample_dt=0.01, rtol=1e-6, atol=1e-9)
DATASETS = (
    "t",
    "q",
    "qdot",
    "tendon_tension",
    "energy",
    "residual_acceleration",
)


def datasets(path):
    with h5py.File(path, "r") as f:
        return {name: f[name][()] for name in DATASETS}


def stop_after(n_segments):
    """A progress callback that interrupts the run once ``n_segments`` segments are stored."""
    seen = []

    def callback(info: StreamProgress) -> None:
        seen.append(info)
        if info.segment == n_segments:
            raise KeyboardInterrupt

    return callback, seen


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """An uninterrupted run: 0.5 s in segments of 0.1 s (5 segments, 51 samples)."""
    path = tmp_path_factory.mktemp("reference") / "run.h5"
    summary = simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, **FAST)
    return path, summary


# ----------------------------------------------------------------------------- the grid
def test_segment_grid_is_aligned_with_samples():
    assert np.allclose(segment_grid((0.0, 0.5), 0.01, 10), [0, 0.1, 0.2, 0.3, 0.4, 0.5])
    # A last, shorter segment ends at t_end; a sliver below 1e-9 sample_dt is merged.
    assert np.allclose(segment_grid((1.0, 1.55), 0.01, 20), [1.0, 1.2, 1.4, 1.55])
    assert np.allclose(segment_grid((0.0, 0.4 + 1e-13), 0.01, 10), [0, 0.1, 0.2, 0.3, 0.4 + 1e-13])
    assert segment_grid((0.0, 0.05), 0.01, 10).tolist() == [0.0, 0.05]


@settings(max_examples=20, suppress_health_check=[HealthCheck.function_scoped_fixture])
@example(t0=0.0, span=0.2, intervals=6, digits=12, per_segment=6)  # 30 Hz rounded, as issue 27
@example(t0=0.0, span=0.4 + 1e-13, intervals=40, digits=3, per_segment=10)
@given(
    t0=st.sampled_from([0.0, 1.0, -0.3]),
    span=st.floats(0.02, 0.2),
    intervals=st.integers(1, 25),
    digits=st.integers(2, 14),
    per_segment=st.integers(1, 7),
)
def test_a_sampling_interval_that_does_not_divide_the_span(
    tmp_path, t0, span, intervals, digits, per_segment
):
    """Any sampling interval (the span's divisors rounded to a few digits, as a user types
    them): the streamed run ends with the samples of one ``simulate`` call, as many segments as
    the grid says, and a run interrupted after its first segment resumes to the same file."""
    sample_dt = float(f"{span / intervals:.{digits}g}")
    t_span = (t0, t0 + span)
    options = dict(FAST, sample_dt=sample_dt, segment=per_segment * sample_dt)
    folder = Path(tempfile.mkdtemp(dir=tmp_path))  # (one per example)
    path, resumed = folder / "run.h5", folder / "resumed.h5"
    summary = simulate_to_file(SHELL, t_span, path, **options)
    whole = simulate(SHELL, t_span, sample_dt=sample_dt, rtol=1e-6, atol=1e-9)
    t = read_trajectory(path).t
    assert np.array_equal(t, whole.t) and t[-1] == t_span[1]
    assert summary.n_samples == t.size == sample_count(*t_span, sample_dt)
    assert (
        summary.segments_stored
        == summary.n_segments
        == len(segment_grid(t_span, sample_dt, summary.samples_per_segment)) - 1
    )
    if summary.n_segments > 1:
        with pytest.raises(KeyboardInterrupt):
            simulate_to_file(SHELL, t_span, resumed, progress=stop_after(1)[0], **options)
        assert simulate_to_file(SHELL, t_span, resumed, **options).resumed_from == 1
        got, want = datasets(resumed), datasets(path)
        for name in DATASETS:
            assert np.array_equal(got[name], want[name]), name


# ----------------------------------------------------------------------------- a whole run
def test_uninterrupted_run_is_a_complete_trajectory(reference):
    path, summary = reference
    assert summary.status == 0 and summary.message == "reached t_end = 0.5 s"
    assert (summary.n_segments, summary.segments_stored, summary.segments_run) == (5, 5, 5)
    assert summary.resumed_from is None and summary.samples_per_segment == 10
    assert not path.with_name(path.name + PARTIAL_SUFFIX).exists()
    trajectory = read_trajectory(path)
    assert trajectory.status == 0 and trajectory.success
    assert trajectory.structure.to_dict() == SHELL.to_dict()
    assert trajectory.settings["t_span"] == [0.0, 0.5]
    assert trajectory.settings["stream"]["n_segments"] == 5
    assert trajectory.nfev == summary.nfev > 0
    assert list(trajectory.energy) == list(ENERGY_COLUMNS)
    # No sample missing or repeated: 51 samples, one every sample_dt, t0 and t_end included.
    t = trajectory.t
    assert t.size == summary.n_samples == 51
    assert t[0] == 0.0 and t[-1] == 0.5
    assert np.allclose(np.diff(t), 0.01, rtol=1e-9, atol=0)
    with h5py.File(path, "r") as f:
        assert f.attrs["complete"] and f["q"].chunks is not None and f["q"].maxshape[0] is None


def test_segments_agree_with_one_simulate_call_and_energy_is_continuous(reference):
    """Restarting the integrator at every boundary changes the result only at the level of the
    integration tolerance, and the works carry on across boundaries instead of restarting at 0."""
    path, _ = reference
    trajectory = read_trajectory(path)
    whole = simulate(SHELL, (0.0, 0.5), **FAST)
    assert np.array_equal(whole.t.size, trajectory.t.size)
    assert np.allclose(trajectory.t, whole.t, rtol=0, atol=1e-12)
    assert np.max(np.abs(trajectory.node_position - whole.node_position)) < 1e-4  # rtol 1e-6, 0.5 s
    dissipated = trajectory.energy["dissipated"]
    assert np.all(np.diff(dissipated) >= 0) and dissipated[-1] > 1.0
    assert abs(dissipated[-1] - whole.energy["dissipated"][-1]) < 1e-4 * dissipated[-1]
    e = trajectory.energy
    total = (
        e["kinetic"]
        + e["elastic"]
        + e["gravity"]
        + e["dissipated"]
        - e["external_work"]
        - e["control_work"]
    )
    assert np.max(np.abs(total - total[0])) < 1e-3 * dissipated[-1]


def test_times_with_a_shorter_last_segment_and_t0_not_zero(tmp_path):
    path = tmp_path / "run.h5"
    summary = simulate_to_file(SHELL, (1.0, 1.25), path, segment=0.1, **FAST)
    t = read_trajectory(path).t
    assert summary.n_segments == 3 and t.size == 26
    assert t[0] == 1.0 and t[-1] == 1.25
    assert np.allclose(np.diff(t), 0.01, rtol=1e-9, atol=0)


def test_a_corrupted_streamed_file_is_an_error_not_wrong_numbers(tmp_path, reference):
    """The streamed file's datasets carry Fletcher-32 checksums: bytes changed in a stored row
    (uncompressed, so nothing else would notice) make the read fail, naming the file."""
    path = tmp_path / "run.h5"
    path.write_bytes(reference[0].read_bytes())
    flip_bytes_in_first_row(path, "q")
    with pytest.raises(ValueError, match=r"run.h5: dataset 'q': corrupted \(.*damaged\)$"):
        read_trajectory(path)


# ----------------------------------------------------------------------------- resuming
def test_interrupted_and_resumed_run_is_bitwise_the_uninterrupted_one(tmp_path, reference):
    ref_path, ref_summary = reference
    path = tmp_path / "run.h5"
    partial = tmp_path / ("run.h5" + PARTIAL_SUFFIX)
    callback, seen = stop_after(2)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, progress=callback, **FAST)
    assert [info.segment for info in seen] == [1, 2]
    assert seen[-1].n_samples == 21 and seen[-1].t == pytest.approx(0.2)
    # The incomplete run is visible as such: no file under the final name, and the partial file
    # is refused by read_trajectory.
    assert not path.exists() and partial.exists()
    with pytest.raises(ValueError, match="not a tensegrity trajectory"):
        read_trajectory(partial)
    checkpoint = read_checkpoint(path)
    assert (checkpoint.next_segment, checkpoint.n_samples, checkpoint.ended) == (2, 21, False)
    assert checkpoint.state.t == pytest.approx(0.2)

    summary = simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, **FAST)
    assert summary.resumed_from == 2 and summary.segments_run == 3
    assert not partial.exists()
    got, want = datasets(path), datasets(ref_path)
    for name in DATASETS:
        assert got[name].shape == want[name].shape, name
        assert np.array_equal(got[name], want[name]), name
    assert (summary.nfev, summary.nsteps, summary.nswitches, summary.nprojections) == (
        ref_summary.nfev,
        ref_summary.nsteps,
        ref_summary.nswitches,
        ref_summary.nprojections,
    )
    assert read_trajectory(path).message == "reached t_end = 0.5 s"


def test_a_run_out_of_time_keeps_its_segments_and_resumes_bitwise(tmp_path, reference):
    """``max_wall_time`` is a budget per call: a streamed run that uses it up raises
    ``OutOfTimeError`` and keeps its finished segments in the partial file; the next call (another
    budget is allowed) continues it to the uninterrupted run's file, bit for bit."""
    import time

    from tensegrity.io.stream import OutOfTimeError

    ref_path, _ = reference
    path = tmp_path / "run.h5"
    partial = tmp_path / ("run.h5" + PARTIAL_SUFFIX)

    def slow(info: StreamProgress) -> None:  # each stored segment costs 0.2 s more
        time.sleep(0.2)

    with pytest.raises(
        OutOfTimeError, match=r"^stopped after max_wall_time \(--max-wall-time\) = 0.3 s"
    ) as stop:
        simulate_to_file(
            SHELL, (0.0, 0.5), path, segment=0.1, progress=slow, max_wall_time=0.3, **FAST
        )
    assert stop.value.partial == partial and partial.exists() and not path.exists()
    assert 1 <= read_checkpoint(path).next_segment < 5
    summary = simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, max_wall_time=60.0, **FAST)
    assert summary.status == 0 and summary.resumed_from is not None
    got, want = datasets(path), datasets(ref_path)
    for name in DATASETS:
        assert np.array_equal(got[name], want[name]), name


def test_interruption_inside_a_segment_and_inside_a_write(tmp_path, reference, monkeypatch):
    """Interrupted while simulating segment 3, then while storing segment 4 (its rows appended
    and its checkpoint written to the spare slot, but not committed): the previous checkpoint
    stays current and the rows past it are dropped on resume."""
    ref_path, _ = reference
    path = tmp_path / "run.h5"
    record = CompiledSystem.record

    def record_then_interrupt(system, samples, row, t, y, inputs):
        if t > 0.25:  # inside segment 3 (0.2 .. 0.3 s)
            raise KeyboardInterrupt
        record(system, samples, row, t, y, inputs)

    monkeypatch.setattr(CompiledSystem, "record", record_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, **FAST)
    assert read_checkpoint(path).next_segment == 2
    monkeypatch.setattr(CompiledSystem, "record", record)

    write_checkpoint = stream_module._write_checkpoint

    def interrupt_before_commit(slot, checkpoint):
        write_checkpoint(slot, checkpoint)  # the spare slot is written in full, ...
        if checkpoint.next_segment == 4:
            raise KeyboardInterrupt  # ... but not made current

    monkeypatch.setattr(stream_module, "_write_checkpoint", interrupt_before_commit)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, **FAST)
    partial = tmp_path / ("run.h5" + PARTIAL_SUFFIX)
    with h5py.File(partial, "r") as f:
        assert f["t"].shape[0] == 41  # segment 4's rows are there ...
    checkpoint = read_checkpoint(path)
    assert (checkpoint.next_segment, checkpoint.n_samples) == (3, 31)  # ... but not committed
    assert checkpoint.state.t == pytest.approx(0.3)
    monkeypatch.setattr(stream_module, "_write_checkpoint", write_checkpoint)

    summary = simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, **FAST)
    assert summary.resumed_from == 3
    got, want = datasets(path), datasets(ref_path)
    for name in DATASETS:
        assert np.array_equal(got[name], want[name]), name


def test_finished_run_is_not_run_again(reference):
    path, summary = reference
    again = simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, **FAST)
    assert again.segments_run == 0 and again.n_samples == summary.n_samples
    assert again.settings_hash == summary.settings_hash


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(rtol=1e-7), ["options.rtol", "1e-06", "1e-07"]),
        (dict(segment=0.2), ["samples_per_segment"]),
        (dict(t_span=(0.0, 0.6)), ["t_span"]),
        (dict(structure=class1_shell(3, 1, damping=0.6)), ["structure"]),
        (dict(gravity=(0.0, 0.0, -9.81)), ["options.gravity"]),
    ],
)
def test_resume_with_other_settings_is_refused(tmp_path, change, words):
    path = tmp_path / "run.h5"
    callback, _ = stop_after(1)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, progress=callback, **FAST)
    arguments = dict(structure=SHELL, t_span=(0.0, 0.5), segment=0.1, **FAST)
    arguments.update(change)
    structure, t_span = arguments.pop("structure"), arguments.pop("t_span")
    with pytest.raises(ValueError, match="cannot resume") as info:
        simulate_to_file(structure, t_span, path, **arguments)
    message = str(info.value)
    assert message.startswith(str(path) + PARTIAL_SUFFIX) and "\n" not in message
    for word in words:
        assert word in message, message
    assert read_checkpoint(path).next_segment == 1  # left as it was
    if "structure" in change:
        return
    # resume=False starts again with the new settings.
    summary = simulate_to_file(structure, t_span, path, resume=False, **arguments)
    assert summary.resumed_from is None and summary.status == 0
    assert read_trajectory(path).t[-1] == t_span[1]


def test_explicit_default_options_match_omitted_ones(tmp_path):
    path = tmp_path / "run.h5"
    callback, _ = stop_after(1)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(SHELL, (0.0, 0.3), path, segment=0.1, progress=callback, **FAST)
    summary = simulate_to_file(
        SHELL,
        (0.0, 0.3),
        path,
        segment=0.1,
        method="DOP853",
        steady_state=False,
        gravity=None,
        **FAST,
    )
    assert summary.resumed_from == 1


# ----------------------------------------------------------------------------- endings
def test_unstable_segment_stops_the_run_and_records_the_failure(tmp_path):
    path = tmp_path / "run.h5"
    summary = simulate_to_file(
        SHELL, (0.0, 1.0), path, segment=0.2, sample_dt=0.05, method="rk4", dt=0.05
    )
    assert summary.status == -1 and not summary.success
    assert summary.message.startswith("unstable")
    assert summary.segments_stored < summary.n_segments
    trajectory = read_trajectory(path)
    assert trajectory.status == -1 and trajectory.message == summary.message
    assert trajectory.t.size == summary.n_samples >= 1
    assert np.all(np.diff(trajectory.t) > 0)


def test_steady_state_stops_the_run(tmp_path):
    path = tmp_path / "run.h5"
    structure = artificial_damping(class1_shell(3, 1))
    summary = simulate_to_file(
        structure,
        (0.0, 20.0),
        path,
        segment=1.0,
        sample_dt=0.05,
        rtol=1e-6,
        atol=1e-9,
        steady_state=True,
        velocity_tol=1e-3,
        acceleration_tol=1e-3,
    )
    assert summary.status == 1 and summary.message.startswith("steady state")
    assert summary.segments_stored < summary.n_segments
    trajectory = read_trajectory(path)
    assert trajectory.status == 1 and trajectory.t[-1] == summary.t_last < 20.0
    assert np.abs(trajectory.node_velocity[-1]).max() < 1e-3


# ----------------------------------------------------------------------------- memory
def test_memory_does_not_grow_with_the_length_of_the_run(tmp_path):
    """Peak traced memory of a run twice as long grows by far less than its extra samples take
    (a plain simulate call, which keeps every sample, grows by about that much)."""
    structure = class1_shell(4, 2, damping=0.5)
    options = dict(method="rk4", dt=2e-3, sample_dt=2e-3)
    simulate_to_file(structure, (0.0, 0.02), tmp_path / "warm.h5", segment=0.01, **options)

    def peak(t_end, run):
        tracemalloc.start()
        try:
            run(t_end)
            return tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()

    def streamed(t_end):
        simulate_to_file(
            structure, (0.0, t_end), tmp_path / f"run{t_end}.h5", segment=0.04, **options
        )

    short, long = peak(0.16, streamed), peak(0.32, streamed)
    extra_samples = (
        read_trajectory(tmp_path / "run0.32.h5").t.size
        - read_trajectory(tmp_path / "run0.16.h5").t.size
    )
    with h5py.File(tmp_path / "run0.32.h5", "r") as f:
        row_bytes = sum(
            f[name].dtype.itemsize * int(np.prod(f[name].shape[1:])) for name in DATASETS
        )
    extra_bytes = extra_samples * row_bytes
    assert extra_bytes > 150_000
    print("MEM", short, long, extra_bytes)
    assert long - short < 0.2 * extra_bytes, (short, long, extra_bytes)
    # The same check catches a run that keeps its samples:
    kept_short = peak(0.16, lambda t: simulate(structure, (0.0, t), **options))
    kept_long = peak(0.32, lambda t: simulate(structure, (0.0, t), **options))
    print("KEPT", kept_short, kept_long)
    assert kept_long - kept_short > 0.5 * extra_bytes


# ----------------------------------------------------------------------------- arguments
def test_invalid_arguments(tmp_path):
    path = tmp_path / "run.h5"
    with pytest.raises(ValueError, match="t_span"):
        simulate_to_file(SHELL, (1.0, 1.0), path)
    with pytest.raises(ValueError, match="segment"):
        simulate_to_file(SHELL, (0.0, 1.0), path, segment=-1.0)
    with pytest.raises(ValueError, match="sample_dt"):
        simulate_to_file(SHELL, (0.0, 1.0), path, sample_dt=0.0)
    with pytest.raises(TypeError, match="unknown option"):
        simulate_to_file(SHELL, (0.0, 1.0), path, rtoll=1e-3)
    with pytest.raises(ValueError, match="directory"):
        simulate_to_file(SHELL, (0.0, 1.0), tmp_path / "missing" / "run.h5")
    assert list(tmp_path.iterdir()) == []


def test_joint_error_is_kept_across_segments_and_a_resume(tmp_path, monkeypatch):
    """The largest joint violation of a streamed run is the largest over all its segments,
    including those run before an interruption (kept in the checkpoint)."""
    from tensegrity.model.shell import class2_shell

    structure = class2_shell(3, 2)
    whole = simulate_to_file(structure, (0.0, 0.1), tmp_path / "whole.h5", segment=0.02, **FAST)
    path = tmp_path / "jointed.h5"
    callback, _ = stop_after(2)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(structure, (0.0, 0.1), path, segment=0.02, progress=callback, **FAST)
    before = read_checkpoint(path).max_constraint_error
    assert 0.0 < before <= whole.max_constraint_error
    summary = simulate_to_file(structure, (0.0, 0.1), path, segment=0.02, **FAST)
    assert summary.segments_run == 3 and summary.segments_stored == 5
    assert summary.max_constraint_error == whole.max_constraint_error < 1e-9
    assert read_trajectory(path).max_constraint_error == whole.max_constraint_error


def test_a_refused_resume_names_the_keyword_and_the_option(tmp_path):
    """The library's message reads right from Python and from the shell (issue 28: before, the
    CLI rewrote ``pass resume=False`` by string replacement)."""
    path = tmp_path / "run.h5"
    callback, _ = stop_after(1)
    with pytest.raises(KeyboardInterrupt):
        simulate_to_file(SHELL, (0.0, 0.5), path, segment=0.1, progress=callback, **FAST)
    with pytest.raises(ValueError, match="cannot resume") as info:
        simulate_to_file(SHELL, (0.0, 0.6), path, segment=0.1, **FAST)
    assert str(info.value).endswith("; start again with resume=False (run without --resume)")


def test_the_streamed_options_are_the_fields_of_options():
    """The options a streamed run takes (and hashes into its settings) are its inputs and the
    fields of ``Options``, not read from a function's signature (issue 28)."""
    import dataclasses

    from tensegrity.engine.options import Options

    fields = {f.name: f.default for f in dataclasses.fields(Options)}
    inputs = {"initial", "control", "external_force", "gravity", "ground", "contact_radius"}
    inputs |= {"controller", "actuators", "stop"}
    assert stream_module._SIMULATE_PARAMETERS == {**dict.fromkeys(inputs), **fields}


@pytest.mark.parametrize("planes", [0, 2])
def test_a_samples_size_estimate_is_what_a_run_holds_and_writes(tmp_path, planes):
    """``sample_bytes`` of a run with ``planes`` planes (a rod and a point mass: ``(2 + 1)
    planes`` contact pairs) is the bytes of a sample the engine hands over (``held``: every
    column of a block of ``Samples``, the int8 contact modes included) and the bytes of a row
    of the file's per-sample datasets (float64)."""
    from tensegrity.io.stream import sample_bytes
    from tensegrity.io.trajectory import sample_rows
    from tensegrity.model.ground import Plane, ground
    from tensegrity.model.structure import Structure

    structure = Structure(
        node_position=[[-0.5, 0, 0.3], [0.5, 0, 0.3], [0, 0, 0.2], [0, 0, 2.0]],
        node_point_mass=[0, 0, 0.5, 0],
        node_fixed=[False, False, False, True],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        tendon_nodes=[[0, 2], [1, 2], [2, 3]],
        tendon_stiffness=[100.0] * 3,
        tendon_rest_length=[0.6, 0.6, 2.0],
    )
    scene = {}
    if planes:
        wall = Plane(point=(5.0, 0.0, 0.0), normal=(-1.0, 0.0, 0.0))
        scene = dict(ground=[ground(), wall], contact_radius=0.01)
    blocks = []
    path = tmp_path / "run.h5"
    simulate_to_file(structure, (0.0, 0.05), path, gravity=(0, 0, -9.81), observe=blocks.append,
                     **FAST, **scene)  # fmt: skip
    rows = sum(len(block.t) for block in blocks)
    assert blocks[0].contact_mode.shape[1] == 3 * planes
    held = sum(column.nbytes for block in blocks for column in block)
    assert held == rows * sample_bytes(structure, held=True, planes=planes)
    with h5py.File(path, "r") as f:
        T = f["t"].shape[0]
        names = sample_rows(structure, 3 * planes)
        assert set(names) <= set(f)
        written = sum(f[name].size * f[name].dtype.itemsize for name in names)
    assert written == T * sample_bytes(structure, planes=planes)
