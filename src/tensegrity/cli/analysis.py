"""One function per CLI verb: compute, return the tables and a writer of the JSON and figures.

``run_equilibrium``, ``run_modes``, ``run_controllability``, ``run_lqr`` and ``run_control``
each take a :class:`~tensegrity.model.structure.Structure`, compute the whole analysis in memory
and return an :class:`Output`: the readable tables, a function that writes the files into a
folder (each atomically, :func:`tensegrity.io.files.atomic_path`) and, if the analysis did not
succeed (no equilibrium, targets missed), a one-line problem.  Nothing is written while they
compute: the ``tensegrity`` command then runs the writer alone in a staging folder and moves all
files into place together (:mod:`tensegrity.cli.main`, :func:`tensegrity.io.files.write_staged`),
so a run killed while it computes leaves nothing in its output folder.  Files:

==========================  ================================================================
verb                        files
==========================  ================================================================
``equilibrium``             ``equilibrium.json`` (node positions, tensions, slack tendons,
                            residuals, per route, and their agreement), ``equilibrium.png``
``modes``                   ``modes.json`` (frequencies [Hz], kinds, node mode shapes, verdict,
                            optional FFT and nonlinear checks), ``frequencies.png``,
                            ``mode_shapes.png``
``controllability``         ``controllability.json`` (ranks per input set and per output set,
                            modes missed, Gramians), ``controllability.png``,
                            ``observability.png``
``lqr``                     ``controller.npz`` (the gain, :mod:`tensegrity.io.controllers`),
                            ``lqr.json`` (closed-loop poles, modes left uncontrolled)
``control``                 ``control.json`` (plan and closed-loop results),
                            ``control_motion.png``, ``control_inputs.png``,
                            ``control_shapes.png``
==========================  ================================================================
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from tensegrity.analysis.bounds import Bounds
from tensegrity.analysis.equilibrium import (
    EquilibriumResult,
    compare_equilibria,
    equilibrium_by_simulation,
    find_equilibrium,
    with_damping,
)
from tensegrity.cli.drawing import Drawing, Job, figure_png, viewer_page
from tensegrity.cli.tables import key_values, table, write_json
from tensegrity.engine.options import Options
from tensegrity.model.actuators import actuators as tendon_actuators
from tensegrity.model.structure import Structure

if TYPE_CHECKING:
    from tensegrity.analysis.controllability import ReachResult
    from tensegrity.analysis.modes import ModalAnalysis
    from tensegrity.analysis.shape_control import ClosedLoop, QuasiStatic
    from tensegrity.design.materials import MemberDesign
    from tensegrity.plots.motion import Frames


class Output(NamedTuple):
    """What a verb computed."""

    text: str  #: tables and verdicts to print
    #: ``write(folder, drawing=None)`` writes the verb's files into ``folder`` (which exists) and
    #: returns them: the JSON itself, the figures and pages as ``drawing``'s jobs
    #: (:class:`~tensegrity.cli.drawing.Drawing`; None: drawn here, one after the other)
    write: Callable[[Path, Drawing | None], list[Path]]
    problem: str | None  #: why the analysis did not succeed (None if it did)


def _structure_summary(s: Structure) -> dict[str, Any]:
    return {
        "nodes": s.n_nodes,
        "rods": s.n_rods,
        "tendons": s.n_tendons,
        "tendon_name": list(s.tendon_name),
    }


def _gravity(structure: Structure, gravity: float | Sequence[float] | None) -> np.ndarray | None:
    """The verbs' ``gravity`` (a number: down the last axis, or a vector) as a (dim,) vector."""
    from tensegrity.model.loads import gravity_vector

    return None if gravity is None else gravity_vector(gravity, structure.dim)


def _equilibrium(structure: Structure, gravity: np.ndarray | None) -> EquilibriumResult:
    eq = find_equilibrium(structure, gravity=gravity)
    if not eq.converged:
        raise RuntimeError(f"no equilibrium found: {eq.message}")
    return eq


