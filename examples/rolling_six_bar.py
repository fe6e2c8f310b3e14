"""A six-bar robot rolls over its faces by changing its cables' rest lengths (issue 29).

:func:`tensegrity.design.rolling.six_bar_roll` stands the robot (``six_bar_robot(stiffness=2000,
tension=100, damping=20)``) on its cable triangle ``f---`` (nodes 0, 4, 8) and plans three
steps; the run tips it six times, over the open triangles between two bars' ends and on to the
next cable triangles, along a zig-zag about a straight line.  This script simulates the plan and
draws the centre of mass's path over the ground and the faces it stood on
(``rolling_six_bar.png`` in ``--out``, default the current folder); ``--tables`` also writes the
robot on its face with its scene (``six_bar_roll.json``) and the control table
(``six_bar_roll.csv``) there, as they are in ``examples/``.

The same run from the shell (the structure file carries the ground, friction 0.8/0.6, contact
radius 1 cm and gravity)::

    tensegrity simulate --structure examples/six_bar_roll.json \\
        --control-table examples/six_bar_roll.csv --t-end 8 --rtol 1e-12 --out roll

(``--kind six-bar`` stands the robot on the ends of two bars, not on a face, hence the file.)
``--rtol 1e-12`` keeps the energy balance within 1e-7 J across the table's corners; the
default 1e-9 gives the same faces with a balance within 1e-5 J.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from tensegrity import simulate
from tensegrity.design.catalogue import six_bar_robot
from tensegrity.design.rolling import six_bar_roll, support_faces
from tensegrity.io.formats import write_structure
from tensegrity.io.tables import write_control_table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."), help="output folder")
    parser.add_argument("--steps", type=int, default=3, help="steps planned (default 3)")
    parser.add_argument("--tables", action="store_true", help="also write the .json and .csv")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    robot = six_bar_robot(stiffness=2000.0, tension=100.0, damping=20.0)
    plan = six_bar_roll(robot, steps=args.steps)
    print("planned faces:", " -> ".join(map(str, plan.faces)))
    if args.tables:
        write_structure(args.out / "six_bar_roll.json", plan.structure, scene=plan.scene)
        write_control_table(args.out / "six_bar_roll.csv", plan.control, plan.structure)
    run = simulate(
        plan.structure,
        (0.0, plan.t_end),
        control=plan.control,
        rtol=1e-12,
        sample_dt=0.01,
        **plan.scene.simulate_options(),
    )
    faces = support_faces(run)
    print("faces in the run:", " -> ".join(f"{nodes} at {t:.2f} s" for t, nodes in faces))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mass = np.full(run.node_position.shape[1], 1.0)  # equal rods: the nodes' mean
    com = np.einsum("n,tnk->tk", mass, run.node_position) / mass.sum()
    fig, ax = plt.subplots(figsize=(8.5, 6))
    for k, (t, nodes) in enumerate(faces):  # (named in the legend, beside the plot: the path
        i = int(np.searchsorted(run.t, t))  # crosses the faces, labels on them would hide it)
        corners = run.node_position[i, list(nodes), :2]
        ax.fill(*corners.T, alpha=0.25, color=f"C{k % 10}", label=f"face {nodes} at {t:.1f} s")
    ax.plot(com[:, 0], com[:, 1], "k-", lw=1.5, label="centre of mass")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("six-bar rolling: centre of mass and support faces")
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, fontsize=8)
    figure = args.out / "rolling_six_bar.png"
    fig.savefig(figure, dpi=120, bbox_inches="tight")
    print("wrote", figure)


if __name__ == "__main__":
    main()
