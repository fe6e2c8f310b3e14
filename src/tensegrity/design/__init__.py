"""The design layer: structures made with the analysis tools (form-finding, prestress).

- :mod:`~tensegrity.design.catalogue` — the generators by kind (``tensegrity export --kind``):
  the paper's shells and planar examples and the prestressed prism, expanded octahedron and
  Needle Tower.

Imports model, physics, engine and analysis; nothing above.
"""
