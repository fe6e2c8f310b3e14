"""``tensegrity simulate --controller`` (issue 30): an LQR law designed by ``tensegrity lqr`` run
with actuator limits from the command line, its updates and saturations in the summary and in
the trajectory file, and the options' errors."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity.cli.main import main
from tensegrity.io.controllers import read_controller
from tensegrity.io.trajectory import read_trajectory


@pytest.fixture(scope="module")
def controller(tmp_path_factory):
    out = tmp_path_factory.mktemp("lqr")
    assert main(["lqr", "--kind", "prism", "--period", "0.005", "--out", str(out)]) == 0
    return out / "controller.npz"


def test_an_lqr_law_runs_with_actuator_limits_and_its_updates_are_stored(
    controller, tmp_path, capsys
):
    out = tmp_path / "run"
    argv = ["simulate", "--kind", "prism", "--t-end", "0.5", "--controller", str(controller),
            "--rest-range", "0.99:1.01", "--max-rate", "0.05", "--lag", "0.01", "--no-view",
            "--load", "3:0,0,-50", "--no-steady-state", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "control updates                   100 updates of 9 actuated tendons" in text
    run = read_trajectory(out / "trajectory.h5")
    law = read_controller(controller)
    assert run.control_tendons == law.tendons
    assert np.allclose(run.control_time, np.arange(100) * 0.005)
    rest0 = run.structure.tendon_rest_length
    # the commands held stay within the rest-length range, and follow the law where inside it
    low, high = rest0 - 1.01 * rest0, rest0 - 0.99 * rest0
    assert np.all(run.control_command >= low - 1e-15) and np.all(run.control_command <= high)
    assert run.settings["actuators"]["max_rate"] == [0.05] * 9
    assert np.abs(run.control_command).max() > 0  # (the load moved it: the law acted)
    bound = [x for x in run.saturations() if x.kind == "bound"]
    assert bound and "saturated at a rest-length bound" in text
    assert np.any(np.isclose(run.control_command, low) | np.isclose(run.control_command, high))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--max-rate", "0.1"], "--max-rate: limits the actuators of a --controller; give one"),
        (["--rest-range", "1.2:1.5"], "--rest-range: need 0 <= LOW <= 1 <= HIGH"),
        (["--controller", "missing.npz"], "--controller: "),
    ],
)
def test_controller_options_errors_are_one_line(tmp_path, capsys, argv, message):
    code = main(["simulate", "--kind", "prism", "--t-end", "0.1", "--out", str(tmp_path / "o"),
                 *argv])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1, err
    assert not (tmp_path / "o").exists()


def test_a_controller_for_another_structure_is_refused(controller, tmp_path, capsys):
    code = main(["simulate", "--kind", "shell", "--n", "3", "--m", "1", "--t-end", "0.1",
                 "--controller", str(controller), "--out", str(tmp_path / "o")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and err.startswith("tensegrity: error: --controller: "), err
    assert err.count("\n") == 1


def test_the_example_script_tracks_a_shape_and_regulates_a_load_through_limited_actuators(
    tmp_path,
):
    """``examples/lqr_with_actuator_limits.sh``: the shell's shape reached through actuators
    whose rate limit is reached; the prism standing under its load is held (before, the free
    prism under 50 N flew off at 34 m/s), and its run stores its updates and saturations."""
    import json
    import shutil
    import subprocess
    from pathlib import Path

    script = Path(__file__).parents[1] / "examples" / "lqr_with_actuator_limits.sh"
    shell = shutil.which("sh")
    assert shell is not None
    done = subprocess.run(
        [shell, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr
    closed = json.loads((tmp_path / "shape-control" / "control.json").read_text())["closed_loop"]
    assert closed["reached"] and closed["saturated"]
    assert closed["actuators"] == {"max_rate_m_per_s": 0.2, "lag_s": 0.005}
    run = read_trajectory(tmp_path / "prism-run" / "trajectory.h5")
    assert run.control_time.size == 400 and run.success
    assert np.abs(run.node_velocity[-1]).max() < 0.01  # (measured 2.7e-3 m/s)
    kinds = {x.kind for x in run.saturations()}
    assert kinds == {"bound", "rate"}
    rate = np.abs(np.diff(run.control_applied, axis=0)) / np.diff(run.control_time)[:, None]
    assert rate.max() <= 0.05 * (1 + 1e-9)
