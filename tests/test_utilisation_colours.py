"""Members coloured by utilisation (issue 18): the viewer page's per-frame utilisation
(plots.viewer, plots.motion.MemberCheck), the figure of each member's largest utilisation
(plots.figures.figure_utilisation) and ``tensegrity simulate``'s utilisation.png and view.html
with a design.  The page's numbers are recomputed here from the run's tensions, the rods' axial
forces and the materials and sections by their formulas; the browser's side is in
test_viewer_browser.py."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from tensegrity import simulate
from tensegrity.cli.main import main
from tensegrity.design.catalogue import prism
from tensegrity.design.materials import Cable, Factors, MemberDesign, SolidRod, material
from tensegrity.design.utilisation import rod_axial_forces
from tensegrity.io.trajectory import read_trajectory
from tensegrity.model.loads import ForceTable
from tensegrity.plots.figures import (
    FAILURE_COLOR,
    figure_utilisation,
    save_png,
    tension_colormap,
    utilisation_colors,
)
from tensegrity.plots.motion import MemberCheck
from tensegrity.plots.viewer import html, read_viewer_data

ROD_D, CABLE_D = 5e-3, 0.6e-3  # steel rods, nylon cables [m]
PULL = 8.0  # [N], pulling the bottom nodes 0 and 1 apart


def design_of(structure) -> MemberDesign:
    """Steel rods of 5 mm, nylon cables of 0.6 mm."""
    return MemberDesign.of(
        structure,
        rod_material=material("steel"),
        rod_section=SolidRod(ROD_D),
        tendon_material=material("nylon"),
        tendon_section=Cable(CABLE_D),
    )


def designed_prism(t_end: float = 0.3):
    """A prism (20 N prestress) of 5 mm steel rods and 0.6 mm nylon cables, its nodes 0 and 1
    pulled apart by 8 N, under gravity: some tendons fail (utilisation 0.5 .. 1.8), the rods
    are at about 0.6.  The run, its check and the force table."""
    base = prism(tension=20)
    design = design_of(base)
    s = design.apply(base, keep_tension=True)
    p = s.node_position
    pull = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0]) * PULL
    force = np.zeros((2, s.n_nodes, 3))
    force[:, 0], force[:, 1] = -pull, pull
    w = ForceTable(np.array([0.0, 1.0]), force)
    run = simulate(s, (0.0, t_end), sample_dt=0.01, external_force=w, gravity=[0, 0, -9.81])
    return run, MemberCheck(design.properties(s), external_force=w), w


def by_hand(run, sample: int, w) -> tuple[np.ndarray, np.ndarray]:
    """The rods' and tendons' utilisation at ``sample`` from the formulas: tendons
    ``T / (pi d^2 / 4) / sigma_y``; rods the larger of ``|C| / (A sigma_y)`` and
    ``C / (pi^2 E I / L^2)``, ``C`` the rod's axial force."""
    s = run.structure
    steel, nylon = material("steel"), material("nylon")
    tendon = run.tendon_tension[sample] / (math.pi * CABLE_D**2 / 4) / nylon.yield_strength
    C = rod_axial_forces(
        s,
        run.q[sample],
        run.tendon_tension[sample],
        qdot=run.qdot[sample],
        external_force=w(run.t[sample]),
        gravity=np.array([0, 0, -9.81]),
    )
    area, second = math.pi * ROD_D**2 / 4, math.pi * ROD_D**4 / 64
    euler = math.pi**2 * steel.youngs_modulus * second / s.rod_length**2
    rod = np.maximum(np.abs(C) / (area * steel.yield_strength), np.maximum(C, 0) / euler)
    return rod, tendon


@pytest.fixture(scope="module")
def run_and_check():
    return designed_prism()


