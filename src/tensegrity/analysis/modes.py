"""Natural frequencies, mode shapes, rigid-body modes, mechanisms and stability (Definition 18.1).

Modes solve ``K v = omega^2 M v`` of a :class:`~tensegrity.analysis.linearize.Linearization`
(undamped).  The 6 rigid-body motions of a free structure are known in closed form
(:func:`~tensegrity.analysis.coordinates.rigid_body_basis`); at a self-equilibrated state they
have zero stiffness exactly (``K B = 0``: checked and reported as ``rigid_residual``).  The other
``5R - 6`` modes are computed in the mass-orthogonal complement of the rigid-body motions, and
classified with the tolerance ``zero_tol`` on ``omega^2`` [1/s^2]:

- *elastic*: ``omega^2 > zero_tol``;
- *mechanism*: ``|omega^2| <= zero_tol``, a deformation that costs no energy to second order
  (for a tensegrity, what prestress must stiffen);
- *unstable*: ``omega^2 < -zero_tol``.

``zero_tol`` defaults to ``1e-8 * max(mean k / mean m_rod, max |omega^2|)``.

Stability verdict in the sense of Definition 18.1 ("an arbitrarily small initial deformation
returns to the given configuration"): *stable* if every non-rigid mode is elastic (the
equilibrium is then a strict minimum of the potential energy up to rigid-body motion: small
deformations stay small without damping and return with damping); *not stable* if there is a
mechanism (the linearization gives no restoring force along it) or an unstable mode.
:func:`stability_by_simulation` shows the same on the nonlinear model, and
:func:`measure_frequency` checks a frequency against the FFT of a nonlinear simulation.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import scipy.linalg

from tensegrity.analysis.coordinates import deformation, mass_complement
from tensegrity.analysis.linearize import Linearization, linearize
from tensegrity.physics import dynamics
from tensegrity.physics.dynamics import State

RIGID, MECHANISM, ELASTIC, UNSTABLE = "rigid", "mechanism", "elastic", "unstable"
#: Relative tolerance defining ``zero_tol`` (see the module docstring).
ZERO_RTOL = 1e-8


@dataclasses.dataclass(frozen=True, eq=False)
class ModalAnalysis:
    """Modes of a linearization, lowest first (rigid-body modes first of all).

    Attributes
    ----------
    Sizes for a free class 1 structure; ``k`` (:attr:`Linearization.n_dof`) in general.

    omega_squared : (5R,) eigenvalues ``omega^2`` [1/s^2] (0 for rigid-body modes).
    frequency_hz : (5R,) ``sqrt(max(omega^2, 0)) / 2 pi`` [Hz].
    shapes : (5R, 5R) mode shapes as columns in the reduced coordinates, ``M``-orthonormal.
    node_shapes : (5R, N, 3) node displacements of each (unit-modal-mass) shape [m].
    kind : (5R,) ``"rigid"``, ``"mechanism"``, ``"elastic"`` or ``"unstable"``.
    zero_tol : [1/s^2].  rigid_residual : ``max |K B| / max |K|`` for the rigid-body basis ``B``.
    stable : bool.  verdict : one sentence.
    """

    linearization: Linearization
    omega_squared: np.ndarray
    frequency_hz: np.ndarray
    shapes: np.ndarray
    node_shapes: np.ndarray
    kind: tuple[str, ...]
    zero_tol: float
    rigid_residual: float
    stable: bool
    verdict: str

    def count(self, kind: str) -> int:
        """Number of modes of a kind."""
        return sum(k == kind for k in self.kind)

    def __repr__(self) -> str:
        """One short line whatever the size: the modes by kind, the range of the elastic
        frequencies and the verdict's first words (up to its colon)."""
        m = self.n_mechanisms
        kinds = (
            f"{self.n_rigid} rigid, {m} mechanism{'' if m == 1 else 's'}, "
            f"{self.count(ELASTIC)} elastic, {self.n_unstable} unstable"
        )
        elastic = self.frequency_hz[[k == ELASTIC for k in self.kind]]
        hz = f", {elastic.min():.4g}..{elastic.max():.4g} Hz" if elastic.size else ""
        return (
            f"<ModalAnalysis: {len(self.kind)} modes ({kinds}){hz}, {self.verdict.split(':')[0]}>"
        )

    @property
    def n_rigid(self) -> int:
        return self.count(RIGID)

    @property
    def n_mechanisms(self) -> int:
        return self.count(MECHANISM)

    @property
    def n_unstable(self) -> int:
        return self.count(UNSTABLE)

    def elastic_indices(self) -> np.ndarray:
        """Indices of the non-rigid modes."""
        return np.array([i for i, k in enumerate(self.kind) if k != RIGID], dtype=int)

    def best_separated(self) -> int:
        """Index of the elastic mode with the largest relative gap to its neighbours (a single,
        well-separated frequency: the one to check by FFT); ``ValueError`` if there is none."""
        idx = [i for i, k in enumerate(self.kind) if k == ELASTIC]
        if not idx:
            raise ValueError(
                "no elastic mode: every non-rigid mode has zero frequency (a mechanism or unstable)"
            )
        f = self.frequency_hz[idx]
        gaps = []
        for j in range(len(idx)):
            left = f[j] - f[j - 1] if j > 0 else f[j]
            right = f[j + 1] - f[j] if j + 1 < len(idx) else f[j]
            gaps.append(min(left, right) / f[j])
        return idx[int(np.argmax(gaps))]

    def to_dict(self, *, shapes: bool = True) -> dict[str, Any]:
        """JSON-ready: frequencies [Hz], kinds, verdict and (optionally) node mode shapes."""
        modes = []
        for i in range(len(self.kind)):
            item: dict[str, Any] = {
                "index": i,
                "kind": self.kind[i],
                "frequency_hz": float(self.frequency_hz[i]),
                "omega_squared": float(self.omega_squared[i]),
            }
            if shapes:
                item["node_shape_m"] = self.node_shapes[i].tolist()
            modes.append(item)
        return {
            "stable": bool(self.stable),
            "verdict": self.verdict,
            "rigid_body_modes": self.n_rigid,
            "mechanisms": self.n_mechanisms,
            "unstable_modes": self.n_unstable,
            "zero_tol_1_s2": self.zero_tol,
            "rigid_residual": self.rigid_residual,
            "modes": modes,
        }


