"""Forces on named nodes (:class:`tensegrity.model.loads.NodalLoad`), constant or ramped in,
as the force table a run takes (:func:`nodal_load_table`, :func:`add_force_tables`), and
``tensegrity simulate --load NODE:FX,FY,FZ[@RAMP]``: the run under them comes to rest at the
equilibrium :func:`find_equilibrium` finds; the summary's utilisation includes them."""

from __future__ import annotations

import re

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism
from tensegrity.design.materials import Cable, MemberDesign, SolidRod, material
from tensegrity.design.utilisation import run_utilisation
from tensegrity.io.trajectory import read_trajectory
from tensegrity.model.loads import ForceTable, NodalLoad, add_force_tables, nodal_load_table
from tensegrity.physics.dynamics import internal_damping


def test_a_ramp_reaches_its_force_exactly_at_its_end_and_holds_it():
    s = prism(3).replace(node_name=["a", "b", "c", "top", "4", "f"])
    table = nodal_load_table(
        s,
        [
            NodalLoad("top", (0.0, 0.0, -6.0), ramp=0.5),
            NodalLoad(5, (1.0, 2.0, 3.0)),
            NodalLoad("top", (0.3, 0.0, 0.0), ramp=0.2),
        ],
    )
    for t, share_a, share_b in [(0, 0, 0), (0.1, 0.2, 0.5), (0.2, 0.4, 1), (0.25, 0.5, 1),
                                (0.5, 1, 1), (0.7, 1, 1), (100, 1, 1)]:  # fmt: skip
        w = table(t)
        np.testing.assert_allclose(w[3], [0.3 * share_b, 0, -6.0 * share_a], rtol=1e-15, atol=0)
        assert np.array_equal(w[5], [1.0, 2.0, 3.0])  # constant: from t = 0
        assert not np.any(w[[0, 1, 2, 4]])
    assert np.array_equal(table(0.5)[3], [0.3, 0.0, -6.0])  # exactly, at the ramp's end


def test_loads_add_to_a_force_table_exactly():
    s = prism(3)
    rng = np.random.default_rng(3)
    given = ForceTable([0.1, 0.3, 0.8], rng.normal(size=(3, 6, 3)))
    loads = nodal_load_table(s, [NodalLoad(2, (1.0, -1.0, 0.5), ramp=0.45)])
    both = add_force_tables(given, loads)
    for t in np.linspace(-0.2, 1.2, 57):
        np.testing.assert_allclose(both(t), given(t) + loads(t), rtol=1e-14, atol=1e-15)
    with pytest.raises(ValueError, match=r"^first: a table zero outside its times"):
        add_force_tables(ForceTable([0.0, 1.0], np.zeros((2, 6, 3)), "zero"), loads)


@pytest.mark.parametrize(
    ("load", "error", "message"),
    [
        (NodalLoad("x", (0, 0, 1)), KeyError, r"no node named 'x' \(the nodes are n0, n1"),
        (NodalLoad("6", (0, 0, 1)), KeyError, r"node 6 out of range \[0, 5\]"),
        (NodalLoad(1, (0, 1)), ValueError, r"^loads\[0\]\.force: expected 3 finite"),
        (NodalLoad(1, (0, 1, np.nan)), ValueError, r"^loads\[0\]\.force: expected 3 finite"),
        (NodalLoad(1, (0, 1, 0), ramp=-1.0), ValueError, r"^loads\[0\]\.ramp: must be finite"),
    ],
)
def test_bad_loads_name_the_load(load, error, message):
    with pytest.raises(error, match=message):
        nodal_load_table(prism(3), [load])


def test_a_fixed_base_prism_under_a_top_load_comes_to_rest_at_the_loaded_equilibrium():
    """A constant 3 N down on each top node of the fixed-base prism, damped to rest by
    simulation: the rest positions are the equilibrium find_equilibrium finds (to 1e-6 m; the
    top sinks by about 0.02 m)."""
    s = internal_damping(prism(3, fixed_base=True))
    loads = [NodalLoad(k, (0.0, 0.0, -3.0)) for k in (3, 4, 5)]
    table = nodal_load_table(s, loads)
    w = table(0.0)
    eq = find_equilibrium(s, external_force=w)
    assert eq.converged
    run = simulate(s, (0.0, 200.0), external_force=table, steady_state=True, rtol=1e-10,
                   atol=1e-12, sample_dt=0.5)  # fmt: skip
    assert run.status == 1, run.message  # at rest
    rest = run.node_position[-1]
    assert (
        np.ptp(s.node_position[3:, 2] - rest[3:, 2])
        < 1e-6
        < 0.01
        < np.min(s.node_position[3:, 2] - rest[3:, 2])
    )
    np.testing.assert_allclose(rest, eq.node_position, rtol=0, atol=1e-6)


