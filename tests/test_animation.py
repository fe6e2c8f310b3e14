"""Frames of a run (plots.motion), videos (plots.animation), the viewer page's data
(plots.viewer) and the verbs ``tensegrity animate`` / ``view`` (issue 15).  The page in a real
browser: tests/test_viewer_browser.py."""

from __future__ import annotations

import importlib
import subprocess
import sys
import types

import h5py
import numpy as np
import pytest
from matplotlib.colors import to_rgb

from tensegrity import artificial_damping, class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.io.trajectory import write_trajectory
from tensegrity.model.planar import planar_two_rod
from tensegrity.model.shell import class2_shell
from tensegrity.plots.animation import animate, render_frames
from tensegrity.plots.motion import (
    decimated_indices,
    frame_indices,
    make_frames,
    playback_times,
    structure_frames,
    tension_colors,
)
from tensegrity.plots.viewer import frame_budget, html, notebook_html, read_viewer_data, view
from test_kernel_system import point_mass_between_anchors

iio = pytest.importorskip("imageio.v2")


@pytest.fixture(scope="module")
def shell31():
    """The paper's example, 2 s sampled every 10 ms: it moves a lot, then settles."""
    return simulate(artificial_damping(class1_shell(3, 1)), (0.0, 2.0), sample_dt=0.01)


@pytest.fixture(scope="module")
def planar():
    s = planar_two_rod(angle=1.1, rest_length=[0.3, 0.35, 0.4, 0.45])
    return simulate(s, (0.0, 0.5), sample_dt=0.01)


@pytest.fixture(scope="module")
def trajectory(tmp_path_factory, shell31):
    path = tmp_path_factory.mktemp("run") / "trajectory.h5"
    write_trajectory(path, shell31)
    return path


# ------------------------------------------------------------------ frames


def test_playback_times_span_the_run_at_the_frame_rate():
    assert playback_times(0.0, 10.0, fps=30).size == 300  # real time
    assert playback_times(0.0, 100.0, fps=30).size == 600  # at most 20 s of video
    t = playback_times(1.0, 3.0, fps=10, speed=0.5)
    assert t.size == 40 and t[0] == 1.0 and t[-1] == 3.0
    assert playback_times(0.0, 3.0, fps=10, duration=1.0).size == 10
    assert playback_times(0.0, 0.0, fps=30).tolist() == [0.0]
    with pytest.raises(ValueError, match="one of them"):
        playback_times(0.0, 1.0, duration=1.0, speed=1.0)
    with pytest.raises(ValueError, match="fps"):
        playback_times(0.0, 1.0, fps=0)


def test_frames_show_the_last_sample_at_or_before_their_time():
    t = np.array([0.0, 0.1, 0.2, 0.3])
    assert frame_indices(t, [0.0, 0.05, 0.1, 0.29, 0.3, 9.0, -1.0]).tolist() == [
        0, 0, 1, 2, 3, 3, 0,
    ]  # fmt: skip
    assert decimated_indices(10, 20).tolist() == list(range(10))
    picked = decimated_indices(1001, 7)
    assert picked.size == 7 and picked[0] == 0 and picked[-1] == 1000
    assert decimated_indices(5, 1).tolist() == [4]


def test_frames_hold_the_samples_and_a_fixed_tension_range(shell31):
    index = np.array([0, 50, 200])
    frames = make_frames(shell31, index)
    np.testing.assert_array_equal(frames.node_position, shell31.node_position[index])
    np.testing.assert_array_equal(frames.tendon_tension, shell31.tendon_tension[index])
    taut = shell31.tendon_tension[shell31.tendon_tension > 0]
    assert frames.tension_range == (taut.min(), taut.max())  # over every sample, not 3
    assert np.all(frames.bounds[0] <= shell31.node_position.min(axis=(0, 1)))
    np.testing.assert_allclose(frames.energy["total"], shell31.total_energy[index])


