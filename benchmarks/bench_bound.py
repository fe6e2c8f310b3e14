"""The compiled kernel against its memory-traffic bound, in interleaved rounds (one process).

On a shared machine the copy bandwidth and the kernel's time both drift by up to 2x within
minutes, so a ratio of two numbers taken minutes apart (as in ``bench_rhs.py``'s report) carries
that drift.  Here every round measures, back to back, the DRAM copy bandwidth (``np.copyto`` of
512 MiB, read + write counted; with ``--threads`` > 1 also T threads copying one slice each) and
one ``evaluate(out=...)`` of the kernel on the benchmark shell: with undamped tendons (the
benchmark's structure; the kernel's undamped specialization), with every tendon damped (the
generic path), and on ``--threads`` threads; each against the bytes its path must touch
(``bench_rhs.kernel_bytes``).  ``evaluate`` also puts the rest lengths into the kernel's tendon
order and the tensions back into the structure's (``kernel.stencil_layout``); the RK4 loop does
not, so every path is also timed inside the compiled RK4 loop (``FastKernel.rk4``, 10 steps per
call, divided by their 40 evaluations; the stage sums and projections are counted with them, so
this is an upper bound on an evaluation inside the loop).  Prints one line per round and the
median and range of each ratio.

    python benchmarks/bench_bound.py --size 100x100 --rounds 10 --threads 2
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_rhs import bench_problem, best_time, copy_bandwidth, kernel_bytes, parse_size


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="100x100", help="shell n x m (default 100x100)")
    parser.add_argument("--rounds", type=int, default=6)
    parser.add_argument("--threads", type=int, default=2, help="threaded kernel (1: skip it)")
    args = parser.parse_args()
    from tensegrity.physics.kernel import FastKernel

    structure, q, qdot, rest = bench_problem(*parse_size(args.size))
    R, S = structure.n_rods, structure.n_tendons
    assert not np.any(structure.tendon_damping), "the benchmark shell has undamped tendons"
    kernels = {"undamped": (FastKernel(structure), kernel_bytes(R, S, tendon_damping=False), 1)}
    # Damped: c tiny but nonzero, so that the generic path runs on nearly the same forces.
    damped = structure.replace(tendon_damping=np.full(S, 1e-9))
    kernels["damped"] = (FastKernel(damped), kernel_bytes(R, S, tendon_damping=True), 1)
    if args.threads > 1:
        kernels[f"undamped, {args.threads} threads"] = (
            FastKernel(structure, threads=args.threads),
            kernel_bytes(R, S, tendon_damping=False),
            args.threads,
        )
    out = (np.empty(6 * R), np.empty(S))
    for kernel, _, _ in kernels.values():
        kernel.evaluate(q, qdot, rest, out=out)  # compile or load the cache outside the rounds
        kernel.rk4(q, qdot, 1e-4, 1, rest)
    ratios: dict[str, list[float]] = {
        f"{name}{suffix}": [] for name in kernels for suffix in ("", ", in RK4")
    }
    dram = 2**29
    for k in range(args.rounds):
        bandwidth = {1: copy_bandwidth(dram, budget=0.5)}
        if args.threads > 1:
            bandwidth[args.threads] = max(
                bandwidth[1], copy_bandwidth(dram, budget=0.5, threads=args.threads)
            )
        parts = [f"round {k}: DRAM copy {bandwidth[1] / 1e9:.1f} GB/s"]
        for name, (kernel, nbytes, threads) in kernels.items():
            bound = nbytes / bandwidth[threads]
            t = best_time(
                lambda kernel=kernel: kernel.evaluate(q, qdot, rest, out=out), 0.4, repeats=5
            )
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
