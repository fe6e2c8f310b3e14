"""The summary a ``tensegrity simulate`` run prints when its files are written
(:func:`print_summary`): its status, samples, damping, errors, energy balance, contacts, control,
tensions, integration and checkpoints, and the members' largest utilisation; the files
themselves are :mod:`tensegrity.cli.simulate_files`'s."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from tensegrity.cli.startup import seconds_since_start
from tensegrity.model.ground import SLIP, STICK
from tensegrity.physics import dynamics

if TYPE_CHECKING:
    from tensegrity.design.materials import Factors
    from tensegrity.design.utilisation import TrajectoryUtilisation
    from tensegrity.model.structure import Structure


def print_summary(
    trajectory,
    summary,
    balance: float,
    resume: bool,
    files: Sequence[Path],
    peaks: TrajectoryUtilisation | None,
    factors: Factors | None = None,
) -> None:
    """The summary of a run: ``trajectory`` read back from its file (its last sample matters),
    the :class:`tensegrity.io.stream.StreamSummary` of the streamed run, the largest energy
    balance error [J], and the members' largest utilisation if they have a design (``peaks``,
    computed with ``factors``)."""
    structure = trajectory.structure
    e = trajectory.energy
    tension = trajectory.tendon_tension[-1]
    rows = [
        ("status", trajectory.message),
        ("samples", f"{summary.n_samples} from t = {summary.t_first:g} to {summary.t_last:.6g} s"),
        ("damping", dynamics.describe_damping(structure)),
        ("final residual acceleration", f"{trajectory.residual_acceleration[-1]:.3e} m/s^2"),
        ("final largest node speed", f"{np.abs(trajectory.node_velocity[-1]).max():.3e} m/s"),
        ("largest rod-length error", f"{summary.max_rod_length_error:.3e} (relative)"),
        *(
            [("largest joint/support error", f"{summary.max_constraint_error:.3e} m")]
            if structure.has_constraints
            else []
        ),
        ("energy dissipated", f"{e['dissipated'][-1]:.6g} J"),
        ("energy balance error", f"{balance:.3e} J"),
        *_contact_rows(trajectory),
        *_control_rows(trajectory),
        ("slack tendons at the end", f"{int(np.sum(tension <= 0))} of {structure.n_tendons}"),
        (
            "tension range at the end",
            f"{tension.min():.6g} .. {tension.max():.6g} N"
            if structure.n_tendons
            else "no tendons",
        ),
        (
            "integration",
            f"{trajectory.settings['method']}: {_counted(summary.nsteps, 'step')}, "
            f"{_counted(summary.nfev, 'evaluation')}, "
            f"{_counted(summary.nswitches, *_EVENT_NOUNS[bool(trajectory.settings.get('ground'))])}"
            " located",
        ),
        (
            "checkpoints",
            f"{_counted(summary.segments_stored, 'segment')} of up to "
            f"{_counted(summary.samples_per_segment, 'sample')}",
        ),
        *([("resumed", _resumed(summary))] if resume else []),
        ("simulation wall time", f"{summary.wall_time:.2f} s"),
        ("time to result", f"{seconds_since_start():.2f} s since the command started"),
    ]
    failures: list[str] = []
    if peaks is not None:
        more, failures = _utilisation_rows(peaks, structure)
        if factors is not None:
            more.insert(
                0,
                (
                    "utilisation factors",
                    f"safety {factors.safety:g} (divides the Euler load), strength "
                    f"{factors.strength:g} (divides the yield strengths)",
                ),
            )
        rows += more
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        print(f"{name:<{width}}  {value}")
    print("wrote " + ", ".join(str(f) for f in files))
    if failures:
        shown = "; ".join(failures[:3]) + (
            f"; and {len(failures) - 3} more" if len(failures) > 3 else ""
        )
        print(
            f"tensegrity: warning: {len(failures)} member{'s' * (len(failures) > 1)} beyond "
            f"{'their' if len(failures) > 1 else 'its'} limits (utilisation > 1): {shown}",
            file=sys.stderr,
        )


def _utilisation_rows(
    u: TrajectoryUtilisation, s: Structure
) -> tuple[list[tuple[str, str]], list[str]]:
    """The summary's rows of the members' largest utilisation over a run of ``s`` (``u``) and
    a line per member beyond its limits."""
    from tensegrity.design.utilisation import Peak

    def shown(name: str, p: Peak | None, member: Sequence[str], every: int) -> str:
        if p is None:
            return f"{name} -"
        sampled = f", from one sample in {every}" if every > 1 else ""
        return f"{name} {p.value:.4g} ({member[p.member]}, t = {p.time:.6g} s{sampled})"

    rods = [f"rod {r}" for r in range(s.n_rods)]
    tendons = [f"tendon {name!r}" for name in s.tendon_name]
    rows = [
        (
            "largest rod utilisation",
            ", ".join(
                shown(kind, p, rods, u.rod_every)
                for kind, p in (("buckling", u.rod_buckling), ("yield", u.rod_yield))
            )
            if s.n_rods
            else "no rods",
        ),
        (
            "largest tendon utilisation",
            shown("yield", u.tendon_yield, tendons, u.tendon_every)
            if s.n_tendons
            else "no tendons",
        ),
    ]
    return rows, u.failures(s)


def _control_rows(trajectory) -> list[tuple[str, str]]:
    """The summary's rows of a controlled run: its updates, and where the actuators' limits
    bound the commands (the stretches of each kind, their total time and the tendons)."""
    if not trajectory.control_tendons:
        return []
    rows = [
        (
            "control updates",
            f"{_counted(trajectory.control_time.size, 'update')} of "
            f"{_counted(len(trajectory.control_tendons), 'actuated tendon')}",
        )
    ]
    for kind, what in (
        ("bound", "at a rest-length bound"),
        ("rate", "at the rate limit"),
        ("force", "at the tension cap"),
    ):
        found = [x for x in trajectory.saturations() if x.kind == kind]
        if found:
            tendons = sorted({x.tendon for x in found})
            shown = ", ".join(tendons[:4]) + (f" and {len(tendons) - 4} more" * (len(tendons) > 4))
            total = sum(x.end - x.start for x in found)
            rows.append(
                (
                    f"saturated {what}",
                    f"{total:.4g} s summed over the tendons, {len(found)} stretches ({shown})",
                )
            )
    return rows


def _contact_rows(trajectory) -> list[tuple[str, str]]:
    """The summary's rows of a run with planes: its contact events by kind, the pairs in
    contact at the end, and the largest penetration over the samples."""
    if not trajectory.planes:
        return []
    counts = trajectory.contact_counts
    mode = trajectory.contact_mode[-1]
    return [
        (
            "contact events",
            f"{_counted(counts['touch_down'], 'touch-down')}, "
            f"{_counted(counts['lift_off'], 'lift-off')}, {_counted(counts['slip'], 'slip')}, "
            f"{_counted(counts['stick'], 'stick')}",
        ),
        (
            "contacts at the end",
            f"{int(np.sum(mode == STICK))} sticking, {int(np.sum(mode == SLIP))} slipping "
            f"of {mode.size} (rod end, plane) pairs",
        ),
        (
            "largest penetration",
            f"{max(float(trajectory.contact_penetration.max()), 0.0):.3e} m (at the samples)",
        ),
    ]


#: What ``nswitches`` counts: the tendons' switches, and with a ground the contacts' events.
_EVENT_NOUNS = {
    False: ("slack/taut switch", "slack/taut switches"),
    True: ("event (slack/taut switches, contacts)", "events (slack/taut switches, contacts)"),
}


def _counted(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun``, in the plural (default ``noun + "s"``) unless ``n`` is 1: ``1
    segment``, ``2 segments``, ``3 switches``."""
    return f"{n} {noun if n == 1 else plural or noun + 's'}"


def _resumed(summary) -> str:
    if summary.resumed_from is not None:
        return (
            f"from segment {summary.resumed_from + 1} of {summary.n_segments} "
            f"({summary.segments_run} run now)"
        )
    if summary.segments_run == 0:
        return "the run had ended already; its files written now"
    return "nothing to resume: started afresh"
