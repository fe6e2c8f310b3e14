"""A structure and its inputs as the compiled engine takes them (:class:`CompiledSystem`): the
packed arrays, the scratch buffers, and the maps between the structure's order (tendons, nodes,
2-D coordinates of a planar structure) and the kernel's (tendons in kernel order, nodes by slot,
always 3-D: a planar structure is simulated embedded at ``z = 0``, where it stays exactly)."""

from __future__ import annotations

import itertools
import weakref
from collections.abc import Callable

import numpy as np

from tensegrity.engine import compiled
from tensegrity.engine.actuation import (
    actuate,
    clip_command,
    controlled_actuators,
    pack_actuation,
    pack_feedback,
)
from tensegrity.engine.feedback import LinearFeedback
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.result import Samples
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics
from tensegrity.physics.contact import pack_contacts
from tensegrity.physics.kernel_system import (
    drop_coordinates,
    embed_planar,
    lift_coordinates,
    make_records,
    pack_system,
    system_nodes,
    system_project,
)
from tensegrity.physics.records import Actuation, Data


def _weakly(method: weakref.WeakMethod) -> Callable[[np.ndarray], int]:
    """A callback calling ``method`` without keeping its object alive."""

    def call(times: np.ndarray) -> int:
        bound = method()
        assert bound is not None, "the system of this input callback is gone"
        return bound(times)

    return call


#: Handles of the input callbacks (``Model.callback``), one per system that needs one.
_HANDLES = itertools.count()