def test_page_utilisation_is_the_members_to_float32(run_and_check):
    run, check, w = run_and_check
    data = read_viewer_data(html(run, check=check, max_frames=12))
    u = data["utilisation"]
    assert u["rods"].dtype == np.float32 and u["rods"].shape == (12, 3)
    assert u["tendons"].shape == (12, 9)
    everywhere = []
    for frame in range(12):
        rod, tendon = by_hand(run, data["sample_index"][frame], w)
        np.testing.assert_allclose(u["rods"][frame], rod, rtol=2e-7)
        np.testing.assert_allclose(u["tendons"][frame], tendon, rtol=2e-7)
        everywhere += [rod.max(), tendon.max()]
    assert 0.3 < u["rods"].min() and u["tendons"].max() > 1.2  # (the test means something)
    assert u["high"] == pytest.approx(max(everywhere), rel=1e-12)  # the scale's top: > 1 here
    assert data["colors"]["failure"] == FAILURE_COLOR


def test_the_scale_reaches_the_run_s_largest(run_and_check):
    """A run's largest known from more samples than the page shows raises the top; below 1
    the top is 1."""
    run, check, _ = run_and_check
    page = read_viewer_data(html(run, check=check._replace(largest=7.5), max_frames=3))
    assert page["utilisation"]["high"] == 7.5
    strong = check._replace(
        members=check.members._replace(tendon_yield=check.members.tendon_yield * 100)
    )
    assert read_viewer_data(html(run, check=strong, max_frames=3))["utilisation"]["high"] == 1.0


def test_a_run_without_a_design_gives_today_s_page(run_and_check):
    run, check, _ = run_and_check
    plain = html(run, max_frames=12)
    data = read_viewer_data(plain)
    assert "utilisation" not in data
    assert set(data["colors"]) == {"rod", "slack", "fixed", "joint"}
    designed = html(run, max_frames=12, check=check)
    # the same page but for the utilisation and the failure colour in its data
    same = read_viewer_data(designed)
    del same["utilisation"], same["colors"]["failure"]
    assert same.keys() == data.keys()
    for key in data:
        np.testing.assert_equal(same[key], data[key])
    with pytest.raises(ValueError, match="check"):
        html(run.structure, check=check)


def test_utilisation_colours_follow_the_scale_and_fail_above_one():
    colours = utilisation_colors(np.array([0.0, 0.5, 1.0, 1.0001, 3.0]), 2.0)
    cmap = tension_colormap()
    np.testing.assert_allclose(colours[:3], cmap(np.array([0.0, 0.25, 0.5])))
    np.testing.assert_allclose(colours[3:], [to_rgba(FAILURE_COLOR)] * 2)


def _magenta(picture: np.ndarray) -> np.ndarray:
    """Pixels of the failure colour (#ff00d4, antialiased edges aside)."""
    r, g, b = picture[..., 0], picture[..., 1], picture[..., 2]
    return (r > 220) & (g < 60) & (b > 170)


def test_the_figure_colours_members_by_utilisation(run_and_check, tmp_path):
    from PIL import Image

    run, _, _ = run_and_check
    s = run.structure
    rod = np.array([0.2, 1.4, 0.6])  # rod 1 fails
    tendon = np.linspace(0.0, 0.9, 9)
    figure = figure_utilisation(s, run.node_position[-1], rod, tendon)
    tendons, rods = figure.axes[0].collections[:2]
    np.testing.assert_allclose(rods.get_colors()[1], to_rgba(FAILURE_COLOR))
    np.testing.assert_allclose(rods.get_colors()[[0, 2]], tension_colormap()(rod[[0, 2]] / 1.4))
    np.testing.assert_allclose(tendons.get_colors(), tension_colormap()(tendon / 1.4))
    assert "failing, > 1 (1)" in [t.get_text() for t in figure.axes[0].get_legend().get_texts()]
    failing = np.asarray(Image.open(save_png(figure, tmp_path / "a.png", dpi=80)).convert("RGB"))
    # the failing rod and the colour bar's top are magenta; with no member above 1, nothing is
    safe = figure_utilisation(s, run.node_position[-1], np.minimum(rod, 0.9), tendon)
    none = np.asarray(Image.open(save_png(safe, tmp_path / "b.png", dpi=80)).convert("RGB"))
    assert _magenta(failing).sum() > 300
    assert _magenta(none).sum() == 0


