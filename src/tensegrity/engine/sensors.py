"""Sensors as hardware has them: measured outputs of a structure with noise, bias, delay and
their own sampling rate, read online by a control loop (:class:`SensorReader`) or offline from a
finished run (:func:`measure`), by one code.

Kinds of sensor (:data:`KINDS`), what each measures and in what unit, each on the items of its
field (``nodes``, ``tendons`` or ``rods``; default: all of them):

================  =========  =====================================================  ===========
kind              field      output, per item                                       channels
================  =========  =====================================================  ===========
``position``      nodes      a marker: the node's position ``p = P q`` [m]          x, y[, z]
``velocity``      nodes      the node's velocity ``P q'`` [m/s]                     x, y[, z]
``length``        tendons    the tendon's length ``|t|`` [m]                        one
``tension``       tendons    the tendon's tension [N] (as the run's, damping in)    one
``orientation``   rods       the rod's unit direction ``b = q2 / |q2|`` (world)     x, y, z
``angular_rate``  rods       the rod's angular velocity ``b x b' / |b|^2`` [rad/s]  x, y, z
``contact``       nodes      the mode of a rod end (or point mass) on each plane:   one a plane
                             0 free, 1 slip, 2 stick (``model.ground``)
================  =========  =====================================================  ===========

An IMU on a rod: a rod of the model is a line with no spin about its own axis (no inertia
there, eq. 18.24), so the orientation an IMU would report has no meaning about that axis.  The
sensors give what is defined: the rod's unit direction ``b`` (from its first end to its second,
``q2 / |q2|``) and the angular velocity ``omega = q2 x q2' / |q2|^2`` [rad/s] of that direction,
both in the world frame (``omega`` is perpendicular to the rod: ``b' = omega x b``).  A planar
structure's rods lie in the ``x, y`` plane (``z`` components zero: its angular rate is about
``z``).  Positions and velocities of a planar structure have the two channels ``x, y``.

The signals come from the package's physics: node positions and velocities from
:func:`tensegrity.physics.coordinates.nodes_from_coordinates`, tendon lengths from
:func:`tensegrity.physics.dynamics.tendon_lengths`, the rods' vectors from
:func:`tensegrity.physics.coordinates.rod_coordinates`; tensions and contact modes are the
run's (the engine's own, given to the reader).

Each sensor (:class:`Sensor`) has, set by itself:

- ``noise``: the standard deviation of a zero-mean Gaussian noise added to each sample [the
  output's SI unit], one number or one per channel, drawn afresh at each sample;
- ``bias``: a constant added to every sample [the output's unit], one number or one per channel;
- ``delay`` [s]: the sample at time ``t_k`` measures the signal at ``t_k - delay``;
- ``rate`` [Hz]: samples at ``t_k = t0 + k / rate`` (``t0`` the first time read, ``k = 0, 1,
  ...``), each held until the next (sample-and-hold); None samples at every time read.

A measurement is ``y_k = x(t_k - delay) + bias + noise * z_k`` with ``z_k`` standard normal.
The signal between two times the reader was given is that of the earlier (the reader knows the
motion only there: give it every sample of the run, or call it at least at the sensors' rates);
before the first it is the first (the sensor's pipeline starts full of the initial state).
Two times within :data:`TIME_TOLERANCE` are the same time.  A contact sensor has no noise or
bias (its output is a mode).

Noise is drawn from one generator per sensor, spawned from the seed (``numpy.random.
SeedSequence(seed).spawn``): the same seed gives the same measurements, whatever the times the
reader is called at, and a sensor's noise does not change when another sensor is added after
it.  Channels are named ``<sensor>.<item>[.<component>]`` (``position.n3.x``,
``tension.c_01``, ``angular_rate.rod2.z``, ``contact.n4`` or ``contact.n4.<plane>`` with
several planes); a sensor's name is its kind unless given.
"""

from __future__ import annotations

import bisect
import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import scipy.interpolate

