"""The model layer: what a structure is, before any physics.

- :mod:`~tensegrity.model.structure` — :class:`Structure`, immutable and validated (topology,
  parameters, supports and joints as data);
- :mod:`~tensegrity.model.connectivity` — the field's ``N``, ``C_b``, ``C_s`` convention;
- :mod:`~tensegrity.model.loads` — gravity, force tables and control tables;
- :mod:`~tensegrity.model.shell`, :mod:`~tensegrity.model.planar` — the paper's generators.

Imports nothing else of the package.
"""
