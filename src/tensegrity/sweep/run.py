"""Parameter sweeps on Dask, of class 1 shells or of any structure file: a grid or a Monte Carlo
sample, one labeled dataset.

A :class:`SweepSpec` names the parameters that vary and the run settings; :func:`run_sweep`
builds every case, runs them in parallel on a Dask cluster (a ``distributed.LocalCluster`` by
default, or any scheduler address) and gathers one :class:`xarray.Dataset`, with per-case status
and message: a case that blows up or cannot be built is reported, the others are unaffected.

Parameters of a case (SI units; defaults in :data:`DEFAULTS`)
-------------------------------------------------------------
``n``, ``m``
    Shell size: elements around, stages up (:func:`tensegrity.model.shell.class1_shell`).
``stiffness``
    Tendon stiffness ``k`` [N/m], every tendon.
``rest_scale``
    Prestress: every tendon's rest length is ``rest_scale`` times its length in the initial layout
    (``< 1``: all tendons start stretched by the same ratio).
``damping``
    Tendon damping ``c`` [N s/m], every tendon.
``load``
    Axial compression [N]: a total force ``load`` pushes the top ring's nodes down and the bottom
    ring's nodes up, shared equally (a self-equilibrated load; no net force on the shell).

Each case starts from the initial layout at rest and runs ``simulate`` over ``(0, t_end)``.

Any structure (``SweepSpec.structure``, ``tensegrity sweep --structure FILE``): the cases are
that structure instead of a shell -- any network, with joints, supports, point masses or 2-D
nodes -- with ``stiffness``, ``rest_scale``, ``damping`` and ``load`` as above (``n`` and ``m``
cannot vary).  A parameter that is not varied keeps the file's values: its tendons' own
stiffnesses, dampings and rest lengths, and no load.  ``load`` pushes the nodes of largest
``z`` (``y`` for a 2-D structure) down and those of smallest up.

How cases run
-------------
- ``method="rk4"`` (the default): cases run through :func:`tensegrity.engine.batch.simulate_batch`
  (one engine run per case, as ``simulate``).  Shells with fewer than :data:`BATCH_MAX_RODS`
  rods: the cases of equal ``(n, m)`` form one batch per Dask worker thread; larger shells: one
  case per task (finer tasks balance the load).  A case that cannot be built is reported and
  left out of its batch.  Measured in ``benchmarks/bench_sweep.py``
  (``benchmarks/results-sweep.md``, run of 2026-11-25): since every path runs the same engine,
  grouping gains 0.96-1.06x.  ``batch=False`` runs every case on its own through ``simulate``
  (bit-for-bit what a direct ``simulate`` call returns).
- Adaptive methods (``"DOP853"``, ...), and structures the compiled kernel does not take
  (joints, supports, point masses, 2-D nodes): one task per case through ``simulate``.

The dataset
-----------
Dimension ``case`` (coordinates: one per parameter -- for a structure file, one per varied
parameter -- so ``ds.where(ds.stiffness == 100)`` works)
and ``t`` (``0, sample_dt, ..., t_end`` [s], as ``SimulationResult.t``).  Per case: ``status``
(``0`` reached ``t_end``, ``-1`` unstable, ``-2`` error: the case could not be built or run),
``message``, ``t_final`` [s], ``nsteps``, ``nfev``, ``wall_time`` [s], ``max_rod_length_error``
(relative), ``max_constraint_error`` [m] (joints and supports; 0 without them), ``batched``
(0/1).
Per case and time (NaN after a run stopped): ``kinetic_energy``, ``elastic_energy``,
``energy_error`` (energy balance minus its initial value) [J], ``max_tension`` [N],
``slack_count``, ``max_displacement`` (largest node displacement from the initial layout) [m].
Attribute ``spec``: the spec as JSON (with the whole structure, for a structure sweep).
:meth:`SweepResult.save` writes it as netCDF-4/HDF5 (``h5netcdf``) atomically; :func:`read_sweep`
reads it back, checked first as a file from someone else (:mod:`tensegrity.io.checked`).
"""

from __future__ import annotations

