"""A run's stop condition (``simulate(stop=...)``, the engine's :class:`StopCondition`): it
sees every sample once, in order, and ends the run at the first one it names a reason for
(status 2), for every method and for streamed runs; the samples up to there are the unstopped
run's.  Its use for design (issue 18): ``stop_at_failure`` stops at the first sample where a
member's utilisation, computed independently from an unstopped run, exceeds 1, and
``tensegrity simulate --stop-on-failure`` does so from the shell."""

from __future__ import annotations

import re

import numpy as np
import pytest

from tensegrity import class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism
from tensegrity.design.materials import Cable, MemberDesign, SolidRod, material
from tensegrity.design.utilisation import run_utilisation, stop_at_failure
from tensegrity.engine.result import STATUS_STOPPED
from tensegrity.io.stream import simulate_to_file
from tensegrity.io.trajectory import read_trajectory
from tensegrity.model.loads import ForceTable

SHELL = class1_shell(3, 1, damping=0.3)
METHODS = [dict(method="DOP853"), dict(method="rk4", dt=1e-3), dict(method="RK45")]


class StopAfter:
    """Stops at the first sample at or after ``time`` [s]; keeps the times it was shown."""

    def __init__(self, time: float) -> None:
        self.time, self.seen = time, []

    def __call__(self, sample):
        assert len(sample.t) == 1 and sample.q.shape == (1, SHELL.n_coordinates)
        self.seen.append(float(sample.t[0]))
        return "its time came" if sample.t[0] >= self.time - 1e-12 else None


@pytest.mark.parametrize("options", METHODS, ids=lambda o: o["method"])
def test_the_run_ends_at_the_first_sample_the_condition_names(options):
    full = simulate(SHELL, (0.0, 0.1), sample_dt=0.01, **options)
    stop = StopAfter(0.05)
    r = simulate(SHELL, (0.0, 0.1), sample_dt=0.01, stop=stop, **options)
    assert r.status == STATUS_STOPPED and r.success
    assert r.message == "stopped at t = 0.05 s: its time came"
    np.testing.assert_allclose(r.t, np.arange(6) * 0.01, atol=1e-12)
    assert stop.seen == pytest.approx(list(r.t), abs=0)  # every sample once, in order
    np.testing.assert_array_equal(r.node_position, full.node_position[:6])
    np.testing.assert_array_equal(r.tendon_tension, full.tendon_tension[:6])


def test_a_condition_true_at_the_start_leaves_one_sample():
    r = simulate(SHELL, (0.0, 0.1), stop=lambda sample: "at once")
    assert r.status == STATUS_STOPPED and len(r.t) == 1 and r.t[0] == 0.0
    assert r.nsteps == 0 and r.message == "stopped at t = 0 s: at once"


def test_a_streamed_run_stops_in_a_later_segment_and_its_file_says_so(tmp_path):
    path = tmp_path / "run.h5"
    summary = simulate_to_file(
        SHELL, (0.0, 0.1), path, segment=0.02, sample_dt=0.01, stop=StopAfter(0.05)
    )
    assert summary.status == STATUS_STOPPED and summary.n_samples == 6
    run = read_trajectory(path)
    assert run.status == STATUS_STOPPED and run.message.startswith("stopped at t = 0.05 s")
    # (the same streamed run unstopped: its steps end at the same checkpoints)
    simulate_to_file(SHELL, (0.0, 0.1), tmp_path / "full.h5", segment=0.02, sample_dt=0.01)
    np.testing.assert_array_equal(run.q, read_trajectory(tmp_path / "full.h5").q[:6])


# ----------------------------------------------------------------------------- design
def _designed_prism(rod_diameter: float, tendon: str, tendon_diameter: float):
    """A prism of 20 N prestress with solid steel rods and ``tendon`` cables (diameters [m]),
    the tensions kept: the structure and its members' properties."""
    design = MemberDesign.of(
        prism(tension=20.0),
        rod_material=material("steel"),
        rod_section=SolidRod(rod_diameter),
        tendon_material=material(tendon),
        tendon_section=Cable(tendon_diameter),
    )
    structure = design.apply(prism(tension=20.0), keep_tension=True)
    return structure, design.properties(structure)


def _pulled_prism():
    """A prism (20 N prestress) of steel rods and 0.8 mm nylon cables (utilisation 0.93 at the
    start) whose bottom nodes 0 and 1 are pulled apart by a force ramp to 20 N over 0.2 s: a
    tendon yields near the end."""
    structure, members = _designed_prism(0.01, "nylon", 0.8e-3)
    p = structure.node_position
    pull = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0]) * 20.0
    force = np.zeros((2, structure.n_nodes, 3))
    force[1, 0], force[1, 1] = -pull, pull
    return structure, members, ForceTable(np.array([0.0, 0.2]), force)


