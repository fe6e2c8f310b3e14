"""MJCF export of joints, supports, anchors and point masses, with MuJoCo as an independent peer:
ball joints and fixed rod ends become ``connect`` equality constraints, anchors world sites,
point masses free bodies.  Node trajectories agree with ours to 1e-6 m over 0.3 s of violent
motion (measured ~5e-8 m)."""

from __future__ import annotations

import numpy as np
import pytest

from tensegrity import simulate
from tensegrity.io.mjcf import mujoco_node_positions, to_mjcf
from tensegrity.model.shell import class2_shell
from test_constraints import GRAVITY, hanging_chain

mujoco = pytest.importorskip("mujoco")


def max_difference_from_mujoco(structure, t_end, gravity, dt=1e-4, samples=10):
    """Largest node-position difference [m] between our run (tight tolerances) and MuJoCo's RK4
    at step ``dt``, at ``samples`` equally spaced times; and our largest kinetic energy [J]."""
    ours = simulate(
        structure, (0.0, t_end), gravity=gravity, sample_dt=t_end / samples, rtol=1e-11, atol=1e-13
    )
    assert ours.status == 0, ours.message
    model = mujoco.MjModel.from_xml_string(to_mjcf(structure, timestep=dt, gravity=gravity))
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    worst, steps = 0.0, 0
    for k in range(1, samples + 1):
        target = round(ours.t[k] / dt)
        for _ in range(target - steps):
            mujoco.mj_step(model, data)
        steps = target
        p = mujoco_node_positions(model, data, structure.n_nodes)
        worst = max(worst, float(np.abs(p - ours.node_position[k]).max()))
    return worst, float(ours.energy["kinetic"].max())


@pytest.mark.parametrize("fixed_base, gravity", [(False, np.zeros(3)), (True, GRAVITY)])
def test_class2_shell_matches_mujoco(fixed_base, gravity):
    s = class2_shell(3, 2, fixed_base=fixed_base)
    difference, kinetic = max_difference_from_mujoco(s, 0.3, gravity)
    assert kinetic > 100.0  # a violent collapse, not a structure at rest
    assert difference < 1e-6


def test_anchors_payload_and_pinned_chain_match_mujoco():
    s = hanging_chain(damped=False)
    difference, kinetic = max_difference_from_mujoco(s, 0.5, GRAVITY)
    assert kinetic > 1.0
    assert difference < 1e-6


def test_model_has_the_constraints_and_bodies():
    s = hanging_chain(damped=False)
    model = mujoco.MjModel.from_xml_string(to_mjcf(s))
    # joints (0,4), (1,2), (3,6); no rod end is fixed (node 0 hangs from anchor 4 by a joint)
    assert model.neq == 3 and model.nbody == 1 + 2 + 1  # world, two rods, the payload
    assert model.nv == 6 * 3
    site = {mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_SITE, k): k for k in range(model.nsite)}
    for anchor in (4, 5, 7):
        assert model.site_bodyid[site[f"node{anchor}"]] == 0
        np.testing.assert_array_equal(
            model.site_pos[site[f"node{anchor}"]], s.node_position[anchor]
        )
    pinned = class2_shell(3, 2, fixed_base=True)
    model = mujoco.MjModel.from_xml_string(to_mjcf(pinned))
    assert model.neq == len(pinned.joint_nodes) + int(pinned.node_fixed.sum())
