"""The compiled physics of every structure (``tensegrity.physics.kernel_system``) against the NumPy
reference (``dynamics.evaluate``, ``project_to_constraints``, the energies), which shares no code
with it.

Structures: a free class 1 shell (the existing kernel, to its last ulps), free and fixed-base
class 2 shells (joints, fixed rod nodes), a pinned rod, a point mass between anchors, the
crane of docs/python.md (a pinned rod, a tendon to an anchor, a payload joined to its tip),
the hanging chain (a joint to an anchor), a tripod on planes, rods and a point mass on lines, a
rod held at both ends (redundant rows, a singular ``K``) tied to a free one, and planar
structures through ``embed_planar``.
States are off the constraints (positions perturbed), with random velocities, tendon and rod
damping, a third of the tendons slack, gravity and external forces.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

pytest.importorskip("numba")

from tensegrity import Structure, class1_shell
from tensegrity.model.planar import planar_two_rod
from tensegrity.model.shell import class2_shell
from tensegrity.physics import (
    dynamics,
    kernel,
)
from tensegrity.physics.constraints import (
    PROJECTION_FLOOR_RTOL,
    constraints_of,
)
from tensegrity.physics.kernel_system import (
    drop_coordinates,
    embed_planar,
    lift_coordinates,
    make_records,
    pack_system,
    system_energies,
    system_errors,
    system_nodes,
    system_project,
    system_rhs,
)
from test_constraints import hanging_chain, pendulum

TOL = 1e-12
NO_TENDONS = dict(tendon_nodes=np.zeros((0, 2), int), tendon_stiffness=[], tendon_rest_length=[])


# --------------------------------------------------------------------------- structures
def point_mass_between_anchors() -> Structure:
    return Structure(
        node_position=[[-2, 0, 0], [2, 0, 0], [0.1, 0.2, -0.1]],
        rod_nodes=np.zeros((0, 2), int),
        rod_mass=[],
        rod_length=[],
        node_fixed=[True, True, False],
        node_point_mass=[0, 0, 0.3],
        tendon_nodes=[[0, 2], [2, 1]],
        tendon_stiffness=[50.0, 70.0],
        tendon_rest_length=[1.0, 1.0],
    )


def crane() -> Structure:
    """The crane of docs/python.md: a rod pinned at node 0, a tendon to an anchor (node 2), a
    payload (node 3) joined to the rod's tip."""
    return Structure(
        node_position=[[0, 0, 0], [1, 0, 0], [0, 0, 1], [1, 0, 0]],
        rod_nodes=[[0, 1]],
        rod_mass=[1],
        rod_length=[1],
        tendon_nodes=[[1, 2]],
        tendon_stiffness=[500],
        tendon_rest_length=[1.2],
        node_fixed=[True, False, True, False],
        node_point_mass=[0, 0, 0, 0.5],
        joint_nodes=[[1, 3]],
    )


def tripod_on_planes() -> Structure:
    """Three rods joined at the apex (a class 3 joint), feet held on planes (one tilted), a
    tendon triangle between the feet."""
    angles = 2 * np.pi * np.arange(3) / 3
    feet = 0.5 * np.stack([np.cos(angles), np.sin(angles), np.zeros(3)], axis=1)
    apex = np.array([0, 0, np.sqrt(1 - 0.25)])
    return Structure(
        node_position=[feet[0], apex, feet[1], apex, feet[2], apex],
        rod_nodes=[[0, 1], [2, 3], [4, 5]],
        rod_mass=[1.2, 1.0, 0.8],
        rod_length=[1.0] * 3,
        joint_nodes=[[1, 3], [3, 5]],
        plane_nodes=[0, 2, 4],
        plane_normal=[[0, 0, 1.0], [0.2, -0.1, 1.0], [0, 0, 2.0]],
        tendon_nodes=[[0, 2], [2, 4], [4, 0]],
        tendon_stiffness=[80.0] * 3,
        tendon_rest_length=[0.7] * 3,
    )