class CompiledSystem:
    """``structure`` with ``inputs``, packed for :mod:`tensegrity.engine.compiled`: the two
    records every compiled function takes, :attr:`model` (read-only) and :attr:`data`
    (mutable; :mod:`tensegrity.physics.records`).

    ``y`` vectors are the engine's ODE state ``[q, q', E_d, W_w, W_u]`` in 3-D coordinates
    (length ``m = 2n + 3``).  ``limits`` = ``(max_rod_length_error, max_constraint_error [m],
    max_energy_growth)``, the blow-up checks' (``Model.limits``).  ``feedback``: a linear law
    compiled code runs every ``feedback.period`` from ``t0`` [s] (``Model.feedback``), through
    the inputs' actuators (default: actuators on its tendons without limits); ``controlled``:
    a controller's commands drive the run (default: actuators on every tendon without limits).
    With actuators (:attr:`actuators`) the actuated tendons follow the commands held by
    :meth:`command`.
    """

    def __init__(
        self,
        structure: Structure,
        inputs: Inputs,
        *,
        limits: tuple[float, float, float] = (np.inf, np.inf, np.inf),
        feedback: LinearFeedback | None = None,
        t0: float = 0.0,
        controlled: bool = False,
    ) -> None:
        self.structure, self.inputs = structure, inputs
        self.planar = structure.dim == 2
        spatial = embed_planar(structure) if self.planar else structure
        packed_system = pack_system(spatial)
        packed = self.packed = packed_system.packed
        self.n = packed_system.n_coordinates
        self.m = 2 * self.n + 3
        S, n_slots = structure.n_tendons, packed.layout.n_slots
        gravity = None if inputs.gravity is None else self._spatial(inputs.gravity)
        rest0 = packed.to_kernel_order(structure.tendon_rest_length)[None]
        contacts = None
        if inputs.ground:
            constraints = packed_system.constraints
            if constraints is not None and constraints.constraint_rhs.size:
                raise ValueError(
                    "ground: contact is for structures without joints or supports (rods, "
                    "tendons, point masses and anchors) for now"
                )
            slot = packed.layout.node_slot
            masses = structure.point_mass_nodes
            contacts = pack_contacts(
                inputs.ground,
                inputs.contact_radius,
                slot[structure.rod_nodes],
                slot[masses],
                structure.node_point_mass[masses],
            )
        self.model, self.data = make_records(
            packed_system, rest=rest0, gravity=gravity, limits=limits, contacts=contacts
        )
        tendon_position = np.argsort(packed.layout.tendon_order)
        self.actuators = controlled_actuators(
            structure, inputs.actuators, feedback=feedback, controlled=controlled
        )
        if feedback is not None:
            self.model = self.model._replace(
                feedback=pack_feedback(
                    structure, feedback, tendon_position, packed.layout.node_slot, t0
                )
            )
        if self.actuators is not None and np.any(np.isfinite(self.actuators.max_tension)):
            caps = np.full(S, np.inf)
            caps[tendon_position[self.actuators.tendons]] = self.actuators.max_tension
            self.model = self.model._replace(tendon_max_tension=caps)
        if self.actuators is not None:
            outputs = 0 if feedback is None else feedback.y_ref.size
            actuation = pack_actuation(
                structure, self.actuators, tendon_position, outputs=outputs, state=self.m
            )
            self.data = self.data._replace(actuation=actuation)
        #: the blow-up monitor (4,), ``data.monitor`` (see :func:`compiled.check_state`)
        self.monitor = self.data.monitor
        self.tendon_position = tendon_position
        slot = packed.layout.node_slot
        self.moving_slots = np.ascontiguousarray(
            np.concatenate(
                [slot[spatial.rod_nodes.ravel()], slot[spatial.point_mass_nodes]]
            ).astype(np.uint64)
        )
        self.node_slot = slot
        #: what the last input callback failed with (:meth:`raise_input_error`), or None
        self.input_error: BaseException | None = None
        self._handle: int | None = None
        self._control_log: list[np.ndarray] = []
        #: scratch node arrays (3, n_slots): positions, velocities
        self.scratch_p, self.scratch_v = np.zeros((3, n_slots)), np.zeros((3, n_slots))
        self._sample_scratch = (np.empty(self.m), *(np.zeros((3, n_slots)) for _ in range(3)),
                                np.zeros(S), self.moving_slots)  # fmt: skip
        kept = np.arange(self.n)
        if self.planar:
            kept = kept[kept % 3 != 2]
        self._sample_maps = (kept, slot.astype(np.int64), self.tendon_position)
        self._prepare_inputs()

    def sensitivity_layout(self, rows: list[np.ndarray]) -> np.ndarray:
        """Sensitivities ``dy/dp`` (P, m) of the samples as (T, P, 2 n) ``[dq/dp, dq'/dp]`` in
        the layout of the results' ``q`` (a planar structure's 2-D coordinates)."""
        kept = self._sample_maps[0]
        S = np.array(rows).reshape(len(rows), -1, self.m)
        return np.concatenate([S[..., kept], S[..., self.n + kept]], axis=-1)

    # ------------------------------------------------------------------ inputs
    def _prepare_inputs(self) -> None:
        """What :meth:`stage_inputs` reuses: the data record if every input is constant; with
        tables (and constants, no callable) the compiled tables (``model.tables``); with a
        Python function among the inputs the callback compiled code calls
        (``model.callback``, :meth:`_make_inputs`)."""
        inputs, packed = self.inputs, self.packed
        self._constant: Data | None = None
        self._buffers: dict[int, Data] = {}
        self.model = self.model._replace(tables=None, callback=None)
        if self.constant:
            self._constant = self._numpy_inputs(np.zeros(1))
            return
        control, force = inputs.control, inputs.external_force
        if control.kind == "function" or force.kind == "function":
            self.model = self.model._replace(callback=np.int64(self._callback_handle()))
            return
        no_table = (np.zeros(0), np.zeros((0, 0)), False)
        control_table, force_table = no_table, no_table
        if control.kind == "table":
            table = control.value
            control_table = (
                np.array(table.time),
                packed.to_kernel_order(table.values),
                table.outside == "zero",
            )
        if force.kind == "table":
            table = force.value
            values = packed.to_slots(self._spatial(table.values)).reshape(len(table.time), -1)
            force_table = (np.array(table.time), values, table.outside == "zero")
        rest0 = packed.to_kernel_order(self.structure.tendon_rest_length)
        self.model = self.model._replace(tables=(*control_table, rest0, *force_table))

    @property
    def constant(self) -> bool:
        """True if every input is constant in time (no table, no function, no actuators)."""
        return self.inputs.constant and self.actuators is None

    @property
    def tables(self) -> tuple | None:
        """:func:`compiled.fill_stage_inputs`'s tables (``model.tables``), or None (constant
        inputs, or a callable among them)."""
        return self.model.tables

    def stage_inputs(self, times: np.ndarray) -> Data:
        """The data record with the inputs at the stage ``times`` (K,) [s]: one row for a
        constant input, K new rows for one that varies.  ``ValueError`` naming the control if a
        rest length would be negative."""
        if self._constant is not None:
            return self._constant
        if self.tables is not None:
            return self._table_inputs(times)
        return self._numpy_inputs(times)

    def input_buffers(self, k: int) -> Data:
        """The data record compiled code fills with ``k`` stages' rows of the inputs that vary
        (:func:`compiled.make_inputs`; kept until the inputs change), or the constant inputs'."""
        if self._constant is not None:
            return self._constant
        if k not in self._buffers:
            self._buffers[k] = self._varying_buffers(k)
        return self._buffers[k]

    def _varying_buffers(self, k: int) -> Data:
        """A data record of ``k`` input rows for the inputs that vary, the constants' rows
        made."""
        t0 = np.zeros(1)
        if not self.inputs.control.constant:
            S = self.structure.n_tendons
            rest, rate, has_rate = np.empty((k, S)), np.empty((k, S)), True
        else:
            rest, rate, has_rate = self._control_rows(t0)
            if self.actuators is not None:  # (their columns made by compiled code)
                rest, rate, has_rate = (
                    np.repeat(rest, k, axis=0),
                    np.zeros((k, rest.shape[1])),
                    True,
                )
        if not self.inputs.external_force.constant:
            force, has_external = np.empty((k, 3, self.packed.layout.n_slots)), True
        else:
            force, has_external = self._force_rows(t0)
        return self._with_inputs(rest, rate, has_rate, force, has_external)

    def _table_inputs(self, times: np.ndarray) -> Data:
        """:meth:`stage_inputs` with tables and constants: the tables' rows made by compiled
        code, the constants' as by NumPy."""
        times = np.ascontiguousarray(times, dtype=float)
        data = self._varying_buffers(times.size)
        if compiled.fill_inputs_entry(self.tables, times, data) >= 0:
            self.inputs.rest_length(times)  # raises the ValueError naming the tendon
        return data

    def _callback_handle(self) -> int:
        """This system's handle in :data:`compiled.INPUT_CALLBACKS` (registered once, dropped
        when the system is)."""
        if self._handle is None:
            self._handle = next(_HANDLES)
            compiled.INPUT_CALLBACKS[self._handle] = _weakly(weakref.WeakMethod(self._make_inputs))
            weakref.finalize(self, compiled.INPUT_CALLBACKS.pop, self._handle, None)
        return self._handle

    def _make_inputs(self, times: np.ndarray) -> int:
        """The callback compiled code calls (:func:`compiled.make_inputs`): the inputs at the
        stage ``times`` (K,) [s] made by NumPy and the Python functions, into
        :meth:`input_buffers` ``(K)``.  Returns -1, or 0 when they could not be made: the
        exception (a rest length negative, or the function's own) is kept in
        :attr:`input_error` for :meth:`raise_input_error`."""
        data = self.input_buffers(times.size)
        try:
            made = self._numpy_inputs(times)
        except BaseException as exc:  # noqa: BLE001 - kept, and re-raised by the loop in Python
            self.input_error = exc
            return 0
        np.copyto(data.rest, made.rest)
        np.copyto(data.rate, made.rate)
        np.copyto(data.force, made.force)
        return -1

    def raise_input_error(self) -> None:
        """Raise what the last input callback failed with, if anything (then forget it)."""
        error, self.input_error = self.input_error, None
        if error is not None:
            raise error

    def _numpy_inputs(self, times: np.ndarray) -> Data:
        """:meth:`stage_inputs` evaluated by NumPy and the Python callables (the actuated
        tendons' rows by :func:`~tensegrity.engine.actuation.actuate`)."""
        rest, rate, has_rate = self._control_rows(times)
        if self.actuators is not None:
            K = times.size
            rest = np.array(np.broadcast_to(rest, (K, rest.shape[1])))
            rate = np.zeros((K, rest.shape[1])) if not has_rate else np.array(rate)
            has_rate = True
        data = self._with_inputs(rest, rate, has_rate, *self._force_rows(times))
        actuate(data.actuation, np.ascontiguousarray(times, dtype=float), data)
        return data

    def _with_inputs(
        self,
        rest: np.ndarray,
        rate: np.ndarray,
        has_rate: bool,
        force: np.ndarray,
        has_external: bool,
    ) -> Data:
        """:attr:`data` (its scratch shared) with these input rows."""
        return self.data._replace(
            rest=rest, rate=rate, has_rate=has_rate, force=force, has_external=has_external
        )

    def _control_rows(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        """Rest lengths and control rates (K or 1, S) in kernel order, and whether there are
        rates."""
        inputs, packed = self.inputs, self.packed
        rest = packed.to_kernel_order(inputs.rest_length(times))
        rate = inputs.control.rate(times)
        if rate is None:
            return rest, np.zeros((1, 1)), False
        return rest, packed.to_kernel_order(rate), True

    def _force_rows(self, times: np.ndarray) -> tuple[np.ndarray, bool]:
        """External forces (K or 1, 3, n_slots), and whether there are any."""
        force = self.inputs.external_force.at(times)
        if force is None:
            return np.zeros((1, 3, 1)), False
        return self.packed.to_slots(self._spatial(force)), True

    def _spatial(self, x: np.ndarray) -> np.ndarray:
        """Vectors (..., dim) as (..., 3)."""
        if not self.planar:
            return np.asarray(x, dtype=float)
        return np.concatenate([x, np.zeros((*x.shape[:-1], 1))], axis=-1)

    @property
    def actuation(self) -> Actuation:
        """The actuators' record (``data.actuation``; a system with actuators)."""
        act = self.data.actuation
        assert act is not None, "actuation: the system has no actuators"
        return act

    def command(self, u: np.ndarray, t: float, y: np.ndarray) -> np.ndarray:
        """Hold the command ``u`` (A,) [m] of the actuators from ``t`` [s] at the state ``y``
        (a Python controller's update): clipped to their bounds, the applied control carrying
        on from its value at ``t`` (:mod:`tensegrity.engine.actuation`), the elastic energy's
        jump (a command held at once) added to ``W_u`` in ``y``.  Returns the command held
        (A,) [m]; the update is in :meth:`take_control_log`."""
        act = self.actuation
        held = np.empty(act.position.size)
        clip_command(act, np.ascontiguousarray(u, dtype=float), held)
        self._drain_log()  # (room for the update)
        compiled.held(self.model, self.stage_inputs(np.array([t])), float(t), y, held)
        return held

    def feedback_update(self, t: float, y: np.ndarray) -> None:
        """The compiled feedback law's update at ``(t, y)`` (its first, and those of the loops
        that are not compiled): as compiled code makes it."""
        self._drain_log()
        data = self.stage_inputs(np.array([t]))
        compiled.feedback_update(self.model.feedback, self.model, data, float(t), y)

    def reset_actuation(self) -> None:
        """The actuators as at the start of a run: no command yet (zero), no updates, an
        empty log."""
        act = self.actuation
        act.start[0], act.updates[0], act.log_count[0] = -np.inf, 0, 0
        act.applied[:] = act.command[:] = 0.0
        self._control_log = []

    def _drain_log(self) -> None:
        """Move the updates logged by compiled code to :meth:`take_control_log`'s list."""
        act = self.actuation
        self._control_log.append(act.log[: act.log_count[0]].copy())
        act.log_count[0] = 0

    def take_control_log(self) -> np.ndarray:
        """The actuators' updates since the last call (U, 1 + 2 A): time [s], the commands
        held (after the bounds) [m], the controls applied at that time [m] (in the order of
        :attr:`actuators`' tendons)."""
        self._drain_log()
        rows = np.concatenate(self._control_log)
        self._control_log = []
        return rows

    # ------------------------------------------------------------------ states
    def state_vector(self, state: dynamics.State, *, project: bool = True) -> np.ndarray:
        """The ODE state ``y`` of ``state`` (energy integrals zero), projected onto the rod,
        joint and support constraints unless ``project`` is False (a state that is on them)."""
        q, qdot = state.q, state.qdot
        if project:
            q, qdot = dynamics.project_to_constraints(self.structure, q, qdot)
        if self.planar:
            q, qdot = lift_coordinates(self.structure, q), lift_coordinates(self.structure, qdot)
        return np.concatenate([q, qdot, np.zeros(3)])

    def project(self, y: np.ndarray) -> bool:
        """Project ``y`` in place onto the constraints; False if that failed."""
        n = self.n
        return bool(system_project(self.model, self.data, y[:n], y[n : 2 * n])[2])

    def rk4_work(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """New scratch of :func:`compiled.rk4_step` (its ``work_step``): the sum of the stages
        and a stage's state (m,), its accelerations (n,), and ``f(t, y)`` at the step's start
        (m,)."""
        m = self.m
        return np.zeros(m), np.zeros(m), np.zeros(self.n), np.zeros(m)

    def check_contacts(self, y: np.ndarray) -> None:
        """``ValueError`` naming ``ground`` if a contact point (a rod's end, a point mass) starts
        below one of the planes (its centre on the solid's side of it)."""
        contacts = self.model.contacts
        if contacts is None:
            return
        s = self.structure
        points = np.concatenate([s.rod_nodes.reshape(-1), s.point_mass_nodes])
        for p, (point, normal) in enumerate(
            zip(contacts.plane_point, contacts.plane_normal, strict=True)
        ):
            height = (self.nodes(y)[points] - point) @ normal
            if np.any(height < 0):
                c = int(np.argmin(height))
                what = f"rod {c // 2}'s end {'ab'[c % 2]}" if c < 2 * s.n_rods else "a point mass"
                raise ValueError(
                    f"ground: node {points[c]} ({what}) starts {-height[c]:.3g} m below plane "
                    f"{p}; start the structure above it"
                )

    def coordinates(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(q, qdot)`` of ``y`` in the structure's coordinates (new arrays)."""
        q, qdot = y[: self.n].copy(), y[self.n : 2 * self.n].copy()
        if self.planar:
            q, qdot = drop_coordinates(self.structure, q), drop_coordinates(self.structure, qdot)
        return q, qdot

    def nodes(self, y: np.ndarray) -> np.ndarray:
        """Node positions (N, dim) [m] at ``y``."""
        n = self.n
        system_nodes(self.model, y[:n], y[n : 2 * n], self.scratch_p, self.scratch_v, False)
        return self.scratch_p[: self.structure.dim, self.node_slot].T.copy()

    def record(self, samples: Samples, row: int, t: float, y: np.ndarray, data: Data) -> None:
        """Sample ``row`` of ``samples`` at ``(t, y)`` with ``data`` holding the inputs at ``t``
        (one row), from one evaluation (:func:`compiled.record_sample`)."""
        samples.t[row] = t
        compiled.record_sample(
            self.model, data, y, self._sample_scratch, self._sample_maps, samples[1:10], row
        )
        if self.model.contacts is not None:
            compiled.record_contacts_entry(data, samples[10:], row)