def test_planar_frames_lie_in_the_plane_z_0(planar):
    frames = make_frames(planar)
    assert frames.node_position.shape == (planar.t.size, 4, 3)
    np.testing.assert_array_equal(frames.node_position[..., :2], planar.node_position)
    assert not frames.node_position[..., 2].any()


def test_a_structure_at_rest_is_one_frame_with_tensions_from_its_stretch():
    s = class1_shell(3, 1)
    frames = structure_frames(s)
    length = np.linalg.norm(np.diff(s.node_position[s.tendon_nodes], axis=1)[:, 0], axis=1)
    expected = np.maximum(s.tendon_stiffness * (length - s.tendon_rest_length), 0)
    np.testing.assert_allclose(frames.tendon_tension[0], expected)
    slack = structure_frames(s.replace(tendon_rest_length=np.full(s.n_tendons, 5.0)))
    assert slack.slack.all() and slack.tension_range == (0.0, 1.0)


def test_tension_colours_run_along_the_colour_map():
    low, mid, high = tension_colors(np.array([1.0, 5.5, 10.0]), (1.0, 10.0))
    assert not np.allclose(low, high) and not np.allclose(low, mid)
    np.testing.assert_array_equal(tension_colors(np.array([-3.0, 99.0]), (1.0, 10.0)), [low, high])


# ------------------------------------------------------------------ animation


def video_frames(path):
    reader = iio.get_reader(path)
    try:
        return [np.asarray(frame) for frame in reader]
    finally:
        reader.close()


@pytest.mark.parametrize("suffix", [".mp4", ".gif", ".webm"])
def test_animation_has_its_frames_size_and_motion(tmp_path, shell31, suffix):
    path = animate(shell31, tmp_path / f"motion{suffix}", fps=10, duration=1.0, size=(320, 256))
    frames = video_frames(path)
    assert len(frames) == 10
    assert frames[0].shape[:2] == (256, 320)
    if suffix == ".gif":
        from PIL import Image

        with Image.open(path) as gif:
            assert gif.info["duration"] == 100 and gif.info["loop"] == 0  # [ms], for ever
    else:
        reader = iio.get_reader(path)
        assert reader.get_meta_data()["fps"] == 10
        reader.close()
    first, last = (f[..., :3].astype(int) for f in (frames[0], frames[-1]))
    changed = np.abs(first - last).max(axis=-1) > 40
    assert changed.mean() > 0.01, "the structure does not move between the first and last frame"
    drawn = first.min(axis=-1) < 200  # dark pixels: rods, tendons, labels
    assert drawn.mean() > 0.02
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"motion{suffix}"]


def test_a_gif_keeps_the_frames_colours(tmp_path, shell31):
    """All frames of a GIF share one palette made from the first (which shows no slack
    tendon) and the members' special colours: the frames read back are the frames drawn to
    within a few levels, the background stays white and the slack tendons red."""
    from PIL import Image

    from tensegrity.plots.animation import _encode
    from tensegrity.plots.figures import SLACK_COLOR

    frames = make_frames(shell31, np.arange(0, 40, 2))
    assert frames.slack[0].sum() == 0 and frames.slack.sum() > 0
    pictures = list(render_frames(frames, size=(320, 256), progress=False))
    _encode(tmp_path / "motion.gif", ".gif", iter(pictures), 10.0)
    with Image.open(tmp_path / "motion.gif") as gif:
        assert gif.n_frames == len(pictures)
        read = []
        for k in range(gif.n_frames):
            gif.seek(k)
            read.append(np.asarray(gif.convert("RGB")).astype(int))
    red = np.rint(np.array(to_rgb(SLACK_COLOR)) * 255)
    slack_pixels = 0
    for drawn, back in zip(pictures, read, strict=True):
        error = np.abs(drawn.astype(int) - back).max(axis=-1)
        assert error.mean() < 3 and (error > 40).mean() < 0.005
        assert (back[drawn.min(axis=-1) == 255] == 255).all()  # white stays white
        slack = (drawn == red).all(axis=-1)
        slack_pixels += slack.sum()
        assert (np.abs(back[slack] - red) <= 10).all()
    assert slack_pixels > 0


