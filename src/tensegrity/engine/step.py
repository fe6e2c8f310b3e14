"""One step at a time, for users who drive their own loop (as Brax's ``step`` and MuJoCo's
``mj_step``): :func:`make_model` packs a structure and its inputs once, :func:`step` advances a
:class:`~tensegrity.physics.dynamics.State` by one classical RK4 step of the compiled physics,
checked and projected onto the rod, joint and support constraints exactly as
``simulate(method="rk4")`` does, and returns a new state.

>>> from tensegrity import class1_shell, initial_state
>>> from tensegrity.engine.step import make_model, step
>>> model = make_model(class1_shell(3, 1), gravity=[0, 0, -9.81])
>>> state = initial_state(model.structure)
>>> for _ in range(1000):
...     state = step(model, state, 1e-4)
>>> round(state.t, 12), state.q.shape      # 0.1 s later, the 6 rods' coordinates [m]
(0.1, (36,))

:func:`step` is pure in what it returns (the state passed in is not changed); the model keeps
scratch buffers, so one model serves one loop at a time.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from tensegrity.engine import compiled
from tensegrity.engine.inputs import Inputs
from tensegrity.engine.system import CompiledSystem
from tensegrity.model.structure import Structure
from tensegrity.physics.dynamics import State


class StepError(RuntimeError):
    """A step blew up (the state is not finite, a rod's length or a joint broke)."""


@dataclasses.dataclass(frozen=True, eq=False)
class Model:
    """A structure with its inputs, packed for the compiled physics (:func:`make_model`)."""

    structure: Structure
    system: CompiledSystem  #: its ``model.limits`` are the step's checks
    #: scratch of a step (:func:`compiled.rk4_step`'s ``work_step``) and the end before
    #: projection (m,)
    scratch: tuple[tuple[np.ndarray, ...], np.ndarray]


def make_model(
    structure: Structure,
    *,
    control: Any = None,
    external_force: Any = None,
    gravity: Any = None,
    max_rod_length_error: float = 1e-3,
) -> Model:
    """Pack ``structure`` with its inputs (as :func:`tensegrity.engine.simulate.simulate` takes
    them: ``control`` (S,) [m], ``external_force`` (N, dim) [N] or functions of time,
    ``gravity`` (dim,) [m/s^2]).  A step fails when a relative rod-length error exceeds
    ``max_rod_length_error`` (joints and supports: that times the longest rod, >= 1 m)."""
    scale = max(float(structure.rod_length.max(initial=0.0)), 1.0)
    system = CompiledSystem(
        structure,
        Inputs(structure, control=control, external_force=external_force, gravity=gravity),
        limits=(max_rod_length_error, max_rod_length_error * scale, np.inf),
    )
    return Model(structure, system, (system.rk4_work(), np.empty(system.m)))


def step(model: Model, state: State, dt: float, *, project: bool = False) -> State:
    """``state`` advanced by one RK4 step of ``dt`` [s] (Theorem 18.1, eqs. 18.39-18.60), then
    projected onto the constraints; ``StepError`` if the step blew up.  ``project``: project
    ``state`` onto the constraints first (for a state made by hand; one returned by
    :func:`step` or :func:`~tensegrity.physics.dynamics.initial_state` is on them)."""
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt: must be a finite step > 0, got {dt!r}")
    system = model.system
    y = system.state_vector(state, project=project)
    work_step, y_end = model.scratch
    data = system.input_buffers(compiled.RK4_C.size)
    _, code, value = compiled.rk4_segment(
        system.model, data, y, y_end, work_step, False, state.t, dt, 1
    )
    if code == compiled.CHECK_INPUT:
        system.raise_input_error()
        system.inputs.rest_length(state.t + compiled.RK4_C * dt)  # (raises, naming the tendon)
    if code != compiled.CHECK_OK:
        raise StepError(
            f"the step from t = {state.t:.6g} s blew up (check {code}, value "
            f"{value:.3g}); take a smaller dt"
        )
    q, qdot = system.coordinates(y)
    return State(t=state.t + dt, q=q, qdot=qdot)
