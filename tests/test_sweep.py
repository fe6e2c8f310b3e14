"""Parameter sweeps on Dask (``tensegrity.sweep.run``) and the batched compiled path
(``tensegrity.engine.batch``): failures are reported per case without losing the others, and every
case's results are those of a direct ``simulate`` call on a structure built here by hand."""

from __future__ import annotations

import errno
import json
import re
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")
pytest.importorskip("xarray")
pytest.importorskip("numba")

from distributed import Client, LocalCluster

from tensegrity import State, class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.engine.batch import simulate_batch
from tensegrity.physics import dynamics
from tensegrity.sweep.run import STATUS_ERROR, SweepSpec, read_sweep, run_sweep

T_END, SAMPLE_DT, DT = 0.02, 2e-3, 2e-4


@pytest.fixture(scope="module")
def cluster():
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0"
    ) as local:
        yield local


@pytest.fixture(scope="module")
def client(cluster):
    with Client(cluster) as c:
        yield c


def hand_built(n, m, stiffness, rest_scale, damping, load):
    """The case's structure and load, built here from the documented definitions."""
    s = class1_shell(n, m, stiffness=stiffness, damping=damping)
    p = s.node_position
    lengths = np.linalg.norm(p[s.tendon_nodes[:, 1]] - p[s.tendon_nodes[:, 0]], axis=1)
    s = s.replace(tendon_rest_length=rest_scale * lengths)
    force = None
    if load:
        force = np.zeros((s.n_nodes, 3))
        top = np.isclose(p[:, 2], p[:, 2].max(), rtol=0, atol=1e-12)
        bottom = np.isclose(p[:, 2], p[:, 2].min(), rtol=0, atol=1e-12)
        assert top.sum() == n and bottom.sum() == n
        force[top, 2] = -load / n
        force[bottom, 2] = load / n
    return s, force


def direct_series(result):
    """The sweep's series computed here from a SimulationResult."""
    p0 = result.structure.node_position
    return {
        "kinetic_energy": result.energy["kinetic"],
        "elastic_energy": result.energy["elastic"],
        "energy_error": result.total_energy - result.total_energy[0],
        "max_tension": result.tendon_tension.max(axis=1),
        "slack_count": np.sum(result.tendon_tension <= 0, axis=1),
        "max_displacement": np.max(np.linalg.norm(result.node_position - p0, axis=2), axis=1),
    }


def case_parameters(ds, i):
    return {
        name: ds[name].values[i].item()
        for name in ("n", "m", "stiffness", "rest_scale", "damping", "load")
    }


GRID = {"stiffness": [80.0, 3e7], "load": [0.0, 6.0], "n": [3, 4], "damping": [0.5]}


@pytest.fixture(scope="module")
def failing_sweep(client):
    spec = SweepSpec(GRID, t_end=T_END, sample_dt=SAMPLE_DT, dt=DT, batch=False)
    return run_sweep(spec, client=client)


def test_failing_cases_are_reported_and_the_others_finish(failing_sweep):
    ds = failing_sweep.dataset
    assert ds.sizes["case"] == 8 and ds.sizes["t"] == round(T_END / SAMPLE_DT) + 1
    status = ds["status"].values
    k = ds["stiffness"].values
    # k = 3e7 at this step blows up.
    unstable = k == 3e7
    assert np.all(status[unstable] == -1)
    assert all(m.startswith("unstable") for m in ds["message"].values[unstable])
    assert np.all(ds["t_final"].values[unstable] < T_END)
    good = k == 80.0
    assert np.all(status[good] == 0)
    assert np.all(ds["t_final"].values[good] == pytest.approx(T_END))
    assert np.all(np.isfinite(ds["kinetic_energy"].values[good]))
    assert sorted(failing_sweep.failed) == sorted(np.flatnonzero(~good).tolist())
    assert "stiffness=3e+07" in failing_sweep.describe_case(int(np.flatnonzero(unstable)[0]))


