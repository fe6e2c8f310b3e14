"""One function per analysis verb: compute, return the tables and a writer of the JSON and
figures.  This module holds what the verbs share (:class:`Output`, the structure's summary, the
equilibrium, the members' utilisation) and ``equilibrium``'s :func:`run_equilibrium`;
:mod:`tensegrity.cli.modes` holds ``run_modes`` and ``run_controllability``,
:mod:`tensegrity.cli.control` ``run_lqr`` and ``run_control``.

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

from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from tensegrity.analysis.equilibrium import (
    EquilibriumResult,
    compare_equilibria,
    equilibrium_by_simulation,
    find_equilibrium,
)
from tensegrity.cli.drawing import Drawing, Job, figure_png, viewer_page
from tensegrity.cli.tables import key_values, table, write_json
from tensegrity.engine.options import Options
from tensegrity.model.structure import Structure

if TYPE_CHECKING:
    from tensegrity.design.materials import MemberDesign


class Output(NamedTuple):
    """What a verb computed."""

    text: str  #: tables and verdicts to print
    #: ``write(folder, drawing=None)`` writes the verb's files into ``folder`` (which exists) and
    #: returns them: the JSON itself, the figures and pages as ``drawing``'s jobs
    #: (:class:`~tensegrity.cli.drawing.Drawing`; None: drawn here, one after the other)
    write: Callable[[Path, Drawing | None], list[Path]]
    problem: str | None  #: why the analysis did not succeed (None if it did)


def structure_summary(s: Structure) -> dict[str, Any]:
    """The JSON files' ``structure``: the numbers of nodes, rods and tendons, the tendons' names."""
    return {
        "nodes": s.n_nodes,
        "rods": s.n_rods,
        "tendons": s.n_tendons,
        "tendon_name": list(s.tendon_name),
    }


def gravity_of(structure: Structure, gravity: float | Sequence[float] | None) -> np.ndarray | None:
    """The verbs' ``gravity`` (a number: down the last axis, or a vector) as a (dim,) vector."""
    from tensegrity.model.loads import gravity_vector

    return None if gravity is None else gravity_vector(gravity, structure.dim)


def converged_equilibrium(structure: Structure, gravity: np.ndarray | None) -> EquilibriumResult:
    """The equilibrium of ``structure`` by least squares under ``gravity`` (a (dim,) vector, or
    None); ``RuntimeError`` if none was found."""
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
    members' ``design``, their utilisation there (:func:`utilisation_report`)."""
    if method not in ("both", "least_squares", "simulation"):
        raise ValueError(
            f"method: expected 'both', 'least_squares' or 'simulation', got {method!r}"
        )
    g = gravity_of(structure, gravity)
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
    data: dict[str, Any] = {"structure": structure_summary(structure)}
    data |= {name: r.to_dict() for name, r in results.items()}
    text = [line for name, r in results.items() for line in _route_text(name, r)]
    if len(results) == 2:
        agreement = compare_equilibria(results["least_squares"], results["simulation"])
        data["agreement"] = agreement
        text.append(_agreement_text(agreement))
    main = results.get("least_squares") or results["simulation"]
    text.append(_tendon_table(structure, main))
    if design is not None:
        data["utilisation"], lines = utilisation_report(structure, design, main)
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
        return [write_json(out / "equilibrium.json", data), *job_results(jobs)]

    failed = [f"{name}: {r.message}" for name, r in results.items() if not r.converged]
    return Output("\n\n".join(text), write, "; ".join(failed) or None)


def job_results(jobs: Sequence[Job[list[Path]]]) -> list[Path]:
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


def utilisation_report(
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