def on_lines() -> Structure:
    """A rod whose end slides along x, a tendon from its tip to an anchor, and a point mass on
    a skew line tied to the tip and the anchor."""
    return Structure(
        node_position=[[0, 0, 0], [0.6, 0.0, -0.8], [1.0, 1.0, -1.0], [0.3, -0.5, -0.9]],
        rod_nodes=[[0, 1]],
        rod_mass=[1.0],
        rod_length=[1.0],
        node_fixed=[False, False, True, False],
        node_point_mass=[0, 0, 0, 0.4],
        line_nodes=[0, 3],
        line_direction=[[2.0, 0, 0], [1.0, 1.0, 1.0]],
        tendon_nodes=[[1, 2], [3, 1], [2, 3]],
        tendon_stiffness=[40.0, 60.0, 30.0],
        tendon_rest_length=[0.5, 0.3, 0.4],
    )


def held_and_free() -> Structure:
    """A rod with both ends fixed and a redundant plane on one (the axial constraint force has
    no effect: ``K`` is singular), tied by four tendons to a free rod."""
    return Structure(
        node_position=[[0, 0, 0], [1, 0, 0], [0.1, 0.5, 0.3], [0.9, 0.6, 0.2]],
        rod_nodes=[[0, 1], [2, 3]],
        rod_mass=[1.0, 0.7],
        rod_length=[1.0, float(np.linalg.norm([0.8, 0.1, -0.1]))],
        node_fixed=[True, True, False, False],
        plane_nodes=[1],
        plane_normal=[[0, 0, 1.0]],
        tendon_nodes=[[0, 2], [1, 3], [0, 3], [1, 2]],
        tendon_stiffness=[50.0, 60.0, 70.0, 80.0],
        tendon_rest_length=[0.3] * 4,
    )


def planar_supported() -> Structure:
    """Example 2 with a fixed rod node, a node on a line, an anchor and a point mass."""
    base = planar_two_rod(angle=1.2)
    position = np.concatenate([base.node_position, [[1.0, 1.0], [0.8, -0.6]]])
    return Structure(
        node_position=position,
        rod_nodes=base.rod_nodes,
        rod_mass=base.rod_mass,
        rod_length=base.rod_length,
        tendon_nodes=np.concatenate([base.tendon_nodes, [[1, 5], [5, 4]]]),
        tendon_stiffness=np.concatenate([base.tendon_stiffness, [40.0, 30.0]]),
        tendon_rest_length=np.concatenate([base.tendon_rest_length, [0.2, 0.3]]),
        node_fixed=[True, False, False, False, True, False],
        node_point_mass=[0, 0, 0, 0, 0, 0.6],
        line_nodes=[2],
        line_direction=[[1.0, 0.3]],
    )


STRUCTURES = {
    "class1(3,1)": lambda: class1_shell(3, 1),
    "class2(3,2)": lambda: class2_shell(3, 2),
    "class2(4,3) fixed base": lambda: class2_shell(4, 3, fixed_base=True),
    "pinned rod": lambda: pendulum(support="fixed", angle=0.3),
    "point mass": point_mass_between_anchors,
    "crane": crane,
    "hanging chain": lambda: hanging_chain(damped=True),
    "tripod on planes": tripod_on_planes,
    "lines": on_lines,
    "held rod": held_and_free,
    "planar two-rod": lambda: planar_two_rod(angle=1.2),
    "planar supported": planar_supported,
}
CASES = list(STRUCTURES)
CONSTRAINED = [name for name in CASES if STRUCTURES[name]().has_constraints]


def _seed(*key) -> int:
    return zlib.crc32(repr(key).encode())