from tensegrity.model.structure import Structure
from tensegrity.physics.coordinates import nodes_from_coordinates, rod_coordinates
from tensegrity.physics.dynamics import tendon_lengths

if TYPE_CHECKING:
    from tensegrity.engine.result import SimulationResult

__all__ = [
    "KINDS",
    "TIME_TOLERANCE",
    "Measurements",
    "Reading",
    "Sensor",
    "SensorReader",
    "SensorSeries",
    "measure",
]

#: The kinds of sensor: the field naming the items each reads and its output's unit.
KINDS: dict[str, tuple[str, str]] = {
    "position": ("nodes", "m"),
    "velocity": ("nodes", "m/s"),
    "length": ("tendons", "m"),
    "tension": ("tendons", "N"),
    "orientation": ("rods", "1"),
    "angular_rate": ("rods", "rad/s"),
    "contact": ("nodes", "mode"),
}

#: Two times closer than this [s] are the same time (a sample time reached by a call, a delayed
#: time found in the history).
TIME_TOLERANCE = 1e-9

#: The fields of a sensor (:class:`Sensor`), as a sensor file names them.
FIELDS = ("kind", "name", "nodes", "tendons", "rods", "noise", "bias", "delay", "rate")


def _number(value: Any, field: str, *, low: float, strict: bool = False) -> float:
    """``value`` as a finite float ``>= low`` (``> low`` if ``strict``); ``ValueError`` naming
    ``field`` otherwise."""
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool)
    if ok and math.isfinite(value) and (value > low if strict else value >= low):
        return float(value)
    bound = f"{'>' if strict else '>='} {low:g}"
    raise ValueError(f"{field}: expected a finite number {bound}, got {value!r:.60}")


def _numbers(value: Any, field: str, *, low: float) -> float | tuple[float, ...]:
    """One number or a sequence of them (one per channel), each finite and ``>= low``."""
    if isinstance(value, (str, bytes, Mapping)) or not isinstance(value, (Sequence, np.ndarray)):
        return _number(value, field, low=low)
    items = tuple(_number(v, f"{field}[{k}]", low=low) for k, v in enumerate(value))
    if not items:
        raise ValueError(f"{field}: expected a number or one per channel, got an empty list")
    return items


@dataclasses.dataclass(frozen=True)
class Sensor:
    """One sensor: what it measures and how (module doc).

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    nodes, tendons, rods : sequence, optional
        The items the kind reads (only its own field may be given; None: all of them): nodes
        and tendons by name or 0-based index, rods by index or by their two end nodes
        (``["n0", "n1"]``, either order).
    noise : float or sequence of float
        Standard deviation of the Gaussian noise [the output's SI unit], >= 0; one per channel
        or one for all.  Zero for a contact sensor.
    bias : float or sequence of float
        Constant offset [the output's unit]; one per channel or one for all.  Zero for a contact
        sensor.
    delay : float
        [s], >= 0.
    rate : float or None
        Sampling rate [Hz], > 0; None: a sample at every time read.
    name : str, optional
        The prefix of its channels (default: ``kind``); no comma, no whitespace.
    """

    kind: str
    nodes: tuple[str | int, ...] | None = None
    tendons: tuple[str | int, ...] | None = None
    rods: tuple[Any, ...] | None = None
    noise: float | tuple[float, ...] = 0.0
    bias: float | tuple[float, ...] = 0.0
    delay: float = 0.0
    rate: float | None = None
    name: str | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        if not isinstance(self.kind, str) or self.kind not in KINDS:
            raise ValueError(f"kind: expected one of {', '.join(KINDS)}, got {self.kind!r:.60}")
        own = KINDS[self.kind][0]
        for field in ("nodes", "tendons", "rods"):
            value = getattr(self, field)
            if value is None:
                continue
            if field != own:
                raise ValueError(f"{field}: a {self.kind} sensor reads {own}, not {field}")
            if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
                raise ValueError(f"{field}: expected a list of {field}, got {value!r:.60}")
            if len(value) == 0:
                raise ValueError(f"{field}: expected at least one (or none given: all)")
            set_(self, field, tuple(value))
        set_(self, "noise", _numbers(self.noise, "noise", low=0.0))
        set_(self, "bias", _numbers(self.bias, "bias", low=-math.inf))
        if self.kind == "contact" and (np.any(self.noise) or np.any(self.bias)):
            raise ValueError(
                f"{'noise' if np.any(self.noise) else 'bias'}: a contact sensor reports a mode "
                "(0 free, 1 slip, 2 stick): no noise or bias"
            )
        set_(self, "delay", _number(self.delay, "delay", low=0.0))
        if self.rate is not None:
            set_(self, "rate", _number(self.rate, "rate", low=0.0, strict=True))
        name = self.kind if self.name is None else self.name
        if not isinstance(name, str) or not name or not name.isprintable() or "," in name:
            raise ValueError(
                f"name: expected a non-empty name without commas or control characters, got "
                f"{name!r:.60}"
            )
        if any(c.isspace() for c in name):
            raise ValueError(f"name: expected a name without spaces, got {name!r:.60}")
        set_(self, "name", name)

    @classmethod
    def from_dict(cls, fields: Any) -> Sensor:
        """A sensor from its fields as a sensor file gives them (:data:`FIELDS`); ``ValueError``
        naming the field that is unknown or wrong."""
        if not isinstance(fields, Mapping):
            raise ValueError(f"expected an object of fields, got {type(fields).__name__}")
        unknown = [key for key in fields if key not in FIELDS]
        if unknown:
            raise ValueError(f"{unknown[0]:.60}: unknown field (expected {', '.join(FIELDS)})")
        if "kind" not in fields:
            raise ValueError(f"kind: missing (one of {', '.join(KINDS)})")
        return cls(**fields)