import contextlib
import dataclasses
import itertools
import json
import logging
import math
import os
import signal
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from tensegrity.engine.options import ADAPTIVE_METHODS, FIXED_STEP_METHODS, Options
from tensegrity.engine.simulate import SimulationResult, simulate
from tensegrity.io.checked import (
    FLOATS,
    NUMBERS,
    TEXT,
    attribute_json,
    check_attributes,
    check_read_bytes,
    hdf5_dataset,
    hdf5_names,
    open_hdf5,
)
from tensegrity.io.files import file_error, read_input
from tensegrity.model.limits import environment_limit
from tensegrity.model.shell import class1_shell
from tensegrity.model.structure import Structure
from tensegrity.physics import dynamics

if TYPE_CHECKING:
    import xarray as xr
    from distributed import Client, LocalCluster

PathLike = str | os.PathLike

#: Parameters a sweep can vary, with their values when not varied.
DEFAULTS: dict[str, float] = {
    "n": 3,
    "m": 1,
    "stiffness": 100.0,
    "rest_scale": 0.9,
    "damping": 0.0,
    "load": 0.0,
}
INTEGER_PARAMETERS = ("n", "m")
#: The parameters that can vary in a sweep of a given structure (its topology is fixed).
STRUCTURE_PARAMETERS = ("stiffness", "rest_scale", "damping", "load")
#: RK4 sweeps: shells with fewer rods than this are batched per worker, larger ones run one per
#: task.
BATCH_MAX_RODS = 1000
#: ``status`` of a case that could not be built or raised while running.
STATUS_ERROR = -2
MODES = ("grid", "monte-carlo")
SERIES = (
    "kinetic_energy",
    "elastic_energy",
    "energy_error",
    "max_tension",
    "slack_count",
    "max_displacement",
)
SCALARS = (
    "status",
    "message",
    "t_final",
    "nsteps",
    "nfev",
    "wall_time",
    "max_rod_length_error",
    "max_constraint_error",
    "batched",
)


# ------------------------------------------------------------------------------- the spec
def _number(value: Any, field: str, *, integer: bool) -> float | int:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{field}: expected a number, got {value!r}")
    if not math.isfinite(value):
        raise ValueError(f"{field}: must be finite, got {value!r}")
    if integer:
        if value != int(value):
            raise ValueError(f"{field}: expected an integer, got {value!r}")
        return int(value)
    return float(value)


#: Environment variable: the most cases a sweep runs.
MAX_CASES_VARIABLE = "TENSEGRITY_MAX_CASES"
#: The limit when the variable is not set.
DEFAULT_MAX_CASES = 1_000_000


def _check_case_count(cases: int, field: str) -> None:
    """Refuse a sweep of more than ``TENSEGRITY_MAX_CASES`` cases (default
    :data:`DEFAULT_MAX_CASES`) before its cases are made, naming ``field``."""
    limit = environment_limit(MAX_CASES_VARIABLE, DEFAULT_MAX_CASES)
    if cases > limit:
        raise ValueError(
            f"{field}: {cases:,} cases, more than the limit of {limit:,}; set "
            f"{MAX_CASES_VARIABLE} to a larger number to run them"
        )


