"""What a run or sweep costs, checked before any work: the samples limit, the steps and time of
a run (:func:`check_run_cost`), the memory of a large structure or sweep; a refusal is a
:class:`~tensegrity.cli.errors.CommandError` naming the option to change, an announcement one
line on stderr."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from tensegrity.cli.errors import CommandError
from tensegrity.engine.options import DEFAULT_MAX_SAMPLES, FIXED_STEP_METHODS, Options
from tensegrity.io.files import byte_text

if TYPE_CHECKING:
    from tensegrity.model.structure import Structure
    from tensegrity.sweep.run import SweepSpec


def check_samples(
    t_end: float,
    sample_dt: float,
    names: tuple[str, str] = ("--t-end", "--sample-dt"),
    where: str = "",
) -> None:
    """Fail up front, before any work, if a run of ``t_end`` sampled every ``sample_dt`` has
    more samples than the engine's limit (``max_samples`` of :func:`tensegrity.simulate`); the
    error names them ``names`` (in ``where``, e.g. a file).  Far beyond the limit, the run's
    bookkeeping (segment bounds, sample times) would overflow or outgrow memory."""
    samples = t_end / sample_dt + 1
    if not samples <= DEFAULT_MAX_SAMPLES:  # inf too
        t_name, dt_name = names
        raise CommandError(
            f"{where}{t_name}: {t_end:g} s at {dt_name} {sample_dt:g} s is {samples:,.0f} "
            f"samples, more than {DEFAULT_MAX_SAMPLES:,}; use a shorter {t_name} or a larger "
            f"{dt_name}"
        )


#: A run estimated to take longer than this [s] is announced on stderr before it starts.
LONG_RUN_SECONDS = 30.0


def check_run_cost(
    structure: Structure,
    t_end: float,
    options: Options,
    *,
    remedy: str = "softer tendons, a shorter --t-end, a larger --max-steps or an implicit "
    "method (--method Radau or BDF)",
) -> None:
    """Before a run of ``structure`` to ``t_end`` [s] with ``options``, by
    :func:`tensegrity.engine.budget.estimate`: refuse it if it needs more than
    ``options.max_steps`` steps or (``"rk4"``) its ``dt`` [s] is unstable, naming ``remedy``
    (what to change); say on stderr if it takes longer than :data:`LONG_RUN_SECONDS` and
    ``options.max_wall_time`` [s] (a steady-state run that may come to rest early: not)."""
    from tensegrity.engine.budget import RK4_STABLE, estimate

    method, dt, steady_state = options.method, options.dt, options.steady_state
    acceleration_tol, max_steps = options.acceleration_tol, options.max_steps
    cost = estimate(
        structure,
        t_end,
        method=method,
        dt=dt,
        atol=options.atol,
        steady_state=steady_state,
        acceleration_tol=acceleration_tol,
    )
    if cost is None:
        return
    stiffest = structure.tendon_stiffness.max(initial=0.0)
    why = f"highest rate {cost.rate:.3g} 1/s, tendons up to {stiffest:g} N/m"
    if not cost.stable:
        raise CommandError(
            f"--dt: {dt:g} s is beyond RK4's stability limit for this structure (about "
            f"{RK4_STABLE / cost.rate:.2g} s; {why}); use --dt {cost.safe_dt:.2g} or less, or an "
            "adaptive --method"
        )
    if cost.settles:
        return
    if steady_state:
        why += (
            f"; round-off of its forces keeps its accelerations above {acceleration_tol:g} m/s^2, "
            "so it cannot come to rest"
        )
    if method not in FIXED_STEP_METHODS and cost.least_steps > max_steps:
        raise CommandError(
            f"a run to {t_end:g} s needs at least {cost.least_steps:.3g} {method} steps ({why}), "
            f"more than --max-steps {max_steps:,}; use {remedy}"
        )
    seconds = min(cost.steps, max_steps) * cost.step_seconds
    if min(seconds, options.max_wall_time) > LONG_RUN_SECONDS:
        stops = (
            f", more than --max-steps {max_steps:,}: it would stop there after"
            if cost.steps > max_steps
            else ","
        )
        print(
            f"tensegrity: a long run: about {cost.steps:.3g} {method} steps{stops} about "
            f"{seconds:,.0f} s ({why}); quicker: {remedy}",
            file=sys.stderr,
        )


#: ``simulate``'s memory [bytes]: a part per member (rod or tendon) and the rest, fitted to the
#: peak resident memory of runs of 10,000, 100,000 and 300,000 members (2026-11-27, 2-core
#: machine: 224, 494 and 1,054 MB; the issue's 10^6 members: 2.5-3.6 GB).
MEMBER_BYTES = 2800


BASE_BYTES = 214 * 10**6


#: ... and its time [s] beside the steps (building, checking, writing, drawing) per member
#: (the 300,000 members' run: 27 s of its 35 s).
MEMBER_SECONDS = 90e-6


#: ``simulate`` says what a structure of at least this many members will cost before it starts.
LARGE_STRUCTURE_MEMBERS = 100_000


def available_memory() -> int | None:
    """The memory available to a new process [bytes] (Linux ``MemAvailable``), or None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as file:
            for line in file:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _refuse_beyond_memory(needed: int, what: str, purpose: str, instead: str) -> None:
    """``CommandError`` if ``needed`` [bytes] exceeds the memory available (when it can be read):
    ``"<what> needs about <needed> of memory <purpose>, more than the <available> available;
    <instead>"``."""
    available = available_memory()
    if available is not None and needed > available:
        raise CommandError(
            f"{what} needs about {byte_text(needed)} of memory {purpose}, more than the "
            f"{byte_text(available)} available; {instead}"
        )


