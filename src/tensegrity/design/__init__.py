"""The design layer: structures made with the analysis tools (form-finding, prestress).

- :mod:`~tensegrity.design.catalogue` — the generators by kind (``tensegrity export --kind``):
  the paper's shells and planar examples and the prestressed prism, expanded octahedron,
  Needle Tower and the six-bar and three-bar robots.
- :mod:`~tensegrity.design.rolling` — the six-bar's rolling example: the cable shortenings that
  tip it from face to face, as a control table (``six_bar_roll``).
- :mod:`~tensegrity.design.materials` — materials (a table of common ones) and round sections;
  the structure a choice of them makes (``E A / Lbar``, ``rho A L``).
- :mod:`~tensegrity.design.utilisation` — how close each member is to yielding, breaking or
  buckling, at a state or over a run.
- :mod:`~tensegrity.design.sizing` — minimal-mass member sizing under yield and buckling for a
  prestress and load cases (linear programs, ``docs/design.md``).
- :mod:`~tensegrity.design.loaded` — sizing at the loaded, deformed equilibrium (structures
  that carry a load only after they move: prisms, towers, shells), each case followed by load
  steps checked stable.
- :mod:`~tensegrity.design.least_mass` — the least mass at the loaded equilibrium (lighter
  than the fully stressed design for a statically indeterminate structure).
- :mod:`~tensegrity.design.dynamic` — the dynamic check: a structure under each load case
  applied suddenly, the members' largest utilisation in motion.
- :mod:`~tensegrity.design.files` — structure files in the material form (members by material
  and section): ``read_design``, ``write_design``; ``trajectory_design`` (the design a
  trajectory file carries).

Imports model, physics, engine, io and analysis; nothing above.
"""
