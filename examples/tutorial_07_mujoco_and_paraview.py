"""
Export to MuJoCo and ParaView
=============================

The same structure in two other tools: MuJoCo, through an MJCF file (rods as bodies, tendons
as spatial springs that go slack), run side by side with this engine; and ParaView, through a
VTK time series of the run.
"""

# %%
# MuJoCo
# ------
# :func:`~tensegrity.io.mjcf.to_mjcf` writes the (3,1) shell with its start on the cylinder;
# MuJoCo's RK4 at 0.1 ms and this engine's DOP853 run the same 0.5 s of free motion.
from pathlib import Path
from tempfile import TemporaryDirectory

import mujoco
import numpy as np

from tensegrity import class1_shell, simulate
from tensegrity.io.mjcf import mujoco_node_positions, to_mjcf
from tensegrity.io.vtk import write_vtk
from tensegrity.plots.figures import new_figure

shell = class1_shell(3, 1)
model = mujoco.MjModel.from_xml_string(to_mjcf(shell, timestep=1e-4, integrator="RK4"))
data = mujoco.MjData(model)
mujoco.mj_resetDataKeyframe(model, data, 0)  # (the structure's start)
ours = simulate(shell, (0.0, 0.5), sample_dt=0.01)
theirs = []
for _ in range(len(ours.t)):
    theirs.append(mujoco_node_positions(model, data, shell.n_nodes))
    mujoco.mj_step(model, data, nstep=100)
gap = np.linalg.norm(np.array(theirs) - ours.node_position, axis=2).max(axis=1)
print(f"largest node distance between the two over 0.5 s: {gap.max():.1e} m")
comparison = new_figure((7.0, 3.5))
ax = comparison.subplots()
ax.semilogy(ours.t[1:], gap[1:])
ax.set_xlabel("t [s]")
ax.set_ylabel("MuJoCo against this engine [m]")

# %%
# ParaView
# --------
# :func:`~tensegrity.io.vtk.write_vtk` writes one ``.vtp`` per sample and a ``.pvd``
# collection that ParaView opens as a time series (``tensegrity vtk FILE.h5`` from the shell).
with TemporaryDirectory() as folder:
    files = write_vtk(Path(folder), ours, every=10)
    print(len(files), "files, the collection:", files[-1].name)