@dataclasses.dataclass(frozen=True)
class SweepSpec:
    """What to sweep and how to run each case (validated at construction: the fields, the limits
    of a run (:meth:`tensegrity.engine.options.Options.check_span`) and the cases' parameters'
    ranges, :func:`check_cases`).

    Parameters
    ----------
    parameters : mapping of name to list of numbers
        Names from :data:`DEFAULTS`.  ``mode="grid"``: the values of each parameter; the cases are
        all combinations (in the order of the mapping, the last varying fastest).
        ``mode="monte-carlo"``: ``[low, high]`` to draw uniformly (integers inclusive for ``n``,
        ``m``), or ``[value]`` to fix it.
    mode : ``"grid"`` or ``"monte-carlo"``.
    samples : int
        Monte Carlo: number of cases (>= 1).
    seed : int
        Monte Carlo: seed of ``numpy.random.default_rng``.
    t_end : float
        Simulated time per case [s], a whole multiple of ``sample_dt``.
    sample_dt : float
        Output spacing [s].
    method : str
        ``"rk4"`` (fixed step ``dt``) or an adaptive scipy method (``rtol``, ``atol``).
    dt : float
        RK4 step [s].
    rtol, atol : float
        Tolerances of adaptive methods.
    batch : bool
        ``method="rk4"`` only: run cases through the batched compiled path (default True; free
        3-D class 1 structures only, others run through ``simulate``).
    structure : Structure, optional
        Sweep this structure instead of the class 1 shell (then only
        :data:`STRUCTURE_PARAMETERS` can vary; see the module docstring).  In the JSON/YAML form,
        a path to a structure file (relative to the spec file) or the structure's JSON form.
    """

    parameters: Mapping[str, Sequence[float]]
    mode: str = "grid"
    samples: int = 0
    seed: int = 0
    t_end: float = 0.1
    sample_dt: float = 1e-3
    method: str = "rk4"
    dt: float = 1e-4
    rtol: float = 1e-9
    atol: float = 1e-12
    batch: bool = True
    structure: Structure | None = None

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode: expected one of {', '.join(MODES)}, got {self.mode!r}")
        if not isinstance(self.parameters, Mapping) or not self.parameters:
            raise ValueError("parameters: expected a mapping of parameter names to value lists")
        clean: dict[str, tuple] = {}
        for name, values in self.parameters.items():
            field = f"parameters.{name}"
            allowed = DEFAULTS if self.structure is None else STRUCTURE_PARAMETERS
            if name not in allowed:
                why = "" if name not in DEFAULTS else " when sweeping a structure file"
                raise ValueError(
                    f"{field}: unknown parameter{why}; choose from {', '.join(allowed)}"
                )
            if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or not values:
                raise ValueError(f"{field}: expected a non-empty list of numbers")
            numbers = tuple(
                _number(v, f"{field}[{i}]", integer=name in INTEGER_PARAMETERS)
                for i, v in enumerate(values)
            )
            if self.mode == "monte-carlo" and not (
                len(numbers) == 1 or (len(numbers) == 2 and numbers[0] <= numbers[1])
            ):
                raise ValueError(
                    f"{field}: Monte Carlo needs a range low <= high (two values) or one value, "
                    f"got {list(numbers)}"
                )
            clean[name] = numbers
        object.__setattr__(self, "parameters", clean)
        for field in ("samples", "seed"):
            object.__setattr__(self, field, _number(getattr(self, field), field, integer=True))
        if self.mode == "monte-carlo" and self.samples < 1:
            raise ValueError(f"samples: must be >= 1 for Monte Carlo, got {self.samples}")
        if self.seed < 0:  # (numpy's default_rng: "expected non-negative integer")
            raise ValueError(f"seed: must be >= 0, got {self.seed}")
        _check_case_count(self.n_cases, "samples" if self.mode == "monte-carlo" else "parameters")
        for field in ("t_end", "sample_dt", "dt", "rtol", "atol"):
            value = _number(getattr(self, field), field, integer=False)
            if value <= 0:
                raise ValueError(f"{field}: must be > 0, got {value!r}")
            object.__setattr__(self, field, value)
        if self.method not in (*ADAPTIVE_METHODS, *FIXED_STEP_METHODS):
            raise ValueError(
                f"method: expected one of "
                f"{', '.join([*FIXED_STEP_METHODS, *ADAPTIVE_METHODS])}, got {self.method!r}"
            )
        ratio = self.t_end / self.sample_dt
        if not math.isfinite(ratio):
            raise ValueError(
                f"t_end: {self.t_end:g} s is too long to count its samples at sample_dt "
                f"(--sample-dt) = {self.sample_dt:g} s; use a shorter t_end (--t-end) or a larger "
                "sample_dt (--sample-dt)"
            )
        intervals = round(ratio)
        if intervals < 1 or abs(intervals * self.sample_dt - self.t_end) > 1e-9 * self.t_end:
            raise ValueError(
                f"t_end: must be a whole multiple of sample_dt (--sample-dt) = "
                f"{self.sample_dt:g} s, got {self.t_end:g} s"
            )
        # the limits every case's simulate() checks before it starts (a dt too small to advance
        # the time, too many steps or samples), checked once here
        Options(
            method=self.method,
            dt=self.dt if self.method in FIXED_STEP_METHODS else None,
            sample_dt=self.sample_dt,
            rtol=self.rtol,
            atol=self.atol,
        ).check_span(0.0, self.t_end)
        if not isinstance(self.batch, bool):
            raise ValueError(f"batch: expected true or false, got {self.batch!r}")
        if self.structure is not None and not isinstance(self.structure, Structure):
            raise ValueError(
                f"structure: expected a Structure, got {type(self.structure).__name__}"
            )
        check_cases(self.cases(), self.structure)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], *, folder: PathLike = ".") -> SweepSpec:
        """A spec from its JSON/YAML form (the field names of this class); ``structure`` is a
        structure file's path (relative to ``folder``) or a structure's JSON form."""
        if not isinstance(data, Mapping):
            raise ValueError("sweep spec: expected a mapping of fields")
        unknown = sorted(set(data) - {f.name for f in dataclasses.fields(cls)})
        if unknown:
            raise ValueError(f"{unknown[0]}: unknown sweep spec field")
        if "parameters" not in data:
            raise ValueError("parameters: missing")
        data = dict(data)
        structure = data.get("structure")
        if isinstance(structure, str):
            from tensegrity.io.formats import read_structure

            data["structure"] = read_structure(Path(folder) / structure)
        elif isinstance(structure, Mapping):
            try:
                data["structure"] = Structure.from_dict(structure)
            except ValueError as exc:
                raise ValueError(f"structure.{exc}") from None
        elif structure is not None:
            raise ValueError("structure: expected a structure file path or a structure's JSON form")
        return cls(**data)

    @classmethod
    def from_file(cls, path: PathLike) -> SweepSpec:
        """A spec from a ``.json`` or ``.yaml``/``.yml`` file (a regular file of at most
        ``TENSEGRITY_MAX_INPUT_BYTES``, :func:`tensegrity.io.files.read_input`)."""
        path = Path(path)
        try:
            text = read_input(path).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise file_error(path, f"not UTF-8 text (byte {exc.start})") from None
        try:
            if path.suffix.lower() in (".yaml", ".yml"):
                import yaml

                data = yaml.safe_load(text)
            else:
                data = json.loads(text)
        except Exception as exc:  # noqa: BLE001 - any parser error (JSONDecodeError, YAMLError)
            first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise file_error(path, f"not a valid sweep spec file ({first})") from None
        return cls.from_dict(data, folder=path.parent)

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (the structure, if any, in its own JSON form)."""
        data = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        data["parameters"] = {k: list(v) for k, v in self.parameters.items()}
        data["structure"] = None if self.structure is None else self.structure.to_dict()
        return data

    @property
    def times(self) -> np.ndarray:
        """The sample times ``0, sample_dt, ..., t_end`` [s]."""
        return np.arange(round(self.t_end / self.sample_dt) + 1) * self.sample_dt

    @property
    def n_cases(self) -> int:
        """The number of cases: ``samples`` (Monte Carlo) or the grid's size."""
        if self.mode == "monte-carlo":
            return int(self.samples)
        return math.prod(len(values) for values in self.parameters.values())

    def cases(self) -> list[dict[str, float | int]]:
        """Every case: a dict with a value for each parameter of :data:`DEFAULTS` (for a
        structure sweep, for each varied parameter only)."""
        names = list(self.parameters)
        if self.mode == "grid":
            combos = [
                dict(zip(names, values, strict=True))
                for values in itertools.product(*self.parameters.values())
            ]
        else:
            rng = np.random.default_rng(self.seed)
            draws: dict[str, list[float | int]] = {}
            for name, values in self.parameters.items():
                low, high = values[0], values[-1]
                if name in INTEGER_PARAMETERS:  # integers (__post_init__)
                    draws[name] = [
                        int(v)
                        for v in rng.integers(int(low), int(high), self.samples, endpoint=True)
                    ]
                else:
                    draws[name] = [float(v) for v in rng.uniform(low, high, self.samples)]
            combos = [{name: draws[name][i] for name in names} for i in range(self.samples)]
        if self.structure is not None:
            return combos
        return [{**DEFAULTS, **combo} for combo in combos]


