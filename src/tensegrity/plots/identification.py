"""The figure of a fit (:func:`tensegrity.analysis.identification.fit`): measured marker
positions against the fitted model's motion, and the starting model's."""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from tensegrity.analysis.identification import Experiment, Fit, simulated_markers
from tensegrity.model.structure import Structure
from tensegrity.plots.figures import FIGURE_DPI, new_figure, save_png

__all__ = ["MAX_MARKERS", "figure_fit"]

#: At most this many markers (rows of the figure) are drawn.
MAX_MARKERS = 6


def figure_fit(fit: Fit, start: Structure, experiment: Experiment, path: str | Path) -> Path:
    """Write ``path`` (PNG): for each of the first :data:`MAX_MARKERS` markers of
    ``experiment``, its coordinates [m] against time [s]: the measurements (dots), the fitted
    model (``fit.structure``, line) and the starting one (``start``, dashed)."""
    names = list(experiment.markers)[:MAX_MARKERS]
    dim = start.dim
    runs = {"fitted": simulated_markers(fit.structure, experiment)[1]}
    with contextlib.suppress(RuntimeError):  # a starting model whose run fails: fitted alone
        runs["start"] = simulated_markers(start, experiment)[1]
    figure = new_figure((3.2 * dim, 1.9 * len(names) + 0.6))
    axes = figure.subplots(len(names), dim, squeeze=False, sharex=True)
    for row, name in enumerate(names):
        t, measured = (np.asarray(a, dtype=float) for a in experiment.markers[name])
        node = start.node_index(name)
        for c in range(dim):
            ax = axes[row, c]
            ax.plot(t, measured[:, c], ".", color="black", markersize=3, label="measured")
            for label, style in (("fitted", "-"), ("start", "--")):
                if label in runs:
                    run = runs[label]
                    ax.plot(run.t, run.node_position[:, node, c], style, lw=1.2, label=label)
            ax.set_ylabel(f"{name} {'xyz'[c]} [m]")
    axes[0, 0].legend(fontsize=7, loc="best")
    for c in range(dim):
        axes[-1, c].set_xlabel("t [s]")
    figure.suptitle(f"{experiment.name}: rms error {fit.rms_error:.3g} m")
    return save_png(figure, path, dpi=FIGURE_DPI)
