"""How tightly MuJoCo holds the MJCF export's closed loops, against the constraint settings.

A rod with both ends on non-parallel planes or lines has no exact joint tree; ``to_mjcf`` closes
the loop with tendon equalities (``tensegrity.io.mjcf``, "Rods with both ends held").  For the
closed-loop structures of ``tests/test_mjcf_held.py`` (a ladder against a wall, a plane and a
skew line, two skew lines, a planar trammel), under gravity, this runs our RK4 once per time
step and MuJoCo's RK4 with the exported model, the closure rows' ``solref`` / ``solimp`` /
solver options edited, and prints the largest node-position difference [m] over the horizon and
the largest distance of a held node from its plane or line in MuJoCo.

    python benchmarks/mjcf_closure.py --t-end 0.5
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from tensegrity import simulate
from tensegrity.io.mjcf import mujoco_node_positions, to_mjcf
from test_constraints import GRAVITY
from test_mjcf_held import LOOPS, off_constraints

#: (label, closure solref, closure solimp, extra <option> attributes); None keeps the export's.
SETTINGS = [
    ("exported: solref '2dt 1', solimp 0.9999", None, None, ""),
    ("solref '1dt 1'", "{dt} 1", None, ""),
    ("solref '4dt 1'", "{dt4} 1", None, ""),
    ("solref '2dt 0.7'", "{dt2} 0.7", None, ""),
    ("solref '-1e8 -2e4' (direct k, b)", "-1e8 -2e4", None, ""),
    ("solref '-1e9 -6.3e4' (direct k, b)", "-1e9 -6.3e4", None, ""),
    ("solimp 0.99", None, "0.99 0.99 0.001", ""),
    ("tolerance 0, 1000 iterations", None, None, 'tolerance="0" iterations="1000"'),
]


def edited(xml: str, solref: str | None, solimp: str | None, option: str, dt: float) -> str:
    """``xml`` with the closure equalities' ``solref`` / ``solimp`` and ``<option>`` edited."""

    def edit(match: re.Match) -> str:
        text = match.group(0)
        if solref:
            value = solref.format(dt=dt, dt2=2 * dt, dt4=4 * dt)
            text = re.sub(r'solref="[^"]*"', f'solref="{value}"', text)
        if solimp:
            text = re.sub(r'solimp="[^"]*"', f'solimp="{solimp}"', text)
        return text

    xml = re.sub(r'<tendon name="hold\d+"[^>]*/>', edit, xml)
    return xml.replace("<option ", f"<option {option} ") if option else xml


def mujoco_positions(xml: str, structure, t_end: float, dt: float, sample_dt: float) -> np.ndarray:
    """Node positions (T, N, d) every ``sample_dt``; NaN after MuJoCo reports an instability."""
    import mujoco

    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    per_sample = round(sample_dt / dt)
    out = [mujoco_node_positions(model, data, structure.n_nodes, dim=structure.dim)]
    for _ in range(round(t_end / sample_dt)):
        for _ in range(per_sample):
            mujoco.mj_step(model, data)
        if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number:
            out.append(np.full_like(out[0], np.nan))
            continue
        out.append(mujoco_node_positions(model, data, structure.n_nodes, dim=structure.dim))
    return np.array(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--t-end", type=float, default=0.5, help="horizon [s] (default 0.5)")
    parser.add_argument(
        "--dt",
        type=float,
        nargs="+",
        default=[1e-4, 5e-5],
        help="time steps [s]: all settings at the first, the export's at the others",
    )
    args = parser.parse_args()
    sample_dt = 0.01
    print("| structure | dt [s] | setting | node difference [m] | off its plane/line [m] |")
    print("|---|---|---|---|---|")
    for name, build in LOOPS.items():
        s = build()
        g = GRAVITY if s.dim == 3 else GRAVITY[[0, 2]]
        for k, dt in enumerate(args.dt):
            ours = simulate(
                s, (0.0, args.t_end), method="rk4", dt=dt, sample_dt=sample_dt, gravity=g
            )
            assert ours.success, ours.message
            xml = to_mjcf(s, timestep=dt, gravity=g)
            for label, solref, solimp, option in SETTINGS if k == 0 else SETTINGS[:1]:
                theirs = mujoco_positions(
                    edited(xml, solref, solimp, option, dt), s, args.t_end, dt, sample_dt
                )
                if np.isnan(theirs).any():
                    print(f"| {name} | {dt:g} | {label} | unstable | - |", flush=True)
                    continue
                difference = np.abs(theirs - ours.node_position).max()
                print(
                    f"| {name} | {dt:g} | {label} | {difference:.1e} | "
                    f"{off_constraints(s, theirs):.1e} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
