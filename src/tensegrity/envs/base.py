"""The base environment (:class:`TensegrityEnv`): any structure, a :class:`Task`, its actuated
cables, the ground and the control period, stepped by the compiled engine
(:class:`~tensegrity.engine.live.Live`) as a :class:`gymnasium.Env` (``docs/environments.md``).

An action is the commanded rest lengths of the actuated cables, scaled to ``[-1, 1]`` over the
actuators' bounds (``-1`` the longest rest length, ``+1`` the shortest); actions outside are
clipped.  The command is held over each control period and the actuators follow it in the
engine (their rate limits and lags, :mod:`tensegrity.model.actuators`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any, Protocol

import gymnasium
import numpy as np
from gymnasium import spaces

from tensegrity.engine.live import EngineError, Live
from tensegrity.engine.loop import Feedback
from tensegrity.engine.result import SimulationResult
from tensegrity.engine.sensors import Sensor, SensorReader
from tensegrity.engine.simulate import simulate
from tensegrity.model.actuators import Actuators
from tensegrity.model.structure import Structure
from tensegrity.physics.coordinates import nodes_from_coordinates
from tensegrity.physics.dynamics import State, initial_state, tendon_lengths

__all__ = ["Motion", "Task", "TensegrityEnv"]


@dataclasses.dataclass(frozen=True)
class Motion:
    """What a task sees of one control period: the node positions (N, 3) [m] at its start
    (``before``) and end (``after``), the node velocities at its end (N, 3) [m/s], the period
    [s] and the control held over it (S,) [m]."""

    before: np.ndarray
    after: np.ndarray
    velocity: np.ndarray
    period: float
    control: np.ndarray


class Task(Protocol):
    """What an environment is for: its reward and when an episode ends."""

    def start(self, nodes: np.ndarray) -> None:
        """An episode starts with the nodes at ``nodes`` (N, 3) [m]."""

    def reward(self, motion: Motion) -> float:
        """The reward of one control period."""
        ...

    def terminated(self, motion: Motion) -> bool:
        """Whether the episode ends after this period (its goal reached, or lost)."""
        ...


class TensegrityEnv(gymnasium.Env):
    """A structure on which a task is learned by commanding its actuated cables.

    Parameters
    ----------
    structure : Structure
        Spatial, its node positions (and velocities) the state every episode starts from.
    task : Task
    actuators : Actuators
        The actuated cables (:func:`tensegrity.model.actuators.actuators`), with finite rest
        length bounds (the action's scale).
    gravity, ground, contact_radius
        The scene, as :func:`~tensegrity.engine.simulate.simulate` takes it.
    control_period : float
        Time [s] between actions (the command is held over it), default 0.02.
    reset_noise : float
        Standard deviation [m/s] of the random velocities added to every coordinate's rate at
        reset (then projected onto the rod constraints), drawn from ``self.np_random``.
    engine : dict, optional
        Options of :class:`~tensegrity.engine.live.Live` (``rtol``, ``atol``,
        ``max_rod_length_error``, ...).
    sensors : sequence of Sensor, optional
        What the learner observes, as hardware measures it
        (:class:`~tensegrity.engine.sensors.Sensor`: markers, IMUs on rods, cable lengths and
        tensions, contacts, with their noise, bias, delay and rate); their noise seeded from
        ``self.np_random`` at each reset.

    The observation (float32) is, without ``sensors``, the node positions (3N) [m], their
    velocities (3N) [m/s] and the actuated cables' lengths (A) [m]; with them, their channels
    (:attr:`observation_channels`).  An engine failure (a blow-up check) ends the episode
    (``terminated``, reward 0, the last good observation) with the reason in
    ``info["failure"]``.
    """

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 - gymnasium's class field

    def __init__(
        self,
        structure: Structure,
        task: Task,
        actuators: Actuators,
        *,
        gravity: Any = None,
        ground: Any = None,
        contact_radius: float = 0.0,
        control_period: float = 0.02,
        reset_noise: float = 0.0,
        engine: dict[str, Any] | None = None,
        sensors: Sequence[Sensor] | None = None,
    ) -> None:
        if structure.dim != 3:
            raise ValueError("structure: environments are for spatial (3-D) structures")
        if not isinstance(actuators, Actuators):
            raise TypeError(f"actuators: expected Actuators, got {type(actuators).__name__}")
        low, high = actuators.command_bounds(structure)
        if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
            raise ValueError("actuators: need finite max_rest_length (the action's scale)")
        for name, value in (("control_period", control_period), ("reset_noise", reset_noise)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: must be a finite number >= 0, got {value!r}")
        if control_period <= 0:
            raise ValueError(f"control_period: must be > 0 [s], got {control_period!r}")
        self.structure, self.task, self.actuators = structure, task, actuators
        self.control_period, self.reset_noise = float(control_period), float(reset_noise)
        self.command_low, self.command_high = low, high
        self.scene = {"gravity": gravity, "ground": ground, "contact_radius": contact_radius}
        self.engine = dict(engine or {})
        self.live = Live(
            structure,
            actuators=actuators,
            gravity=gravity,
            ground=ground,
            contact_radius=contact_radius,
            **(engine or {}),
        )
        self.start = initial_state(structure)
        A, N = actuators.size, structure.n_nodes
        self.action_space = spaces.Box(-1.0, 1.0, (A,), np.float32)
        low_obs = np.concatenate([np.full(6 * N, -np.inf), np.zeros(A)]).astype(np.float32)
        self.observation_space = spaces.Box(low_obs, np.float32(np.inf), dtype=np.float32)
        self._nodes = np.zeros((N, 3))
        self._observation = np.zeros(6 * N + A, np.float32)
        self.reader: SensorReader | None = None
        if sensors is not None:
            planes = len(self.live.system.inputs.ground)
            self.reader = SensorReader(structure, sensors, planes=planes, seed=0)
            size = len(self.reader.channel)
            self.observation_space = spaces.Box(-np.inf, np.inf, (size,), np.float32)
            self._observation = np.zeros(size, np.float32)

    @property
    def observation_channels(self) -> tuple[str, ...]:
        """What each entry of an observation is: the sensors' channels, or ``p{i}_x``...,
        ``v{i}_x``..., ``length_{tendon}``."""
        if self.reader is not None:
            return tuple(self.reader.channel)
        nodes = [f"{i}_{axis}" for i in range(self.structure.n_nodes) for axis in "xyz"]
        lengths = [f"length_{self.structure.tendon_name[s]}" for s in self.actuators.tendons]
        return (*(f"p{n}" for n in nodes), *(f"v{n}" for n in nodes), *lengths)

    @property
    def observation_size(self) -> int:
        """The length of an observation (6 N + A)."""
        return self._observation.size

    # ------------------------------------------------------------------ gymnasium
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start an episode from the structure's state, its rates perturbed by
        ``reset_noise`` from the seeded ``self.np_random``."""
        super().reset(seed=seed)
        noise = self.np_random.normal(0.0, self.reset_noise, self.start.qdot.shape)
        if self.reader is not None:
            self.reader.reset(int(self.np_random.integers(2**31)))
        self.live.reset(State(t=0.0, q=self.start.q, qdot=self.start.qdot + noise))
        self._observe(self.live.state())
        self.task.start(self._nodes)
        return self._observation.copy(), {}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Hold the action's command over one control period; ``(observation, reward,
        terminated, truncated, info)``.  ``ValueError`` naming ``action`` if it has the wrong
        shape or is not finite."""
        command = self.command(action)
        try:
            outcome: State | EngineError = self.live.advance(command, self.control_period)
        except EngineError as failure:
            outcome = failure
        return self.outcome(outcome)

    def outcome(
        self, outcome: State | EngineError
    ) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """What :meth:`step` returns once the engine has advanced a control period to the state
        ``outcome`` (or failed with it: the episode ends, the reason in ``info["failure"]``);
        the vector environment advances its copies together and calls this for each."""
        if isinstance(outcome, EngineError):
            return self._observation.copy(), 0.0, True, False, {"failure": str(outcome)}
        before = self._nodes
        velocity = self._observe(outcome)
        motion = Motion(before, self._nodes, velocity, self.control_period, self.live.control)
        reward = float(self.task.reward(motion))
        return self._observation.copy(), reward, bool(self.task.terminated(motion)), False, {}

    def simulate(
        self,
        policy: Callable[[np.ndarray], Any],
        duration: float,
        *,
        seed: int | None = None,
        sample_dt: float | None = None,
    ) -> SimulationResult:
        """Run ``policy`` (observation -> action, e.g. a trained agent's ``predict``) from a
        reset for ``duration`` [s] in :func:`~tensegrity.engine.simulate.simulate`: the whole
        run (samples every ``sample_dt``, default the control period; energies, tensions,
        contact modes) for the viewer, animations and files.  Its state at the end of each
        control period is the one :meth:`step` gives for the same actions.  It resets the
        environment (with ``seed``) and leaves it mid-way: call :meth:`reset` before stepping it
        again.  Environments with ``sensors`` are refused (their readings are made between the
        engine's periods)."""
        if self.reader is not None:
            raise ValueError("simulate: an environment with sensors cannot run in simulate")
        self.reset(seed=seed)
        start = self.live.state()

        def law(t: float, q: np.ndarray, qdot: np.ndarray) -> np.ndarray:
            self._observe(State(t=t, q=q, qdot=qdot))
            return self.command(policy(self._observation.copy()))

        return simulate(
            self.structure,
            (0.0, duration),
            initial=start,
            controller=Feedback(law, self.control_period),
            actuators=self.actuators,
            sample_dt=self.control_period if sample_dt is None else sample_dt,
            **self.scene,
            **self.engine,
        )

    # ------------------------------------------------------------------ the actuators
    def command(self, action: Any) -> np.ndarray:
        """The controls ``u`` (A,) [m] the action commands: ``[-1, 1]`` (clipped) mapped onto
        the actuators' bounds (:meth:`Actuators.command_bounds`)."""
        a = np.asarray(action, dtype=float)
        if a.shape != self.action_space.shape:
            raise ValueError(f"action: expected shape {self.action_space.shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError("action: must be finite")
        a = np.clip(a, -1.0, 1.0)
        return self.command_low + 0.5 * (a + 1.0) * (self.command_high - self.command_low)

    # ------------------------------------------------------------------ observations
    def _observe(self, state: State) -> np.ndarray:
        """Fill the observation of ``state``; the node velocities (N, 3) [m/s]."""
        s = self.structure
        self._nodes = nodes_from_coordinates(s, state.q)
        velocity = nodes_from_coordinates(s, state.qdot, rates=True)
        if self.reader is not None:
            extra: dict[str, np.ndarray] = {}
            if self.reader.needs:
                sample = self.live.sample()
                extra = {
                    "tension": sample.tendon_tension[0],
                    "contact_mode": sample.contact_mode[0],
                }
            reading = self.reader(
                state.t,
                state.q,
                state.qdot,
                **{name: extra[name] for name in self.reader.needs},
            )
            self._observation = reading.value.astype(np.float32)
            return velocity
        lengths = tendon_lengths(s, self._nodes)[self.actuators.tendons]
        self._observation = np.concatenate([self._nodes.ravel(), velocity.ravel(), lengths]).astype(
            np.float32
        )
        return velocity
