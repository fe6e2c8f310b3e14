"""Fitting a structure's parameters to measured motion (identification; ``docs/identification.md``).

A fit chooses the values of some parameters of a structure -- tendon stiffness, damping and
rest length, rod and point masses, each for all members or a named group; the ground's
friction, contact stiffness and damping -- so that simulated runs reproduce what was measured:
marker positions of some nodes, tendon lengths, tensions, each at its own sample times, in one
or several experiments at once:

- :func:`parameter` reads a parameter's name (``"tendon_stiffness"``, ``"rod_mass"``,
  ``"tendon_damping:t1_*"``): its kind, and the members it sets to one common value.
- :class:`Experiment`: the measurements (markers: node name -> sample times (T,) [s] and
  positions (T, dim) [m]; lengths and tensions: tendon name -> times and values [m], [N]),
  their noise (standard deviations, the weights of the least squares), and how the run is made
  (its start state and the keywords of :func:`~tensegrity.engine.simulate.simulate`: gravity,
  loads, control, ground ...).
- :func:`fit`: weighted nonlinear least squares (``scipy.optimize.least_squares``, trust-region
  reflective, the parameters' bounds), the residuals ``(simulated - measured) / noise`` of every
  measured value.  Each run is sampled finely and read at the measurements' times by cubic
  Hermite interpolation of the node positions and velocities; lengths and tensions follow by
  the tension law.

The Jacobian is the runs' sensitivities to the parameters, integrated with the state in the
compiled engine through every located event (:mod:`tensegrity.engine.sensitivity`): one run
per experiment, costing less than ``P + 1`` plain runs (the right-hand side's analytic tangent,
:mod:`tensegrity.engine.tangent`).

The report (:class:`Fit`): the estimates with their standard errors and 95 % intervals (from the
Jacobian at the optimum: ``cov = s^2 (J^T J)^-1``, ``s^2`` the residuals' variance per degree
of freedom, Student's t quantile), the correlations, the residuals, and the fitted structure.
"""

from __future__ import annotations

import dataclasses
import fnmatch
import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import scipy.optimize
import scipy.stats
from scipy.interpolate import CubicHermiteSpline as Spline

from tensegrity.engine.inputs import Inputs
from tensegrity.engine.result import SimulationResult
from tensegrity.engine.simulate import simulate
from tensegrity.model.ground import Plane, planes_of
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import State, tendon_forces

__all__ = [
    "KINDS",
    "MEASURED",
    "Experiment",
    "Fit",
    "Parameter",
    "Simulated",
    "fit",
    "parameter",
    "simulated_measurements",
]

#: The least value of a quantity that must be > 0 (stiffness, mass, rest length).
TINY = float(np.finfo(float).tiny)

#: What can be fitted: the field of :class:`~tensegrity.model.structure.Structure` (or of
#: :class:`~tensegrity.model.ground.Plane`) each kind sets, its members (``"tendon"``,
#: ``"rod"``, ``"node"``: the nodes carrying a point mass, or ``"plane"``: every ground plane),
#: and the least value it may take.
KINDS: dict[str, tuple[str, str, float]] = {
    "tendon_stiffness": ("tendon_stiffness", "tendon", TINY),
    "tendon_damping": ("tendon_damping", "tendon", 0.0),
    "tendon_rest_length": ("tendon_rest_length", "tendon", TINY),
    "rod_mass": ("rod_mass", "rod", TINY),
    "point_mass": ("node_point_mass", "node", TINY),
    "friction": ("friction", "plane", 0.0),
    "kinetic_friction": ("kinetic_friction", "plane", 0.0),
    "contact_stiffness": ("stiffness", "plane", TINY),
    "contact_damping": ("damping", "plane", 0.0),
}

#: The run's accuracy when fitting (relative and absolute tolerances of DOP853): far below the
#: measurements' noise.
RTOL, ATOL = 1e-10, 1e-13

#: The fractions of the experiments' spans fitted in turn (:func:`fit`'s ``horizons``).
HORIZONS = (0.25, 0.5, 1.0)

#: Two estimates correlated beyond this are reported as not determined separately.
CORRELATION_LIMIT = 0.99999

#: Times this close (relative, at least 1 s scale) are the same time.
TIME_TOLERANCE = 1e-12


