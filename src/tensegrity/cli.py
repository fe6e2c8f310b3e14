"""Command-line interface: ``tensegrity simulate | info | export | matrices``.

A thin layer over the library.  Errors are one line on stderr with exit code 2 (bad input) or
1 (the simulation failed); nothing is written unless the whole run succeeded, and every file is
written atomically.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from tensegrity import dynamics
from tensegrity.integrators import ADAPTIVE_METHODS, FIXED_STEP_METHODS
from tensegrity.planar import planar_rod, planar_two_rod
from tensegrity.shell import class1_shell, class2_shell
from tensegrity.structure import Structure

EXIT_FAILED, EXIT_USAGE = 1, 2


class CommandError(Exception):
    """A one-line error for the user, with its exit code."""

    def __init__(self, message: str, code: int = EXIT_USAGE) -> None:
        super().__init__(message)
        self.code = code


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, not usage + error
        raise CommandError(f"{self.prog}: {message}")


def _positive(text: str) -> float:
    value = _finite(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return value


def _non_negative(text: str) -> float:
    value = _finite(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def _damping(text: str) -> str | float:
    if text in ("none", "critical"):
        return text
    try:
        return _non_negative(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected 'none', 'critical' or a damping >= 0 in N s/m, got {text!r}"
        ) from None


def _add_structure_options(parser: argparse.ArgumentParser, *, allow_file: bool = True) -> None:
    group = parser.add_argument_group("structure (default: the paper's (3,1) class 1 shell)")
    if allow_file:
        group.add_argument("--structure", type=Path, metavar="FILE.json",
                           help="a structure file (JSON form) instead of a generated shell")
    group.add_argument("--kind", choices=tuple(_GENERATORS), default="shell",
                       help="the generated structure: the class 1 shell (default), the class 2 "
                            "shell of Lemma 18.1, the planar two-rod tensegrity (Appendix A, "
                            "Example 2) or a single planar rod (Example 1)")
    group.add_argument("--n", type=int, help="elements around the shell, >= 3 (default 3)")
    group.add_argument("--m", type=int,
                       help="stages up the shell, >= 1 (default 1; class 2 shell: >= 2, default 2)")
    group.add_argument("--fixed-base", action="store_true",
                       help="class 2 shell: fix the base ring to ground")
    group.add_argument("--primal", action="store_true", help="primal shell: no t9, t10 tendons")
    group.add_argument("--stiffness", type=_positive, help="tendon stiffness k [N/m] (default 100)")
    group.add_argument("--rest-length", type=_non_negative,
                       help="tendon rest length L0 [m] (default: half the shortest initial tendon)")


_SHELL_OPTIONS = ("n", "m", "primal", "stiffness", "rest_length", "fixed_base")
#: ``--kind``: (generator, the options of _SHELL_OPTIONS it takes, default m)
_GENERATORS: dict[str, tuple[Callable[..., Structure], tuple[str, ...], int]] = {
    "shell": (class1_shell, ("n", "m", "primal", "stiffness", "rest_length"), 1),
    "class2-shell": (class2_shell, _SHELL_OPTIONS, 2),
    "planar": (planar_two_rod, ("stiffness", "rest_length"), 0),
    "rod": (planar_rod, (), 0),
}


def _structure(args: argparse.Namespace) -> Structure:
    """The structure the options describe (a file, or a shell)."""
    given = [name for name in _SHELL_OPTIONS
             if getattr(args, name) is not None and getattr(args, name) is not False]
    flags = " ".join(f"--{name.replace('_', '-')}" for name in given)
    if getattr(args, "structure", None) is not None:
        if given or args.kind != "shell":
            raise CommandError(f"{flags or '--kind'}: generator options cannot be combined with "
                               "--structure")
        from tensegrity.io import read_structure

        return read_structure(args.structure)
    generator, accepted, default_m = _GENERATORS[args.kind]
    foreign = [f"--{name.replace('_', '-')}" for name in given if name not in accepted]
    if foreign:
        raise CommandError(f"{' '.join(foreign)}: not an option of --kind {args.kind}")
    options = {name: getattr(args, name) for name in given}
    if "n" in accepted:
        options.setdefault("n", 3)
        options.setdefault("m", default_m)
    return generator(**options)


def _apply_damping(structure: Structure, damping: str | float | None) -> Structure:
    if damping is None:
        return structure
    if damping == "critical":
        return dynamics.critical_damping(structure)
    tendon = 0.0 if damping == "none" else float(damping)
    return structure.replace(
        tendon_damping=np.full(structure.n_tendons, tendon), rod_damping=np.zeros(structure.n_rods)
    )


# ------------------------------------------------------------------------------ commands
def _cmd_simulate(args: argparse.Namespace) -> int:
    from tensegrity.io import write_structure, write_trajectory
    from tensegrity.plotting import save_figures
    from tensegrity.simulate import simulate

    structure = _structure(args)
    damping = args.damping
    if damping is None and getattr(args, "structure", None) is None:
        damping = "critical"  # the paper's example
    structure = _apply_damping(structure, damping)
    if args.method in FIXED_STEP_METHODS and args.dt is None:
        raise CommandError(f"--dt: method {args.method!r} is fixed-step and needs --dt")
    if args.method not in FIXED_STEP_METHODS and args.dt is not None:
        raise CommandError(f"--dt: only for fixed-step methods ({', '.join(FIXED_STEP_METHODS)})")
    result = simulate(
        structure,
        (0.0, args.t_end),
        method=args.method,
        rtol=args.rtol,
        atol=args.atol,
        dt=args.dt,
        sample_dt=args.sample_dt,
        steady_state=not args.no_steady_state,
        progress=sys.stderr.isatty(),
    )
    if not result.success:
        raise CommandError(f"simulation failed: {result.message} (nothing written)", EXIT_FAILED)
    written = _write_all(args.out, lambda staging: [
        write_trajectory(staging / "trajectory.h5", result),
        write_structure(staging / "structure.json", structure),
        *save_figures(result, staging),
    ])
    _print_summary(result, written)
    return 0


def _write_all(out: Path, write: Callable[[Path], list[Path]]) -> list[Path]:
    """Write every output into a staging folder inside ``out``, then move them into ``out``.

    Either all files appear (each by an atomic rename) or, if any write fails, none does and a
    folder created for them is removed again.
    """
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        with tempfile.TemporaryDirectory(dir=out, prefix=".staging-") as staging:
            moved = []
            for path in write(Path(staging)):
                os.replace(path, out / path.name)
                moved.append(out / path.name)
            return moved
    except BaseException:
        if created and not any(out.iterdir()):
            out.rmdir()
        raise


def _print_summary(result, files: Sequence[Path]) -> None:
    e = result.energy
    rows = [
        ("status", result.message),
        ("samples", f"{result.t.size} from t = {result.t[0]:g} to {result.t[-1]:.6g} s"),
        ("final residual acceleration", f"{result.residual_acceleration[-1]:.3e} m/s^2"),
        ("final largest node speed", f"{np.abs(result.node_velocity[-1]).max():.3e} m/s"),
        ("largest rod-length error", f"{result.max_rod_length_error:.3e} (relative)"),
        *([("largest joint/support error", f"{result.max_constraint_error:.3e} m")]
          if result.structure.has_constraints else []),
        ("energy dissipated", f"{e['dissipated'][-1]:.6g} J"),
        ("energy balance error", f"{np.abs(result.total_energy - result.total_energy[0]).max():.3e} J"),
        ("slack tendons at the end", f"{int(result.slack_count[-1])} of {result.structure.n_tendons}"),
        ("tension range at the end",
         f"{result.tendon_tension[-1].min():.6g} .. {result.tendon_tension[-1].max():.6g} N"),
        ("integration", f"{result.settings['method']}: {result.nsteps} steps, {result.nfev} "
                        f"evaluations, {result.nswitches} slack/taut switches located"),
        ("wall time", f"{result.wall_time:.2f} s"),
    ]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    print("wrote " + ", ".join(str(f) for f in files))


def _cmd_info(args: argparse.Namespace) -> int:
    s = _structure(args)
    lengths = dynamics.tendon_lengths(s, s.node_position)
    low, high = s.node_position.min(axis=0), s.node_position.max(axis=0)
    slack = int(np.sum(lengths <= s.tendon_rest_length))
    masses = f", {s.dim} per point mass" if s.point_mass_nodes.size else ""
    rows = [
        ("nodes", s.n_nodes),
        ("rods", s.n_rods),
        ("tendons", s.n_tendons),
        ("degrees of freedom", f"{s.n_dof} ({2 * s.dim - 1} per rod{masses})"),
        ("coordinates q", f"{s.n_coordinates} ({2 * s.dim} per rod: q1 = p_a + p_b, q2 = p_b - p_a"
                          f"{masses})"),
        ("total mass", f"{s.total_mass:.6g} kg"),
        ("rod length", _range(s.rod_length, "m")),
        ("tendon stiffness", _range(s.tendon_stiffness, "N/m")),
        ("tendon rest length", _range(s.tendon_rest_length, "m")),
        ("tendon damping", _range(s.tendon_damping, "N s/m")),
        ("initial tendon length", _range(lengths, "m")),
        ("initially slack tendons", slack),
        ("bounding box", f"[{', '.join(f'{x:.4g}' for x in low)}] .. "
                         f"[{', '.join(f'{x:.4g}' for x in high)}] m"),
    ]
    supports = (("ball joints (node pairs)", len(s.joint_nodes)), ("fixed nodes", int(s.node_fixed.sum())),
                ("point masses", len(s.point_mass_nodes)), ("nodes on planes", len(s.plane_nodes)),
                ("nodes on lines", len(s.line_nodes)))
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
    from tensegrity.io import write_structure

    structure = _apply_damping(_structure(args), args.damping)
    write_structure(args.output, structure)
    print(f"wrote {args.output} ({structure.n_nodes} nodes, {structure.n_rods} rods, "
          f"{structure.n_tendons} tendons)")
    return 0


def _cmd_matrices(args: argparse.Namespace) -> int:
    from tensegrity.matrices import undamped, write_matrices
    from tensegrity.simulate import simulate

    structure = undamped(_structure(args))
    if args.at == "equilibrium":
        # Tight rest tolerances: with the damping removed, K_p q = q'' is then below ~1e-8.
        result = simulate(dynamics.critical_damping(structure), (0.0, args.t_end),
                          steady_state=True, velocity_tol=1e-9, acceleration_tol=1e-9,
                          rtol=1e-10, sample_dt=0.1, progress=sys.stderr.isatty())
        if result.status != 1:
            raise CommandError(
                f"no equilibrium found by damped simulation within --t-end {args.t_end:g} s: "
                f"{result.message}", EXIT_FAILED)
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


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="tensegrity", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    sim = sub.add_parser(
        "simulate",
        help="simulate a structure (default: the paper's damped (3,1) shell, until steady state)",
        description="Simulate a structure and write trajectory.h5, structure.json and figures.",
    )
    _add_structure_options(sim)
    sim.add_argument("--damping", type=_damping, metavar="none|critical|VALUE",
                     help="tendon damping: 'critical' (default for a shell; see docs), 'none', or "
                          "c in N s/m for every tendon (default for --structure: as in the file)")
    sim.add_argument("--t-end", type=_positive, default=60.0, help="end time [s] (default 60)")
    sim.add_argument("--no-steady-state", action="store_true",
                     help="run to --t-end even after the structure has come to rest")
    sim.add_argument("--out", type=Path, default=Path("results"), help="output folder (default ./results)")
    integration = sim.add_argument_group("integration")
    integration.add_argument("--method", default="DOP853",
                             choices=[*ADAPTIVE_METHODS, *FIXED_STEP_METHODS],
                             help="adaptive scipy method or fixed-step 'rk4' (default DOP853)")
    integration.add_argument("--dt", type=_positive, help="fixed step [s] (rk4 only)")
    integration.add_argument("--rtol", type=_positive, default=1e-9, help="relative tolerance (default 1e-9)")
    integration.add_argument("--atol", type=_positive, default=1e-12, help="absolute tolerance (default 1e-12)")
    integration.add_argument("--sample-dt", type=_positive, default=0.01,
                             help="output spacing [s] (default 0.01)")
    sim.set_defaults(run=_cmd_simulate)

    info = sub.add_parser("info", help="print counts and sizes of a structure")
    _add_structure_options(info)
    info.set_defaults(run=_cmd_info)

    export = sub.add_parser("export", help="write a structure file (JSON form)")
    _add_structure_options(export, allow_file=False)
    export.add_argument("--damping", type=_damping, metavar="none|critical|VALUE",
                        help="tendon damping to store (default none)")
    export.add_argument("-o", "--output", type=Path, required=True, help="output .json file")
    export.set_defaults(run=_cmd_export)

    matrices = sub.add_parser(
        "matrices",
        help="write the paper's matrices (Q, R, T, B^d, B^o, H, K_r, K_p, B, D, ...) of a shell",
        description="Write the matrix model (18.59) of a class 1 shell as .npz and Matrix Market "
                    "(.mtx) files with an index (matrices.json).",
    )
    _add_structure_options(matrices)
    matrices.add_argument("--at", choices=("initial", "equilibrium"), default="initial",
                          help="state at which the state-dependent matrices are evaluated: the "
                               "initial layout, or the equilibrium reached by damped simulation")
    matrices.add_argument("--t-end", type=_positive, default=60.0,
                          help="longest damped simulation when looking for the equilibrium [s]")
    matrices.add_argument("--out", type=Path, default=Path("matrices"),
                          help="output folder (default ./matrices)")
    matrices.set_defaults(run=_cmd_matrices)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``tensegrity`` command; returns the exit code."""
    try:
        args = build_parser().parse_args(argv)
        return args.run(args)
    except CommandError as exc:
        print(f"tensegrity: error: {exc}", file=sys.stderr)
        return exc.code
    except (ValueError, OSError, KeyError) as exc:
        print(f"tensegrity: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("tensegrity: interrupted (nothing written)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
