"""The ground and the contacts in the viewer and the animations (issue 29): each plane a
semi-transparent patch with a grid around the footprint of the run, for any normal; the rod ends
in contact at each frame coloured by mode (stick, slip); a run without planes drawn as before.
The page in a browser: tests/test_viewer_browser.py."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from mpl_toolkits.mplot3d import proj3d

from tensegrity import class1_shell, simulate
from tensegrity.cli.main import main
from tensegrity.design.catalogue import six_bar_robot
from tensegrity.io.formats import write_network
from tensegrity.io.trajectory import read_trajectory
from tensegrity.model.ground import SLIP, STICK, Scene, ground
from tensegrity.plots.animation import _Scene
from tensegrity.plots.figures import PLANE_ALPHA, PLANE_COLOR, SLIP_COLOR, STICK_COLOR
from tensegrity.plots.motion import PLANE_MARGIN, make_frames, plane_patches
from tensegrity.plots.viewer import html, read_viewer_data, viewer_data

G = 9.81
SCENE = Scene((ground(friction=0.3),), contact_radius=0.01, gravity=[0.0, 0.0, -G])


def sliding_robot():
    """The six-bar robot (k = 2000 N/m, 100 N of prestress) on a face of two rods' ends, its
    lowest ends at the contact radius above z = 0, thrown along x at 1 m/s: its ends touch down,
    slip and stick in turn as it rocks."""
    robot = six_bar_robot(stiffness=2000.0, tension=100.0)
    nodes = robot.node_position.copy()
    nodes[:, 2] += SCENE.contact_radius - nodes[:, 2].min()
    velocity = np.zeros_like(nodes)
    velocity[:, 0] = 1.0
    return robot.replace(node_position=nodes, node_velocity=velocity)


@pytest.fixture(scope="module")
def run():
    result = simulate(
        sliding_robot(), (0.0, 0.3), sample_dt=0.01, max_steps=100_000, **SCENE.simulate_options()
    )
    assert result.status == 0, result.message
    modes = set(np.unique(result.contact_mode).tolist())
    assert {SLIP, STICK} <= modes  # (both shown)
    return result


# ------------------------------------------------------------------------------ the patches
@pytest.mark.parametrize(
    "normal", [(0, 0, 1), (np.sin(0.3), 0, np.cos(0.3)), (1, 0, 0), (0, -1, 0), (1, 2, 3)]
)
def test_a_patch_lies_on_its_plane_around_the_footprint_of_the_nodes(normal):
    """The ground, an incline and walls: the patch's corners are on the plane, it is a
    rectangle, and it holds every node projected on the plane with the margin to spare."""
    rng = np.random.default_rng(3)
    nodes = rng.uniform(-1.0, 2.0, (7, 5, 3))
    point = np.array([0.3, -0.2, 0.1])
    patch, unit, cell = plane_patches([{"point": point, "normal": normal}], nodes)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    assert unit[0] == pytest.approx(n)
    corners = patch[0]
    assert (corners - point) @ n == pytest.approx(np.zeros(4), abs=1e-12)
    u, v = corners[1] - corners[0], corners[3] - corners[0]
    assert u @ v == pytest.approx(0.0, abs=1e-12)
    assert corners[2] == pytest.approx(corners[0] + u + v)
    size = np.ptp(nodes.reshape(-1, 3), axis=0).max()
    a = (nodes.reshape(-1, 3) - corners[0]) @ (u / np.linalg.norm(u))
    b = (nodes.reshape(-1, 3) - corners[0]) @ (v / np.linalg.norm(v))
    inset = PLANE_MARGIN * size - 1e-12
    assert a.min() >= inset and a.max() <= np.linalg.norm(u) - inset
    assert b.min() >= inset and b.max() <= np.linalg.norm(v) - inset
    assert cell == 0.5  # (an eighth of the size 3, rounded up to 1, 2 or 5 times a power of 10)
    assert np.linalg.norm(u) / cell == pytest.approx(round(np.linalg.norm(u) / cell))


# ------------------------------------------------------------------------------ the viewer
def test_the_viewer_data_hold_the_plane_and_the_modes_at_each_frame(run):
    page = read_viewer_data(html(run, max_frames=12))
    contacts = page["contacts"]
    index = np.asarray(page["sample_index"])
    assert index.size == 12 and index[-1] == run.t.size - 1
    np.testing.assert_array_equal(contacts["mode"], run.contact_mode[index])
    np.testing.assert_array_equal(contacts["node"], run.contact_node)
    patch = np.array(contacts["patch"])
    assert patch.shape == (1, 4, 3) and np.all(patch[..., 2] == 0.0)  # (on z = 0)
    footprint = run.node_position[..., :2].reshape(-1, 2)
    assert np.all(patch[0, 0, :2] < footprint.min(axis=0))
    assert np.all(patch[0, 2, :2] > footprint.max(axis=0))
    assert page["colors"]["stick"] == STICK_COLOR and page["colors"]["slip"] == SLIP_COLOR
    assert np.array(page["bounds"])[0] == pytest.approx(patch[0].min(axis=0))


def test_a_run_without_planes_has_the_viewer_data_it_had():
    run = simulate(class1_shell(3, 1), (0.0, 0.05), sample_dt=0.01)
    frames = make_frames(run)
    assert frames.contacts is None
    data = viewer_data(frames)
    assert set(data) == {
        "format", "version", "title", "dim", "n_frames", "n_nodes", "n_rods", "n_tendons",
        "t", "sample_index", "energy", "node_position", "tendon_tension", "rod_nodes",
        "tendon_nodes", "tendon_name", "fixed", "joints", "point_masses", "tension_range",
        "bounds", "rod_radius", "colormap", "colors", "max_real_time",
    }  # fmt: skip
    assert data["version"] == 2 and set(data["colors"]) == {"rod", "slack", "fixed", "joint"}
    assert data["bounds"] == frames.bounds.tolist()


# ------------------------------------------------------------------------------ the animation
def _screen(scene, points):
    """Pixel (column, row) of 3-D ``points`` (K, 3) [m] in ``scene``'s picture."""
    ax = scene.ax
    x, y, _ = proj3d.proj_transform(*np.asarray(points).T, ax.get_proj())
    xy = ax.transData.transform(np.column_stack([x, y]))
    height = scene.figure.bbox.height
    return np.column_stack([xy[:, 0], height - xy[:, 1]]).round().astype(int)


