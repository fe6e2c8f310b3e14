"""Time to result from the shell: ``tensegrity simulate`` as a whole process against MuJoCo as a
whole process, on the same structure over the same simulated time, each with its accuracy.

Usage::

    python benchmarks/bench_cli.py [--sizes 3x1,10x10,30x30] [--runs 3] [--output FILE]

For each shell ``(n, m)`` and its span ``T`` (:data:`SPANS`):

- ``tensegrity simulate --n N --m M --damping none --no-steady-state --t-end T``: the CLI's main
  job from the paper's start (nodes on a cylinder, at rest, undamped), with every file it writes
  (trajectory, figures, page); by default DOP853, and again with ``--method rk4 --dt 1e-4``;
- MuJoCo: a Python process that imports MuJoCo, builds the same structure (read from the
  ``structure.json`` the CLI wrote) as free-body rods and spatial tendons (``bench_rhs.mjcf``:
  RK4 at dt = 1e-4, contacts off), compiles it and steps it over ``T``, then saves the nodes;
- the same from Python with tensegrity: a process that reads the structure, calls
  ``simulate`` over ``T`` (DOP853) and saves the nodes, writing nothing else, as MuJoCo's;
- the reference: ``simulate`` of that structure at rtol = atol = 1e-12, in this process.

Each whole process is timed from start to exit (the median of ``--runs``, wall clock, after one
run not counted); the accuracy is the largest node distance from the reference at ``T``.
"""

from __future__ import annotations

import argparse
import datetime
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
#: Simulated time [s] per shell: MuJoCo's (30,30) steps at about 170 a second.
SPANS = {(3, 1): 1.0, (10, 10): 0.5, (30, 30): 0.1}
DT = 1e-4


def _timed(command: list[str], runs: int) -> float:
    """Median wall time [s] of ``runs`` runs of ``command`` after one not counted."""
    times = []
    for k in range(runs + 1):
        start = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        if k:
            times.append(time.perf_counter() - start)
    return statistics.median(times)


def _mujoco_run(structure_file: str, span: float, nodes_file: str) -> None:
    """The MuJoCo process: the structure of ``structure_file`` stepped over ``span``; its node
    positions at ``span`` saved to ``nodes_file``."""
    import mujoco

    sys.path.insert(0, str(HERE))
    from bench_rhs import mjcf, mujoco_nodes, mujoco_set_state

    from tensegrity.io.formats import read_structure
    from tensegrity.physics import dynamics

    structure = read_structure(structure_file)
    p = structure.node_position
    model = mujoco.MjModel.from_xml_string(mjcf(structure, structure.tendon_rest_length, p, DT))
    data = mujoco.MjData(model)
    q = dynamics.coordinates_from_nodes(structure, p)
    mujoco_set_state(model, data, structure, q, np.zeros_like(q))
    mujoco.mj_step(model, data, nstep=round(span / DT))
    np.save(nodes_file, mujoco_nodes(model, data, structure))


def _api_run(structure_file: str, span: float, nodes_file: str) -> None:
    """The same from Python, as MuJoCo's process does it: the structure read, simulated over
    ``span`` (DOP853, the defaults), its node positions at ``span`` saved; no other file."""
    from tensegrity import simulate
    from tensegrity.io.formats import read_structure

    result = simulate(read_structure(structure_file), (0.0, span))
    np.save(nodes_file, result.node_position[-1])


def _deviation(nodes: np.ndarray, reference: np.ndarray) -> float:
    return float(np.max(np.linalg.norm(nodes - reference, axis=1)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="3x1,10x10,30x30")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--output", type=Path, help="also write the report to this file")
    for peer in ("mujoco", "api"):  # (the processes this one times)
        parser.add_argument(f"--{peer}-run", nargs=3, metavar=("STRUCTURE", "SPAN", "NODES"))
    args = parser.parse_args()
    for run, given in ((_mujoco_run, args.mujoco_run), (_api_run, args.api_run)):
        if given:
            structure_file, span, nodes_file = given
            run(structure_file, float(span), nodes_file)
            return
    from tensegrity import simulate
    from tensegrity.io.formats import read_structure
    from tensegrity.io.trajectory import read_dataset

    lines = [
        "# Time to result from the shell: `tensegrity simulate` against MuJoCo",
        "",
        f"- Command: `python benchmarks/bench_cli.py --sizes {args.sizes} --runs {args.runs}`",
        f"- Date: {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC",
        "- Whole processes, wall clock, median of the runs after one not counted; the "
        "deviation is the largest node distance at the end from `simulate` at rtol = atol = "
        "1e-12. MuJoCo: RK4 at dt = 1e-4, free-body rods, spatial tendons, contacts off.",
        "",
        "| shell | span | `tensegrity simulate` (DOP853) | deviation | `--method rk4 --dt 1e-4` "
        "| deviation | `simulate()` process | deviation | MuJoCo process | deviation "
        "| MuJoCo / `simulate()` process |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    print("\n".join(lines), flush=True)
    for text in args.sizes.split(","):
        n, m = (int(x) for x in text.split("x"))
        span = SPANS.get((n, m), 0.1)
        with tempfile.TemporaryDirectory() as folder:
            out = Path(folder)
            base = [
                "tensegrity", "simulate", "--n", str(n), "--m", str(m), "--damping", "none",
                "--no-steady-state", "--t-end", str(span),
            ]  # fmt: skip
            adaptive = _timed([*base, "--out", str(out / "dop853")], args.runs)
            fixed = _timed(
                [*base, "--method", "rk4", "--dt", str(DT), "--out", str(out / "rk4")], args.runs
            )
            structure_file = out / "dop853" / "structure.json"
            peers = {
                peer: _timed(
                    [sys.executable, __file__, f"--{peer}-run", str(structure_file), str(span),
                     str(out / f"{peer}.npy")],
                    args.runs,
                )
                for peer in ("api", "mujoco")
            }  # fmt: skip
            structure = read_structure(structure_file)
            reference = simulate(structure, (0.0, span), rtol=1e-12, atol=1e-12).node_position[-1]
            deviations = [
                _deviation(
                    read_dataset(out / kind / "trajectory.h5", "node_position")[-1], reference
                )
                for kind in ("dop853", "rk4")
            ]
            deviations += [_deviation(np.load(out / f"{p}.npy"), reference) for p in peers]
        row = (
            f"| ({n},{m}) | {span:g} s | {adaptive:.2f} s | {deviations[0]:.1e} m | {fixed:.2f} s "
            f"| {deviations[1]:.1e} m | {peers['api']:.2f} s | {deviations[2]:.1e} m "
            f"| {peers['mujoco']:.2f} s | {deviations[3]:.1e} m "
            f"| {peers['mujoco'] / peers['api']:.1f}× |"  # noqa: RUF001 - the multiplication sign
        )
        lines.append(row)
        print(row, flush=True)
    if args.output:
        args.output.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
