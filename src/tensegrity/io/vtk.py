"""Export a simulation to VTK/ParaView: one PolyData file per sample and a ``.pvd`` collection.

Each ``<name>_<k>.vtp`` (VTK XML PolyData, ASCII) holds the ``N`` nodes as points and every rod
and tendon as a two-point line (cells ``0 .. R-1`` are the rods, ``R .. R+S-1`` the tendons, in
the structure's order), with

- cell data ``tension`` [N] (the tendon's tension, 0 when slack; 0 for rods), ``is_tendon``
  (0 for a rod, 1 for a tendon) and ``slack`` (1 for a slack tendon, else 0);
- point data ``velocity`` [m/s] when the velocities are known.

``<name>.pvd`` lists the files with their times [s]; open it in ParaView to play the motion.
The files are written into a staging folder and moved into place
(:func:`tensegrity.io.trajectory.write_staged`), the collection last, so a reader never sees a
collection that points at missing files.
"""

from __future__ import annotations

import os
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from tensegrity.engine.result import SimulationResult
from tensegrity.io.files import PathLike, write_staged
from tensegrity.model.structure import Structure


def _ascii(values: np.ndarray) -> str:
    return " ".join(repr(float(x)) for x in np.ravel(values))


def polydata(
    structure: Structure, nodes: np.ndarray, tension: np.ndarray, velocity: np.ndarray | None = None
) -> str:
    """One VTK XML PolyData document: nodes (N, 3) [m], tendon tensions (S,) [N], velocities."""
    R, S, N = structure.n_rods, structure.n_tendons, structure.n_nodes
    connectivity = np.concatenate([structure.rod_nodes, structure.tendon_nodes]).ravel()
    offsets = 2 * np.arange(1, R + S + 1)
    cells = {
        ("Float64", "tension"): np.concatenate([np.zeros(R), tension]),
        ("Int32", "is_tendon"): np.concatenate([np.zeros(R, int), np.ones(S, int)]),
        ("Int32", "slack"): np.concatenate([np.zeros(R, int), (tension <= 0).astype(int)]),
    }
    lines = [
        '<?xml version="1.0"?>',
        '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian">',
        "  <PolyData>",
        f'    <Piece NumberOfPoints="{N}" NumberOfVerts="0" NumberOfLines="{R + S}" '
        'NumberOfStrips="0" NumberOfPolys="0">',
        "      <Points>",
        '        <DataArray type="Float64" NumberOfComponents="3" format="ascii">'
        f"{_ascii(nodes)}</DataArray>",
        "      </Points>",
        "      <Lines>",
        '        <DataArray type="Int64" Name="connectivity" format="ascii">'
        f"{' '.join(map(str, connectivity))}</DataArray>",
        '        <DataArray type="Int64" Name="offsets" format="ascii">'
        f"{' '.join(map(str, offsets))}</DataArray>",
        "      </Lines>",
        '      <CellData Scalars="tension">',
    ]
    for (kind, name), values in cells.items():
        text = _ascii(values) if kind == "Float64" else " ".join(map(str, values))
        lines.append(
            f'        <DataArray type="{kind}" Name="{name}" format="ascii">{text}</DataArray>'
        )
    lines.append("      </CellData>")
    if velocity is not None:
        lines += [
            '      <PointData Vectors="velocity">',
            f'        <DataArray type="Float64" Name="velocity" NumberOfComponents="3" '
            f'format="ascii">{_ascii(velocity)}</DataArray>',
            "      </PointData>",
        ]
    lines += ["    </Piece>", "  </PolyData>", "</VTKFile>", ""]
    return "\n".join(lines)


def write_vtk(
    out: PathLike, source: SimulationResult, *, name: str = "tensegrity", every: int = 1
) -> list[Path]:
    """Write every ``every``-th sample of a simulation as ``out/<name>_<k>.vtp`` and
    ``out/<name>.pvd``.

    Parameters
    ----------
    out : path
        Output folder (created if missing).  Existing files of the same names are replaced.
    source : SimulationResult
        A result of :func:`tensegrity.engine.simulate.simulate` or one read by
        :func:`tensegrity.io.trajectory.read_trajectory`.
    every : int
        Keep one sample in ``every`` (the last sample is always kept).

    Returns
    -------
    list of pathlib.Path
        The files written, the collection last.
    """
    if isinstance(every, bool) or not isinstance(every, int) or every < 1:
        raise ValueError(f"every: must be an integer >= 1, got {every!r}")
    if not name or os.sep in name or (os.altsep and os.altsep in name):
        raise ValueError(f"name: must be a plain file name stem, got {name!r}")
    structure, times = source.structure, source.t
    nodes, tension, velocity = source.node_position, source.tendon_tension, source.node_velocity
    T, N, S = np.shape(times)[0], structure.n_nodes, structure.n_tendons
    for field, array, shape in (
        ("nodes", nodes, (T, N, 3)),
        ("tendon_tension", tension, (T, S)),
        ("velocities", velocity, (T, N, 3)),
    ):
        if array is not None and np.shape(array) != shape:
            raise ValueError(
                f"{field}: expected shape {shape} for {T} samples, got {np.shape(array)}"
            )
    keep = np.unique(np.append(np.arange(0, times.size, every), times.size - 1))
    width = len(str(keep.size - 1))

    def write(staging: Path) -> list[Path]:
        files, entries = [], []
        for k, i in enumerate(keep):
            path = staging / f"{name}_{k:0{width}d}.vtp"
            path.write_text(
                polydata(
                    structure, nodes[i], tension[i], None if velocity is None else velocity[i]
                ),
                encoding="utf-8",
            )
            files.append(path)
            entries.append(
                f'    <DataSet timestep={quoteattr(repr(float(times[i])))} part="0" '
                f"file={quoteattr(path.name)}/>"
            )
        collection = staging / f"{name}.pvd"
        collection.write_text(
            '<?xml version="1.0"?>\n<VTKFile type="Collection" version="1.0">\n  <Collection>\n'
            + "\n".join(entries)
            + "\n  </Collection>\n</VTKFile>\n",
            encoding="utf-8",
        )
        return [*files, collection]

    return write_staged(Path(out), write)
