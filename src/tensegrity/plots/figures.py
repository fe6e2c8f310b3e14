"""Figures of a structure and of a simulation, like the paper's Figures 18.10-18.12.

- :func:`figure_structure` -- the structure in 3-D: rods thick and dark, tendons thin (coloured by
  tension when tensions are given), slack tendons dashed red (Figures 18.10 and 18.11);
- :func:`figure_tendon_lengths` -- tendon lengths against time (Figure 18.12);
- :func:`figure_utilisation` -- the structure with every member (rods too) coloured by its
  largest utilisation over a run (:mod:`tensegrity.design.utilisation`), failing members
  (utilisation > 1) in :data:`FAILURE_COLOR`;
- :func:`save_figures` -- the three figures of a simulation as PNG files, written atomically.

Figures are built as :class:`matplotlib.figure.Figure` objects with the Agg canvas, without
``pyplot``: nothing here changes the global backend or pyplot state, no window opens, and the
functions work in headless sessions and alongside a user's own interactive backend.  To show a
figure in a notebook, display the returned ``Figure``; to draw into your own 3-D axes, use
:func:`draw_structure`.

SI units throughout: positions and lengths in m, tensions in N, time in s.
"""

from __future__ import annotations

import re
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from tensegrity.io.files import atomic_path
from tensegrity.model.structure import Structure

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Path3DCollection
    from mpl_toolkits.mplot3d.axes3d import Axes3D

    from tensegrity.engine.result import SimulationResult

ROD_COLOR = "#26282b"
TENDON_COLOR = "#2f6fb0"
SLACK_COLOR = "#d62728"
FIXED_COLOR = "#8c564b"
#: Members whose utilisation exceeds 1 (they yield, break or buckle): apart from the colour map
#: and from the slack tendons' red.
FAILURE_COLOR = "#ff00d4"
#: A run's planes (the ground, inclines, walls: semi-transparent patches, :data:`PLANE_ALPHA`
#: opaque) and the grid drawn on them, so that rolling and sliding show.
PLANE_COLOR = "#c8b48c"
PLANE_GRID_COLOR = "#8c7a55"
PLANE_ALPHA = 0.45
#: Rod ends in contact with a plane: sticking (held) and slipping (kinetic friction); free ends
#: are not marked.
STICK_COLOR = "#ff7f0e"
SLIP_COLOR = "#1fb6e8"
#: Colour map of tendon tension; the yellow end is cut off so that every tendon shows on white.
TENSION_CMAP = "viridis"
_CMAP_RANGE = (0.0, 0.85)
ROD_WIDTH = 4.0
TENDON_WIDTH = 1.3
#: Resolution of the figures a run writes [dots per inch]: about 1100 x 1000 pixels for the
#: structure figures.
FIGURE_DPI = 150
#: At most this many tendons get a legend entry each in :func:`figure_tendon_lengths`.
MAX_LEGEND_TENDONS = 12
#: Above this many tendons, :func:`figure_tendon_lengths` draws the range and median only.
MAX_TENDON_LINES = 500


def new_figure(figsize: tuple[float, float]) -> Figure:
    """A matplotlib ``Figure`` of ``figsize`` (width, height) [inches], constrained layout, with
    its own Agg canvas: outside pyplot's figure manager (nothing left open, safe in threads)."""
    figure = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def tension_colormap():
    """The tension colour map (a matplotlib ``Colormap``): :data:`TENSION_CMAP` with its
    yellow end cut off, so that every tendon shows on white; the figures', the animations' and
    the viewer's."""
    import matplotlib
    from matplotlib.colors import ListedColormap

    base = matplotlib.colormaps[TENSION_CMAP]
    return ListedColormap(base(np.linspace(*_CMAP_RANGE, 256)), name=f"{TENSION_CMAP}_cut")


def utilisation_colors(utilisation: Any, high: float) -> np.ndarray:
    """RGBA colours (..., 4) of utilisations (...): the tension colour map over the scale
    ``0 .. high`` (``high >= 1``, clipped at its ends), :data:`FAILURE_COLOR` above 1; the
    figures' and the viewer's (``viewer.js`` applies the same rule)."""
    from matplotlib.colors import to_rgba

    u = np.asarray(utilisation, dtype=float)
    colors = tension_colormap()(np.clip(u / high, 0.0, 1.0))
    colors[u > 1.0] = to_rgba(FAILURE_COLOR)
    return colors