@dataclasses.dataclass(frozen=True)
class Parameter:
    """A quantity of a structure to fit: ``kind`` (a key of :data:`KINDS`), the ``members``
    (indices of tendons, rods or nodes carrying a point mass, sorted; none for the planes') it
    sets to one value, and its ``name`` as given."""

    name: str
    kind: str
    members: np.ndarray

    @property
    def field(self) -> str:
        """The :class:`Structure` field (or :class:`~tensegrity.model.ground.Plane` field) it
        sets."""
        return KINDS[self.kind][0]

    @property
    def scene(self) -> bool:
        """Whether it is a property of the ground planes (an experiment's ``ground``), not of
        the structure."""
        return KINDS[self.kind][1] == "plane"

    def value(self, structure: Structure, options: Mapping[str, Any]) -> float:
        """Its value in ``structure`` (or in the planes of the run ``options``' ``ground``):
        the mean over its members (SI units of the field)."""
        if self.scene:
            return float(np.mean([_plane_value(p, self.field) for p in _planes(options)]))
        return float(np.mean(getattr(structure, self.field)[self.members]))

    def apply(self, structure: Structure, value: float) -> Structure:
        """``structure`` with every member of the parameter at ``value`` (unchanged for a
        parameter of the planes)."""
        if self.scene:
            return structure
        values = np.array(getattr(structure, self.field), dtype=float)
        values[self.members] = value
        return structure.replace(**{self.field: values})

    def applied(self, options: Mapping[str, Any], value: float) -> dict[str, Any]:
        """The run ``options`` with every ground plane's field at ``value`` (unchanged for a
        parameter of the structure)."""
        if not self.scene:
            return dict(options)
        planes = [dataclasses.replace(p, **{self.field: value}) for p in _planes(options)]
        return {**options, "ground": planes}


def _planes(options: Mapping[str, Any]) -> tuple[Plane, ...]:
    """The ground planes of run ``options`` (none without ``ground``)."""
    return planes_of(options["ground"]) if options.get("ground") is not None else ()


def _plane_value(plane: Plane, field: str) -> float:
    """A plane's ``field``; its kinetic friction is its static one unless given."""
    value = getattr(plane, field)
    return float(plane.friction if value is None else value)


def parameter(structure: Structure, name: str) -> Parameter:
    """The parameter ``name`` of ``structure``: ``KIND`` (every member of its kind) or
    ``KIND:PATTERN[,PATTERN...]``, patterns of member names (shell-style wildcards, ``t1_*``;
    rods are named by their index, point masses by their nodes' names).

    Raises
    ------
    ValueError
        One line naming the unknown kind, or a pattern no member matches.
    """
    kind, _, patterns = name.partition(":")
    if kind not in KINDS:
        raise ValueError(
            f"parameter {name!r}: unknown kind {kind!r}; expected one of {', '.join(KINDS)}"
        )
    member = KINDS[kind][1]
    if member == "plane":
        if patterns:
            raise ValueError(f"parameter {name!r}: {kind} is every ground plane's; no names")
        return Parameter(name, kind, np.zeros(0, dtype=int))
    if member == "tendon":
        names = dict(enumerate(structure.tendon_name))
    elif member == "rod":
        names = {r: str(r) for r in range(structure.n_rods)}
    else:  # (the nodes carrying a point mass)
        member = "node with a point mass"
        names = {int(i): structure.node_name[i] for i in structure.point_mass_nodes}
    if not patterns:
        chosen = set(names)
    else:
        chosen = set()
        for pattern in patterns.split(","):
            found = [i for i, n in names.items() if fnmatch.fnmatchcase(n, pattern.strip())]
            if not found:
                raise ValueError(f"parameter {name!r}: no {member} matches {pattern.strip()!r}")
            chosen.update(found)
    if not chosen:
        plural = member.replace("node", "nodes") if member.startswith("node") else member + "s"
        raise ValueError(f"parameter {name!r}: the structure has no {plural}")
    return Parameter(name, kind, np.array(sorted(chosen)))