@pytest.mark.parametrize(
    "grid, words",
    [
        ({"n": [3, 2]}, "case 1 (n=2, m=1, stiffness=100, rest_scale=0.9, damping=0, load=0): n:"),
        ({"stiffness": [100.0, -5.0, 50.0]}, "case 1 (n=3, m=1, stiffness=-5,"),
        ({"damping": [0.0, 1.0, -0.5]}, "case 2 (n=3, m=1, stiffness=100, rest_scale=0.9, dam"),
    ],
)
def test_cases_out_of_range_are_refused_before_the_cluster_starts(grid, words, monkeypatch):
    """A parameter out of its range fails in one line naming the case, before any cluster is
    started or work sent out (before, every such case failed on the cluster and the sweep
    wrote a dataset of failed cases)."""
    from tensegrity.sweep import run as sweep_run

    def no_cluster(*args, **kwargs):
        raise AssertionError("a cluster was started")

    monkeypatch.setattr(sweep_run._Cluster, "__enter__", no_cluster)
    with pytest.raises(ValueError) as refused:
        run_sweep(SweepSpec(grid, t_end=T_END, sample_dt=SAMPLE_DT, dt=DT))
    message = str(refused.value)
    assert message.startswith(words) and "\n" not in message, message


def test_a_case_that_fails_on_a_worker_is_reported_not_raised():
    """What a worker runs (``run_cases``): a case whose model cannot be built (one the check
    up front did not probe) becomes a failed row naming the parameter, and the others run."""
    from tensegrity.sweep.run import run_cases

    spec = SweepSpec({"n": [3]}, t_end=T_END, sample_dt=SAMPLE_DT, dt=DT, batch=False)
    good, bad = spec.cases()[0], {**spec.cases()[0], "n": 2}
    rows = run_cases([bad, good], spec, batched=False)
    assert rows[0]["status"] == STATUS_ERROR and "n: a shell needs n >= 3" in rows[0]["message"]
    assert rows[1]["status"] == 0


