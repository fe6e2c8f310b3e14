"""The compiled kernel against its memory-traffic bound, in interleaved rounds (one process).

On a shared machine the copy bandwidth and the kernel's time both drift by up to 2x within
minutes, so a ratio of two numbers taken minutes apart (as in ``bench_rhs.py``'s report) carries
that drift.  Here every round measures, back to back, the DRAM copy bandwidth (``np.copyto`` of
512 MiB, read + write counted) and one evaluation of the engine (``system_rhs`` on records made
once, ``bench_rhs.evaluation``) on the benchmark shell: with undamped tendons (the benchmark's
structure; the kernel's undamped specialization) and with every tendon damped (the generic
path); each against the bytes its path must touch (``bench_rhs.kernel_bytes``).  Every path is
also timed inside the engine's compiled RK4 stretch (``CompiledKernel.rk4`` of
``tests/kernel_harness.py``, 10 steps per call, divided by their 40 evaluations; the stage sums
and projections are counted with them, so this is an upper bound on an evaluation inside the
loop).  Prints one line per round and the median and range of each ratio.

    python benchmarks/bench_bound.py --size 100x100 --rounds 10
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_rhs import bench_problem, best_time, copy_bandwidth, evaluation, kernel_bytes, parse_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="100x100", help="shell n x m (default 100x100)")
    parser.add_argument("--rounds", type=int, default=6)
    args = parser.parse_args()
    from kernel_harness import CompiledKernel  # (tests/: on the path once bench_rhs is imported)

    structure, q, qdot, rest = bench_problem(*parse_size(args.size))
    R, S = structure.n_rods, structure.n_tendons
    assert not np.any(structure.tendon_damping), "the benchmark shell has undamped tendons"
    kernels = {"undamped": (CompiledKernel(structure), kernel_bytes(R, S, tendon_damping=False))}
    # Damped: c tiny but nonzero, so that the generic path runs on nearly the same forces.
    damped = structure.replace(tendon_damping=np.full(S, 1e-9))
    kernels["damped"] = (CompiledKernel(damped), kernel_bytes(R, S, tendon_damping=True))
    evaluations = {name: evaluation(kernel, q, qdot, rest) for name, (kernel, _) in kernels.items()}
    for name, (kernel, _) in kernels.items():
        evaluations[name]()  # compile or load the cache outside the rounds
        kernel.rk4(q, qdot, 1e-4, 1, rest)
    ratios: dict[str, list[float]] = {
        f"{name}{suffix}": [] for name in kernels for suffix in ("", ", in RK4")
    }
    dram = 2**29
    for k in range(args.rounds):
        bandwidth = copy_bandwidth(dram, budget=0.5)
        parts = [f"round {k}: DRAM copy {bandwidth / 1e9:.1f} GB/s"]
        for name, (kernel, nbytes) in kernels.items():
            bound = nbytes / bandwidth
            t = best_time(evaluations[name], 0.4, repeats=5)
            step = (
                best_time(lambda kernel=kernel: kernel.rk4(q, qdot, 1e-4, 10, rest), 0.4, repeats=3)
                / 40
            )
            ratios[name].append(t / bound)
            ratios[f"{name}, in RK4"].append(step / bound)
            parts.append(
                f"{name} {t * 1e3:.3f} ms = {t / bound:.2f}x, in RK4 {step * 1e3:.3f} ms"
                f" = {step / bound:.2f}x ({bound * 1e6:.0f} us)"
            )
        print("; ".join(parts), flush=True)
    for name, values in ratios.items():
        print(
            f"{name}: kernel / bound median {np.median(values):.2f}x "
            f"(range {min(values):.2f}-{max(values):.2f}x over {len(values)} rounds)"
        )


if __name__ == "__main__":
    main()