def utilisation_colormap(high: float):
    """The colour bar of :func:`utilisation_colors` (a matplotlib ``Colormap`` over
    ``0 .. high``): the tension colour map up to 1, :data:`FAILURE_COLOR` above."""
    from matplotlib.colors import ListedColormap

    return ListedColormap(utilisation_colors(np.linspace(0.0, high, 512), high), "utilisation")


def _positions(structure: Structure, node_position: Any) -> np.ndarray:
    """Node positions (N, 3) to draw; a planar structure's (N, 2) are drawn in the plane z = 0."""
    p = np.asarray(node_position, dtype=float)
    if p.shape != (structure.n_nodes, structure.dim):
        raise ValueError(
            f"node_position: expected shape ({structure.n_nodes}, {structure.dim}) for this "
            f"structure, got {p.shape}"
        )
    return p if structure.dim == 3 else np.hstack([p, np.zeros((structure.n_nodes, 1))])


def _tensions(structure: Structure, tension: Any) -> np.ndarray | None:
    if tension is None:
        return None
    t = np.asarray(tension, dtype=float)
    if t.shape != (structure.n_tendons,):
        raise ValueError(
            f"tension: expected shape ({structure.n_tendons},) for this structure, got {t.shape}"
        )
    return t


def draw_structure(
    ax: Axes3D,
    structure: Structure,
    node_position: Any,
    tension: Any = None,
    *,
    color_by_tension: bool = True,
    show_nodes: bool = True,
    legend: bool = True,
) -> dict[str, Any]:
    """Draw a structure on 3-D axes: rods thick and dark, tendons thin, slack tendons dashed.

    The axes get equal scales on x, y and z (``set_box_aspect`` from the data ranges), limits
    that fit the structure and labels in m.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        Axes with ``projection="3d"``.
    structure : Structure
        ``N`` nodes, ``R`` rods, ``S`` tendons.
    node_position : array_like, shape (N, 3)
        Node positions to draw [m] (e.g. ``result.node_position[k]``).
    tension : array_like, shape (S,), optional
        Tendon tensions [N].  Tendons with ``tension <= 0`` are slack: drawn dashed in red, with a
        legend entry ``"slack tendons (k)"``.  Taut tendons are coloured by tension
        (``color_by_tension``; see the returned ``"mappable"`` for a colour bar), unless their
        tensions agree to 1e-4 relative (one colour then, no colour bar).
    color_by_tension : bool
        Colour taut tendons by tension (default) rather than in one colour.
    show_nodes : bool
        Mark the nodes (rod ends) with dots.  Fixed nodes (``structure.node_fixed``: supports
        and anchors) are always marked, with triangles and a legend entry ``"fixed nodes (k)"``.
    legend : bool
        Add a legend (rods, tendons, slack tendons and fixed nodes if any).

    Returns
    -------
    dict
        The artists: ``"rods"``, ``"tendons"`` (taut or all; None if there is none), ``"slack"``
        (None if no tendon is slack), ``"nodes"`` (or None), ``"fixed"`` (None if no node is
        fixed), and ``"mappable"``: a ``ScalarMappable`` of the tension
        colours, or None.
    """
    p = _positions(structure, node_position)
    tension = _tensions(structure, tension)
    slack = np.zeros(structure.n_tendons, bool) if tension is None else tension <= 0
    mappable, tendon_colors = _tendon_colors(tension, slack, color_by_tension)
    tendons, slack_lines, rods = _draw_lines(ax, structure, p, slack, tendon_colors)
    nodes, fixed = _draw_nodes(ax, structure, p, show_nodes)
    fit_axes(ax, np.array([p.min(axis=0), p.max(axis=0)]))
    if legend:
        handles = _legend_handles(structure, tension, slack, mappable, fixed is not None)
        ax.legend(handles=handles, loc="upper left", fontsize="small", framealpha=0.85)
    return {
        "rods": rods,
        "tendons": tendons,
        "slack": slack_lines,
        "nodes": nodes,
        "fixed": fixed,
        "mappable": mappable,
    }


