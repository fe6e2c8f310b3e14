#!/usr/bin/env python
"""Sweeps: cases grouped into tasks in different ways on Dask, for the same cases (every way runs
the engine; before it, ``simulate`` ran NumPy and the batched path a compiled loop of its own).

Usage::

    python benchmarks/bench_sweep.py [--sizes 3x1,10x10,30x30] [--cases 16] [--workers 2]
                                     [--output benchmarks/results-sweep.md]

For each shell size, ``--cases`` cases (a grid over stiffness and rest-length scale, RK4 at
dt = 1e-4 over 0.05 s, samples every 5 ms: 500 steps, 11 samples per case) run four ways:

- ``dask: simulate per case``: one Dask task per case on a LocalCluster of ``--workers``
  single-threaded processes, each running ``simulate(method="rk4")``;
  ``run_sweep(spec with batch=False)``.
- ``dask: compiled per case``: one task per case, each a batch of one (``simulate_batch``);
- ``dask: batched``: the cases in one batch per worker;
- ``run_sweep``: what the sweep does for RK4 (its rule, ``sweep.plan``: one batch per worker below
  ``sweep.BATCH_MAX_RODS`` rods, else one compiled case per task), dataset included;
- ``one process: batched``: all cases in one batch in this process (one core), no Dask.

Dask times are wall clock from submitting to gathering, with the cluster already started and
warmed up (numba's disk cache loaded in every worker).  The machine may be shared: the load average
is printed.  One run per method (these take seconds to minutes).
"""

from __future__ import annotations

import argparse
import datetime
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_rhs import machine_info, parse_size, write_report  # noqa: E402 - after the sys.path insert


def make_spec(n: int, m: int, cases: int, *, batch: bool = True):
    from tensegrity.sweep.run import SweepSpec

    k = max(1, cases // 2)
    stiffness = [60.0 + 140.0 * i / max(1, k - 1) for i in range(k)]
    scales = [0.85, 0.95][: max(1, cases // k)]
    return SweepSpec(
        {"n": [n], "m": [m], "stiffness": stiffness, "rest_scale": scales},
        t_end=0.05,
        sample_dt=5e-3,
        dt=1e-4,
        batch=batch,
    )


def time_dask_tasks(client, spec, parts: int) -> float:
    """Wall time of the compiled path with the cases in ``parts`` tasks."""
    import numpy as np
    from distributed import wait

    from tensegrity.sweep.run import run_cases

    cases = spec.cases()
    t0 = time.perf_counter()
    futures = [
        client.submit(run_cases, [cases[i] for i in chunk], spec, True, pure=False)
        for chunk in np.array_split(np.arange(len(cases)), parts)
    ]
    wait(futures)
    elapsed = time.perf_counter() - t0
    assert all(r["status"] == 0 for rows in client.gather(futures) for r in rows)
    return elapsed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="3x1,10x10,30x30")
    parser.add_argument("--cases", type=int, default=16)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--output", default=str(HERE / "results-sweep.md"))
    args = parser.parse_args(argv)

    from distributed import Client, LocalCluster

    from tensegrity.sweep.run import run_cases, run_sweep

    info = machine_info()
    date = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    print(f"load average before: {info.get('load_before', '?')}", flush=True)
    rows = []
    with (
        LocalCluster(
            n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=":0"
        ) as cluster,
        Client(cluster) as client,
    ):
        warm = make_spec(3, 1, 2)
        client.run(lambda: run_cases(warm.cases()[:1], warm, True))  # numba cache in every worker
        run_cases(warm.cases()[:1], warm, True)
        for text in args.sizes.split(","):
            n, m = parse_size(text)
            spec = make_spec(n, m, args.cases)
            cases = len(spec.cases())
            times = {}
            t0 = time.perf_counter()
            result = run_sweep(make_spec(n, m, args.cases, batch=False), client=client)
            times["dask_simulate"] = time.perf_counter() - t0
            assert result.success
            times["dask_compiled"] = time_dask_tasks(client, spec, cases)
            times["dask_batched"] = time_dask_tasks(client, spec, args.workers)
            t0 = time.perf_counter()
            result = run_sweep(spec, client=client)
            times["run_sweep"] = time.perf_counter() - t0
            assert result.success
            t0 = time.perf_counter()
            rows_local = run_cases(spec.cases(), spec, True)
            times["local_batched"] = time.perf_counter() - t0
            assert all(r["status"] == 0 for r in rows_local)
            rows.append(((n, m), cases, times))
            print(
                f"({n},{m}) {cases} cases: "
                + ", ".join(f"{k} {v:.2f} s" for k, v in times.items()),
                flush=True,
            )
    load_after = " ".join(f"{x:.2f}" for x in os.getloadavg())

    steps = 500
    lines = [
        "# Sweep benchmark: batched compiled path vs process parallelism on Dask",
        "",
        f"- Command: `python benchmarks/bench_sweep.py --sizes {args.sizes} --cases {args.cases} "
        f"--workers {args.workers}`",
        f"- Date: {date}; machine: {info['cpu']}, {info['cpus']} CPUs; load average before "
        f"{info.get('load_before', '?')}, after {load_after} (shared machine)",
        "- Each case: RK4, dt = 1e-4 s, 0.05 s (500 steps), 11 samples; a grid over stiffness "
        "and rest-length scale.  Dask: LocalCluster of "
        f"{args.workers} single-threaded worker processes, started and warmed up before timing.",
        "",
        "| shell | cases | Dask, `simulate` per case | Dask, compiled per case | Dask, batched "
        "(one batch per worker) | one process, batched | `run_sweep` (its rule) "
        "| `run_sweep` / simulate (Dask) | compiled per case / batched (Dask) "
        "| case-steps/s, `run_sweep` |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for (n, m), cases, t in rows:
        lines.append(
            f"| ({n},{m}) | {cases} | {t['dask_simulate']:.2f} s | {t['dask_compiled']:.2f} s | "
            f"{t['dask_batched']:.2f} s | {t['local_batched']:.2f} s | {t['run_sweep']:.2f} s | "
            f"{t['dask_simulate'] / t['run_sweep']:.1f}× | "  # noqa: RUF001 - the report's multiplication sign, U+00D7
            f"{t['dask_compiled'] / t['dask_batched']:.2f}× | "  # noqa: RUF001 - the report's multiplication sign, U+00D7
            f"{cases * steps / t['run_sweep']:,.0f} |"
        )
    write_report("\n".join(lines) + "\n", args.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