def test_each_frame_draws_its_own_sample(shell31):
    frames = make_frames(shell31, np.array([0, 0, 150]))
    pictures = list(render_frames(frames, size=(320, 256), progress=False))
    assert len(pictures) == 3 and pictures[0].shape == (256, 320, 3)
    np.testing.assert_array_equal(pictures[0], pictures[1])
    assert (pictures[0] != pictures[2]).any()


def test_a_frame_leaves_nothing_on_the_next(shell31):
    """Each frame is drawn over the figure's kept background, not over the frame before: frame
    0 after frame 150 is frame 0 as first drawn."""
    frames = make_frames(shell31, np.array([0, 150, 0]))
    pictures = list(render_frames(frames, size=(320, 256), progress=False))
    np.testing.assert_array_equal(pictures[0], pictures[2])
    assert (pictures[0] != pictures[1]).any()


def test_a_blitted_frame_is_the_whole_figure_drawn(shell31):
    """A frame drawn over the kept background is, pixel for pixel, the figure drawn whole with
    the frame's rods, tendons and nodes (and the same text over it)."""
    from tensegrity.plots.animation import _Scene

    frames = make_frames(shell31, np.array([0, 30, 150]))
    scene = _Scene(frames, size=(320, 256), view=None)
    for k in range(frames.n_frames):
        blitted = scene.show(k)
        for artist in scene.moving:
            artist.set_animated(False)  # part of the figure's own drawing again
        scene.figure.canvas.draw()
        whole = scene.labelled(k)
        for artist in scene.moving:
            artist.set_animated(True)
        np.testing.assert_array_equal(blitted, whole)


@pytest.mark.parametrize("size", [(800, 640), (480, 384), (320, 256), (160, 160)])
def test_a_frames_counts_stay_clear_of_its_time_and_energies(size):
    """The counts of a run on the ground ("3 rods, 9 tendons, 0 slack, 3 ends sticking, 0
    slipping") are broken into lines where the picture is too narrow for them beside the time
    and energies (at 480x384 one line ran into the energies; since the text of frames narrower
    than 640 is scaled down, a large structure's counts), or go under them; clear of the
    colour bar either way."""
    from tensegrity.design.catalogue import three_bar_robot
    from tensegrity.model.ground import ground
    from tensegrity.plots.animation import COLOUR_BAR, _Scene, _text_mask

    run = simulate(three_bar_robot(), (0.0, 0.05), gravity=[0, 0, -9.81], ground=ground())
    frames = make_frames(run, np.array([0, len(run.t) - 1]))
    scene = _Scene(frames, size=size, view=None)
    lines = ["t =    0.050 s", "E       = 28.85 J", "E_kin   = 11.55 J", "E_el    = 6.75 J"]
    count = "3 rods, 9 tendons, 1 slack (dashed), 3 ends sticking, 0 slipping"
    if size == (480, 384):
        count = (
            "20,000 rods, 99,000 tendons, 12,345 slack (dashed), 1,234 ends sticking, 567 slipping"
        )
    placed = scene.text_layout(lines, count)
    boxes = [(x, y, x + mask.shape[1], y + mask.shape[0]) for mask, (x, y), _ in placed]
    left, bottom, width, _ = COLOUR_BAR
    bar = (*scene.colour_at, (left + width) * size[0], (1.0 - bottom) * size[1])
    for k, a in enumerate(boxes):
        assert 0 <= a[0] and a[2] <= size[0], (a, size)  # (within the picture's width)
        for b in [*boxes[k + 1 :], bar]:
            assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1], (a, b)
    rows = len(placed) - 1
    if size == (800, 640):
        assert rows == 1
    if size == (480, 384):  # (where the count on one line ran into the energies)
        one_line = _text_mask(count, scene.fonts["sans-serif"])
        assert scene.count_at[0] - one_line.shape[1] < boxes[0][2]
        assert rows >= 2
    picture = scene.show(1)  # (and the frame is drawn with it)
    assert picture.shape == (size[1], size[0], 3)