@dataclasses.dataclass(frozen=True)
class Experiment:
    """One measured run.

    Attributes
    ----------
    markers : mapping of str to (array, array)
        Node name -> ``(t (T,) [s], position (T, dim) [m])``: each marker's samples, strictly
        increasing times at or after the start.
    noise : float
        The standard deviation of a measured coordinate or length [m] (the least squares'
        weight ``1 / noise``; the reported errors use the residuals' own spread).
    initial : State or None
        The start state (default: the structure's node positions and velocities at ``t0``).
    t0 : float
        The start time [s].
    options : mapping
        Keywords of :func:`~tensegrity.engine.simulate.simulate` for the run (``gravity``,
        ``external_force``, ``control``, ``ground``, ...), not its span, start, accuracy or
        sampling; no ``controller`` or ``actuators``.
    name : str
        For the report.
    lengths : mapping of str to (array, array)
        Tendon name -> ``(t (T,) [s], length (T,) [m])``: measured tendon lengths (a cable's
        encoder, a stretch sensor), weighed by ``1 / noise``.
    tensions : mapping of str to (array, array)
        Tendon name -> ``(t (T,) [s], tension (T,) [N])``: measured tensions (a load cell),
        weighed by ``1 / tension_noise``.
    tension_noise : float
        The standard deviation of a measured tension [N].
    """

    markers: Mapping[str, tuple[np.ndarray, np.ndarray]] = dataclasses.field(default_factory=dict)
    noise: float = 1e-3
    initial: State | None = None
    t0: float = 0.0
    options: Mapping[str, Any] = dataclasses.field(default_factory=dict)
    name: str = "experiment"
    lengths: Mapping[str, tuple[np.ndarray, np.ndarray]] = dataclasses.field(default_factory=dict)
    tensions: Mapping[str, tuple[np.ndarray, np.ndarray]] = dataclasses.field(default_factory=dict)
    tension_noise: float = 0.1

    def series(self) -> dict[str, Mapping[str, tuple[np.ndarray, np.ndarray]]]:
        """Its measurements by kind (:data:`MEASURED`): markers, lengths, tensions."""
        return {"markers": self.markers, "lengths": self.lengths, "tensions": self.tensions}


#: What an experiment measures: each kind's items (nodes or tendons), the shape of one sample
#: (``"dim"``: the structure's dimension), and the :class:`Experiment` field of its noise.
MEASURED = {
    "markers": ("node", "dim", "noise"),
    "lengths": ("tendon", (), "noise"),
    "tensions": ("tendon", (), "tension_noise"),
}

#: The unit of each noise field.
NOISE_UNIT = {"noise": "m", "tension_noise": "N"}

#: Run options whose inputs a fit cannot follow (their sensitivities are not made, and the rest
#: lengths they set are the run's own).
UNFITTED_OPTIONS = ("controller", "actuators")


@dataclasses.dataclass(frozen=True)
class _Bound:
    """An experiment bound to a structure: the nodes or tendons of its measurements of each
    kind (:data:`MEASURED`) and their times, the measured values flattened in the residuals'
    order (kind by kind, item by item, time by time, coordinate by coordinate) with their
    weights, which of them are tensions, the end of its run and its sample spacing."""

    experiment: Experiment
    items: dict[str, np.ndarray]  # kind -> (items,) node or tendon indices
    times: dict[str, list[np.ndarray]]  # kind -> each item's times (T,) [s]
    measured: np.ndarray  # (values,)
    weight: np.ndarray  # (values,) 1 / noise [1/m or 1/N]
    tension: np.ndarray  # (values,) bool
    t_end: float
    sample_dt: float


#: The most samples of a run per marker sample interval (the finest spacing read by interpolation).
SAMPLES_PER_INTERVAL = 4

#: The least sample spacing of a fitted run [s].
MIN_SAMPLE_DT = 1e-3