# ------------------------------------------------------------------------------ equilibrium
def run_equilibrium(
    structure: Structure,
    *,
    method: str = "both",
    t_end: float = 60.0,
    velocity_tol: float = Options.velocity_tol,
    acceleration_tol: float = Options.acceleration_tol,
    gravity: float | Sequence[float] | None = None,
    design: MemberDesign | None = None,
) -> Output:
    """``tensegrity equilibrium``: the equilibrium by least squares, by damped simulation, or
    both (``method``: ``"least_squares"``, ``"simulation"``, ``"both"``) and their agreement,
    under ``gravity`` [m/s^2] (a number: down the last axis; or a vector), if given; with the
    members' ``design``, their utilisation there (:func:`_utilisation`)."""
    if method not in ("both", "least_squares", "simulation"):
        raise ValueError(
            f"method: expected 'both', 'least_squares' or 'simulation', got {method!r}"
        )
    g = _gravity(structure, gravity)
    results: dict[str, EquilibriumResult] = {}
    if method in ("both", "least_squares"):
        results["least_squares"] = find_equilibrium(structure, gravity=g)
    if method in ("both", "simulation"):
        results["simulation"] = equilibrium_by_simulation(
            structure,
            t_end=t_end,
            velocity_tol=velocity_tol,
            acceleration_tol=acceleration_tol,
            gravity=g,
        )
    data: dict[str, Any] = {"structure": _structure_summary(structure)}
    data |= {name: r.to_dict() for name, r in results.items()}
    text = [line for name, r in results.items() for line in _route_text(name, r)]
    if len(results) == 2:
        agreement = compare_equilibria(results["least_squares"], results["simulation"])
        data["agreement"] = agreement
        text.append(_agreement_text(agreement))
    main = results.get("least_squares") or results["simulation"]
    text.append(_tendon_table(structure, main))
    if design is not None:
        data["utilisation"], lines = _utilisation(structure, design, main)
        text.append(lines)
    # the page: the damped run's settling if the simulation route ran (the viewer decimates
    # its samples), else the structure at rest
    simulated = results.get("simulation")
    settling = structure if simulated is None else (simulated.trajectory or structure)

    def write(out: Path, drawing: Drawing | None = None) -> list[Path]:
        drawing = drawing or Drawing(0)
        jobs = [
            drawing.submit(
                figure_png,
                "figures.figure_structure",
                out / "equilibrium.png",
                structure,
                main.node_position,
                main.tension,
                title=f"Equilibrium ({main.method.replace('_', ' ')})",
            ),
            drawing.submit(viewer_page, settling, out / "settling.html"),
        ]
        return [write_json(out / "equilibrium.json", data), *_results(jobs)]

    failed = [f"{name}: {r.message}" for name, r in results.items() if not r.converged]
    return Output("\n\n".join(text), write, "; ".join(failed) or None)


def _results(jobs: Sequence[Job[list[Path]]]) -> list[Path]:
    """The files ``jobs`` wrote, once they are done, in their order."""
    return [path for job in jobs for path in job.result()]


def _route_text(name: str, r: EquilibriumResult) -> list[str]:
    """The heading and the key values (convergence, residuals, tensions) of one route."""
    return [
        f"[{name}] {r.message}",
        key_values(
            [
                ("converged", r.converged),
                ("residual force max |Q|", f"{r.residual_force:.3e} N"),
                ("residual acceleration max |q''|", f"{r.residual_acceleration:.3e} m/s^2"),
                (
                    "tension range",
                    f"{r.tension.min():.6g} .. {r.tension.max():.6g} N"
                    if r.tension.size
                    else "no tendons",
                ),
                ("slack tendons", ", ".join(r.slack_names) or "none"),
            ]
        ),
    ]


