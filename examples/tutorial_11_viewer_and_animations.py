"""
The viewer and animations
=========================

Two ways to watch a run: the 3-D viewer, one self-contained HTML page that turns, zooms and
plays the run in a browser (or inline, in a notebook or on this page); and a video (GIF, MP4 or
WebM) drawn frame by frame. Both draw the same frames the same way: rods dark, tendons coloured
by tension on a scale fixed over the whole run, slack tendons dashed red, feet that stick or
slip on the ground marked.
"""

# %%
# A run to watch
# --------------
# The three-bar robot of :func:`~tensegrity.design.catalogue.three_bar_robot`, thrown sideways
# and spun on a ground with Coulomb friction: it tips over its base's edge and rolls onto a
# side, its ends touching down, sticking and slipping.
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from tensegrity import simulate
from tensegrity.design.catalogue import three_bar_robot
from tensegrity.model.ground import ground
from tensegrity.physics.dynamics import State, coordinates_from_nodes, initial_state
from tensegrity.plots.animation import animate, render_frames
from tensegrity.plots.figures import new_figure
from tensegrity.plots.motion import frame_indices, make_frames, playback_times
from tensegrity.plots.viewer import notebook_html, view

robot = three_bar_robot(stiffness=300.0, tension=20.0)
robot = robot.replace(node_position=robot.node_position + np.array([0.0, 0.0, 0.005]))  # 5 mm up
centre = robot.node_position.mean(axis=0)
spin = np.cross([0.0, -10.0, 0.0], robot.node_position - centre)  # 10 rad/s about -y
velocity = spin + np.array([-1.0, 0.0, 0.0])  # and 1 m/s along -x [m/s]
start = State(0.0, initial_state(robot).q, coordinates_from_nodes(robot, velocity))
run = simulate(
    robot,
    (0.0, 1.0),
    initial=start,
    sample_dt=0.01,
    gravity=[0.0, 0.0, -9.81],
    ground=ground(friction=0.8, kinetic_friction=0.6),
)
print(run.message, "|", len(run.t), "samples |", run.contact_counts)

# %%
# The viewer
# ----------
# :func:`~tensegrity.plots.viewer.view` writes the page (``tensegrity view trajectory.h5`` from
# the shell, and ``tensegrity simulate`` writes ``view.html`` beside its figures); at most
# ``max_frames`` frames, spread evenly with the first and the last kept.
# :func:`~tensegrity.plots.viewer.notebook_html` is the same page in an ``<iframe>``: as a
# cell's value it shows inline, here as in Jupyter. Drag to turn, scroll to zoom, play,
# step or scrub the time; the panel lists the energies of each frame.
with TemporaryDirectory() as folder:
    page = view(run, Path(folder) / "robot.html", max_frames=200)
    print(f"{page.name}: {page.stat().st_size / 1e6:.1f} MB, one file, no server")
notebook_html(run, height=480)

# %%
# A video
# -------
# :func:`~tensegrity.plots.animation.animate` writes a video, its format from the suffix;
# ``speed`` plays the run slower (0.25: a quarter of real time) or faster, ``duration`` fits it
# into a length, ``fps`` and ``size`` set the frames (``tensegrity animate trajectory.h5 -o
# motion.mp4`` from the shell). The file is written atomically: an interrupted drawing leaves
# no half-written video.
with TemporaryDirectory() as folder:
    video = animate(run, Path(folder) / "robot.gif", speed=0.25, fps=25, size=(480, 384))
    print(f"{video.name}: {video.stat().st_size / 1e6:.2f} MB")

# %%
# The frames themselves
# ---------------------
# A video is :func:`~tensegrity.plots.motion.make_frames` (which samples to show, with the
# tension scale and bounds over the whole run) drawn by
# :func:`~tensegrity.plots.animation.render_frames`, one picture (height, width, 3) at a time:
# here four moments of the roll.
times = playback_times(run.t[0], run.t[-1], duration=4 / 25, fps=25)
frames = make_frames(run, frame_indices(run.t, times))
stills = new_figure((8.0, 6.4))
for ax, picture, t in zip(
    stills.subplots(2, 2).flat, render_frames(frames, size=(480, 384)), frames.t, strict=True
):
    ax.imshow(picture)
    ax.set_title(f"t = {t:.2f} s", fontsize=9)
    ax.set_axis_off()

# %%
# Other motions
# -------------
# Anything that moves can be drawn the same way: :func:`~tensegrity.plots.motion.motion_frames`
# takes times, node positions and tensions as arrays (a mode's oscillation, a sequence of
# equilibria, a controller's plan), :func:`~tensegrity.plots.motion.structure_frames` a
# structure at rest; :func:`~tensegrity.plots.viewer.view` and the drawing take those frames
# as they take a run. ``tensegrity modes --shapes`` writes one such page per low mode.