def modal_analysis(lin: Linearization, *, zero_tol: float | None = None) -> ModalAnalysis:
    """Natural frequencies and mode shapes, rigid-body modes and mechanisms, and the verdict."""
    s = lin.structure
    M, K = lin.mass, lin.stiffness
    rigid = lin.rigid_basis
    Z = mass_complement(rigid, M)
    lam, Y = scipy.linalg.eigh(Z.T @ K @ Z)
    V = Z @ Y
    scale_k = float(np.max(np.abs(K))) or 1.0
    rigid_residual = float(np.max(np.abs(K @ rigid)) / scale_k) if rigid.size else 0.0
    if zero_tol is None:
        masses = np.concatenate([s.rod_mass, s.node_point_mass[s.point_mass_nodes]])
        reference = float(np.mean(s.tendon_stiffness) / np.mean(masses)) if s.n_tendons else 0.0
        zero_tol = ZERO_RTOL * max(reference, float(np.max(np.abs(lam), initial=0.0)))
    kinds = [RIGID] * rigid.shape[1]
    for value in lam:
        kinds.append(ELASTIC if value > zero_tol else UNSTABLE if value < -zero_tol else MECHANISM)
    omega2 = np.concatenate([np.zeros(rigid.shape[1]), lam])
    shapes = np.hstack([rigid, V])
    node_shapes = (lin.position_jacobian @ shapes).T.reshape(-1, s.n_nodes, 3)
    n_mech = kinds.count(MECHANISM)
    n_unst = kinds.count(UNSTABLE)
    n_el = kinds.count(ELASTIC)
    freq = np.sqrt(np.maximum(omega2, 0.0)) / (2 * np.pi)
    slack = int(np.sum(~lin.taut))
    slack_note = f"; {slack} slack tendon(s) carry nothing" if slack else ""
    if n_unst:
        stable = False
        verdict = (
            f"unstable: {n_unst} mode(s) with negative stiffness (omega^2 down to "
            f"{lam.min():.4g} 1/s^2); small deformations along them grow{slack_note}"
        )
    elif n_mech:
        stable = False
        verdict = (
            f"not stable (Definition 18.1): {n_mech} mechanism(s), non-rigid modes of zero "
            f"stiffness (|omega^2| <= {zero_tol:.3g} 1/s^2) besides the "
            f"{rigid.shape[1]} rigid-body modes; a small deformation along them meets no "
            f"restoring force and does not return{slack_note}"
        )
    elif not n_el:
        stable = True
        verdict = (
            f"stable (Definition 18.1) trivially: no non-rigid mode, the {rigid.shape[1]} "
            f"degree(s) of freedom the supports leave are rigid-body motions{slack_note}"
        )
    else:
        stable = True
        verdict = (
            f"stable (Definition 18.1): all {n_el} non-rigid modes have positive stiffness "
            f"(lowest {freq[rigid.shape[1]]:.4g} Hz), {rigid.shape[1]} rigid-body modes; "
            f"small deformations return (with damping) and stay bounded (without)"
            f"{slack_note}"
        )
    return ModalAnalysis(
        lin,
        omega2,
        freq,
        shapes,
        node_shapes,
        tuple(kinds),
        float(zero_tol),
        rigid_residual,
        stable,
        verdict,
    )


