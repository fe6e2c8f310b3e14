"""``tensegrity fit``: a structure's parameters fitted to measured motion: marker positions,
tendon lengths, tensions (:func:`tensegrity.analysis.identification.fit`,
``docs/identification.md``); writes the fitted structure, the estimates and a figure to
``--out``::

    tensegrity fit --structure model.json --data markers.csv --param tendon_stiffness \\
        --param rod_mass --gravity 9.81 --load n8:5,0,0 -o fitted/

``--data`` is a markers file (``time,marker,x,y,z``), a measurements file
(``time,channel,value`` with channels ``position.NODE.x``, ``length.TENDON``,
``tension.TENDON``; both :mod:`tensegrity.io.measurements`; the run starts from the
structure's own node positions and velocities at t = 0) or a trajectory file (HDF5: every
node a marker at the file's sample times after its first, the run starting from its first
sample); repeat it for several experiments fitted together, each run with the same loads.
Each run is in the ``--structure`` file's scene (its ground planes, contact radius and
gravity; ``--gravity`` replaces its gravity), so that the friction on the ground can be fitted
(``--param kinetic_friction``: every plane's).  ``--noise`` weighs positions and lengths,
``--tension-noise`` tensions.  Writes ``fitted/structure.json`` (the
fitted structure, with its scene and the planes' fitted values), ``fitted/fit.json`` (the
estimates, standard errors, 95 % intervals and correlations; the settings) and
``fitted/fit.png`` (measured against fitted motion, of the first experiment), together or not
at all.  Bad input is one line with exit code 2; a fit that does not converge, exit code 1.
The first paragraph is the verb's ``--help`` description
(:func:`tensegrity.cli.arguments.description`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from tensegrity.cli import arguments, structures
from tensegrity.cli.errors import EXIT_FAILED, CommandError, blame, one_line
from tensegrity.cli.simulate import with_loads
from tensegrity.cli.simulate_options import nodal_load
from tensegrity.cli.startup import announce_compiling
from tensegrity.io.files import atomic_path, shown_path, write_staged

__all__ = ["add_parser"]


#: The verb's line in ``tensegrity --help``.
HELP = "fit stiffness, damping, rest lengths, masses or friction to measured motion"


def add_parser(sub: Any) -> None:
    """Add the ``fit`` verb to the ``tensegrity`` subcommands ``sub``."""
    from tensegrity.analysis.identification import KINDS

    p = sub.add_parser(
        "fit",
        help=HELP,
        description=arguments.description(__doc__),
    )
    structures.add_source_options(p)
    p.add_argument(
        "--data",
        type=Path,
        action="append",
        required=True,
        metavar="FILE",
        help="measurements: a markers CSV file (time,marker,x,y,z), a measurements CSV file "
        "(time,channel,value: position.NODE.x, length.TENDON, tension.TENDON) or a trajectory "
        "(.h5); repeat for several experiments",
    )
    p.add_argument(
        "--param",
        action="append",
        required=True,
        metavar="KIND[:NAMES]",
        help=f"a parameter to fit: {', '.join(KINDS)}, for every member or those whose names "
        "match NAMES (comma-separated, wildcards: tendon_stiffness:t1_*); repeat",
    )
    p.add_argument(
        "--noise",
        type=arguments.at_least(0.0, strict=True),
        default=1e-3,
        metavar="M",
        help="standard deviation of a measured coordinate or length [m] (default %(default)g)",
    )
    p.add_argument(
        "--tension-noise",
        type=arguments.at_least(0.0, strict=True),
        default=0.1,
        metavar="N",
        help="standard deviation of a measured tension [N] (default %(default)g)",
    )
    structures.add_gravity_option(p)
    p.add_argument(
        "--load",
        type=nodal_load,
        action="append",
        default=[],
        metavar="NODE:FX,FY,FZ[@RAMP]",
        help="a known nodal force [N] during the experiments (a name or 0-based index; ramped in "
        "over RAMP s); repeat",
    )
    p.add_argument(
        "--max-nfev",
        type=arguments.at_least(1, strict=False, parse=arguments.whole),
        default=50,
        metavar="N",
        help="the most evaluations of the residuals (default %(default)s)",
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.set_defaults(run=_cmd_fit)


def _experiment(
    path: Path, structure: Any, options: dict[str, Any], noise: float, tension_noise: float
) -> Any:
    """The experiment of the data file ``path``."""
    from tensegrity.analysis.identification import Experiment
    from tensegrity.io.measurements import (
        csv_kind,
        fitted_channels,
        read_markers,
        read_measurements,
    )
    from tensegrity.io.trajectory import read_trajectory
    from tensegrity.physics.dynamics import State

    if path.suffix.lower() in (".h5", ".hdf5"):
        with blame("--data", path):
            run = read_trajectory(path)
        ran = run.structure
        if not (
            ran.node_name == structure.node_name
            and np.array_equal(ran.rod_nodes, structure.rod_nodes)
            and np.array_equal(ran.tendon_nodes, structure.tendon_nodes)
        ):
            raise CommandError(
                f"--data: {shown_path(path)} is a run of another structure (other node names, "
                "rods or tendons than the model's)"
            )
        planes = options.get("ground") or ()
        if len(run.planes) != len(planes):
            raise CommandError(
                f"--data: {shown_path(path)} is a run on {len(run.planes)} ground plane(s), the "
                f"--structure file's scene has {len(planes)} (a file with a 'scene' key gives "
                "the planes)"
            )
        markers = {
            name: (run.t[1:], run.node_position[1:, i])
            for i, name in enumerate(structure.node_name)
            if not structure.node_fixed[i]
        }
        initial = State(float(run.t[0]), run.q[0], run.qdot[0])
        return Experiment(markers, noise, initial, float(run.t[0]), options, name=path.name)
    with blame("--data", path):
        if csv_kind(path) == "markers":
            d = structure.dim
            markers = {name: (s.t, s.position[:, :d]) for name, s in read_markers(path).items()}
            return Experiment(markers, noise, None, 0.0, options, name=path.name)
        series = fitted_channels(read_measurements(path), structure.dim)
    return Experiment(
        series["markers"],
        noise,
        None,
        0.0,
        options,
        name=path.name,
        lengths=series["lengths"],
        tensions=series["tensions"],
        tension_noise=tension_noise,
    )


def _cmd_fit(args: argparse.Namespace) -> int:
    from tensegrity.analysis.identification import fit
    from tensegrity.io.formats import read_scene, write_structure
    from tensegrity.model.ground import Scene
    from tensegrity.model.loads import gravity_vector
    from tensegrity.plots.identification import figure_fit

    if args.out.exists() and not args.out.is_dir():
        raise CommandError(f"--out: {shown_path(args.out)} is a file, expected a folder")
    structure = structures.structure_of(args)
    scene = Scene()
    if args.structure is not None:
        with blame("--structure", args.structure):
            scene = read_scene(args.structure)
    options: dict[str, Any] = {k: v for k, v in scene.simulate_options().items() if v is not None}
    force = with_loads(args.load, structure, None)
    if force is not None:
        options["external_force"] = force
    if args.gravity is not None:
        options["gravity"] = gravity_vector(args.gravity, structure.dim)
    experiments = [
        _experiment(path, structure, options, args.noise, args.tension_noise) for path in args.data
    ]
    announce_compiling()
    try:
        result = fit(structure, experiments, args.param, max_nfev=args.max_nfev)
    except ValueError as exc:
        raise CommandError(one_line(exc)) from None
    report = result.to_dict() | {
        "settings": dict(
            structure=None if args.structure is None else str(args.structure),
            data=[str(p) for p in args.data],
            noise_m=args.noise,
            tension_noise_n=args.tension_noise,
            gravity=args.gravity,
            load=[text for text, _ in args.load],
        )
    }

    def write(staging: Path) -> list[Path]:
        planes = result.options[0].get("ground") or ()
        fitted = dataclasses.replace(scene, planes=tuple(planes))
        target = write_structure(staging / "structure.json", result.structure, scene=fitted)
        with atomic_path(staging / "fit.json") as tmp:
            tmp.write_text(json.dumps(report, indent=2, allow_nan=False) + "\n", "utf-8")
        figure = figure_fit(result, structure, experiments[0], staging / "fit.png")
        return [Path(target), staging / "fit.json", figure]

    written = write_staged(args.out, write)
    for i, p in enumerate(result.parameters):
        low, high = result.interval[i]
        print(
            f"{p.name}: {result.estimate[i]:.6g} ± {result.standard_error[i]:.2g} "
            f"(95 %: {low:.6g} .. {high:.6g}; started at {result.initial[i]:.6g})"
        )
    print(
        f"rms error {result.rms_summary()} over {result.residual.size} measured values; "
        f"{result.message} ({result.nfev} evaluations, {result.njev} Jacobians)"
    )
    print("wrote " + ", ".join(str(f) for f in written))
    for sentence in result.undetermined():
        print(f"tensegrity: warning: {sentence}", file=sys.stderr)
    return 0 if result.success else EXIT_FAILED
