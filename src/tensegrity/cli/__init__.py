"""The command line, a thin layer over the library: :mod:`~tensegrity.cli.main` (the parser,
``simulate``, ``export``, ``info``, ``matrices``, ``vtk``, ``sweep``) and
:mod:`~tensegrity.cli.analysis` (``equilibrium``, ``modes``, ``controllability``, ``control``)."""

from tensegrity.cli.main import main

__all__ = ["main"]
