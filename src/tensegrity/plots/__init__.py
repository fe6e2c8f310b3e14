"""Figures (matplotlib): :mod:`~tensegrity.plots.figures` for structures and trajectories,
:mod:`~tensegrity.plots.report` for the analysis verbs' figures."""