class Reading(NamedTuple):
    """The latest measurements of a :class:`SensorReader`: ``value`` (C,) in the order of
    ``channel`` (C,), their names."""

    value: np.ndarray
    channel: tuple[str, ...]


class SensorSeries(NamedTuple):
    """The samples of one sensor over a run: sample times ``t`` (K,) [s] and ``value`` (K, C)
    of its channels ``channel`` (C,); ``sensor`` itself and its items' labels ``items`` (node
    or tendon names, ``rod<r>``)."""

    sensor: Sensor
    items: tuple[str, ...]
    channel: tuple[str, ...]
    t: np.ndarray
    value: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class Measurements:
    """The samples of a set of sensors (:func:`measure`, :meth:`SensorReader.measurements`),
    each at its own times."""

    series: tuple[SensorSeries, ...]

    @property
    def channel(self) -> tuple[str, ...]:
        """Every channel's name, sensor by sensor."""
        return tuple(name for s in self.series for name in s.channel)

    def channels(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Each channel by name: its sample times (K,) [s] and values (K,)."""
        return {name: (s.t, s.value[:, c]) for s in self.series for c, name in enumerate(s.channel)}

    def held(self, t: Any) -> np.ndarray:
        """Every channel at the times ``t`` (T,) [s] as the sensors show them, each sample held
        until the next: (T, C), NaN before a sensor's first sample."""
        times = np.asarray(t, dtype=float).reshape(-1)
        columns = []
        for s in self.series:
            index = np.searchsorted(s.t, times + TIME_TOLERANCE, side="right") - 1
            block = np.full((times.size, len(s.channel)), math.nan)
            block[index >= 0] = s.value[index[index >= 0]]
            columns.append(block)
        return np.concatenate(columns, axis=1) if columns else np.zeros((times.size, 0))


class _Bound(NamedTuple):
    """A sensor fitted to a structure: its items' indices and labels, its channels, its noise
    and bias per channel, where its signal sits in the reader's signal vector."""

    sensor: Sensor
    selected: np.ndarray  # nodes, tendons, rods or contact pairs (one per channel for contacts)
    items: tuple[str, ...]
    channel: tuple[str, ...]
    noise: np.ndarray
    bias: np.ndarray
    span: slice


def _per_channel(value: float | tuple[float, ...], channels: int, field: str) -> np.ndarray:
    if isinstance(value, tuple):
        if len(value) != channels:
            raise ValueError(
                f"{field}: expected one number or {channels} (one per channel), got {len(value)}"
            )
        return np.array(value)
    return np.full(channels, float(value))


def _nodes(structure: Structure, given: tuple[str | int, ...] | None) -> np.ndarray:
    if given is None:
        return np.arange(structure.n_nodes)
    try:
        index = [structure.node_index(node) for node in given]
    except (KeyError, TypeError) as exc:
        raise ValueError(f"nodes: {exc.args[0]}") from None
    return _distinct(index, given, "nodes")


def _tendons(structure: Structure, given: tuple[str | int, ...] | None) -> np.ndarray:
    S = structure.n_tendons
    if given is None:
        return np.arange(S)
    index = []
    for tendon in given:
        if isinstance(tendon, str):
            try:
                index.append(structure.tendon_index(tendon))
            except KeyError as exc:
                raise ValueError(f"tendons: {exc.args[0]}") from None
        elif isinstance(tendon, (int, np.integer)) and not isinstance(tendon, bool):
            if not 0 <= tendon < S:
                raise ValueError(f"tendons: tendon {tendon} out of range [0, {S - 1}]")
            index.append(int(tendon))
        else:
            raise ValueError(f"tendons: expected tendon names or indices, got {tendon!r:.60}")
    return _distinct(index, given, "tendons")


def _rods(structure: Structure, given: tuple[Any, ...] | None) -> np.ndarray:
    R = structure.n_rods
    if given is None:
        return np.arange(R)
    ends = {frozenset(map(int, pair)): r for r, pair in enumerate(structure.rod_nodes)}
    index = []
    for rod in given:
        if isinstance(rod, (int, np.integer)) and not isinstance(rod, bool):
            if not 0 <= rod < R:
                raise ValueError(f"rods: rod {rod} out of range [0, {R - 1}]")
            index.append(int(rod))
            continue
        if isinstance(rod, (str, bytes)) or not isinstance(rod, Sequence) or len(rod) != 2:
            raise ValueError(f"rods: expected rod indices or pairs of end nodes, got {rod!r:.60}")
        try:
            pair = frozenset(structure.node_index(node) for node in rod)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"rods: {exc.args[0]}") from None
        if pair not in ends:
            raise ValueError(f"rods: no rod joins nodes {list(rod)!r:.60}")
        index.append(ends[pair])
    return _distinct(index, given, "rods")