def randomized(name: str, rng: np.random.Generator, damped: bool = True) -> Structure:
    """The named structure with unequal masses and stiffnesses, and (``damped``) tendon damping
    large enough to clip some tensions and rod damping, to ground and relative to the
    rigid-body motion (which a supported structure applies to ground)."""
    s = STRUCTURES[name]()
    R, S = s.n_rods, s.n_tendons
    return s.replace(
        rod_mass=rng.uniform(0.3, 3.0, R),
        node_point_mass=s.node_point_mass * rng.uniform(0.5, 2.0, s.n_nodes),
        tendon_stiffness=rng.uniform(10.0, 500.0, S),
        tendon_damping=rng.uniform(0.5, 40.0, S) if damped else np.zeros(S),
        rod_damping=rng.uniform(0.1, 5.0, R) if damped else np.zeros(R),
        rod_relative_damping=rng.uniform(0.1, 5.0, R) if damped else np.zeros(R),
    )


#: Structures whose ``K`` is singular (a rod held at both ends: an axial force on it does
#: nothing).  Off the constraints ``-A q''_free`` has a part outside the range of ``K``, which
#: both solvers amplify by ``1/delta`` (``solve_psd``'s regularization) into multipliers whose
#: effect on ``q''`` vanishes only up to round-off (1e-4 relative, measured): the problem is
#: ill-posed there, and these structures are compared on the constraints, where it is not.
SINGULAR = {"held rod"}


def perturbed_state(s: Structure, rng, jitter=0.02, speed=2.0, *, on_constraints=False):
    """``(q, qdot)`` near the layout, off the constraints: positions perturbed, random rates
    (``on_constraints``: then projected by the reference)."""
    q = dynamics.initial_state(s).q
    q, qdot = q + jitter * rng.standard_normal(q.size), speed * rng.standard_normal(q.size)
    return dynamics.project_to_constraints(s, q, qdot) if on_constraints else (q, qdot)