# ------------------------------------------------------------------ nonlinear checks
def mode_initial_state(lin: Linearization, shape: np.ndarray, amplitude: float) -> State:
    """A state at rest, displaced along ``shape`` (k,) so that the largest node displacement is
    ``amplitude`` [m] (to first order); rods keep their lengths exactly (and the joints and
    supports hold: :meth:`Linearization.configuration`)."""
    largest = float(np.max(np.linalg.norm((lin.position_jacobian @ shape).reshape(-1, 3), axis=1)))
    eta = amplitude / largest * shape
    q, _ = lin.configuration(np.concatenate([eta, np.zeros_like(eta)]))
    return State(t=0.0, q=q, qdot=np.zeros_like(q))


@dataclasses.dataclass(frozen=True, eq=False)
class FrequencyCheck:
    """A natural frequency of the linearization against an FFT of a nonlinear simulation."""

    mode: int
    linear_hz: float
    measured_hz: float
    relative_error: float
    amplitude: float
    duration: float
    time: np.ndarray
    signal: np.ndarray  #: modal coordinate of the simulated motion [sqrt(kg) m]

    def to_dict(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "linear_hz": self.linear_hz,
            "measured_hz": self.measured_hz,
            "relative_error": self.relative_error,
            "amplitude_m": self.amplitude,
            "duration_s": self.duration,
        }


def fft_peak(t: np.ndarray, signal: np.ndarray, *, near: float | None = None) -> float:
    """Frequency [Hz] of the largest spectral peak of a uniformly sampled signal.

    Hann window, zero padding to 16x the length, and a parabola through the log-magnitude of
    the peak bin and its neighbours.  ``near``: look for the largest peak within 20% of it.
    """
    dt = float(t[1] - t[0])
    y = (signal - signal.mean()) * np.hanning(signal.size)
    n = 16 * signal.size
    spectrum = np.abs(np.fft.rfft(y, n))
    f = np.fft.rfftfreq(n, dt)
    mask = np.ones_like(f, bool) if near is None else np.abs(f - near) <= 0.2 * near
    mask[0] = False
    k = int(np.flatnonzero(mask)[np.argmax(spectrum[mask])])
    a, b, c = np.log(spectrum[k - 1 : k + 2] + 1e-300)
    offset = 0.5 * (a - c) / (a - 2 * b + c)
    return float((k + offset) * (f[1] - f[0]))