def _agreement_text(agreement: dict[str, Any]) -> str:
    """How far apart the two routes' equilibria are (:func:`compare_equilibria`)."""
    return key_values(
        [
            (
                "routes agree: node distance",
                f"{agreement['node_distance']:.3e} m (after removing rigid-body motion)",
            ),
            (
                "routes agree: tension difference",
                f"{agreement['tension_difference']:.3e} N",
            ),
        ]
    )


def _utilisation(
    structure: Structure, design: MemberDesign, eq: EquilibriumResult
) -> tuple[dict[str, Any], str]:
    """The members' utilisation at ``eq`` with the design's factors
    (:func:`~tensegrity.design.utilisation.utilisation`; the rods' forces with the supports'
    and joints', ``eq.rod_compression``): the JSON section and the summary's lines."""
    from tensegrity.design.utilisation import utilisation

    factors = design.factors
    u = utilisation(
        structure,
        design.properties(structure),
        tension=eq.tension,
        compression=eq.rod_compression,
        safety_factor=factors.safety,
        strength_factor=factors.strength,
    )

    def largest(values: np.ndarray, names: Sequence[str]) -> str:
        k = int(np.argmax(values))
        return f"{values[k]:.4g} ({names[k]})"

    rods = [f"rod {r}" for r in range(structure.n_rods)]
    tendons = [f"tendon {name!r}" for name in structure.tendon_name]
    rows = [
        ("utilisation factors", f"safety {factors.safety:g}, strength {factors.strength:g}"),
        (
            "largest rod utilisation",
            f"buckling {largest(u.rod_buckling, rods)}, yield {largest(u.rod_yield, rods)}"
            if structure.n_rods
            else "no rods",
        ),
        (
            "largest tendon utilisation",
            f"yield {largest(u.tendon_yield, tendons)}" if structure.n_tendons else "no tendons",
        ),
    ]
    section = {
        "safety_factor": factors.safety,
        "strength_factor": factors.strength,
        "tendon_yield": u.tendon_yield.tolist(),
        "rod_yield": u.rod_yield.tolist(),
        "rod_buckling": u.rod_buckling.tolist(),
        "largest": u.largest,
    }
    return section, key_values(rows)


def _tendon_table(structure: Structure, eq: EquilibriumResult) -> str:
    """Per tendon of ``eq``: tension, length, rest length and whether it is slack."""
    return table(
        ["tendon", "tension [N]", "length [m]", "rest length [m]", "slack"],
        [
            (n, T, length, r, "yes" if sl else "")
            for n, T, length, r, sl in zip(
                structure.tendon_name,
                eq.tension,
                eq.tendon_length,
                eq.rest_length,
                eq.slack,
                strict=True,
            )
        ],
    )