def test_text_beyond_the_picture_is_cut_off():
    """A text wider than the picture, or placed left of or above it, is written where it falls
    inside and nowhere else (a negative start must not wrap to the other edge)."""
    from tensegrity.plots.animation import _font, _text_mask, _write

    mask = _text_mask("6 rods, 24 tendons, 3 slack (dashed)", _font("sans-serif", pixels=12))
    whole = np.full((40, 400, 3), 255, dtype=np.uint8)
    _write(whole, mask, (100, 10), fill=0)
    inked = np.nonzero(whole.min(axis=(0, 2)) < 128)[0]
    assert inked.min() >= 100 and inked.max() - inked.min() > 150
    for shift in (160, 30):  # the text starts 160 or 30 pixels left of the picture
        cut = np.full((40, 120, 3), 255, dtype=np.uint8)
        _write(cut, mask, (-shift, 10), fill=0)
        np.testing.assert_array_equal(cut, whole[:, 100 + shift : 220 + shift])
    above = np.full((40, 400, 3), 255, dtype=np.uint8)
    _write(above, mask, (100, -5), fill=0)
    np.testing.assert_array_equal(above[:25], whole[15:40])


def test_progress_bar_on_request(shell31, capsys):
    frames = make_frames(shell31, np.array([0, 10, 20]))
    assert len(list(render_frames(frames, size=(320, 256), progress=True))) == 3
    err = capsys.readouterr().err
    assert "animate" in err and "3/3" in err
    list(render_frames(frames, size=(320, 256)))  # not a terminal: no bar
    assert capsys.readouterr().err == ""


def test_planar_and_constrained_structures_animate(tmp_path, planar):
    animate(planar, tmp_path / "planar.gif", fps=5, duration=1.0, size=(320, 256))
    assert len(video_frames(tmp_path / "planar.gif")) == 5
    shell = class2_shell(3, 2, fixed_base=True)
    run = simulate(artificial_damping(shell), (0.0, 0.2), sample_dt=0.02, gravity=[0, 0, -9.81])
    animate(run, tmp_path / "class2.mp4", fps=10, duration=0.5, size=(320, 256))
    assert len(video_frames(tmp_path / "class2.mp4")) == 5


def test_point_masses_and_anchors_animate(tmp_path):
    run = simulate(point_mass_between_anchors(), (0.0, 0.2), sample_dt=0.01)
    frames = make_frames(run)
    assert frames.point_mass_nodes.tolist() == [2] and frames.fixed_nodes.tolist() == [0, 1]
    animate(run, tmp_path / "mass.gif", fps=10, duration=1.0, size=(320, 256))
    pictures = video_frames(tmp_path / "mass.gif")
    assert len(pictures) == 10
    assert (np.abs(pictures[0].astype(int) - pictures[5].astype(int)).max(axis=-1) > 40).any()


def test_an_interrupted_animation_leaves_the_old_file(tmp_path, shell31, monkeypatch):
    from tensegrity.plots import animation

    path = tmp_path / "motion.mp4"
    path.write_bytes(b"the older video")
    shown = animation._Scene.show
    calls = []

    def interrupted(self, k):
        calls.append(k)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return shown(self, k)

    monkeypatch.setattr(animation._Scene, "show", interrupted)
    with pytest.raises(KeyboardInterrupt):
        animate(shell31, path, fps=10, duration=1.0, size=(320, 256))
    assert [p.name for p in tmp_path.iterdir()] == ["motion.mp4"]
    assert path.read_bytes() == b"the older video"


