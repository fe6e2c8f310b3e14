"""Figures: valid PNGs of sensible size, written atomically, slack tendons marked, no pyplot or
backend side effects."""

from __future__ import annotations

import struct

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.io.trajectory import read_trajectory, write_trajectory
from tensegrity.plots.figures import (
    draw_structure,
    figure_structure,
    figure_tendon_lengths,
    save_figures,
)

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def result():
    return simulate(artificial_damping(class1_shell(3, 1)), (0.0, 0.3), sample_dt=0.05)


def png_size(path):
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, f"{path} is not a PNG"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def legend_texts(ax):
    legend = ax.get_legend()
    return [] if legend is None else [t.get_text() for t in legend.get_texts()]


def test_save_figures_writes_three_sensible_pngs(tmp_path, result):
    backend = matplotlib.get_backend()
    out = tmp_path / "figs"  # created on demand
    paths = save_figures(result, out)
    assert [p.name for p in paths] == ["initial.png", "equilibrium.png", "tendon_lengths.png"]
    for path in paths:
        assert path.parent == out and path.stat().st_size > 10_000
        width, height = png_size(path)
        assert 600 <= width <= 3000 and 400 <= height <= 3000, (path.name, width, height)
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in paths)
    assert matplotlib.get_backend() == backend


def test_save_figures_accepts_a_trajectory_read_back(tmp_path, result):
    write_trajectory(tmp_path / "run.h5", result)
    paths = save_figures(read_trajectory(tmp_path / "run.h5"), tmp_path / "figs")
    assert all(png_size(p)[0] > 0 for p in paths)


def test_failed_figure_write_leaves_old_file_and_no_temp(tmp_path, result, monkeypatch):
    old = tmp_path / "initial.png"
    old.write_bytes(b"old")

    def failing_savefig(self, *args, **kwargs):
        raise RuntimeError("renderer failed")

    monkeypatch.setattr(Figure, "savefig", failing_savefig)
    with pytest.raises(RuntimeError, match="renderer failed"):
        save_figures(result, tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["initial.png"]
    assert old.read_bytes() == b"old"


def test_slack_tendons_are_marked_in_the_legend(result):
    s = result.structure
    tension = result.tendon_tension[-1].copy()
    tension[[1, 7]] = [0.0, -0.5]
    figure = figure_structure(s, result.node_position[-1], tension, title="slack")
    ax = figure.axes[0]
    texts = legend_texts(ax)
    assert "slack tendons (2)" in texts and f"taut tendons ({s.n_tendons - 2})" in texts
    png = figure_structure(s, result.node_position[-1], tension)
    assert isinstance(png, Figure)


def test_no_slack_entry_when_all_taut_and_equal_scales(result):
    s = result.structure
    figure = Figure()
    ax = figure.add_subplot(projection="3d")
    p = result.node_position[0]
    artists = draw_structure(ax, s, p, result.tendon_tension[0])
    texts = legend_texts(ax)
    assert artists["slack"] is None and not any("slack" in t for t in texts)
    assert artists["mappable"] is not None  # the initial tensions differ: coloured by tension
    figure.draw_without_rendering()  # projects the 3-D segments
    assert len(artists["rods"].get_segments()) == s.n_rods
    assert len(artists["tendons"].get_segments()) == s.n_tendons
    # equal scale: box aspect proportional to the axis ranges
    ranges = np.array([np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())])
    aspect = np.array(ax.get_box_aspect())
    assert np.allclose(aspect / aspect.max(), ranges / ranges.max(), rtol=1e-6)
    assert [ax.get_xlabel(), ax.get_ylabel(), ax.get_zlabel()] == ["x [m]", "y [m]", "z [m]"]


def test_structure_without_tension_and_bad_shapes(result):
    s = result.structure
    figure = figure_structure(s, s.node_position, title="layout")
    assert legend_texts(figure.axes[0]) == [f"rods ({s.n_rods})", f"tendons ({s.n_tendons})"]
    assert len(figure.axes) == 1  # no colour bar without tensions
    with pytest.raises(ValueError, match="node_position"):
        figure_structure(s, s.node_position[:-1])
    with pytest.raises(ValueError, match="tension"):
        figure_structure(s, s.node_position, np.ones(3))