# ------------------------------------------------------------------------------ modes
def run_modes(
    structure: Structure,
    *,
    shapes: int = 6,
    check_fft: bool = False,
    check_simulation: bool = False,
    gravity: float | Sequence[float] | None = None,
    design: MemberDesign | None = None,
) -> Output:
    """``tensegrity modes``: natural frequencies [Hz], mode shapes, rigid-body modes, mechanisms
    and the stability verdict at the equilibrium (least squares); optionally the FFT check of
    the best-separated mode and the perturbed nonlinear simulations; with the members'
    ``design``, their utilisation at the equilibrium (:func:`_utilisation`)."""
    from tensegrity.analysis.linearize import linearize
    from tensegrity.analysis.modes import (
        ELASTIC,
        measure_frequency,
        modal_analysis,
        stability_by_simulation,
    )

    eq = _equilibrium(structure, _gravity(structure, gravity))
    lin = linearize(structure, eq)
    modes = modal_analysis(lin)
    data: dict[str, Any] = {
        "structure": _structure_summary(structure),
        "equilibrium_residual_force_N": eq.residual_force,
    }
    data |= modes.to_dict()
    text = [modes.verdict]
    if design is not None:
        data["utilisation"], lines = _utilisation(structure, design, eq)
        text.append(lines)
    rows = [
        (i, modes.kind[i], modes.frequency_hz[i], modes.omega_squared[i])
        for i in range(len(modes.kind))
    ]
    text.append(table(["mode", "kind", "frequency [Hz]", "omega^2 [1/s^2]"], rows))
    if check_fft and not modes.count(ELASTIC):
        text.append("FFT check: not done, no elastic mode (no non-zero frequency to measure)")
    elif check_fft:
        check = measure_frequency(modes)
        data["fft_check"] = check.to_dict()
        text.append(
            f"FFT check, mode {check.mode}: linearization {check.linear_hz:.6g} Hz, "
            f"nonlinear simulation {check.measured_hz:.6g} Hz (relative difference "
            f"{check.relative_error:.2e})"
        )
    if check_simulation:
        sim = stability_by_simulation(modes)
        data["simulation_check"] = sim.to_dict()
        text.append(sim.verdict)
    chosen = [int(i) for i in modes.elastic_indices()[:shapes]]
    clips = {i: mode_clip(modes, i) for i in chosen}

    def write(out: Path, drawing: Drawing | None = None) -> list[Path]:
        drawing = drawing or Drawing(0)
        shapes = (  # the longest first
            [
                drawing.submit(
                    figure_png, "report.figure_mode_shapes", out / "mode_shapes.png", modes, chosen
                )
            ]
            if chosen
            else []
        )
        jobs = [
            drawing.submit(figure_png, "report.figure_frequencies", out / "frequencies.png", modes),
            *(
                drawing.submit(viewer_page, clip, out / f"mode_{i}.html")
                for i, clip in clips.items()
            ),
        ]
        written = [write_json(out / "modes.json", data)]
        return written + _results([jobs[0], *shapes, *jobs[1:]])

    return Output("\n\n".join(text), write, None)


#: Frames of one period of a mode's clip (:func:`mode_clip`).
MODE_CLIP_FRAMES = 48
#: Largest node displacement of a mode's clip, as a fraction of the structure's size.
MODE_CLIP_AMPLITUDE = 0.1


def mode_clip(modes: ModalAnalysis, i: int, *, n_frames: int = MODE_CLIP_FRAMES) -> Frames:
    """One period of mode ``i`` (elastic) as the viewer's frames: node positions
    ``p0 + a sin(2 pi j / n_frames) phi_i`` (the linearized motion, frames ``j = 0 ..
    n_frames - 1`` at times ``j T / n_frames``, ``T`` the mode's period [s]), the largest node
    displacement ``a |phi_i|_max`` :data:`MODE_CLIP_AMPLITUDE` of the structure's size; tendon
    tensions exact at each displaced configuration (:func:`~tensegrity.physics.dynamics.
    tendon_tensions`, at rest: no damping).  A mode of zero frequency (a mechanism, an unstable
    mode) has no period: its shape is shown the same way over 1 s, and the title says so."""
    from tensegrity.physics.dynamics import tendon_tensions
    from tensegrity.plots.motion import motion_frames

    lin = modes.linearization
    p0 = lin.equilibrium.node_position
    size = float(np.ptp(p0, axis=0).max()) or 1.0
    shape = modes.node_shapes[i]
    amplitude = MODE_CLIP_AMPLITUDE * size / (float(np.max(np.linalg.norm(shape, axis=1))) or 1.0)
    phase = 2 * np.pi * np.arange(n_frames) / n_frames
    position = p0 + amplitude * np.sin(phase)[:, None, None] * shape
    tension = np.stack([tendon_tensions(lin.structure, p) for p in position])
    frequency = float(modes.frequency_hz[i])
    if frequency > 0:
        period = 1.0 / frequency
        title = f"mode {i}: {frequency:.4g} Hz (period {period:.4g} s), linearized"
    else:  # a mechanism or an unstable mode: a shape that does not oscillate
        period = 1.0
        title = f"mode {i}: {modes.kind[i]}, zero frequency (no period): its shape over 1 s"
    return motion_frames(
        lin.structure, phase / (2 * np.pi) * period, position, tension, title=title
    )


