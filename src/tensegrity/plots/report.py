"""Figures of the analyses (the verbs' tables and JSON files: :mod:`tensegrity.cli.tables`).

Figures are :class:`matplotlib.figure.Figure` objects with an Agg canvas (no pyplot), as in
:mod:`tensegrity.plots.figures`, saved atomically.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from tensegrity.plots.figures import (
    draw_structure,
    natural_key,
    new_figure,
    save_png,
    tendon_family,
)

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from tensegrity.analysis.controllability import ReachResult
    from tensegrity.analysis.modes import ModalAnalysis
    from tensegrity.analysis.shape_control import ClosedLoop, QuasiStatic

KIND_COLORS = {
    "rigid": "#7f7f7f",
    "mechanism": "#d62728",
    "elastic": "#2f6fb0",
    "unstable": "#ff7f0e",
}


def save_figure(figure: Figure, path: str | Path, *, dpi: int = 130) -> Path:
    """Save a figure as PNG, atomically (:func:`tensegrity.plots.figures.save_png`)."""
    return save_png(figure, path, dpi=dpi)


# ------------------------------------------------------------------------------ modes
def figure_frequencies(modes: ModalAnalysis, *, title: str = "Natural frequencies") -> Figure:
    """Frequencies [Hz] against mode number, coloured by kind (rigid, mechanism, elastic)."""
    fig = new_figure((11.0, 4.6))
    ax, ax_table = fig.subplots(1, 2, width_ratios=[2.2, 1])
    index = np.arange(len(modes.kind))
    for kind, color in KIND_COLORS.items():
        sel = [i for i, k in enumerate(modes.kind) if k == kind]
        if sel:
            ax.vlines(index[sel], 0, modes.frequency_hz[sel], color=color, lw=2)
            ax.plot(
                index[sel],
                modes.frequency_hz[sel],
                "o",
                color=color,
                ms=4,
                label=f"{kind} ({len(sel)})",
            )
    ax.set_xlabel("mode")
    ax.set_ylabel("frequency [Hz]")
    ax.set_title(title, fontsize="medium")
    ax.legend(fontsize="small", loc="upper left")
    ax.grid(alpha=0.3)
    _frequency_table(ax_table, modes)
    return fig


def _frequency_table(ax: Axes, modes: ModalAnalysis, max_rows: int = 18) -> None:
    """Distinct frequencies (to 1e-6 relative) with their modes, multiplicity and kind."""
    rows: list[list[str]] = []
    for i, (f, kind) in enumerate(zip(modes.frequency_hz, modes.kind, strict=True)):
        if rows and rows[-1][3] == kind and abs(f - rows[-1][4]) <= 1e-6 * max(f, 1e-300):
            rows[-1][0] = rows[-1][0].split("-")[0] + f"-{i}"
            rows[-1][2] = str(int(rows[-1][2]) + 1)
        else:
            rows.append([str(i), f"{f:.4g}", "1", kind, f])
    shown = [r[:4] for r in rows[:max_rows]]
    if len(rows) > max_rows:
        shown.append(["...", f"{len(rows) - max_rows} more", "", ""])
    ax.axis("off")
    table = ax.table(
        cellText=shown,
        colLabels=["modes", "f [Hz]", "mult.", "kind"],
        loc="upper center",
        cellLoc="center",
    )
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    table.scale(1.0, 1.1)


def figure_mode_shapes(
    modes: ModalAnalysis,
    indices: Sequence[int],
    *,
    amplitude: float | None = None,
    columns: int = 3,
) -> Figure:
    """The equilibrium (grey) and each mode's displaced shape (largest node displacement
    ``amplitude`` [m], default 15% of the structure's size), one 3-D panel per mode."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    lin = modes.linearization
    s, p0 = lin.structure, lin.equilibrium.node_position
    size = float(np.ptp(p0, axis=0).max()) or 1.0
    amplitude = 0.15 * size if amplitude is None else amplitude
    rows = max(1, math.ceil(len(indices) / columns))
    fig = new_figure((4.0 * min(columns, len(indices)), 3.8 * rows))
    for k, i in enumerate(indices):
        ax = fig.add_subplot(rows, min(columns, len(indices)), k + 1, projection="3d")
        shape = modes.node_shapes[i]
        largest = float(np.max(np.linalg.norm(shape, axis=1))) or 1.0
        p = p0 + amplitude / largest * shape
        pairs = np.vstack([s.rod_nodes, s.tendon_nodes])
        ax.add_collection3d(Line3DCollection(p0[pairs], colors="0.8", linewidths=0.8))
        draw_structure(ax, s, p, None, legend=False, show_nodes=False)
        ax.set_title(
            f"mode {i}: {modes.frequency_hz[i]:.4g} Hz ({modes.kind[i]})", fontsize="small"
        )
        ax.tick_params(labelsize="x-small")
    return fig