def measure_frequency(
    modes: ModalAnalysis,
    mode: int | None = None,
    *,
    amplitude: float = 1e-4,
    periods: float = 40.0,
    samples_per_period: float = 16.0,
    rtol: float = 1e-10,
) -> FrequencyCheck:
    """Excite a mode by its shape (small amplitude [m], at rest) on the *undamped* nonlinear model,
    simulate ``periods`` periods, and measure the frequency of its modal coordinate by FFT.

    ``mode``: default :meth:`ModalAnalysis.best_separated`.
    """
    from tensegrity.engine.simulate import simulate

    lin = modes.linearization
    mode = modes.best_separated() if mode is None else int(mode)
    if modes.kind[mode] != ELASTIC:
        raise ValueError(f"mode {mode} is {modes.kind[mode]}, not elastic")
    s = lin.structure
    undamped = dynamics.undamped(s)
    shape = modes.shapes[:, mode]
    initial = mode_initial_state(lin, shape, amplitude)
    f_lin = float(modes.frequency_hz[mode])
    duration = periods / f_lin
    result = simulate(
        undamped,
        (0.0, duration),
        initial=initial,
        control=lin.equilibrium.control,
        sample_dt=1.0 / (samples_per_period * f_lin),
        rtol=rtol,
        atol=1e-14,
        external_force=lin.equilibrium.external_force,
        gravity=lin.equilibrium.gravity,
    )
    if not result.success:
        raise RuntimeError(f"simulation failed: {result.message}")
    eta = lin.to_eta(lin.chart.x(result.q))  # (T, k)
    signal = eta @ (lin.mass * shape)
    measured = fft_peak(result.t, signal, near=f_lin)
    return FrequencyCheck(
        mode, f_lin, measured, abs(measured - f_lin) / f_lin, amplitude, duration, result.t, signal
    )


@dataclasses.dataclass(frozen=True, eq=False)
class StabilitySimulation:
    """A small deformation of an equilibrium, followed on the nonlinear model.

    ``deformation_*`` are RMS node distances from the equilibrium after removing rigid-body
    motion (mass-weighted Kabsch fit) [m].
    """

    initial_deformation: float
    damped_time: np.ndarray
    damped_deformation: np.ndarray
    undamped_time: np.ndarray
    undamped_deformation: np.ndarray
    returns: bool  #: damped: final deformation <= return_ratio * initial
    bounded: bool  #: undamped: max deformation <= bound
    bound: (
        float  #: the energy bound of the linearization, ``sqrt(w2_max / w2_min)`` x 1.1 x initial
    )
    return_ratio: float
    stable: bool
    verdict: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "initial_deformation_m": self.initial_deformation,
            "final_damped_deformation_m": float(self.damped_deformation[-1]),
            "max_undamped_deformation_m": float(self.undamped_deformation.max()),
            "bound_m": self.bound,
            "returns": self.returns,
            "bounded": self.bounded,
            "stable": self.stable,
            "verdict": self.verdict,
        }


