"""``tensegrity simulate`` with members by material and section (issue 18): ``--material``,
``--section`` and files in the material form build the structure; the summary reports the
members' largest utilisation over the run, recomputed here by hand from the trajectory's
tensions, and warns on stderr when a member exceeds its limits (exit code 0)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from tensegrity.cli.main import main
from tensegrity.design.files import write_design
from tensegrity.design.materials import Cable, MemberDesign, SolidRod, material
from tensegrity.design.utilisation import run_utilisation
from tensegrity.io.formats import read_structure
from tensegrity.io.trajectory import read_trajectory

RUN = ["--t-end", "0.2", "--sample-dt", "0.01", "--no-steady-state", "--damping", "none"]


def _steel_rods(structure, tendon_material, diameter: float) -> MemberDesign:
    """Steel rods of 10 mm, cables of ``tendon_material`` and ``diameter`` [m]."""
    return MemberDesign.of(
        structure,
        rod_material=material("steel"),
        rod_section=SolidRod(0.01),
        tendon_material=tendon_material,
        tendon_section=Cable(diameter),
    )


def _row(out: str, name: str) -> str:
    match = re.search(rf"^{name}\s+(.*)$", out, re.MULTILINE)
    assert match, out
    return match.group(1)


def test_weak_tendons_warn_and_equal_the_hand_stresses(tmp_path, capsys):
    """Nylon cables of 0.5 mm under a prism's 20 N prestress, its bottom nodes 0 and 1 pulled
    apart by a force table (a ramp to 5 N): every tendon yields.  The largest tendon
    utilisation printed (value, tendon, time) equals max T / (pi d^2/4) / sigma_y over the
    trajectory's tension samples, computed here from its formula; the rods' equals the
    library's run utilisation of the same trajectory with the same forces."""
    from tensegrity.design.catalogue import prism
    from tensegrity.model.loads import ForceTable

    s = prism()
    p = s.node_position
    pull = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0]) * 5.0
    force = np.zeros((2, s.n_nodes, 3))
    force[1, 0], force[1, 1] = -pull, pull
    table = tmp_path / "pull.npz"
    np.savez(table, time=np.array([0.0, 0.2]), force=force)
    out = tmp_path / "run"
    code = main(
        [
            "simulate",
            "--kind",
            "prism",
            "--set",
            "tension=20",
            "--material",
            "steel,nylon",
            "--section",
            "rod:10,cable:0.5",
            "--force-table",
            str(table),
            *RUN,
            "--out",
            str(out),
        ]
    )
    captured = capsys.readouterr()
    assert code == 0
    run = read_trajectory(out / "trajectory.h5")
    assert len(run.t) == 21
    stress = run.tendon_tension / (math.pi * 0.5e-3**2 / 4)
    ratio = stress / material("nylon").yield_strength
    sample, tendon = np.unravel_index(np.argmax(ratio), ratio.shape)
    assert np.ptp(run.tendon_tension[:, tendon]) > 0.01  # the tensions vary over the run
    name = run.structure.tendon_name[tendon]
    assert _row(captured.out, "largest tendon utilisation") == (
        f"yield {ratio[sample, tendon]:.4g} (tendon {name!r}, t = {run.t[sample]:.6g} s)"
    )
    failing = int(np.sum(ratio.max(axis=0) > 1))
    assert failing == 9
    warning = captured.err.strip()
    assert warning.startswith(f"tensegrity: warning: {failing} members beyond their limits")
    assert "\n" not in warning
    # rods: the library's run utilisation of the same file (steel rods, nothing near a limit)
    structure = read_structure(out / "structure.json")
    design = _steel_rods(structure, material("nylon"), 0.5e-3)
    w = ForceTable(np.array([0.0, 0.2]), force)
    u = run_utilisation(run, design.properties(structure), external_force=w)
    r = np.unravel_index(np.argmax(u.samples.rod_buckling), u.samples.rod_buckling.shape)
    assert _row(captured.out, "largest rod utilisation").startswith(
        f"buckling {u.samples.rod_buckling[r]:.4g} (rod {r[1]}, t = {u.t[r[0]]:.6g} s)"
    )