def _bind(structure: Structure, experiment: Experiment, k: int) -> _Bound:
    """``experiment`` (the ``k``-th) checked against ``structure``; one-line errors naming the
    experiment, the marker or tendon and the row at fault."""
    where = f"experiments[{k}] ({experiment.name!r})"
    if not any(experiment.series().values()):
        raise ValueError(f"{where}: no markers, lengths or tensions")
    for field, unit in NOISE_UNIT.items():
        value = getattr(experiment, field)
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{where}: {field} must be > 0 [{unit}], got {value!r}")
    for option in UNFITTED_OPTIONS:
        if experiment.options.get(option) is not None:
            raise ValueError(
                f"{where}: options[{option!r}]: a fit follows runs without a controller or "
                "actuators (their sensitivities are not made); give the control as a table or "
                "a function of time"
            )
    items: dict[str, np.ndarray] = {}
    times: dict[str, list[np.ndarray]] = {}
    measured, weight, tension = [], [], []
    t0, dim = float(experiment.t0), structure.dim
    for kind, series in experiment.series().items():
        member, sample, noise_field = MEASURED[kind]
        shape = (dim,) if sample == "dim" else ()
        index, times[kind] = [], []
        for name, (t, value) in series.items():
            what = f"{where}: {'marker' if kind == 'markers' else kind[:-1]} {name!r}"
            try:
                index.append(
                    structure.node_index(name) if member == "node" else structure.tendon_index(name)
                )
            except KeyError:
                raise ValueError(f"{what}: no {member} of the structure has that name") from None
            t = np.asarray(t, dtype=float)
            value = np.asarray(value, dtype=float)
            if t.ndim != 1 or value.shape != (t.size, *shape):
                noun = {"markers": "positions"}.get(kind, kind)
                expected = "(T, " + ", ".join(map(str, shape)) + ")" if shape else "(T,)"
                raise ValueError(
                    f"{what}: expected times (T,) and {noun} {expected}, got {t.shape} and "
                    f"{value.shape}"
                )
            finite = np.isfinite(value).all(axis=tuple(range(1, value.ndim)))
            bad = np.flatnonzero(~np.isfinite(t) | ~finite)
            if bad.size:
                raise ValueError(f"{what}: row {bad[0]} is not finite (NaN or infinite)")
            if t.size and t[0] < t0:
                raise ValueError(f"{what}: row 0 at t = {t[0]:g} s is before the start {t0:g} s")
            late = np.flatnonzero(np.diff(t) <= 0)
            if late.size:
                raise ValueError(f"{what}: row {late[0] + 1}: times must increase")
            times[kind].append(t)
            measured.append(value.ravel())
            weight.append(np.full(value.size, 1.0 / getattr(experiment, noise_field)))
            tension.append(np.full(value.size, kind == "tensions"))
        items[kind] = np.array(index, dtype=np.int64)
    every = [t for kind in times.values() for t in kind if t.size]
    t_end = max((float(t[-1]) for t in every), default=t0)
    if t_end <= t0:
        raise ValueError(f"{where}: the measurements hold no sample after the start {t0:g} s")
    spacing = min(float(np.min(np.diff(np.concatenate([[t0], t])))) for t in every)
    sample_dt = max(MIN_SAMPLE_DT, spacing / SAMPLES_PER_INTERVAL)
    sample_dt = min(sample_dt, (t_end - t0) / 4)
    return _Bound(
        experiment,
        items,
        times,
        np.concatenate(measured),
        np.concatenate(weight),
        np.concatenate(tension),
        t_end,
        sample_dt,
    )


class Simulated(NamedTuple):
    """An experiment as a model runs it (:func:`simulated_measurements`)."""

    #: (values,) the measurements as simulated, flattened as the residuals (markers, lengths,
    #: tensions; item by item, time by time, coordinate by coordinate) [m, N]
    values: np.ndarray
    run: SimulationResult  #: the run
    #: (values, P) their derivatives with respect to the parameters asked for, or None
    jacobian: np.ndarray | None


def simulated_measurements(
    structure: Structure,
    experiment: Experiment,
    *,
    parameters: Sequence[str | Parameter] | None = None,
) -> Simulated:
    """The run of ``structure`` for ``experiment`` and its measurements as simulated at their
    sample times; with ``parameters`` (names, :func:`parameter`, or :class:`Parameter` s),
    their derivatives too (the sensitivities integrated with the run, as :func:`fit`'s
    Jacobian).

    Raises
    ------
    ValueError
        A bad experiment or parameter (as :func:`fit`).
    RuntimeError
        If the run fails (its message).
    """
    chosen = None
    if parameters is not None:
        chosen = [p if isinstance(p, Parameter) else parameter(structure, p) for p in parameters]
    return Simulated(*_run(structure, _bind(structure, experiment, 0), sensitivity=chosen))


