"""The verbs that read or convert a structure or a trajectory: ``info``, ``export``, ``vtk``
and ``matrices``."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.cli import arguments, outputs
from tensegrity.cli.errors import EXIT_FAILED, CommandError, blame
from tensegrity.cli.limits import check_run_cost
from tensegrity.cli.startup import announce_compiling
from tensegrity.cli.structures import (
    add_structure_options,
    apply_damping,
    damping_kind,
    structure_of,
)
from tensegrity.engine.options import Options
from tensegrity.io.files import folders_made, write_staged as _write_all
from tensegrity.physics import dynamics

if TYPE_CHECKING:
    from tensegrity.model.structure import Structure


#: ``info`` counts the degrees of freedom the joints and supports leave (a dense SVD) up to this
#: many degrees of freedom before them.
_INFO_DOF_LIMIT = 3000


def _cmd_info(args: argparse.Namespace) -> int:
    s = structure_of(args)
    lengths = dynamics.tendon_lengths(s, s.node_position)
    low, high = s.node_position.min(axis=0), s.node_position.max(axis=0)
    slack = int(np.sum(lengths <= s.tendon_rest_length))
    masses = f", {s.dim} per point mass" if s.point_mass_nodes.size else ""
    dof = f"{s.n_dof} ({2 * s.dim - 1} per rod{masses})"
    if s.has_constraints:
        if s.n_dof <= _INFO_DOF_LIMIT:
            from tensegrity.analysis.coordinates import admitted_dof

            held = s.n_dof - admitted_dof(s)
            dof = (
                f"{s.n_dof - held} ({2 * s.dim - 1} per rod{masses}, less {held} held by the "
                "joints and supports in this layout)"
            )
        else:
            dof += " before the joints and supports"
    rows = [
        ("nodes", s.n_nodes),
        ("rods", s.n_rods),
        ("tendons", s.n_tendons),
        ("degrees of freedom", dof),
        (
            "coordinates q",
            f"{s.n_coordinates} ({2 * s.dim} per rod: q1 = p_a + p_b, q2 = p_b - p_a{masses})",
        ),
        ("total mass", f"{s.total_mass:.6g} kg"),
        ("rod length", _range(s.rod_length, "m")),
        ("tendon stiffness", _range(s.tendon_stiffness, "N/m")),
        ("tendon rest length", _range(s.tendon_rest_length, "m")),
        ("damping", dynamics.describe_damping(s)),
        ("initial tendon length", _range(lengths, "m")),
        ("initially slack tendons", slack),
        (
            "bounding box",
            f"[{', '.join(f'{x:.4g}' for x in low)}] .. [{', '.join(f'{x:.4g}' for x in high)}] m",
        ),
    ]
    supports = (
        ("ball joints (node pairs)", len(s.joint_nodes)),
        ("fixed nodes", int(s.node_fixed.sum())),
        ("point masses", len(s.point_mass_nodes)),
        ("nodes on planes", len(s.plane_nodes)),
        ("nodes on lines", len(s.line_nodes)),
    )
    rows += [(name, count) for name, count in supports if count]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    return 0


def _range(values: np.ndarray, unit: str) -> str:
    if values.size == 0:
        return "-"
    low, high = values.min(), values.max()
    return f"{low:.6g} {unit}" if low == high else f"{low:.6g} .. {high:.6g} {unit}"


def _cmd_export(args: argparse.Namespace) -> int:
    from tensegrity.io.formats import FORMATS, write_network

    structure = apply_damping(structure_of(args), args.damping)
    outputs.check_file(args.output, "--output")
    fmt = args.format or FORMATS.get(args.output.suffix.lower(), "json")
    with folders_made(args.output.parent):
        write_network(args.output, structure, format=fmt, keep_joints=args.keep_joints)
    print(
        f"wrote {args.output} ({fmt}: {structure.n_nodes} nodes, {structure.n_rods} rods, "
        f"{structure.n_tendons} tendons)"
    )
    return 0


def _cmd_vtk(args: argparse.Namespace) -> int:
    from tensegrity.io.trajectory import read_trajectory
    from tensegrity.io.vtk import write_vtk

    outputs.check_folder(args.output, "--output")
    with blame("vtk", args.trajectory):
        trajectory = read_trajectory(args.trajectory)
    written = write_vtk(args.output, trajectory, every=args.every, name=args.name)
    print(f"wrote {len(written) - 1} VTK files and {written[-1]} (open it in ParaView)")
    return 0


#: ``matrices --at equilibrium`` is at rest when node speeds [m/s] and accelerations [m/s^2]
#: are below this.
MATRICES_REST_TOL = 1e-9


def _cmd_matrices(args: argparse.Namespace) -> int:
    from tensegrity.engine.simulate import simulate
    from tensegrity.io.matrices import write_matrices

    _check_shell_options(args)
    outputs.check_folder(args.out, "--out")
    structure = dynamics.undamped(structure_of(args))
    _check_matrix_size(structure)
    _check_shell(structure, args)
    if args.at == "equilibrium":
        announce_compiling()
        check_run_cost(
            structure,
            args.t_end,
            Options(steady_state=True, acceleration_tol=MATRICES_REST_TOL),
            remedy="softer tendons or a shorter --t-end",
        )
        # Tight rest tolerances: with the damping removed, K_p q = q'' is then below ~1e-8.
        result = simulate(
            dynamics.artificial_damping(structure),
            (0.0, args.t_end),
            steady_state=True,
            velocity_tol=MATRICES_REST_TOL,
            acceleration_tol=MATRICES_REST_TOL,
            rtol=1e-10,
            sample_dt=0.1,
            progress=sys.stderr.isatty(),
        )
        if result.status != 1:
            raise CommandError(
                f"no equilibrium found by damped simulation within --t-end {args.t_end:g} s: "
                f"{result.message}",
                EXIT_FAILED,
            )
        state = result.final_state
    else:
        state = dynamics.initial_state(structure)
    rows: list = []

    def write(staging: Path) -> list[Path]:
        rows.extend(write_matrices(staging, structure, state.q, state.qdot, at=args.at))
        return sorted(staging.iterdir())

    written = _write_all(args.out, write)
    width = max(len(name) for name, _, _ in rows)
    print(f"{'matrix':<{width}}  {'shape':>13}  non-zeros")
    for name, (n_rows, n_cols), nnz in rows:
        print(f"{name:<{width}}  {n_rows:>6} x {n_cols:<6}  {nnz}")
    print(f"evaluated at the {args.at} state; wrote {len(written)} files to {args.out}")
    return 0


#: What ``matrices`` takes, after the option that asks for something else.
_SHELLS_ONLY = (
    "the matrix model: supports only free 3-D class 1 shells (--kind shell, the default, with "
    "or without --primal; not --fixed-base)"
)


def _check_shell_options(args: argparse.Namespace) -> None:
    """Refuse a generated structure other than a free class 1 shell before any work, naming
    the option that asks for it."""
    if args.structure is not None:
        return  # a file: :func:`_check_shell` once it is read
    if args.kind not in (None, "shell"):
        raise CommandError(f"--kind {args.kind}: {_SHELLS_ONLY}")
    if args.fixed_base:
        raise CommandError(f"--fixed-base: {_SHELLS_ONLY}")


def _check_shell(structure: Structure, args: argparse.Namespace) -> None:
    """Refuse ``structure`` up front (before a damped simulation to the equilibrium) if it is
    not a class 1 shell the matrix model takes."""
    from tensegrity.physics.matrix_form import shell_size

    source = "matrices" if args.structure is None else "--structure"
    with blame(source, args.structure):
        shell_size(structure)


#: ``matrices`` builds dense (nodes x nodes) arrays: at most this many nodes (0.5 GiB each).
_MATRICES_NODE_LIMIT = 8192


def _check_matrix_size(structure: Structure) -> None:
    """Fail up front if the matrix model of ``structure`` would need too large dense arrays."""
    n = structure.n_nodes
    if n > _MATRICES_NODE_LIMIT:
        raise CommandError(
            f"matrices: the matrix model of {n} nodes builds dense {n} x {n} arrays "
            f"({n * n * 8 / 2**30:.3g} GiB each); expected at most {_MATRICES_NODE_LIMIT} nodes "
            "(a smaller shell)"
        )


def _add_info_parser(sub: Any) -> None:
    """``info``: counts and sizes of a structure."""
    info = sub.add_parser(
        "info",
        help="print counts and sizes of a structure",
        description="Print the counts and sizes of a structure: nodes, rods, tendons, degrees "
        "of freedom, coordinates, mass, lengths, stiffnesses, damping, slack tendons, bounding "
        "box, and its joints, supports and point masses.",
    )
    add_structure_options(info)
    info.set_defaults(run=_cmd_info)


def _add_export_parser(sub: Any) -> None:
    """``export``: a structure to a file in any format."""
    export = sub.add_parser(
        "export",
        help="write a generated structure or a structure file to a file (any format)",
        description="Write a generated structure or a structure file to a structure file: JSON, "
        "YAML, TOML, connectivity .npz or MuJoCo MJCF (.xml), by --format or the suffix of "
        "--output.",
    )
    add_structure_options(export)
    export.add_argument(
        "--damping",
        type=damping_kind,
        metavar="internal|artificial|none|VALUE",
        help="damping to store, as for simulate (default: none for a generated structure, "
        "as in the file for --structure)",
    )
    export.add_argument(
        "--format",
        choices=("json", "yaml", "toml", "connectivity", "mjcf"),
        help="file format (default: from the suffix .json .yaml .toml .npz .xml, else json)",
    )
    export.add_argument(
        "--keep-joints",
        action="store_true",
        help="yaml/toml/connectivity: keep every rod's end nodes and list the ball "
        "joints (reads back identical) instead of merging joined nodes into "
        "nodes shared by bars (class k, the default)",
    )
    export.add_argument("-o", "--output", type=arguments.name, required=True, help="output file")
    export.set_defaults(run=_cmd_export)


def _add_vtk_parser(sub: Any) -> None:
    """``vtk``: a trajectory file to VTK files for ParaView."""
    vtk = sub.add_parser(
        "vtk",
        help="convert a trajectory to VTK files for ParaView",
        description="Write a trajectory (trajectory.h5) as one VTK PolyData file "
        "per sample (.vtp) and a collection (.pvd) for ParaView.",
    )
    vtk.add_argument("trajectory", type=arguments.name, help="a trajectory.h5 written by simulate")
    vtk.add_argument("-o", "--output", type=arguments.name, required=True, help="output folder")
    vtk.add_argument(
        "--every", type=int, default=1, help="keep one sample in EVERY (default %(default)d)"
    )
    vtk.add_argument("--name", default="tensegrity", help="file name stem (default %(default)s)")
    vtk.set_defaults(run=_cmd_vtk)


def _add_matrices_parser(sub: Any) -> None:
    """``matrices``: the paper's matrix model of a shell to files."""
    matrices = sub.add_parser(
        "matrices",
        help="write the paper's matrices (Q, R, T, B^d, B^o, H, K_r, K_p, B, D, ...) of a shell",
        description="Write the matrix model (18.59) of a class 1 shell as .npz and Matrix Market "
        "(.mtx) files with an index (matrices.json).",
    )
    add_structure_options(matrices)
    matrices.add_argument(
        "--at",
        choices=("initial", "equilibrium"),
        default="initial",
        help="state at which the state-dependent matrices are evaluated: the "
        "initial layout, or the equilibrium reached by damped simulation (default %(default)s)",
    )
    matrices.add_argument(
        "--t-end",
        type=arguments.positive,
        default=60.0,
        help="longest damped simulation when looking for the equilibrium [s] (default %(default)g)",
    )
    matrices.add_argument(
        "--out",
        type=arguments.name,
        default=Path("matrices"),
        help="output folder (default ./matrices)",
    )
    matrices.set_defaults(run=_cmd_matrices)


def add_parsers(sub: Any) -> None:
    """Add the verbs ``info``, ``export``, ``vtk`` and ``matrices`` to the ``tensegrity``
    subcommands ``sub``."""
    _add_info_parser(sub)
    _add_export_parser(sub)
    _add_vtk_parser(sub)
    _add_matrices_parser(sub)