# ------------------------------------------------------------------------------ controllability
def figure_reach(results: Sequence[ReachResult], modes: ModalAnalysis) -> Figure:
    """Which mode clusters each input (output) set reaches (sees): a PBH map."""
    clusters = list(results[0].mode_tests)
    data = np.array([[t.rank / t.multiplicity for t in r.mode_tests] for r in results])
    fig = new_figure((max(6.0, 0.22 * len(clusters) + 3), 0.35 * len(results) + 2.2))
    ax = fig.add_subplot()
    image = ax.imshow(data, aspect="auto", cmap="RdYlGn", vmin=0, vmax=1, interpolation="nearest")
    ax.set_yticks(
        range(len(results)),
        [f"{r.name} ({r.rank}/{r.n_states})" for r in results],
        fontsize="small",
    )
    labels = ["rigid" if t.kind == "rigid" else f"{t.frequency_hz:.3g}" for t in clusters]
    ax.set_xticks(range(len(clusters)), labels, rotation=90, fontsize="x-small")
    ax.set_xlabel("mode cluster (frequency [Hz])")
    kind = results[0].property
    ax.set_title(
        f"PBH test of {kind}: fraction of each cluster reached"
        if kind == "controllability"
        else f"PBH test of {kind}: fraction of each cluster seen",
        fontsize="medium",
    )
    fig.colorbar(image, ax=ax, shrink=0.8)
    return fig


# ------------------------------------------------------------------------------ shape control
def figure_shape_motion(plan: QuasiStatic, closed: ClosedLoop | None = None) -> Figure:
    """Outputs against time (closed loop) or step (open loop), with their targets."""
    names, units = plan.output.names, plan.output.units
    fig = new_figure((8.0, 2.6 * len(names)))
    axes = fig.subplots(len(names), 1, sharex=True, squeeze=False)[:, 0]
    for j, ax in enumerate(axes):
        if closed is not None:
            ax.plot(
                closed.t, closed.outputs[:, j], color="#2f6fb0", label="closed loop (nonlinear)"
            )
            ax.plot(
                closed.t,
                closed.reference_outputs[:, j],
                "--",
                color="0.4",
                label="quasi-static plan",
            )
            final = plan.targets[-1, j]
            if np.isfinite(final):
                ax.axhline(final, color="#d62728", lw=0.8, label="final target")
        else:
            steps = np.arange(len(plan.equilibria))
            ax.plot(steps, plan.outputs[:, j], "o-", color="#2f6fb0", label="equilibria")
            ax.plot(steps, plan.targets[:, j], "x", color="#d62728", label="targets")
        ax.set_ylabel(f"{names[j]} [{units[j]}]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small")
    axes[-1].set_xlabel("step" if closed is None else "time [s]")
    fig.suptitle("Shape control: outputs", fontsize="medium")
    return fig


def figure_shape_controls(plan: QuasiStatic, closed: ClosedLoop | None = None) -> Figure:
    """Rest-length changes ``u`` of every tendon and the smallest tension."""
    fig = new_figure((8.0, 6.0))
    ax_u, ax_t = fig.subplots(2, 1, sharex=True)
    if closed is not None:
        x, u, tmin, xlabel = closed.t, closed.control, closed.tension.min(axis=1), "time [s]"
    else:
        x = np.arange(len(plan.equilibria))
        u, tmin, xlabel = plan.control, plan.min_tension, "step"
    names = plan.structure.tendon_name
    families = sorted(set(map(tendon_family, names)), key=natural_key)
    colors = {f: f"C{k % 10}" for k, f in enumerate(families)}
    labelled: set[str] = set()
    for j, family in enumerate(tendon_family(n) for n in names):
        label = family if family not in labelled and len(families) <= 12 else None
        labelled.add(family)
        ax_u.plot(x, u[:, j], lw=0.9, color=colors[family], label=label)
    if len(families) <= 12:
        ax_u.legend(
            fontsize="small",
            ncols=min(len(families), 6),
            title="tendon family",
            title_fontsize="small",
        )
    ax_u.set_ylabel("rest-length change u [m]")
    ax_u.grid(alpha=0.3)
    ax_t.plot(x, tmin, color="#2f6fb0", label="smallest tendon tension")
    ax_t.axhline(plan.bounds.min_tension, color="#d62728", lw=0.8, label="floor")
    ax_t.set_ylabel("tension [N]")
    ax_t.set_xlabel(xlabel)
    ax_t.grid(alpha=0.3)
    ax_t.legend(fontsize="small")
    fig.suptitle(
        "Shape control: controls (every tendon) and the smallest tension", fontsize="medium"
    )
    return fig


def figure_shape_structures(plan: QuasiStatic) -> Figure:
    """The structure before and after, tendons coloured by tension."""
    fig = new_figure((11.0, 5.0))
    first, last = plan.equilibria[0], plan.equilibria[-1]
    for k, (eq, title) in enumerate([(first, "initial equilibrium"), (last, "final equilibrium")]):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        artists = draw_structure(ax, plan.structure, eq.node_position, eq.tension, legend=k == 0)
        if artists["mappable"] is not None:
            fig.colorbar(
                artists["mappable"], ax=ax, shrink=0.6, pad=0.1, label="tendon tension [N]"
            )
        y = plan.output.value(eq.node_position)
        ax.set_title(
            title
            + ": "
            + ", ".join(
                f"{n} {v:.4g} {u}"
                for n, v, u in zip(plan.output.names, y, plan.output.units, strict=True)
            ),
            fontsize="small",
        )
    return fig
