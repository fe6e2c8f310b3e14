"""The result of a run held in memory (:class:`SimulationResult`), and the sink that builds it
(:class:`MemorySink`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from tensegrity.model.ground import FREE, SLIP, STICK
from tensegrity.model.structure import Structure
from tensegrity.physics.coordinates import nodes_from_coordinates

if TYPE_CHECKING:  # (physics loads SciPy: a reader of results need not)
    from tensegrity.physics.dynamics import State

__all__ = [
    "ENERGY_NAMES",
    "STATUS_END",
    "STATUS_FAILED",
    "STATUS_STEADY",
    "STATUS_STOPPED",
    "MemorySink",
    "RunSummary",
    "Samples",
    "SimulationResult",
    "shortened",
    "total_energy",
]

#: ``status`` values: failed, end time reached, steady state reached, stopped by the run's
#: stop condition (``simulate(stop=...)``).
STATUS_FAILED, STATUS_END, STATUS_STEADY, STATUS_STOPPED = -1, 0, 1, 2

#: Names of the energy components of a sample, in order [J].
ENERGY_NAMES = ("kinetic", "elastic", "gravity", "dissipated", "external_work", "control_work")


class Samples(NamedTuple):
    """Output samples as columns, one row per sample time, in the structure's order and
    dimension (SI units).  The engine fills them a row at a time
    (:meth:`tensegrity.engine.system.CompiledSystem.record`) and hands them to its sink in
    blocks of many rows."""

    t: np.ndarray  #: (T,) [s]
    q: np.ndarray  #: (T, n) [m]
    qdot: np.ndarray  #: (T, n) [m/s]
    node_position: np.ndarray  #: (T, N, dim) [m]
    node_velocity: np.ndarray  #: (T, N, dim) [m/s]
    tendon_length: np.ndarray  #: (T, S) [m]
    tendon_tension: np.ndarray  #: (T, S) [N]
    energy: np.ndarray  #: (T, 6) [J]: kinetic, elastic, gravity, dissipated, external, control
    residual_acceleration: np.ndarray  #: (T,) largest node acceleration [m/s^2]
    largest_speed: np.ndarray  #: (T,) largest node speed [m/s]
    contact_normal_force: np.ndarray  #: (T, CP) F_n of each contact pair [N] (CP = 0: none)
    contact_friction_force: np.ndarray  #: (T, CP, 3) its tangential force [N]
    contact_mode: np.ndarray  #: (T, CP) int8: its mode, ``FREE`` 0, ``SLIP`` 1, ``STICK`` 2

    @classmethod
    def empty(cls, rows: int, structure: Structure, pairs: int = 0) -> Samples:
        """Room for ``rows`` samples of ``structure`` with ``pairs`` contact pairs
        (uninitialised)."""
        n, N, S, d = structure.n_coordinates, structure.n_nodes, structure.n_tendons, structure.dim
        return cls(
            np.empty(rows),
            np.empty((rows, n)),
            np.empty((rows, n)),
            np.empty((rows, N, d)),
            np.empty((rows, N, d)),
            np.empty((rows, S)),
            np.empty((rows, S)),
            np.empty((rows, len(ENERGY_NAMES))),
            np.empty(rows),
            np.empty(rows),
            np.empty((rows, pairs)),
            np.empty((rows, pairs, 3)),
            np.empty((rows, pairs), np.int8),
        )

    @staticmethod
    def row_bytes(structure: Structure, pairs: int = 0) -> int:
        """Bytes of one sample of ``structure`` with ``pairs`` contact pairs."""
        n, N, S, d = structure.n_coordinates, structure.n_nodes, structure.n_tendons, structure.dim
        return 8 * (1 + 2 * n + 2 * N * d + 2 * S + len(ENERGY_NAMES) + 2 + 4 * pairs) + pairs

    def head(self, rows: int) -> Samples:
        """The first ``rows`` samples (views)."""
        return Samples(*(column[:rows] for column in self))

    def row(self, index: int) -> Samples:
        """Sample ``index`` alone, as a block of one row (views)."""
        return Samples(*(column[index : index + 1] for column in self))

    @classmethod
    def join(cls, blocks: Sequence[Samples]) -> Samples:
        """``blocks`` (at least one) one after the other; the block itself if only one."""
        if len(blocks) == 1:
            return blocks[0]
        return cls(*(np.concatenate(columns) for columns in zip(*blocks, strict=True)))


@dataclasses.dataclass(frozen=True)
class RunSummary:
    """How a run ended, and what it cost."""

    status: int  #: ``STATUS_*``
    message: str
    t_final: float  #: time of the last sample [s]
    nfev: int  #: right-hand-side evaluations
    nsteps: int  #: accepted steps
    nswitches: int  #: located slack/taut switches
    nprojections: int  #: projections onto the constraints
    max_rod_length_error: float  #: largest relative rod-length error at a step's end
    max_constraint_error: float  #: largest joint/support violation at a step's end [m]
    wall_time: float  #: [s]
    settings: dict[str, Any]
    switch_times: tuple[float, ...] = ()  #: times of the located switches [s]
    #: (E, 4) the contact pairs' changes of mode: time [s], pair, mode before, mode after
    contact_events: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 4)))
    #: (U, 1 + 2 A) the actuators' updates: time [s], the commands held (after the bounds)
    #: [m], the controls applied at that time [m]; (0, 1) without actuators
    control_updates: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 1)))
    stopped_for_time: bool = False  #: failed because this call used up ``max_wall_time``
    #: (T, P, 2 n) the sensitivities ``[dq/dp, dq'/dp]`` at the samples in the layout of
    #: ``q`` and ``qdot`` (n of their columns), or None (not asked for)
    sensitivity: np.ndarray | None = None

    @property
    def evaluations_per_step(self) -> float:
        """Right-hand-side evaluations per accepted step."""
        return self.nfev / max(self.nsteps, 1)


def shortened(text: str, limit: int = 80) -> str:
    """``text``, cut to ``limit`` characters (its end replaced by ``…``) if longer: a message
    in a ``repr``."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def total_energy(energy: Mapping[str, np.ndarray]) -> np.ndarray:
    """``E_kin + E_el + E_grav + E_d - W_w - W_u`` [J] of energies by :data:`ENERGY_NAMES`
    (arrays of one shape): the balance a run conserves up to integration error."""
    e = energy
    return (
        e["kinetic"]
        + e["elastic"]
        + e["gravity"]
        + e["dissipated"]
        - e["external_work"]
        - e["control_work"]
    )