def _distinct(index: list[int], given: tuple[Any, ...], field: str) -> np.ndarray:
    array = np.array(index, dtype=np.int64)
    if np.unique(array).size != array.size:
        raise ValueError(f"{field}: each once, got {list(given)!r:.80}")
    return array


def _bind(structure: Structure, sensor: Sensor, planes: int, start: int) -> _Bound:
    """``sensor`` fitted to ``structure`` (run with ``planes`` planes), its signal at
    ``start`` of the reader's signal vector; ``ValueError`` naming the field that does not
    fit."""
    kind, name = sensor.kind, sensor.name
    if kind == "contact" and sensor.nodes is None:  # every rod end and point mass
        index = np.concatenate([structure.rod_nodes.reshape(-1), structure.point_mass_nodes])
        items = tuple(structure.node_name[i] for i in index)
    elif kind in ("position", "velocity", "contact"):
        index = _nodes(structure, sensor.nodes)
        items = tuple(structure.node_name[i] for i in index)
    elif kind in ("length", "tension"):
        index = _tendons(structure, sensor.tendons)
        items = tuple(structure.tendon_name[i] for i in index)
    else:
        index = _rods(structure, sensor.rods)
        items = tuple(f"rod{r}" for r in index)
    if kind in ("length", "tension"):
        channel = tuple(f"{name}.{item}" for item in items)
    elif kind == "contact":
        index, channel = _contact_pairs(structure, sensor, index, items, planes)
    else:  # a vector per item: positions and velocities in the structure's dimension
        components = "xyz"[: structure.dim if kind in ("position", "velocity") else 3]
        channel = tuple(f"{name}.{item}.{c}" for item in items for c in components)
    C = len(channel)
    return _Bound(
        sensor,
        index,
        items,
        channel,
        _per_channel(sensor.noise, C, "noise"),
        _per_channel(sensor.bias, C, "bias"),
        slice(start, start + C),
    )


