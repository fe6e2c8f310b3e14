"""The physics layer: forces, accelerations, energies and constraints of a
:class:`~tensegrity.model.structure.Structure` (Theorem 18.1).

- :mod:`~tensegrity.physics.dynamics` — the readable NumPy reference every other formulation
  is tested against (the one tension law, eqs. 18.39-18.40);
- :mod:`~tensegrity.physics.constraints` — joints and supports: the constraint solver and the
  projection (built here from a structure's data, cached per structure);
- :mod:`~tensegrity.physics.kernel`, :mod:`~tensegrity.physics.kernel_system` — the same
  physics compiled (numba), used by the engine;
- :mod:`~tensegrity.physics.matrix_form` — the paper's explicit matrix model (eq. 18.59).

Imports only :mod:`tensegrity.model`.
"""
