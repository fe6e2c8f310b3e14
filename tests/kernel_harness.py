"""The engine's compiled physics called from Python, for the tests and the benchmarks
(``benchmarks/`` puts this folder on its path): one evaluation of Theorem 18.1 with given rest
lengths, external forces and gravity, and the engine's checked, projected RK4 steps
(``simulate(method="rk4")``'s compiled stretch), in the structure's tendon order.

This is a harness around the engine's records (:mod:`tensegrity.physics.records`), not a second
engine: the evaluation is :func:`tensegrity.physics.kernel_system.system_rhs` and the steps are
:func:`tensegrity.engine.compiled.rk4_segment`, as a run calls them.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from tensegrity.engine import compiled
from tensegrity.model.structure import Structure
from tensegrity.physics.kernel_system import make_records, pack_system, system_project, system_rhs


class Evaluation(NamedTuple):
    """One evaluation (:meth:`CompiledKernel.evaluate`)."""

    qddot: np.ndarray  #: accelerations (n,) [m/s^2]
    tension: np.ndarray  #: tendon tensions (S,) [N], damping included, structure order
    dissipated_power: float  #: [W], >= 0
    external_power: float  #: power of the external nodal forces [W]


class Steps(NamedTuple):
    """The end of :meth:`CompiledKernel.rk4_with_work`."""

    q: np.ndarray
    qdot: np.ndarray
    dissipated_energy: float  #: energy removed by damping over the steps taken [J]
    external_work: float  #: work of the external forces over the steps taken [J]
    n_steps: int  #: steps taken (fewer than asked if a check failed)
    #: largest relative rod-length error at the end of a step, before its projection (NaN: the
    #: state was not finite)
    max_rod_length_error: float


class CompiledKernel:
    """A 3-D structure packed once; inputs given per call, tendon values in its order."""

    def __init__(self, structure: Structure) -> None:
        self.structure = structure
        self.system = pack_system(structure)
        self.packed = self.system.packed
        self.position = np.argsort(self.packed.layout.tendon_order)
        self.n = self.system.n_coordinates

    def records(self, rest, external_force=None, gravity=None, max_rod_length_error=np.inf):
        """The engine's records with these inputs (constant over a step)."""
        packed = self.packed
        force = None if external_force is None else packed.to_slots(external_force)[None]
        return make_records(
            self.system,
            rest=packed.to_kernel_order(np.asarray(rest, dtype=float))[None],
            force=force,
            gravity=gravity,
            limits=(max_rod_length_error, np.inf, np.inf),
        )

    def evaluate(self, q, qdot, rest, external_force=None, gravity=None) -> Evaluation:
        model, data = self.records(rest, external_force, gravity)
        qddot = np.empty(self.n)
        q, qdot = np.array(q, dtype=float), np.array(qdot, dtype=float)
        dissipated, external = system_rhs(model, data, 0, q, qdot, qddot)
        return Evaluation(qddot, data.tension[self.position].copy(), dissipated, external)

    def rk4_with_work(
        self,
        q,
        qdot,
        dt,
        n_steps,
        rest,
        external_force=None,
        gravity=None,
        *,
        max_rod_length_error=np.inf,
    ) -> Steps:
        """``n_steps`` RK4 steps of ``dt`` [s], each checked and projected; stops after the
        first whose rod-length error exceeds ``max_rod_length_error`` or is not finite."""
        model, data = self.records(rest, external_force, gravity, max_rod_length_error)
        n = self.n
        y = np.concatenate([q, qdot, np.zeros(3)])
        work_step = (np.zeros(y.size), np.zeros(y.size), np.zeros(n), np.zeros(y.size))
        taken, code, _ = compiled.rk4_segment(
            model, data, y, np.empty(y.size), work_step, False, 0.0, float(dt), int(n_steps)
        )
        worst = np.nan if code == compiled.CHECK_NOT_FINITE else data.monitor[2]
        return Steps(y[:n].copy(), y[n : 2 * n].copy(), y[-3], y[-2], taken, worst)

    def rk4(self, q, qdot, dt, n_steps, rest, external_force=None, gravity=None):
        steps = self.rk4_with_work(q, qdot, dt, n_steps, rest, external_force, gravity)
        return steps.q, steps.qdot

    def project(self, q, qdot):
        """``(q, qdot)`` projected onto the rod constraints (new arrays)."""
        model, data = self.records(self.structure.tendon_rest_length)
        q, qdot = np.array(q, dtype=float), np.array(qdot, dtype=float)
        system_project(model, data, q, qdot)
        return q, qdot