def test_material_options_keep_the_tensions_and_set_stiffness(tmp_path, capsys):
    out = tmp_path / "run"
    args = ["simulate", "--kind", "prism", *RUN, "--t-end", "0.01"]
    assert main([*args, "--out", str(tmp_path / "plain")]) == 0
    plain = read_structure(tmp_path / "plain" / "structure.json")
    assert "utilisation" not in capsys.readouterr().out  # no design: no report
    assert (
        main(
            [
                *args,
                "--material",
                "aluminium,steel",
                "--section",
                "tube:20:2,cable:1",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert "largest tendon utilisation" in capsys.readouterr().out
    s = read_structure(out / "structure.json")
    EA = material("steel").youngs_modulus * math.pi * 1e-3**2 / 4
    np.testing.assert_allclose(s.tendon_stiffness, EA / s.tendon_rest_length, rtol=1e-14)
    length = np.linalg.norm(np.diff(s.node_position[s.tendon_nodes], axis=1)[:, 0], axis=1)
    tension = s.tendon_stiffness * (length - s.tendon_rest_length)
    plain_tension = plain.tendon_stiffness * (length - plain.tendon_rest_length)
    np.testing.assert_allclose(tension, plain_tension, rtol=1e-9)
    tube = math.pi * (0.02**2 - 0.016**2) / 4
    np.testing.assert_allclose(s.rod_mass, 2700 * tube * s.rod_length, rtol=1e-14)


def test_a_material_form_file_is_simulated(tmp_path, capsys):
    """A prism written in the material form with rest lengths that keep its 20 N prestress
    (2 mm nylon cables): simulated from the file as given, it stays at its prestress and no
    member fails (largest tendon utilisation 30 N / A / sigma_y)."""
    from tensegrity.design.catalogue import prism

    base = prism(tension=20)
    design = _steel_rods(base, material("nylon"), 2e-3)
    structure = design.apply(base, keep_tension=True)
    path = write_design(tmp_path / "s.yaml", structure, design)
    out = tmp_path / "run"
    assert main(["simulate", "--structure", str(path), *RUN, "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    written = read_structure(out / "structure.json")
    assert written.to_dict() == structure.to_dict()
    largest = 30.0 / (math.pi * 2e-3**2 / 4) / material("nylon").yield_strength
    value = float(_row(captured.out, "largest tendon utilisation").split()[1])
    assert value == pytest.approx(largest, rel=1e-3)


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--material", "steel"], "--material: needs --section too"),
        (["--section", "rod:10,cable:1"], "--section: needs --material too"),
        (["--tendon-mass"], "--tendon-mass: only with --material and --section"),
        (
            ["--material", "stel", "--section", "rod:10,cable:1"],
            "--material stel: material: unknown 'stel'",
        ),
        (["--material", "steel", "--section", "rod:10"], "--section rod:10: expected ROD,TENDON"),
        (["--material", "steel", "--section", "cable:10,cable:1"], "a cable cannot be a rod"),
        (
            ["--material", "steel", "--section", "rod:10,cable:1", "--stiffness", "50"],
            "--stiffness: cannot be combined with --material",
        ),
    ],
)
def test_material_option_errors(tmp_path, capsys, options, message):
    out = tmp_path / "run"
    code = main(["simulate", "--kind", "shell", *RUN, *options, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and message in err and err.count("\n") == 1
    assert not out.exists()


def test_material_options_and_a_material_file_conflict(tmp_path, capsys):
    from tensegrity.design.catalogue import prism

    base = prism()
    design = _steel_rods(base, material("steel"), 1e-3)
    path = write_design(tmp_path / "s.toml", design.apply(base), design)
    code = main(
        ["simulate", "--structure", str(path), "--material", "steel", "--section", "rod:1,cable:1"]
    )
    assert code == 2
    assert "gives its members' materials and sections already" in capsys.readouterr().err
