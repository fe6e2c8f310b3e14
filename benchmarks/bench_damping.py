#!/usr/bin/env python
"""What internal damping costs: the compiled RK4 step of a shell undamped, with the paper's
artificial damping (to ground) and with internal damping (relative to the rigid-body motion,
the default of ``tensegrity simulate``), side by side in one run.

Usage::

    python benchmarks/bench_damping.py [--sizes 3x1,10x10,100x100]

Internal damping adds one pass over the rods per evaluation (the rigid-body fit,
``physics.kernel._rigid_motion``) and the relative rates in the rod pass.  The structure:
``class1_shell(n, m)`` (rods 1 kg, 1 m; tendons 100 N/m), started on its cylinder with random
rod-consistent velocities of about 0.3 m/s, no gravity.  Times are the best of five repeats of
the engine's compiled RK4 stretch (``CompiledKernel.rk4`` of ``tests/kernel_harness.py``) over a
fixed number of steps (wall clock; the machine may be shared), after one call that compiles or
loads the code.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

# The compiled kernel is timed through the tests' harness (tests/kernel_harness.py), which calls
# the engine's compiled functions on its records; the library has no public kernel object.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from kernel_harness import CompiledKernel
from tensegrity import artificial_damping, class1_shell, internal_damping, undamped
from tensegrity.physics import dynamics

#: The damping kinds compared, the first the reference of the ratios.
KINDS = {"undamped": undamped, "artificial": artificial_damping, "internal": internal_damping}
#: RK4 step [s] (stable for 100 N/m on 1 kg rods).
DT = 1e-4


def step_seconds(structure, steps: int) -> float:
    """Best of five: seconds per RK4 step of ``structure`` from a moving state."""
    rng = np.random.default_rng(0)
    q = dynamics.coordinates_from_nodes(structure, structure.node_position)
    v = 0.3 * rng.standard_normal(structure.node_position.shape)
    q, qdot = dynamics.project_to_constraints(
        structure, q, dynamics.coordinates_from_nodes(structure, v)
    )
    kernel = CompiledKernel(structure)
    rest = structure.tendon_rest_length
    kernel.rk4(q, qdot, DT, 1, rest)  # compile or load
    best = np.inf
    for _ in range(5):
        start = time.perf_counter()
        kernel.rk4(q, qdot, DT, steps, rest)
        best = min(best, time.perf_counter() - start)
    return best / steps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="3x1,10x10,100x100")
    args = parser.parse_args()
    print(
        f"| shell | rods | {' | '.join(f'{k} [us/step]' for k in KINDS)} | internal / artificial |"
    )
    print(f"|---|---|{'---|' * len(KINDS)}---|")
    for size in args.sizes.split(","):
        n, m = (int(x) for x in size.split("x"))
        shell = class1_shell(n, m)
        steps = max(20, 200_000 // shell.n_tendons)
        times = {name: step_seconds(damp(shell), steps) for name, damp in KINDS.items()}
        cells = " | ".join(f"{1e6 * t:.3g}" for t in times.values())
        ratio = times["internal"] / times["artificial"]
        print(f"| ({n},{m}) | {shell.n_rods} | {cells} | {ratio:.2f}x |")


if __name__ == "__main__":
    main()
