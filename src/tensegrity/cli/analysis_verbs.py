"""The analysis verbs' parsers and their one command (:func:`run_analysis`): ``equilibrium``,
``modes``, ``controllability``, ``lqr``, ``control``; what each computes and writes is its
``run_<verb>`` (its keywords the options' names): in :mod:`tensegrity.cli.analysis`
(``equilibrium``), :mod:`tensegrity.cli.modes` (``modes``, ``controllability``) and
:mod:`tensegrity.cli.control` (``lqr``, ``control``)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tensegrity.analysis.bounds import Bounds
from tensegrity.cli import arguments, outputs
from tensegrity.cli.drawing import Drawing, worker_count
from tensegrity.cli.errors import EXIT_FAILED, CommandError
from tensegrity.cli.limits import check_run_cost
from tensegrity.cli.startup import announce_compiling
from tensegrity.cli.structures import add_gravity_option, add_structure_options, designed_of
from tensegrity.engine.options import Options
from tensegrity.io.files import write_staged as _write_all


def _cmd_analysis(args: argparse.Namespace) -> int:
    """``equilibrium | modes | controllability | lqr | control``: its ``run_<verb>``."""
    from tensegrity.cli import analysis, control, modes

    runs: dict[str, Callable[..., Any]] = {
        "equilibrium": analysis.run_equilibrium,
        "modes": modes.run_modes,
        "controllability": modes.run_controllability,
        "lqr": control.run_lqr,
        "control": control.run_control,
    }
    run = runs[args.command]
    outputs.check_folder(args.out, "--out")
    # the drawing's workers start now: they import matplotlib while the analysis computes
    workers = worker_count(2) if args.command in _DRAWN_IN_WORKERS else 0
    with Drawing(workers) as drawing:
        return _analysis_and_write(args, run, drawing)


#: The analysis verbs whose figures and pages are drawn in workers: it paid for these
#: (whole processes paired with drawing in the command, 2026-11-26: equilibrium 0.91x, modes
#: 0.85x), not for ``controllability`` (python-control imports matplotlib into the command
#: anyway) nor ``control`` (its figures' plan holds closures, which do not pickle; made
#: picklable, the verb was still 1.06x with workers: its LQR design imports python-control, and
#: so matplotlib): there the workers' imports only competed with the computation (1.14x, 1.11x).
_DRAWN_IN_WORKERS = ("equilibrium", "modes")


def _analysis_and_write(args: argparse.Namespace, run: Callable, drawing: Drawing) -> int:
    """An analysis verb once its output folder is checked: ``run`` on the structure of
    ``args``, its files (the figures and pages drawn by ``drawing``) and its tables."""
    import inspect

    announce_compiling()
    structure, design = designed_of(args)
    for option in ("safety_factor", "strength_factor"):
        if design is None and getattr(args, option) is not None:
            raise CommandError(
                f"--{option.replace('_', '-')}: needs members with a design (--material and "
                "--section, or a structure file in the material form)"
            )
    if args.command == "equilibrium" and args.method != "least_squares":
        check_run_cost(
            structure,
            args.t_end,
            Options(steady_state=True, acceleration_tol=args.acceleration_tol),
            remedy="softer tendons, a shorter --t-end or --method least_squares",
        )
    options = {
        name: getattr(args, name)
        for name in inspect.signature(run).parameters
        if name not in ("structure", "design") and hasattr(args, name)
    }
    if "design" in inspect.signature(run).parameters:
        options["design"] = design
    # The whole computation first, with nothing in --out; then only the writing is staged.
    try:
        output = run(structure, **options)
    except RuntimeError as exc:  # no equilibrium, a failed simulation: nothing written
        raise CommandError(f"{exc} (nothing written)", EXIT_FAILED) from None
    except KeyError as exc:  # a tendon or output pattern that matches nothing
        raise CommandError(str(exc.args[0])) from None
    written = _write_all(args.out, drawing.writing(output.write), record=args.command)
    print(output.text)
    print("\nwrote " + ", ".join(str(f) for f in written))
    if output.problem:
        raise CommandError(f"{output.problem} (results written)", EXIT_FAILED)
    return 0


def add_parsers(sub: Any) -> None:
    """The analysis verbs (issue 4); option names are the keywords of their ``run_<verb>``."""
    verbs = {
        "equilibrium": "static equilibrium by least squares and by damped simulation: node "
        "positions, tensions, slack tendons, residuals",
        "modes": "natural frequencies [Hz], mode shapes, rigid-body modes, mechanisms and the "
        "stability verdict at the equilibrium",
        "controllability": "controllability (observability) ranks, PBH test per mode and "
        "Gramians per set of actuated tendons (measured outputs)",
        "lqr": "an LQR feedback gain at the equilibrium on the modes the tendons reach, "
        "written as a controller file (controller.npz) for simulate --controller",
        "control": "shape control: shorten to --height of the equilibrium height, twist back; "
        "open loop (equilibria) and closed loop (LQR on the nonlinear model)",
    }
    parsers = {}
    for verb, text in verbs.items():
        parsers[verb] = p = sub.add_parser(
            verb,
            help=text,
            description=text[0].upper()
            + text[1:]
            + f"; writes {verb}.json{_WRITES.get(verb, ' and figures')} to --out.",
        )
        add_structure_options(p)
        arguments.add_factors(p, from_file=True)  # the members' utilisation, with a design
        p.add_argument(
            "--out",
            type=arguments.name,
            default=Path(verb),
            help=f"output folder (default ./{verb})",
        )
        p.set_defaults(run=_cmd_analysis)
    # shape control: without gravity
    for verb in ("equilibrium", "modes", "controllability", "lqr"):
        add_gravity_option(parsers[verb])
    _add_equilibrium_options(parsers["equilibrium"])
    _add_modes_options(parsers["modes"])
    _add_controllability_options(parsers["controllability"])
    _add_lqr_options(parsers["lqr"])
    _add_control_options(parsers["control"])
    _add_closed_loop_options(parsers["control"])


def _add_equilibrium_options(p: argparse.ArgumentParser) -> None:
    """``equilibrium``: the method and the damped simulation's limits."""
    p.add_argument(
        "--method",
        choices=("both", "least_squares", "simulation"),
        default="both",
        help="least squares (eq. 18.61, analytic Jacobian), damped simulation to rest, "
        "or both and their agreement (default both)",
    )
    p.add_argument(
        "--t-end",
        type=arguments.positive,
        default=60.0,
        help="longest damped simulation [s] (default %(default)g)",
    )
    p.add_argument(
        "--velocity-tol",
        type=arguments.positive,
        default=Options.velocity_tol,
        help="at rest when node speeds are below this [m/s] (default %(default)g)",
    )
    p.add_argument(
        "--acceleration-tol",
        type=arguments.positive,
        default=Options.acceleration_tol,
        help="... and node accelerations below this [m/s^2] (default %(default)g)",
    )