def stability_by_simulation(
    modes: ModalAnalysis,
    *,
    amplitude: float = 1e-3,
    damped_time: float | None = None,
    undamped_time: float | None = None,
    return_ratio: float = 1e-2,
    shape: np.ndarray | None = None,
    seed: int = 0,
    sample_dt: float = 0.01,
    **simulate_options: Any,
) -> StabilitySimulation:
    """Deform the equilibrium by a small random combination of all non-rigid modes (largest node
    displacement ``amplitude`` [m], at rest), then simulate the nonlinear model

    - with the paper's artificial critical damping: it *returns* if the deformation falls to
      ``return_ratio`` of its initial size (default 1%) within ``damped_time`` (default: the time
      the damped linearization needs to shrink 1000-fold, at most 20 s; 5 s if it has no decay);
    - without damping: it stays *bounded* if the deformation never exceeds ``1.1 sqrt(w2_max /
      w2_min)`` times its initial size (the energy bound of the linearization) within
      ``undamped_time`` (default 10 periods of the lowest mode, at most 10 s).

    The verdict is *stable* only if both hold (with zero-stiffness modes there is no energy
    bound, and the undamped check fails).  ``shape`` (5R,): deform along it instead (e.g. a
    mechanism's mode shape, ``modes.shapes[:, i]``).  ``simulate_options`` go to ``simulate``.
    """
    from tensegrity.engine.simulate import simulate

    lin = modes.linearization
    s, eq = lin.structure, lin.equilibrium
    idx = modes.elastic_indices()
    if shape is None:
        shape = modes.shapes[:, idx] @ np.random.default_rng(seed).normal(size=idx.size)
    initial = mode_initial_state(lin, shape, amplitude)
    w = s.node_mass
    p0 = eq.node_position
    d0 = float(deformation(dynamics.nodes_from_coordinates(s, initial.q), p0, w, rigid=lin.aligned))
    w2 = modes.omega_squared[idx]
    positive = w2[w2 > modes.zero_tol]
    if damped_time is None:
        damped_time = _damped_time(lin)
    if undamped_time is None:
        undamped_time = _undamped_time(positive)
    common = dict(
        initial=initial,
        control=eq.control,
        external_force=eq.external_force,
        gravity=eq.gravity,
        sample_dt=sample_dt,
        **simulate_options,
    )
    run_d = simulate(dynamics.artificial_damping(s), (0.0, damped_time), **common)
    undamped = dynamics.undamped(s)
    run_u = simulate(undamped, (0.0, undamped_time), **common)
    dd = deformation(run_d.node_position, p0, w, rigid=lin.aligned)
    du = deformation(run_u.node_position, p0, w, rigid=lin.aligned)
    if positive.size == idx.size and positive.size:
        bound = 1.1 * float(np.sqrt(positive.max() / positive.min())) * d0
    else:
        bound = float("inf")
    returns = bool(run_d.success and dd[-1] <= return_ratio * d0)
    bounded = bool(run_u.success and np.isfinite(bound) and du.max() <= bound)
    stable = returns and bounded
    undamped_text = _undamped_text(bounded, bound, du, float(run_u.t[-1]))
    verdict = (
        f"{'stable' if stable else 'not stable'} on the nonlinear model: a deformation of "
        f"{d0:.3g} m {'returns' if returns else 'does not return'} with damping "
        f"({dd[-1]:.3g} m after {run_d.t[-1]:.3g} s) and {undamped_text}"
    )
    return StabilitySimulation(
        d0, run_d.t, dd, run_u.t, du, returns, bounded, bound, return_ratio, stable, verdict
    )


def _damped_time(lin: Linearization) -> float:
    """Default damped run [s]: until the damped linearization has shrunk 1000-fold, at most
    20 s (5 s if it does not decay)."""
    s, eq = lin.structure, lin.equilibrium
    damped = dynamics.artificial_damping(s)
    decay = _slowest_decay(linearize(damped, eq))
    return 5.0 if decay <= 0 else min(np.log(1e3) / decay, 20.0)


def _undamped_time(positive: np.ndarray) -> float:
    """Default undamped run [s]: 10 periods of the lowest of the ``positive`` ``omega^2``, at
    most 10 s (5 s without any)."""
    return min(10.0 / (np.sqrt(positive.min()) / (2 * np.pi)), 10.0) if positive.size else 5.0


def _undamped_text(bounded: bool, bound: float, du: np.ndarray, t_end: float) -> str:
    """The undamped run's part of the verdict: within the energy bound, beyond it, or no bound."""
    if bounded:
        return (
            f"stays within the bound {bound:.3g} m without (max {du.max():.3g} m "
            f"over {t_end:.3g} s)"
        )
    if np.isfinite(bound):
        return f"exceeds the bound {bound:.3g} m without damping ({du.max():.3g} m)"
    return (
        f"has no energy bound without damping (zero-stiffness modes; max "
        f"{du.max():.3g} m over {t_end:.3g} s)"
    )


def _slowest_decay(lin: Linearization) -> float:
    """Smallest decay rate ``-Re(lambda)`` [1/s] among the non-rigid eigenvalues of ``A``."""
    A, _ = lin.elastic_part()
    return float(np.min(-np.linalg.eigvals(A).real))
