"""Feedback design on the part of the linear model the rest-length inputs reach
(:mod:`tensegrity.analysis.control_design`), the controller file
(:mod:`tensegrity.io.controllers`) and ``tensegrity lqr``.

Evidence independent of the design code: ``control.lqr`` on the whole linearization (it fails);
the eigenvalues of the whole linear model closed with the node-coordinate gain (``numpy``'s
``eigvals`` of ``A - B K C``, no reduction); the modes' PBH test; the file read back.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from tensegrity.analysis.control_design import lqr, place, reachable
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.linearize import Linearization, linearize
from tensegrity.cli.main import main
from tensegrity.design.catalogue import generate
from tensegrity.io.controllers import read_controller, write_controller
from tensegrity.physics.dynamics import internal_damping

control = pytest.importorskip("control")

#: The (3,1) class 1 shell's mode that no rest-length change moves (tensegrity modes: mode 9).
SHELL_UNREACHED_HZ = 3.2356


@functools.cache
def _linear(kind: str, damped: bool = False) -> Linearization:
    """The linearization of the (3,1) shell or the 3-bar prism at its equilibrium."""
    s = generate("shell", n=3, m=1) if kind == "shell" else generate("prism", n=3)
    if damped:
        s = internal_damping(s)
    return linearize(s, find_equilibrium(s))


def _closed_full(lin: Linearization, feedback) -> np.ndarray:
    """``A - B K C_y`` of the whole model (2k, 2k): the law on node positions and velocities,
    ``y - y_ref = [J eta, J eta']``."""
    k = lin.n_dof
    J = lin.position_jacobian
    Cy = np.zeros((2 * J.shape[0], 2 * k))
    Cy[: J.shape[0], :k], Cy[J.shape[0] :, k:] = J, J
    cols = lin.input_indices(list(feedback.tendons))
    return lin.A - lin.B[:, cols] @ feedback.K @ Cy


@pytest.mark.parametrize("kind", ["shell", "prism"])
def test_lqr_fails_on_the_whole_model_and_succeeds_on_the_reduced_one(kind):
    lin = _linear(kind)
    full = lin.statespace()
    n, m = full.nstates, full.ninputs
    with pytest.raises((ValueError, np.linalg.LinAlgError)):
        control.lqr(full, np.eye(n), np.eye(m))
    model = reachable(lin)
    assert model.system.nstates < n
    design = lqr(model, period=0.002)
    assert np.all(design.closed_loop_poles.real < 0)
    assert design.slowest_decay > 0
    # the same as control.lqr with the same weights on the reduced StateSpace
    r = model.system.nstates
    K, _, _ = control.lqr(model.system, np.eye(r), np.eye(m))
    assert np.all(np.linalg.eigvals(model.system.A - model.system.B @ K).real < 0)


@pytest.mark.parametrize(
    ("kind", "damped", "inputs"),
    [
        ("shell", False, "all"),
        ("shell", True, "t1_*"),
        ("prism", True, "all"),
        ("prism", True, "b0"),  # the damping couples 3 modes b0 does not move: kept
        ("prism", True, "s0"),  # 4 modes left out
    ],
)
def test_reduced_closed_loop_is_the_whole_closed_loop_on_the_reachable_part(kind, damped, inputs):
    lin = _linear(kind, damped)
    model = reachable(lin, inputs)
    if inputs == "b0":
        assert model.damping_moved == (8, 10, 13)
    design = lqr(model, period=0.01)
    A_cl = _closed_full(lin, design.feedback)
    k, r = lin.n_dof, model.shapes.shape[1]
    T = np.zeros((2 * k, 2 * r))
    T[:k, :r], T[k:, r:] = model.shapes, model.shapes
    P = np.zeros((2 * r, 2 * k))
    P[:r, :k], P[r:, k:] = model.projection, model.projection
    restricted = P @ A_cl @ T
    reduced = np.asarray(model.system.A) - np.asarray(model.system.B) @ design.gain
    scale = np.abs(reduced).max()
    assert np.abs(restricted - reduced).max() <= 1e-6 * scale
    assert np.abs(A_cl @ T - T @ restricted).max() <= 1e-6 * scale  # an invariant subspace
    # every reduced closed-loop pole is an eigenvalue of the whole closed loop
    whole = np.linalg.eigvals(A_cl)
    for pole in design.closed_loop_poles:
        assert np.min(np.abs(whole - pole)) <= 1e-6 * abs(pole)
    # rigid-body motions at the equilibrium do not change the control
    position_gain = design.feedback.K[:, : lin.position_jacobian.shape[0]]
    rigid_nodes = lin.position_jacobian @ lin.rigid_basis
    assert np.abs(position_gain @ rigid_nodes).max() <= 1e-8 * np.abs(position_gain).max()


@pytest.mark.parametrize(
    ("kind", "options"), [("shell", {"n": 3, "m": 1, "fixed_base": True}), ("planar", {})]
)
def test_supported_and_planar_structures(kind, options):
    """Joints and supports (``eta`` the admitted motions) and a planar structure (its node
    outputs x, y): the law on the structure's own node coordinates closes the loop of the whole
    model with the reduced model's poles."""
    s = generate(kind, **options)
    lin = linearize(s, find_equilibrium(s))
    design = lqr(reachable(lin), period=0.01)
    assert design.feedback.check(s).size == s.n_tendons
    k, dim = lin.n_dof, s.dim
    J = lin.position_jacobian.reshape(-1, 3, k)[:, :dim].reshape(-1, k)
    Cy = np.zeros((2 * J.shape[0], 2 * k))
    Cy[: J.shape[0], :k], Cy[J.shape[0] :, k:] = J, J
    whole = np.linalg.eigvals(lin.A - lin.B @ design.feedback.K @ Cy)
    assert np.all(design.closed_loop_poles.real < 0)
    for pole in design.closed_loop_poles:
        assert np.min(np.abs(whole - pole)) <= 1e-6 * abs(pole)


def test_feedback_reads_node_positions_about_the_equilibrium():
    lin = _linear("prism")
    design = lqr(reachable(lin), period=0.005)
    fb = design.feedback
    assert fb.outputs == ("position", "velocity")
    assert fb.tendons == lin.structure.tendon_name
    assert fb.period == 0.005
    np.testing.assert_array_equal(fb.y_ref[:18], lin.equilibrium.node_position.ravel())
    np.testing.assert_array_equal(fb.y_ref[18:], 0.0)
    np.testing.assert_array_equal(fb.u_ref, lin.equilibrium.control)


@pytest.mark.parametrize("kind", ["shell", "prism"])
def test_pole_placement_puts_the_poles_where_asked(kind):
    lin = _linear(kind)
    model = reachable(lin)
    r = model.shapes.shape[1]
    wanted = -np.linspace(2.0, 20.0, 2 * r)
    design = place(model, wanted, period=0.002)
    np.testing.assert_allclose(np.sort(design.closed_loop_poles.real), np.sort(wanted), rtol=1e-6)
    np.testing.assert_allclose(design.closed_loop_poles.imag, 0.0, atol=1e-6)
    whole = np.linalg.eigvals(_closed_full(lin, design.feedback))
    for pole in wanted:
        assert np.min(np.abs(whole - pole)) <= 1e-6 * abs(pole)
    with pytest.raises(ValueError, match="poles"):
        place(model, wanted[:-1], period=0.002)


def test_the_shells_unreached_mode_is_left_out_with_its_reason():
    lin = _linear("shell")
    model = reachable(lin)
    left = [m for m in model.left_out if m.kind != "rigid"]
    assert [m.mode for m in left] == [9]
    assert left[0].frequency_hz == pytest.approx(SHELL_UNREACHED_HZ, abs=5e-4)
    assert "changes no tendon length" in left[0].reason
    assert sum(m.kind == "rigid" for m in model.left_out) == 6
    assert model.system.nstates == 2 * (30 - 6 - 1)
    assert not any(name.startswith("mode9_") for name in model.system.state_labels)
    assert "mode6_2129mHz" in model.system.state_labels
    # the PBH test agrees: mode 9 changes no tendon length
    v = model.modes.shapes[:, 9]
    assert np.linalg.norm(lin.equilibrium_matrix.T @ v) < 1e-8
    design = lqr(model, period=0.002)
    assert [m.mode for m in design.uncontrolled if m.kind != "rigid"] == [9]
    # the prism: every non-rigid mode is reached
    assert [m for m in reachable(_linear("prism")).left_out if m.kind != "rigid"] == []


def test_controller_file_round_trips(tmp_path):
    lin = _linear("shell")
    design = lqr(reachable(lin, "t1_*"), period=0.004)
    path = write_controller(tmp_path / "gains.npz", design.feedback, lin.structure)
    back = read_controller(path)
    for field in ("K", "y_ref", "u_ref"):
        np.testing.assert_array_equal(getattr(back, field), getattr(design.feedback, field))
    assert back.period == 0.004
    assert back.outputs == ("position", "velocity")
    assert back.tendons == design.model.tendons
    assert [p.name for p in tmp_path.iterdir()] == ["gains.npz"]


def _fields(path):
    with np.load(path) as archive:
        return {name: archive[name] for name in archive.files}


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda d: d.pop("period"), "period"),
        (lambda d: d.update(K=d["K"][:, :-1]), "K"),
        (lambda d: d.update(period=np.array("fast")), "period"),
        (lambda d: d.update(period=np.array([0.1, 0.2])), "period"),
        (lambda d: d.update(outputs=np.array(["speed"])), "outputs"),
        (lambda d: d.update(u_ref=np.array([np.nan] * d["u_ref"].size)), "u_ref"),
    ],
)
def test_a_bad_controller_file_is_a_one_line_error(tmp_path, change, field):
    s = generate("prism", n=3)
    from tensegrity.engine.feedback import LinearFeedback

    good = write_controller(tmp_path / "good.npz", LinearFeedback.zero(s, 0.01), s)
    data = _fields(good)
    change(data)
    bad = tmp_path / "bad.npz"
    np.savez(bad, **data)
    with pytest.raises(ValueError) as info:
        read_controller(bad)
    message = str(info.value)
    assert message.startswith(str(bad)) and "\n" not in message
    assert field in message
    (tmp_path / "text.npz").write_text("not a zip")
    with pytest.raises(ValueError, match=r"text\.npz: not a NumPy \.npz archive"):
        read_controller(tmp_path / "text.npz")