@dataclasses.dataclass(frozen=True, eq=False)
class SimulationResult:
    """Samples of a simulation and how it ended.

    Sampled arrays have ``T`` rows, one per output time.

    Attributes
    ----------
    t : (T,) sample times [s].
    q, qdot : (T, 6R) coordinates [m] and rates [m/s].
    node_position, node_velocity : (T, N, 3) ``p = P q`` [m] and ``P q'`` [m/s] (eq. 18.60);
        (T, N, 2) for a planar structure.
    tendon_length : (T, S) [m].  tendon_tension : (T, S) [N], damping included.
    energy : dict of (T,) arrays [J]: ``kinetic``, ``elastic``, ``gravity``, ``dissipated``,
        ``external_work``, ``control_work``.
    residual_acceleration : (T,) largest node acceleration [m/s^2].
    status : ``1`` steady state reached, ``0`` end time reached, ``-1`` failed (see ``message``).
    nfev, nsteps, nswitches, nprojections : right-hand-side evaluations, steps, located slack/taut
        switches, projections onto the rod constraints.
    max_rod_length_error : largest relative rod-length error seen at the end of a step.
    max_constraint_error : largest violation ``|A q - b|`` [m] of the joints and supports seen at
        the end of a step (0 without any; see ``docs/constraints.md``).
    wall_time : [s].  settings : the options of the run.
    switch_times : (nswitches,) times of the located events [s]: slack/taut switches and the
        contact events that changed a pair's mode.
    contact_normal_force : (T, CP) normal force ``F_n`` [N] of each contact pair (a rod end
        against a plane, :attr:`contact_node`, :attr:`contact_plane`; CP = 0 without planes).
    contact_friction_force : (T, CP, 3) its tangential (friction) force [N].
    contact_mode : (T, CP) int8, its mode: 0 free, 1 slipping, 2 sticking
        (:data:`tensegrity.model.ground.CONTACT_MODES`).
    contact_event_time, contact_event_pair, contact_event_mode : (E,) [s], (E,), (E, 2): the
        changes of a pair's mode, at located events (or at the start, from free): when, which
        pair, the modes before and after (:attr:`contact_counts` counts them).
    q_sensitivity, qdot_sensitivity : (T, P, n) or None (n the columns of ``q``): ``dq/dp`` and
        ``dq'/dp`` with respect to the P parameters of ``simulate(..., sensitivity=...)``
        (:mod:`tensegrity.engine.sensitivity`) [unit of q per unit of each parameter];
        :meth:`node_position_sensitivity` and :meth:`node_velocity_sensitivity` give them per
        node.
    control_time, control_command, control_applied : (U,) [s], (U, A) [m], (U, A) [m]: the
        actuators' updates (a controller's), when, the commands held (after the rest-length
        bounds), the controls applied at that time; A actuated tendons
        (:attr:`control_tendons`, ``settings["actuators"]``), U = 0 without a controller.
        :meth:`saturations` says where the limits bound them.
    """

    structure: Structure
    t: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    node_position: np.ndarray
    node_velocity: np.ndarray
    tendon_length: np.ndarray
    tendon_tension: np.ndarray
    energy: dict[str, np.ndarray]
    residual_acceleration: np.ndarray
    status: int
    message: str
    nfev: int
    nsteps: int
    nswitches: int
    nprojections: int
    max_rod_length_error: float
    wall_time: float
    settings: dict[str, Any]
    max_constraint_error: float = 0.0
    switch_times: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    contact_normal_force: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))
    contact_friction_force: np.ndarray = dataclasses.field(
        default_factory=lambda: np.zeros((0, 0, 3))
    )
    contact_mode: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0), np.int8))
    contact_event_time: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    contact_event_pair: np.ndarray = dataclasses.field(
        default_factory=lambda: np.zeros(0, np.int64)
    )
    contact_event_mode: np.ndarray = dataclasses.field(
        default_factory=lambda: np.zeros((0, 2), np.int8)
    )
    control_time: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    control_command: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))
    control_applied: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros((0, 0)))
    q_sensitivity: np.ndarray | None = None
    qdot_sensitivity: np.ndarray | None = None

    def node_position_sensitivity(self) -> np.ndarray:
        """``dp/dparam`` (T, P, N, dim) [m per unit of each parameter] of the nodes' positions
        (anchors 0), from :attr:`q_sensitivity` (``simulate(..., sensitivity=...)``)."""
        return nodes_from_coordinates(self.structure, self._sensitivity("q"), rates=True)

    def node_velocity_sensitivity(self) -> np.ndarray:
        """``dv/dparam`` (T, P, N, dim) [m/s per unit] of the nodes' velocities."""
        return nodes_from_coordinates(self.structure, self._sensitivity("qdot"), rates=True)

    def gradient(self, loss_q: np.ndarray, loss_qdot: np.ndarray | None = None) -> np.ndarray:
        """The gradient (P,) of a scalar loss of the samples, ``L(q, qdot)``, with respect to the
        parameters of ``simulate(..., sensitivity=...)``, from the loss's partial derivatives
        ``loss_q = dL/dq`` and ``loss_qdot = dL/dqdot`` (T, n) at the samples (the chain rule
        through :attr:`q_sensitivity` and :attr:`qdot_sensitivity`) [unit of L per unit of each
        parameter]."""
        grad = np.einsum("tpn,tn->p", self._sensitivity("q"), np.asarray(loss_q, dtype=float))
        if loss_qdot is not None:
            qdot = np.asarray(loss_qdot, dtype=float)
            grad = grad + np.einsum("tpn,tn->p", self._sensitivity("qdot"), qdot)
        return grad

    def _sensitivity(self, name: str) -> np.ndarray:
        values = getattr(self, f"{name}_sensitivity")
        if values is None:
            raise ValueError(
                f"{name}_sensitivity: the run integrated no sensitivities (give simulate "
                "sensitivity=[...])"
            )
        return values

    @property
    def control_tendons(self) -> tuple[str, ...]:
        """The actuated tendons' names (A,), in the order of :attr:`control_command`'s
        columns (empty without actuators)."""
        return tuple(self.settings.get("actuators", {}).get("tendons", ()))

    def saturations(self) -> list[Saturation]:
        """Where the actuators' limits bound the commands: each stretch of time an actuated
        tendon's command sat on a rest-length bound (``"bound"``), its control moved at the
        rate limit (``"rate"``), or its tension was at its cap (``"force"``, from the first to
        the last sample of a run of samples at it), in time order."""
        settings = self.settings.get("actuators")
        if settings is None or self.control_time.size == 0:
            return []
        names = self.control_tendons
        index = [self.structure.tendon_index(name) for name in names]
        rest0 = self.structure.tendon_rest_length[index]

        def limit(key: str, missing: float) -> np.ndarray:
            return np.array([missing if v is None else v for v in settings[key]], dtype=float)

        low = rest0 - limit("max_rest_length", np.inf)
        high = rest0 - limit("min_rest_length", 0.0)
        rate, tau = limit("max_rate", np.inf), limit("time_constant", 0.0)
        cap = limit("max_tension", np.inf)
        ends = np.append(self.control_time[1:], self.t[-1] if self.t.size else np.inf)
        found: list[Saturation] = []
        for a, name in enumerate(names):
            command, applied = self.control_command[:, a], self.control_applied[:, a]
            on_bound = (command <= low[a]) | (command >= high[a])
            ramp = np.zeros(command.size)
            if np.isfinite(rate[a]):  # (the time at the rate limit, model.actuators)
                ramp = np.maximum(np.abs(command - applied) - rate[a] * tau[a], 0.0) / rate[a]
            at_cap = self.tendon_tension[:, index[a]] >= cap[a] * (1.0 - 1e-12)
            edges = np.diff(np.concatenate([[0], at_cap.astype(int), [0]]))
            first, last = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
            for kind, starts, stops in (
                ("bound", self.control_time[on_bound], ends[on_bound]),
                (
                    "rate",
                    self.control_time[ramp > 0],
                    np.minimum(self.control_time + ramp, ends)[ramp > 0],
                ),
                ("force", self.t[first], self.t[last]),
            ):
                for start, stop in zip(starts, stops, strict=True):
                    if found and found[-1][:2] == (name, kind) and found[-1].end == start:
                        found[-1] = found[-1]._replace(end=float(stop))
                    else:
                        found.append(Saturation(name, kind, float(start), float(stop)))
        return sorted(found, key=lambda x: (x.start, x.tendon))

    def __post_init__(self) -> None:
        """Contact arrays left out (a run without planes): (T, 0) of theirs."""
        for name in ("contact_normal_force", "contact_friction_force", "contact_mode"):
            value = getattr(self, name)
            if value.size == 0 and value.shape[0] != self.t.shape[0]:
                object.__setattr__(self, name, value.reshape(self.t.shape[0], *value.shape[1:]))

    def __repr__(self) -> str:
        """A few hundred characters at most whatever the run's size, as NumPy's and xarray's:
        how it ended (``status`` and the start of ``message``), the samples and their times, the
        structure (its ``repr``) and the slack tendons at the end."""
        T, S = self.t.size, self.structure.n_tendons
        samples = f"{T} sample{'' if T == 1 else 's'}"
        if T:
            samples += f" t = {self.t[0]:.6g}..{self.t[-1]:.6g} s"
            slack = f", {int(self.slack_count[-1])} of {S} tendons slack at the end"
        else:
            slack = ""
        return (
            f"<SimulationResult: status {self.status} ({shortened(self.message)}), {samples}, "
            f"{self.structure!r}{slack}>"
        )

    @property
    def success(self) -> bool:
        """True unless the run failed."""
        return self.status >= 0

    @property
    def evaluations_per_step(self) -> float:
        """Right-hand-side evaluations per accepted step (12 for DOP853 without rejected steps,
        dense outputs or located switches; 4 for RK4)."""
        return self.nfev / max(self.nsteps, 1)

    @property
    def final_state(self) -> State:
        """The state at the last sample."""
        from tensegrity.physics.dynamics import State

        return State(t=float(self.t[-1]), q=self.q[-1], qdot=self.qdot[-1])

    @property
    def total_energy(self) -> np.ndarray:
        """``E_kin + E_el + E_grav + E_d - W_w - W_u`` [J], (T,): constant up to integration
        error."""
        return total_energy(self.energy)

    @property
    def tendon_name(self) -> tuple[str, ...]:
        """Tendon names (S,): the structure's ``tendon_name``, as in the trajectory file's
        ``tendon_name`` attribute."""
        return self.structure.tendon_name

    @property
    def slack_count(self) -> np.ndarray:
        """Number of slack (zero-tension) tendons at each sample, (T,)."""
        return np.sum(self.tendon_tension <= 0, axis=1)

    @property
    def planes(self) -> tuple[dict[str, Any], ...]:
        """The run's planes, each as its fields (``Plane.settings()``), from :attr:`settings`."""
        return tuple(self.settings.get("ground", ()))

    @property
    def contact_node(self) -> np.ndarray:
        """The node of each contact pair (CP,): pair ``k = c P + p`` is point ``c`` against
        plane ``p``, the points the rods' ends (end ``c % 2`` of rod ``c // 2``), then the point
        masses."""
        s = self.structure
        points = np.concatenate([s.rod_nodes.reshape(-1), s.point_mass_nodes]).astype(np.int64)
        return np.repeat(points, len(self.planes))

    @property
    def contact_plane(self) -> np.ndarray:
        """The plane of each contact pair (CP,): an index into :attr:`planes`."""
        s = self.structure
        return np.tile(np.arange(len(self.planes)), 2 * s.n_rods + s.point_mass_nodes.size)

    @property
    def contact_penetration(self) -> np.ndarray:
        """Penetration ``delta = r - n . (x - x0)`` [m] of each contact pair at each sample
        (T, CP): > 0 where the end's sphere of radius ``settings["contact_radius"]`` reaches
        into the plane."""
        if not self.planes:
            return np.zeros((self.t.size, 0))
        point = np.array([plane["point"] for plane in self.planes])[self.contact_plane]
        normal = np.array([plane["normal"] for plane in self.planes])[self.contact_plane]
        x = self.node_position[:, self.contact_node]
        height = np.einsum("tkd,kd->tk", x - point, normal)
        return float(self.settings["contact_radius"]) - height

    @property
    def contact_counts(self) -> dict[str, int]:
        """The contact events by kind: ``touch_down`` (free to in contact, the start's contacts
        included), ``lift_off``, ``slip`` (sticking to slipping), ``stick`` (slipping to
        sticking)."""
        before, after = self.contact_event_mode.T
        return {
            "touch_down": int(np.sum((before == FREE) & (after != FREE))),
            "lift_off": int(np.sum((before != FREE) & (after == FREE))),
            "slip": int(np.sum((before == STICK) & (after == SLIP))),
            "stick": int(np.sum((before == SLIP) & (after == STICK))),
        }