def test_stop_at_failure_stops_where_the_utilisation_first_exceeds_one():
    structure, members, force = _pulled_prism()
    options = dict(sample_dt=0.005, external_force=force)
    full = simulate(structure, (0.0, 0.2), **options)
    u = run_utilisation(full, members, external_force=force)
    largest = np.maximum(u.samples.tendon.max(axis=1), u.samples.rod.max(axis=1))
    first = int(np.argmax(largest > 1))
    assert 0 < first < len(full.t) - 1  # the failure is inside the run, not at its start
    r = simulate(
        structure, (0.0, 0.2), stop=stop_at_failure(structure, members, external_force=force),
        **options,
    )  # fmt: skip
    assert r.status == STATUS_STOPPED and len(r.t) == first + 1
    worst = structure.tendon_name[int(np.argmax(u.samples.tendon[first]))]
    assert re.fullmatch(
        rf"stopped at t = {full.t[first]:.6g} s: tendon {worst!r} over its limits "
        rf"\(utilisation {u.samples.tendon[first].max():.3g}: yield\)",
        r.message,
    ), r.message


def test_stop_at_failure_names_a_buckling_rod_with_the_safety_factor():
    # The same prism with 5 mm steel rods and strong steel cables: its rods at 0.64 of their
    # Euler load, no tendon near its limit; with a safety factor of 10 the rods buckle at once.
    structure, members = _designed_prism(0.005, "steel", 2e-3)
    assert (
        simulate(structure, (0.0, 0.01), stop=stop_at_failure(structure, members)).status == 0
    )  # (the factor 1: the rods hold)
    r = simulate(structure, (0.0, 0.01), stop=stop_at_failure(structure, members, safety_factor=10))
    assert r.status == STATUS_STOPPED and len(r.t) == 1
    reason = r"rod \d over its limits \(utilisation [\d.]+: buckling\)"
    assert re.fullmatch(rf"stopped at t = 0 s: {reason}", r.message), r.message


# ----------------------------------------------------------------------------- CLI
def _cli_pulled_prism(tmp_path, *extra):
    from tensegrity.design.catalogue import prism as make

    s = make()
    p = s.node_position
    pull = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0]) * 20.0
    force = np.zeros((2, s.n_nodes, 3))
    force[1, 0], force[1, 1] = -pull, pull
    tmp_path.mkdir(parents=True, exist_ok=True)
    table = tmp_path / "pull.npz"
    np.savez(table, time=np.array([0.0, 0.2]), force=force)
    out = tmp_path / "run"
    args = ["simulate", "--kind", "prism", "--set", "tension=20", "--material", "steel,nylon",
            "--section", "rod:10,cable:0.8", "--force-table", str(table), "--t-end", "0.2",
            "--sample-dt", "0.01", "--no-steady-state", "--damping", "none", "--out", str(out),
            *extra]  # fmt: skip
    return main(args), out


def test_cli_stop_on_failure_ends_the_run_at_the_failing_sample(tmp_path, capsys):
    code, out = _cli_pulled_prism(tmp_path)
    assert code == 0
    full = read_trajectory(out / "trajectory.h5")
    capsys.readouterr()
    code, out = _cli_pulled_prism(tmp_path / "stopped", "--stop-on-failure")
    printed = capsys.readouterr().out
    assert code == 0
    run = read_trajectory(out / "trajectory.h5")
    assert run.status == STATUS_STOPPED and 1 < len(run.t) < len(full.t)
    np.testing.assert_array_equal(run.tendon_tension, full.tendon_tension[: len(run.t)])
    assert re.search(r"^status\s+stopped at t = [\d.]+ s: tendon '.*' over its limits", printed,
                     re.MULTILINE), printed  # fmt: skip
    # its last sample is the first whose tendon stress exceeds the yield strength
    ratio = full.tendon_tension / (np.pi * 0.8e-3**2 / 4) / material("nylon").yield_strength
    assert int(np.argmax(ratio.max(axis=1) > 1)) == len(run.t) - 1


@pytest.mark.parametrize("option", [["--stop-on-failure"], ["--safety-factor", "2"]])
def test_cli_design_checks_need_a_design(tmp_path, capsys, option):
    code = main(["simulate", "--t-end", "0.01", "--out", str(tmp_path / "x"), *option])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert f"{option[0]}: needs members with a design" in err
    assert not (tmp_path / "x").exists()


def test_cli_safety_factor_divides_the_euler_load_in_the_report(tmp_path, capsys):
    rows = []
    for factor in ("1", "4"):
        code, _ = _cli_pulled_prism(tmp_path / factor, "--safety-factor", factor)
        assert code == 0
        line = re.search(r"^largest rod utilisation\s+(.*)$", capsys.readouterr().out, re.M)
        assert line, "no rod utilisation row"
        rows.append(float(re.match(r"buckling ([\d.e+-]+)", line.group(1)).group(1)))
    assert rows[1] == pytest.approx(4 * rows[0], rel=1e-3)