# ------------------------------------------------------------------------------ controllability
def run_controllability(
    structure: Structure,
    *,
    inputs: Sequence[str] | None = None,
    outputs: Sequence[str] | None = None,
    damping: str = "artificial",
    gravity: float | Sequence[float] | None = None,
) -> Output:
    """``tensegrity controllability``: ranks, PBH per mode and Gramians for each input set
    (tendon-name patterns; default all tendons, each family, one tendon) and observability for
    each output set (default node positions, tendon lengths, tensions, node 0).  Gramians use
    ``damping`` (``"artificial"``: the paper's artificial critical damping; ``"as-is"``)."""
    from tensegrity.analysis.controllability import controllability_table
    from tensegrity.analysis.linearize import linearize
    from tensegrity.analysis.modes import modal_analysis

    damped = with_damping(structure, damping)
    eq = _equilibrium(structure, _gravity(structure, gravity))
    lin = linearize(damped, eq)
    modes = modal_analysis(lin)
    input_sets = None if inputs is None else {p: p for p in inputs}
    output_sets = None if outputs is None else {p: p for p in outputs}
    ctrl, obs = controllability_table(lin, modes, input_sets, output_sets)
    text = [
        f"{lin.A.shape[0]} states ({lin.n_dof} coordinates and their rates), of which "
        f"{ctrl[0].elastic_states} non-rigid; rank = 2 x (modes reached), PBH per mode with "
        f"relative tolerance {ctrl[0].pbh_rtol:g}; Gramians with {damping} damping"
    ]

    text.append(
        "Controllability (inputs: rest-length changes)\n"
        + table(
            ["input set", "tendons", "rank", "non-rigid rank", "modes not reached", "Gramian eig"],
            _reach_rows(ctrl),
        )
    )
    text.append(
        "Observability\n"
        + table(
            ["output set", "outputs", "rank", "non-rigid rank", "modes not seen", "Gramian eig"],
            _reach_rows(obs),
        )
    )
    data = {
        "structure": _structure_summary(structure),
        "states": lin.A.shape[0],
        "pbh_rtol": ctrl[0].pbh_rtol,
        "damping": damping,
        "modes": [
            {"index": i, "kind": k, "frequency_hz": float(f)}
            for i, (k, f) in enumerate(zip(modes.kind, modes.frequency_hz, strict=True))
        ],
        "controllability": [r.to_dict() for r in ctrl],
        "observability": [r.to_dict() for r in obs],
    }

    def write(out: Path, drawing: Drawing | None = None) -> list[Path]:
        drawing = drawing or Drawing(0)
        jobs = [
            drawing.submit(figure_png, "report.figure_reach", out / f"{name}.png", results, modes)
            for name, results in (("controllability", ctrl), ("observability", obs))
        ]
        return [write_json(out / "controllability.json", data), *_results(jobs)]

    return Output("\n\n".join(text), write, None)


def _reach_rows(results: Sequence[ReachResult]) -> list[tuple[Any, ...]]:
    """Table rows of controllability (observability) results: signals, ranks, the modes not
    reached (seen) and the Gramian's eigenvalue range."""
    out_rows = []
    for r in results:
        g = r.gramian_eigenvalues
        missed = r.missed_modes()
        out_rows.append(
            (
                r.name,
                len(r.signals),
                f"{r.rank}/{r.n_states}",
                f"{r.elastic_rank}/{r.elastic_states}",
                ", ".join(str(m) for m in missed[:12]) + (" ..." if len(missed) > 12 else "")
                or "none",
                "-" if g is None else f"{max(g.min(), 0.0):.3g} .. {g.max():.3g}",
            )
        )
    return out_rows


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

    eq = _equilibrium(structure, _gravity(structure, gravity))
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
        "structure": _structure_summary(structure),
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
    eq = _equilibrium(structure, None)  # shape control: no gravity
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
        "structure": _structure_summary(structure),
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
        return [*_results(views), json_file, *_results(figures)]

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
