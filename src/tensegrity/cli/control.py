"""``tensegrity lqr`` and ``tensegrity control``: :func:`run_lqr` (an LQR gain at the
equilibrium, written as a controller file) and :func:`run_control` (shape control: the
quasi-static plan, then the LQR closed loop on the nonlinear model; the default rings:
:func:`rings`); each returns an :class:`~tensegrity.cli.analysis.Output`
(:mod:`tensegrity.cli.analysis`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.analysis.bounds import Bounds
from tensegrity.analysis.equilibrium import EquilibriumResult
from tensegrity.cli.analysis import (
    Output,
    converged_equilibrium,
    gravity_of,
    job_results,
    structure_summary,
)
from tensegrity.cli.drawing import Drawing, figure_png, viewer_page
from tensegrity.cli.tables import key_values, table, write_json
from tensegrity.model.actuators import actuators as tendon_actuators
from tensegrity.model.structure import Structure

if TYPE_CHECKING:
    from tensegrity.analysis.shape_control import ClosedLoop, QuasiStatic
    from tensegrity.plots.motion import Frames


# ------------------------------------------------------------------------------ lqr
def run_lqr(
    structure: Structure,
    *,
    period: float,
    inputs: str = "all",
    gravity: float | Sequence[float] | None = None,
) -> Output:
    """``tensegrity lqr``: an LQR gain at the structure's equilibrium on the modes the tendons
    ``inputs`` (``"all"`` or name patterns) reach (:mod:`tensegrity.analysis.control_design`,
    default weights), written as the controller file ``controller.npz`` (run every ``period``
    [s]) with ``lqr.json`` (the closed-loop poles, the modes left uncontrolled and why)."""
    from tensegrity.analysis.control_design import lqr, reachable
    from tensegrity.analysis.linearize import linearize
    from tensegrity.io.controllers import write_controller

    eq = converged_equilibrium(structure, gravity_of(structure, gravity))
    model = reachable(linearize(structure, eq), inputs)
    design = lqr(model, period=period)
    left = [item for item in design.uncontrolled if item.kind != "rigid"]
    rigid = len(design.uncontrolled) - len(left)
    text = [
        f"{model.system.nstates} states: the {model.system.nstates // 2} modes that "
        f"{len(model.tendons)} tendon(s) reach; left uncontrolled: {rigid} rigid-body motion(s)"
        + (f" and {len(left)} mode(s):" if left else ", no other mode"),
    ]
    if left:
        text.append(
            table(
                ["mode", "kind", "frequency [Hz]", "why"],
                [(m.mode, m.kind, m.frequency_hz, m.reason) for m in left],
            )
        )
    text.append(
        key_values(
            [
                ("closed loop: slowest decay rate", f"{design.slowest_decay:.6g} 1/s"),
                ("control period", f"{period:g} s"),
            ]
        )
    )
    poles = design.closed_loop_poles
    data = {
        "structure": structure_summary(structure),
        "period_s": period,
        "tendons": list(model.tendons),
        "states": list(model.system.state_labels),
        "slowest_decay_per_s": design.slowest_decay,
        "closed_loop_poles": {"real": poles.real.tolist(), "imag": poles.imag.tolist()},
        "uncontrolled": [item.to_dict() for item in design.uncontrolled],
        "moved_by_damping": list(model.damping_moved),
    }

    def write(out: Path, drawing: Drawing | None = None) -> list[Path]:
        return [
            write_controller(out / "controller.npz", design.feedback, structure),
            write_json(out / "lqr.json", data),
        ]

    return Output("\n\n".join(text), write, None)


# ------------------------------------------------------------------------------ control
def rings(structure: Structure, p: np.ndarray, rtol: float = 1e-6) -> tuple[list[int], list[int]]:
    """Bottom and top "rings": the nodes at the lowest and at the highest z (within ``rtol`` of
    the structure's height) -- the default for structure files."""
    z = p[:, 2]
    span = float(np.ptp(z)) or 1.0
    bottom = np.flatnonzero(z <= z.min() + rtol * span).tolist()
    top = np.flatnonzero(z >= z.max() - rtol * span).tolist()
    return bottom, top


def run_control(
    structure: Structure,
    *,
    height: float = 0.8,
    twist_back: bool = True,
    actuators: str = "t1_*",
    steps: tuple[int, int] = (8, 4),
    bottom: Sequence[int] | None = None,
    top: Sequence[int] | None = None,
    closed_loop: bool = True,
    move_time: float = 2.0,
    settle_time: float = 4.0,
    min_rest_length: float = Bounds.min_rest_length,
    max_change: float = Bounds.max_change,
    min_tension: float = Bounds.min_tension,
    tolerance: float = 1e-6,
    max_rate: float | None = None,
    lag: float | None = None,
) -> Output:
    """``tensegrity control``: shorten the structure to ``height`` times its equilibrium height
    with the ``actuators`` (tendon pattern; twist free), then (``twist_back``) restore the twist
    with every tendon, by a quasi-static sequence of equilibria, then (``closed_loop``) play it
    with LQR feedback on the nonlinear model, through actuators whose rest lengths change at
    most ``max_rate`` [m/s] behind a first-order ``lag`` [s] (default: at once).
    ``bottom``/``top``: node indices of the two rings (default: the nodes at the lowest and the
    highest z of the equilibrium)."""
    from tensegrity.analysis.shape_control import closed_loop as run_closed_loop, describe_plan

    _check_control_options(structure, height=height, steps=steps, bottom=bottom, top=top)
    eq = converged_equilibrium(structure, None)  # shape control: no gravity
    bottom, top = _control_rings(structure, eq.node_position, bottom, top)
    bounds = Bounds(min_rest_length=min_rest_length, max_change=max_change, min_tension=min_tension)
    plan = _open_loop_plan(
        structure,
        eq,
        bottom,
        top,
        height=height,
        twist_back=twist_back,
        actuators=actuators,
        steps=steps,
        bounds=bounds,
        tolerance=tolerance,
    )
    data: dict[str, Any] = {
        "structure": structure_summary(structure),
        "bottom": list(bottom),
        "top": list(top),
        "bounds": dataclasses.asdict(bounds),
        "open_loop": describe_plan(plan),
    }
    text = [
        f"open loop (quasi-static, {len(plan.equilibria) - 1} steps): {plan.message}",
        _plan_table(plan),
    ]
    closed = None
    if closed_loop:
        drives = None
        if max_rate is not None or lag is not None:
            drives = tendon_actuators(
                structure, max_rate=max_rate or math.inf, time_constant=lag or 0.0
            )
        closed = run_closed_loop(
            plan, move_time=move_time, settle_time=settle_time, actuators=drives
        )
        data["closed_loop"] = _closed_loop_summary(closed)
        data["closed_loop"]["actuators"] = {"max_rate_m_per_s": max_rate, "lag_s": lag}
        text.append(f"closed loop (LQR, nonlinear model, {closed.t[-1]:.3g} s): {closed.message}")
        if drives is not None:
            text.append(
                f"actuators: rate limit {max_rate or math.inf:g} m/s, lag {lag or 0.0:g} s; "
                + ("a limit was reached" if closed.saturated else "no limit reached")
            )

    pages = {"open_loop.html": _open_loop_frames(plan)}
    if closed is not None:
        pages["control.html"] = _closed_loop_frames(closed)

    def write(out: Path, drawing: Drawing | None = None) -> list[Path]:
        drawing = drawing or Drawing(0)
        views = [drawing.submit(viewer_page, frames, out / name) for name, frames in pages.items()]
        here = Drawing(0)  # (the plan holds its outputs' functions, closures: they do not pickle)
        figures = [
            here.submit(figure_png, f"report.{maker}", out / name, *arguments)
            for maker, name, arguments in (
                ("figure_shape_motion", "control_motion.png", (plan, closed)),
                ("figure_shape_controls", "control_inputs.png", (plan, closed)),
                ("figure_shape_structures", "control_shapes.png", (plan,)),
            )
        ]
        json_file = write_json(out / "control.json", data)
        return [*job_results(views), json_file, *job_results(figures)]

    missed = [
        f"{name}: {r.message}"
        for name, r in (("open loop", plan), ("closed loop", closed))
        if r is not None and not r.reached
    ]
    return Output("\n\n".join(text), write, "; ".join(missed) or None)


def _open_loop_frames(plan: QuasiStatic) -> Frames:
    """The viewer's frames of the open-loop plan: one per equilibrium of the quasi-static
    sequence, its "time" the step number (a sequence of states at rest, not a motion)."""
    from tensegrity.plots.motion import motion_frames

    steps = np.arange(len(plan.equilibria), dtype=float)
    return motion_frames(
        plan.structure,
        steps,
        np.stack([eq.node_position for eq in plan.equilibria]),
        np.stack([eq.tension for eq in plan.equilibria]),
        title=f"open loop: {len(steps) - 1} quasi-static steps (time axis = step number)",
    )


def _closed_loop_frames(closed: ClosedLoop) -> Frames:
    """The viewer's frames of the closed-loop manoeuvre: its samples (times [s], node
    positions, tensions), decimated to the page's budget (first and last kept)."""
    from tensegrity.plots.motion import (
        MAX_BYTES,
        MAX_FRAMES,
        decimated_indices,
        frame_budget,
        motion_frames,
    )

    s = closed.structure
    budget = frame_budget(s, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES)
    return motion_frames(
        s,
        closed.t,
        closed.node_position[..., : s.dim],
        closed.tension,
        indices=decimated_indices(closed.t.size, budget),
        title=f"closed loop (LQR, nonlinear model): {closed.message}",
    )


#: Most quasi-static steps per phase of ``control``.
MAX_CONTROL_STEPS = 10_000


def _check_control_options(
    structure: Structure,
    *,
    height: float,
    steps: tuple[int, int],
    bottom: Sequence[int] | None,
    top: Sequence[int] | None,
) -> None:
    """Raise unless ``structure`` is spatial, ``height`` > 0, ``steps`` two counts >= 1 and the
    ``bottom`` and ``top`` rings (if given) node indices of ``structure``."""
    from tensegrity.analysis.shape_control import require_spatial

    require_spatial(structure)
    if not height > 0:
        raise ValueError(
            f"height: must be > 0 (a fraction of the equilibrium height), got {height}"
        )
    if len(steps) != 2 or min(steps) < 1 or max(steps) > MAX_CONTROL_STEPS:
        raise ValueError(
            f"steps: expected two step counts from 1 to {MAX_CONTROL_STEPS:,} (each step is an "
            f"equilibrium solve, about a second each for a large shell), got {list(steps)}"
        )
    for name, nodes in (("bottom", bottom), ("top", top)):
        bad = [i for i in nodes or () if not 0 <= i < structure.n_nodes]
        if bad:
            raise ValueError(f"{name}: node {bad[0]} out of range 0..{structure.n_nodes - 1}")


def _control_rings(
    structure: Structure, p: np.ndarray, bottom: Sequence[int] | None, top: Sequence[int] | None
) -> tuple[Sequence[int], Sequence[int]]:
    """``(bottom, top)``: each as given, or else :func:`rings` of the equilibrium's node
    positions ``p`` (N, 3) [m]; they must not share nodes."""
    if bottom is None or top is None:
        b, t = rings(structure, p)
        bottom = b if bottom is None else bottom
        top = t if top is None else top
    if set(bottom) & set(top):
        raise ValueError(f"bottom, top: the rings share nodes {sorted(set(bottom) & set(top))}")
    return bottom, top


def _open_loop_plan(
    structure: Structure,
    eq: EquilibriumResult,
    bottom: Sequence[int],
    top: Sequence[int],
    *,
    height: float,
    twist_back: bool,
    actuators: str,
    steps: tuple[int, int],
    bounds: Bounds,
    tolerance: float,
) -> QuasiStatic:
    """The quasi-static plan of ``run_control``: from ``eq``, shorten to ``height`` times its
    height with the ``actuators`` (twist free) in ``steps[0]`` steps, then (``twist_back``)
    restore the twist with every tendon in ``steps[1]``, within ``bounds``."""
    from tensegrity.analysis.shape_control import height_twist, quasi_static

    output = height_twist(eq.node_position, bottom, top)
    y0 = output.value(eq.node_position)
    phases: list[Any] = [{"targets": (height * y0[0], None), "actuators": actuators}]
    n_steps = [steps[0]]
    if twist_back:
        phases.append((height * y0[0], 0.0))
        n_steps.append(steps[1])
    return quasi_static(
        structure,
        output,
        phases,
        start=eq,
        steps=n_steps,
        bounds=bounds,
        tolerance=[tolerance, tolerance],
    )


def _plan_table(plan: QuasiStatic) -> str:
    """The plan's steps: phase, outputs, smallest tension [N] and largest ``|u|`` [m]."""
    output = plan.output
    return table(
        [
            "step",
            "phase",
            *[f"{n} [{u}]" for n, u in zip(output.names, output.units, strict=True)],
            "min tension [N]",
            "max |u| [m]",
        ],
        [
            (
                k,
                int(plan.phase[k]),
                *plan.outputs[k],
                plan.min_tension[k],
                float(np.abs(plan.control[k]).max()),
            )
            for k in range(len(plan.equilibria))
        ],
    )


def _closed_loop_summary(closed: ClosedLoop) -> dict[str, Any]:
    """``control.json``'s ``closed_loop``: verdict, final outputs and errors, extremes, gains."""
    return {
        "reached": closed.reached,
        "message": closed.message,
        "final_outputs": closed.outputs[-1].tolist(),
        "final_error": closed.final_error.tolist(),
        "tolerance": closed.tolerance.tolist(),
        "min_tension_N": closed.min_tension,
        "min_rest_length_m": closed.min_rest_length,
        "saturated": closed.saturated,
        "max_rod_length_error": closed.max_rod_length_error,
        "duration_s": float(closed.t[-1]),
        "gains": closed.gains,
    }
