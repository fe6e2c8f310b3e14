#!/usr/bin/env python
"""Speed of the right-hand side and of fixed-step RK4: NumPy reference, compiled kernel,
a mass-matrix formulation of the same physics, and MuJoCo, side by side on class 1 shells.

Usage::

    python benchmarks/bench_rhs.py [--sizes 3x1,10x10,30x30,100x100] [--quick]
                                   [--mujoco-max 30x30]
                                   [--output benchmarks/results.md]

Every (size, method) pair runs in its own subprocess, so that its peak memory (``ru_maxrss``) is
its own and one method's caches or allocations do not slow another.  Timings are the best of
three repeats of wall-clock time (the machine may be shared).

Methods (all one thread, the same structure, the same state):

- ``numpy``: ``tensegrity.physics.dynamics.evaluate`` (the readable reference), and a plain RK4 loop
  of it with projection onto the rod constraints after every step.
- ``simulate``: the user's path, ``simulate()`` through the engine (blow-up checks, energy
  bookkeeping and samples included): ``method="rk4"`` with one sample per 100 steps (its rate:
  the time of ``2k`` steps less that of ``k``, per step; the fixed cost of a call, packing the
  structure and making the result, is reported apart), and the
  default DOP853 over ``SPAN`` = 0.02 s (steps, evaluations per step, time), each with its
  largest node deviation at 0.02 s from a DOP853 run at rtol 1e-12.
- ``kernel``: the engine's compiled physics, through the tests' harness
  (``tests/kernel_harness.py``, ``CompiledKernel``): ``evaluate()`` called from Python (the
  records made and the tendons reordered at every call), the engine's evaluation ``system_rhs``
  called from Python on records made once (into an array made once), and ``rk4()``, the engine's
  compiled RK4 stretch (``simulate(method="rk4")``'s checked, projected steps; its cost per
  step / 4 is the in-loop cost of one evaluation).
- ``massmatrix``: end-point (node) coordinates with the consistent mass matrix of a uniform rod,
  ``(m/6) [[2I, I], [I, 2I]]``, and the rod lengths held by Lagrange multipliers: every evaluation
  assembles the sparse KKT system ``[[M, G^T], [G, 0]]`` and solves it with
  ``scipy.sparse.linalg.spsolve`` (SuperLU).  The general-purpose formulation that Theorem 18.1
  avoids; its accelerations agree with the kernel's (printed).
- ``mujoco``: rods are free bodies (mass ``m``, inertia ``diag(mL^2/12, mL^2/12, eps)`` about the
  centre, sites at the ends), tendons are spatial tendons with ``stiffness=k`` and
  ``springlength="0 Lbar"`` (a deadband: pulls only when longer than ``Lbar``), RK4 at dt = 1e-4,
  contacts off, one thread, ``<size memory>`` set explicitly.  ``mj_forward`` stands for one
  right-hand-side evaluation.  The trajectory is checked against the kernel's over 0.02 s.

The structure: ``class1_shell(n, m)`` (rods 1 kg, 1 m; tendons 100 N/m, no damping: MuJoCo's
tendon damping acts while slack, unlike a cable), rest lengths 0.95 x the initial tendon lengths,
random rod-consistent initial velocities (about 0.3 m/s), no gravity.

The memory-traffic lower bound of one evaluation counts the bytes the kernel must read or write
once (``q``, ``q'``, rod and tendon parameters and indices, rest lengths, ``q''``, tensions) and
divides by the bandwidth of a NumPy copy, both of a large (DRAM) array and of an array the size of
the data (a cache-resident copy, the relevant bound when the data fit in cache).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import math
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# The compiled kernel is timed through the tests' harness (tests/kernel_harness.py), which calls
# the engine's compiled functions on its records; the library has no public kernel object.
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

HERE = Path(__file__).resolve().parent
DT = 1e-4
SEED = 20240611
METHODS = ("numpy", "simulate", "kernel", "massmatrix", "mujoco")
#: Simulated time of the time-to-result comparison [s] (MuJoCo's trajectory check's span).
SPAN = 0.02


# =========================================================================== the benchmark state
def parse_size(text: str) -> tuple[int, int]:
    n, m = (int(x) for x in text.lower().split("x"))
    return n, m


def bench_problem(n: int, m: int):
    """``(structure, q, qdot, rest_length)``: the shell, its layout with rod-consistent random
    velocities, and rest lengths 0.95 x the initial tendon lengths."""
    from tensegrity import class1_shell
    from tensegrity.physics import dynamics

    structure = class1_shell(n, m)
    p = structure.node_position
    rest = 0.95 * dynamics.tendon_lengths(structure, p)
    rng = np.random.default_rng(SEED)
    v = np.empty_like(p)
    for a, b in structure.rod_nodes:
        d = p[b] - p[a]
        vc = 0.3 * rng.standard_normal(3)
        dv = np.cross(0.3 * rng.standard_normal(3), d)
        v[a], v[b] = vc - dv / 2, vc + dv / 2
    q = dynamics.coordinates_from_nodes(structure, p)
    qdot = dynamics.coordinates_from_nodes(structure, v)
    q, qdot = dynamics.project_to_constraints(structure, q, qdot)
    return structure, q, qdot, rest


def best_time(fn, budget: float, repeats: int = 3) -> float:
    """Best wall time of one call of ``fn`` over ``repeats`` timed batches of about
    ``budget / repeats`` seconds each (a single call if one call already exceeds that)."""
    t0 = time.perf_counter()
    fn()
    first = time.perf_counter() - t0
    if first > budget / repeats:  # slow: one or two single calls
        return first if first > budget else min(first, _timed(fn, 1))
    calls = max(1, int(budget / repeats / max(first, 1e-9)))
    return min(_timed(fn, calls) for _ in range(repeats))


def _timed(fn, calls: int) -> float:
    t0 = time.perf_counter()
    for _ in range(calls):
        fn()
    return (time.perf_counter() - t0) / calls


def steps_for(budget: float, seconds_per_step: float) -> int:
    return max(1, int(budget / 3 / max(seconds_per_step, 1e-9)))


def vm_hwm_mb() -> float:
    """Peak resident memory so far [MB] (VmHWM)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


