"""The simulation engine: one integration loop (:func:`tensegrity.engine.loop.run`) over a
compiled right-hand side, for every structure and every method; samples go to a sink (memory,
or the HDF5 file of :mod:`tensegrity.io.stream`).

- :mod:`~tensegrity.engine.options` — :class:`Options`, the options of a run, defined once;
- :mod:`~tensegrity.engine.inputs` — controls, loads and gravity at the stage times;
- :mod:`~tensegrity.engine.system` — a structure packed for the compiled code;
- :mod:`~tensegrity.engine.compiled` — the compiled stages, steps, checks and outputs;
- :mod:`~tensegrity.engine.dop853` — DOP853, the default method, its whole step loop compiled;
- :mod:`~tensegrity.engine.steppers` — other ``scipy`` methods behind one protocol, and RK4;
- :mod:`~tensegrity.engine.loop` — :func:`run`, the controller hook (:class:`Controller`,
  :class:`Feedback`) and exact checkpoints (:class:`Checkpointing`, :class:`LoopState`);
- :mod:`~tensegrity.engine.result` — :class:`SimulationResult`, :class:`MemorySink`;
- :mod:`~tensegrity.engine.simulate` — :func:`simulate`, the engine with a memory sink;
- :mod:`~tensegrity.engine.batch` — :func:`simulate_batch`, many copies of one structure;
- :mod:`~tensegrity.engine.step` — :func:`step`, one step at a time for a loop of your own.

The compiled modules import numba; ``import tensegrity`` does not load them.
"""
