"""
The class 2 shell standing under gravity
========================================

Lemma 18.1 of the paper: joining the class 1 shell's rods end to end by ball joints gives the
class 2 shell. Here a (4, 3) class 2 shell with its base ring fixed to the ground, released
under gravity: it sags onto its tendons and settles. The joints and supports are constraints
the engine keeps exactly (``docs/constraints.md``), and their reaction forces come with the
equilibrium.
"""

# %%
# The structure
# -------------
import numpy as np

from tensegrity import internal_damping, simulate
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.model.shell import class2_shell
from tensegrity.plots.figures import figure_structure

shell = class2_shell(4, 3, stiffness=3000.0, fixed_base=True)
print(shell.n_rods, "rods,", shell.n_tendons, "tendons,", len(shell.joint_nodes), "joints")
print("fixed nodes:", np.flatnonzero(shell.node_fixed).tolist())

# %%
# Released under gravity
# ----------------------
gravity = np.array([0.0, 0.0, -9.81])
run = simulate(internal_damping(shell), (0.0, 20.0), gravity=gravity, steady_state=True)
print(run.message)
print(f"joints and supports held to {run.max_constraint_error:.1e} m")
top = run.node_position[:, :, 2].max(axis=1)
print(f"top sank {1e3 * (top[0] - top[-1]):.1f} mm")
settled = figure_structure(
    shell, run.node_position[-1], run.tendon_tension[-1], title="Settled under gravity"
)

# %%
# The equilibrium found directly
# ------------------------------
# The same state by least squares (eq. 18.61 with the constraints), and the ground's reactions
# at the base: together they carry the structure's weight.
eq = find_equilibrium(shell, run.q[-1], gravity=gravity)
print(
    f"distance from the run's rest: {np.abs(eq.node_position - run.node_position[-1]).max():.1e} m"
)
weight = shell.rod_mass.sum() * 9.81
print(f"reactions {eq.reaction_force[:, 2].sum():.3f} N up against a weight of {weight:.3f} N")
