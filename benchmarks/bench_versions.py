"""Two versions of the compiled kernel against each other, in one process (paired ratios).

On a shared machine the same call drifts by up to 1.4x within minutes, so two benchmark runs
taken apart cannot show a 5% change.  Here the kernel of an earlier commit (its
``src/tensegrity/kernel.py``, taken with ``git show`` into a temporary module) and the working
tree's run in the same process on the same benchmark shell (``bench_rhs.bench_problem``), in
alternating rounds: one ``evaluate(out=...)`` and one compiled RK4 call (``FastKernel.rk4``,
10 steps from (100,100) up, else 100; time per step).  Prints, for each, the median time of
each version and the median and range of the per-round ratios new / old.

    python benchmarks/bench_versions.py --rev a1e6c12 --size 100x100 --rounds 8
    python benchmarks/bench_versions.py --rev a1e6c12 --size 100x100 --damped --threads 2
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from bench_rhs import bench_problem, best_time, parse_size

REPO = Path(__file__).resolve().parents[1]


#: Where the modules an older kernel imports live since the package was laid out in layers
#: (2026-11-25): its imports are pointed there, so that kernels from before and after compare.
MOVED = {
    "tensegrity.structure": "tensegrity.model.structure",
    "tensegrity.kernel": "tensegrity.physics.kernel",
}
#: The kernel's file, now and before the layers.
KERNEL_PATHS = ("src/tensegrity/physics/kernel.py", "src/tensegrity/kernel.py")


def kernel_at(rev: str):
    """The compiled kernel module as it was at commit ``rev``."""
    for kernel_path in KERNEL_PATHS:
        source = subprocess.run(
            ["git", "show", f"{rev}:{kernel_path}"], cwd=REPO, capture_output=True, text=True
        )
        if source.returncode == 0:
            break
    else:
        sys.exit(f"--rev: {source.stderr.strip()}")
    text = source.stdout
    for old, new in MOVED.items():
        text = re.sub(rf"\bfrom {re.escape(old)} import", f"from {new} import", text)
    path = Path(tempfile.mkdtemp()) / "kernel_at_rev.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("kernel_at_rev", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rev", required=True, help="git commit of the old kernel")
    parser.add_argument("--size", default="100x100", help="shell n x m (default 100x100)")
    parser.add_argument("--damped", action="store_true", help="every tendon damped (c = 1e-9)")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--rounds", type=int, default=8)
    args = parser.parse_args()
    from tensegrity.physics import kernel as new

    structure, q, qdot, rest = bench_problem(*parse_size(args.size))
    if args.damped:
        structure = structure.replace(tendon_damping=np.full(structure.n_tendons, 1e-9))
    kernels = {
        "old": kernel_at(args.rev).FastKernel(structure, threads=args.threads),
        "new": new.FastKernel(structure, threads=args.threads),
    }
    out = (np.empty(q.size), np.empty(structure.n_tendons))
    steps = 10 if structure.n_rods >= 20_000 else 100
    for kernel in kernels.values():  # compile or load the cache outside the rounds
        kernel.warm_up()
        kernel.evaluate(q, qdot, rest, out=out)
        kernel.rk4(q, qdot, 1e-4, 2, rest)
    times = {(name, what): [] for name in kernels for what in ("evaluate", "RK4 step")}
    for _ in range(args.rounds):
        for name, kernel in kernels.items():
            times[name, "evaluate"].append(
                best_time(lambda kernel=kernel: kernel.evaluate(q, qdot, rest, out=out), 0.3)
            )
            times[name, "RK4 step"].append(
                best_time(lambda kernel=kernel: kernel.rk4(q, qdot, 1e-4, steps, rest), 0.3) / steps
            )
    case = f"{args.size}, {'damped' if args.damped else 'undamped'}, {args.threads} thread(s)"
    for what in ("evaluate", "RK4 step"):
        old, new_ = np.array(times["old", what]), np.array(times["new", what])
        ratio = new_ / old
        print(
            f"{case}, {what}: old {np.median(old) * 1e3:.4f} ms, new {np.median(new_) * 1e3:.4f}"
            f" ms; new / old median {np.median(ratio):.3f} (range {ratio.min():.3f}-"
            f"{ratio.max():.3f}, {args.rounds} rounds)"
        )


if __name__ == "__main__":
    main()
