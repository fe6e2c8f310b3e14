"""``tensegrity modes`` and ``tensegrity controllability``, the verbs of the linearization at
the equilibrium: :func:`run_modes` (frequencies, mode shapes, the stability verdict; a mode's
page: :func:`mode_clip`) and :func:`run_controllability` (ranks, PBH per mode, Gramians); each
returns an :class:`~tensegrity.cli.analysis.Output` (:mod:`tensegrity.cli.analysis`)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.analysis.equilibrium import with_damping
from tensegrity.cli.analysis import (
    Output,
    converged_equilibrium,
    gravity_of,
    job_results,
    structure_summary,
    utilisation_report,
)
from tensegrity.cli.drawing import Drawing, figure_png, viewer_page
from tensegrity.cli.tables import table, write_json
from tensegrity.model.structure import Structure

if TYPE_CHECKING:
    from tensegrity.analysis.controllability import ReachResult
    from tensegrity.analysis.modes import ModalAnalysis
    from tensegrity.design.materials import MemberDesign
    from tensegrity.plots.motion import Frames


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
    ``design``, their utilisation at the equilibrium
    (:func:`~tensegrity.cli.analysis.utilisation_report`)."""
    from tensegrity.analysis.linearize import linearize
    from tensegrity.analysis.modes import (
        ELASTIC,
        measure_frequency,
        modal_analysis,
        stability_by_simulation,
    )

    eq = converged_equilibrium(structure, gravity_of(structure, gravity))
    lin = linearize(structure, eq)
    modes = modal_analysis(lin)
    data: dict[str, Any] = {
        "structure": structure_summary(structure),
        "equilibrium_residual_force_N": eq.residual_force,
    }
    data |= modes.to_dict()
    text = [modes.verdict]
    if design is not None:
        data["utilisation"], lines = utilisation_report(structure, design, eq)
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
        return written + job_results([jobs[0], *shapes, *jobs[1:]])

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
    eq = converged_equilibrium(structure, gravity_of(structure, gravity))
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
        "structure": structure_summary(structure),
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
        return [write_json(out / "controllability.json", data), *job_results(jobs)]

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
