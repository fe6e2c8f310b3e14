"""
Equilibrium, prestress and modes
================================

The analysis behind the paper's Definition 18.1 (stability) on the (3,1) shell: its static
equilibrium (eq. 18.61) found directly, the self-stress states that make it a tensegrity, and
its natural frequencies and mode shapes about that equilibrium.
"""

# %%
# The equilibrium
# ---------------
# :func:`~tensegrity.analysis.equilibrium.find_equilibrium` solves eq. 18.61 in coordinates that
# keep every rod's length exactly (least squares, then Newton). The result carries the tensions,
# the slack tendons and the rods' compressions.
import numpy as np

from tensegrity import class1_shell
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import modal_analysis
from tensegrity.analysis.prestress import self_stress
from tensegrity.plots.figures import figure_structure

shell = class1_shell(3, 1)
eq = find_equilibrium(shell)
print(eq.message)
print(f"tension {eq.tension.min():.2f} to {eq.tension.max():.2f} N, slack: {int(eq.slack.sum())}")
print(f"rod compression {eq.rod_compression.min():.2f} N, residual force {eq.residual_force:.1e} N")
equilibrium = figure_structure(shell, eq.node_position, eq.tension, title="The equilibrium")

# %%
# Prestress
# ---------
# The self-stress states are the tensions in equilibrium with no load (the null space of the
# equilibrium matrix at that shape); the mechanisms are the motions that stretch no tendon. A
# tensegrity is stiff because a self-stress state, all its tensions positive, stiffens its
# mechanisms.
states = self_stress(shell, eq.q)
print(states.n_states, "self-stress state(s),", states.n_mechanisms, "mechanism(s)")

# %%
# Modes
# -----
# Linearized about the equilibrium, the shell has six rigid-body modes (zero frequency) and
# elastic modes; the verdict applies Definition 18.1.
modes = modal_analysis(linearize(shell, eq))
print(modes.verdict)
elastic = [i for i, kind in enumerate(modes.kind) if kind != "rigid"]
print("lowest frequencies [Hz]:", np.round(modes.frequency_hz[elastic][:5], 3))

# %%
# The lowest elastic mode, its node displacements scaled to 0.15 m at the largest and drawn on
# the equilibrium (the shell's three-fold symmetry makes it one of three modes of the same
# frequency: any combination of them is a mode too).
first = elastic[0]
shape = modes.node_shapes[first]
moved = eq.node_position + 0.15 * shape / np.abs(shape).max()
mode = figure_structure(
    shell, moved, title=f"Mode {first}: {modes.frequency_hz[first]:.3f} Hz (displaced)"
)
