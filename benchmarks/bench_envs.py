#!/usr/bin/env python
"""Learning environments: environment steps per second of this package's vector environment
against MuJoCo stepping the exported MJCF of the same robot, side by side in one run.

Usage::

    python benchmarks/bench_envs.py [--quick] [--copies 1 64 1024] [--robots three six]
                                    [--steps 20] [--threads 1 2]

For each robot (``three``: ``tensegrity/ThreeBarCrawl-v0``, ``six``: ``SixBarRoll-v0``), each
number of copies and each number of threads:

- **ours**: ``make_vector(env_id, copies)`` (one compiled call advances every copy over a 20 ms
  control period, DOP853 at rtol 1e-9 with its events located; the cables' rate limit and lag),
  random actions from a seeded generator, episodes cut at 50 steps so that resets are part of
  the work; numba's threads set to ``--threads``.  Timed: ``steps`` calls of ``step`` after one
  warm-up step (compilation excluded: the cache is filled first).
- **MuJoCo**: ``tensegrity.io.mjcf.to_mjcf`` of the same robot on the same ground (one
  friction coefficient, the static one), ``implicitfast`` at dt = 1 ms (the published
  tensegrity robots' step) and frame skip 20, each copy its own ``MjModel``/``MjData``; an
  action sets the actuated cables' rest lengths (``tendon_lengthspring``, the same scaling of
  the action, no rate limit or lag) and ``mj_step(nstep=20)`` advances it; copies stepped by
  ``--threads`` Python threads (MuJoCo releases the GIL while it steps); the same resets.

Reported: environment steps per second (copies x steps / wall time) and the ratio ours/MuJoCo.
The two do not solve the same problem to the same accuracy: MuJoCo's soft contacts at dt = 1 ms
creep (``../shared/spec/notes-for-cross-checks.md``: mm/s on a slope) where this engine sticks
exactly; the column says what each was asked for.  ``--quick``: the three-bar, 1 and 8 copies, 5
steps.  Results go to ``benchmarks/results-envs.md``.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

ENV_IDS = {"three": "tensegrity/ThreeBarCrawl-v0", "six": "tensegrity/SixBarRoll-v0"}
EPISODE, DT, FRAME_SKIP = 50, 1e-3, 20


def ours(env_id: str, copies: int, steps: int, threads: int) -> float:
    """Environment steps per second of the vector environment."""
    import numba

    from tensegrity.envs.vector import make_vector

    numba.set_num_threads(threads)
    vector = make_vector(env_id, copies)
    vector.max_episode_steps = EPISODE  # (resets are part of the work)
    rng = np.random.default_rng(0)
    vector.reset(seed=0)
    shape = vector.action_space.shape
    vector.step(rng.uniform(-1, 1, shape).astype(np.float32))  # (warm-up)
    start = time.perf_counter()
    for _ in range(steps):
        vector.step(rng.uniform(-1, 1, shape).astype(np.float32))
    return copies * steps / (time.perf_counter() - start)


def mujoco_copies(env_id: str, copies: int, steps: int, threads: int) -> float:
    """Environment steps per second of MuJoCo on the exported robot, copies stepped by
    ``threads`` Python threads."""
    import gymnasium
    import mujoco

    import tensegrity.envs  # noqa: F401 (registers the environments)
    from tensegrity.io.mjcf import to_mjcf

    env = gymnasium.make(env_id).unwrapped
    s, actuated = env.structure, env.actuators
    plane = env.live.system.inputs.ground
    xml = to_mjcf(
        s,
        timestep=DT,
        integrator="implicitfast",
        gravity=env.live.system.inputs.gravity,
        ground=plane,
        contact_radius=env.live.system.inputs.contact_radius,
    )
    models = [mujoco.MjModel.from_xml_string(xml) for _ in range(copies)]
    datas = [mujoco.MjData(m) for m in models]
    rest0 = s.tendon_rest_length[actuated.tendons]
    low, high = env.command_low, env.command_high
    rng = np.random.default_rng(0)

    def reset(b: int) -> None:
        mujoco.mj_resetDataKeyframe(models[b], datas[b], 0)
        mujoco.mj_forward(models[b], datas[b])

    def advance(b: int, action: np.ndarray) -> None:
        u = low + 0.5 * (np.clip(action, -1, 1) + 1.0) * (high - low)
        models[b].tendon_lengthspring[actuated.tendons, 1] = rest0 - u
        mujoco.mj_step(models[b], datas[b], nstep=FRAME_SKIP)

    for b in range(copies):
        reset(b)
    pool = concurrent.futures.ThreadPoolExecutor(threads) if threads > 1 else None
    shape = (copies, actuated.size)

    def one_step(k: int, actions: np.ndarray) -> None:
        work = [(b, actions[b]) for b in range(copies)]
        if pool is None:
            for b, a in work:
                advance(b, a)
        else:
            list(pool.map(lambda item: advance(*item), work))
        if (k + 1) % EPISODE == 0:
            for b in range(copies):
                reset(b)

    one_step(0, rng.uniform(-1, 1, shape))  # (warm-up)
    start = time.perf_counter()
    for k in range(steps):
        one_step(k + 1, rng.uniform(-1, 1, shape))
    elapsed = time.perf_counter() - start
    if pool is not None:
        pool.shutdown()
    return copies * steps / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--copies", type=int, nargs="+", default=[1, 64, 1024])
    parser.add_argument("--robots", nargs="+", choices=sorted(ENV_IDS), default=["three", "six"])
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--out", type=Path, default=Path(__file__).with_name("results-envs.md"))
    args = parser.parse_args()
    if args.quick:
        args.copies, args.robots, args.steps = [1, 8], ["three"], 5
    rows = []
    for robot in args.robots:
        for copies in args.copies:
            for threads in args.threads:
                a = ours(ENV_IDS[robot], copies, args.steps, threads)
                b = mujoco_copies(ENV_IDS[robot], copies, args.steps, threads)
                rows.append((robot, copies, threads, a, b))
                print(
                    f"{robot:5s} copies {copies:5d} threads {threads}: ours {a:9.1f} steps/s, "
                    f"MuJoCo {b:9.1f} steps/s, ratio {a / b:.3f}",
                    flush=True,
                )
    lines = [
        "# Learning environments: environment steps per second",
        "",
        f"`python benchmarks/bench_envs.py {' '.join(sys.argv[1:])}` on "
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
        f"{time.strftime('%Y-%m-%d')}; {args.steps} timed steps after one warm-up step; "
        f"episodes of {EPISODE} steps; control period 20 ms.",
        "",
        "| robot | copies | threads | ours [steps/s] | MuJoCo dt 1 ms [steps/s] | ours / MuJoCo |",
        "|---|---:|---:|---:|---:|---:|",
        *(f"| {r} | {c} | {t} | {a:.1f} | {b:.1f} | {a / b:.3f} |" for r, c, t, a, b in rows),
        "",
    ]
    args.out.write_text("\n".join(lines))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
