"""Linear output feedback run inside the compiled loop (:class:`LinearFeedback`): the form that
``linearize`` and an LQR design give, ``u = u_ref - K (y - y_ref)``, updated every ``period``
with zero-order hold (through the actuators' limits and dynamics when the run has actuators).

The outputs ``y`` it reads are groups of the structure's outputs, in this order within a group
(the names of :class:`tensegrity.analysis.linearize.Linearization`'s outputs):

- ``"position"``: node positions (N * dim,) [m], node by node (``p{i}_x``, ``p{i}_y``, ...);
- ``"velocity"``: node velocities (N * dim,) [m/s], the same order;
- ``"length"``: tendon lengths (S,) [m];
- ``"tension"``: tendon tensions (S,) [N].

The controller file of ``tensegrity simulate --controller FILE.npz`` holds the fields of the same
names: ``K`` (A, Y), ``y_ref`` (Y,), ``u_ref`` (A,), ``period`` (), ``outputs`` (group names) and
``tendons`` (the A actuated tendons' names) (:mod:`tensegrity.io.controllers`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from tensegrity.model.structure import Structure

#: The output groups a linear feedback may read, in the order they are stacked in ``y``.
OUTPUT_GROUPS = ("position", "velocity", "length", "tension")

__all__ = ["OUTPUT_GROUPS", "LinearFeedback", "output_sizes"]


def output_sizes(structure: Structure) -> dict[str, int]:
    """The size of each output group of ``structure`` (:data:`OUTPUT_GROUPS`)."""
    nodes = structure.n_nodes * structure.dim
    S = structure.n_tendons
    return dict(position=nodes, velocity=nodes, length=S, tension=S)


@dataclasses.dataclass(frozen=True, eq=False)
class LinearFeedback:
    """``u = u_ref - K (y - y_ref)`` on the actuated ``tendons``, every ``period`` [s].

    Attributes
    ----------
    K : (A, Y) float array
        The gain [m per unit of each output].
    y_ref : (Y,) float array
        The outputs' reference (their values at the equilibrium designed about).
    u_ref : (A,) float array
        The controls at the reference [m] (rest lengths ``L0 - u``).
    period : float
        Time between updates [s] (> 0).
    outputs : tuple of str
        The output groups ``y`` stacks, a subsequence of :data:`OUTPUT_GROUPS` in that order.
    tendons : tuple of str or int, or None
        The actuated tendons (names or indices; None: every tendon, ``A = S``). Tendons not
        actuated keep the run's own control (zero, or the actuators' rest length).
    """

    K: np.ndarray
    y_ref: np.ndarray
    u_ref: np.ndarray
    period: float
    outputs: tuple[str, ...] = ("position", "velocity")
    tendons: tuple[str | int, ...] | None = None

    def __post_init__(self) -> None:
        def array(name: str, ndim: int) -> np.ndarray:
            try:
                x = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError):
                raise ValueError(
                    f"{name}: expected numbers, got {getattr(self, name)!r:.60}"
                ) from None
            if x.ndim != ndim or not np.all(np.isfinite(x)):
                raise ValueError(
                    f"{name}: expected a finite {ndim}-D array, got shape {x.shape}"
                    + ("" if np.all(np.isfinite(x)) else " with non-finite values")
                )
            x.setflags(write=False)
            object.__setattr__(self, name, x)
            return x

        K, y_ref, u_ref = array("K", 2), array("y_ref", 1), array("u_ref", 1)
        if K.shape != (u_ref.size, y_ref.size):
            raise ValueError(
                f"K: expected shape (len(u_ref), len(y_ref)) = ({u_ref.size}, {y_ref.size}), "
                f"got {K.shape}"
            )
        period = self.period
        ok = isinstance(period, (int, float, np.integer, np.floating)) and not isinstance(
            period, bool
        )
        if not (ok and math.isfinite(period) and period > 0):
            raise ValueError(f"period: must be a finite number > 0 [s], got {period!r}")
        object.__setattr__(self, "period", float(period))
        outputs = (self.outputs,) if isinstance(self.outputs, str) else tuple(self.outputs)
        unknown = [g for g in outputs if g not in OUTPUT_GROUPS]
        if unknown or not outputs:
            raise ValueError(
                f"outputs: expected groups among {', '.join(OUTPUT_GROUPS)}, got {outputs!r}"
            )
        order = [OUTPUT_GROUPS.index(g) for g in outputs]
        if order != sorted(set(order)):
            raise ValueError(
                f"outputs: each group once, in the order {', '.join(OUTPUT_GROUPS)}; got "
                f"{outputs!r}"
            )
        object.__setattr__(self, "outputs", outputs)
        if self.tendons is not None:
            object.__setattr__(self, "tendons", tuple(self.tendons))

    def tendon_indices(self, structure: Structure) -> np.ndarray:
        """The actuated tendons' indices (A,) in ``structure``; ``ValueError`` naming
        ``tendons`` or ``K`` if they do not fit it."""
        S = structure.n_tendons
        if self.tendons is None:
            index = np.arange(S)
        else:
            try:
                index = np.array(
                    [
                        t if isinstance(t, (int, np.integer)) else structure.tendon_index(str(t))
                        for t in self.tendons
                    ],
                    dtype=np.int64,
                )
            except KeyError as exc:
                raise ValueError(f"tendons: {exc.args[0]}") from None
            if np.any((index < 0) | (index >= S)) or np.unique(index).size != index.size:
                raise ValueError(
                    f"tendons: expected distinct tendons of the structure (0..{S - 1}), got "
                    f"{list(self.tendons)!r}"
                )
        if index.size != self.u_ref.size:
            raise ValueError(
                f"u_ref: expected one control per actuated tendon ({index.size}), got "
                f"{self.u_ref.size}"
            )
        return index

    def check(self, structure: Structure) -> np.ndarray:
        """Check the law against ``structure`` (the outputs' size, the tendons); returns the
        actuated tendons' indices (A,).  ``ValueError`` naming the field that does not fit."""
        index = self.tendon_indices(structure)
        sizes = output_sizes(structure)
        Y = sum(sizes[g] for g in self.outputs)
        if self.y_ref.size != Y:
            shown = " + ".join(f"{g} {sizes[g]}" for g in self.outputs)
            raise ValueError(f"y_ref: expected {Y} outputs ({shown}), got {self.y_ref.size}")
        return index

    @classmethod
    def zero(
        cls,
        structure: Structure,
        period: float,
        *,
        outputs: Sequence[str] = ("position", "velocity"),
        tendons: Sequence[str | int] | None = None,
        u_ref: Any = None,
    ) -> LinearFeedback:
        """The law with ``K = 0``: it holds ``u_ref`` (default zero) whatever the outputs."""
        A = structure.n_tendons if tendons is None else len(tendons)
        sizes = output_sizes(structure)
        Y = sum(sizes[g] for g in outputs)
        u = np.zeros(A) if u_ref is None else u_ref
        return cls(
            np.zeros((A, Y)),
            np.zeros(Y),
            u,
            period,
            tuple(outputs),
            None if tendons is None else tuple(tendons),
        )