def _row(out: str, name: str) -> str:
    match = re.search(rf"^{name}\s+(.*)$", out, re.MULTILINE)
    assert match, out
    return match.group(1)


def test_simulate_load_is_the_force_table_it_stands_for(tmp_path, capsys):
    """``--load`` and ``--force-table`` of the same forces give the same run and the same
    summary; the rods' utilisation printed is the library's with those forces; ``--load`` and
    ``--force-table`` together add up."""
    s = prism(3)
    loads = [NodalLoad(3, (0.0, 0.0, -4.0), ramp=0.1), NodalLoad("n4", (1.0, 0.0, 0.0))]
    table = nodal_load_table(s, loads)
    path = tmp_path / "w.npz"
    np.savez(path, time=table.time, force=table.force)
    half = tmp_path / "half.npz"
    np.savez(half, time=table.time, force=table.force / 2)
    common = ["simulate", "--kind", "prism", "--material", "steel,dyneema"]
    common += ["--section", "rod:10,cable:1", "--t-end", "0.2", "--sample-dt", "0.01"]
    common += ["--no-steady-state", "--no-view", "--no-animation"]
    runs = {
        "load": ["--load", "3:0,0,-4@0.1", "--load", "n4:1,0,0"],
        "table": ["--force-table", str(path)],
        "both": ["--force-table", str(half), "--load", "3:0,0,-2@0.1", "--load", "n4:0.5,0,0"],
    }
    outs = {}
    for name, options in runs.items():
        assert main([*common, *options, "--out", str(tmp_path / name)]) == 0
        outs[name] = capsys.readouterr().out
    got = {name: read_trajectory(tmp_path / name / "trajectory.h5") for name in runs}
    np.testing.assert_array_equal(got["load"].q, got["table"].q)
    np.testing.assert_allclose(got["both"].q, got["load"].q, rtol=0, atol=1e-12)
    design = MemberDesign.of(
        got["load"].structure,
        rod_material=material("steel"),
        rod_section=SolidRod(0.01),
        tendon_material=material("dyneema"),
        tendon_section=Cable(0.001),
    )
    u = run_utilisation(got["load"], design.properties(got["load"].structure), external_force=table)
    r = np.unravel_index(np.argmax(u.samples.rod_buckling), u.samples.rod_buckling.shape)
    for name in runs:
        assert _row(outs[name], "largest rod utilisation").startswith(
            f"buckling {u.samples.rod_buckling[r]:.4g} (rod {r[1]}, t = {u.t[r[0]]:.6g} s)"
        ), name


@pytest.mark.parametrize(
    ("load", "message"),
    [
        ("x:0,0,1", "--load x:0,0,1: no node named 'x' (the nodes are n0, n1, n2, n3, n4, ...)"),
        ("9:0,0,1", "--load 9:0,0,1: node 9 out of range [0, 5] (and no node is named '9')"),
        ("1:0,0", "--load 1:0,0: loads[0].force: expected 3 finite components"),
        ("1:0,0,1@-1", "argument --load: RAMP in '1:0,0,1@-1': must be >= 0"),
        ("1:0,0,z", "argument --load: expected NODE:FX,FY,FZ[@RAMP] with a node name or index"),
        ("1", "argument --load: expected NODE:FX,FY,FZ[@RAMP]"),
    ],
)
def test_simulate_load_errors_are_one_line(tmp_path, capsys, load, message):
    out = tmp_path / "out"
    assert main(["simulate", "--kind", "prism", "--load", load, "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.err.startswith("tensegrity: error: ") and captured.err.count("\n") == 1
    assert message in captured.err, captured.err
    assert not out.exists()