def check_structure_size(structure: Structure) -> None:
    """Before ``simulate``'s run of a structure of :data:`LARGE_STRUCTURE_MEMBERS` members or
    more: refuse it if its memory (:data:`MEMBER_BYTES`) exceeds the memory available, else say
    on stderr how much memory and time it takes before its steps."""
    from tensegrity.engine.budget import STEP_SECONDS

    members = structure.n_rods + structure.n_tendons
    if members < LARGE_STRUCTURE_MEMBERS:
        return
    needed = BASE_BYTES + MEMBER_BYTES * members
    _refuse_beyond_memory(
        needed, f"a structure of {members:,} members", "to simulate", "simulate a smaller one"
    )
    fixed, per_member = STEP_SECONDS["DOP853"]
    print(
        f"tensegrity: a large structure: {members:,} members, about {byte_text(needed)} of "
        f"memory, {members * MEMBER_SECONDS:,.0f} s to set up and write and "
        f"{fixed + per_member * members:.2g} s a step",
        file=sys.stderr,
    )


#: ``sweep``'s memory [bytes]: a part per case (with its series' own bytes per sample) and the
#: rest, fitted to the peak resident memory of default grids of 1,000 and 4,000 cases (2026-11-27,
#: 2-core machine: 306 and 604 MB at 101 samples a case: 99 kB a case).
SWEEP_CASE_BYTES = 94_000


SWEEP_BASE_BYTES = 207 * 10**6


#: ``sweep`` says how much memory a sweep of at least this many cases takes before it starts.
LARGE_SWEEP_CASES = 10_000


def check_sweep_size(spec: SweepSpec) -> None:
    """Before a sweep of :data:`LARGE_SWEEP_CASES` cases or more (``spec``, a
    :class:`tensegrity.sweep.run.SweepSpec`): refuse it if its memory exceeds the memory
    available, else say on stderr how much it takes."""
    from tensegrity.sweep.run import SERIES

    cases = spec.n_cases
    if cases < LARGE_SWEEP_CASES:
        return
    per_case = SWEEP_CASE_BYTES + 8 * len(SERIES) * spec.times.size
    needed = SWEEP_BASE_BYTES + cases * per_case
    _refuse_beyond_memory(
        needed, f"a sweep of {cases:,} cases", "for its results", "sweep fewer cases"
    )
    print(
        f"tensegrity: a large sweep: {cases:,} cases, about {byte_text(needed)} of memory",
        file=sys.stderr,
    )
