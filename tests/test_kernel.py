"""The compiled kernel (``tensegrity.physics.kernel``) against the NumPy reference
``dynamics.evaluate``.

Random consistent states (every rod exactly ``L`` long, no rod-stretching velocity), random rest
lengths with a third of the tendons slack and one at zero, random tendon and rod damping (so that
some taut tendons have their tension clipped at zero), random external forces and gravity.  The
compiled RK4 loop is compared with a classical RK4 (``python_rk4``) driven by ``dynamics.evaluate``
and projected after every step, as ``simulate(method="rk4")`` does.  Both go through the
engine's records (:mod:`tensegrity.physics.records`; ``kernel_harness.CompiledKernel``).
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

pytest.importorskip("numba")

from kernel_harness import CompiledKernel
from tensegrity import Structure, class1_shell, simulate
from tensegrity.physics import (
    dynamics,
    kernel as kernel_module,
)
from tensegrity.physics.kernel import stencil_layout
from tensegrity.physics.kernel_system import system_rhs
from test_dynamics import (
    mixed_controls,
    random_consistent_state as random_consistent_nodes,
)

TOL = 1e-12


def random_general_structure(rng, n_rods: int = 9, n_tendons: int = 40) -> Structure:
    """Rods of random masses and lengths whose end nodes are numbered in a scrambled order (so an
    index mix-up between rods, nodes and coordinates shows), and random tendons between them."""
    nodes = rng.permutation(2 * n_rods).reshape(n_rods, 2)
    length = rng.uniform(0.5, 2.0, n_rods)
    position = np.empty((2 * n_rods, 3))
    for r, (a, b) in enumerate(nodes):
        d = rng.standard_normal(3)
        centre = 2.0 * rng.standard_normal(3)
        position[a] = centre - 0.5 * length[r] * d / np.linalg.norm(d)
        position[b] = centre + 0.5 * length[r] * d / np.linalg.norm(d)
    pairs = set()
    while len(pairs) < n_tendons:
        a, b = (int(x) for x in rng.choice(2 * n_rods, 2, replace=False))
        if {a, b} in [set(x) for x in nodes.tolist()] or (min(a, b), max(a, b)) in pairs:
            continue
        pairs.add((min(a, b), max(a, b)))
    tendon_nodes = np.array([(a, b) if rng.random() < 0.5 else (b, a) for a, b in sorted(pairs)])
    return Structure(
        node_position=position,
        rod_nodes=nodes,
        rod_mass=rng.uniform(0.3, 3.0, n_rods),
        rod_length=length,
        tendon_nodes=tendon_nodes,
        tendon_stiffness=rng.uniform(10.0, 500.0, n_tendons),
        tendon_rest_length=np.zeros(n_tendons),
    )


def with_random_parameters(structure: Structure, rng: np.random.Generator) -> Structure:
    """Unequal masses, stiffnesses and (large enough to clip some tensions) damping values, the
    rods damped both to ground and relative to the rigid-body motion."""
    return structure.replace(
        rod_mass=rng.uniform(0.3, 3.0, structure.n_rods),
        tendon_stiffness=rng.uniform(10.0, 500.0, structure.n_tendons),
        tendon_damping=rng.uniform(0.5, 40.0, structure.n_tendons),
        rod_damping=rng.uniform(0.1, 5.0, structure.n_rods),
        rod_relative_damping=rng.uniform(0.1, 5.0, structure.n_rods),
    )


def random_consistent_state(structure, rng, speed=2.0, jitter=0.15):
    """``(q, qdot)`` near the layout with every ``|q2| = L`` and ``q2 . q2' = 0`` (the node
    positions and velocities of ``test_dynamics.random_consistent_state``)."""
    p, v = random_consistent_nodes(structure, rng, speed=speed, jitter=jitter)
    return (
        dynamics.coordinates_from_nodes(structure, p),
        dynamics.coordinates_from_nodes(structure, v),
    )


def random_rest_lengths(structure, q, rng):
    """A third of the tendons slack, one at ``Lbar = 0``, the rest taut by a random amount
    (``test_dynamics.mixed_controls`` at the nodes of ``q``): ``(rest, slack)``."""
    _, rest, slack = mixed_controls(structure, dynamics.nodes_from_coordinates(structure, q), rng)
    return rest, slack


def _rel(actual, expected, scale=None) -> float:
    scale = np.max(np.abs(expected)) if scale is None else scale
    return float(np.max(np.abs(np.asarray(actual) - np.asarray(expected))) / max(scale, 1e-300))


CASES = [
    pytest.param(dict(n=3, m=1), id="shell(3,1)"),
    pytest.param(dict(n=4, m=2), id="shell(4,2)"),
    pytest.param(dict(n=10, m=10), id="shell(10,10)"),
    pytest.param(dict(n=4, m=2, primal=True), id="primal(4,2)"),
    pytest.param(dict(n=3, m=1, primal=True), id="primal(3,1)"),
    pytest.param(None, id="general"),
]


def _structure(case, rng) -> Structure:
    base = random_general_structure(rng) if case is None else class1_shell(**case)
    return with_random_parameters(base, rng)


def _seed(case, *extra) -> int:
    return zlib.crc32(repr((sorted(case.items()) if case else "general", extra)).encode())


# --------------------------------------------------------------------------- evaluate


@pytest.fixture(params=[None, 2], ids=["default runs", "runs of 2"])
def min_run(request, monkeypatch):
    """The kernel's shortest run of tendons (``kernel.MIN_RUN``): its default, which leaves the
    small test shells without runs, or 2 (and no least total, ``MIN_TENDONS_IN_RUNS``), which
    puts most of their tendons into runs, including runs whose tail and head force slices
    overlap (see ``test_stencil_layout_invariants``)."""
    if request.param is not None:
        monkeypatch.setattr(kernel_module, "MIN_RUN", request.param)
        monkeypatch.setattr(kernel_module, "MIN_TENDONS_IN_RUNS", 0)
    return request.param


@pytest.mark.parametrize("loads", ["none", "gravity", "external", "both"])
@pytest.mark.parametrize("case", CASES)
def test_evaluate_matches_numpy_reference(case, loads, min_run):
    rng = np.random.default_rng(_seed(case, loads))
    structure = _structure(case, rng)
    kernel = CompiledKernel(structure)
    model, data = kernel.records(structure.tendon_rest_length)
    clipped_seen = 0
    for trial in range(4):
        q, qdot = random_consistent_state(structure, rng, speed=[0.5, 2.0, 5.0, 10.0][trial])
        rest, slack = random_rest_lengths(structure, q, rng)
        with_w = loads in ("external", "both")
        w = 20.0 * rng.standard_normal((structure.n_nodes, 3)) if with_w else None
        g = rng.standard_normal(3) * [1, 1, 10] if loads in ("gravity", "both") else None
        ref = dynamics.evaluate(structure, q, qdot, rest_length=rest, external_force=w, gravity=g)
        got = kernel.evaluate(q, qdot, rest, external_force=w, gravity=g)
        # the same evaluation into one data record, twice: the force scratch is left zero for
        # the next evaluation's tendon pass (no pass clears it)
        again = np.empty_like(got.qddot)
        for _ in range(2):
            model, data = kernel.records(rest, w, g)
            data.node_force[:] = 0.0
            system_rhs(model, data, 0, q, qdot, again)
            assert not np.any(data.node_force)
        assert np.array_equal(again, got.qddot)

        assert got.qddot.shape == (structure.n_coordinates,)
        assert _rel(got.qddot, ref.qddot) < TOL, f"trial {trial}: qddot"
        assert _rel(got.tension, ref.tendons.tension) < TOL, f"trial {trial}: tension"
        # Slack tendons are exactly zero in both.
        assert np.all(got.tension[slack] == 0.0) and np.array_equal(
            got.tension == 0.0, ref.tendons.tension == 0.0
        )
        power_scale = abs(ref.dissipated_power) + abs(ref.external_power) + 1.0
        assert abs(got.dissipated_power - ref.dissipated_power) < TOL * power_scale
        assert got.dissipated_power >= 0.0
        assert abs(got.external_power - ref.external_power) < TOL * power_scale
        if w is None:
            assert got.external_power == 0.0
        # Taut tendons whose damping term made the tension negative (clipped to zero).
        taut = np.setdiff1d(np.arange(structure.n_tendons), slack)
        clipped_seen += int(np.sum(got.tension[taut] == 0.0))
    assert clipped_seen > 0, "no taut tendon had its tension clipped: the test lost coverage"


def _undamped(structure: Structure) -> Structure:
    return structure.replace(tendon_damping=np.zeros(structure.n_tendons))


@pytest.mark.parametrize("loads", ["none", "both"])
@pytest.mark.parametrize("case", CASES)
def test_undamped_specialization_matches_reference_and_generic_path(case, loads):
    """All ``c = 0``: ``pack`` selects the specialization without node velocities and length
    rates; it agrees with the reference (1e-12) and bit for bit with the generic (damped) path
    run on explicit zero damping.  One damped tendon selects the generic path."""
    from tensegrity.physics.kernel import pack, rhs

    rng = np.random.default_rng(_seed(case, loads, "undamped"))
    structure = _undamped(_structure(case, rng))
    kernel = CompiledKernel(structure)
    assert kernel.packed.tendon_damping is None and pack(structure).tendon_damping is None
    one_damped = structure.replace(tendon_damping=np.eye(1, structure.n_tendons, 3)[0])
    packed = pack(one_damped)
    assert np.array_equal(packed.tendon_damping, packed.to_kernel_order(one_damped.tendon_damping))
    for trial in range(3):
        q, qdot = random_consistent_state(structure, rng, speed=[0.5, 3.0, 10.0][trial])
        rest, slack = random_rest_lengths(structure, q, rng)
        w = 20.0 * rng.standard_normal((structure.n_nodes, 3)) if loads == "both" else None
        g = np.array([0.3, -1.0, -9.81]) if loads == "both" else None
        ref = dynamics.evaluate(structure, q, qdot, rest_length=rest, external_force=w, gravity=g)
        got = kernel.evaluate(q, qdot, rest, external_force=w, gravity=g)
        assert _rel(got.qddot, ref.qddot) < TOL, f"trial {trial}: qddot"
        assert _rel(got.tension, ref.tendons.tension) < TOL, f"trial {trial}: tension"
        assert np.all(got.tension[slack] == 0.0)
        assert np.all(got.tension[np.setdiff1d(np.arange(structure.n_tendons), slack)] > 0.0)
        scale = abs(ref.dissipated_power) + abs(ref.external_power) + 1.0
        assert abs(got.dissipated_power - ref.dissipated_power) < TOL * scale  # rod damping
        assert abs(got.external_power - ref.external_power) < TOL * scale

        # The generic path on the same structure, forced with an explicit zero damping array.
        qddot = np.empty_like(got.qddot)
        model, data = kernel.records(rest, w, g)
        model = model._replace(tendon_damping=np.zeros(structure.n_tendons))
        generic = rhs(model, data, 0, q, qdot, qddot)
        tension = data.tension[kernel.position]  # kernel order -> tendon order
        assert np.array_equal(qddot, got.qddot) and np.array_equal(tension, got.tension)
        assert generic == (got.dissipated_power, got.external_power)


def test_undamped_rk4_loop_matches_python_rk4():
    rng = np.random.default_rng(_seed(None, "undamped rk4"))
    structure = _undamped(_structure(dict(n=4, m=2), rng))  # rods still damped
    kernel = CompiledKernel(structure)
    q0, qdot0 = random_consistent_state(structure, rng, speed=3.0)
    rest, _ = random_rest_lengths(structure, q0, rng)
    w = 5.0 * rng.standard_normal((structure.n_nodes, 3))
    g = np.array([0.2, -0.4, -9.81])
    got = kernel.rk4_with_work(q0, qdot0, 1e-4, 100, rest, w, g)
    q_ref, qdot_ref, dissipated_ref, work_ref, _ = python_rk4(
        structure, q0, qdot0, 1e-4, 100, rest, w, g
    )
    assert kernel.packed.tendon_damping is None
    assert _rel(got.q, q_ref) < TOL and _rel(got.qdot, qdot_ref) < TOL
    assert dissipated_ref > 0.0  # the rods' damping
    assert abs(got.dissipated_energy - dissipated_ref) < TOL * abs(dissipated_ref)
    assert abs(got.external_work - work_ref) < TOL * (abs(work_ref) + 1e-3)
    assert _rel(got.q, q0) > 1e-6


# --------------------------------------------------------------------------- RK4


def python_rk4(structure, q, qdot, dt, n_steps, rest, w, g):
    """Classical RK4 (``y + h/6 (k1 + 2 k2 + 2 k3 + k4)``) on ``y = [q, q', E_d, W_w]`` with
    ``dynamics.evaluate``, projected onto the rod constraints after every step (as
    ``simulate(method="rk4")``)."""
    n = structure.n_coordinates

    def fun(t, y):
        ev = dynamics.evaluate(
            structure, y[:n], y[n : 2 * n], rest_length=rest, external_force=w, gravity=g
        )
        return np.concatenate([y[n : 2 * n], ev.qddot, [ev.dissipated_power, ev.external_power]])

    y = np.concatenate([q, qdot, [0.0, 0.0]])
    t, worst = 0.0, 0.0
    for _ in range(n_steps):
        k1 = fun(t, y)
        k2 = fun(t + dt / 2, y + dt / 2 * k1)
        k3 = fun(t + dt / 2, y + dt / 2 * k2)
        k4 = fun(t + dt, y + dt * k3)
        t, y = t + dt, y + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        worst = max(worst, float(np.max(np.abs(dynamics.rod_length_error(structure, y[:n])))))
        qp, vp = dynamics.project_to_constraints(structure, y[:n], y[n : 2 * n])
        y = np.concatenate([qp, vp, y[2 * n :]])
    return y[:n], y[n : 2 * n], y[2 * n], y[2 * n + 1], worst


@pytest.mark.parametrize("case", [CASES[0], CASES[1], CASES[2], CASES[3], CASES[5]])
def test_rk4_loop_matches_python_rk4(case, min_run):
    rng = np.random.default_rng(_seed(case, "rk4"))
    structure = _structure(case, rng)
    kernel = CompiledKernel(structure)
    q0, qdot0 = random_consistent_state(structure, rng, speed=3.0)
    rest, _ = random_rest_lengths(structure, q0, rng)
    w = 5.0 * rng.standard_normal((structure.n_nodes, 3))
    g = np.array([0.2, -0.4, -9.81])
    dt, n_steps = 1e-4, 100
    q_in, qdot_in = q0.copy(), qdot0.copy()

    got = kernel.rk4_with_work(q0, qdot0, dt, n_steps, rest, w, g)
    q_ref, qdot_ref, dissipated_ref, work_ref, worst_ref = python_rk4(
        structure, q0, qdot0, dt, n_steps, rest, w, g
    )

    assert np.array_equal(q0, q_in) and np.array_equal(qdot0, qdot_in), "inputs were modified"
    assert _rel(got.q, q_ref) < TOL
    assert _rel(got.qdot, qdot_ref) < TOL
    assert abs(got.dissipated_energy - dissipated_ref) < TOL * (abs(dissipated_ref) + 1e-3)
    assert abs(got.external_work - work_ref) < TOL * (abs(work_ref) + 1e-3)
    assert got.n_steps == n_steps
    assert 0.0 < got.max_rod_length_error and abs(got.max_rod_length_error - worst_ref) < 1e-14
    # It moved, and it stayed on the constraints.
    assert _rel(got.q, q0) > 1e-6
    assert np.max(np.abs(dynamics.rod_length_error(structure, got.q))) < 1e-14
    q2, v2 = dynamics.rods_view(got.q)[:, 1], dynamics.rods_view(got.qdot)[:, 1]
    assert np.max(np.abs(np.sum(q2 * v2, axis=1))) < 1e-12 * np.max(np.abs(got.qdot))
    # rk4() is rk4_with_work() without the energies; split calls continue the same trajectory.
    q_a, qdot_a = kernel.rk4(q0, qdot0, dt, n_steps, rest, w, g)
    assert np.array_equal(q_a, got.q) and np.array_equal(qdot_a, got.qdot)
    q_b, qdot_b = kernel.rk4(*kernel.rk4(q0, qdot0, dt, 40, rest, w, g), dt, 60, rest, w, g)
    assert np.array_equal(q_b, got.q) and np.array_equal(qdot_b, got.qdot)


def test_rk4_stops_on_blow_up():
    """Too large a step stretches the rods: the loop stops after the first step whose rod-length
    error exceeds the limit; a non-finite state stops it at once with error NaN."""
    structure = class1_shell(3, 1, stiffness=1e4)
    kernel = CompiledKernel(structure)
    state = dynamics.initial_state(structure)
    rest = structure.tendon_rest_length
    fine = kernel.rk4_with_work(state.q, state.qdot, 1e-4, 20, rest, max_rod_length_error=1e-3)
    assert fine.n_steps == 20 and fine.max_rod_length_error < 1e-3
    coarse = kernel.rk4_with_work(state.q, state.qdot, 0.05, 20, rest, max_rod_length_error=1e-3)
    assert coarse.n_steps < 20 and coarse.max_rod_length_error > 1e-3
    no_limit = kernel.rk4_with_work(state.q, state.qdot, 0.05, coarse.n_steps, rest)
    assert np.array_equal(no_limit.q, coarse.q)
    bad = state.qdot.copy()
    bad[4] = np.nan
    nan = kernel.rk4_with_work(state.q, bad, 1e-4, 20, rest, max_rod_length_error=1e-3)
    assert nan.n_steps == 1 and np.isnan(nan.max_rod_length_error)
    # NaN in the first rod only: a later rod's finite error must not hide it.
    q_bad = state.q.copy()
    q_bad[3] = np.nan
    assert np.isnan(kernel.project(q_bad, state.qdot)[0][3])
    from tensegrity.physics.kernel import project

    for k in (3, 0):  # in q2, in q2' (first rod)
        q_, qdot_ = state.q.copy(), state.qdot.copy()
        (q_ if k == 3 else qdot_)[3] = np.nan
        assert np.isnan(project(q_, qdot_, kernel.packed.rod_param))


def test_project_matches_reference():
    rng = np.random.default_rng(11)
    structure = random_general_structure(rng)
    q, qdot = random_consistent_state(structure, rng)
    q = q * (1 + 1e-3 * rng.standard_normal(q.size))
    qdot = qdot + rng.standard_normal(q.size)
    expected = dynamics.project_to_constraints(structure, q, qdot)
    got = CompiledKernel(structure).project(q, qdot)
    assert _rel(got[0], expected[0]) < TOL and _rel(got[1], expected[1]) < TOL


def test_import_tensegrity_does_not_import_numba():
    """The kernel is imported lazily: ``import tensegrity`` alone must not pull in numba."""
    import subprocess
    import sys

    code = "import sys, tensegrity; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# --------------------------------------------------------------------------- stencil layout
LAYOUT_CASES = [
    *CASES[:3],
    pytest.param(dict(n=40, m=3), id="shell(40,3)"),
    pytest.param(dict(n=12, m=4, primal=True), id="primal(12,4)"),
    pytest.param(None, id="general"),
]


@pytest.mark.parametrize("case", LAYOUT_CASES)
def test_stencil_layout_invariants(case, min_run):
    """Slots are distinct and in range, the kernel order is a permutation, the runs (pieces of
    at most ``RUN_CHUNK``) tile the start of it and every run's tails and heads are at
    consecutive slots, as ``_tendon_run`` assumes.  The shells' runs include ones whose tails
    and heads are in the same class less than a run apart (overlapping force slices, which the
    compiled loop must not vectorize): those structures are in
    ``test_evaluate_matches_numpy_reference``."""
    rng = np.random.default_rng(_seed(case, "layout"))
    structure = _structure(case, rng)
    tendon_nodes = structure.tendon_nodes.reshape(-1, 2)
    N, S = structure.n_nodes, structure.n_tendons
    layout = stencil_layout(tendon_nodes, N)
    slot = layout.node_slot
    assert np.unique(slot).size == N and slot.min() >= 0 and slot.max() < layout.n_slots
    assert layout.n_slots % layout.node_classes == 0
    assert np.array_equal(np.sort(layout.tendon_order), np.arange(S))
    position = 0
    for start, length, tail, head in layout.tendon_runs:
        assert start == position and 1 <= length <= kernel_module.RUN_CHUNK
        tendons = layout.tendon_order[start : start + length]
        assert np.array_equal(slot[tendon_nodes[tendons, 0]], tail + np.arange(length))
        assert np.array_equal(slot[tendon_nodes[tendons, 1]], head + np.arange(length))
        position += length
    cells = layout.n_slots // layout.node_classes
    runs = layout.tendon_runs
    overlapping = (runs[:, 2] // cells == runs[:, 3] // cells) & (
        np.abs(runs[:, 3] - runs[:, 2]) < runs[:, 1]
    )
    if min_run == 2 and case is not None:
        assert position >= 0.75 * S and overlapping.any()


def test_large_shell_is_nearly_all_runs():
    """The benchmark shell: four node classes (two rods per element) and 99.5% of the tendons in
    runs (docs/performance.md)."""
    structure = class1_shell(100, 100)
    layout = stencil_layout(structure.tendon_nodes, structure.n_nodes)
    assert layout.node_classes == 4
    assert layout.tendon_runs[:, 1].sum() >= 0.99 * structure.n_tendons


def test_long_runs_match_reference():
    """Runs longer than ``kernel.RUN_CHUNK`` are cut into pieces, ordered by cell: the (100,50)
    shell (runs of ~5,000 tendons), damped and undamped, against the reference."""
    rng = np.random.default_rng(_seed(None, "long runs"))
    structure = with_random_parameters(class1_shell(100, 50), rng)
    layout = stencil_layout(structure.tendon_nodes, structure.n_nodes)
    runs = layout.tendon_runs
    assert np.sum(runs[:, 1] == kernel_module.RUN_CHUNK) > 8  # full pieces of long runs
    tail_cell = runs[:, 2] % (layout.n_slots // layout.node_classes)
    assert (
        np.all(np.diff(tail_cell) >= 0)
        and np.unique(runs[:, 2] // (layout.n_slots // layout.node_classes)).size > 1
    )  # pieces interleaved by cell
    q, qdot = random_consistent_state(structure, rng, speed=2.0)
    rest, _ = random_rest_lengths(structure, q, rng)
    for s in (structure, _undamped(structure)):
        ref = dynamics.evaluate(s, q, qdot, rest_length=rest)
        got = CompiledKernel(s).evaluate(q, qdot, rest)
        assert _rel(got.qddot, ref.qddot) < TOL
        assert _rel(got.tension, ref.tendons.tension) < TOL
        assert abs(got.dissipated_power - ref.dissipated_power) < TOL * (
            abs(ref.dissipated_power) + 1.0
        )


def test_a_compiled_only_function_called_from_python_is_a_type_error():
    """The engine's callees compiled without a wrapper for Python (``compiled_only``) refuse a
    call from Python instead of crashing the interpreter, and still serve compiled callers."""
    from tensegrity.engine import compiled

    for function in (compiled.dop853_attempt, compiled.judge_state, compiled.make_inputs):
        with pytest.raises(TypeError, match="called from compiled code only"):
            function(np.zeros(3))
    assert simulate(class1_shell(3, 1, damping=0.3), (0.0, 0.05)).success