def _contact_pairs(
    structure: Structure, sensor: Sensor, nodes: np.ndarray, items: tuple[str, ...], planes: int
) -> tuple[np.ndarray, tuple[str, ...]]:
    """The contact pairs of ``nodes`` (pair ``c P + p``: contact point ``c`` on plane ``p``,
    the points the rods' ends, then the point masses) and their channels."""
    if planes < 1:
        raise ValueError(f"kind: a contact sensor needs a plane (the run has none): {sensor.name}")
    points = np.concatenate([structure.rod_nodes.reshape(-1), structure.point_mass_nodes])
    point_of = {int(node): c for c, node in enumerate(points)}
    pairs, channel = [], []
    for node, item in zip(nodes, items, strict=True):
        if int(node) not in point_of:
            raise ValueError(
                f"nodes: node {item!r} is no rod end or point mass: it touches nothing"
            )
        for p in range(planes):
            pairs.append(point_of[int(node)] * planes + p)
            channel.append(f"{sensor.name}.{item}" + (f".{p}" if planes > 1 else ""))
    return np.array(pairs, dtype=np.int64), tuple(channel)


def _signals(
    structure: Structure,
    bound: Sequence[_Bound],
    q: np.ndarray,
    qdot: np.ndarray,
    tension: np.ndarray | None,
    contact_mode: np.ndarray | None,
) -> np.ndarray:
    """The true signal of every channel (..., C) at states ``q``, ``qdot`` (..., n), with the
    tendons' tensions (..., S) [N] and the contact pairs' modes (..., CP) where sensors read
    them: the one computation of the online reader and of the offline measurement."""
    lead = q.shape[:-1]
    cache: dict[str, np.ndarray] = {}

    def rods() -> tuple[np.ndarray, np.ndarray]:
        if "b" not in cache:
            b = rod_coordinates(structure, q)[..., 1, :]
            b_dot = rod_coordinates(structure, qdot)[..., 1, :]
            if structure.dim == 2:
                b, b_dot = (np.concatenate([x, np.zeros_like(x[..., :1])], -1) for x in (b, b_dot))
            cache["b"], cache["b_dot"] = b, b_dot
        return cache["b"], cache["b_dot"]

    def nodes(rates: bool) -> np.ndarray:
        key = "v" if rates else "p"
        if key not in cache:
            cache[key] = nodes_from_coordinates(structure, qdot if rates else q, rates=rates)
        return cache[key]

    parts = []
    for b in bound:
        kind, index = b.sensor.kind, b.selected
        if kind in ("position", "velocity"):
            x = nodes(kind == "velocity")[..., index, :]
        elif kind == "length":
            x = tendon_lengths(structure, nodes(False))[..., index]
        elif kind == "tension":
            x = _given(tension, "tension", (*lead, structure.n_tendons))[..., index]
        elif kind == "contact":
            modes = _given(contact_mode, "contact_mode", None)
            if modes.shape[:-1] != lead or modes.shape[-1] <= index.max():
                raise ValueError(
                    f"contact_mode: expected the contact pairs' modes, shape (..., CP) with CP > "
                    f"{index.max()}, got {modes.shape}"
                )
            x = modes[..., index].astype(float)
        else:
            vector, rate = rods()
            vector, rate = vector[..., index, :], rate[..., index, :]
            squared = vector[..., 0] ** 2 + vector[..., 1] ** 2 + vector[..., 2] ** 2
            if kind == "orientation":
                x = vector / np.sqrt(squared)[..., None]
            else:
                x = np.cross(vector, rate) / squared[..., None]
        parts.append(x.reshape(*lead, -1))
    return np.concatenate(parts, axis=-1) if parts else np.zeros((*lead, 0))