def _tendon_colors(
    tension: np.ndarray | None, slack: np.ndarray, color_by_tension: bool
) -> tuple[ScalarMappable | None, np.ndarray | str]:
    """The taut tendons' colours: by tension (with its mappable) or one colour (and None)."""
    taut_tension = None if tension is None else tension[~slack]
    if (
        color_by_tension
        and taut_tension is not None
        and taut_tension.size
        and not _uniform(taut_tension)
    ):
        low, high = float(taut_tension.min()), float(taut_tension.max())
        mappable = ScalarMappable(Normalize(low, high), tension_colormap())
        mappable.set_array(taut_tension)
        return mappable, mappable.to_rgba(taut_tension)
    return None, TENDON_COLOR


def _segments(p: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """The line segments (K, 2, 3) between the node ``pairs`` (K, 2) at positions ``p``."""
    return p[pairs] if len(pairs) else np.zeros((0, 2, 3))


def _draw_lines(
    ax: Axes3D,
    structure: Structure,
    p: np.ndarray,
    slack: np.ndarray,
    tendon_colors: np.ndarray | str,
    rod_colors: np.ndarray | str = ROD_COLOR,
) -> tuple[Line3DCollection | None, Line3DCollection | None, Line3DCollection | None]:
    """Draw the taut tendons, the slack ones (dashed) and the rods; each collection or None."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    tendon_pairs = structure.tendon_nodes
    taut_pairs = tendon_pairs[~slack]
    tendons = None
    if len(taut_pairs):  # matplotlib cannot add an empty 3-D collection
        tendons = Line3DCollection(
            _segments(p, taut_pairs), colors=tendon_colors, linewidths=TENDON_WIDTH, zorder=1
        )
        ax.add_collection3d(tendons)
    slack_lines = None
    if slack.any():
        slack_lines = Line3DCollection(
            _segments(p, tendon_pairs[slack]),
            colors=SLACK_COLOR,
            linewidths=TENDON_WIDTH + 0.3,
            linestyles=(0, (4, 2.5)),
            zorder=2,
        )
        ax.add_collection3d(slack_lines)
    rods = None
    if structure.n_rods:  # (a structure of point masses has none)
        rods = Line3DCollection(
            _segments(p, structure.rod_nodes),
            colors=rod_colors,
            linewidths=ROD_WIDTH,
            zorder=3,
            capstyle="round",
        )
        ax.add_collection3d(rods)
    return tendons, slack_lines, rods


def _draw_nodes(
    ax: Axes3D, structure: Structure, p: np.ndarray, show_nodes: bool
) -> tuple[Path3DCollection | None, Path3DCollection | None]:
    """Mark the nodes (or only the point masses) and the fixed nodes; each collection or None."""
    nodes = None
    if show_nodes:
        nodes = ax.scatter(*p.T, s=14, color=ROD_COLOR, depthshade=False, zorder=4)
    elif structure.point_mass_nodes.size:  # point masses are bodies: always drawn
        nodes = ax.scatter(
            *p[structure.point_mass_nodes].T, s=30, color=ROD_COLOR, depthshade=False, zorder=4
        )
    fixed = None
    if structure.node_fixed.any():
        fixed = ax.scatter(
            *p[structure.node_fixed].T,
            s=60,
            marker="^",
            color=FIXED_COLOR,
            depthshade=False,
            zorder=5,
        )
    return nodes, fixed


def _legend_handles(
    structure: Structure,
    tension: np.ndarray | None,
    slack: np.ndarray,
    mappable: ScalarMappable | None,
    has_fixed: bool,
) -> list[Line2D]:
    """Legend entries: rods, (taut) tendons, slack tendons and fixed nodes, with counts."""
    handles = [
        Line2D(
            [],
            [],
            color=ROD_COLOR,
            lw=ROD_WIDTH,
            solid_capstyle="round",
            label=f"rods ({structure.n_rods})",
        )
    ]
    n_taut = int(np.count_nonzero(~slack))
    if n_taut or tension is None:
        color = mappable.cmap(0.5) if mappable is not None else TENDON_COLOR
        what = "tendons" if tension is None else "taut tendons"
        handles.append(
            Line2D([], [], color=color, lw=TENDON_WIDTH + 0.5, label=f"{what} ({n_taut})")
        )
    if slack.any():
        handles.append(
            Line2D(
                [],
                [],
                color=SLACK_COLOR,
                lw=TENDON_WIDTH + 0.5,
                ls=(0, (4, 2.5)),
                label=f"slack tendons ({int(slack.sum())})",
            )
        )
    if has_fixed:
        handles.append(
            Line2D(
                [],
                [],
                color=FIXED_COLOR,
                marker="^",
                ls="",
                markersize=8,
                label=f"fixed nodes ({int(structure.node_fixed.sum())})",
            )
        )
    return handles


def _uniform(values: np.ndarray) -> bool:
    """True if ``values`` agree to 1e-4 relative: one colour, no colour bar."""
    return float(np.ptp(values)) <= 1e-4 * float(np.max(np.abs(values)))


def fit_axes(ax: Axes3D, bounds: np.ndarray) -> None:
    """Limits around ``bounds`` (2, 3) [m] (the lowest and highest corner of what is drawn)
    with a margin, equal scales, labels in m; a flat structure still gets a visible box."""
    low, high = np.asarray(bounds, dtype=float)
    span = high - low
    size = float(span.max()) if span.max() > 0 else 1.0
    span = np.maximum(span, 0.08 * size)
    centre = 0.5 * (low + high)
    half = 0.5 * span + 0.04 * size
    ax.set_xlim(centre[0] - half[0], centre[0] + half[0])
    ax.set_ylim(centre[1] - half[1], centre[1] + half[1])
    ax.set_zlim(centre[2] - half[2], centre[2] + half[2])
    ax.set_box_aspect(tuple(2 * half))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(nbins=5))
    ax.tick_params(labelsize="small")


def figure_structure(
    structure: Structure,
    node_position: Any,
    tension: Any = None,
    *,
    title: str | None = "Tensegrity structure",
    subtitle: str | None = None,
    elev: float = 22.0,
    azim: float = -58.0,
    figsize: tuple[float, float] = (7.5, 6.5),
) -> Figure:
    """A figure of the structure at ``node_position``, optionally with tensions (Fig. 18.10/18.11).

    Parameters
    ----------
    structure : Structure
    node_position : array_like, shape (N, 3)
        Node positions [m].
    tension : array_like, shape (S,), optional
        Tendon tensions [N]: taut tendons are coloured by tension (with a colour bar), slack ones
        (``<= 0``) dashed red.
    title : str, optional
        Figure title.
    subtitle : str, optional
        A second, smaller line; default: counts of nodes, rods, tendons (slack, tension range).
    elev, azim : float
        View angles [degrees].
    figsize : (float, float)
        Size [inches].

    Returns
    -------
    matplotlib.figure.Figure
        With an Agg canvas; save it with ``figure.savefig(path)``.
    """
    figure = new_figure(figsize)
    ax = figure.add_subplot(projection="3d")
    artists = draw_structure(ax, structure, node_position, tension)
    ax.view_init(elev=elev, azim=azim)
    if artists["mappable"] is not None:
        figure.colorbar(artists["mappable"], ax=ax, shrink=0.6, pad=0.1, label="tendon tension [N]")
    if subtitle is None:
        subtitle = (
            f"{structure.n_nodes} nodes, {structure.n_rods} rods, {structure.n_tendons} tendons"
        )
        t = _tensions(structure, tension)
        if t is not None and t.size:
            n_slack = int(np.sum(t <= 0))
            taut = t[t > 0]
            subtitle += f"; {n_slack} slack" if n_slack else "; all taut"
            if taut.size and _uniform(taut):
                subtitle += f"; tension {taut.mean():.4g} N" + (
                    " in every taut tendon" if n_slack else " in every tendon"
                )
            elif taut.size:
                subtitle += f"; tension {taut.min():.4g} .. {taut.max():.4g} N"

    _titles(figure, title, subtitle)
    return figure


def figure_utilisation(
    structure: Structure,
    node_position: Any,
    rod_utilisation: Any,
    tendon_utilisation: Any,
    *,
    high: float | None = None,
    title: str | None = "Largest member utilisation over the run",
    subtitle: str | None = None,
    elev: float = 22.0,
    azim: float = -58.0,
    figsize: tuple[float, float] = (7.5, 6.5),
) -> Figure:
    """A figure of the structure at ``node_position`` with every member coloured by its
    utilisation (:func:`utilisation_colors`), e.g. its largest over a run
    (:class:`~tensegrity.design.utilisation.TrajectoryUtilisation`'s ``rod_peak`` and
    ``tendon_peak``): a colour bar over ``0 .. high``, failing members (> 1) in
    :data:`FAILURE_COLOR` with a legend entry and their count.

    Parameters
    ----------
    structure : Structure
        ``N`` nodes, ``R`` rods, ``S`` tendons.
    node_position : array_like, shape (N, 3)
        Node positions [m] (``(N, 2)`` for a planar structure).
    rod_utilisation : array_like, shape (R,)
        The rods' governing utilisation (the larger of yield and buckling).
    tendon_utilisation : array_like, shape (S,)
        The tendons' (yield).
    high : float, optional
        Top of the colour scale; default ``max(1, largest utilisation given)``.
    title, subtitle : str, optional
        Default subtitle: the counts, the largest utilisation and the failing members.
    elev, azim : float
        View angles [degrees].
    figsize : (float, float)
        Size [inches].

    Returns
    -------
    matplotlib.figure.Figure
        With an Agg canvas.
    """
    p = _positions(structure, node_position)
    rod = np.asarray(rod_utilisation, dtype=float).reshape(structure.n_rods)
    tendon = np.asarray(tendon_utilisation, dtype=float).reshape(structure.n_tendons)
    largest = float(max(rod.max(initial=0.0), tendon.max(initial=0.0)))
    high = max(1.0, largest) if high is None else float(high)
    figure = new_figure(figsize)
    ax = figure.add_subplot(projection="3d")
    _draw_lines(
        ax,
        structure,
        p,
        np.zeros(structure.n_tendons, bool),
        utilisation_colors(tendon, high),
        utilisation_colors(rod, high),
    )
    _draw_nodes(ax, structure, p, False)
    fit_axes(ax, np.array([p.min(axis=0), p.max(axis=0)]))
    ax.view_init(elev=elev, azim=azim)
    failing = int(np.sum(rod > 1) + np.sum(tendon > 1))
    shown = "0.45"  # (a member's colour is its utilisation's: the keys show the widths)
    handles = [
        Line2D([], [], color=shown, lw=ROD_WIDTH, label=f"rods ({structure.n_rods})"),
        Line2D([], [], color=shown, lw=TENDON_WIDTH + 0.5, label=f"tendons ({tendon.size})"),
    ]
    if failing:
        handles.append(
            Line2D([], [], color=FAILURE_COLOR, lw=ROD_WIDTH, label=f"failing, > 1 ({failing})")
        )
    ax.legend(handles=handles, loc="upper left", fontsize="small", framealpha=0.85)
    mappable = ScalarMappable(Normalize(0.0, high), utilisation_colormap(high))
    figure.colorbar(mappable, ax=ax, shrink=0.6, pad=0.1, label="utilisation")
    if subtitle is None:
        subtitle = (
            f"{structure.n_nodes} nodes, {structure.n_rods} rods, {structure.n_tendons} "
            f"tendons; largest {largest:.3g}; "
            + (f"{failing} failing (> 1)" if failing else "none failing")
        )
    _titles(figure, title, subtitle)
    return figure


def _titles(figure: Figure, title: str | None, subtitle: str | None) -> None:
    if title and subtitle:
        figure.suptitle(f"{title}\n", fontsize="large", fontweight="bold")
        figure.text(
            0.5,
            0.955,
            subtitle,
            ha="center",
            va="top",
            fontsize="small",
            color="0.3",
            transform=figure.transFigure,
        )
    elif title:
        figure.suptitle(title, fontsize="large", fontweight="bold")
    elif subtitle:
        figure.suptitle(subtitle, fontsize="small", fontweight="normal")


def tendon_family(name: str) -> str:
    """``"t3_2_1"`` -> ``"t3"``: the name without trailing ``_<number>`` indices."""
    return re.sub(r"(_\d+)+$", "", name) or name


def natural_key(text: str) -> list:
    """Sort key with numbers compared as numbers: ``t9`` before ``t10``."""
    return [
        (0, int(part), "") if part.isdigit() else (1, 0, part)
        for part in re.split(r"(\d+)", text)
        if part
    ]


def figure_tendon_lengths(
    time: Any,
    tendon_length: Any,
    names: Sequence[str],
    *,
    rest_length: Any = None,
    title: str | None = "Tendon lengths",
    subtitle: str | None = None,
    figsize: tuple[float, float] = (8.0, 5.0),
) -> Figure:
    """Tendon lengths against time, one line per tendon (Figure 18.12).

    With at most ``MAX_LEGEND_TENDONS`` tendons each gets a legend entry.  Otherwise, if the names
    fall into a few families (``t3_1_1``, ``t3_2_1``, ... form family ``t3``, as for a shell),
    lines are coloured by family with one legend entry per family; if not, a note gives the count
    instead of a legend.  Above ``MAX_TENDON_LINES`` tendons only the range (min..max over
    tendons) and the median are drawn.

    Parameters
    ----------
    time : array_like, shape (T,)
        Sample times [s].
    tendon_length : array_like, shape (T, S)
        Tendon lengths [m].
    names : sequence of str, length S
        Tendon names.
    rest_length : float or array_like, shape (S,), optional
        Rest lengths [m]; if all equal, drawn as a dashed line (a tendon below it is slack).
    title, subtitle : str, optional
    figsize : (float, float)
        Size [inches].

    Returns
    -------
    matplotlib.figure.Figure
    """
    t = np.asarray(time, dtype=float)
    lengths = np.asarray(tendon_length, dtype=float)
    names = list(names)
    if t.ndim != 1 or lengths.shape != (t.size, len(names)):
        raise ValueError(
            f"tendon_length: expected shape (T, S) = ({t.size}, {len(names)}) for {t.size} "
            f"times and {len(names)} names, got {lengths.shape}"
        )
    figure = new_figure(figsize)
    ax = figure.add_subplot()
    note = _plot_tendon_lengths(ax, t, lengths, names)
    if rest_length is not None and names:
        _mark_rest_length(ax, rest_length, len(names))
    if note:
        ax.text(
            0.99,
            0.98,
            note,
            transform=ax.transAxes,
            ha="right",
            va="top",
            fontsize="small",
            color="0.3",
        )
    if t.size > 1:
        ax.set_xlim(t[0], t[-1])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("tendon length [m]")
    ax.grid(True, alpha=0.3)
    _titles(figure, title, subtitle)
    return figure


def _plot_tendon_lengths(
    ax: Axes, t: np.ndarray, lengths: np.ndarray, names: list[str]
) -> str | None:
    """Plot the lengths (T, S) as :func:`figure_tendon_lengths` says; a note for the corner (no
    tendons, or no legend), or None."""
    S = len(names)
    marker = "o" if t.size == 1 else None
    if S == 0:
        return "no tendons"
    if S > MAX_TENDON_LINES:
        ax.fill_between(
            t,
            lengths.min(axis=1),
            lengths.max(axis=1),
            color=TENDON_COLOR,
            alpha=0.25,
            lw=0,
            label=f"range over {S} tendons",
        )
        ax.plot(
            t, np.median(lengths, axis=1), color=TENDON_COLOR, lw=1.5, marker=marker, label="median"
        )
        ax.legend(fontsize="small", loc="best")
    elif S <= MAX_LEGEND_TENDONS:
        for k, name in enumerate(names):
            ax.plot(t, lengths[:, k], lw=1.4, marker=marker, label=name)
        ax.legend(fontsize="small", loc="best", ncols=2 if S > 6 else 1)
    else:
        families = sorted(dict.fromkeys(tendon_family(name) for name in names), key=natural_key)
        if len(families) > 10:
            for k in range(S):
                ax.plot(t, lengths[:, k], lw=1.0, alpha=0.8, marker=marker)
            return f"{S} tendons (legend omitted)"
        _plot_tendon_families(ax, t, lengths, names, families, marker)
    return None


def _plot_tendon_families(
    ax: Axes,
    t: np.ndarray,
    lengths: np.ndarray,
    names: list[str],
    families: list[str],
    marker: str | None,
) -> None:
    """One colour per tendon family, with one legend entry (and count) per family."""
    colors = {f: f"C{k}" for k, f in enumerate(families)}
    for k, name in enumerate(names):
        ax.plot(
            t,
            lengths[:, k],
            lw=1.3,
            color=colors[tendon_family(name)],
            alpha=0.9,
            marker=marker,
        )
    counts = {f: sum(tendon_family(n) == f for n in names) for f in families}
    handles = [Line2D([], [], color=colors[f], lw=2, label=f"{f} ({counts[f]})") for f in families]
    ax.legend(
        handles=handles,
        fontsize="small",
        loc="best",
        title="tendon family",
        title_fontsize="small",
        ncols=2 if len(families) > 5 else 1,
    )


def _mark_rest_length(ax: Axes, rest_length: Any, S: int) -> None:
    """A dashed line at the rest length, if every one of the ``S`` tendons has the same."""
    rest = np.broadcast_to(np.asarray(rest_length, dtype=float), (S,))
    if np.ptp(rest) == 0:
        ax.axhline(rest[0], color="0.35", ls="--", lw=1.0, zorder=0)
        ax.annotate(
            f"rest length {rest[0]:.4g} m",
            (1.0, rest[0]),
            xycoords=("axes fraction", "data"),
            xytext=(-4, -3),
            textcoords="offset points",
            ha="right",
            va="top",
            fontsize="small",
            color="0.35",
        )


#: The files of :func:`save_figures`.
FIGURE_NAMES = ("initial.png", "equilibrium.png", "tendon_lengths.png")


def save_figures(
    result: SimulationResult,
    out_dir: str | Path,
    *,
    dpi: int = FIGURE_DPI,
    history: tuple[np.ndarray, np.ndarray] | None = None,
    names: Collection[str] = FIGURE_NAMES,
) -> list[Path]:
    """Write the figures of a simulation as PNG files in ``out_dir``, each atomically.

    - ``initial.png``: the structure at the first sample (Figure 18.10);
    - ``equilibrium.png``: at the last sample, tendons coloured by tension, slack ones dashed
      (Figure 18.11; titled "Steady-state equilibrium" only if the run reached one);
    - ``tendon_lengths.png``: tendon lengths against time (Figure 18.12).

    Parameters
    ----------
    result : SimulationResult
        A run from :func:`tensegrity.engine.simulate.simulate`, or one read back with
        :func:`tensegrity.io.trajectory.read_trajectory` (e.g. one sample in ten of a long run:
        ``every=10``).
    out_dir : str or pathlib.Path
        Output folder, created if missing.
    dpi : int
        Resolution; the default gives about 1100 x 1000 pixels for the structure figures.
    history : (t (T,) [s], tendon_length (T, S) [m]), optional
        The series of the tendon-length figure, if not the result's own samples: a long run's
        figures from its first and last samples (``result``) and its tendon lengths alone
        (:func:`tensegrity.io.trajectory.read_dataset`).
    names : collection of str
        Which of the three files to write (:data:`FIGURE_NAMES`; e.g. some in one process,
        the others in another).

    Returns
    -------
    list of pathlib.Path
        The files, in the order above.
    """
    unknown = set(names) - set(FIGURE_NAMES)
    if unknown:
        raise ValueError(
            f"names: unknown figures {sorted(unknown)}, expected some of {FIGURE_NAMES}"
        )
    structure, time = result.structure, result.t
    nodes, tension = result.node_position, result.tendon_tension
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if result.status == 1:
        final_title = f"Steady-state equilibrium (t = {time[-1]:.4g} s)"
    elif result.status < 0:
        final_title = f"Last state before failure (t = {time[-1]:.4g} s)"
    else:
        final_title = f"Final configuration (t = {time[-1]:.4g} s)"
    rest = None if (result.settings or {}).get("control") else structure.tendon_rest_length
    series_t, series_length = (time, result.tendon_length) if history is None else history
    figures = {  # each drawn only if asked for
        "initial.png": lambda: figure_structure(
            structure, nodes[0], tension[0], title=f"Initial configuration (t = {time[0]:.4g} s)"
        ),
        "equilibrium.png": lambda: figure_structure(
            structure, nodes[-1], tension[-1], title=final_title
        ),
        "tendon_lengths.png": lambda: figure_tendon_lengths(
            series_t,
            series_length,
            structure.tendon_name,
            rest_length=rest,
            title="Tendon lengths",
            subtitle=_first_upper(result.message),
        ),
    }
    return [
        save_png(draw(), out / name, dpi=dpi) for name, draw in figures.items() if name in names
    ]


#: zlib level of the PNG files: 3 instead of Pillow's 6 takes 0.035 s off each (10,10)
#: structure figure (0.17 -> 0.135 s) for files 5% larger (measured).
PNG_COMPRESSION = 3


def save_png(figure: Figure, path: str | Path, *, dpi: int) -> Path:
    """Save ``figure`` as a PNG file at ``path``, atomically, on a white background."""
    with atomic_path(path) as tmp:
        figure.savefig(
            tmp,
            format="png",
            dpi=dpi,
            facecolor="white",
            pil_kwargs={"compress_level": PNG_COMPRESSION},
        )
    return Path(path)


def _first_upper(text: str) -> str:
    return text[:1].upper() + text[1:] if text else text