def test_an_unknown_video_format_writes_nothing(tmp_path, shell31):
    with pytest.raises(ValueError, match="unknown video format"):
        animate(shell31, tmp_path / "motion.avi")
    assert not list(tmp_path.iterdir())


# ------------------------------------------------------------------ the page's data


def test_page_data_hold_the_positions_to_float32_precision(shell31):
    page = html(shell31, max_frames=25)
    data = read_viewer_data(page)
    index = np.array(data["sample_index"])
    assert data["n_frames"] == index.size == 25 and index[0] == 0 and index[-1] == 200
    np.testing.assert_array_equal(
        data["node_position"], shell31.node_position[index].astype(np.float32)
    )
    np.testing.assert_array_equal(
        data["tendon_tension"], shell31.tendon_tension[index].astype(np.float32)
    )
    np.testing.assert_array_equal(data["tendon_nodes"], class1_shell(3, 1).tendon_nodes)
    assert data["tendon_name"] == list(shell31.structure.tendon_name)
    assert "<script src" not in page and "<link" not in page  # everything inline


def test_page_frames_fit_the_byte_budget():
    big = class1_shell(30, 30)
    per_frame = 4 * (3 * big.n_nodes + big.n_tendons)
    assert frame_budget(big, max_frames=300, max_bytes=10 * per_frame + 5) == 10
    assert frame_budget(big, max_frames=4, max_bytes=10**12) == 4
    assert frame_budget(big, max_frames=300, max_bytes=1) == 1


def test_the_frame_budget_counts_the_contact_modes_of_a_run_with_planes():
    """A page's frame of a run with planes holds the contact pairs' int8 modes beside the
    float32 positions and tensions: the budget counts the bytes of the frames made of a run."""
    from tensegrity.model.ground import Plane, ground
    from tensegrity.plots.motion import make_frames
    from test_contact import lying_rod

    wall = Plane(point=(5.0, 0.0, 0.0), normal=(-1.0, 0.0, 0.0))
    run = simulate(lying_rod(z=0.5), (0.0, 0.02), ground=[ground(), wall], contact_radius=0.01,
                   sample_dt=0.01)  # fmt: skip
    frames = make_frames(run)
    assert frames.contacts is not None
    page = (
        frames.node_position.astype(np.float32).nbytes
        + frames.tendon_tension.astype(np.float32).nbytes
        + frames.contacts.mode.nbytes
    )
    per_frame = page // frames.n_frames
    assert page == per_frame * frames.n_frames and frames.contacts.mode.shape[1] == 4
    budget = {"max_frames": 300, "planes": 2}
    assert frame_budget(run.structure, max_bytes=7 * per_frame, **budget) == 7
    assert frame_budget(run.structure, max_bytes=7 * per_frame - 1, **budget) == 6


def test_a_name_cannot_end_the_data_script(shell31):
    names = tuple(f"</script><b>{k}" for k in range(shell31.structure.n_tendons))
    s = shell31.structure.replace(tendon_name=names)
    page = html(s)
    assert page.count("</script>") == 3  # data, three.js, viewer
    assert read_viewer_data(page)["tendon_name"] == list(names)


# ------------------------------------------------------------------ the verbs


