#!/usr/bin/env python
"""Ground contact: this engine against MuJoCo on the exported scene, side by side in one run.

Usage::

    python benchmarks/bench_contact.py [--quick] [--span 10] [--budget 300]

Cases (the six-bar robot of ``tests/test_contact.py``: rods 1 kg, 1 m; cables 2000 N/m, 100 N
of prestress, 20 N s/m; ground ``k = 1e5`` N/m, ``c = 100`` N s/m; ends of radius 0.01 m):

- ``drop``: dropped flat on its face ``f---`` from 0.5 m onto the ground (``mu = 0.8``).
- ``slope``: a rod (1 kg, 1 m, along the slope) resting on a 20 degree slope (gravity tilted) at
  ``mu = 0.5``, which must stick (``atan 0.5`` = 26.6 degrees): the creep, as MuJoCo's mean speed
  over the second half of the span [mm/s] and our largest node drift over the span [m].  (The
  six-bar on its face tips over on that slope: its tipping angle is about 22 degrees.)
- ``roll``: the rolling example (``examples/six_bar_roll.json`` and ``.csv``, planned by
  ``tensegrity.design.rolling.six_bar_roll``): three steps of cable shortenings in 8 s that tip
  the six-bar over six faces, at ``mu = 0.8`` for static and kinetic friction alike (MuJoCo has
  one coefficient; the example's ``mu_k = 0.6`` alone moves the centre of mass 17 mm in the
  first step, ``tests/test_mjcf_ground.py``).  MuJoCo's rest lengths follow the table
  (``model.tendon_lengthspring[:, 1] = Lbar - u(t)``, set before each step at its midpoint).

For each case and each simulator: the wall-clock time to simulate ``--span`` seconds
(``simulate`` at its defaults, rtol 1e-9; MuJoCo ``to_mjcf(..., ground=..., contact_radius=...)``
with RK4 at dt = 1e-4), their ratio, and the largest node deviation over the samples (every 0.01
s) from a reference run of this engine at rtol 1e-12, atol 1e-14.  ``--quick``: a span of 1 s.
Each run of this engine has a wall-clock budget (``--budget`` [s], ``max_wall_time``): a run
that stops short says where (the column ``ours reached``), and its deviations are over the
samples it made.  Each simulator runs once (a short warm-up run first loads numba's cache).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

RADIUS, G, DT, SAMPLE = 0.01, 9.81, 1e-4, 0.01


def six_bar(height: float):
    """The six-bar on its face ``f---`` with its lowest ends ``height`` [m] above the ground."""
    from tensegrity.design.catalogue import six_bar_robot

    robot = six_bar_robot(stiffness=2000.0, tension=100.0, damping=20.0)
    face = -np.ones(3) / np.sqrt(3)
    axis = np.cross(face, [0.0, 0.0, -1.0])
    skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    nodes = robot.node_position @ (np.eye(3) + skew + skew @ skew / (1.0 - face[2])).T
    nodes[:, 2] += RADIUS + height - nodes[:, 2].min()
    return robot.replace(node_position=nodes)


def resting_rod(theta: float):
    """A 1 kg, 1 m rod along ``x`` lying on ``z = 0``, pressed in by its weight's normal part."""
    from tensegrity.model.structure import Structure

    ends = np.zeros((2, 3))
    ends[:, 0] = [-0.5, 0.5]
    ends[:, 2] = RADIUS - G * math.cos(theta) / (2 * 1e5)
    return Structure(
        node_position=ends,
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        tendon_nodes=np.zeros((0, 2), int),
        tendon_stiffness=[],
        tendon_rest_length=[],
    )


def rolling():
    """The rolling example's robot on its face and its control table (``examples/``)."""
    from tensegrity.io.formats import read_structure
    from tensegrity.io.tables import read_control_table

    path = Path(__file__).resolve().parent.parent / "examples" / "six_bar_roll"
    robot = read_structure(path.with_suffix(".json"))
    return robot, read_control_table(path.with_suffix(".csv"), robot)


