#!/usr/bin/env python
"""What the first run costs, and what the viewer's frames cost, in one process each.

Usage::

    python benchmarks/bench_first_run.py [--viewer]

Default: runs ``tensegrity simulate`` (the CLI's ``main``, the default example) in a child
process whose numba cache is a new empty folder, and prints the wall time of the call and the
CPU time numba spent compiling each entry point (numba's ``numba:compile`` events, outermost
only: the time of a function includes the callees it compiled).  The numbers behind
`benchmarks/README.md`'s "The first run" and docs/performance.md.

``--viewer``: writes a (10,10) 60 s run with ``simulate_to_file`` (warm cache), then times, in
this process, the three ways of making its viewer frames: keeping them as the samples pass
(``plots.motion.FrameKeeper``, fed the run's blocks again from the file), reading the datasets
they show (``read_frames``), and reading the whole trajectory (``read_trajectory`` every k-th
sample), each followed by writing the page.  Best of 3.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_CHILD = """
import sys, time
from numba.core import event
totals = {}
class Listener(event.Listener):
    def __init__(self):
        self.stack = []
    def on_start(self, ev):
        self.stack.append((ev.data["dispatcher"].py_func.__qualname__, time.process_time()))
    def on_end(self, ev):
        name, t0 = self.stack.pop()
        if not self.stack:
            totals[name] = totals.get(name, 0.0) + time.process_time() - t0
event.register("numba:compile", Listener())
from tensegrity.cli.main import main
wall = time.perf_counter()
main(["simulate", "--out", sys.argv[1]])
print(f"wall of main(): {time.perf_counter() - wall:.1f} s", file=sys.stderr)
for name, cpu in sorted(totals.items(), key=lambda kv: -kv[1]):
    print(f"  compile {name:30s} {cpu:6.2f} s CPU", file=sys.stderr)
"""


def first_run() -> None:
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        subprocess.run(
            [sys.executable, "-c", _CHILD, out], env=env, check=True, stdout=subprocess.DEVNULL
        )


def viewer() -> None:
    import numpy as np

    from tensegrity.engine.result import ENERGY_NAMES, Samples
    from tensegrity.io.stream import simulate_to_file
    from tensegrity.io.trajectory import read_trajectory
    from tensegrity.model.shell import class1_shell
    from tensegrity.physics.dynamics import artificial_damping
    from tensegrity.plots.motion import (
        MAX_BYTES,
        MAX_FRAMES,
        FrameKeeper,
        frame_budget,
        make_frames,
        read_frames,
    )
    from tensegrity.plots.viewer import view

    def best(fn) -> float:
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        return min(times)

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.h5"
        shell = artificial_damping(class1_shell(10, 10))
        summary = simulate_to_file(shell, (0.0, 60.0), path, sample_dt=0.01, steady_state=True)
        run = read_trajectory(path)
        budget = frame_budget(shell, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES)
        K = summary.samples_per_segment
        energy = np.stack([run.energy[name] for name in ENERGY_NAMES], axis=1)
        blocks = [
            Samples(
                run.t[a : a + K],
                run.q[a : a + K],
                run.qdot[a : a + K],
                run.node_position[a : a + K],
                run.node_velocity[a : a + K],
                run.tendon_length[a : a + K],
                run.tendon_tension[a : a + K],
                energy[a : a + K],
                run.residual_acceleration[a : a + K],
                run.residual_acceleration[a : a + K],
            )
            for a in range(0, run.t.size, K)
        ]
        page = Path(folder) / "view.html"

        def kept() -> None:
            keeper = FrameKeeper(shell, t0=0.0, sample_dt=0.01, max_frames=budget)
            for block in blocks:
                keeper.add(block)
            view(keeper.frames(), page)

        def read_shown() -> None:
            view(read_frames(path, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES)[0], page)

        def read_all() -> None:
            every = max(1, -(-(run.t.size - 1) // (budget - 1)))
            view(make_frames(read_trajectory(path, every=every)), page)

        print(f"(10,10), {run.t.size} samples, {path.stat().st_size / 1e6:.0f} MB file:")
        for label, fn in (
            ("frames kept as samples pass, page", kept),
            ("datasets shown read back, page", read_shown),
            ("whole trajectory read back, page", read_all),
        ):
            print(f"  {label:36s} {best(fn):.3f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--viewer", action="store_true", help="the viewer frames' cost instead")
    args = parser.parse_args()
    if args.viewer:
        viewer()
    else:
        first_run()


if __name__ == "__main__":
    main()