# ------------------------------------------------------------------------------- one case
def case_model(
    case: Mapping[str, float],
    structure: Structure | None = None,
) -> tuple[Structure, np.ndarray | None]:
    """``(structure, external_force)`` of a case (see the module docstring): the class 1 shell of
    the case, or ``structure`` with the case's parameters applied; raises ValueError naming the
    parameter if the case is not a valid structure."""
    if structure is None:
        structure = class1_shell(
            int(case["n"]), int(case["m"]), stiffness=case["stiffness"], damping=case["damping"]
        )
    else:
        changes = {
            f"tendon_{name}": np.full(structure.n_tendons, float(case[name]))
            for name in ("stiffness", "damping")
            if name in case
        }
        try:
            structure = structure.replace(**changes)
        except ValueError as exc:  # "tendon_stiffness[0]: must be > 0": name the parameter
            raise ValueError(
                f"{', '.join(n for n in ('stiffness', 'damping') if n in case)}: {exc}"
            ) from None
    if "rest_scale" in case:
        scale = case["rest_scale"]
        if not scale >= 0:
            raise ValueError(f"rest_scale: must be >= 0, got {scale!r}")
        lengths = dynamics.tendon_lengths(structure, structure.node_position)
        structure = structure.replace(tendon_rest_length=scale * lengths)
    if case.get("load", 0.0) == 0:
        return structure, None
    up = structure.node_position[:, structure.dim - 1]
    top, bottom = np.flatnonzero(up == up.max()), np.flatnonzero(up == up.min())
    force = np.zeros((structure.n_nodes, structure.dim))
    force[top, -1] = -case["load"] / top.size
    force[bottom, -1] = case["load"] / bottom.size
    return structure, force


