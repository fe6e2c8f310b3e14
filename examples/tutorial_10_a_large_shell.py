"""
A large shell
=============

The (30,30) class 1 shell: 1,800 rods, 8,940 tendons, 10,800 coordinates. The same functions as
for the paper's (3,1) shell, and what changes with the size: a run streamed to a file in
checkpointed segments (resumable, memory independent of the run's length), read back a part
at a time, and the analyses that need dense matrices kept to smaller shells.
"""

# %%
# The structure
# -------------
# :func:`~tensegrity.model.shell.class1_shell` builds any ``n x m`` shell by the paper's closure
# rules; its nodes start on a cylinder. The engine packs the tendons once for the compiled kernel,
# whatever their number.
from pathlib import Path
from tempfile import TemporaryDirectory

import numpy as np

from tensegrity import class1_shell, internal_damping
from tensegrity.io.stream import simulate_to_file
from tensegrity.io.trajectory import read_dataset, read_trajectory
from tensegrity.plots.figures import figure_structure, new_figure

shell = internal_damping(class1_shell(30, 30))
print(f"{shell.n_rods} rods, {shell.n_tendons} tendons, {shell.n_nodes} nodes")

# %%
# A run streamed to a file
# ------------------------
# :func:`~tensegrity.io.stream.simulate_to_file` runs the engine once and stores its samples
# segment by segment, with a checkpoint after each: a run that is interrupted (or killed) is
# continued from its last checkpoint by the same call, to the trajectory it would have had;
# until the end the data sit in ``run.h5.partial``, so a half-written file never looks
# finished. Memory holds about two segments, however long the run. (From the shell:
# ``tensegrity simulate --n 30 --m 30``, and ``--resume`` after an interruption.)
folder = TemporaryDirectory()
path = Path(folder.name) / "run.h5"
summary = simulate_to_file(shell, (0.0, 1.0), path, segment=0.25, sample_dt=0.01)
print(summary.message, f"| {summary.n_samples} samples in {summary.segments_stored} segments")
print(f"{path.name}: {path.stat().st_size / 1e6:.0f} MB")

# %%
# Reading a part of it
# --------------------
# :func:`~tensegrity.io.trajectory.read_dataset` reads one series (here the tendons'
# tensions), :func:`~tensegrity.io.trajectory.read_trajectory` with ``every=`` an overview of
# the whole run, one sample in ``every``: neither needs the whole file in memory.
tension = read_dataset(path, "tendon_tension")
t = read_dataset(path, "t")
slack = (tension <= 0.0).sum(axis=1)
print(f"tensions {tension.shape}: slack tendons from {slack[0]} to {slack[-1]}")
overview = read_trajectory(path, every=25)
print(f"overview: {overview.t.size} samples at t = {np.round(overview.t, 2)}")
balance = overview.total_energy  # E_kin + E_el + E_grav + E_d - W_w - W_u [J]
elastic = overview.energy["elastic"][0]
print(f"energy balance held to {np.ptp(balance) / elastic:.1e} of the elastic energy")

curves = new_figure((7.0, 3.0))
ax = curves.subplots()
ax.plot(t, slack)
ax.set_xlabel("t [s]")
ax.set_ylabel("slack tendons")

# %%
# The shell after 1 s
# -------------------
# Drawn with its tendons coloured by tension (slack ones dashed red). The viewer and the
# videos read such a file a part at a time (``tensegrity view run.h5``, ``tensegrity animate
# run.h5``; :func:`~tensegrity.plots.motion.read_frames` in Python), keeping at most a budget
# of frames (:doc:`tutorial_11_viewer_and_animations`).
last = overview.node_position[-1]
picture = figure_structure(
    shell, last, overview.tendon_tension[-1], title="The (30,30) shell after 1 s"
)
folder.cleanup()

# %%
# What does not scale
# -------------------
# The dynamics cost grows with the number of members. The equilibrium solver
# (:func:`~tensegrity.analysis.equilibrium.find_equilibrium`), the linearization's modes
# (:func:`~tensegrity.analysis.modes.modal_analysis`) and the controllability tests work on
# dense matrices, whose cost grows with the cube of the coordinates: use them on shells up to
# about (10,10), and a damped run to rest (``steady_state=True``) for larger ones.
