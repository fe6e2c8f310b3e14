#!/usr/bin/env python
"""What rate-limited actuators cost the adaptive loop: the LQR closed loop of
``examples/tutorial_05_control.py`` (the (3,1) shell kicked at 0.5 m/s, the law every 2 ms,
actuators with a 10 ms lag) run with and without a rate limit, side by side in one run.

Usage::

    python benchmarks/bench_actuator_steps.py [--t-end 2] [--max-rate 0.05]

Prints for each: DOP853's steps and evaluations, the wall time (best of three, after a run that
loads the compiled code), the control work ``W_u`` at the end and, with the rate limit, its
difference from a run at ``rtol`` 1e-12 (the energy integrals' accuracy at the default 1e-9).
A finding of session 12: with the limit, about 5 times the steps and 9 times the evaluations;
since the loop ends a step where a ramp meets the lag, about 2 times each
(``benchmarks/history.md``).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from tensegrity import State, class1_shell, internal_damping, simulate
from tensegrity.analysis.control_design import lqr, reachable
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.linearize import linearize
from tensegrity.model.actuators import actuators
from tensegrity.physics.dynamics import coordinates_from_nodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-end", type=float, default=2.0, help="simulated time [s]")
    parser.add_argument("--max-rate", type=float, default=0.05, help="rate limit [m/s]")
    args = parser.parse_args()
    shell = class1_shell(3, 1)
    eq = find_equilibrium(shell)
    design = lqr(reachable(linearize(internal_damping(shell), eq)), period=0.002)
    kick = np.zeros_like(eq.node_position)
    kick[11] = [0.5, 0.0, 0.0]
    start = State(0.0, eq.q, coordinates_from_nodes(shell, kick))

    def run(rate: float, **options):
        motors = actuators(shell, design.feedback.tendons, time_constant=0.01, max_rate=rate)
        return simulate(
            shell,
            (0.0, args.t_end),
            initial=start,
            controller=design.feedback,
            actuators=motors,
            sample_dt=0.005,
            **options,
        )

    reference = run(args.max_rate, rtol=1e-12).energy["control_work"][-1]
    print(f"{'max_rate [m/s]':>15} {'steps':>8} {'evaluations':>12} {'seconds':>8} {'W_u [J]':>14}")
    for rate in (math.inf, args.max_rate):
        run(rate)  # (loads the compiled code)
        times = []
        for _ in range(3):
            started = time.perf_counter()
            result = run(rate)
            times.append(time.perf_counter() - started)
        work = result.energy["control_work"][-1]
        print(f"{rate:>15g} {result.nsteps:>8} {result.nfev:>12} {min(times):>8.2f} {work:>14.9f}")
    print(f"W_u at rtol 1e-12 with the limit: {reference:.9f} J")


if __name__ == "__main__":
    main()
