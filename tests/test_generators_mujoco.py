"""Generated structures in MuJoCo (through the MJCF export) and in this library: same motion.

Undamped, no gravity, random velocities consistent with the rods (a structure at rest in its
equilibrium would not move; every tendon stays taut).  Measured, largest node-position
difference over 0.5 s (nodes move 0.1-0.2 m): MuJoCo RK4 vs our RK4 at the same dt = 1e-4 s,
1.7e-14 .. 2.8e-14 m; vs our DOP853 (rtol 1e-12), 8e-14 .. 1.4e-13 m, for the simplex, the
4-bar prism, the octahedron and the 3x2 tower.
"""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.design.catalogue import octahedron, prism, tower

pytest.importorskip("mujoco")
from test_mjcf import SAMPLE_DT, max_difference, rod_consistent_velocity, run_mujoco

CASES = {
    "simplex": lambda: prism(3),
    "4-bar prism": lambda: prism(4),
    "octahedron": octahedron,
    "tower 3x2": lambda: tower(3, 2),
}


@pytest.mark.parametrize("name", list(CASES))
def test_generated_structure_moves_alike_in_mujoco(name):
    s = CASES[name]()
    s = s.replace(node_velocity=rod_consistent_velocity(s, 0.3, seed=11))
    t_end, dt = 0.5, 1e-4
    rk4 = simulate(s, (0.0, t_end), method="rk4", dt=dt, sample_dt=SAMPLE_DT)
    adaptive = simulate(s, (0.0, t_end), rtol=1e-12, atol=1e-15, sample_dt=SAMPLE_DT)
    assert rk4.success and adaptive.success
    positions, _ = run_mujoco(s, t_end, dt)
    moved = np.abs(positions[-1] - positions[0]).max()
    assert moved > 0.01, moved  # a real motion, not a structure at rest
    same_scheme = max_difference(positions, rk4.node_position).max()
    assert same_scheme < 1e-9, same_scheme
    assert max_difference(positions, adaptive.node_position).max() < 1e-9  # issue: 1e-5
    # undamped: energy conserved by both of ours
    assert np.ptp(adaptive.total_energy) < 1e-8 * adaptive.total_energy[0]