def _run(
    structure: Structure,
    b: _Bound,
    options: Mapping[str, Any] | None = None,
    *,
    sensitivity: Sequence[Parameter] | None = None,
) -> tuple[np.ndarray, SimulationResult, np.ndarray | None]:
    """:func:`simulated_measurements` of a bound experiment (with other run ``options`` than its
    own, if given), and with ``sensitivity`` their derivatives (values, P) with respect to
    those parameters (integrated with the run, :mod:`tensegrity.engine.sensitivity`).

    The node positions between the run's samples are cubic Hermite interpolations of its
    positions and velocities, the velocities that interpolation's derivative; their
    sensitivities are interpolated the same way.  Lengths and tensions follow from them by the
    tension law (:func:`~tensegrity.physics.dynamics.tendon_forces`) with the run's rest
    lengths at those times."""
    e = b.experiment
    options = dict(e.options if options is None else options)
    result = simulate(
        structure,
        (e.t0, b.t_end),
        initial=e.initial,
        rtol=RTOL,
        atol=ATOL,
        sample_dt=b.sample_dt,
        sensitivity=sensitivity,
        **options,
    )
    if result.status < 0 or result.t[-1] < b.t_end - TIME_TOLERANCE * max(1.0, abs(b.t_end)):
        raise RuntimeError(f"experiment {e.name!r}: the run failed: {result.message}")
    position = velocity = None
    if sensitivity is not None:  # (T, P, N, dim)
        position = result.node_position_sensitivity()
        velocity = result.node_velocity_sensitivity()

    def motion(nodes: np.ndarray) -> tuple[Spline, Spline | None]:
        """The interpolated motion of ``nodes`` (their positions; its derivative the
        velocities) and of their sensitivities (None without)."""
        x = Spline(result.t, result.node_position[:, nodes], result.node_velocity[:, nodes], axis=0)
        if position is None or velocity is None:
            return x, None
        return x, Spline(result.t, position[:, :, nodes], velocity[:, :, nodes], axis=0)

    values, derivatives, dim = [], [], structure.dim
    for node, t in zip(b.items["markers"], b.times["markers"], strict=True):
        x, dx = motion(np.array([node]))
        values.append(x(t).ravel())
        if dx is not None:  # (T, P, 1, dim) -> (T * dim, P), the residuals' order
            derivatives.append(dx(t)[:, :, 0].transpose(0, 2, 1).reshape(t.size * dim, -1))
    inputs = Inputs(structure, control=options.get("control"))
    for kind in ("lengths", "tensions"):
        for tendon, t in zip(b.items[kind], b.times[kind], strict=True):
            x, dx = motion(structure.tendon_nodes[tendon])
            value, derivative = _tendon_measurement(
                structure, kind, tendon, inputs.rest_length(t), (x, dx), t, sensitivity
            )
            values.append(value)
            derivatives.append(derivative)
    jacobian = np.concatenate(derivatives) if sensitivity is not None else None
    return np.concatenate(values), result, jacobian


