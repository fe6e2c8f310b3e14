"""
A parameter sweep on Dask, read with xarray
===========================================

The three-bar prism standing on its fixed base, pressed down on its top, over a grid of tendon
stiffnesses and loads: twenty cases run in parallel on a local Dask cluster by
:func:`~tensegrity.sweep.run.run_sweep`, gathered into one labelled :class:`xarray.Dataset`,
written as netCDF-4/HDF5 and read back. From the shell, with the structure in a file, the same
sweep is ``tensegrity sweep --structure FILE --param stiffness=100,200,400,800 --param
load=0,5,10,20,40 --t-end 5 --dt 1e-3 --sample-dt 0.05 -o sweep.nc``.
"""

# %%
# The cases
# ---------
# :class:`~tensegrity.sweep.run.SweepSpec` names the parameters that vary and how each case runs.
# Without ``structure`` the cases are class 1 shells; here they are copies of one structure:
# :func:`~tensegrity.design.catalogue.prism`, prestressed to a mean tension of 5 N, its three bottom
# nodes fixed to the ground, with :func:`~tensegrity.physics.dynamics.internal_damping` so that
# every case settles into its loaded equilibrium. ``stiffness`` [N/m] is every tendon's; ``load``
# [N] is a total force down on the top nodes, shared equally (the sweep pushes the lowest nodes up
# by as much, which the supports take here). What is not varied keeps the structure's own values:
# its rest lengths, so the prestress grows with the stiffness.
from pathlib import Path
from tempfile import TemporaryDirectory

from tensegrity import internal_damping
from tensegrity.design.catalogue import prism
from tensegrity.plots.figures import new_figure
from tensegrity.sweep import SweepSpec, read_sweep, run_sweep
from tensegrity.sweep.run import plan

standing = internal_damping(prism(3, fixed_base=True))
spec = SweepSpec(
    parameters={"stiffness": [100.0, 200.0, 400.0, 800.0], "load": [0.0, 5.0, 10.0, 20.0, 40.0]},
    structure=standing,
    t_end=5.0,  # [s] simulated per case
    sample_dt=0.05,  # [s] between the dataset's samples
    dt=1e-3,  # [s] the RK4 step
)
cases = spec.cases()
print(spec.n_cases, "cases; case 7:", cases[7])

# %%
# :func:`~tensegrity.sweep.run.plan` says how the cases become Dask tasks for a cluster of two
# worker threads: free class 1 structures run in batches, one per thread; a structure with
# supports runs one :func:`~tensegrity.engine.simulate.simulate` task per case.
tasks = plan(spec, cases, 2)
print(len(tasks), "tasks; the first:", tasks[0])

# %%
# The run on Dask
# ---------------
# :func:`~tensegrity.sweep.run.run_sweep` starts a ``distributed.LocalCluster`` (by default
# one single-threaded worker process per CPU), or connects to a running scheduler
# (``scheduler="tcp://host:8786"``), or uses a ``client=`` you made. Here two workers that are
# threads of this process (``processes=False``): a worker process is started by ``spawn`` and
# imports the running script again, which a script needs to allow with an
# ``if __name__ == "__main__":`` guard; this tutorial, run as it is or by the documentation
# build, has none. For large sweeps use processes: from a guarded script, from ``tensegrity
# sweep``, or on a cluster through its scheduler's address. A case that fails is reported in
# the dataset (``status``, ``message``); the other cases are kept.
result = run_sweep(spec, n_workers=2, processes=False)
print("every case reached t_end:", result.success, "| failed:", result.failed)
print(result.describe_case(7))

# %%
# Saved and read back
# -------------------
# :meth:`~tensegrity.sweep.run.SweepResult.save` writes the dataset as netCDF-4/HDF5 through
# h5netcdf, atomically; :func:`~tensegrity.sweep.run.read_sweep` checks the file as one from
# someone else before xarray reads it, and loads it into memory (so the folder can go).
with TemporaryDirectory() as folder:
    path = result.save(Path(folder) / "prism-sweep.nc")
    ds = read_sweep(path)
print("dimensions:", dict(ds.sizes))
print("coordinates:", list(ds.coords))
print("per case:", [name for name, v in ds.data_vars.items() if v.dims == ("case",)])
print("per case and time:", [name for name, v in ds.data_vars.items() if v.dims == ("case", "t")])

# %%
# A grid of the parameters
# ------------------------
# The cases lie along one dimension, ``case``, with a coordinate per parameter.
# ``set_index`` and ``unstack`` turn it into one dimension per parameter, and ``sel`` then
# picks cases by value. ``max_displacement`` is the largest distance of a node from where it
# started [m]; its last sample is the loaded equilibrium's.
grid = ds.set_index(case=["stiffness", "load"]).unstack("case")
settled = 1e3 * grid.max_displacement.isel(t=-1)  # [mm]
print("settled displacement [mm], stiffness down, load across:")
print(settled.round(2).to_pandas())
print("no tendon went slack in any case:", int(ds.slack_count.max()) == 0)

displacement = new_figure((7.0, 4.0))
ax = displacement.subplots()
settled.plot.line(x="load", hue="stiffness", marker="o", ax=ax)
ax.set_xlabel("load on the top [N]")
ax.set_ylabel("settled displacement [mm]")
ax.set_title("The standing prism under load")

# %%
# The prism stiffens as it sinks: each newton more moves it less. And a stiffness twice as
# large under twice the load settles in the same place, since with the rest lengths kept the
# tensions scale with the stiffness: at rest only the load over the stiffness counts.
same = settled.sel(stiffness=200.0, load=10.0) - settled.sel(stiffness=100.0, load=5.0)
print(f"(200 N/m, 10 N) against (100 N/m, 5 N): {float(same):.1e} mm apart")

# %%
# On the way there
# ----------------
# The series keep the time. The damping is the structure's own in every case (``damping`` is not
# varied): :func:`~tensegrity.physics.dynamics.internal_damping` made it critical for 100 N/m, so
# the stiffer prisms are less than critically damped and overshoot. Two summaries from the series,
# by reductions over ``t``: the largest displacement over the settled one, and the time after which
# each loaded case stays within 1 % of its settled displacement. The figure shows the cases of 200
# N/m, each load a line.
left = float(ds.kinetic_energy.isel(t=-1).max())
print(f"kinetic energy left at {float(ds.t[-1]):g} s, the most of any case: {left:.1e} J")
loaded = grid.max_displacement.sel(load=[5.0, 10.0, 20.0, 40.0])
final = loaded.isel(t=-1)
print("largest over settled displacement:")
print((loaded.max("t") / final).round(3).to_pandas())
outside = abs(loaded - final) > 0.01 * final
settling = loaded.t.where(outside).max("t") + spec.sample_dt
print("time to stay within 1 % of the settled displacement [s]:")
print(settling.round(2).to_pandas())

in_time = new_figure((7.0, 4.0))
ax = in_time.subplots()
(1e3 * loaded.sel(stiffness=200.0, t=slice(0.0, 2.0))).plot.line(x="t", hue="load", ax=ax)
ax.set_xlabel("t [s]")
ax.set_ylabel("largest node displacement [mm]")
ax.set_title("Stiffness 200 N/m, the load held from t = 0")