ARGS = [
    "simulate",
    "--kind",
    "prism",
    "--set",
    "tension=20",
    "--t-end",
    "0.2",
    "--sample-dt",
    "0.01",
    "--no-steady-state",
    "--damping",
    "none",
    "--gravity",
    "9.81",
]


def test_simulate_with_a_design_writes_the_utilisation(tmp_path, capsys):
    from PIL import Image

    table = tmp_path / "pull.npz"
    base = prism(tension=20)
    p = base.node_position
    pull = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0]) * PULL
    force = np.zeros((2, base.n_nodes, 3))
    force[:, 0], force[:, 1] = -pull, pull
    np.savez(table, time=np.array([0.0, 1.0]), force=force)
    out = tmp_path / "designed"
    design = ["--material", "steel,nylon", "--section", "rod:5,cable:0.6"]
    assert main([*ARGS, *design, "--force-table", str(table), "--out", str(out)]) == 0
    capsys.readouterr()
    picture = np.asarray(Image.open(out / "utilisation.png").convert("RGB"))
    assert _magenta(picture).sum() > 300  # failing tendons (and the colour bar above 1)
    data = read_viewer_data((out / "view.html").read_text())
    run = read_trajectory(out / "trajectory.h5")
    w = ForceTable(np.array([0.0, 1.0]), force)
    for frame in (0, data["n_frames"] // 2, data["n_frames"] - 1):
        rod, tendon = by_hand(run, data["sample_index"][frame], w)
        np.testing.assert_allclose(data["utilisation"]["rods"][frame], rod, rtol=2e-7)
        np.testing.assert_allclose(data["utilisation"]["tendons"][frame], tendon, rtol=2e-7)
    assert data["utilisation"]["high"] > 1.2

    plain = tmp_path / "plain"
    assert main([*ARGS, "--out", str(plain)]) == 0
    assert not (plain / "utilisation.png").exists()
    assert (plain / "equilibrium.png").exists()
    assert "utilisation" not in read_viewer_data((plain / "view.html").read_text())


@pytest.fixture(scope="module")
def designed_run(tmp_path_factory):
    """The prism of :func:`design_of` in the material form, with factors 1.25 (safety) and 1.5
    (strength), simulated by ``tensegrity simulate --structure FILE``: the file and the run's
    folder."""
    from tensegrity.design.files import write_design

    folder = tmp_path_factory.mktemp("designed")
    base = prism(tension=20)
    design = dataclasses.replace(design_of(base), factors=Factors(1.25, 1.5))
    file = write_design(folder / "prism.yaml", design.apply(base, keep_tension=True), design)
    out = folder / "run"
    assert main([ARGS[0], "--structure", str(file), *ARGS[5:], "--out", str(out)]) == 0
    return file, out


def test_view_colours_a_trajectory_by_the_design_given(designed_run, tmp_path, capsys):
    """``tensegrity view --structure FILE``: the design of a structure file in the material form
    gives the page that ``simulate`` wrote; a file of another structure, or without materials,
    is refused."""
    from tensegrity.design.files import write_design
    from tensegrity.io.formats import write_structure

    file, out = designed_run
    written = read_viewer_data((out / "view.html").read_text())["utilisation"]
    page = tmp_path / "v.html"
    trajectory = str(out / "trajectory.h5")
    assert main(["view", trajectory, "-o", str(page), "--structure", str(file)]) == 0
    again = read_viewer_data(page.read_text())["utilisation"]
    np.testing.assert_array_equal(again["rods"], written["rods"])
    np.testing.assert_array_equal(again["tendons"], written["tendons"])
    assert again["high"] == written["high"] > 1
    capsys.readouterr()

    square = design_of(prism(4))
    other = write_design(tmp_path / "other.yaml", square.apply(prism(4)), square)
    plain = write_structure(tmp_path / "plain.json", prism(tension=20))
    for given, words in ((other, "is not the structure of"), (plain, "no materials")):
        assert main(["view", trajectory, "-o", str(page), "--structure", str(given)]) == 2
        assert words in capsys.readouterr().err


def test_view_colours_a_designed_run_with_no_option(designed_run, tmp_path, capsys):
    """``tensegrity view run/trajectory.h5`` of a designed run, no ``--structure``: the
    trajectory carries the design and its factors, and the page is coloured as the one
    ``simulate`` wrote.  A run without a design gives a page without utilisation, and the
    factor options are refused for it in one line."""
    _, out = designed_run
    written = read_viewer_data((out / "view.html").read_text())["utilisation"]
    page = tmp_path / "v.html"
    assert main(["view", str(out / "trajectory.h5"), "-o", str(page)]) == 0
    again = read_viewer_data(page.read_text())["utilisation"]
    np.testing.assert_array_equal(again["rods"], written["rods"])
    np.testing.assert_array_equal(again["tendons"], written["tendons"])
    assert again["high"] == written["high"] > 1

    plain = tmp_path / "plain"
    assert main([*ARGS, "--no-animation", "--out", str(plain)]) == 0
    assert main(["view", str(plain / "trajectory.h5"), "-o", str(page)]) == 0
    assert "utilisation" not in read_viewer_data(page.read_text())
    capsys.readouterr()
    code = main(["view", str(plain / "trajectory.h5"), "-o", str(page), "--safety-factor", "2"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--safety-factor: " in err


def test_a_designed_cli_run_s_trajectory_carries_its_design(designed_run):
    """The trajectory of ``simulate --structure FILE`` (streamed) holds the design of FILE:
    materials, sections (so areas), factors; the same as ``structure-material.json``."""
    from tensegrity.design.files import read_design, trajectory_design

    file, out = designed_run
    given = read_design(file).design
    structure, carried = trajectory_design(out / "trajectory.h5")
    assert carried == given == read_design(out / "structure-material.json").design
    assert carried is not None and carried.factors == Factors(1.25, 1.5)
    assert structure.to_dict() == read_trajectory(out / "trajectory.h5").structure.to_dict()
    np.testing.assert_array_equal(
        carried.properties(structure).tendon_area, np.full(9, math.pi * CABLE_D**2 / 4)
    )


def test_a_designed_run_writes_its_structure_by_material_for_view(tmp_path, capsys):
    """``simulate --material ... --section ...`` writes ``structure-material.json``: the run's
    structure in the material form (read back: the structure of ``structure.json`` and its
    design), with which ``tensegrity view --structure`` gives the page ``simulate`` wrote; a run
    without a design writes none."""
    from tensegrity.design.files import read_design
    from tensegrity.io.formats import read_structure

    out = tmp_path / "designed"
    design = ["--material", "steel,nylon", "--section", "rod:5,cable:0.6"]
    assert main([*ARGS, *design, "--out", str(out)]) == 0
    structure, members = read_design(out / "structure-material.json")
    plain = read_structure(out / "structure.json")
    assert members is not None
    for name in ("node_position", "rod_mass", "tendon_stiffness", "tendon_rest_length"):
        np.testing.assert_allclose(getattr(structure, name), getattr(plain, name), rtol=1e-14)
    page = tmp_path / "again.html"
    trajectory = str(out / "trajectory.h5")
    files = ["--structure", str(out / "structure-material.json")]
    assert main(["view", trajectory, "-o", str(page), *files]) == 0
    written = read_viewer_data((out / "view.html").read_text())["utilisation"]
    again = read_viewer_data(page.read_text())["utilisation"]
    np.testing.assert_array_equal(again["rods"], written["rods"])
    np.testing.assert_array_equal(again["tendons"], written["tendons"])
    assert main([*ARGS, "--out", str(tmp_path / "plain")]) == 0
    assert not (tmp_path / "plain" / "structure-material.json").exists()
    capsys.readouterr()