# =========================================================================== (b) mass matrix
class MassMatrixModel:
    """The same physics in node coordinates ``x`` (3N,): ``M x'' = f + G^T lambda``, ``G x'' =
    -G' x'`` (rod lengths ``|p_b - p_a|^2 = L^2``), solved as one sparse KKT system per call."""

    def __init__(self, structure):
        import scipy.sparse as sp

        self.s = structure
        N, R = structure.n_nodes, structure.n_rods
        self.n = n = 3 * N
        a, b = structure.rod_nodes[:, 0], structure.rod_nodes[:, 1]
        self.a, self.b = a, b
        m = structure.rod_mass
        i3 = np.arange(3)
        ia = (3 * a[:, None] + i3).ravel()  # (3R,)
        ib = (3 * b[:, None] + i3).ravel()
        m3 = np.repeat(m, 3)
        m_rows = np.concatenate([ia, ib, ia, ib])
        m_cols = np.concatenate([ia, ib, ib, ia])
        m_data = np.concatenate([m3 / 3, m3 / 3, m3 / 6, m3 / 6])
        self.M = sp.csr_matrix((m_data, (m_rows, m_cols)), shape=(n, n))
        alpha_x = np.empty(n)  # rod damping rate of each coordinate
        alpha_x[ia] = np.repeat(structure.rod_damping, 3)
        alpha_x[ib] = np.repeat(structure.rod_damping, 3)
        self.alpha_M = sp.diags(alpha_x) @ self.M
        r3 = np.repeat(np.arange(R), 3) + n
        g_rows = np.concatenate([r3, r3, ia, ib])  # G (R, 3N) and G^T (3N, R)
        g_cols = np.concatenate([ia, ib, r3, r3])
        rows = np.concatenate([m_rows, g_rows])
        cols = np.concatenate([m_cols, g_cols])
        self.n_m = m_data.size
        self.data = np.concatenate([m_data, np.zeros(g_rows.size)])
        # CSC with a fixed pattern: find where each COO entry lands, to update values in place.
        probe = sp.csc_matrix(
            (np.arange(1, rows.size + 1, dtype=float), (rows, cols)), shape=(n + R, n + R)
        )
        probe.sort_indices()
        self.perm = probe.data.astype(np.int64) - 1
        self.K = probe
        self.node_mass = structure.node_mass
        self.rhs = np.zeros(n + R)

    def accelerations(self, x, v, rest, external_force=None, gravity=None):
        from scipy.sparse.linalg import spsolve

        from tensegrity.physics import dynamics

        s, n = self.s, self.n
        p, vv = x.reshape(-1, 3), v.reshape(-1, 3)
        tendons = dynamics.tendon_forces(s, p, vv, rest)
        f = -(s.tendon_incidence_transpose @ (tendons.tension[:, None] * tendons.direction))
        if external_force is not None:
            f = f + external_force
        if gravity is not None:
            f = f + self.node_mass[:, None] * gravity
        f = f.ravel() - self.alpha_M @ v
        d = p[self.b] - p[self.a]
        dv = vv[self.b] - vv[self.a]
        two_d = (2.0 * d).ravel()
        self.data[self.n_m :] = np.concatenate([-two_d, two_d, -two_d, two_d])
        self.K.data[:] = self.data[self.perm]
        self.rhs[:n] = f
        self.rhs[n:] = -2.0 * np.sum(dv * dv, axis=1)
        return spsolve(self.K, self.rhs)[:n]

    def project(self, x, v):
        L = self.s.rod_length[:, None]
        p, vv = x.reshape(-1, 3).copy(), v.reshape(-1, 3).copy()
        a, b = self.a, self.b
        c, d = 0.5 * (p[a] + p[b]), p[b] - p[a]
        d *= L / np.linalg.norm(d, axis=1, keepdims=True)
        p[a], p[b] = c - d / 2, c + d / 2
        vc, dv = 0.5 * (vv[a] + vv[b]), vv[b] - vv[a]
        dv -= np.sum(d * dv, axis=1, keepdims=True) / L**2 * d
        vv[a], vv[b] = vc - dv / 2, vc + dv / 2
        return p.ravel(), vv.ravel()

    def rk4_step(self, x, v, h, rest):
        acc = self.accelerations
        a1 = acc(x, v, rest)
        x2, v2 = x + h / 2 * v, v + h / 2 * a1
        a2 = acc(x2, v2, rest)
        x3, v3 = x + h / 2 * v2, v + h / 2 * a2
        a3 = acc(x3, v3, rest)
        x4, v4 = x + h * v3, v + h * a3
        a4 = acc(x4, v4, rest)
        x = x + h / 6 * (v + 2 * v2 + 2 * v3 + v4)
        v = v + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        return self.project(x, v)