def cases():
    """name -> (structure, plane, gravity, control table or None)."""
    from tensegrity.model.ground import ground

    theta = math.radians(20.0)
    slope = [G * math.sin(theta), 0.0, -G * math.cos(theta)]
    robot, table = rolling()
    return {
        "drop": (six_bar(0.5), ground(friction=0.8), [0.0, 0.0, -G], None),
        "slope": (resting_rod(theta), ground(friction=0.5), slope, None),
        "roll": (robot, ground(friction=0.8), [0.0, 0.0, -G], table),
    }


def ours(structure, plane, gravity, control, span, **tolerances):
    from tensegrity import simulate

    start = time.perf_counter()
    run = simulate(
        structure,
        (0.0, span),
        control=control,
        gravity=gravity,
        ground=plane,
        contact_radius=RADIUS,
        sample_dt=SAMPLE,
        **tolerances,
    )
    return time.perf_counter() - start, run


def mujoco_run(structure, plane, gravity, control, times):
    import mujoco

    from tensegrity.io.mjcf import mujoco_node_positions, to_mjcf

    xml = to_mjcf(structure, ground=plane, contact_radius=RADIUS, gravity=gravity, timestep=DT)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    rest = model.tendon_lengthspring[:, 1].copy()  # springlength "0 Lbar" of each tendon
    nodes = []
    start = time.perf_counter()
    for t in times:
        while data.time < t - DT / 2:
            if control is not None:
                model.tendon_lengthspring[:, 1] = rest - control(data.time + DT / 2)
            mujoco.mj_step(model, data)
        nodes.append(mujoco_node_positions(model, data, structure.n_nodes))
    return time.perf_counter() - start, np.array(nodes)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="simulate 1 s instead of --span")
    parser.add_argument("--span", type=float, default=10.0, help="simulated time [s]")
    parser.add_argument(
        "--budget", type=float, default=300.0, help="wall-clock budget of each run of ours [s]"
    )
    args = parser.parse_args(argv)
    span = 1.0 if args.quick else args.span
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    structure, plane, gravity, _ = cases()["drop"]
    ours(structure, plane, gravity, None, 0.05)  # (warm-up: numba's cache loaded)
    print(f"\n{span:g} s simulated, node deviations from this engine at rtol 1e-12\n")
    print(
        "| case | ours reached | ours [s] | MuJoCo [s] | ours / MuJoCo | ours dev. [m] |"
        " MuJoCo dev. [m] | creep: ours drift [m] | creep: MuJoCo [mm/s] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, (structure, plane, gravity, control) in cases().items():
        budget = dict(max_wall_time=args.budget)
        scene = (structure, plane, gravity, control)
        _, reference = ours(*scene, span, rtol=1e-12, atol=1e-14, **budget)
        wall, run = ours(*scene, span, **budget)
        mj_wall, mj_nodes = mujoco_run(*scene, reference.t)
        rows = min(len(run.t), len(reference.t))
        ours_dev = np.abs(run.node_position[:rows] - reference.node_position[:rows]).max()
        mj_dev = np.abs(mj_nodes - reference.node_position).max()
        reached = f"{run.t[-1]:g} s, ref. {reference.t[-1]:g} s"
        creep = ours_creep = "-"
        if name == "slope":
            ours_creep = f"{np.abs(run.node_position - run.node_position[0]).max():.1e}"
            half = len(reference.t) // 2
            moved = np.linalg.norm(mj_nodes[-1] - mj_nodes[half], axis=1).max()
            creep = f"{1e3 * moved / (reference.t[-1] - reference.t[half]):.3f}"
        print(
            f"| {name} | {reached} | {wall:.2f} | {mj_wall:.2f} | {wall / mj_wall:.2f} |"
            f" {ours_dev:.1e} | {mj_dev:.1e} | {ours_creep} | {creep} |"
        )
    print(f"\nload average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