def test_cli_sweep_out_of_range_writes_nothing(tmp_path, capsys):
    out = tmp_path / "s.nc"
    assert main(["sweep", "--param", "stiffness=-5,100", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("tensegrity: error: case 0 (") and "stiffness: must be > 0" in err, err
    assert not out.exists() and not list(tmp_path.iterdir())


QUICK_SWEEP = ["--param", "stiffness=100,200", "--t-end", "0.004", "--sample-dt", "0.002"]
QUICK_SWEEP += ["--dt", "0.0002", "--workers", "1"]


def test_cli_sweep_makes_the_folders_of_its_output(tmp_path, capsys, monkeypatch):
    """``-o`` in folders that do not exist: sweep makes them, as the other verbs make theirs
    (before: ``No such file or directory`` after the whole sweep had run); if writing the dataset
    fails, the folders it made are removed again."""
    from tensegrity.sweep.run import SweepResult

    out = tmp_path / "new" / "deeper" / "s.nc"
    save = SweepResult.save

    def full_disk(self, path):
        assert Path(path).parent.is_dir()
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.setattr(SweepResult, "save", full_disk)
    # a full disk fails the command (exit 1, as everywhere), it is not bad input
    assert main(["sweep", *QUICK_SWEEP, "-o", str(out)]) == 1
    assert capsys.readouterr().err == f"tensegrity: error: {out}: No space left on device\n"
    assert list(tmp_path.iterdir()) == []
    monkeypatch.setattr(SweepResult, "save", save)
    assert main(["sweep", *QUICK_SWEEP, "-o", str(out)]) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    assert read_sweep(out).sizes["case"] == 2


def test_cli_sweep_refuses_an_output_it_cannot_write_before_it_runs(tmp_path, capsys, monkeypatch):
    """A file where a folder of ``-o`` goes, or a folder where the file goes: one line and exit 2
    before any case runs (before: after the whole sweep)."""

    def never(*args, **kwargs):
        raise AssertionError("the sweep ran")

    monkeypatch.setattr("tensegrity.sweep.run.run_sweep", never)
    (tmp_path / "file").write_text("")
    (tmp_path / "folder.nc").mkdir()
    assert main(["sweep", *QUICK_SWEEP, "-o", str(tmp_path / "file" / "s.nc")]) == 2
    assert main(["sweep", *QUICK_SWEEP, "-o", str(tmp_path / "folder.nc")]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"tensegrity: error: --output: {tmp_path / 'file'} exists and is not a folder",
        f"tensegrity: error: --output: {tmp_path / 'folder.nc'} is a folder, expected a file name",
    ]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "folder.nc"]


def test_sweep_cases_equal_direct_simulate_bitwise(failing_sweep):
    ds = failing_sweep.dataset
    checked = 0
    for i in np.flatnonzero(ds["status"].values != STATUS_ERROR):
        structure, force = hand_built(**case_parameters(ds, i))
        result = simulate(
            structure, (0.0, T_END), method="rk4", dt=DT, sample_dt=SAMPLE_DT, external_force=force
        )
        assert int(ds["status"].values[i]) == result.status
        assert ds["message"].values[i] == result.message
        assert ds["nsteps"].values[i] == result.nsteps
        rows = np.isclose(result.t, np.rint(result.t / SAMPLE_DT) * SAMPLE_DT, rtol=0, atol=1e-15)
        for name, series in direct_series(result).items():
            got = ds[name].values[i]
            np.testing.assert_array_equal(got[: rows.sum()], series[rows], err_msg=name)
            assert np.all(np.isnan(got[rows.sum() :])), name
        checked += 1
    assert checked == 8  # (every case: none is out of range)


def test_batched_sweep_matches_direct_simulate(client):
    spec = SweepSpec(
        {
            "stiffness": [60.0, 150.0],
            "rest_scale": [0.85, 0.95],
            "load": [0.0, 4.0],
            "damping": [0.3],
        },
        t_end=T_END,
        sample_dt=SAMPLE_DT,
        dt=DT,
    )
    result = run_sweep(spec, client=client)
    ds = result.dataset
    assert result.success and np.all(ds["batched"].values == 1)
    for i in range(ds.sizes["case"]):
        structure, force = hand_built(**case_parameters(ds, i))
        ref = simulate(
            structure, (0.0, T_END), method="rk4", dt=DT, sample_dt=SAMPLE_DT, external_force=force
        )
        expected = direct_series(ref)
        energy_scale = np.max(expected["kinetic_energy"] + expected["elastic_energy"])
        for name, series in expected.items():
            got = ds[name].values[i]
            # energy_error is a balance (a cancellation): compare it with the energies.
            scale = energy_scale if name == "energy_error" else np.max(np.abs(series))
            assert np.max(np.abs(got - series)) <= 1e-12 * scale, name


def test_monte_carlo_cases_are_reproducible_and_in_range():
    spec = SweepSpec(
        {"stiffness": [50.0, 200.0], "n": [3, 5], "load": [2.0]},
        mode="monte-carlo",
        samples=40,
        seed=7,
    )
    cases = spec.cases()
    assert cases == SweepSpec.from_dict(spec.to_dict()).cases()
    assert len(cases) == 40
    k = np.array([c["stiffness"] for c in cases])
    n = np.array([c["n"] for c in cases])
    assert np.all((50 <= k) & (k <= 200)) and np.unique(k).size == 40
    assert set(n.tolist()) == {3, 4, 5}
    assert all(c["load"] == 2.0 and c["m"] == 1 for c in cases)


@pytest.mark.parametrize(
    "changes, field",
    [
        (dict(parameters={"stifness": [1.0]}), "parameters.stifness"),
        (dict(parameters={"n": [3.5]}), r"parameters.n\[0\]"),
        (dict(parameters={"load": []}), "parameters.load"),
        (dict(parameters={"load": [3, 1]}, mode="monte-carlo", samples=3), "parameters.load"),
        (dict(mode="monte-carlo"), "samples"),
        (dict(t_end=0.0105), "t_end"),
        (dict(method="euler"), "method"),
        (dict(mode="random"), "mode"),
        (dict(mode="monte-carlo", samples=2, seed=-1), "seed: must be >= 0, got -1"),
        # before: OverflowError; a ValueError only from run_sweep; a sweep of failed cases
        (dict(t_end=1e308), "t_end: 1e[+]308 s is too long to count its samples"),
        (dict(parameters={"n": [0]}), r"case 0 \(n=0, m=1, .*\): n: "),
        (dict(dt=1e-300), r"dt: 1e-300 s does not advance the time"),
        (dict(t_end=10.0, dt=1e-9), r"dt: 1e-09 s over 10 s is 10,000,000,000 steps, more than"),
    ],
)
def test_bad_specs_name_the_field(changes, field):
    base = dict(parameters={"stiffness": [100.0]})
    with pytest.raises(ValueError, match=f"^{field}"):
        SweepSpec(**{**base, **changes})


@pytest.mark.parametrize(
    "args, line",
    [
        (["--param", "stiffness=1:2", "--samples", "0"], "--samples: must be >= 1 for Monte Carlo"),
        (
            ["--param", "stiffness=2:1", "--samples", "3"],
            "--param stiffness: Monte Carlo needs a range low <= high (two values) or one value",
        ),
        (["--param", "n=3,3.5"], "--param n: expected an integer, got 3.5"),
        (["--param", "stifness=1"], "--param stifness: unknown parameter; choose from n, m"),
        (
            ["--param", "stiffness=1", "--t-end", "0.0015"],
            "--t-end: must be a whole multiple of sample_dt (--sample-dt) = 0.001 s, got 0.0015 s",
        ),
        (["--param", "stiffness=1", "--method", "euler"], "--method: expected one of rk4, "),
        (["--param", "stiffness=1:2", "--samples", "2", "--seed", "-1"], "--seed: must be >= 0"),
        (["--param", "stiffness=1:2", "--samples", "5"], "--samples: 5 cases, more than the "),
        (["--param", "stiffness=1,2", "--param", "n=3,4"], "--param: 4 cases, more than the "),
        (["--param", "stiffness=1", "--workers", "0"], "--workers: must be >= 1, got 0"),
        # a range without --samples, a grid's list with it (before: both silently a grid / a
        # range), a range of three numbers (before: a grid), a step as simulate refuses it
        # (before: exit 1 after every case had failed, an empty dataset written)
        (["--param", "stiffness=5:1"], "--param stiffness: LOW:HIGH is a range to draw from and "),
        (["--param", "stiffness=1:2"], "--param stiffness: LOW:HIGH is a range to draw from and "),
        (["--param", "stiffness=1,2", "--samples", "2"], "--param stiffness: V1,V2,... are a g"),
        (
            ["--param", "stiffness=1:2:3"],
            "sweep: argument --param: expected NAME=V1,V2,... or NAME=LOW:HIGH, got 'stiffness=1:",
        ),
        (
            ["--param", "stiffness=1", "--dt", "1e-300"],
            "--dt: 1e-300 s does not advance the time (at t = 0.1 s a step must be at least its "
            "rounding); use a larger dt (--dt)",
        ),
    ],
)
def test_cli_sweep_errors_name_the_option(args, line, tmp_path, capsys, monkeypatch):
    """The sweep's one-line errors name the option the user typed (``--samples``,
    ``--param n``, ``--t-end``), not the library's argument (``samples``, ``parameters.n[1]``,
    ``t_end``; those stay in the library's own messages, above); refused before any case runs."""
    monkeypatch.setenv("TENSEGRITY_MAX_CASES", "3")
    out = tmp_path / "s.nc"
    assert main(["sweep", *args, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"tensegrity: error: {line}") and err.count("\n") == 1, err
    assert not out.exists()


def test_spec_files_and_saved_dataset(tmp_path, client):
    (tmp_path / "spec.yaml").write_text(
        "parameters:\n  stiffness: [90, 110]\nt_end: 0.004\nsample_dt: 0.002\ndt: 0.0002\n"
    )
    spec = SweepSpec.from_file(tmp_path / "spec.yaml")
    (tmp_path / "spec.json").write_text(json.dumps(spec.to_dict()))
    assert SweepSpec.from_file(tmp_path / "spec.json") == spec
    (tmp_path / "bad.json").write_text('{"parameters": {"k": [1]}}')
    with pytest.raises(ValueError, match=re.escape("parameters.k")):
        SweepSpec.from_file(tmp_path / "bad.json")
    result = run_sweep(spec, client=client)
    path = result.save(tmp_path / "sweep.nc")
    back = read_sweep(path)
    assert back.identical(result.dataset)
    assert json.loads(back.attrs["spec"]) == spec.to_dict()
    assert not list(tmp_path.glob("*.tmp"))


def test_scheduler_address(cluster):
    spec = SweepSpec(
        {"stiffness": [100.0, 120.0, 140.0]}, t_end=0.004, sample_dt=0.002, dt=DT, method="RK45"
    )
    calls = []
    result = run_sweep(
        spec,
        scheduler=cluster.scheduler_address,
        progress=lambda done, total: calls.append((done, total)),
    )
    assert result.success and result.dataset.sizes["case"] == 3
    assert calls == [(1, 3), (2, 3), (3, 3)]  # one task per case for an adaptive method
    with pytest.raises(ValueError, match=r"^scheduler"):
        run_sweep(spec, scheduler=cluster.scheduler_address, client=object())


def test_cli_sweep_reports_failures_and_writes(tmp_path, capsys):
    out = tmp_path / "s.nc"
    code = main(
        [
            "sweep",
            "--param",
            "stiffness=100,3e7",
            "--t-end",
            "0.004",
            "--sample-dt",
            "0.002",
            "--dt",
            "0.0002",
            "--workers",
            "1",
            "-o",
            str(out),
        ]
    )
    captured = capsys.readouterr()
    assert code == 1
    assert "1 of 2 cases reached t_end" in captured.out
    assert captured.err.count("\n") == 1 and "stiffness=3e+07" in captured.err
    assert read_sweep(out).sizes["case"] == 2
    assert main(["sweep", "--param", "stiffness", "-o", str(out)]) == 2
    assert main(["sweep", "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("tensegrity: error:") for line in err)


# ------------------------------------------------------------------------------ batched path
@pytest.mark.parametrize("min_run", [None, 2], ids=["default runs", "runs of 2"])
def test_batch_matches_single_runs_and_isolates_a_blow_up(min_run, monkeypatch):
    """Copies with random masses, lengths, stiffnesses, rest lengths, tendon and rod damping,
    loads, start states and gravity, one of them unstable: each equals its own simulate run.  The
    copy with undamped tendons, run alone, takes the kernel's undamped specialization and gives
    the same numbers as in the mixed batch (generic path, zero damping).  The (4,2) shell has no
    run of the default length; with runs of 2 most of its tendons are in runs."""
    if min_run is not None:
        from tensegrity.physics import kernel

        monkeypatch.setattr(kernel, "MIN_RUN", min_run)
        monkeypatch.setattr(kernel, "MIN_TENDONS_IN_RUNS", 0)
    rng = np.random.default_rng(3)
    base = class1_shell(4, 2)
    structures, forces, starts = [], [], []
    for b in range(4):
        L = rng.uniform(0.8, 1.2)
        s = class1_shell(4, 2, rod_length=L)
        lengths = dynamics.tendon_lengths(s, s.node_position)
        s = s.replace(
            rod_mass=rng.uniform(0.5, 2.0, s.n_rods),
            tendon_stiffness=rng.uniform(50, 300, s.n_tendons) * (1e6 if b == 2 else 1.0),
            tendon_rest_length=rng.uniform(0.8, 1.0, s.n_tendons) * lengths,
            tendon_damping=rng.uniform(0, 2, s.n_tendons) * (b != 3),  # copy 3: undamped tendons
            rod_damping=rng.uniform(0, 1, s.n_rods),
        )
        structures.append(s)
        forces.append(rng.normal(0, 2, (s.n_nodes, 3)) if b != 1 else None)
        start = dynamics.initial_state(s)
        starts.append(
            State(t=0.0, q=start.q, qdot=start.qdot + 0.1 * rng.standard_normal(start.q.size))
        )
    assert all(np.array_equal(s.tendon_nodes, base.tendon_nodes) for s in structures)
    g = np.array([0.0, 0.0, -9.81])
    batch = simulate_batch(
        structures,
        (0.0, 0.03),
        dt=2e-4,
        sample_dt=2e-3,
        initial=starts,
        external_force=forces,
        gravity=g,
    )
    for b, (s, got) in enumerate(zip(structures, batch, strict=True)):
        ref = simulate(
            s,
            (0.0, 0.03),
            method="rk4",
            dt=2e-4,
            sample_dt=2e-3,
            initial=starts[b],
            external_force=forces[b],
            gravity=g,
        )
        assert got.status == ref.status and got.nsteps == ref.nsteps
        np.testing.assert_array_equal(got.t, ref.t)
        if b == 2:
            assert got.status == -1 and got.message == ref.message
            assert got.message.startswith("unstable")
            continue
        assert got.status == 0 and got.nfev == ref.nfev
        for name in ("q", "qdot", "tendon_tension", "node_position"):
            a, r = getattr(got, name), getattr(ref, name)
            assert np.max(np.abs(a - r)) <= 1e-12 * np.max(np.abs(r)), name
        for name, e in ref.energy.items():
            scale = max(np.max(np.abs(e)), np.max(np.abs(ref.energy["kinetic"])))
            assert np.max(np.abs(got.energy[name] - e)) <= 1e-12 * scale, name
    alone = simulate_batch(
        structures[3:],
        (0.0, 0.03),
        dt=2e-4,
        sample_dt=2e-3,
        initial=starts[3:],
        external_force=forces[3:],
        gravity=g,
    )[0]
    for name in ("q", "qdot", "tendon_tension"):
        np.testing.assert_array_equal(getattr(alone, name), getattr(batch[3], name), name)


def test_batch_rejects_what_it_cannot_do():
    a, b = class1_shell(3, 1), class1_shell(4, 1)
    with pytest.raises(ValueError, match=r"^structures\[1\]"):
        simulate_batch([a, b], (0, 0.01), dt=1e-4, sample_dt=1e-3)
    with pytest.raises(ValueError, match=r"^sample_dt"):
        simulate_batch([a], (0, 0.01), dt=1e-4, sample_dt=1.5e-4)
    with pytest.raises(ValueError, match=r"^t_span"):
        simulate_batch([a], (0, 0.01005), dt=1e-4, sample_dt=1e-3)
    with pytest.raises(ValueError, match=r"^external_force"):
        simulate_batch([a], (0, 0.01), dt=1e-4, sample_dt=1e-3, external_force=[None, None])


def test_plan_batches_small_shells_per_worker_and_large_ones_per_case():
    from tensegrity.sweep.run import BATCH_MAX_RODS, plan

    spec = SweepSpec({"n": [3, 25], "m": [1, 20], "stiffness": [50.0, 100.0, 150.0]})
    cases = spec.cases()
    tasks = plan(spec, cases, 2)
    assert sorted(i for idx, _ in tasks for i in idx) == list(range(len(cases)))
    by_size = {}
    for idx, batched in tasks:
        sizes = {(cases[i]["n"], cases[i]["m"]) for i in idx}
        assert batched and len(sizes) == 1
        by_size.setdefault(sizes.pop(), []).append(len(idx))
    # (3,1), (3,20), (25,1): 6, 120, 50 rods, one batch per worker; (25,20): 1000 rods, per case
    assert 2 * 25 * 20 == BATCH_MAX_RODS
    assert by_size == {(3, 1): [2, 1], (3, 20): [2, 1], (25, 1): [2, 1], (25, 20): [1, 1, 1]}
    adaptive = SweepSpec({"stiffness": [50.0, 100.0]}, method="DOP853")
    assert plan(adaptive, adaptive.cases(), 2) == [([0], False), ([1], False)]


def test_cli_sweep_from_a_spec_file(tmp_path, capsys):
    spec = tmp_path / "spec.json"
    spec.write_text(
        json.dumps(
            {
                "parameters": {"damping": [0.0, 1.0]},
                "t_end": 0.004,
                "sample_dt": 0.002,
                "dt": 0.0002,
            }
        )
    )
    out = tmp_path / "s.nc"
    assert main(["sweep", "--spec", str(spec), "--workers", "1", "-o", str(out)]) == 0
    assert "2 of 2 cases reached t_end" in capsys.readouterr().out
    ds = read_sweep(out)
    assert ds["damping"].values.tolist() == [0.0, 1.0] and np.all(ds["status"].values == 0)
    assert main(["sweep", "--spec", str(spec), "--t-end", "1", "-o", str(out)]) == 2
    assert main(["sweep", "--spec", str(tmp_path / "missing.json"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "--spec: cannot be combined" in err[0] and "missing.json" in err[1]


# ------------------------------------------------------------------------ structure-file sweeps
def prism_on_ground():
    """The 3-bar prism with its bottom triangle fixed (supports: not for the compiled kernel)."""
    from tensegrity.design import catalogue as generators

    s = generators.prism(3)
    z = s.node_position[:, 2]
    return s.replace(node_fixed=np.isclose(z, z.min(), rtol=0, atol=1e-12))


def structure_case(base, stiffness, load):
    """A structure sweep's case built here by hand: every tendon's stiffness set, the file's rest
    lengths and damping kept, the load split over the highest and the lowest nodes."""
    s = base.replace(tendon_stiffness=np.full(base.n_tendons, stiffness))
    if not load:
        return s, None
    z = s.node_position[:, 2]
    top, bottom = (
        np.isclose(z, z.max(), rtol=0, atol=1e-12),
        np.isclose(z, z.min(), rtol=0, atol=1e-12),
    )
    force = np.zeros((s.n_nodes, 3))
    force[top, 2] = -load / top.sum()
    force[bottom, 2] = load / bottom.sum()
    return s, force


@pytest.mark.parametrize("supported", [False, True], ids=["free prism", "prism on ground"])
def test_structure_sweep_cases_equal_direct_simulate(client, supported):
    from tensegrity.design import catalogue as generators

    base = prism_on_ground() if supported else generators.prism(4)
    spec = SweepSpec(
        {"stiffness": [60.0, 150.0], "load": [0.0, 4.0]},
        t_end=T_END,
        sample_dt=SAMPLE_DT,
        dt=DT,
        structure=base,
    )
    result = run_sweep(spec, client=client)
    ds = result.dataset
    assert result.success and ds.sizes["case"] == 4
    assert set(ds.coords) == {"case", "t", "stiffness", "load"}  # no n, m for a file
    # the compiled (batched) path takes the free prism only; the supported one runs simulate
    assert np.all(ds["batched"].values == (0 if supported else 1))
    for i in range(4):
        structure, force = structure_case(base, ds["stiffness"].values[i], ds["load"].values[i])
        ref = simulate(
            structure, (0.0, T_END), method="rk4", dt=DT, sample_dt=SAMPLE_DT, external_force=force
        )
        # The file's rest lengths are kept: unloaded, the prism stays at its equilibrium.
        moved = np.max(np.abs(ref.node_position[-1] - base.node_position))
        assert moved > 1e-6 if ds["load"].values[i] else moved < 1e-9
        assert ds["max_constraint_error"].values[i] == ref.max_constraint_error
        assert (ref.max_constraint_error > 0) == supported
        expected = direct_series(ref)
        energy_scale = np.max(expected["kinetic_energy"] + expected["elastic_energy"])
        for name, series in expected.items():
            got = ds[name].values[i]
            if supported:  # the same simulate call
                np.testing.assert_array_equal(got, series, err_msg=name)
            else:  # round-off: energies against the case's energy, lengths against a rod's
                scale = {
                    "kinetic_energy": energy_scale,
                    "elastic_energy": energy_scale,
                    "energy_error": energy_scale,
                    "max_displacement": base.rod_length[0],
                }.get(name, np.max(np.abs(series)))
                assert np.max(np.abs(got - series)) <= 1e-12 * scale, name
    assert "stiffness=60" in result.describe_case(0) and "n=" not in result.describe_case(0)


def test_structure_sweep_spec_forms_and_errors(tmp_path):
    from tensegrity.io.formats import write_structure

    base = prism_on_ground()
    with pytest.raises(
        ValueError,
        match=r"^parameters\.n: unknown parameter when sweeping a "
        r"structure file; choose from stiffness",
    ):
        SweepSpec({"n": [3, 4]}, structure=base)
    folder = tmp_path / "study"
    folder.mkdir()
    write_structure(folder / "prism.json", base)
    (folder / "spec.json").write_text(
        json.dumps(
            {"parameters": {"damping": [0.1, 0.2]}, "structure": "prism.json", "t_end": 0.01}
        )
    )
    spec = SweepSpec.from_file(folder / "spec.json")  # the path is relative to the spec file
    assert spec.structure.to_dict() == base.to_dict()
    assert spec.cases() == [{"damping": 0.1}, {"damping": 0.2}]
    again = SweepSpec.from_dict(json.loads(json.dumps(spec.to_dict())))  # structure inline
    assert again.structure.to_dict() == base.to_dict() and again.cases() == spec.cases()
    (folder / "bad.json").write_text(
        json.dumps({"parameters": {"damping": [0.1]}, "structure": "missing.json"})
    )
    with pytest.raises(ValueError, match=re.escape("missing.json")):
        SweepSpec.from_file(folder / "bad.json")


def test_cli_sweep_of_a_structure_file(tmp_path, capsys):
    from tensegrity.io.formats import write_structure

    path = tmp_path / "prism.json"
    write_structure(path, prism_on_ground())
    out = tmp_path / "s.nc"
    code = main(
        [
            "sweep",
            "--structure",
            str(path),
            "--param",
            "stiffness=50,100",
            "--t-end",
            "0.004",
            "--sample-dt",
            "0.002",
            "--dt",
            "0.0002",
            "--workers",
            "1",
            "-o",
            str(out),
        ]
    )
    assert code == 0 and "2 of 2 cases reached t_end" in capsys.readouterr().out
    ds = read_sweep(out)
    assert list(ds["stiffness"].values) == [50.0, 100.0] and "n" not in ds.coords
    assert (
        json.loads(ds.attrs["spec"])["structure"]["nodes"] == prism_on_ground().to_dict()["nodes"]
    )
    for args in (
        ["--structure", str(path), "--param", "n=3,4"],
        ["--structure", str(tmp_path / "missing.json"), "--param", "stiffness=50"],
        ["--structure", str(path), "--spec", str(path)],
    ):
        assert main(["sweep", *args, "-o", str(tmp_path / "x.nc")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and all(line.startswith("tensegrity: error:") for line in err)
    assert err[0].startswith("tensegrity: error: --param n: unknown parameter when sweeping a")
    assert "missing.json" in err[1] and "--spec" in err[2]
    assert not (tmp_path / "x.nc").exists()


FULL_DISK_CHILD = """
import resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG) instead
resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))  # files of at most 100 kB
from tensegrity.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def test_sweep_onto_a_full_disk_fails_in_one_line_and_leaves_nothing(tmp_path):
    """Writing the dataset fails part way (a file-size limit stands for a full disk): one line
    naming the file, exit code 2, no file left (before: pages of h5py tracebacks and a
    segmentation fault, exit code 139)."""
    import subprocess
    import sys

    out = tmp_path / "s.nc"
    args = ["sweep", "--param", "stiffness=100,200,300,400", "--param", "load=0,1,2"]
    args += ["--t-end", "0.5", "--workers", "1", "-o", str(out)]
    child = subprocess.run(
        [sys.executable, "-c", FULL_DISK_CHILD, *args], capture_output=True, text=True, timeout=300
    )
    assert child.returncode == 2, child.stderr[-2000:]
    assert child.stderr.strip().splitlines() == [f"tensegrity: error: {out}: File too large"], (
        child.stderr[-2000:]
    )
    assert list(tmp_path.iterdir()) == []


#: A child that runs ``tensegrity sweep ARGS`` and prints ``started`` once every case is sent to
#: the workers.
STARTED_CHILD = """
import signal, sys
signal.signal(signal.SIGINT, signal.default_int_handler)  # (a foreground job's, even if the
# tests run in a background job, whose SIGINT is ignored, and its children's with it)
import distributed
as_completed = distributed.as_completed
def announced(futures):
    print("started", flush=True)
    return as_completed(futures)
distributed.as_completed = announced
from tensegrity.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def test_ctrl_c_during_a_sweep_is_one_line_and_exit_130(tmp_path):
    """Ctrl-C reaches the terminal's whole process group, the local workers too: one line, exit
    code 130, nothing written (before: each worker printed the tracebacks of its interrupted
    event loop, 77 lines in all, and Dask logged warnings as it stopped them)."""
    import os
    import signal
    import subprocess
    import sys

    out = tmp_path / "s.nc"
    args = ["sweep", "--param", "stiffness=100,200,300,400", "--t-end", "200", "--workers", "2"]
    child = subprocess.Popen(
        [sys.executable, "-c", STARTED_CHILD, *args, "-o", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
    )
    try:
        assert child.stdout is not None and child.stdout.readline() == "started\n"
        time.sleep(1.0)  # the cases are running on the workers
        os.killpg(child.pid, signal.SIGINT)  # what Ctrl-C in a terminal does
        _, err = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
    assert child.returncode == 130, err[-2000:]
    assert err == "tensegrity: interrupted (nothing written)\n", err[-3000:]
    assert list(tmp_path.iterdir()) == []
