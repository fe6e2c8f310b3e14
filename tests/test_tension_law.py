"""One tension law outside the compiled kernel (issue 28): ``k max(l - Lbar, 0)`` is
:func:`tensegrity.physics.dynamics.elastic_tensions`, which the reference's tendon forces, the
statics, the run budget, a design's kept prestress and a structure's view all call (the
compiled copy is tested against the reference in tests/test_kernel_system.py)."""

from __future__ import annotations

import sys

import numpy as np
from hypothesis import given, strategies as st
from hypothesis.extra.numpy import arrays

from tensegrity.analysis import statics
from tensegrity.design import materials
from tensegrity.design.catalogue import prism
from tensegrity.design.materials import Cable, MemberDesign, SolidRod, material
from tensegrity.engine import budget
from tensegrity.model.shell import class1_shell
from tensegrity.physics import dynamics
from tensegrity.plots import motion

SHELL = class1_shell(3, 1)
S = SHELL.n_tendons
positive = st.floats(1e-3, 1e6)


@given(
    stiffness=arrays(float, S, elements=positive),
    length=arrays(float, (2, S), elements=st.floats(0.0, 10.0)),
    rest=arrays(float, (2, S), elements=st.floats(0.0, 10.0)),
)
def test_the_law_pulls_in_proportion_to_the_stretch_and_never_pushes(stiffness, length, rest):
    structure = SHELL.replace(tendon_stiffness=stiffness)
    tension = dynamics.elastic_tensions(structure, length, rest)
    taut = length > rest
    assert tension.shape == (2, S)
    np.testing.assert_array_equal(
        tension[taut], np.broadcast_to(stiffness, (2, S))[taut] * (length - rest)[taut]
    )
    assert np.all(tension[~taut] == 0.0)
    default = dynamics.elastic_tensions(structure, length[0])
    np.testing.assert_array_equal(
        default, dynamics.elastic_tensions(structure, length[0], structure.tendon_rest_length)
    )


def test_every_tension_outside_the_kernel_is_the_law(monkeypatch):
    """Each user of the law calls :func:`~tensegrity.physics.dynamics.elastic_tensions` (a spy
    records its callers) and gets the reference's tensions."""
    callers = set()
    law = dynamics.elastic_tensions

    def spy(*args, **kwargs):
        callers.add(sys._getframe(1).f_globals["__name__"])
        return law(*args, **kwargs)

    for module in (dynamics, motion, materials, budget):
        monkeypatch.setattr(module, "elastic_tensions", spy)
    rest = SHELL.tendon_rest_length.copy()
    rest[0] *= 10  # slack
    shell = SHELL.replace(tendon_rest_length=rest)
    rng = np.random.default_rng(3)
    p = shell.node_position + 1e-3 * rng.standard_normal(shell.node_position.shape)
    reference = dynamics.tendon_tensions(shell, p)
    assert np.any(reference > 0) and np.any(reference == 0)

    np.testing.assert_array_equal(motion.structure_frames(shell, p).tendon_tension[0], reference)
    np.testing.assert_array_equal(
        statics.tendon_state(shell, p, shell.tendon_rest_length).tension, reference
    )
    floor = np.finfo(float).eps * dynamics.tendon_tensions(shell, shell.node_position).max()
    assert budget.acceleration_floor(shell) == floor / shell.node_mass[shell.node_mass > 0].min()
    s = prism(tension=7)
    design = MemberDesign.of(
        s,
        rod_material=material("steel"),
        rod_section=SolidRod(0.01),
        tendon_material=material("dyneema"),
        tendon_section=Cable(0.001),
    )
    kept = design.apply(s, keep_tension=True)
    np.testing.assert_allclose(
        dynamics.tendon_tensions(kept, s.node_position),
        dynamics.tendon_tensions(s, s.node_position),
        rtol=1e-9,
    )
    assert callers == {
        "tensegrity.physics.dynamics",
        "tensegrity.plots.motion",
        "tensegrity.analysis.statics",
        "tensegrity.engine.budget",
        "tensegrity.design.materials",
    }