def test_tendon_lengths_figure_labels_and_legends(result):
    t, lengths = result.t, result.tendon_length
    names = result.structure.tendon_name
    # few tendons: one legend entry each
    few = figure_tendon_lengths(t, lengths[:, :4], names[:4])
    ax = few.axes[0]
    assert legend_texts(ax) == list(names[:4])
    assert "[s]" in ax.get_xlabel() and "[m]" in ax.get_ylabel()
    assert len(ax.get_lines()) == 4
    # a shell's 24 tendons: one entry per family t1..t8
    shell = figure_tendon_lengths(
        t, lengths, names, rest_length=result.structure.tendon_rest_length
    )
    assert legend_texts(shell.axes[0]) == [f"t{a} (3)" for a in range(1, 9)]
    # many unrelated names: no legend, a note instead
    odd = [f"tendon-{k}" for k in range(len(names))]
    many = figure_tendon_lengths(t, lengths, odd)
    ax = many.axes[0]
    assert ax.get_legend() is None
    assert any(f"{len(names)} tendons" in text.get_text() for text in ax.texts)
    with pytest.raises(ValueError, match="tendon_length"):
        figure_tendon_lengths(t, lengths, names[:3])


@pytest.mark.parametrize("tendons", [1, 0], ids=["every-tendon-slack", "no-tendons"])
def test_figures_of_a_structure_without_taut_tendons(tmp_path, tendons):
    """Two rods drifting together: their one tendon (if any) goes slack; the figures are still
    drawn, the slack tendon marked, and no empty set of taut tendons is drawn."""
    from tensegrity import Structure

    structure = Structure(
        node_position=[[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]],
        node_velocity=[[0, 0.5, 0], [0, 0.5, 0], [0, -0.5, 0], [0, -0.5, 0]],
        rod_nodes=[[0, 1], [2, 3]],
        rod_mass=[1.0, 1.0],
        rod_length=[1.0, 1.0],
        tendon_nodes=[[0, 2]][:tendons],
        tendon_stiffness=[10.0][:tendons],
        tendon_rest_length=[0.9][:tendons],
    )
    r = simulate(structure, (0.0, 0.5), sample_dt=0.05)
    assert r.status == 0, r.message
    assert r.slack_count[-1] == tendons  # the rods have moved closer than the rest length
    paths = save_figures(r, tmp_path)
    assert [p.name for p in paths] == ["initial.png", "equilibrium.png", "tendon_lengths.png"]
    assert all(png_size(p)[0] > 0 for p in paths)
    figure = Figure()
    ax = figure.add_subplot(projection="3d")
    artists = draw_structure(ax, structure, r.node_position[-1], r.tendon_tension[-1])
    assert artists["tendons"] is None
    assert (artists["slack"] is not None) == bool(tendons)
    expected = ["rods (2)"] + [f"slack tendons ({tendons})"] * bool(tendons)
    assert legend_texts(ax) == expected


def test_fixed_nodes_are_marked():
    """Supports and anchors show as triangles at exactly the fixed nodes, with a legend entry;
    a free structure has neither."""
    from tensegrity.model.shell import class2_shell

    s = class2_shell(4, 2, fixed_base=True)
    figure = figure_structure(s, s.node_position)
    ax = figure.axes[0]
    fixed = np.flatnonzero(s.node_fixed)
    assert fixed.size == 8 and f"fixed nodes ({fixed.size})" in legend_texts(ax)
    marked = [c for c in ax.collections if c.get_offsets().shape[0] == fixed.size]
    assert len(marked) == 1
    xs, ys, _ = marked[0]._offsets3d
    np.testing.assert_allclose(np.column_stack([xs, ys]), s.node_position[fixed, :2])
    free = figure_structure(class2_shell(4, 2), class2_shell(4, 2).node_position)
    assert not any(t.startswith("fixed") for t in legend_texts(free.axes[0]))
