"""The simulation engine: one integration loop (:func:`run`) over a compiled right-hand side,
for every structure and every method; samples go to a sink (memory or an HDF5 file).

- :mod:`~tensegrity.engine.options` — :class:`Options`, the options of a run, defined once;
- :mod:`~tensegrity.engine.inputs` — controls, loads and gravity at the stage times;
- :mod:`~tensegrity.engine.system` — a structure packed for the compiled code;
- :mod:`~tensegrity.engine.compiled` — the compiled stages, steps, checks and outputs;
- :mod:`~tensegrity.engine.steppers` — DOP853, other ``scipy`` methods, RK4;
- :mod:`~tensegrity.engine.loop` — :func:`run` and :class:`RunSummary`;
- :mod:`~tensegrity.engine.result` — :class:`SimulationResult` and :class:`MemorySink`.

The compiled modules import numba; this package imports them on first use of :func:`run`.
"""