def _tendon_measurement(
    structure: Structure,
    kind: str,
    tendon: int,
    rest: np.ndarray,
    motion: tuple[Spline, Spline | None],
    t: np.ndarray,
    parameters: Sequence[Parameter] | None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Tendon ``tendon``'s length [m] or tension [N] (``kind``: ``"lengths"``, ``"tensions"``)
    at the times ``t`` (K,) [s]: from the motion of its two nodes (``motion``: their positions,
    whose derivative is their velocities, and their sensitivities to ``parameters`` or None)
    and the rest lengths ``rest`` (K or 1, S) [m] there, by the tension law
    (:func:`~tensegrity.physics.dynamics.tendon_forces`).  With sensitivities, the values'
    derivatives (K, P): the length's ``u . d(x_b - x_a)``, the tension's ``k (dl - dLbar) + (l -
    Lbar) dk + c dl' + l' dc`` while it pulls (0 while slack), ``dk``, ``dc``, ``dLbar`` 1 for a
    parameter setting this tendon's stiffness, damping or rest length; else None."""
    x, dx = motion
    p = np.zeros((t.size, structure.n_nodes, structure.dim))
    v = np.zeros_like(p)
    ends = structure.tendon_nodes[tendon]  # (tail, head)
    p[:, ends], v[:, ends] = x(t), x(t, 1)
    forces = tendon_forces(structure, p, v, rest)
    length, direction = forces.length[:, tendon], forces.direction[:, tendon]
    value = length if kind == "lengths" else forces.tension[:, tendon]
    if dx is None or parameters is None:
        return value, None
    dp = dx(t)  # (K, P, 2, dim)
    d_span = dp[:, :, 1] - dp[:, :, 0]
    d_length = np.einsum("kd,kpd->kp", direction, d_span)
    if kind == "lengths":
        return value, d_length
    dv = dx(t, 1)
    with np.errstate(divide="ignore", invalid="ignore"):  # (a tendon of no length: 0 below)
        d_direction = (d_span - direction[:, None] * d_length[:, :, None]) / length[:, None, None]
    d_rate = np.einsum("kpd,kd->kp", d_direction, v[:, ends[1]] - v[:, ends[0]]) + np.einsum(
        "kd,kpd->kp", direction, dv[:, :, 1] - dv[:, :, 0]
    )
    own = {  # (P,) 1 where a parameter sets this tendon's field
        field: np.array([q.kind == field and tendon in q.members for q in parameters], float)
        for field in ("tendon_stiffness", "tendon_damping", "tendon_rest_length")
    }
    stretch = length - np.broadcast_to(rest[:, tendon], length.shape)
    derivative = (
        structure.tendon_stiffness[tendon] * (d_length - own["tendon_rest_length"])
        + stretch[:, None] * own["tendon_stiffness"]
        + structure.tendon_damping[tendon] * d_rate
        + forces.length_rate[:, tendon, None] * own["tendon_damping"]
    )
    return value, np.where(value[:, None] > 0, derivative, 0.0)


@dataclasses.dataclass(frozen=True, eq=False)
class Fit:
    """The result of :func:`fit`.

    Attributes
    ----------
    parameters : tuple of Parameter
        The fitted parameters.
    initial : (P,) array
        Their starting values.
    estimate : (P,) array
        The fitted values (SI units of each field).
    standard_error : (P,) array
        From the Jacobian at the optimum.
    interval : (P, 2) array
        95 % confidence intervals (Student's t with ``n - P`` degrees of freedom), within the
        bounds.
    bounds : (P, 2) array
        The bounds the estimates were kept in.
    correlation : (P, P) array
        Of the estimates.
    residual : (n,) array
        ``(simulated - measured) / noise`` of every measured value at the optimum.
    rms_error : float
        The root mean square of ``simulated - measured`` of the marker coordinates and lengths
        [m] (NaN without any).
    rms_tension_error : float
        Of the tensions [N] (NaN without any).
    structure : Structure
        The fitted structure.
    options : tuple of dict
        Each experiment's run options with the fitted parameters of the ground planes (its
        ``ground``).
    status, message : int, str
        ``scipy.optimize.least_squares``'s.
    nfev, njev : int
        Residual and Jacobian evaluations (a Jacobian is one run per experiment with its
        sensitivities).
    """

    parameters: tuple[Parameter, ...]
    initial: np.ndarray
    estimate: np.ndarray
    standard_error: np.ndarray
    interval: np.ndarray
    bounds: np.ndarray
    correlation: np.ndarray
    residual: np.ndarray
    rms_error: float
    rms_tension_error: float
    structure: Structure
    options: tuple[dict[str, Any], ...]
    status: int
    message: str
    nfev: int
    njev: int

    @property
    def success(self) -> bool:
        """Whether the least squares converged."""
        return self.status > 0

    def undetermined(self) -> list[str]:
        """Sentences naming the parameters the data do not determine: an estimate at a bound,
        a standard error not below the estimate's size (or not finite), or two estimates
        correlated beyond
        :data:`CORRELATION_LIMIT` (e.g. every stiffness and mass scaled together, when no known
        force sets the scale)."""
        names = [p.name for p in self.parameters]
        found = []
        for name, value, error, (low, high) in zip(
            names, self.estimate, self.standard_error, self.bounds, strict=True
        ):
            if value <= low or value >= high:
                side = "lower" if value <= low else "upper"
                found.append(
                    f"{name} ended at its {side} bound {value:.6g}: the data would take it "
                    "further (the model may lack something the data show)"
                )
            elif not error < abs(value):
                found.append(
                    f"{name} is not determined by the data (standard error {error:.3g} against "
                    f"the estimate {value:.6g})"
                )
        for i in range(len(names)):
            for j in range(i):
                c = self.correlation[i, j]
                if np.isfinite(c) and abs(c) > CORRELATION_LIMIT:
                    found.append(
                        f"{names[j]} and {names[i]} are not determined separately by the data "
                        f"(correlation {c:.5f}); add a known force or mass, or fit one of them"
                    )
        return found

    def rms_summary(self) -> str:
        """The root mean square errors in words: ``"0.000983 m, 0.115 N"`` (each kind of
        measurement there is)."""
        return ", ".join(
            f"{value:.3g} {unit}"
            for value, unit in ((self.rms_error, "m"), (self.rms_tension_error, "N"))
            if np.isfinite(value)
        )

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready report."""
        return dict(
            success=self.success,
            message=self.message,
            nfev=self.nfev,
            njev=self.njev,
            rms_error_m=_finite(self.rms_error),
            rms_tension_error_n=_finite(self.rms_tension_error),
            parameters=[
                dict(
                    name=p.name,
                    kind=p.kind,
                    members=p.members.tolist(),
                    initial=float(self.initial[i]),
                    estimate=float(self.estimate[i]),
                    standard_error=_finite(self.standard_error[i]),
                    interval_95=[_finite(x) for x in self.interval[i]],
                )
                for i, p in enumerate(self.parameters)
            ],
            correlation=[[_finite(x) for x in row] for row in self.correlation],
            undetermined=self.undetermined(),
        )


def _samples(experiment: Experiment, t0: float) -> int:
    """The number of ``experiment``'s samples (markers, lengths, tensions) after ``t0`` [s]."""
    return sum(
        int(np.sum(np.asarray(t, dtype=float) > t0))
        for series in experiment.series().values()
        for t, _ in series.values()
    )


def _rms(x: np.ndarray) -> float:
    """The root mean square of ``x`` (NaN if empty)."""
    return float(np.sqrt(np.mean(x**2))) if x.size else math.nan


def _finite(x: float) -> float | None:
    """``x`` as a float, None if not finite (JSON has no infinity)."""
    return float(x) if np.isfinite(x) else None


def _until(experiment: Experiment, t: float) -> Experiment:
    """``experiment`` with its samples up to time ``t`` [s] (markers and tendons left without
    one are dropped)."""

    def kept(series: Mapping[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, Any]:
        out = {}
        for name, (times, value) in series.items():
            times = np.asarray(times, dtype=float)
            keep = times <= t + TIME_TOLERANCE * max(1.0, abs(t))
            if keep.any():
                out[name] = (times[keep], np.asarray(value, dtype=float)[keep])
        return out

    return dataclasses.replace(
        experiment,
        markers=kept(experiment.markers),
        lengths=kept(experiment.lengths),
        tensions=kept(experiment.tensions),
    )


def _inverse_normal_matrix(J: np.ndarray) -> np.ndarray:
    """``(J^T J)^-1`` by the singular values of ``J``, those below its rank tolerance (numpy's
    ``matrix_rank``) raised to it: along a direction the data do not determine (an exact
    Jacobian's columns exactly dependent) the variance is then huge, and positive, instead of
    round-off of either sign."""
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    tol = sv.max(initial=0.0) * max(J.shape) * np.finfo(float).eps
    sv = np.maximum(sv, tol if tol > 0 else np.finfo(float).tiny)
    return (Vt.T / sv**2) @ Vt


def fit(
    structure: Structure,
    experiments: Experiment | Sequence[Experiment],
    parameters: Sequence[str | Parameter],
    *,
    initial: Sequence[float] | None = None,
    bounds: Sequence[tuple[float, float]] | None = None,
    max_nfev: int = 50,
    horizons: Sequence[float] = HORIZONS,
) -> Fit:
    """Fit ``parameters`` of ``structure`` to the measurements of ``experiments`` (see the module
    docstring).

    Parameters
    ----------
    structure : the model; its values of the parameters are the starting guess unless
        ``initial`` gives one.
    experiments : one or several measured runs, fitted together.
    parameters : names (:func:`parameter`) or :class:`Parameter` s; no member may be in two of
        the same kind.
    initial : (P,) starting values, optional.
    bounds : (P,) ``(low, high)`` pairs, optional; default from the least value of each kind
        (:data:`KINDS`) to infinity, a kinetic friction fitted alone up to the planes' static
        one, a static friction fitted alone down to their kinetic one.
    max_nfev : the most residual evaluations of each least squares.
    horizons : the fits are made in turn on the data up to these fractions of each
        experiment's span (increasing, the last 1), each from the last one's estimate: a long
        run's residuals have many local minima in the parameters (the motion's phase slips by
        whole periods), a short one's few.

    Raises
    ------
    ValueError
        One line: a bad parameter, experiment (a controller or actuators among its options),
        marker, tendon series, start or bound, or fewer measured values than parameters.
    RuntimeError
        A run failed (at the starting values, or at values the search tried): its message.
    """
    given = [experiments] if isinstance(experiments, Experiment) else list(experiments)
    if not given:
        raise ValueError("experiments: give at least one")
    chosen = tuple(p if isinstance(p, Parameter) else parameter(structure, p) for p in parameters)
    if not chosen:
        raise ValueError("parameters: give at least one")
    for i, p in enumerate(chosen):
        for q in chosen[:i]:
            if p.kind == q.kind and (p.scene or np.intersect1d(p.members, q.members).size):
                raise ValueError(f"parameters: {q.name!r} and {p.name!r} share members")
    for p in chosen:
        for k, e in enumerate(given):
            if p.scene and not _planes(e.options):
                raise ValueError(
                    f"parameter {p.name!r}: experiments[{k}] ({e.name!r}) has no ground planes "
                    "(its options' 'ground')"
                )
    P = len(chosen)
    x0 = np.array(
        [p.value(structure, given[0].options) for p in chosen]
        if initial is None
        else np.asarray(initial, dtype=float)
    )
    if x0.shape != (P,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"initial: expected {P} finite values, got {initial!r}")
    low = np.array([KINDS[p.kind][2] for p in chosen], dtype=float)
    high = np.full(P, np.inf)
    kinds = [p.kind for p in chosen]
    planes = [plane for e in given for plane in _planes(e.options)]
    for j, kind in enumerate(kinds):  # kinetic friction never above the static one held fixed
        if kind == "kinetic_friction" and "friction" not in kinds:
            high[j] = min(plane.friction for plane in planes)
        if kind == "friction" and "kinetic_friction" not in kinds:
            low[j] = max(float(plane.kinetic_friction) for plane in planes)  # type: ignore[arg-type]
    if bounds is not None:
        if len(bounds) != P:
            raise ValueError(f"bounds: expected {P} (low, high) pairs, got {len(bounds)}")
        low, high = (np.array(side, dtype=float) for side in zip(*bounds, strict=True))
    if np.any(low >= high) or np.any(x0 < low) or np.any(x0 > high):
        raise ValueError("initial: each starting value must lie within its bounds (low < high)")
    spans = np.asarray(horizons, dtype=float)
    if not (spans.ndim == 1 and spans.size and np.all(np.diff(spans) > 0) and spans[0] > 0):
        raise ValueError(f"horizons: expected increasing fractions in (0, 1], got {horizons!r}")
    if spans[-1] != 1.0:
        raise ValueError(f"horizons: the last must be 1 (all the data), got {horizons!r}")
    bound = [_bind(structure, e, k) for k, e in enumerate(given)]
    measured = np.concatenate([b.measured for b in bound])
    if measured.size <= P:
        raise ValueError(
            f"experiments: {measured.size} measured values for {P} parameters; need more"
        )

    def structure_at(x: np.ndarray) -> Structure:
        s = structure
        for p, value in zip(chosen, x, strict=True):
            s = p.apply(s, float(value))
        return s

    def options_at(experiment: Experiment, x: np.ndarray) -> dict[str, Any]:
        options = dict(experiment.options)
        for p, value in zip(chosen, x, strict=True):
            options = p.applied(options, float(value))
        return options

    def solve(bound: list[_Bound], start: np.ndarray) -> scipy.optimize.OptimizeResult:
        """The weighted least squares of the bound experiments from ``start``."""
        weights = np.concatenate([b.weight for b in bound])
        measured = np.concatenate([b.measured for b in bound])

        def simulated(x: np.ndarray) -> np.ndarray:
            s = structure_at(x)
            return np.concatenate([_run(s, b, options_at(b.experiment, x))[0] for b in bound])

        def jacobian(x: np.ndarray) -> np.ndarray:
            s = structure_at(x)
            columns = []
            for b in bound:
                derivatives = _run(s, b, options_at(b.experiment, x), sensitivity=chosen)[2]
                assert derivatives is not None  # (asked for)
                columns.append(derivatives)
            return np.concatenate(columns) * weights[:, None]

        return scipy.optimize.least_squares(
            lambda x: (simulated(x) - measured) * weights,
            start,
            jac=jacobian,
            bounds=(low, high),
            x_scale="jac",
            method="trf",
            max_nfev=max_nfev,
        )

    x, nfev, njev = x0, 0, 0
    for fraction in horizons:  # the data up to a growing horizon, each from the last estimate
        part = [
            _bind(structure, shortened, k)
            for k, (e, b) in enumerate(zip(given, bound, strict=True))
            if _samples(shortened := _until(e, e.t0 + fraction * (b.t_end - e.t0)), e.t0)
        ]
        if fraction < 1 and sum(b.measured.size for b in part) <= P:
            continue  # too few samples so early: the next horizon
        solution = solve(part, x)
        x, nfev, njev = solution.x, nfev + solution.nfev, njev + solution.njev
    weights = np.concatenate([b.weight for b in bound])
    tension = np.concatenate([b.tension for b in bound])
    r, J = solution.fun, solution.jac
    dof = max(measured.size - P, 1)
    variance = float(r @ r) / dof  # per weighted coordinate: 1 when the noise is as given
    covariance = variance * _inverse_normal_matrix(J)
    error = np.sqrt(np.diag(covariance))
    quantile = float(scipy.stats.t.ppf(0.975, dof))
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(error, error)
    x = solution.x
    return Fit(
        parameters=chosen,
        initial=x0,
        estimate=x,
        standard_error=error,
        interval=np.stack(
            [np.maximum(x - quantile * error, low), np.minimum(x + quantile * error, high)], axis=1
        ),
        bounds=np.stack([low, high], axis=1),
        correlation=correlation,
        residual=r,
        rms_error=_rms(r[~tension] / weights[~tension]),
        rms_tension_error=_rms(r[tension] / weights[tension]),
        structure=structure_at(x),
        options=tuple(options_at(e, x) for e in given),
        status=int(solution.status),
        message=str(solution.message),
        nfev=int(nfev),
        njev=int(njev),
    )
