#!/usr/bin/env python
"""Identification: the time of a fit (``tensegrity.analysis.identification.fit``) on the two
examples of ``docs/identification.md``, and where it goes.

Usage::

    python benchmarks/bench_identify.py [--output FILE]

- **shell**: the fixed-base (3,1) shell under gravity and a known 5 N push, 1 s of 4 markers at
  30 Hz with 1 mm noise; tendon stiffness, tendon damping and rod mass fitted from 20 % off.
- **robot**: the three-bar robot dropped 1 cm onto the ground at 1.5 m/s sideways, 1 s of 3
  markers at 30 Hz with 1 mm noise; kinetic friction and cable stiffness fitted from 0.3 and
  250 N/m (truth 0.4 and 300 N/m).

For each: the wall time of the fit (the engine's cache warm: one run first), its residual and
Jacobian evaluations (a Jacobian is one run with the sensitivities integrated,
:mod:`tensegrity.engine.sensitivity`), the time of one plain run and of one with the
sensitivities, and the estimates against the truth.  Results go to
``benchmarks/results-identify.md`` (or ``--output``).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import time
from pathlib import Path

import numpy as np

from tensegrity import simulate
from tensegrity.analysis.identification import Experiment, fit, parameter
from tensegrity.design.catalogue import three_bar_robot
from tensegrity.engine.sensors import Sensor, measure
from tensegrity.model.ground import ground
from tensegrity.model.shell import class1_shell
from tensegrity.physics.dynamics import State, coordinates_from_nodes, initial_state

HERE = Path(__file__).resolve().parent
GRAVITY = np.array([0.0, 0.0, -9.81])
NOISE = 1e-3


def _markers(run, names, seed=0):
    (series,) = measure(
        run, [Sensor("position", nodes=names, noise=NOISE, rate=30.0)], seed=seed
    ).series
    return {n: (series.t, series.value[:, 3 * i : 3 * i + 3]) for i, n in enumerate(names)}


def shell_case():
    """(starting structure, experiment, parameters, true values, start state, run options)."""
    base = class1_shell(3, 1, fixed_base=True)

    def shell(k, c, m):
        return base.replace(
            tendon_stiffness=np.full(base.n_tendons, k),
            tendon_damping=np.full(base.n_tendons, c),
            rod_mass=np.full(base.n_rods, m),
        )

    w = np.zeros((12, 3))
    w[11, 0] = 5.0
    options = {"gravity": GRAVITY, "external_force": w}
    run = simulate(shell(120.0, 0.8, 1.3), (0.0, 1.0), sample_dt=0.01, **options)
    experiment = Experiment(_markers(run, ("n3", "n7", "n11", "n5")), NOISE, options=options)
    names = ["tendon_stiffness", "tendon_damping", "rod_mass"]
    return shell(100.0, 0.6, 1.0), experiment, names, [120.0, 0.8, 1.3], None, options


def robot_case():
    robot = three_bar_robot(stiffness=300.0, tension=20.0)
    robot = robot.replace(node_position=robot.node_position + np.array([0.0, 0.0, 0.01]))
    v = np.zeros_like(robot.node_position)
    v[:, 0] = 1.5
    start = State(0.0, initial_state(robot).q, coordinates_from_nodes(robot, v))
    true = {"gravity": GRAVITY, "ground": ground(friction=0.5, kinetic_friction=0.4)}
    run = simulate(robot, (0.0, 1.0), initial=start, sample_dt=0.01, **true)
    guess = {"gravity": GRAVITY, "ground": ground(friction=0.5, kinetic_friction=0.3)}
    experiment = Experiment(_markers(run, robot.node_name[:3]), NOISE, start, options=guess)
    model = robot.replace(tendon_stiffness=np.full(robot.n_tendons, 250.0))
    return model, experiment, ["kinetic_friction", "tendon_stiffness"], [0.4, 300.0], start, guess


def measure_case(name, case):
    model, experiment, names, truth, start, options = case()
    t0 = time.perf_counter()
    simulate(model, (0.0, 1.0), initial=start, sample_dt=0.01, **options)
    one_run = time.perf_counter() - t0
    parameters = [parameter(model, n) for n in names]
    t0 = time.perf_counter()
    simulate(model, (0.0, 1.0), initial=start, sample_dt=0.01, sensitivity=parameters, **options)
    one_sensitivity_run = time.perf_counter() - t0
    t0 = time.perf_counter()
    result = fit(model, experiment, names)
    wall = time.perf_counter() - t0
    estimates = ", ".join(
        f"{n} {e:.5g} ± {s:.2g} (truth {t:g})"
        for n, e, s, t in zip(names, result.estimate, result.standard_error, truth, strict=True)
    )
    return (
        f"| {name} | {wall:.1f} s | {result.nfev} | {result.njev} | "
        f"{1e3 * one_run:.0f} ms | {1e3 * one_sensitivity_run:.0f} ms | {estimates} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", type=Path, default=HERE / "results-identify.md")
    args = parser.parse_args()
    for case in (shell_case, robot_case):  # fill numba's cache first
        case()
    rows = [
        measure_case(name, case) for name, case in (("shell", shell_case), ("robot", robot_case))
    ]
    write_report(
        args.output,
        title="Identification: the time of a fit",
        command="python benchmarks/bench_identify.py",
        note="The fits of `docs/identification.md`'s examples (growing horizons: each of 3 least "
        "squares counted, their runs with the horizons' shorter spans); a Jacobian is one run "
        "with the sensitivities to the P parameters integrated (`docs/identification.md`); the "
        "runs of 1 s at the starting values, plain and with the sensitivities.",
        table=[
            "| example | fit | residual evaluations | Jacobians | one run | one run with "
            "sensitivities | estimates |",
            "|---|---:|---:|---:|---:|---:|---|",
            *rows,
        ],
    )


def write_report(output: Path, *, title: str, command: str, note: str, table: list[str]) -> None:
    """A results page: its title, the command, the date and machine, a note, the table;
    printed and written to ``output``."""
    lines = [
        f"# {title}",
        "",
        f"- Command: `{command}`",
        f"- Date: {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC; {platform.machine()}, "
        f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at the end",
        f"- {note}",
        "",
        *table,
        "",
    ]
    text = "\n".join(lines)
    print(text)
    output.write_text(text)


if __name__ == "__main__":
    main()
