"""The figure of a fit (:func:`tensegrity.analysis.identification.fit`): measured marker
positions against the fitted model's motion, and the starting model's."""

from __future__ import annotations

import contextlib
import dataclasses
from pathlib import Path

import numpy as np

from tensegrity.analysis.identification import Experiment, Fit, simulated_measurements
from tensegrity.model.structure import Structure
from tensegrity.plots.figures import FIGURE_DPI, new_figure, save_png

__all__ = ["MAX_MARKERS", "figure_fit"]

#: At most this many measured items (markers, then tendons: the figure's rows) are drawn.
MAX_MARKERS = 6


def figure_fit(
    fit: Fit, start: Structure, experiment: Experiment, path: str | Path, *, index: int = 0
) -> Path:
    """Write ``path`` (PNG): for each of the first :data:`MAX_MARKERS` measured items of
    ``experiment`` (markers, then tendons' lengths and tensions), its coordinates [m], length
    [m] or tension [N] against time [s]: the measurements (dots), the fitted model
    (``fit.structure`` with the fitted options of the fit's experiment ``index``, which
    ``experiment`` is: its ground's fitted friction, line) and the starting one (``start``,
    dashed)."""
    rows = [(kind, name) for kind, series in experiment.series().items() for name in series][
        :MAX_MARKERS
    ]
    dim = start.dim if any(kind == "markers" for kind, _ in rows) else 1
    fitted = dataclasses.replace(experiment, options=fit.options[index])
    runs = {"fitted": simulated_measurements(fit.structure, fitted).run}
    with contextlib.suppress(RuntimeError):  # a starting model whose run fails: fitted alone
        runs["start"] = simulated_measurements(start, experiment).run
    figure = new_figure((3.2 * dim, 1.9 * len(rows) + 0.6))
    axes = figure.subplots(len(rows), dim, squeeze=False, sharex=True)
    for row, (kind, name) in enumerate(rows):
        t, measured = (np.asarray(a, dtype=float) for a in experiment.series()[kind][name])
        if kind == "markers":
            node = start.node_index(name)
            curves = {which: run.node_position[:, node] for which, run in runs.items()}
            labels = [f"{name} {'xyz'[c]} [m]" for c in range(dim)]
        else:
            tendon = start.tendon_index(name)
            field = "tendon_length" if kind == "lengths" else "tendon_tension"
            curves = {which: getattr(run, field)[:, tendon, None] for which, run in runs.items()}
            measured = measured[:, None]
            labels = [f"{name} {kind[:-1]} [{'m' if kind == 'lengths' else 'N'}]"]
            for c in range(1, dim):
                axes[row, c].set_axis_off()
        for c, label in enumerate(labels):
            ax = axes[row, c]
            ax.plot(t, measured[:, c], ".", color="black", markersize=3, label="measured")
            for which, style in (("fitted", "-"), ("start", "--")):
                if which in runs:
                    ax.plot(runs[which].t, curves[which][:, c], style, lw=1.2, label=which)
            ax.set_ylabel(label)
    axes[0, 0].legend(fontsize=7, loc="best")
    for c in range(dim):  # (the time axis under each column's lowest drawn plot)
        lowest = [ax for ax in axes[:, c] if ax.axison][-1]
        lowest.tick_params(labelbottom=True)
        lowest.set_xlabel("t [s]")
    figure.suptitle(f"{experiment.name}: rms error {fit.rms_summary()}")
    return save_png(figure, path, dpi=FIGURE_DPI)
