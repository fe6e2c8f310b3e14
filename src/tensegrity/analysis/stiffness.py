"""Tangent stiffness of an equilibrium, and the linear response to a load increment about it.

At an equilibrium (loaded or not) the tangent stiffness ``K`` of
:func:`~tensegrity.analysis.linearize.linearize` -- the tendons' material and geometric
stiffness, the rods' geometric term with the external loads, gravity and the reactions, in the
motions the joints and supports admit -- relates a small increment ``dw`` (N, 3) [N] of the
nodal loads to the node displacements ``du`` (N, 3) [m] it causes::

    du = sum_i  v_i (v_i . dw) / omega_i^2      (non-rigid modes i)

with ``v_i`` the node shapes and ``omega_i^2`` the eigenvalues of ``K v = omega^2 M v``
(:func:`~tensegrity.analysis.modes.modal_analysis`, mass-orthonormal shapes): the same as
``J K^-1 J^T dw``, with ``J = dp/deta``.  The compliance of a load pattern ``e`` (N, 3) is the
displacement its increment causes along itself, ``c = e . du(e)`` [m/N]: for three equal
vertical forces on a prism's top nodes summing to 1 N downward, the sinking of the top per
newton, so that ``1 / c`` is the axial tangent stiffness [N/m] (``docs/design.md``, "Axial
stiffness of the prism: a check against the closed form").

The response is defined only where it is unique and bounded: an increment that does work on a
rigid-body motion the supports admit (an unbalanced load on a free structure) is refused, and so
is an equilibrium that is not stable (a mechanism or a mode of negative stiffness, the verdict
of :func:`~tensegrity.analysis.modes.modal_analysis`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from tensegrity.analysis.coordinates import spatial_vector
from tensegrity.analysis.equilibrium import EquilibriumResult
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import ELASTIC, RIGID, ModalAnalysis, modal_analysis
from tensegrity.model.structure import Structure

#: A load increment is unbalanced if its work on the admitted rigid-body motions exceeds this
#: times its largest work on a mode (both per unit modal mass).
BALANCE_RTOL = 1e-9


@dataclasses.dataclass(frozen=True, eq=False)
class TangentStiffness:
    """The tangent stiffness of an equilibrium and the linear response to load increments.

    Attributes
    ----------
    modes : ModalAnalysis
        Its modes (:func:`~tensegrity.analysis.modes.modal_analysis`), lowest first: the
        frequencies (``modes.frequency_hz`` [Hz]: the lowest natural frequency about the
        equilibrium) and the node shapes ``modes.node_shapes`` (k, N, 3).
    """

    modes: ModalAnalysis

    @property
    def matrix(self) -> np.ndarray:
        """``K`` (k, k): the tangent stiffness in the reduced coordinates of the linearization
        (``modes.linearization.stiffness``; material plus geometric, constraints included)."""
        return self.modes.linearization.stiffness

    def displacement(self, load: Any) -> np.ndarray:
        """Node displacements (N, d) [m] caused by the nodal load increment ``load`` (N, d) [N].

        ``d`` is the structure's dimension (2 for a planar structure).  ``ValueError`` if
        ``load`` is not (N, d) finite numbers, does work on an admitted rigid-body motion, or
        the equilibrium is not stable.
        """
        return self._response(np.asarray(load, dtype=float), "load")

    def compliance(self, load_pattern: Any) -> float:
        """``e . du(e)`` [m/N]: the displacement along the load pattern ``e`` (N, d) [N] that its
        increment causes, per unit of the pattern (see the module docstring); its inverse is the
        tangent stiffness along the pattern [N/m].  Errors as :meth:`displacement`."""
        e = np.asarray(load_pattern, dtype=float)
        return float(np.sum(e * self._response(e, "load_pattern")))

    def _response(self, w: np.ndarray, name: str) -> np.ndarray:
        """:meth:`displacement` of ``w``, its errors naming the argument ``name``."""
        lin = self.modes.linearization
        source = lin.source
        shape = (source.n_nodes, source.dim)
        if w.shape != shape or not np.all(np.isfinite(w)):
            got = f"shape {w.shape}" if w.shape != shape else "non-finite values"
            raise ValueError(f"{name}: expected finite nodal forces of shape {shape}, got {got}")
        if not self.modes.stable:
            raise ValueError(
                f"equilibrium: no unique response to a load increment: {self.modes.verdict}"
            )
        shapes = self.modes.node_shapes  # (k, N, 3), M-orthonormal modes
        work = np.einsum("inj,nj->i", shapes, spatial_vector(source, w))
        rigid = np.array([kind == RIGID for kind in self.modes.kind], dtype=bool)
        largest = float(np.max(np.abs(work), initial=0.0))
        if np.any(np.abs(work[rigid]) > BALANCE_RTOL * largest):
            raise ValueError(
                f"{name}: not balanced: it does work on a rigid-body motion the supports admit "
                "(on a free structure, a load increment needs zero net force and moment)"
            )
        elastic = np.array([kind == ELASTIC for kind in self.modes.kind], dtype=bool)
        amplitude = work[elastic] / self.modes.omega_squared[elastic]
        du = np.einsum("i,inj->nj", amplitude, shapes[elastic])
        return np.asarray(du[:, : source.dim])


def tangent_stiffness(
    structure: Structure,
    equilibrium: EquilibriumResult | np.ndarray | None = None,
    *,
    include_threshold: bool = True,
) -> TangentStiffness:
    """The tangent stiffness of ``structure`` about ``equilibrium``.

    Parameters
    ----------
    structure : Structure
    equilibrium : EquilibriumResult or (6R,) q, optional
        As :func:`~tensegrity.analysis.linearize.linearize`: a result of
        :func:`~tensegrity.analysis.equilibrium.find_equilibrium` carries its external forces and
        gravity, which enter the geometric stiffness; default the structure's node positions.
    include_threshold : bool
        Tendons exactly at their rest length add their material stiffness (as ``linearize``).
    """
    lin = linearize(structure, equilibrium, include_threshold=include_threshold)
    return TangentStiffness(modal_analysis(lin))


def compliance(
    structure: Structure,
    equilibrium: EquilibriumResult | np.ndarray | None,
    load_pattern: Any,
) -> float:
    """``e . du(e)`` [m/N] of the load pattern ``e`` (N, d) [N] about ``equilibrium``
    (:meth:`TangentStiffness.compliance`); ``1 / compliance`` is the tangent stiffness along
    the pattern [N/m]."""
    return tangent_stiffness(structure, equilibrium).compliance(load_pattern)