def _near(picture, color, tolerance=12):
    """Pixels of ``picture`` within ``tolerance`` of ``color`` in every channel."""
    rgb = np.array(to_rgb(color)) * 255
    return np.all(np.abs(picture.astype(float) - rgb) <= tolerance, axis=-1)


def _on_plane(picture):
    """Pixels of the plane's colour at :data:`PLANE_ALPHA` over a light grey (the background or
    an axis pane: the same grey under each channel)."""
    under = (picture.astype(float) - PLANE_ALPHA * np.array(to_rgb(PLANE_COLOR)) * 255) / (
        1 - PLANE_ALPHA
    )
    return (under.min(axis=-1) > 220) & (np.ptp(under, axis=-1) < 8)


def test_an_animation_frame_shows_the_plane_under_the_robot_and_its_contacts(run):
    frames = make_frames(run)
    scene = _Scene(frames, size=(640, 512), view=None)
    assert len(scene.planes) == 2
    stuck = next(k for k in range(frames.n_frames) if (frames.contacts.mode[k] == STICK).any())
    slipping = next(k for k in range(frames.n_frames) if (frames.contacts.mode[k] == SLIP).any())
    for k, mode, color in ((stuck, STICK, STICK_COLOR), (slipping, SLIP, SLIP_COLOR)):
        picture = scene.show(k)
        plane = _on_plane(picture)
        assert plane.mean() > 0.05
        rows = np.flatnonzero(plane.any(axis=1))
        lowest = _screen(scene, frames.node_position[k])[:, 1].max()
        assert rows.max() > lowest + 10  # (the patch reaches below the lowest node)
        ends = np.unique(frames.contacts.node[frames.contacts.mode[k] == mode])
        marked = _near(picture, color)
        for column, row in _screen(scene, frames.node_position[k][ends]):
            assert marked[row - 3 : row + 4, column - 3 : column + 4].sum() > 5


def test_a_run_without_planes_shows_no_plane_in_its_frames():
    run = simulate(class1_shell(3, 1), (0.0, 0.05), sample_dt=0.01)
    scene = _Scene(make_frames(run), size=(640, 512), view=None)
    picture = scene.show(0)
    assert scene.planes == [] and not _on_plane(picture).any()
    assert not _near(picture, STICK_COLOR).any() and not _near(picture, SLIP_COLOR).any()


# ------------------------------------------------------------------------------ the command
def test_simulate_and_view_pages_of_a_run_on_the_ground_hold_its_modes(tmp_path):
    """``simulate``'s page (frames kept as the samples pass) and ``view``'s (read from the
    file) hold the trajectory's contact modes at their frames."""
    path = write_network(tmp_path / "robot.yaml", sliding_robot(), scene=SCENE)
    out = tmp_path / "out"
    argv = ["--t-end", "0.3", "--sample-dt", "0.01", "--no-animation", "--out", str(out)]
    assert main(["simulate", "--structure", str(path), *argv]) == 0
    trajectory = read_trajectory(out / "trajectory.h5")
    assert main(["view", str(out / "trajectory.h5"), "-o", str(tmp_path / "again.html")]) == 0
    for page in (out / "view.html", tmp_path / "again.html"):
        data = read_viewer_data(page.read_text())
        index = np.asarray(data["sample_index"])
        np.testing.assert_array_equal(data["contacts"]["mode"], trajectory.contact_mode[index])
        assert (data["contacts"]["mode"] == STICK).any()
