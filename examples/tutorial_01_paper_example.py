"""
The paper's (3,1) shell, step by step
=====================================

The example of Skelton, Pinaud and Mingori (§18.5): the (3,1) class 1 shell of three two-rod
elements, its twelve nodes started on a cylinder, every tendon alike, released and damped until
it comes to rest. This is what ``tensegrity simulate`` does with no options; here it is taken
apart: the structure, the run, and the paper's Figures 18.10 to 18.12.
"""

# %%
# The structure
# -------------
# :func:`~tensegrity.model.shell.class1_shell` builds the shell of ``n x m`` elements with the
# closure rules of the paper (``docs/paper-notes.md``). A
# :class:`~tensegrity.model.structure.Structure` is immutable and validated; its arrays are named
# ``<object>_<property>`` in SI units.
import numpy as np

from tensegrity import class1_shell, internal_damping, simulate, tendon_tensions
from tensegrity.plots.figures import figure_structure, figure_tendon_lengths

shell = class1_shell(3, 1)
print(shell.n_nodes, "nodes,", shell.n_rods, "rods,", shell.n_tendons, "tendons")
print("rod mass [kg]:", shell.rod_mass[0], " rod length [m]:", shell.rod_length[0])
k, rest = shell.tendon_stiffness[0], shell.tendon_rest_length[0]
print("stiffness [N/m]:", k, " rest length [m]:", rest)

# %%
# Figure 18.10: the start, every node on a cylinder, the tendons coloured by the tension they start
# with (:func:`~tensegrity.physics.dynamics.tendon_tensions`: far from equal, the shell is not yet
# at rest).
tension = tendon_tensions(shell, shell.node_position)
print(f"tensions at the start: {tension.min():.1f} to {tension.max():.1f} N")
start = figure_structure(
    shell, shell.node_position, tension, title="Initial configuration (Fig. 18.10)"
)

# %%
# The run
# -------
# The paper damps the shell with an "artificial critical damping" it does not define; ours
# (:func:`~tensegrity.physics.dynamics.internal_damping`) damps each tendon critically and the rods'
# motion relative to the structure's rigid motion, so that nothing drags the shell through space.
# ``steady_state=True`` ends the run when every node is at rest. DOP853 locates each slack/taut
# switch of a tendon inside the step it happens in.
run = simulate(internal_damping(shell), (0.0, 20.0), steady_state=True, sample_dt=0.01)
print(run.message)
print("switches located:", run.nswitches, " steps:", run.nsteps)
energy = run.total_energy
print(f"energy balance drift: {np.ptp(energy):.2e} J (kinetic + elastic + dissipated)")

# %%
# Figure 18.11: the equilibrium it comes to rest in, tendons coloured by tension [N].
rest = figure_structure(
    shell,
    run.node_position[-1],
    run.tendon_tension[-1],
    title="Steady-state equilibrium (Fig. 18.11)",
)

# %%
# Figure 18.12: the tendon lengths on the way there, and their rest length.
lengths = figure_tendon_lengths(
    run.t, run.tendon_length, shell.tendon_name, rest_length=shell.tendon_rest_length
)

# %%
# The same from the shell, with every file written to ``results/``::
#
#     tensegrity simulate
