"""``tensegrity sweep``: a parameter sweep on Dask (:mod:`tensegrity.sweep.run`), written to
one netCDF/HDF5 dataset."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import re
import sys
from collections.abc import Iterator, Sequence
from typing import Any

from tensegrity.cli import arguments, outputs
from tensegrity.cli.errors import EXIT_FAILED, CommandError, blame, one_line
from tensegrity.cli.limits import check_samples, check_sweep_size
from tensegrity.cli.structures import read_structure
from tensegrity.io.files import folders_made, shown_path


def _sweep_parameter(text: str) -> tuple[str, list[float], bool]:
    """``--param NAME=V1,V2,...`` (a grid's values, or one value) or ``NAME=LOW:HIGH`` (a Monte
    Carlo range): ``(name, values, whether a range)``."""
    name, sep, values = text.partition("=")
    is_range = ":" in values
    parts = values.split(":") if is_range else values.split(",")
    try:
        numbers = [float(v) for v in parts]
    except ValueError:
        numbers = []
    if not sep or not numbers or (is_range and len(numbers) != 2):
        raise argparse.ArgumentTypeError(f"expected NAME=V1,V2,... or NAME=LOW:HIGH, got {text!r}")
    return name, numbers, is_range


def _sweep_parameters(
    params: Sequence[tuple[str, list[float], bool]], monte_carlo: bool
) -> dict[str, list[float]]:
    """The values of the ``--param`` options, each in the form of the sweep's mode: ranges
    ``LOW:HIGH`` for a Monte Carlo sample (``--samples``), lists ``V1,V2,...`` for a grid (one
    value fits both)."""
    for name, values, is_range in params:
        if is_range and not monte_carlo:
            raise CommandError(
                f"--param {name}: LOW:HIGH is a range to draw from and needs --samples N (a "
                "Monte Carlo sample); a grid takes the values V1,V2,..."
            )
        if not is_range and len(values) > 1 and monte_carlo:
            raise CommandError(
                f"--param {name}: V1,V2,... are a grid's values; with --samples give a range "
                "LOW:HIGH or one value"
            )
    return {name: values for name, values, _ in params}


def _cmd_sweep(args: argparse.Namespace) -> int:
    from tensegrity.sweep.run import SweepSpec, run_sweep

    outputs.check_file(args.output, "--output")
    options = {
        name: getattr(args, name)
        for name in ("samples", "seed", "t_end", "sample_dt", "method", "dt")
        if getattr(args, name) is not None
    }
    if args.no_batch:
        options["batch"] = False
    if args.spec is not None:
        if args.param or options or args.structure is not None:
            raise CommandError(
                "--spec: cannot be combined with --param, --structure or run options"
            )
        with blame("--spec", args.spec):
            spec = SweepSpec.from_file(args.spec)
        where = f"--spec: {shown_path(args.spec)}: "
        check_samples(spec.t_end, spec.sample_dt, ("t_end", "sample_dt"), where)
    elif not args.param:
        raise CommandError("sweep: give --spec FILE or at least one --param NAME=VALUES")
    else:
        defaults = {field.name: field.default for field in dataclasses.fields(SweepSpec)}
        check_samples(
            options.get("t_end", defaults["t_end"]), options.get("sample_dt", defaults["sample_dt"])
        )
        mode = "monte-carlo" if args.samples is not None else "grid"
        if args.structure is not None:
            options["structure"] = read_structure(args.structure, "--structure")
        with _in_sweep_options():
            spec = SweepSpec(
                _sweep_parameters(args.param, args.samples is not None), mode=mode, **options
            )
    check_sweep_size(spec)
    with _in_sweep_options():
        result = run_sweep(
            spec, scheduler=args.scheduler, n_workers=args.workers, progress=sys.stderr.isatty()
        )
    with folders_made(args.output.parent):
        path = result.save(args.output)
    n = result.dataset.sizes["case"]
    print(
        f"{n - len(result.failed)} of {n} cases reached t_end in {result.wall_time:.1f} s; "
        f"wrote {path}"
    )
    for i in result.failed:
        print(f"{result.describe_case(i)}: {result.dataset['message'].values[i]}", file=sys.stderr)
    return EXIT_FAILED if result.failed else 0


#: The sweep's arguments (``SweepSpec`` fields, ``run_sweep`` keywords) the options set.
_SWEEP_OPTIONS = {
    "parameters": "--param",
    "samples": "--samples",
    "seed": "--seed",
    "t_end": "--t-end",
    "sample_dt": "--sample-dt",
    "method": "--method",
    "dt": "--dt",
    "n_workers": "--workers",
    "scheduler": "--scheduler",
}


@contextlib.contextmanager
def _in_sweep_options() -> Iterator[None]:
    """A sweep's ``ValueError`` raised within the block (``SweepSpec``, ``run_sweep``) as a
    one-line error led by the option the user typed instead of the library's argument:
    ``parameters.n[1]: ...`` -> ``--param n: ...``, ``t_end: ...`` -> ``--t-end: ...`` (the
    message itself names both, e.g. ``sample_dt (--sample-dt)``).  A message that names no
    argument (a case's) stays."""
    try:
        yield
    except ValueError as exc:
        message = one_line(exc)
        field, sep, problem = message.partition(": ")
        parameter = re.fullmatch(r"parameters\.(.+?)(?:\[\d+\])?", field)
        if parameter is not None:
            message = f"--param {parameter.group(1)}: {problem}"
        elif sep and field in _SWEEP_OPTIONS:
            message = f"{_SWEEP_OPTIONS[field]}: {problem}"
        raise CommandError(message) from exc


#: The verb's line in ``tensegrity --help``.
HELP = (
    "simulate many shells or copies of a structure file (a grid or Monte Carlo sample of "
    "parameters) on Dask"
)


def add_parser(sub: Any) -> None:
    """``sweep``: a parameter sweep on Dask."""
    from tensegrity.sweep.run import DEFAULTS, SweepSpec

    # SweepSpec's, not the options' defaults: an option given may not go with --spec
    spec = {field.name: field.default for field in dataclasses.fields(SweepSpec)}
    sweep = sub.add_parser(
        "sweep",
        help=HELP,
        description="Run a parameter sweep on Dask and write one netCDF/HDF5 dataset; exit code 1 "
        "if some case failed (reported per case, the others are kept).",
    )
    sweep.add_argument(
        "--spec", type=arguments.name, metavar="FILE", help="sweep spec (.json or .yaml)"
    )
    sweep.add_argument(
        "--structure",
        type=arguments.name,
        metavar="FILE",
        help="sweep this structure file (any format) instead of the class 1 shell: "
        "then stiffness, rest_scale, damping and load can vary",
    )
    sweep.add_argument(
        "--param",
        type=_sweep_parameter,
        action="append",
        metavar="NAME=VALUES",
        help="vary NAME: n, m (the shell's elements around, stages), stiffness [N/m], "
        "rest_scale (every tendon's rest length over its initial length), damping [N s/m] or "
        "load [N] (an axial compression: the top nodes pushed down, the bottom ones up): "
        "V1,V2,... for a grid, LOW:HIGH with --samples; repeatable. A parameter not varied is "
        f"{', '.join(f'{name} = {value:g}' for name, value in DEFAULTS.items())} (with "
        "--structure: the file's values, and no load)",
    )
    sweep.add_argument(
        "--samples",
        type=int,
        help="Monte Carlo sample of this many cases (default: none, a grid of the --param values)",
    )
    sweep.add_argument("--seed", type=int, help=f"Monte Carlo seed (default {spec['seed']})")
    sweep.add_argument(
        "--t-end",
        type=arguments.positive,
        help=f"simulated time per case [s] (default {spec['t_end']:g})",
    )
    sweep.add_argument(
        "--sample-dt",
        type=arguments.positive,
        help=f"output spacing [s] (default {spec['sample_dt']:g})",
    )
    sweep.add_argument(
        "--method", help=f"{spec['method']} (default) or an adaptive scipy method, e.g. DOP853"
    )
    sweep.add_argument(
        "--dt", type=arguments.positive, help=f"{spec['method']} step [s] (default {spec['dt']:g})"
    )
    sweep.add_argument(
        "--no-batch",
        action="store_true",
        help="run rk4 cases one by one through simulate, not batched",
    )
    sweep.add_argument(
        "--scheduler", metavar="ADDRESS", help="Dask scheduler address (default: a local cluster)"
    )
    sweep.add_argument("--workers", type=int, help="local cluster workers (default: CPU count)")
    sweep.add_argument(
        "-o",
        "--output",
        type=arguments.name,
        required=True,
        help="output .nc file (missing folders are made, as for every verb's outputs)",
    )
    sweep.set_defaults(run=_cmd_sweep)