def _given(value: np.ndarray | None, name: str, shape: tuple[int, ...] | None) -> np.ndarray:
    """``value`` as an array (of ``shape`` if given); ``ValueError`` naming ``name`` if
    missing or of another shape."""
    if value is None:
        raise ValueError(f"{name}: a sensor reads it; give the run's {name}")
    array = np.asarray(value, dtype=float)
    if shape is not None and array.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {array.shape}")
    return array


class _Clock:
    """One sensor's sampling: its sample times, noise generator, samples so far and the value it
    holds."""

    def __init__(self, bound: _Bound, rng: np.random.Generator) -> None:
        self.bound, self.rng = bound, rng
        self.next = 0  # index of the next sample (rated sensors)
        self.t: list[float] = []
        self.value: list[np.ndarray] = []

    def due(self, t0: float, t: float) -> list[float]:
        """The sample times not yet taken up to time ``t`` (a rated sensor's from ``t0``)."""
        rate = self.bound.sensor.rate
        if rate is None:
            return [t]
        times = []
        while (sample := t0 + self.next / rate) <= t + TIME_TOLERANCE:
            times.append(sample)
            self.next += 1
        return times

    def take(self, t: float, signal: np.ndarray) -> None:
        """A sample at time ``t`` of the true ``signal`` (C,) (at ``t - delay``)."""
        b = self.bound
        noise = self.rng.standard_normal(b.noise.size) * b.noise
        self.t.append(t)
        self.value.append(signal + b.bias + noise)

    def next_query(self, t0: float, t: float) -> float:
        """The earliest signal time [s] this sensor can still ask for, after a call at ``t``."""
        rate = self.bound.sensor.rate
        due = t if rate is None else t0 + self.next / rate
        return due - self.bound.sensor.delay


