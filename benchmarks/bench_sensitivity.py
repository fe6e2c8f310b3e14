#!/usr/bin/env python
"""Gradients through a run: the sensitivities integrated with the state
(``simulate(..., sensitivity=...)``, :mod:`tensegrity.engine.sensitivity`) against central
differences of whole runs, for accuracy and time, side by side in one process.

Usage::

    python benchmarks/bench_sensitivity.py [--output FILE] [--repeat N]

- **shell**: the damped fixed-base (3,1) shell under gravity and a 5 N push, 1 s (slack/taut
  switches); 4 parameters: tendon stiffness, damping and rest length, rod mass.
- **robot**: the three-bar robot dropped 1 cm onto the ground at 1.5 m/s sideways, 1 s
  (touch-downs, lift-offs, sticks, slips); 4 parameters: cable stiffness, rod mass, static
  and kinetic friction.

Then the cost against the number of parameters: both runs with P = 1, 2, 4, 8 parameters, each
one tendon's stiffness.

Both at the fit's tolerances (``rtol`` 1e-10, ``atol`` 1e-13).  The reference is central
differences of whole runs at ``rtol`` 1e-12 (step 1e-5 of each parameter); the error is the
largest over samples and coordinates of ``|dq/dp - reference|``, relative to the largest
``|reference|``, worst over the parameters.  Times are medians of ``--repeat`` runs (numba's
cache warm), the differences' being the ``2 P`` runs they need.  Results go to
``benchmarks/results-sensitivity.md`` (or ``--output``).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import statistics
import time
from pathlib import Path

import numpy as np
from bench_identify import write_report  # (run from this folder, as the usage says)

from tensegrity import simulate
from tensegrity.analysis.identification import parameter
from tensegrity.design.catalogue import three_bar_robot
from tensegrity.model.ground import ground
from tensegrity.model.shell import class1_shell
from tensegrity.physics.dynamics import State, coordinates_from_nodes, initial_state

HERE = Path(__file__).resolve().parent
GRAVITY = np.array([0.0, 0.0, -9.81])
FIT = {"rtol": 1e-10, "atol": 1e-13}
REFERENCE = {"rtol": 1e-12, "atol": 1e-15}
STEP = 1e-5


@dataclasses.dataclass(frozen=True)
class Case:
    """A structure, its run options for given parameter values, and the parameters."""

    name: str
    structure: object
    values: tuple[float, ...]
    parameters: list
    options: object  # values -> (structure, run options)


def shell_case() -> Case:
    base = class1_shell(3, 1, fixed_base=True)
    base = base.replace(
        tendon_stiffness=np.full(base.n_tendons, 120.0),
        tendon_damping=np.full(base.n_tendons, 0.8),
        rod_mass=np.full(base.n_rods, 1.3),
    )
    w = np.zeros((12, 3))
    w[11, 0] = 5.0
    names = ["tendon_stiffness", "tendon_damping", "tendon_rest_length", "rod_mass"]
    parameters = [parameter(base, n) for n in names]

    def options(values):
        s = base
        for p, v in zip(parameters, values, strict=True):
            s = p.apply(s, v)
        return s, {"gravity": GRAVITY, "external_force": w, "sample_dt": 0.01}

    values = tuple(float(np.mean(getattr(base, p.field))) for p in parameters)
    return Case("shell (3,1), damped, 1 s", base, values, parameters, options)


def robot_case() -> Case:
    robot = three_bar_robot(stiffness=300.0, tension=20.0)
    robot = robot.replace(node_position=robot.node_position + np.array([0.0, 0.0, 0.01]))
    v = np.zeros_like(robot.node_position)
    v[:, 0] = 1.5
    start = State(0.0, initial_state(robot).q, coordinates_from_nodes(robot, v))
    names = ["tendon_stiffness", "rod_mass", "friction", "kinetic_friction"]
    parameters = [parameter(robot, n) for n in names]

    def options(values):
        k, m, mu_s, mu_k = values
        s = parameters[1].apply(parameters[0].apply(robot, k), m)
        plane = ground(friction=mu_s, kinetic_friction=mu_k)
        return s, {"initial": start, "gravity": GRAVITY, "ground": plane, "sample_dt": 0.01}

    values = (300.0, float(robot.rod_mass[0]), 0.5, 0.4)
    return Case("three-bar robot on the ground, 1 s", robot, values, parameters, options)


def differences(case: Case, tolerances: dict) -> np.ndarray:
    """(T, P, n) dq/dp by central differences of whole runs."""
    columns = []
    for j, value in enumerate(case.values):
        h = STEP * value
        runs = []
        for sign in (1, -1):
            values = list(case.values)
            values[j] = value + sign * h
            s, options = case.options(values)
            runs.append(simulate(s, (0.0, 1.0), **options, **tolerances).q)
        columns.append((runs[0] - runs[1]) / (2 * h))
    return np.stack(columns, axis=1)


def integrated(case: Case, tolerances: dict) -> np.ndarray:
    s, options = case.options(case.values)
    run = simulate(s, (0.0, 1.0), sensitivity=case.parameters, **options, **tolerances)
    return run.q_sensitivity


def error(result: np.ndarray, reference: np.ndarray) -> float:
    return max(
        float(np.abs(result[:, j] - reference[:, j]).max() / np.abs(reference[:, j]).max())
        for j in range(reference.shape[1])
    )


def timed(function, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        function()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def measure_case(case: Case, repeat: int) -> str:
    s, options = case.options(case.values)
    plain = timed(lambda: simulate(s, (0.0, 1.0), **options, **FIT), repeat)
    with_sensitivity = timed(lambda: integrated(case, FIT), repeat)
    by_differences = timed(lambda: differences(case, FIT), repeat)
    reference = differences(case, REFERENCE)
    P = len(case.parameters)
    return (
        f"| {case.name} | {P} | {1e3 * plain:.0f} ms | {1e3 * with_sensitivity:.0f} ms "
        f"({with_sensitivity / plain:.1f}x) | {1e3 * by_differences:.0f} ms "
        f"({by_differences / plain:.1f}x) | {error(integrated(case, FIT), reference):.1e} | "
        f"{error(differences(case, FIT), reference):.1e} |"
    )


def cost_rows(case: Case, repeat: int) -> list[str]:
    """The run with sensitivities to P = 1, 2, 4, 8 parameters (each one tendon's stiffness)
    against the plain run: how the cost grows with P."""
    s, options = case.options(case.values)
    plain = timed(lambda: simulate(s, (0.0, 1.0), **options, **FIT), repeat)
    cells = []
    for P in COUNTS:
        params = [parameter(s, f"tendon_stiffness:{name}") for name in s.tendon_name[:P]]
        run = functools.partial(simulate, s, (0.0, 1.0), sensitivity=params, **options, **FIT)
        run()  # (numba's cache)
        cost = timed(run, repeat)
        cells.append(f"{1e3 * cost:.0f} ms ({cost / plain:.1f}x)")
    return [f"| {case.name} | {1e3 * plain:.0f} ms | " + " | ".join(cells) + " |"]


#: The numbers of parameters of :func:`cost_rows`.
COUNTS = (1, 2, 4, 8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--output", type=Path, default=HERE / "results-sensitivity.md")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    cases = [shell_case(), robot_case()]
    for case in cases:  # fill numba's cache first
        integrated(case, FIT)
        differences(case, FIT)
    rows = [measure_case(case, args.repeat) for case in cases]
    costs = [row for case in cases for row in cost_rows(case, args.repeat)]
    write_report(
        args.output,
        title="Gradients through a run: integrated sensitivities against differences of runs",
        command="python benchmarks/bench_sensitivity.py",
        note="At the fit's tolerances (rtol 1e-10); error against central differences of runs "
        "at rtol 1e-12, relative to the largest derivative, worst parameter; times are medians "
        f"of {args.repeat} (the ratio to one plain run in brackets, x).",
        table=[
            "| run | P | plain run | with sensitivities | central differences (2 P runs) | "
            "error, sensitivities | error, differences |",
            "|---|---:|---:|---:|---:|---:|---:|",
            *rows,
            "",
            "The cost against the number of parameters P (each one tendon's stiffness): the run "
            "with sensitivities, and its ratio to the plain run.",
            "",
            "| run | plain run | " + " | ".join(f"P = {P}" for P in COUNTS) + " |",
            "|---|---:|" + "---:|" * len(COUNTS),
            *costs,
        ],
    )


if __name__ == "__main__":
    main()
