"""The engine's adaptive loop (DOP853, the default) on runs that take many steps per sample,
where the loop's own cost shows: wall time of ``simulate`` and its counts, best of a few runs.

Runs the package it imports, so two versions compare by pointing ``PYTHONPATH`` at another
checkout (the counts then show whether the runs are the same)::

    python benchmarks/bench_loop.py
    git worktree add /tmp/old aa9cb18 && PYTHONPATH=/tmp/old/src python benchmarks/bench_loop.py

The first ``simulate`` of each structure is run once untimed (numba's cache loads).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import tensegrity
from tensegrity import class1_shell, simulate
from tensegrity.physics import dynamics


def _perturbed(structure, seed: int, jitter: float, speed: float) -> dynamics.State:
    """The layout moved by ``jitter`` [m] and set moving at about ``speed`` [m/s], projected."""
    rng = np.random.default_rng(seed)
    start = dynamics.initial_state(structure)
    q, qdot = dynamics.project_to_constraints(
        structure,
        start.q + jitter * rng.standard_normal(start.q.size),
        speed * rng.standard_normal(start.q.size),
    )
    return dynamics.State(0.0, q, qdot)


def cases() -> dict[str, tuple]:
    """name: (structure, t_span, simulate's keyword arguments)."""
    s31, s42 = class1_shell(3, 1), class1_shell(4, 2)
    return {
        "undamped (3,1), 30 s, samples every 0.03 s": (s31, (0.0, 30.0), {}),
        "undamped perturbed (4,2), 0.5 s, samples every 0.01 s": (
            s42,
            (0.0, 0.5),
            dict(initial=_perturbed(s42, 2, 0.03, 1.0), sample_dt=0.01),
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per case (best kept)")
    args = parser.parse_args()
    print(f"tensegrity from {tensegrity.__file__}")
    for name, (structure, span, kwargs) in cases().items():
        simulate(structure, (0.0, 1e-3))  # (the compiled code loaded)
        best = np.inf
        for _ in range(args.repeat):
            wall = time.perf_counter()
            result = simulate(structure, span, **kwargs)
            best = min(best, time.perf_counter() - wall)
        print(
            f"{name}: {best:.3f} s; {result.nsteps} steps, {result.nswitches} switches, "
            f"{result.nprojections} projections, {result.nfev} evaluations"
        )


if __name__ == "__main__":
    main()
