#!/usr/bin/env python
"""Cost of joints and supports: one evaluation of Theorem 18.1 (``dynamics.evaluate``) and one
projection onto the constraints, for the class 1 shell and the class 2 shell of the same size
(free, and with the base ring fixed).

Usage::

    python benchmarks/bench_constraints.py [--sizes 3x2,8x4,20x10] [--repeats 5]

Timings are the best of ``--repeats`` runs of process time (the machine may be shared), per
call.  The class 2 shells use the dense constraint solve up to ``constraints.DENSE_ROWS``
constraint rows and the sparse one above (the column ``path``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from tensegrity.model.shell import class1_shell, class2_shell
from tensegrity.physics import dynamics
from tensegrity.physics.constraints import constraints_of


def best_time(call, repeats: int, budget: float = 0.5) -> float:
    """Best per-call process time [s] over ``repeats`` batches of about ``budget`` s each."""
    call()
    start = time.process_time()
    call()
    once = max(time.process_time() - start, 1e-6)
    count = max(1, int(budget / once))
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        for _ in range(count):
            call()
        best = min(best, (time.process_time() - start) / count)
    return best


def measure(structure, repeats: int) -> dict[str, float | str]:
    rng = np.random.default_rng(0)
    state = dynamics.initial_state(structure)
    q = state.q
    qdot = dynamics.project_to_constraints(structure, q, 0.1 * rng.normal(size=q.size))[1]
    rest = structure.tendon_rest_length
    perturbed = q + 1e-9 * rng.normal(size=q.size)
    constraints = constraints_of(structure)
    return {
        "rows": 0 if constraints is None else constraints.matrix.shape[0],
        "path": "-" if constraints is None else ("dense" if constraints.dense else "sparse"),
        "evaluate": best_time(
            lambda: dynamics.evaluate(structure, q, qdot, rest_length=rest), repeats
        ),
        "project": best_time(
            lambda: dynamics.project_to_constraints(structure, perturbed, qdot), repeats
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="3x2,8x4,20x10")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print("| shell | n x m | rods | constraint rows | path | evaluate [ms] | project [ms] |")
    print("|---|---|---|---|---|---|---|")
    for size in args.sizes.split(","):
        n, m = (int(x) for x in size.split("x"))
        for name, structure in (
            ("class 1", class1_shell(n, m)),
            ("class 2", class2_shell(n, m)),
            ("class 2, fixed base", class2_shell(n, m, fixed_base=True)),
        ):
            r = measure(structure, args.repeats)
            print(
                f"| {name} | {n} x {m} | {structure.n_rods} | {r['rows']} | {r['path']} | "
                f"{1e3 * r['evaluate']:.3f} | {1e3 * r['project']:.3f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