@pytest.mark.parametrize(
    "argv, name",
    [
        (["animate", "T", "--fps", "5", "--size", "160x160", "--duration", "0.4"], "m.gif"),
        (["view", "T", "--max-frames", "3"], "v.html"),
    ],
)
def test_cli_animate_and_view_make_the_folders_of_their_output(tmp_path, trajectory, argv, name):
    """As every verb (``sweep``, ``export``, the output folders): the missing folders of
    ``-o`` are made (before: refused, ``folder ... does not exist``); if the file cannot be
    written there, the folders made are removed again."""
    import errno

    argv = [str(trajectory) if a == "T" else a for a in argv]
    out = tmp_path / "new" / "deeper" / name
    assert main([*argv, "-o", str(out)]) == 0
    assert out.is_file() and list(out.parent.iterdir()) == [out]
    target = {
        "animate": "tensegrity.plots.animation.animate",
        "view": "tensegrity.plots.viewer.view",
    }

    def full_disk(frames, path, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(target[argv[0]], full_disk)
        # a full disk fails the command (exit 1, as everywhere), it is not bad input
        assert main([*argv, "-o", str(tmp_path / "other" / name)]) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new"]


def test_cli_animate_and_view_write_their_files(tmp_path, trajectory, capsys):
    assert main(["animate", str(trajectory), "-o", str(tmp_path / "m.gif"), "--fps", "5",
                 "--size", "320x256"]) == 0  # fmt: skip
    assert len(video_frames(tmp_path / "m.gif")) == 10  # 2 s in real time
    assert main(["view", str(trajectory), "-o", str(tmp_path / "v.html"), "--max-frames", "7"]) == 0
    out = capsys.readouterr().out
    assert "wrote" in out and "KiB" in out and "7 frames of 201 samples" in out
    assert read_viewer_data((tmp_path / "v.html").read_text())["n_frames"] == 7


@pytest.fixture
def bad_files(tmp_path, trajectory):
    truncated = tmp_path / "truncated.h5"
    truncated.write_bytes(trajectory.read_bytes()[:4000])
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f["x"] = np.zeros(3)
    text = tmp_path / "text.h5"
    text.write_text("not a trajectory\n")
    return {"missing": tmp_path / "missing.h5", "truncated": truncated, "other": other,
            "text": text}  # fmt: skip


@pytest.mark.parametrize("which", ["missing", "truncated", "other", "text"])
@pytest.mark.parametrize("verb, name", [("animate", "m.mp4"), ("view", "v.html")])
def test_cli_bad_trajectory_is_one_line_exit_2_nothing_written(
    tmp_path, bad_files, capsys, which, verb, name
):
    out = tmp_path / "out"
    out.mkdir()
    assert main([verb, str(bad_files[which]), "-o", str(out / name)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"tensegrity: error: {verb}: ")
    assert bad_files[which].name in err
    assert not list(out.iterdir())


@pytest.mark.parametrize(
    "argv, words",
    [
        (["animate", "T", "-o", "m.avi"], "expected a name ending in .mp4"),
        (["animate", "T", "-o", "m.mp4", "--size", "100x100"], "multiples of 16"),
        (["animate", "T", "-o", "m.mp4", "--duration", "1", "--speed", "2"], "not both"),
    ],
)
def test_cli_bad_options_are_one_line(tmp_path, trajectory, capsys, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    argv = [str(trajectory) if a == "T" else a for a in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_view_writes_a_structure_page_atomically(tmp_path):
    path = view(class1_shell(3, 1), tmp_path / "s.html")
    assert [p.name for p in tmp_path.iterdir()] == ["s.html"]
    assert read_viewer_data(path.read_text())["n_frames"] == 1


def test_results_and_structures_are_shown_by_the_plots_functions(tmp_path):
    """``tensegrity.plots.view(result, path)``, ``plots.animate(result, path)`` and
    ``plots.view(structure, path)``: the same files and page as the functions they call."""
    from tensegrity import class1_shell, plots, simulate
    from tensegrity.plots.viewer import html, read_viewer_data

    shell = class1_shell(3, 1)
    result = simulate(shell, (0.0, 0.2), sample_dt=0.02)
    page = plots.view(result, tmp_path / "run.html").read_text()
    assert page == html(result)
    data = read_viewer_data(page)
    np.testing.assert_array_equal(data["node_position"], result.node_position.astype(np.float32))
    assert read_viewer_data(plots.view(shell, tmp_path / "shell.html").read_text())["n_frames"] == 1
    video = plots.animate(result, tmp_path / "run.gif", fps=10)
    assert video.stat().st_size > 0


def test_results_and_structures_are_shown_inline():
    """The inline view in Jupyter (``plots.show_inline``, on IPython's HTML formatter; IPython
    is a test dependency)."""
    from IPython.core import formatters

    from tensegrity import class1_shell, plots, simulate

    shell = class1_shell(3, 1)
    result = simulate(shell, (0.0, 0.2), sample_dt=0.02)
    ipython = types.SimpleNamespace(display_formatter=formatters.DisplayFormatter())
    plots.show_inline(ipython)  # (the part of a shell it uses)
    for shown in (result, shell):
        inline = ipython.display_formatter.format(shown)[0]["text/html"]
        assert inline.startswith("<iframe srcdoc=") and "tensegrity-data" in inline


def test_the_notebook_page_shows_as_html_where_a_front_end_asks_for_it():
    """``notebook_html`` is a ``str`` that front ends without IPython's formatter (VS Code,
    marimo, sphinx-gallery: the tutorials' inline viewer) render by its ``_repr_html_``."""
    from tensegrity import class1_shell

    page = notebook_html(class1_shell(3, 1))
    assert isinstance(page, str) and page._repr_html_() == str(page)
    assert page.startswith("<iframe srcdoc=") and "tensegrity-data" in page


def test_the_package_shows_results_inline_under_ipython():
    """Imported in a running IPython (as in a Jupyter kernel), the package registers the inline
    view itself; the model and the engine are not given methods for it, and matplotlib is not
    loaded until a page is shown."""
    code = (
        "import sys\n"
        "from IPython.core.interactiveshell import InteractiveShell\n"
        "ipython = InteractiveShell.instance()\n"
        "import tensegrity\n"
        "assert 'matplotlib' not in sys.modules\n"
        "shell = tensegrity.class1_shell(3, 1)\n"
        "assert not hasattr(tensegrity.Structure, '_repr_html_')\n"
        "assert not hasattr(tensegrity.SimulationResult, '_repr_html_')\n"
        "inline = ipython.display_formatter.format(shell)[0]['text/html']\n"
        "assert inline.startswith('<iframe srcdoc=') and 'tensegrity-data' in inline\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)


def test_simulate_writes_the_viewer_from_the_samples_it_kept(tmp_path):
    """``tensegrity simulate`` writes ``view.html`` beside its figures, its frames kept as the
    run's samples passed (not read back from the file): each frame is a sample of the
    trajectory (positions and tensions to float32), the first and the last among them, at most
    the page's frame budget; a resumed run's page, read from the file, shows the same samples'
    values; ``--no-view`` writes none."""
    from tensegrity.cli.main import main
    from tensegrity.io.trajectory import read_trajectory
    from tensegrity.plots.motion import MAX_FRAMES, read_frames
    from tensegrity.plots.viewer import read_viewer_data

    out = tmp_path / "out"
    run = ["simulate", "--t-end", "8", "--no-steady-state", "--sample-dt", "0.01"]
    assert main([*run, "--out", str(out)]) == 0
    trajectory = read_trajectory(out / "trajectory.h5")
    data = read_viewer_data((out / "view.html").read_text())
    numbers = np.array(data["sample_index"])
    assert 100 <= numbers.size <= MAX_FRAMES and numbers[0] == 0
    assert numbers[-1] == trajectory.t.size - 1 and np.all(np.diff(numbers) > 0)
    np.testing.assert_array_equal(data["t"], trajectory.t[numbers])
    np.testing.assert_array_equal(
        data["node_position"], trajectory.node_position[numbers].astype(np.float32)
    )
    np.testing.assert_array_equal(
        data["tendon_tension"], trajectory.tendon_tension[numbers].astype(np.float32)
    )
    # (a resumed run's frames are read from the file: the datasets they show, one row in k)
    frames, n_samples = read_frames(out / "trajectory.h5", max_frames=50, max_bytes=10**9)
    assert n_samples == trajectory.t.size and frames.n_frames <= 50 and frames.index[-1] == 800
    np.testing.assert_array_equal(frames.t, trajectory.t[frames.index])
    np.testing.assert_array_equal(frames.node_position, trajectory.node_position[frames.index])
    np.testing.assert_array_equal(frames.tendon_tension, trajectory.tendon_tension[frames.index])
    assert main([*run, "--no-view", "--out", str(tmp_path / "bare")]) == 0
    assert not (tmp_path / "bare" / "view.html").exists()


def gif_delays(path):
    """The delay of each frame of the GIF at ``path`` [ms]."""
    from PIL import Image

    with Image.open(path) as gif:
        delays = []
        for k in range(gif.n_frames):
            gif.seek(k)
            delays.append(gif.info["duration"])
    return delays


def test_simulate_writes_a_gif_by_default(tmp_path, capsys, monkeypatch):
    """``tensegrity simulate`` writes ``motion.gif`` beside the other files unasked: the run in
    real time at 20 fps (0.5 s: 10 frames of 640 x 512, 5 hundredths of a second each),
    moving; ``--animation mp4`` an MP4 instead, ``--no-animation`` none, both at once is a
    one-line error; a video over the default's drawing budget is left out with a line that
    says so, and drawn when asked for."""
    cli = importlib.import_module("tensegrity.cli.simulate_files")
    run = ["simulate", "--t-end", "0.5", "--no-steady-state", "--damping", "none"]
    assert main([*run, "--out", str(tmp_path / "a")]) == 0
    assert "a/motion.gif" in capsys.readouterr().out
    frames = video_frames(tmp_path / "a" / "motion.gif")
    assert len(frames) == 10 and frames[0].shape[:2] == (512, 640)
    assert gif_delays(tmp_path / "a" / "motion.gif") == [50] * 10
    first, last = (f[..., :3].astype(int) for f in (frames[0], frames[-1]))
    assert (np.abs(first - last).max(axis=-1) > 40).mean() > 0.01

    assert main([*run, "--animation", "mp4", "--out", str(tmp_path / "b")]) == 0
    assert [p.name for p in (tmp_path / "b").glob("motion.*")] == ["motion.mp4"]
    assert len(video_frames(tmp_path / "b" / "motion.mp4")) == 10
    assert main([*run, "--no-animation", "--out", str(tmp_path / "c")]) == 0
    assert not list((tmp_path / "c").glob("motion.*"))
    capsys.readouterr()
    assert main([*run, "--animation", "gif", "--no-animation", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "--no-animation" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()

    monkeypatch.setattr(cli, "DEFAULT_VIDEO_SECONDS", 0.01)  # (10 frames: about 0.06 s)
    assert main([*run, "--out", str(tmp_path / "d")]) == 0
    assert not list((tmp_path / "d").glob("motion.*"))
    err = capsys.readouterr().err
    assert "motion.gif not drawn: 10 frames of 30 members" in err and "--animation gif" in err
    assert main([*run, "--animation", "gif", "--out", str(tmp_path / "e")]) == 0
    assert len(video_frames(tmp_path / "e" / "motion.gif")) == 10


@pytest.mark.parametrize(("fps", "delay", "count"), [(30, 3, 33), (25, 4, 25), (7, 14, 7)])
def test_a_gif_plays_in_the_time_its_frames_show(tmp_path, shell31, fps, delay, count):
    """A GIF's frame delays are whole hundredths of a second: asked for 30 fps, it is written
    at 33.3 (delays of 3 hundredths) with as many frames more, so that 1 s of the run plays in
    1 s, not in 0.9 (30 frames of 30 ms); the frames show the run's times at that rate."""
    path = animate(shell31, tmp_path / "m.gif", fps=fps, duration=1.0, size=(320, 256))
    delays = gif_delays(path)
    assert delays == [10 * delay] * count
    assert abs(sum(delays) / 1000 - 1.0) <= delay / 100
