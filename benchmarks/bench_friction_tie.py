#!/usr/bin/env python
"""The cost of a tie of the friction coefficients (``mu_s = mu_k``) on the rolling example.

Usage::

    python benchmarks/bench_friction_tie.py [--span 2]

The rolling example (``examples/six_bar_roll.json`` and ``.csv``, the scene of the file with
its friction replaced) run by ``simulate`` at its defaults (DOP853, rtol 1e-9) over ``--span``
seconds, for several ``(mu_s, mu_k)``: the wall-clock time, the accepted steps and the located
events.  At a tie a slip starts from rest with almost nothing to drive it and stays slow, and
a slow slip is stiff (its friction's direction turns at ``mu_k F_n |W| / |v_t|``): the steps
grow about tenfold (``benchmarks/results-contact.md``, ``docs/simulation.md``).  One short
warm-up run first loads numba's cache.
"""

from __future__ import annotations

import argparse
import dataclasses
import time

from bench_contact import rolling

#: (mu_s, mu_k) pairs: each tie beside a kinetic coefficient a little and well below it.
PAIRS = ((0.8, 0.6), (0.8, 0.7), (0.8, 0.79), (0.8, 0.8), (0.6, 0.59), (0.6, 0.6))


def main() -> None:
    from pathlib import Path

    from tensegrity import simulate
    from tensegrity.io.formats import read_scene
    from tensegrity.model.ground import planes_of

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--span", type=float, default=2.0, help="simulated time [s]")
    args = parser.parse_args()
    robot, table = rolling()
    path = Path(__file__).resolve().parent.parent / "examples" / "six_bar_roll.json"
    scene = read_scene(path).simulate_options()
    (plane,) = planes_of(scene.pop("ground"))
    simulate(robot, (0.0, 0.01), control=table, ground=plane, **scene)  # (warm-up)
    print(f"{args.span:g} s of the rolling example, simulate() at its defaults\n")
    print("| mu_s | mu_k | time [s] | steps | events |")
    print("|---:|---:|---:|---:|---:|")
    for mu_s, mu_k in PAIRS:
        ground = dataclasses.replace(plane, friction=mu_s, kinetic_friction=mu_k)
        t0 = time.perf_counter()
        run = simulate(
            robot, (0.0, args.span), control=table, ground=ground, sample_dt=0.01, **scene
        )
        seconds = time.perf_counter() - t0
        print(f"| {mu_s} | {mu_k} | {seconds:.2f} | {run.nsteps:,} | {run.nswitches} |")


if __name__ == "__main__":
    main()