class SensorReader:
    """Sensors read online: call it at each time of a control loop or a learning environment
    with the state; it returns the latest measurement of every channel (module doc).

    Parameters
    ----------
    structure : Structure
    sensors : sequence of Sensor
        The sensors (distinct names; two position sensors never on the same node, so that a
        marker is one node's).
    planes : int
        The run's number of planes (contact sensors need at least one).
    seed : int, optional
        The noise's seed (None: fresh entropy).

    Attributes
    ----------
    channel : tuple of str
        The channels' names, in the order of each reading's values.

    Raises
    ------
    ValueError
        Naming the sensor and the field that does not fit: ``"sensors[1].nodes: no node named
        'x' (...)"``.
    """

    def __init__(
        self,
        structure: Structure,
        sensors: Sequence[Sensor],
        *,
        planes: int = 0,
        seed: int | None = None,
    ) -> None:
        if not isinstance(structure, Structure):
            raise TypeError(f"structure: expected a Structure, got {type(structure).__name__}")
        if isinstance(planes, bool) or not isinstance(planes, (int, np.integer)) or planes < 0:
            raise ValueError(f"planes: expected a whole number >= 0, got {planes!r:.60}")
        self.structure, self.planes = structure, int(planes)
        bound: list[_Bound] = []
        names: dict[str, int] = {}
        markers: dict[int, int] = {}
        start = 0
        for j, sensor in enumerate(sensors):
            if not isinstance(sensor, Sensor):
                raise TypeError(f"sensors[{j}]: expected a Sensor, got {type(sensor).__name__}")
            if sensor.name in names:
                raise ValueError(
                    f"sensors[{j}].name: {sensor.name!r} is sensors[{names[sensor.name]}]'s too "
                    "(give each sensor of a kind its own name)"
                )
            names[str(sensor.name)] = j
            try:
                b = _bind(structure, sensor, self.planes, start)
            except ValueError as exc:
                raise ValueError(f"sensors[{j}].{exc}") from None
            if sensor.kind == "position":
                for node, item in zip(b.selected, b.items, strict=True):
                    if int(node) in markers:
                        raise ValueError(
                            f"sensors[{j}].nodes: node {item!r} is a marker of "
                            f"sensors[{markers[int(node)]}] too (a marker is one node's)"
                        )
                    markers[int(node)] = j
            bound.append(b)
            start = b.span.stop
        self.bound = tuple(bound)
        self.channel = tuple(name for b in bound for name in b.channel)
        self._clocks: list[_Clock] = []
        self.reset(seed)

    @property
    def needs(self) -> frozenset[str]:
        """What a call must give beyond the state: ``"tension"``, ``"contact_mode"``."""
        kinds = {b.sensor.kind for b in self.bound}
        return frozenset(
            name for name, kind in (("tension", "tension"), ("contact_mode", "contact"))
            if kind in kinds
        )  # fmt: skip

    def reset(self, seed: int | None = None) -> None:
        """Forget every sample and the history; with ``seed``, restart the noise from it (else
        the noise goes on from where it was, as Gymnasium's ``reset(seed=None)``)."""
        if seed is not None and (
            isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0
        ):
            raise ValueError(f"seed: expected a whole number >= 0 or None, got {seed!r:.60}")
        if seed is not None or not self._clocks:
            streams = np.random.SeedSequence(seed).spawn(len(self.bound))
            generators = [np.random.default_rng(stream) for stream in streams]
        else:
            generators = [clock.rng for clock in self._clocks]
        self._clocks = [_Clock(b, g) for b, g in zip(self.bound, generators, strict=True)]
        self._t0: float | None = None
        self._times: list[float] = []
        self._history: list[np.ndarray] = []
        self._latest = np.full(len(self.channel), math.nan)

    def __call__(
        self,
        t: float,
        q: np.ndarray,
        qdot: np.ndarray,
        *,
        tension: np.ndarray | None = None,
        contact_mode: np.ndarray | None = None,
    ) -> Reading:
        """The measurements at time ``t`` [s] of the state ``q``, ``qdot`` (n,), with the
        tendons' tensions (S,) [N] and the contact pairs' modes (CP,) (the run's
        ``contact_mode`` row) if sensors read them (:attr:`needs`); times never decrease
        between calls.  Returns the :class:`Reading` (a copy)."""
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        n = (self.structure.n_coordinates,)
        if q.shape != n or qdot.shape != n:
            raise ValueError(f"q, qdot: expected shape {n}, got {q.shape} and {qdot.shape}")
        signal = _signals(self.structure, self.bound, q, qdot, tension, contact_mode)
        self._advance(_number(t, "t", low=-math.inf), signal)
        return Reading(self._latest.copy(), self.channel)

    def _advance(
        self, t: float, signal: np.ndarray, exact: Callable[[float], np.ndarray] | None = None
    ) -> None:
        """Time ``t`` [s] with the true ``signal`` (C,) of every channel: the samples due, each
        of the signal at its time (less the delay) by ``exact`` if given (a finished run's
        interpolation), else as last read up to that time."""
        if self._times and t < self._times[-1]:
            raise ValueError(f"t: {t!r} is before the last time read, {self._times[-1]!r}")
        if self._t0 is None:
            self._t0 = t
        self._times.append(t)
        self._history.append(signal)
        t0 = self._t0
        for clock in self._clocks:
            span = clock.bound.span
            for sample in clock.due(t0, t):
                query = sample - clock.bound.sensor.delay
                true = self._signal_at(query) if exact is None else exact(query)
                clock.take(sample, true[span])
            if clock.value:
                self._latest[span] = clock.value[-1]
        # forget what no sensor can ask for again
        oldest = min((c.next_query(t0, t) for c in self._clocks), default=t)
        keep = max(bisect.bisect_right(self._times, oldest + TIME_TOLERANCE) - 1, 0)
        if keep:
            del self._times[:keep], self._history[:keep]

    def _signal_at(self, t: float) -> np.ndarray:
        """The signal at time ``t`` [s]: at the last time read up to ``t``, or the first."""
        k = bisect.bisect_right(self._times, t + TIME_TOLERANCE) - 1
        return self._history[max(k, 0)]

    def measurements(self) -> Measurements:
        """Every sample taken since the last :meth:`reset`, sensor by sensor."""
        return Measurements(
            tuple(
                SensorSeries(
                    c.bound.sensor,
                    c.bound.items,
                    c.bound.channel,
                    np.array(c.t),
                    np.array(c.value).reshape(len(c.t), len(c.bound.channel)),
                )
                for c in self._clocks
            )
        )