def test_cli_lqr_writes_a_controller_file(tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["lqr", "--kind", "shell", "--n", "3", "--m", "1", "--period", "0.002"]
    code = main([*argv, "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == [".lqr-outputs", "controller.npz", "lqr.json"]
    feedback = read_controller(out / "controller.npz")
    s = generate("shell", n=3, m=1)
    assert feedback.check(s).tolist() == list(range(s.n_tendons))
    assert feedback.period == 0.002
    design = lqr(reachable(_linear("shell")), period=0.002)
    np.testing.assert_allclose(feedback.K, design.feedback.K, rtol=1e-9, atol=1e-12)
    assert f"{design.slowest_decay:.6g} 1/s" in printed
    assert "3.23558" in printed


def test_cli_lqr_bad_input_is_one_line(tmp_path, capsys):
    out = tmp_path / "out"
    for argv, message in [
        (["--period", "0"], "tensegrity: error: lqr: argument --period: must be > 0, got '0'"),
        (["--period", "0.01", "--inputs", "zz*"], "tensegrity: error: no tendon matches 'zz*'"),
    ]:
        code = main(["lqr", "--kind", "prism", "--out", str(out), *argv])
        assert code == 2
        assert capsys.readouterr().err.splitlines() == [message]
        assert not out.exists()