def check_cases(cases: Sequence[Mapping[str, float]], structure: Structure | None = None) -> None:
    """Build the models of the cases that hold each parameter's smallest and largest value
    (:func:`case_model`), before any work is sent out: a parameter out of its range (a stiffness
    <= 0, a negative damping, ...) fails here in one line naming the case, not in every case on
    the cluster.  The ranges are bounds, so these cases stand for all.

    Raises
    ------
    ValueError
        ``"case 0 (n=3, m=1, stiffness=-5, ...): tendons[0] ('t1_1_1').stiffness: must be > 0"``.
    """
    probe = {0} if cases else set()
    for name in cases[0] if cases else ():
        values = np.array([case[name] for case in cases], dtype=float)
        probe.update((int(np.argmin(values)), int(np.argmax(values))))
    for i in sorted(probe):
        try:
            case_model(cases[i], structure)
        except ValueError as exc:
            shown = ", ".join(f"{name}={value:g}" for name, value in cases[i].items())
            raise ValueError(f"case {i} ({shown}): {exc}") from None


def summarize(result: SimulationResult, times: np.ndarray) -> dict[str, Any]:
    """The per-case variables of the sweep dataset from one simulation's samples.

    Samples at the sweep's ``times`` fill the series (NaN where the run had stopped); a failing
    run's last sample (off the sample grid) only sets ``t_final``.
    """
    sample_dt = times[1] - times[0]
    index = np.rint(result.t / sample_dt).astype(int)
    on_grid = (np.abs(result.t - index * sample_dt) <= 1e-9 * sample_dt) & (index < times.size)
    rows, where = np.flatnonzero(on_grid), index[on_grid]
    displacement = np.linalg.norm(
        result.node_position - result.structure.node_position, axis=-1
    ).max(axis=1)
    values = {
        "kinetic_energy": result.energy["kinetic"],
        "elastic_energy": result.energy["elastic"],
        "energy_error": result.total_energy - result.total_energy[0],
        "max_tension": result.tendon_tension.max(axis=1),
        "slack_count": result.slack_count.astype(float),
        "max_displacement": displacement,
    }
    out: dict[str, Any] = {}
    for name, value in values.items():
        series = np.full(times.size, np.nan)
        series[where] = value[rows]
        out[name] = series
    out.update(
        status=int(result.status),
        message=result.message,
        t_final=float(result.t[-1]),
        nsteps=int(result.nsteps),
        nfev=int(result.nfev),
        wall_time=float(result.wall_time),
        max_rod_length_error=float(result.max_rod_length_error),
        max_constraint_error=float(result.max_constraint_error),
        batched=int(bool(result.settings.get("batched", False))),
    )
    return out


def _error_summary(exc: BaseException, times: np.ndarray) -> dict[str, Any]:
    out: dict[str, Any] = {name: np.full(times.size, np.nan) for name in SERIES}
    out.update(
        status=STATUS_ERROR,
        message=f"{type(exc).__name__}: {exc}",
        t_final=np.nan,
        nsteps=0,
        nfev=0,
        wall_time=0.0,
        max_rod_length_error=np.nan,
        max_constraint_error=np.nan,
        batched=0,
    )
    return out


