#!/usr/bin/env python
"""How ``find_equilibrium`` scales with the shell's size (a finding of session 12: its solver is
dense, so large shells are out of its reach), and where its time goes.

Usage::

    python benchmarks/bench_equilibrium.py [--sizes 3x1,6x3,10x10] [--profile]

For each ``class1_shell(n, m)`` from its cylinder: the wall time of one ``find_equilibrium``
(after one (3,1) solve that loads the compiled code), its message and the number of unknowns
(``5 R``).  ``--profile`` prints the largest shell's ``cProfile`` top entries (the descent's
dense ``eigh``, the Levenberg-Marquardt solve, the dense force Jacobian).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time

from tensegrity import class1_shell
from tensegrity.analysis.equilibrium import find_equilibrium


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="3x1,6x3,10x10", help="shells as NxM, comma-separated")
    parser.add_argument("--profile", action="store_true", help="profile the largest shell")
    args = parser.parse_args()
    sizes = [tuple(int(k) for k in size.split("x")) for size in args.sizes.split(",")]
    find_equilibrium(class1_shell(3, 1))  # (loads the compiled code)
    print(f"{'shell':>9} {'unknowns':>9} {'seconds':>9}  message")
    for n, m in sizes:
        shell = class1_shell(n, m)
        started = time.perf_counter()
        eq = find_equilibrium(shell)
        took = time.perf_counter() - started
        print(f"{f'({n},{m})':>9} {5 * shell.n_rods:>9} {took:>9.2f}  {eq.message}")
    if args.profile:
        n, m = sizes[-1]
        profile = cProfile.Profile()
        profile.runcall(find_equilibrium, class1_shell(n, m))
        pstats.Stats(profile).sort_stats("tottime").print_stats(8)


if __name__ == "__main__":
    main()
