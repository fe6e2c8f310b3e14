"""Member utilisation from a trajectory file (tensegrity.design.utilisation.
trajectory_utilisation): what it reads, and the same numbers as run_utilisation."""

from __future__ import annotations

import numpy as np

from tensegrity.design.materials import Cable, MemberDesign, SolidRod, material
from tensegrity.design.utilisation import run_utilisation
from tensegrity.io.trajectory import read_trajectory


def test_trajectory_utilisation_reads_one_sample_in_k(tmp_path):
    """Within the byte and sample limits given, tendons and rods come from one sample in k
    (and the last), equal to the library's run utilisation of those samples."""
    from tensegrity import simulate
    from tensegrity.design.catalogue import prism
    from tensegrity.design.utilisation import trajectory_utilisation
    from tensegrity.io.trajectory import write_trajectory

    base = prism()
    design = MemberDesign.of(
        base,
        rod_material=material("aluminium"),
        rod_section=SolidRod(0.004),
        tendon_material=material("nylon"),
        tendon_section=Cable(0.4e-3),
    )
    s = design.apply(base, keep_tension=True)
    kicked = s.replace(
        node_velocity=np.tile([0.0, 0.0, 0.3], (s.n_nodes, 1)) * [[1], [-1], [1], [0], [0], [0]]
    )
    result = simulate(kicked, (0.0, 0.3), sample_dt=0.01)
    path = write_trajectory(tmp_path / "run.h5", result)
    n = len(result.t)
    props = design.properties(s)
    u = trajectory_utilisation(
        path, props, n_samples=n, rod_samples=8, tension_bytes=n * 9 * 8 // 3
    )
    assert u.rod_every == -(-n // 8) and u.tendon_every == 3
    rods = run_utilisation(read_trajectory(path, every=u.rod_every), props)
    np.testing.assert_array_equal(u.rod_peak, rods.rod_peak)
    tendons = run_utilisation(read_trajectory(path, every=3), props)
    np.testing.assert_array_equal(u.tendon_peak, tendons.tendon_peak)
    np.testing.assert_array_equal(u.tendon_peak_time, tendons.tendon_peak_time)
    assert u.rod_buckling.value == rods.samples.rod_buckling.max()