def _add_modes_options(p: argparse.ArgumentParser) -> None:
    """``modes``: the shapes drawn and the optional checks."""
    p.add_argument(
        "--shapes",
        type=arguments.whole_non_negative,
        default=6,
        help="mode shapes to draw, the lowest non-rigid modes (default %(default)d)",
    )
    p.add_argument(
        "--check-fft",
        action="store_true",
        help="measure the best-separated frequency by FFT of an undamped simulation",
    )
    p.add_argument(
        "--check-simulation",
        action="store_true",
        help="perturb the equilibrium and simulate with and without damping",
    )


def _patterns(text: str) -> str:
    """``--inputs`` / ``--outputs``: one set, comma-separated names or patterns (none empty)."""
    from tensegrity.analysis.controllability import split_patterns

    try:
        split_patterns(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def _add_controllability_options(p: argparse.ArgumentParser) -> None:
    """``controllability``: the input and output sets and the damping."""
    p.add_argument(
        "--inputs",
        nargs="+",
        type=_patterns,
        metavar="PATTERN",
        help="sets of actuated tendons, each 'all' or comma-separated name patterns "
        "(default: all, each family, the first tendon)",
    )
    p.add_argument(
        "--outputs",
        nargs="+",
        type=_patterns,
        metavar="PATTERN",
        help="sets of outputs: position, length, tension, all or name patterns like "
        "'p0_*' (default: position, length, tension, p0_*)",
    )
    p.add_argument(
        "--damping",
        choices=("artificial", "as-is"),
        default="artificial",
        help="damping of the linearization used for the Gramians: the paper's artificial "
        "critical damping (default) or the structure's own",
    )


#: What a verb writes besides its JSON, where that is not figures.
_WRITES = {"lqr": " and controller.npz"}


def _add_lqr_options(p: argparse.ArgumentParser) -> None:
    """``lqr``: the control period and the actuated tendons."""
    p.add_argument(
        "--period",
        type=arguments.positive,
        required=True,
        help="the controller's update period [s] (written into the controller file)",
    )
    p.add_argument(
        "--inputs",
        type=_patterns,
        default="all",
        metavar="PATTERN",
        help="the actuated tendons: 'all' (default) or comma-separated name patterns",
    )


#: ``control --steps``' default: quasi-static steps shortening, twisting back.
_STEPS = (8, 4)


def _add_control_options(p: argparse.ArgumentParser) -> None:
    """``control``: the targets, the actuators, the steps and the rings."""
    p.add_argument(
        "--height",
        type=arguments.positive,
        default=0.8,
        help="target height as a fraction of the equilibrium height (default %(default)g)",
    )
    p.add_argument(
        "--no-twist-back",
        dest="twist_back",
        action="store_false",
        help="only shorten (twist free), do not restore the twist",
    )
    p.add_argument(
        "--actuators",
        default="t1_*",
        help="tendons that shorten the structure (default '%(default)s'); every tendon "
        "takes part in the twist-back",
    )
    p.add_argument(
        "--steps",
        type=int,
        nargs=2,
        default=_STEPS,
        metavar=("SHORTEN", "TWIST"),
        help=f"quasi-static steps per phase (default {_STEPS[0]} {_STEPS[1]})",
    )
    p.add_argument(
        "--bottom",
        type=int,
        nargs="+",
        metavar="NODE",
        help="bottom ring nodes (default: the lowest nodes)",
    )
    p.add_argument(
        "--top",
        type=int,
        nargs="+",
        metavar="NODE",
        help="top ring nodes (default: the highest nodes)",
    )


def _add_closed_loop_options(p: argparse.ArgumentParser) -> None:
    """``control``: the closed loop's times, the bounds and the tolerance."""
    p.add_argument(
        "--no-closed-loop",
        dest="closed_loop",
        action="store_false",
        help="open loop only (no LQR simulation)",
    )
    p.add_argument(
        "--move-time",
        type=arguments.positive,
        default=2.0,
        help="closed loop: time per phase [s] (default %(default)g)",
    )
    p.add_argument(
        "--settle-time",
        type=arguments.positive,
        default=4.0,
        help="closed loop: time at the final target [s] (default %(default)g)",
    )
    p.add_argument(
        "--min-rest-length",
        type=arguments.non_negative,
        default=Bounds.min_rest_length,
        help="bound: rest lengths >= this [m] (default %(default)g)",
    )
    p.add_argument(
        "--max-change",
        type=arguments.positive,
        default=Bounds.max_change,
        help="bound: |rest-length change| <= this [m] (default %(default)g)",
    )
    p.add_argument(
        "--min-tension",
        type=arguments.positive,
        default=Bounds.min_tension,
        help="bound: every tendon taut with at least this tension [N] (default %(default)g)",
    )
    p.add_argument(
        "--tolerance",
        type=arguments.positive,
        default=1e-6,
        help="targets reached within this [m, rad] (default %(default)g)",
    )
    p.add_argument(
        "--max-rate",
        type=arguments.positive,
        metavar="M_PER_S",
        help="closed loop: the tendons' rest lengths change at most this fast [m/s] (a rate "
        "limit of their actuators; default none)",
    )
    p.add_argument(
        "--lag",
        type=arguments.positive,
        metavar="SECONDS",
        help="closed loop: the tendons follow the law's commands with this first-order lag [s] "
        "(default none: at once)",
    )