def run_cases(cases: Sequence[Mapping[str, float]], spec: SweepSpec, batched: bool) -> list[dict]:
    """Run ``cases`` (one task's share) and return their :func:`summarize` dicts, in order.

    ``batched``: all cases share ``(n, m)`` and go through
    :func:`tensegrity.engine.batch.simulate_batch` (cases that cannot be built are reported and
    left out).  Otherwise each case runs through :func:`tensegrity.engine.simulate.simulate`.  Any
    exception of a case becomes its ``STATUS_ERROR``.
    """
    times = spec.times
    out: dict[int, dict] = {}  # case index: summary (every case gets one)
    models = {}
    for i, case in enumerate(cases):
        try:
            models[i] = case_model(case, spec.structure)
        except Exception as exc:  # noqa: BLE001 - reported per case
            out[i] = _error_summary(exc, times)
    if batched and models:
        from tensegrity.engine.batch import simulate_batch

        keys = list(models)
        try:
            results = simulate_batch(
                [models[i][0] for i in keys],
                (0.0, spec.t_end),
                dt=spec.dt,
                sample_dt=spec.sample_dt,
                external_force=[models[i][1] for i in keys],
            )
        except Exception as exc:  # noqa: BLE001 - reported for every case of the batch
            for i in keys:
                out[i] = _error_summary(exc, times)
        else:
            for i, result in zip(keys, results, strict=True):
                out[i] = summarize(result, times)
        return [out[i] for i in range(len(cases))]
    for i, (structure, force) in models.items():
        try:
            result = simulate(
                structure,
                (0.0, spec.t_end),
                method=spec.method,
                dt=(spec.dt if spec.method in FIXED_STEP_METHODS else None),
                rtol=spec.rtol,
                atol=spec.atol,
                sample_dt=spec.sample_dt,
                external_force=force,
            )
            out[i] = summarize(result, times)
        except Exception as exc:  # noqa: BLE001 - reported per case
            out[i] = _error_summary(exc, times)
    return [out[i] for i in range(len(cases))]


# ------------------------------------------------------------------------------- the sweep
@dataclasses.dataclass(frozen=True, eq=False)
class SweepResult:
    """The gathered sweep: ``dataset`` (see the module docstring) and the ``spec``."""

    dataset: xr.Dataset
    spec: SweepSpec
    wall_time: float  #: [s], the whole sweep

    @property
    def failed(self) -> list[int]:
        """Indices of the cases that did not reach ``t_end`` (unstable or error)."""
        return [int(i) for i in np.flatnonzero(self.dataset["status"].values < 0)]

    @property
    def success(self) -> bool:
        return not self.failed

    def describe_case(self, index: int) -> str:
        """``"case 3 (n=3, m=1, stiffness=100, ...)"``."""
        ds = self.dataset
        values = ", ".join(
            f"{name}={ds[name].values[index]:g}" for name in DEFAULTS if name in ds.coords
        )
        return f"case {index} ({values})"

    def save(self, path: PathLike) -> Path:
        """Write the dataset to ``path`` (netCDF-4/HDF5 via h5netcdf), atomically.

        The file is made in memory and then written by Python: HDF5 writing a file directly
        onto a disk that fills up printed a page of tracebacks and crashed the process
        (a segmentation fault) instead of raising; now a full disk is an ``OSError``."""
        import io

        from tensegrity.io.files import atomic_path

        image = io.BytesIO()
        self.dataset.to_netcdf(image, engine="h5netcdf")
        try:
            with atomic_path(path) as tmp:
                tmp.write_bytes(image.getbuffer())
        except OSError as exc:  # (named after the file asked for, not the temporary one)
            raise OSError(exc.errno, exc.strerror, os.fspath(path)) from exc
        return Path(path)


#: The kinds of data of the sweep dataset's variables, as its netCDF-4/HDF5 datasets hold them
#: (:func:`tensegrity.io.checked.hdf5_dataset`); any other variable: real numbers.
SWEEP_KINDS = {
    **dict.fromkeys(("t", *SERIES, "t_final", "wall_time"), FLOATS),
    **dict.fromkeys(("max_rod_length_error", "max_constraint_error"), FLOATS),
    "message": TEXT,
}


