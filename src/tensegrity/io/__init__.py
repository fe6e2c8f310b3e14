"""The I/O layer: files in and out, all written atomically, all read with one-line errors.

- :mod:`~tensegrity.io.files` — atomic writes, staged sets of outputs, file errors, input files
  read within limits;
- :mod:`~tensegrity.io.checked` — HDF5 datasets and attributes and ``.npz`` arrays checked
  against the documented layout and the limits before they are read (untrusted files);
- :mod:`~tensegrity.io.formats` — structure files (JSON, YAML, TOML, connectivity ``.npz``,
  MJCF ``.xml``) and the scene they carry;
- :mod:`~tensegrity.io.trajectory` — the trajectory HDF5 file (its layout is defined there);
- :mod:`~tensegrity.io.stream` — a run streamed to that file with checkpoints (resumable);
- :mod:`~tensegrity.io.tables` — force and control tables from ``.npz``/``.csv``;
- :mod:`~tensegrity.io.mjcf`, :mod:`~tensegrity.io.vtk`, :mod:`~tensegrity.io.matrices` —
  MuJoCo models, ParaView time series, the paper's matrices.

The names below are the common entry points.
"""

from tensegrity.io.files import PathLike, atomic_path, file_error, write_staged
from tensegrity.io.formats import (
    read_network,
    read_scene,
    read_structure,
    write_network,
    write_structure,
)
from tensegrity.io.trajectory import read_trajectory, write_trajectory

__all__ = [
    "PathLike",
    "atomic_path",
    "file_error",
    "read_network",
    "read_scene",
    "read_structure",
    "read_trajectory",
    "write_network",
    "write_staged",
    "write_structure",
    "write_trajectory",
]