class MemorySink:
    """Keeps every sample; :meth:`result` assembles the :class:`SimulationResult`."""

    def __init__(self) -> None:
        self.blocks: list[Samples] = []

    def add(self, samples: Samples) -> None:
        self.blocks.append(samples)

    @property
    def samples(self) -> Samples:
        """Every sample so far (at least one)."""
        return Samples.join(self.blocks)

    def result(self, structure: Structure, summary: RunSummary) -> SimulationResult:
        """The samples and ``summary`` as one result."""
        s = self.samples
        return SimulationResult(
            structure=structure,
            t=s.t,
            q=s.q,
            qdot=s.qdot,
            node_position=s.node_position,
            node_velocity=s.node_velocity,
            tendon_length=s.tendon_length,
            tendon_tension=s.tendon_tension,
            energy={name: s.energy[:, k] for k, name in enumerate(ENERGY_NAMES)},
            residual_acceleration=s.residual_acceleration,
            status=summary.status,
            message=summary.message,
            nfev=summary.nfev,
            nsteps=summary.nsteps,
            nswitches=summary.nswitches,
            nprojections=summary.nprojections,
            max_rod_length_error=summary.max_rod_length_error,
            max_constraint_error=summary.max_constraint_error,
            wall_time=summary.wall_time,
            settings=summary.settings,
            switch_times=np.array(summary.switch_times),
            contact_normal_force=s.contact_normal_force,
            contact_friction_force=s.contact_friction_force,
            contact_mode=s.contact_mode,
            **contact_event_arrays(summary.contact_events),
            **control_arrays(summary.control_updates),
            **sensitivity_arrays(structure, summary.sensitivity),
        )


