"""The command line, a thin layer over the library: :mod:`~tensegrity.cli.main` (the parser,
``simulate``, ``export``, ``info``, ``matrices``, ``vtk``, ``sweep``) and
:mod:`~tensegrity.cli.analysis` (``equilibrium``), :mod:`~tensegrity.cli.modes` (``modes``,
``controllability``) and :mod:`~tensegrity.cli.control` (``lqr``, ``control``)."""

from tensegrity.cli.main import main

__all__ = ["main"]
