"""Parameter sweeps on Dask (:mod:`~tensegrity.sweep.run`): a grid or a Monte Carlo sample of
cases, run in parallel, gathered into one labeled dataset."""

from tensegrity.sweep.run import SweepResult, SweepSpec, read_sweep, run_sweep

__all__ = ["SweepResult", "SweepSpec", "read_sweep", "run_sweep"]