# =========================================================================== MuJoCo model
def _quat_z_to(d: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) rotating the z axis onto the direction of ``d``."""
    d = d / np.linalg.norm(d)
    axis = np.cross([0.0, 0.0, 1.0], d)
    s, c = np.linalg.norm(axis), d[2]
    if s < 1e-15:
        return np.array([1.0, 0, 0, 0]) if c > 0 else np.array([0.0, 1, 0, 0])
    angle = math.atan2(s, c)
    return np.r_[math.cos(angle / 2), math.sin(angle / 2) * axis / s]


def _quat_matrix(qt: np.ndarray) -> np.ndarray:
    w, x, y, z = qt
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def mujoco_memory_mb(structure) -> int:
    """Arena size: measured use is ~0.11 kB per (dof + tendon); give ~20x that plus 64 MB."""
    return 64 + math.ceil(2.0 * (6 * structure.n_rods + structure.n_tendons) / 1024)


def mjcf(structure, rest: np.ndarray, p: np.ndarray, dt: float = DT) -> str:
    """MJCF of the structure at node positions ``p`` (rod axes = body z axes)."""

    def f(x):
        return repr(float(x))

    lines = [
        '<mujoco model="tensegrity">',
        '  <compiler angle="radian"/>',
        f'  <option integrator="RK4" timestep="{f(dt)}" gravity="0 0 0">',
        '    <flag contact="disable"/>',
        "  </option>",
        f'  <size memory="{mujoco_memory_mb(structure)}M"/>',
        "  <worldbody>",
    ]
    for r, (a, b) in enumerate(structure.rod_nodes):
        m, L = structure.rod_mass[r], structure.rod_length[r]
        c, qt = 0.5 * (p[a] + p[b]), _quat_z_to(p[b] - p[a])
        inertia = m * L * L / 12
        lines.append(
            f'    <body name="rod{r}" pos="{f(c[0])} {f(c[1])} {f(c[2])}" '
            f'quat="{f(qt[0])} {f(qt[1])} {f(qt[2])} {f(qt[3])}"><freejoint/>'
            f'<inertial pos="0 0 0" mass="{f(m)}" diaginertia="{f(inertia)} {f(inertia)} '
            f'{f(1e-6 * inertia)}"/>'
            f'<site name="n{a}" pos="0 0 {f(-L / 2)}"/><site name="n{b}" pos="0 0 {f(L / 2)}"/>'
            "</body>"
        )
    lines += ["  </worldbody>", "  <tendon>"]
    for k, (tail, head) in enumerate(structure.tendon_nodes):
        lines.append(
            f'    <spatial name="s{k}" stiffness="{f(structure.tendon_stiffness[k])}" '
            f'springlength="0 {f(rest[k])}" damping="0">'
            f'<site site="n{tail}"/><site site="n{head}"/></spatial>'
        )
    lines += ["  </tendon>", "</mujoco>"]
    return "\n".join(lines)


def mujoco_set_state(model, data, structure, q, qdot) -> None:
    """Free-joint ``qpos``/``qvel`` from ``(q, qdot)``: body origin at the rod centre, body z
    along ``q2``; ``qvel`` holds the centre velocity (world) and angular velocity (body frame)."""
    from tensegrity.physics import dynamics

    rods, rates = dynamics.rods_view(q), dynamics.rods_view(qdot)
    for r in range(structure.n_rods):
        q1, q2 = rods[r]
        v1, v2 = rates[r]
        L = structure.rod_length[r]
        qt = _quat_z_to(q2)
        omega_world = np.cross(q2, v2) / L**2  # v2 = omega x q2 with omega . q2 = 0
        adr, vadr = model.jnt_qposadr[r], model.jnt_dofadr[r]
        data.qpos[adr : adr + 3] = q1 / 2
        data.qpos[adr + 3 : adr + 7] = qt
        data.qvel[vadr : vadr + 3] = v1 / 2
        data.qvel[vadr + 3 : vadr + 6] = _quat_matrix(qt).T @ omega_world


def mujoco_nodes(model, data, structure) -> np.ndarray:
    import mujoco

    mujoco.mj_kinematics(model, data)  # after mj_step, site_xpos holds the last RK4 stage
    p = np.empty((structure.n_nodes, 3))
    for k in range(structure.n_nodes):
        p[k] = data.site_xpos[model.site(f"n{k}").id]
    return p


# =========================================================================== workers
def time_simulate(structure, q, qdot, rest, budget: float) -> dict:
    """The user's path: ``simulate(method="rk4")`` steps per second with one sample per 100
    steps, and the default DOP853 over ``SPAN``, each with its deviation from a tight run."""
    from tensegrity import simulate
    from tensegrity.physics.dynamics import State

    s_r = structure.replace(tendon_rest_length=rest)
    initial = State(0.0, q, qdot)
    out: dict = {}

    def rk4(n_steps: int):
        r = simulate(
            s_r, (0.0, n_steps * DT), initial=initial, method="rk4", dt=DT, sample_dt=100 * DT
        )
        assert r.success and r.nsteps == n_steps, r.message
        return r

    rk4(100)  # the compiled code's disk cache loaded outside the timings
    t0 = time.perf_counter()
    rk4(100)
    k = 100 * max(1, steps_for(budget, (time.perf_counter() - t0) / 100) // 100)
    # steps/s is the rate of a run (k more steps cost this much more); a call's fixed cost
    # (packing the structure, the first projection, the result's arrays) is reported apart
    once, twice = best_time(lambda: rk4(k), budget), best_time(lambda: rk4(2 * k), budget)
    out["rk4_step_s"] = (twice - once) / k
    out["rk4_setup_s"] = max(0.0, once - k * out["rk4_step_s"])

    def dop853(**tolerances):
        return simulate(s_r, (0.0, SPAN), initial=initial, sample_dt=SPAN / 10, **tolerances)

    run = dop853()
    out["dop853_s"] = best_time(dop853, budget)
    out["dop853_steps"], out["dop853_nfev"] = run.nsteps, run.nfev
    reference = dop853(rtol=1e-12, atol=1e-14).node_position[-1]
    out["dop853_deviation_m"] = float(np.max(np.abs(run.node_position[-1] - reference)))
    n_span = round(SPAN / DT)
    out["rk4_deviation_m"] = float(np.max(np.abs(rk4(n_span).node_position[-1] - reference)))
    out["rk4_span_s"] = best_time(lambda: rk4(n_span), budget)
    return out


def evaluation(kernel, q: np.ndarray, qdot: np.ndarray, rest: np.ndarray):
    """One evaluation as the engine's loop makes it, called from Python: a callable without
    arguments running ``system_rhs`` on ``kernel``'s records made once (rest lengths ``rest``
    [m], structure order), into an acceleration array made once."""
    from tensegrity.physics.kernel_system import system_rhs

    model, data = kernel.records(rest)
    qddot = np.empty(q.size)
    return lambda: system_rhs(model, data, 0, q, qdot, qddot)


def worker(method: str, n: int, m: int, budget: float, cold: bool) -> dict:
    """Time one method on one size in this (fresh) process; returns a JSON-able dict."""
    import tensegrity  # noqa: F401  (import cost outside the measurement)
    from tensegrity.physics import dynamics

    if method in ("kernel", "simulate"):
        import numba  # noqa: F401  (import cost outside the measurement)
    if method == "mujoco":
        import mujoco
    import scipy.sparse.linalg  # noqa: F401  (import cost outside the measurement)

    structure, q, qdot, rest = bench_problem(n, m)
    out: dict = dict(
        method=method,
        n=n,
        m=m,
        R=structure.n_rods,
        S=structure.n_tendons,
        rss_after_import_mb=vm_hwm_mb(),
    )

    if method == "numpy":

        def ev():
            return dynamics.evaluate(structure, q, qdot, rest_length=rest)

        out["rhs_s"] = best_time(ev, budget)

        def rk4_step(qq, vv, h=DT):
            a1 = dynamics.evaluate(structure, qq, vv, rest_length=rest).qddot
            q2, v2 = qq + h / 2 * vv, vv + h / 2 * a1
            a2 = dynamics.evaluate(structure, q2, v2, rest_length=rest).qddot
            q3, v3 = qq + h / 2 * v2, vv + h / 2 * a2
            a3 = dynamics.evaluate(structure, q3, v3, rest_length=rest).qddot
            q4, v4 = qq + h * v3, vv + h * a3
            a4 = dynamics.evaluate(structure, q4, v4, rest_length=rest).qddot
            return dynamics.project_to_constraints(
                structure,
                qq + h / 6 * (vv + 2 * v2 + 2 * v3 + v4),
                vv + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4),
            )

        out["rk4_step_s"] = best_time(lambda: rk4_step(q, qdot), budget)

    elif method == "simulate":
        out.update(time_simulate(structure, q, qdot, rest, budget))

    elif method == "kernel":
        from kernel_harness import CompiledKernel

        # first call: compile (or load from numba's cache) the evaluation and the RK4 stretch
        t0 = time.perf_counter()
        kernel = CompiledKernel(structure)
        kernel.evaluate(q, qdot, rest)
        kernel.rk4(q, qdot, DT, 1, rest)
        out["first_call_s"] = time.perf_counter() - t0
        out["first_call_kind"] = "cold compile" if cold else "disk cache"
        out["rhs_s"] = best_time(lambda: kernel.evaluate(q, qdot, rest), budget)
        out["rhs_out_s"] = best_time(evaluation(kernel, q, qdot, rest), budget)
        k = steps_for(budget, 4 * out["rhs_out_s"])
        out["rk4_step_s"] = best_time(lambda: kernel.rk4(q, qdot, DT, k, rest), budget) / k
        out["rk4_steps_per_call"] = k
        ref = dynamics.evaluate(structure, q, qdot, rest_length=rest).qddot
        got = kernel.evaluate(q, qdot, rest).qddot
        out["max_rel_diff_vs_numpy"] = float(np.max(np.abs(got - ref)) / np.max(np.abs(ref)))

    elif method == "massmatrix":
        model = MassMatrixModel(structure)
        x = dynamics.nodes_from_coordinates(structure, q).ravel()
        v = dynamics.nodes_from_coordinates(structure, qdot).ravel()
        out["rhs_s"] = best_time(lambda: model.accelerations(x, v, rest), budget)
        out["rk4_step_s"] = best_time(lambda: model.rk4_step(x, v, DT, rest), budget)
        ref = dynamics.nodes_from_coordinates(
            structure, dynamics.evaluate(structure, q, qdot, rest_length=rest).qddot
        ).ravel()
        got = model.accelerations(x, v, rest)
        out["max_rel_diff_vs_numpy"] = float(np.max(np.abs(got - ref)) / np.max(np.abs(ref)))

    elif method == "mujoco":
        import mujoco

        xml = mjcf(structure, rest, structure.node_position)
        t0 = time.perf_counter()
        model = mujoco.MjModel.from_xml_string(xml)
        data = mujoco.MjData(model)
        out["compile_s"] = time.perf_counter() - t0
        out["nv"], out["ntendon"] = model.nv, model.ntendon
        out["memory_mb"] = mujoco_memory_mb(structure)

        def reset():
            mujoco.mj_resetData(model, data)
            mujoco_set_state(model, data, structure, q, qdot)
            mujoco.mj_forward(model, data)

        reset()
        # Same initial node positions and velocities as the other methods?
        vel = np.empty(6)
        node_v = dynamics.nodes_from_coordinates(structure, qdot)
        err_v = 0.0
        for k in range(structure.n_nodes):
            mujoco.mj_objectVelocity(
                model, data, mujoco.mjtObj.mjOBJ_SITE, model.site(f"n{k}").id, vel, 0
            )
            err_v = max(err_v, float(np.max(np.abs(vel[3:] - node_v[k]))))
        p0 = dynamics.nodes_from_coordinates(structure, q)
        out["initial_position_error"] = float(
            np.max(np.abs(mujoco_nodes(model, data, structure) - p0))
        )
        out["initial_velocity_error"] = err_v
        reset()
        out["rhs_s"] = best_time(lambda: mujoco.mj_forward(model, data), budget)
        reset()
        mujoco.mj_step(model, data)
        t0 = time.perf_counter()
        mujoco.mj_step(model, data)
        one = time.perf_counter() - t0
        k = steps_for(budget, one)
        out["rk4_step_s"] = best_time(lambda: mujoco.mj_step(model, data, nstep=k), budget) / k
        out["arena_used_mb"] = data.maxuse_arena / 1e6
        out["peak_rss_mb"] = vm_hwm_mb()
        # (after the peak memory: the kernel's numba import is not MuJoCo's)
        # Trajectory check: 200 steps (0.02 s) against the kernel.
        steps_check = 200
        reset()
        mujoco.mj_step(model, data, nstep=steps_check)
        p_mj = mujoco_nodes(model, data, structure)
        try:
            from kernel_harness import CompiledKernel

            qk, _ = CompiledKernel(structure).rk4(q, qdot, DT, steps_check, rest)
            p_k = dynamics.nodes_from_coordinates(structure, qk)
            out["trajectory_diff_0.02s"] = float(np.max(np.abs(p_mj - p_k)))
            out["trajectory_moved_0.02s"] = float(np.max(np.abs(p_k - p0)))
        except ImportError:
            pass
    else:
        raise ValueError(method)

    out.setdefault("peak_rss_mb", vm_hwm_mb())
    return out


def run_worker(
    method: str,
    size: tuple[int, int],
    budget: float,
    cold: bool = False,
    timeout: float | None = None,
) -> dict:
    env = dict(os.environ)
    tmp = None
    if cold:
        tmp = tempfile.TemporaryDirectory()
        env["NUMBA_CACHE_DIR"] = tmp.name
    cmd = [
        sys.executable,
        str(Path(__file__).resolve()),
        "--worker",
        method,
        "--sizes",
        f"{size[0]}x{size[1]}",
        "--budget",
        str(budget),
    ] + (["--cold"] if cold else [])
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=timeout)
    except subprocess.TimeoutExpired:
        return dict(method=method, n=size[0], m=size[1], error=f"timeout after {timeout} s")
    finally:
        if tmp is not None:
            tmp.cleanup()
    if proc.returncode != 0:
        return dict(
            method=method,
            n=size[0],
            m=size[1],
            error=(proc.stderr.strip().splitlines() or ["?"])[-1],
        )
    return json.loads(proc.stdout.strip().splitlines()[-1])


# =========================================================================== machine facts
def copy_bandwidth(nbytes: int, budget: float = 0.3) -> float:
    """Bytes per second moved by ``np.copyto`` of an array of ``nbytes`` (read + write counted),
    on one thread."""
    n = max(1, nbytes // 8)
    src, dst = np.random.default_rng().random(n), np.empty(n)  # any values: only copied
    np.copyto(dst, src)  # fault the pages in first: not part of the bandwidth
    t = best_time(lambda: np.copyto(dst, src), budget, repeats=5)
    return 2 * n * 8 / t


def kernel_bytes(R: int, S: int, *, tendon_damping: bool) -> int:
    """Bytes one kernel evaluation must touch at least once: reads q, q' (6R each), rod nodes
    (2R int64), rod m, L, alpha (3R); tendon nodes (2S int64), k, Lbar and, if any tendon is
    damped, c (2S or 3S); writes q'' (6R), tension and elastic tension (2S).  (Undamped tendons:
    the kernel's specialization does not read c, so neither does the bound.)"""
    tendon_param = 3 if tendon_damping else 2
    return 8 * (6 * R + 6 * R + 2 * R + 3 * R + 6 * R) + 8 * (2 * S + tendon_param * S + 2 * S)


def machine_info() -> dict:
    import numpy

    info = dict(
        python=platform.python_version(),
        numpy=numpy.__version__,
        platform=platform.platform(),
        cpus=os.cpu_count(),
    )
    try:
        cpu = [
            ln
            for ln in Path("/proc/cpuinfo").read_text().splitlines()
            if ln.startswith("model name")
        ]
        info["cpu"] = cpu[0].split(":", 1)[1].strip() if cpu else platform.processor()
    except OSError:
        info["cpu"] = platform.processor()
    for mod in ("scipy", "numba", "mujoco"):
        try:
            info[mod] = __import__(mod).__version__
        except ImportError:
            info[mod] = "not installed"
    caches = []
    for index in sorted(Path("/sys/devices/system/cpu/cpu0/cache").glob("index*")):
        try:
            level, kind, size = ((index / f).read_text().strip() for f in ("level", "type", "size"))
        except OSError:
            continue
        if kind != "Instruction":
            caches.append(f"L{level} {size}")
    info["caches"] = ", ".join(caches) if caches else "?"
    with contextlib.suppress(OSError):
        info["load_before"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    return info


# =========================================================================== report
def fmt_rate(seconds: float | None) -> str:
    if seconds is None or not math.isfinite(seconds) or seconds <= 0:
        return "—"
    r = 1.0 / seconds
    if r >= 1e5:
        return f"{r / 1e3:,.0f}k"
    if r >= 100:
        return f"{r:,.0f}"
    if r >= 1:
        return f"{r:.1f}"
    return f"{r:.3g}"


def fmt_ratio(num: float | None, den: float | None) -> str:
    if not num or not den:
        return "—"
    x = den / num  # rates: (1/num) / (1/den)
    return f"{x:,.0f}×" if x >= 100 else (f"{x:.1f}×" if x >= 1 else f"{x:.2f}×")  # noqa: RUF001 - the report's multiplication sign, U+00D7


def fmt_time(seconds: float | None) -> str:
    if seconds is None:
        return "—"
    if seconds < 1e-6:
        return f"{seconds * 1e9:.0f} ns"
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} µs"
    if seconds < 1:
        return f"{seconds * 1e3:.2f} ms"
    return f"{seconds:.2f} s"


def report(results: dict, sizes, info: dict, bw: dict, command: str, notes: list[str]) -> str:
    def get(size, method, key):
        r = results.get((size, method))
        return None if r is None or "error" in r else r.get(key)

    def label(s):
        return f"({s[0]},{s[1]})"

    def measured_sizes():
        """``(size, R, S)`` for the sizes some method measured."""
        for s in sizes:
            r = results.get((s, "kernel")) or results.get((s, "numpy")) or {}
            if r.get("R"):
                yield s, r["R"], r["S"]

    lines = []
    out = lines.append
    out(
        "# RHS and RK4 benchmark: NumPy reference vs compiled kernel vs mass-matrix formulation "
        "vs MuJoCo\n"
    )
    out(f"- Command: `{command}`")
    out(f"- Date: {info['date']}")
    out(
        f"- Machine: {info['cpu']}, {info['cpus']} CPUs ({info.get('caches', '?')}), "
        f"{info['platform']}; load average before "
        f"the run {info.get('load_before', '?')}, after {info.get('load_after', '?')} "
        "(a shared machine: other jobs may have been running)"
    )
    out(
        f"- Python {info['python']}, NumPy {info['numpy']}, SciPy {info['scipy']}, numba "
        f"{info['numba']}, MuJoCo {info['mujoco']}"
    )
    out(
        f"- Copy bandwidth (NumPy `copyto`, read + write): {bw['dram'] / 1e9:.1f} GB/s for a "
        f"{bw['dram_bytes'] / 2**20:.0f} MiB array (DRAM)"
    )
    out(
        "- Structure: `class1_shell(n, m)` (rods 1 kg, 1 m; tendons 100 N/m, undamped), "
        "rest lengths "
        "0.95 × initial lengths, random rod-consistent velocities (~0.3 m/s), no gravity. "  # noqa: RUF001 - the report's multiplication sign, U+00D7
        "One thread everywhere. Rates are the best of 3 timed batches (wall clock)."
    )
    out("")
    out("## Right-hand-side evaluations per second\n")
    out(
        "| shell | rods R | tendons S | NumPy `dynamics.evaluate` "
        "| kernel `evaluate()` (Python call) "
        "| kernel `system_rhs` (records made once) "
        "| kernel, in the RK4 loop (step/4) | mass matrix + sparse KKT | MuJoCo `mj_forward` "
        "| kernel call / NumPy |"
    )
    out("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for s in sizes:
        r = results.get((s, "numpy"), {})
        k_loop = get(s, "kernel", "rk4_step_s")
        out(
            f"| {label(s)} | {r.get('R', '')} | {r.get('S', '')} "
            f"| {fmt_rate(get(s, 'numpy', 'rhs_s'))} "
            f"| {fmt_rate(get(s, 'kernel', 'rhs_s'))} | {fmt_rate(get(s, 'kernel', 'rhs_out_s'))} "
            f"| {fmt_rate(k_loop / 4 if k_loop else None)} "
            f"| {fmt_rate(get(s, 'massmatrix', 'rhs_s'))} | {fmt_rate(get(s, 'mujoco', 'rhs_s'))} "
            f"| {fmt_ratio(get(s, 'kernel', 'rhs_s'), get(s, 'numpy', 'rhs_s'))} |"
        )
    out("")
    out(
        "## RK4 steps per second (dt = 1e-4, projection onto the rod constraints after each step)\n"
    )
    out(
        '| shell | NumPy loop | `simulate(method="rk4")` (a sample per 100 steps) '
        "| kernel `rk4()` (compiled loop) "
        "| mass matrix + KKT | MuJoCo `mj_step` | kernel / MuJoCo | kernel / NumPy loop "
        "| kernel / mass matrix | mass matrix / MuJoCo | `simulate` / kernel "
        "| `simulate` / MuJoCo |"
    )
    out("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for s in sizes:
        k = get(s, "kernel", "rk4_step_s")
        mj = get(s, "mujoco", "rk4_step_s")
        mm = get(s, "massmatrix", "rk4_step_s")
        out(
            f"| {label(s)} | {fmt_rate(get(s, 'numpy', 'rk4_step_s'))} "
            f"| {fmt_rate(get(s, 'simulate', 'rk4_step_s'))} | {fmt_rate(k)} | {fmt_rate(mm)} "
            f"| {fmt_rate(mj)} | {fmt_ratio(k, mj)} "
            f"| {fmt_ratio(k, get(s, 'numpy', 'rk4_step_s'))} "
            f"| {fmt_ratio(k, mm)} | {fmt_ratio(mm, mj)} "
            f"| {fmt_ratio(get(s, 'simulate', 'rk4_step_s'), k)} "
            f"| {fmt_ratio(get(s, 'simulate', 'rk4_step_s'), mj)} |"
        )
    setups = [
        f"{label(s)} {fmt_time(get(s, 'simulate', 'rk4_setup_s'))}"
        for s in sizes
        if get(s, "simulate", "rk4_setup_s") is not None
    ]
    if setups:
        out(
            '\n`simulate(method="rk4")` steps/s is its rate (the time of 2k steps less that of '
            "k); each call costs once more (packing the structure, the first projection and "
            "sample, the result): " + ", ".join(setups) + "."
        )
    out("")
    out(f"## Time to result: {SPAN:g} s of simulated time\n")
    out(
        "Wall time for the same motion through the user's path (`simulate`, samples, checks and "
        "energy bookkeeping included), the kernel's compiled RK4 loop and MuJoCo (RK4 steps at "
        f"dt = {DT:g} s), and the largest node deviation at the end from `simulate` at rtol "
        "1e-12 (MuJoCo's: from the kernel's RK4, see Checks).\n"
    )
    out(
        "| shell | `simulate` DOP853 | its steps, evaluations / step | deviation "
        "| `simulate` rk4 | deviation | kernel `rk4()` | MuJoCo | speed, DOP853 / MuJoCo |"
    )
    out("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    n_span = round(SPAN / DT)
    for s in sizes:
        steps = get(s, "simulate", "dop853_steps")
        per = f"{steps}, {get(s, 'simulate', 'dop853_nfev') / steps:.1f}" if steps else "—"

        def dev(key, s=s):
            return (
                f"{get(s, 'simulate', key):.1e} m" if get(s, "simulate", key) is not None else "—"
            )

        k, mj = get(s, "kernel", "rk4_step_s"), get(s, "mujoco", "rk4_step_s")
        out(
            f"| {label(s)} | {fmt_time(get(s, 'simulate', 'dop853_s'))} | {per} "
            f"| {dev('dop853_deviation_m')} | {fmt_time(get(s, 'simulate', 'rk4_span_s'))} "
            f"| {dev('rk4_deviation_m')} | {fmt_time(k * n_span if k else None)} "
            f"| {fmt_time(mj * n_span if mj else None)} "
            f"| {fmt_ratio(get(s, 'simulate', 'dop853_s'), mj * n_span if mj else None)} |"
        )
    out("")
    out("## The memory-traffic bound\n")
    out(
        "The bound is the bytes one kernel evaluation must touch once (`kernel_bytes`: q, q', rod "
        "and tendon indices and parameters, rest lengths, q'', tensions; the tendons are undamped, "
        "so neither the kernel nor the bound reads their damping) over the bandwidth of a "
        "NumPy copy: of a DRAM-sized array, and of a copy of the same number of bytes (at least "
        "1 MiB, so as not to time NumPy's call overhead; caches: "
        f"{info.get('caches', '?')}), on one thread. Kernel times are one `system_rhs` call on "
        "records made once (Python call included).\n"
    )
    out(
        "| shell | bytes / eval | bound: DRAM | bound: same-size copy | kernel | / DRAM bound "
        "| / same-size bound |"
    )
    out("|---|---:|---:|---:|---:|---:|---:|")
    for s, R, S in measured_sizes():
        nbytes = kernel_bytes(R, S, tendon_damping=False)
        key = f"{s[0]}x{s[1]}"
        bounds = (nbytes / bw["dram"], nbytes / bw["by_size"][key])
        k1 = get(s, "kernel", "rhs_out_s")

        def x(t, b):
            return f"{t / b:.1f}×" if t else "—"  # noqa: RUF001 - the report's multiplication sign, U+00D7

        out(
            f"| {label(s)} | {nbytes / 1e6:.3f} MB | {fmt_time(bounds[0])} | {fmt_time(bounds[1])} "
            f"| {fmt_time(k1)} | {x(k1, bounds[0])} | {x(k1, bounds[1])} |"
        )
    out("")
    out("## Cost per element\n")
    out("Per-evaluation cost divided by (rods + tendons), in ns, for linearity.\n")
    out(
        "| shell | kernel `system_rhs` (records made once) | kernel in the RK4 loop (step/4) "
        "| NumPy | mass matrix | MuJoCo step / 4 | MuJoCo µs per (dof+tendon) per step |"
    )
    out("|---|---:|---:|---:|---:|---:|---:|")
    for s, R, S in measured_sizes():

        def per(t, R=R, S=S):
            return "—" if not t else f"{t / (R + S) * 1e9:.1f}"

        def quarter(t):
            return t / 4 if t else None

        mj = get(s, "mujoco", "rk4_step_s")
        out(
            f"| {label(s)} | {per(get(s, 'kernel', 'rhs_out_s'))} "
            f"| {per(quarter(get(s, 'kernel', 'rk4_step_s')))} "
            f"| {per(get(s, 'numpy', 'rhs_s'))} | {per(get(s, 'massmatrix', 'rhs_s'))} "
            f"| {per(quarter(mj))} "
            f"| {'—' if not mj else f'{mj / (6 * R + S) * 1e6:.2f}'} |"
        )
    out("")
    out("## Peak memory and set-up cost\n")
    out(
        "Peak resident memory of the process that ran the method (VmHWM), and its growth over the "
        "peak right after the imports (the model, its buffers and the solve).\n"
    )
    out(
        "| shell | NumPy peak (Δ) | kernel peak (Δ) | mass matrix peak (Δ) | MuJoCo peak (Δ) "
        "| MuJoCo compile | MuJoCo arena set / used | kernel first call |"
    )
    out("|---|---:|---:|---:|---:|---:|---:|---:|")
    for s in sizes:

        def mem(method, s=s):
            r = results.get((s, method))
            if r is None:
                return "not run"
            if "error" in r:
                return "error"
            return f"{r['peak_rss_mb']:.0f} MB (+{r['peak_rss_mb'] - r['rss_after_import_mb']:.0f})"

        mjr = results.get((s, "mujoco"), {})
        kr = results.get((s, "kernel"), {})
        arena = (
            f"{mjr['memory_mb']} MB / {mjr['arena_used_mb']:.1f} MB"
            if "arena_used_mb" in mjr
            else "—"
        )
        first = (
            f"{kr['first_call_s']:.2f} s ({kr['first_call_kind']})" if "first_call_s" in kr else "—"
        )
        out(
            f"| {label(s)} | {mem('numpy')} | {mem('kernel')} | {mem('massmatrix')} "
            f"| {mem('mujoco')} | {fmt_time(mjr.get('compile_s'))} | {arena} | {first} |"
        )
    out("")
    out("## Checks\n")
    for s in sizes:
        parts = []
        v = get(s, "kernel", "max_rel_diff_vs_numpy")
        if v is not None:
            parts.append(f"kernel vs NumPy accelerations {v:.1e} (relative)")
        v = get(s, "massmatrix", "max_rel_diff_vs_numpy")
        if v is not None:
            parts.append(f"mass matrix vs NumPy {v:.1e}")
        mjr = results.get((s, "mujoco"), {})
        if "trajectory_diff_0.02s" in mjr:
            parts.append(
                f"MuJoCo vs kernel node positions after 200 steps (0.02 s): "
                f"{mjr['trajectory_diff_0.02s']:.1e} m (nodes moved up to "
                f"{mjr['trajectory_moved_0.02s']:.1e} m; initial state mismatch "
                f"{mjr['initial_position_error']:.0e} m, {mjr['initial_velocity_error']:.0e} m/s)"
            )
        for method in METHODS:
            r = results.get((s, method))
            if r is not None and "error" in r:
                parts.append(f"{method}: {r['error']}")
        out(f"- {label(s)}: " + ("; ".join(parts) if parts else "—"))
    for note in notes:
        out(f"- {note}")
    out("")
    return "\n".join(lines)


# =========================================================================== main
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--sizes",
        default="3x1,10x10,30x30,100x100",
        help="comma-separated shell sizes n x m (default %(default)s)",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="shorter timings (about 0.3 s per measurement instead of 1.5 s)",
    )
    parser.add_argument(
        "--mujoco-max",
        default="30x30",
        help="largest shell (by rod count) to build in MuJoCo, or 'none'; MuJoCo's "
        "compile time grows ~quadratically (6.5 min at 100x100) (default %(default)s)",
    )
    parser.add_argument(
        "--methods",
        default=",".join(METHODS),
        help="comma-separated subset of " + ",".join(METHODS),
    )
    parser.add_argument(
        "--output",
        default=str(HERE / "results.md"),
        help="markdown report to write (default %(default)s); '-' for none",
    )
    parser.add_argument("--budget", type=float, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--cold", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    sizes = [parse_size(x) for x in args.sizes.split(",") if x.strip()]
    budget = args.budget if args.budget is not None else (0.3 if args.quick else 1.5)
    if args.worker:
        print(json.dumps(worker(args.worker, *sizes[0], budget, args.cold)))
        return 0

    methods = [x.strip() for x in args.methods.split(",") if x.strip()]
    mujoco_max = None if args.mujoco_max.lower() == "none" else parse_size(args.mujoco_max)
    info = machine_info()
    info["date"] = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    command = "python benchmarks/bench_rhs.py " + " ".join(
        a if " " not in a else repr(a) for a in (argv if argv is not None else sys.argv[1:])
    )

    print(
        f"machine: {info['cpu']}, {info['cpus']} CPUs, load {info.get('load_before', '?')}",
        flush=True,
    )
    bw = {"dram_bytes": 512 * 2**20}
    bw["dram"] = copy_bandwidth(bw["dram_bytes"] // 2)
    bw["by_size"] = {}
    print(f"copy bandwidth (DRAM): {bw['dram'] / 1e9:.1f} GB/s", flush=True)

    results: dict = {}
    notes: list[str] = []
    cold_done = False
    for size in sizes:
        n, m = size
        R, S = 2 * n * m, n * (10 * m - 2)
        # (at least 1 MiB: smaller copies measure NumPy's call overhead, not the memory)
        same_size = max(kernel_bytes(R, S, tendon_damping=False) // 2, 2**20 // 2)
        bw["by_size"][f"{n}x{m}"] = copy_bandwidth(same_size)
        for method in methods:
            if method == "mujoco" and (
                mujoco_max is None or 2 * n * m > 2 * mujoco_max[0] * mujoco_max[1]
            ):
                continue
            cold = method == "kernel" and not cold_done
            print(f"({n},{m}) {method} ...", end=" ", flush=True)
            t0 = time.perf_counter()
            r = run_worker(method, size, budget, cold=cold)
            cold_done |= cold and "error" not in r
            results[(size, method)] = r
            if "error" in r:
                print(f"ERROR {r['error']}", flush=True)
            else:
                print(
                    f"rhs {fmt_rate(r.get('rhs_s'))}/s, "
                    f"rk4 {fmt_rate(r.get('rk4_step_s'))} steps/s "
                    f"({time.perf_counter() - t0:.1f} s)",
                    flush=True,
                )
        skipped = mujoco_max is None or 2 * n * m > 2 * mujoco_max[0] * mujoco_max[1]
        if "mujoco" in methods and skipped:
            notes.append(
                f"({n},{m}): MuJoCo not run (--mujoco-max {args.mujoco_max}); the cross-check "
                "notes measured ~5 steps/s and a 6.5 min compile at (100,100)"
            )
    with contextlib.suppress(OSError):
        info["load_after"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    write_report(report(results, sizes, info, bw, command, notes), args.output)
    return 0


def write_report(text: str, output: str) -> None:
    """Print the markdown report and write it to ``output`` (unless ``"-"``)."""
    print()
    print(text)
    if output != "-":
        Path(output).write_text(text)
        print(f"wrote {output}")


if __name__ == "__main__":
    sys.exit(main())