def measure(
    result: SimulationResult, sensors: Sequence[Sensor], *, seed: int | None = None
) -> Measurements:
    """The measurements of ``sensors`` over a finished run, each at its own sample times: a
    :class:`SensorReader` (with ``seed``) called at each of the run's samples, reading the
    signal at a sample time (less its delay) that falls between two of the run's samples by
    interpolation (cubic Hermite of ``q`` with ``qdot``) instead of holding the earlier one; so
    the two agree sample for sample where the sensors sample at the run's times.

    Parameters
    ----------
    result : SimulationResult
        The run (its ``t``, ``q``, ``qdot``, ``tendon_tension``, ``contact_mode`` and planes).
    sensors : sequence of Sensor
    seed : int, optional
        The noise's seed.
    """
    reader = SensorReader(result.structure, sensors, planes=len(result.planes), seed=seed)
    needs = reader.needs
    t = np.asarray(result.t, dtype=float)
    q, qdot = np.asarray(result.q, dtype=float), np.asarray(result.qdot, dtype=float)
    tension = result.tendon_tension if "tension" in needs else None
    modes = result.contact_mode if "contact_mode" in needs else None
    signal = _signals(result.structure, reader.bound, q, qdot, tension, modes)
    exact = _interpolation(result.structure, reader.bound, t, q, qdot, tension, modes, signal)
    for time, row in zip(t, signal, strict=True):
        reader._advance(float(time), row, exact)
    return reader.measurements()


def _interpolation(
    structure: Structure,
    bound: Sequence[_Bound],
    t: np.ndarray,
    q: np.ndarray,
    qdot: np.ndarray,
    tension: np.ndarray | None,
    contact_mode: np.ndarray | None,
    signal: np.ndarray,
) -> Callable[[float], np.ndarray]:
    """The true signal (C,) at any time of a finished run sampled at ``t`` (T,): the state by
    cubic Hermite interpolation of ``q`` with ``qdot`` (``qdot`` its derivative), tensions
    linearly, contact modes held from the last sample; clamped to the run's span; at a time
    within :data:`TIME_TOLERANCE` of a sample's, that sample's ``signal`` (T, C) row."""
    keep = np.concatenate([np.diff(t) > 0, [True]])  # one sample per time (the last)
    t, q, qdot, signal = t[keep], q[keep], qdot[keep], signal[keep]
    tension = None if tension is None else np.asarray(tension, dtype=float)[keep]
    contact_mode = None if contact_mode is None else np.asarray(contact_mode)[keep]
    spline = scipy.interpolate.CubicHermiteSpline(t, q, qdot, axis=0) if t.size > 1 else None

    def at(time: float) -> np.ndarray:
        s = min(max(time, t[0]), t[-1])
        k = max(int(np.searchsorted(t, s + TIME_TOLERANCE, side="right")) - 1, 0)
        if spline is None or s - t[k] <= TIME_TOLERANCE:  # a sample's time (within 1 ns)
            return signal[k]
        qs, vs = spline(s), spline(s, 1)
        ts = None if tension is None else np.array([np.interp(s, t, c) for c in tension.T])
        ms = None if contact_mode is None else contact_mode[k]
        row = _signals(
            structure,
            bound,
            qs[None],
            vs[None],
            None if ts is None else ts[None],
            None if ms is None else ms[None],
        )
        return row[0]

    return at