def sensitivity_arrays(structure: Structure, sensitivity: np.ndarray | None) -> dict[str, Any]:
    """A run's sensitivities (T, P, 2 n) (:attr:`RunSummary.sensitivity`) as a result's
    ``q_sensitivity`` and ``qdot_sensitivity`` (None when there are none)."""
    if sensitivity is None:
        return {"q_sensitivity": None, "qdot_sensitivity": None}
    n = sensitivity.shape[-1] // 2
    return {"q_sensitivity": sensitivity[..., :n], "qdot_sensitivity": sensitivity[..., n:]}


def control_arrays(updates: np.ndarray) -> dict[str, np.ndarray]:
    """The actuators' updates (U, 1 + 2 A) (:attr:`RunSummary.control_updates`) as a
    result's ``control_time``, ``control_command`` and ``control_applied``."""
    A = (updates.shape[1] - 1) // 2
    return {
        "control_time": updates[:, 0].copy(),
        "control_command": updates[:, 1 : 1 + A].copy(),
        "control_applied": updates[:, 1 + A :].copy(),
    }


class Saturation(NamedTuple):
    """A stretch of time an actuator's limit bound it (:meth:`SimulationResult.saturations`)."""

    tendon: str  #: the actuated tendon's name
    kind: str  #: ``"bound"`` (a rest-length bound) or ``"rate"`` (the rate limit)
    start: float  #: [s]
    end: float  #: [s]


def contact_event_arrays(events: np.ndarray) -> dict[str, np.ndarray]:
    """A log of contact events (E, 4) (time [s], pair, mode before, mode after) as the
    result's ``contact_event_time``, ``contact_event_pair`` and ``contact_event_mode``."""
    events = np.asarray(events, dtype=float).reshape(-1, 4)
    return {
        "contact_event_time": events[:, 0].copy(),
        "contact_event_pair": events[:, 1].astype(np.int64),
        "contact_event_mode": events[:, 2:].astype(np.int8),
    }