def read_sweep(path: PathLike) -> xr.Dataset:
    """The :class:`xarray.Dataset` a :meth:`SweepResult.save` wrote.

    The file may come from someone else: it is checked as the library's other readers check
    theirs (docs/reliability.md, "Untrusted files") before xarray reads any of it: a regular
    file, HDF5, with the ``spec`` attribute (a JSON object); every variable a dataset stored in
    the file (no external or soft link, virtual dataset or external raw storage, which would
    read other local files), of its kind of data (:data:`SWEEP_KINDS`: real floats, text;
    numbers for the others), in chunks of at most one row or 64 MiB; the variables and every
    attribute within ``TENSEGRITY_MAX_ARRAY_BYTES``.

    Raises
    ------
    ValueError
        One line starting with the file name, naming the variable or attribute at fault.
    """
    import xarray as xr

    with open_hdf5(path, "a sweep file is netCDF-4/HDF5") as f:
        _check_sweep_file(f, path)
        try:
            return xr.load_dataset(f, engine="h5netcdf")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise file_error(path, f"not a sweep file ({exc})") from None


def _check_sweep_file(f: Any, path: PathLike) -> None:
    """``ValueError`` naming the file and the object unless the open HDF5 file ``f`` has the
    sweep dataset's layout (:func:`read_sweep`); nothing of its data is read."""
    if "spec" not in f.attrs:
        raise file_error(path, "missing attribute 'spec' (not a tensegrity sweep file)")
    check_attributes(f, path)
    attribute_json(f, "spec", path)
    datasets = [
        hdf5_dataset(f, name, path, kinds=SWEEP_KINDS.get(name, NUMBERS))
        for name in hdf5_names(f, path)
    ]
    for dataset in datasets:
        check_attributes(dataset, path)
    check_read_bytes(datasets, path)


def plan(
    spec: SweepSpec, cases: Sequence[Mapping[str, float]], n_slots: int
) -> list[tuple[list[int], bool]]:
    """The tasks: ``(case indices, batched)``.

    RK4 with ``spec.batch``: the cases of each ``(n, m)`` (or all cases of a structure sweep) in
    ``n_slots`` nearly equal batches if the structure has fewer than :data:`BATCH_MAX_RODS` rods,
    else one compiled task per case.  Otherwise, and for structures the compiled kernel does not
    take, one ``simulate`` task per case.
    """
    base = spec.structure
    if spec.method in FIXED_STEP_METHODS and spec.batch and (base is None or base.is_free_class1):
        groups: dict[tuple[int, int], list[int]] = {}
        for i, case in enumerate(cases):
            key = (0, 0) if base is not None else (int(case["n"]), int(case["m"]))
            groups.setdefault(key, []).append(i)
        tasks = []
        for key, members in groups.items():
            rods = base.n_rods if base is not None else 2 * key[0] * key[1]
            parts = min(n_slots, len(members)) if rods < BATCH_MAX_RODS else len(members)
            for part in np.array_split(np.array(members), parts):
                tasks.append(([int(i) for i in part], True))
        return tasks
    return [([i], False) for i in range(len(cases))]


def _dataset(
    spec: SweepSpec, cases: Sequence[Mapping[str, float]], rows: Sequence[dict]
) -> xr.Dataset:
    import xarray as xr

    coords: dict[str, np.ndarray | tuple[Any, ...]] = {
        name: ("case", np.array([c[name] for c in cases])) for name in cases[0]
    }
    coords["case"] = np.arange(len(cases))
    coords["t"] = ("t", spec.times, {"units": "s"})
    data: dict[str, tuple[str | tuple[str, ...], np.ndarray]] = {
        name: (("case", "t"), np.array([r[name] for r in rows])) for name in SERIES
    }
    for name in SCALARS:
        values = [r[name] for r in rows]
        data[name] = ("case", np.array(values, dtype=str if name == "message" else None))
    units = dict(
        kinetic_energy="J",
        elastic_energy="J",
        energy_error="J",
        max_tension="N",
        max_displacement="m",
        t_final="s",
        wall_time="s",
        max_constraint_error="m",
        stiffness="N/m",
        damping="N s/m",
        load="N",
    )
    ds = xr.Dataset(data, coords=coords, attrs={"spec": json.dumps(spec.to_dict())})
    for name, unit in units.items():
        if name in ds.variables:
            ds[name].attrs["units"] = unit
    return ds


@contextlib.contextmanager
def _interrupts_ignored() -> Iterator[None]:
    """Ignore Ctrl-C (SIGINT) within the block, in the main thread (elsewhere signals cannot be
    set); processes started in it inherit that, and Python then leaves it so.

    Ctrl-C reaches every process of the terminal's process group: the sweep's local worker
    processes would each print the tracebacks of their interrupted event loops.  They ignore it
    instead, and this process, which the interrupt still reaches, stops them."""
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