def random_rest(s: Structure, q, rng):
    """Rest lengths with a third of the tendons slack and the rest taut by a random amount."""
    p = dynamics.nodes_from_coordinates(s, q)
    lengths = dynamics.tendon_lengths(s, p)
    rest = lengths * rng.uniform(0.3, 0.98, s.n_tendons)
    slack = rng.permutation(s.n_tendons)[: s.n_tendons // 3]
    rest[slack] = lengths[slack] * rng.uniform(1.02, 1.5, slack.size)
    return rest


def _rel(actual, expected, scale=None) -> float:
    expected = np.asarray(expected)
    if expected.size == 0:
        return 0.0
    scale = np.max(np.abs(expected)) if scale is None else scale
    return float(np.max(np.abs(np.asarray(actual) - expected)) / max(scale, 1e-300))


class Compiled:
    """``pack_system`` of a structure (a planar one embedded), its buffers, and the compiled
    functions called in the structure's own coordinates and tendon order."""

    def __init__(self, structure: Structure) -> None:
        self.structure = structure
        self.planar = structure.dim == 2
        self.system = pack_system(embed_planar(structure) if self.planar else structure)
        self.packed = self.system.packed
        self.model, self.data = self.records(self.structure.tendon_rest_length)

    def records(self, rest, w=None, g=None):
        """The records with rest lengths ``rest`` (S,), nodal forces ``w`` (N, dim) and gravity
        ``g`` (dim,), or NaN where they are absent: not to be read without ``has_external`` /
        ``has_gravity`` (NaN would show)."""
        has_w, has_g = w is not None, g is not None
        p = self.packed
        model, data = make_records(
            self.system,
            rest=p.to_kernel_order(np.asarray(rest, dtype=float))[None],
            force=p.to_slots(self.nodes3(w))[None] if has_w else None,
            gravity=np.pad(np.asarray(g, float), (0, 3 - len(g))) if has_g else None,
        )
        if not has_w:
            data = data._replace(force=np.full((1, 3, 1), np.nan))
        if not has_g:
            model = model._replace(gravity=np.full(3, np.nan))
        return model, data

    def lift(self, x):
        return lift_coordinates(self.structure, x) if self.planar else np.array(x, dtype=float)

    def drop(self, x):
        return drop_coordinates(self.structure, x) if self.planar else x

    def nodes3(self, values):
        values = np.asarray(values, dtype=float)
        return np.pad(values, ((0, 0), (0, 3 - values.shape[1])))

    def structure_order(self, values):
        out = np.empty_like(values)
        out[self.packed.layout.tendon_order] = values
        return out

    def rhs(self, q, qdot, rest, w=None, g=None):
        """``(qddot (lifted), tension, elastic_tension, dissipated, external)``."""
        model, data = self.records(rest, w, g)
        self.data = data
        qddot = np.full(self.system.n_coordinates, np.nan)
        d, e = system_rhs(model, data, 0, self.lift(q), self.lift(qdot), qddot)
        tension, elastic = data.tension, data.elastic_tension
        return (qddot, self.structure_order(tension), self.structure_order(elastic), d, e)


# --------------------------------------------------------------------------- rhs
@pytest.mark.parametrize("damped", [True, False], ids=["damped", "undamped"])
@pytest.mark.parametrize("loads", ["none", "both"])
@pytest.mark.parametrize("name", CASES)
def test_rhs_matches_numpy_reference(name, loads, damped):
    rng = np.random.default_rng(_seed(name, loads, damped))
    s = randomized(name, rng, damped)
    compiled = Compiled(s)
    free = name in ("class1(3,1)", "planar two-rod")  # (embedded: a free 3-D class 1 structure)
    assert (compiled.system.constraints is None) == free
    assert (compiled.packed.tendon_damping is None) == (not damped or s.n_tendons == 0)
    for trial in range(3):
        q, qdot = perturbed_state(
            s, rng, speed=[0.5, 2.0, 6.0][trial], on_constraints=name in SINGULAR
        )
        rest = random_rest(s, q, rng)
        w = 20.0 * rng.standard_normal((s.n_nodes, s.dim)) if loads == "both" else None
        g = rng.standard_normal(s.dim) * 5 if loads == "both" else None
        ref = dynamics.evaluate(s, q, qdot, rest_length=rest, external_force=w, gravity=g)
        qddot, tension, elastic, dissipated, external = compiled.rhs(q, qdot, rest, w, g)

        assert _rel(compiled.drop(qddot), ref.qddot) < TOL, f"trial {trial}: qddot"
        assert _rel(tension, ref.tendons.tension) < TOL, f"trial {trial}: tension"
        assert _rel(elastic, ref.tendons.elastic_tension) < TOL, f"trial {trial}: elastic"
        scale = abs(ref.dissipated_power) + abs(ref.external_power) + 1.0
        assert abs(dissipated - ref.dissipated_power) < TOL * scale
        assert abs(external - ref.external_power) < TOL * scale
        if w is None:
            assert external == 0.0
        if compiled.planar:  # no force out of the plane: z accelerations exactly 0
            assert np.all(qddot.reshape(-1, 3)[:, 2] == 0.0)
        # kernel.rhs's contract: the force scratch is left zero (anchors and point masses too)
        assert not np.any(compiled.data.node_force)
        if s.has_constraints:  # the constraint forces are really there
            accel = np.max(np.abs(ref.qddot))
            assert np.max(np.abs(constraints_of(s).matrix @ ref.qddot)) < 1e-9 * accel
            free = ref.qddot - dynamics.force_response(s, q, ref.constraint_force)
            assert _rel(compiled.drop(qddot), free) > 1e-6


#: Units in the last place by which two compiled copies of the same code may differ: numba links
#: every entry point with copies of its callees of its own, each optimised in its caller's
#: context, and with ``fastmath={"contract"}`` a copy may fuse ``a * b + c`` where another does
#: not; which copy a call reaches depends on which library was loaded first (measured: with a
#: simulation's entry points loaded from the cache first, system_rhs was 1 ulp off kernel.rhs in
#: 2 of 36 accelerations; with the two loaded first, bit for bit).
COPIES_ULP = 4


def _same_code(got, expected):
    np.testing.assert_array_max_ulp(np.asarray(got), np.asarray(expected), maxulp=COPIES_ULP)


def test_free_class1_is_the_existing_kernel():
    """``model.constraints`` None: system_rhs, system_project, system_energies and
    system_errors give kernel.rhs's, kernel.project's and kernel.energies's numbers (the same
    code; to the last ulps of :data:`COPIES_ULP`)."""
    for damped in (True, False):
        rng = np.random.default_rng(_seed("bitwise", damped))
        s = randomized("class1(3,1)", rng, damped)
        compiled = Compiled(s)
        p = compiled.packed
        assert compiled.system.constraints is None
        assert compiled.system.n_coordinates == s.n_coordinates
        q, qdot = perturbed_state(s, rng)
        rest = random_rest(s, q, rng)
        w, g = rng.standard_normal((s.n_nodes, 3)), np.array([0.3, -0.2, -9.81])
        records = [compiled.records(rest, w, g) for _ in range(2)]
        n = s.n_coordinates
        qddots = [np.empty(n), np.empty(n)]
        got = system_rhs(*records[0], 0, q, qdot, qddots[0])
        expected = kernel.rhs(*records[1], 0, q, qdot, qddots[1])
        _same_code(got, expected)
        _same_code(qddots[0], qddots[1])
        for field in ("tension", "elastic_tension", "damping_power"):
            _same_code(getattr(records[0][1], field), getattr(records[1][1], field))
        assert not np.any(records[0][1].node_force)

        kernel_rest = records[0][1].rest[0]
        energy = system_energies(*records[0], kernel_rest, q, qdot)
        _same_code(energy, kernel.energies(*records[1], kernel_rest, q, qdot))
        states = [(q.copy(), qdot.copy()) for _ in range(2)]
        rod_error, constraint_error, ok = system_project(*records[0], *states[0])
        _same_code(rod_error, kernel.project(*states[1], p.rod_param))
        assert ok and constraint_error == 0.0
        _same_code(states[0][0], states[1][0])
        _same_code(states[0][1], states[1][1])
        assert system_errors(*records[0], q) == (rod_error, 0.0)


# --------------------------------------------------------------------------- projection
@pytest.mark.parametrize("name", CASES)
def test_projection_matches_reference(name):
    rng = np.random.default_rng(_seed(name, "project"))
    s = randomized(name, rng)
    compiled = Compiled(s)
    records = compiled.model, compiled.data
    floor = PROJECTION_FLOOR_RTOL * max(float(s.rod_length.max(initial=0.0)), 1.0)
    for jitter in (1e-3, 3e-2):
        q, qdot = perturbed_state(s, rng, jitter=jitter)
        ref_q, ref_qdot = dynamics.project_to_constraints(s, q, qdot)
        got_q, got_qdot = compiled.lift(q), compiled.lift(qdot)
        before = system_errors(*records, got_q)
        rod_error, constraint_error, ok = system_project(*records, got_q, got_qdot)
        assert ok
        assert (rod_error, constraint_error) == before
        rod_ref = np.max(np.abs(dynamics.rod_length_error(s, q)), initial=0.0)
        assert abs(rod_error - rod_ref) < 1e-14
        assert abs(constraint_error - dynamics.constraint_error(s, q)) < 1e-14
        assert _rel(compiled.drop(got_q), ref_q) < TOL
        assert _rel(compiled.drop(got_qdot), ref_qdot) < TOL
        if compiled.planar:
            assert np.all(got_q.reshape(-1, 3)[:, 2] == 0.0)
            assert np.all(got_qdot.reshape(-1, 3)[:, 2] == 0.0)
        # on the constraints, to the projection's tolerance
        q_2d, qdot_2d = compiled.drop(got_q), compiled.drop(got_qdot)
        rods_after, constraints_after = system_errors(*records, got_q)
        assert np.all(np.abs(dynamics.rod_length_error(s, q_2d)) * s.rod_length <= floor)
        assert rods_after <= floor and constraints_after <= floor
        assert dynamics.constraint_error(s, q_2d) <= floor
        v_scale = np.max(np.abs(qdot))
        rods_q, rods_v = (
            dynamics.rod_coordinates(s, q_2d)[:, 1],
            dynamics.rod_coordinates(s, qdot_2d)[:, 1],
        )
        assert np.max(np.abs(np.sum(rods_q * rods_v, axis=-1)), initial=0.0) < TOL * v_scale
        if s.has_constraints:
            assert np.max(np.abs(constraints_of(s).matrix @ qdot_2d)) < TOL * v_scale
        # a state on the constraints is (nearly) a fixed point
        again_q, again_qdot = got_q.copy(), got_qdot.copy()
        assert system_project(*records, again_q, again_qdot)[2]
        assert _rel(again_q, got_q) < TOL and _rel(again_qdot, got_qdot) < TOL


@pytest.mark.parametrize("name", ["class1(3,1)", "point mass", "crane", "class2(3,2)"])
def test_projection_reports_a_non_finite_state(name):
    s = STRUCTURES[name]()
    compiled = Compiled(s)
    state = dynamics.initial_state(s)
    for where, value in ((0, np.nan), (1, np.inf)):
        q, qdot = state.q.copy(), state.qdot.copy()
        (q if where == 0 else qdot)[-1] = value
        rod_error, _, ok = system_project(compiled.model, compiled.data, q, qdot)
        assert not ok
        if s.n_rods and where == 0 and s.is_free_class1:
            assert np.isnan(rod_error)
    q = state.q.copy()
    if s.n_rods:
        q[3] = np.nan
        assert np.isnan(system_errors(compiled.model, compiled.data, q)[0])
    if s.has_constraints:
        q = state.q.copy()
        q[0] = np.nan
        assert np.isnan(system_errors(compiled.model, compiled.data, q)[1])


# --------------------------------------------------------------------------- energies, nodes
@pytest.mark.parametrize("name", CASES)
def test_energies_errors_and_nodes_match_reference(name):
    rng = np.random.default_rng(_seed(name, "energy"))
    s = randomized(name, rng)
    compiled = Compiled(s)
    p = compiled.packed
    for with_gravity in (True, False):
        q, qdot = perturbed_state(s, rng, jitter=0.05)
        rest = random_rest(s, q, rng)
        g = rng.standard_normal(s.dim) * 5
        model, data = compiled.records(rest, g=g if with_gravity else None)
        kinetic, elastic, potential = system_energies(
            model, data, data.rest[0], compiled.lift(q), compiled.lift(qdot)
        )
        nodes = dynamics.nodes_from_coordinates(s, q)
        expected = (
            dynamics.kinetic_energy(s, qdot),
            dynamics.elastic_energy(s, nodes, rest),
            dynamics.gravity_energy(s, q, g if with_gravity else None),
        )
        scale = sum(abs(x) for x in expected) + 1e-300
        for got, want in zip((kinetic, elastic, potential), expected, strict=True):
            assert abs(got - want) < TOL * scale
        assert not np.any(data.node_force)

        rod_error, constraint_error = system_errors(model, data, compiled.lift(q))
        assert abs(rod_error - np.max(np.abs(dynamics.rod_length_error(s, q)), initial=0.0)) < 1e-15
        assert abs(constraint_error - dynamics.constraint_error(s, q)) < 1e-14
        if s.has_constraints:
            assert constraint_error > 1e-4  # the perturbation is seen

        positions, velocities = (np.full((3, p.layout.n_slots), np.nan) for _ in range(2))
        system_nodes(model, compiled.lift(q), compiled.lift(qdot), positions, velocities, True)
        slot = p.layout.node_slot
        assert np.array_equal(positions[:, slot].T, compiled.nodes3(nodes))
        rates = compiled.nodes3(dynamics.nodes_from_coordinates(s, qdot, rates=True))
        assert np.array_equal(velocities[:, slot].T, rates)
        untouched = np.full((3, p.layout.n_slots), 7.0)
        system_nodes(model, compiled.lift(q), compiled.lift(qdot), positions, untouched, False)
        assert np.all(untouched == 7.0)


# --------------------------------------------------------------------------- packing, planar
def test_planar_embedding_and_coordinates():
    s = planar_supported()
    lifted = embed_planar(s)
    assert lifted.dim == 3 and np.array_equal(lifted.node_position[:, :2], s.node_position)
    assert np.all(lifted.node_position[:, 2] == 0) and np.all(lifted.line_direction[:, 2] == 0)
    assert np.array_equal(lifted.joint_nodes, s.joint_nodes)
    assert np.array_equal(lifted.node_fixed, s.node_fixed)
    assert np.array_equal(lifted.node_point_mass, s.node_point_mass)
    assert lifted.tendon_name == s.tendon_name
    rng = np.random.default_rng(3)
    x = rng.standard_normal((5, s.n_coordinates))
    up = lift_coordinates(s, x)
    assert up.shape == (5, lifted.n_coordinates) and np.all(up.reshape(5, -1, 3)[..., 2] == 0)
    assert np.array_equal(drop_coordinates(s, up), x)
    # the lifted coordinates are the embedded structure's: same nodes
    np.testing.assert_array_equal(
        dynamics.nodes_from_coordinates(lifted, up[0])[:, :2],
        dynamics.nodes_from_coordinates(s, x[0]),
    )
    # the reference itself agrees between the two forms (what the kernel tests rely on)
    q, qdot = perturbed_state(s, rng)
    rest = random_rest(s, q, rng)
    flat = dynamics.evaluate(s, q, qdot, rest_length=rest, gravity=np.array([0.5, -9.81]))
    deep = dynamics.evaluate(
        lifted,
        lift_coordinates(s, q),
        lift_coordinates(s, qdot),
        rest_length=rest,
        gravity=np.array([0.5, -9.81, 0.0]),
    )
    assert _rel(drop_coordinates(s, deep.qddot), flat.qddot) < 1e-10


def test_packing_rejects_wrong_dimensions():
    with pytest.raises(ValueError, match=r"^structure: "):
        pack_system(planar_two_rod())
    with pytest.raises(ValueError, match=r"^structure: "):
        embed_planar(class1_shell(3, 1))
    with pytest.raises(ValueError, match=r"^structure: "):
        kernel.pack(planar_two_rod(), general=True)
    with pytest.raises(ValueError, match=r"^the compiled kernel: supports only free 3-D class 1"):
        kernel.pack(crane())
    with pytest.raises(ValueError, match=r"^x: "):
        lift_coordinates(planar_two_rod(), np.zeros(5))
    with pytest.raises(ValueError, match=r"^structure2d: "):
        lift_coordinates(class1_shell(3, 1), np.zeros(12))


def test_constraint_rows_are_the_references():
    """The packed rows are ``LinearConstraints``'s independent rows (a redundant plane dropped),
    and every row touches at most two nodes."""
    for name in CONSTRAINED:
        s = STRUCTURES[name]()
        s3 = embed_planar(s) if s.dim == 2 else s
        constraints = pack_system(s3).constraints
        c = constraints_of(s3).matrix.shape[0]
        assert constraints.constraint_rhs.shape == (c,)
        assert np.bincount(constraints.entry_row, minlength=c).max() <= 2
        assert sorted(constraints.constraint_rhs) == pytest.approx(
            sorted(constraints_of(s3).rhs), abs=1e-15
        )
    assert pack_system(held_and_free()).constraints.constraint_rhs.size == 6
