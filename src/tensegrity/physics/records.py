"""The two records every compiled function of the engine takes: a read-only :class:`Model` (the
packed structure, its parameters, gravity, the input tables, the limits) and a mutable
:class:`Data` (the inputs' rows at the stages of a step, and the scratch the evaluations write),
as MuJoCo passes ``(m, d)``.

Compiled code reads them by field name (``model.tendon_stiffness[s]``, ``data.tension[s]``);
numba compiles a record as a struct, so reading a field costs nothing.  A new parameter of the
physics (a tendon's, a rod's, a contact's) is one field here, filled where the records are made
(:func:`tensegrity.physics.kernel_system.make_records`), and read where it acts.

Optional parts are ``None`` (tendon damping when every ``c`` is 0, the constraints of a free
class 1 structure, the tables of constant inputs): numba compiles a separate specialization for
each, with the absent part's code left out.  Compiled code tests such a field by passing it as an
argument to a function of its own (``_pass(model.tendon_damping, model, data)``), where numba
can decide ``x is None`` at compile time; a field read inside a function cannot be tested so.

Shapes: ``R`` rods, ``S`` tendons, ``M`` point masses, ``n_slots`` node slots of the kernel
layout (:func:`tensegrity.physics.kernel.stencil_layout`), ``K`` stage rows (1 when the inputs
are constant over a step).  Tendon arrays are in *kernel order*, node arrays by coordinate and
slot (:class:`tensegrity.physics.kernel.PackedStructure`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

__all__ = [
    "Actuation",
    "ConstraintWork",
    "Constraints",
    "ContactWork",
    "Contacts",
    "Data",
    "FeedbackLaw",
    "Model",
]


class Constraints(NamedTuple):
    """What a structure has beyond free rods and tendons (read-only; ``Model.constraints``).

    Bodies are the rods ``0..R-1`` then the point masses ``R..R+M-1``.  A constraint row's
    *entries* are its nodes on bodies (anchors are in ``constraint_rhs``), grouped by body.  Rows
    are numbered in the reverse Cuthill-McKee order of the projection rows (constraint rows and
    one rod-length row per rod), which keeps the envelopes of ``K`` and ``J W^-1 J^T`` narrow
    (:mod:`tensegrity.physics.kernel_system`).
    """

    mass_slots: np.ndarray  #: (M,) uint64: slots of the point masses
    point_mass: np.ndarray  #: (M,) float64: their masses [kg]
    anchor_slots: np.ndarray  #: (F,) uint64: slots of the anchors
    anchor_position: np.ndarray  #: (3, F) float64: anchor positions [m]
    body_start: np.ndarray  #: (R + M + 1,) int64: entries of body k are body_start[k]:[k + 1]
    entry_row: np.ndarray  #: (E,) int64: constraint row of each entry (0..c-1)
    entry_sign: np.ndarray  #: (E,) float64: -1 at a rod's end a, +1 at end b, 0 (point mass)
    entry_coef: np.ndarray  #: (E, 3) float64: the row's coefficients ``A_n`` at that node
    constraint_rhs: np.ndarray  #: (c,) float64: ``b`` [m] (anchor terms included)
    constraint_prow: np.ndarray  #: (c,) int64: projection row of each constraint row
    rod_prow: np.ndarray  #: (R,) int64: projection row of each rod's length (if c > 0)
    k_first: np.ndarray  #: (c,) int64: first column of each row's envelope in K
    k_offset: np.ndarray  #: (c + 1,) int64: start of each row's envelope in the values
    n_first: np.ndarray  #: (P,) int64: the same for ``J W^-1 J^T`` (P = c + R, or 0 if c = 0)
    n_offset: np.ndarray  #: (P + 1,) int64


class ConstraintWork(NamedTuple):
    """Scratch of the joint and support forces and of the projection (``Data.constraint_work``;
    written by every call)."""

    k_values: np.ndarray  #: K's lower envelope
    k_factor: np.ndarray  #: its Cholesky factor
    n_values: np.ndarray  #: ``J W^-1 J^T``'s lower envelope
    n_factor: np.ndarray  #: its Cholesky factor
    vectors: np.ndarray  #: (4, max(P, 1)) vectors


class Contacts(NamedTuple):
    """Rigid planes the rods' ends and the point masses touch (read-only; ``Model.contacts``;
    the physics in :mod:`tensegrity.physics.contact`).  Contact point ``c < 2R`` is end ``c %
    2`` (a, b) of rod ``c // 2``, the next ``M`` the point masses; pair ``k = c P + p`` is
    point ``c`` against plane ``p``."""

    plane_point: np.ndarray  #: (P, 3) a point of each plane [m]
    plane_normal: np.ndarray  #: (P, 3) unit normals, out of the solid
    plane_tangent: np.ndarray  #: (P, 2, 3) unit tangents
    friction_static: np.ndarray  #: (P,) mu_s
    friction_kinetic: np.ndarray  #: (P,) mu_k
    contact_stiffness: np.ndarray  #: (P,) k [N/m]
    contact_damping: np.ndarray  #: (P,) c [N s/m]
    point_radius: np.ndarray  #: (C,) radius of each contact point [m]
    point_rod: np.ndarray  #: (C,) int64: the rod of a rod's end, -1 for a point mass
    point_offset: np.ndarray  #: (C,) int64: a point mass's first coordinate in q (6R + 3j)
    point_slot: np.ndarray  #: (C,) uint64: the point's node slot (its forces)
    point_mass: np.ndarray  #: (C,) a point mass's mass [kg] (0 for a rod's end)


class ContactWork(NamedTuple):
    """The contacts' modes and what an evaluation writes of them (``Data.contact_work``);
    ``CP`` pairs (:class:`Contacts`)."""

    mode: np.ndarray  #: (CP,) int64: ``contact.FREE``, ``SLIP`` or ``STICK``
    slip_direction: np.ndarray  #: (CP, 3) the sliding direction a slip started in
    normal_force: np.ndarray  #: (CP,) F_n [N]
    friction_force: np.ndarray  #: (CP, 3) the tangential force on the point [N]
    indicator: np.ndarray  #: (2 CP,) the events' indicators (contact, friction) per pair
    #: (B, 4) the modes' changes since the loop last took them: time [s], pair, mode before,
    #: mode after (``tensegrity.engine.events.log_changes``)
    log: np.ndarray
    log_count: np.ndarray  #: (1,) int64: rows of ``log`` written


class FeedbackLaw(NamedTuple):
    """Linear output feedback ``u = u_ref - K (y - y_ref)`` run by compiled code every
    ``period`` (read-only; ``Model.feedback``; :mod:`tensegrity.engine.actuation`).  ``A``
    actuated tendons (``Data.actuation``), ``Y`` outputs, ``N`` nodes."""

    gain: np.ndarray  #: (A, Y) ``K``
    output_ref: np.ndarray  #: (Y,) ``y_ref``
    control_ref: np.ndarray  #: (A,) ``u_ref`` [m]
    #: (4,) bool: which output groups ``y`` stacks (position, velocity, length, tension)
    groups: np.ndarray
    node_slot: np.ndarray  #: (N,) int64: each node's slot
    dim: int  #: coordinates per node in ``y`` (2 for a planar structure)
    tendon_position: np.ndarray  #: (S,) int64: each tendon's position in kernel order
    schedule: np.ndarray  #: (2,) float64: the first update's time [s] and the period [s]


class Actuation(NamedTuple):
    """The actuated tendons and the command they follow (``Data.actuation``;
    :mod:`tensegrity.engine.actuation`, :mod:`tensegrity.model.actuators`).  ``A`` actuators;
    the limits are read-only, the last arrays are the held command that updates write, and the
    log of updates (``L`` rows of ``1 + 2 A``: time [s], the commands after the bounds [m], the
    controls applied at that time [m])."""

    position: np.ndarray  #: (A,) int64: the actuated tendons' positions in kernel order
    rest0: np.ndarray  #: (A,) their rest lengths ``L0`` [m]
    low: np.ndarray  #: (A,) the smallest command ``u`` the rest-length bounds admit [m]
    high: np.ndarray  #: (A,) the largest [m]
    max_rate: np.ndarray  #: (A,) [m/s] (inf: none)
    time_constant: np.ndarray  #: (A,) [s] (0: none)
    start: np.ndarray  #: (1,) the last command's time [s]
    applied: np.ndarray  #: (A,) the control at ``start`` [m]
    command: np.ndarray  #: (A,) the command held since ``start`` [m]
    updates: (
        np.ndarray
    )  #: (1,) int64: updates so far (the next is due at schedule[0] + updates * period)
    log: np.ndarray  #: (L, 1 + 2 A) the updates not yet taken by Python
    log_count: np.ndarray  #: (1,) int64: rows of ``log`` written
    proposed: np.ndarray  #: (A,) scratch: a command before it is held
    outputs: np.ndarray  #: (Y,) scratch: the outputs a feedback law read
    state: np.ndarray  #: (m,) scratch: a state's derivative


class Model(NamedTuple):
    """The read-only record: a structure packed for compiled code, with what a run holds
    constant (gravity, the input tables, the limits)."""

    rod_slots: np.ndarray  #: (R, 2) uint64: slots of each rod's end nodes (a, b)
    #: (R, 6) float64: m [kg], L [m], alpha [1/s], 2/m, 6/(m L^2), beta [1/s]
    #: (columns ``kernel.ROD_*``)
    rod_param: np.ndarray
    tendon_slots: np.ndarray  #: (S, 2) uint64: slots of (tail, head)
    #: (G, 4) int64: runs of the kernel order (first position, length, tail slot, head slot)
    tendon_runs: np.ndarray
    tendon_stiffness: np.ndarray  #: (S,) float64: k [N/m]
    tendon_damping: np.ndarray | None  #: (S,) float64: c [N s/m]; None when every c is 0
    constraints: Constraints | None  #: None for a free class 1 structure
    has_gravity: bool
    gravity: np.ndarray  #: (3,) float64 [m/s^2] (read if ``has_gravity``)
    #: the engine's input tables (``tensegrity.engine.compiled.fill_stage_inputs``), or None
    tables: Any
    #: None, or the handle (int64) by which compiled code asks Python for inputs that are Python
    #: functions of time (``tensegrity.engine.compiled.make_inputs``)
    callback: Any
    #: (3,) float64: max relative rod-length error, max constraint error [m], max energy growth
    limits: np.ndarray
    contacts: Contacts | None = None  #: planes the rods' ends touch; None: none
    feedback: FeedbackLaw | None = None  #: linear feedback run by compiled code; None: none
    #: (S,) float64: the tendons' tension caps [N] (an actuator's winch; inf: none); None when
    #: no tendon has one
    tendon_max_tension: np.ndarray | None = None


class Data(NamedTuple):
    """The mutable record: the inputs' rows at the stages of a step, and scratch.

    Row ``s`` of the inputs is the stage ``s`` of a step, or row 0 for all stages when the
    array has one row (inputs constant over the step).  After an evaluation ``tension`` and
    ``elastic_tension`` hold that state's values.
    """

    rest: np.ndarray  #: (K, S) rest lengths ``Lbar = L0 - u`` [m]
    rate: np.ndarray  #: (K, S) control rates ``du/dt`` [m/s] (read if ``has_rate``)
    has_rate: bool
    force: np.ndarray  #: (K, 3, n_slots) external nodal forces [N] (read if ``has_external``)
    has_external: bool
    node_position: np.ndarray  #: (3, n_slots) scratch [m]
    #: (3, n_slots) scratch [m/s] (written only with tendon damping)
    node_velocity: np.ndarray
    #: (3, n_slots) tendon forces [N]: zero on entry to an evaluation, and left zero
    node_force: np.ndarray
    tension: np.ndarray  #: (S,) [N]
    elastic_tension: np.ndarray  #: (S,) ``k (l - Lbar)`` while taut [N]
    damping_power: np.ndarray  #: (S,) power removed by each tendon's damping [W]
    constraint_work: ConstraintWork | None  #: None when ``Model.constraints`` is None
    #: (4,) the blow-up monitor: energy at the start [J], largest energy scale [J], largest rod
    #: error, largest constraint error [m]
    monitor: np.ndarray
    contact_work: ContactWork | None = None  #: None when ``Model.contacts`` is None
    actuation: Actuation | None = None  #: the actuated tendons; None: no actuators