class _Cluster:
    """A Dask client: the given one, one connected to ``scheduler``, or a new LocalCluster."""

    def __init__(
        self,
        client: Client | None,
        scheduler: str | None,
        n_workers: int | None,
        processes: bool,
    ) -> None:
        self.client, self.scheduler = client, scheduler
        self.n_workers, self.processes = n_workers, processes
        self._own: list[Client | LocalCluster] = []  # closed on exit, in this order

    def __enter__(self) -> Client:
        from distributed import Client, LocalCluster

        if self.client is not None:
            return self.client
        if self.scheduler is not None:
            self.client = Client(self.scheduler)
        else:
            with _interrupts_ignored():  # (inherited by the worker processes started here)
                cluster = LocalCluster(
                    n_workers=self.n_workers or os.cpu_count() or 1,
                    threads_per_worker=1,
                    processes=self.processes,
                    dashboard_address=":0",  # any free port
                    # quiet: a case's failure is reported in the dataset, and stopping busy
                    # workers (Ctrl-C) logs pages of warnings and errors (lost heartbeats)
                    silence_logs=logging.CRITICAL,
                )
            self._own.append(cluster)
            self.client = Client(cluster)
        self._own.insert(0, self.client)
        return self.client

    def __exit__(self, *exc: object) -> None:
        for thing in self._own:
            thing.close()


def run_sweep(
    spec: SweepSpec,
    *,
    client: Client | None = None,
    scheduler: str | None = None,
    n_workers: int | None = None,
    processes: bool = True,
    progress: bool | Callable[[int, int], None] = False,
) -> SweepResult:
    """Run every case of ``spec`` on Dask and gather one dataset.

    Parameters
    ----------
    spec : SweepSpec
    client : distributed.Client, optional
        Use this client (left open).
    scheduler : str, optional
        Address of a running Dask scheduler (``"tcp://host:8786"``) to connect to.
    n_workers : int, optional
        Workers of the default ``LocalCluster`` (default: the CPU count), one thread each.
    processes : bool
        LocalCluster workers as processes (default) or threads of this process.  Its worker
        processes ignore Ctrl-C (this process stops them) and its Dask logging is silenced.
        They are started by ``spawn``, which imports the calling script again: a script that
        runs a sweep with processes needs an ``if __name__ == "__main__":`` guard around it.
    progress : bool or callable
        True: a ``tqdm`` bar over cases on stderr; a callable receives ``(cases_done, cases)``.

    Returns
    -------
    SweepResult
        Every case, failed or not; a task that dies (e.g. its worker process is killed) marks its
        cases ``STATUS_ERROR`` with the exception as message.
    """
    from distributed import as_completed

    if client is not None and scheduler is not None:
        raise ValueError("scheduler: give a client or a scheduler address, not both")
    if n_workers is not None and n_workers < 1:
        raise ValueError(f"n_workers: must be >= 1, got {n_workers!r}")
    cases = spec.cases()  # (checked by SweepSpec: check_cases)
    rows: dict[int, dict] = {}  # case index: summary (every case is in one task)
    wall0 = time.perf_counter()
    bar = None
    if progress is True:
        from tqdm import tqdm

        bar = tqdm(total=len(cases), unit="case", desc="sweep")
    with _Cluster(client, scheduler, n_workers, processes) as dask_client:
        slots = max(1, sum(dask_client.nthreads().values()))
        tasks = plan(spec, cases, slots)
        futures = {
            dask_client.submit(run_cases, [cases[i] for i in idx], spec, batched, pure=False): idx
            for idx, batched in tasks
        }
        done = 0
        for future in as_completed(futures):
            idx = futures[future]
            try:
                summaries = future.result()
            except Exception as exc:  # noqa: BLE001 - a lost task: report its cases
                summaries = [_error_summary(exc, spec.times) for _ in idx]
            for i, summary in zip(idx, summaries, strict=True):
                rows[i] = summary
            done += len(idx)
            if bar is not None:
                bar.update(len(idx))
            elif callable(progress):
                progress(done, len(cases))
    if bar is not None:
        bar.close()
    rows_in_order = [rows[i] for i in range(len(cases))]
    return SweepResult(_dataset(spec, cases, rows_in_order), spec, time.perf_counter() - wall0)
