"""
Controllability, an LQR controller and shape control
====================================================

Which motions of the (3,1) shell can its tendons' rest lengths move, and a controller that
damps them: a linear-quadratic regulator on the modes the controls reach, run inside the
compiled loop through actuators with a lag, against the open loop. Then shape control: the
shell shortened and twisted back by a plan of equilibria, played in time with LQR feedback.
"""

# %%
# Controllability
# ---------------
# About the equilibrium, the linearized shell has 60 states. The PBH test says how many of
# them the rest lengths of a group of tendons reach.
import numpy as np

from tensegrity import State, class1_shell, internal_damping, simulate
from tensegrity.analysis.control_design import lqr, reachable
from tensegrity.analysis.controllability import controllability
from tensegrity.analysis.equilibrium import find_equilibrium
from tensegrity.analysis.linearize import linearize
from tensegrity.analysis.modes import modal_analysis
from tensegrity.analysis.shape_control import closed_loop, height_twist, quasi_static, shell_rings
from tensegrity.model.actuators import actuators
from tensegrity.physics.dynamics import coordinates_from_nodes
from tensegrity.plots.figures import new_figure

shell = class1_shell(3, 1)
eq = find_equilibrium(shell)
lin = linearize(internal_damping(shell), eq)
for group in ("t1_*", "all"):
    report = controllability(lin, modal_analysis(lin), group)
    print(f"tendons {group}: rank {report.rank} of {lin.A.shape[0]} states")

# %%
# An LQR controller
# -----------------
# :func:`~tensegrity.analysis.control_design.lqr` designs on the modes the rest lengths reach
# (the six rigid-body motions and a mode no tendon moves are left out, and said so), sampled
# every 2 ms; its ``feedback`` is the law ``u = u_ref - K (y - y_ref)``. It is designed on the
# damped shell's linearization and run below on the undamped shell: the controller supplies
# the damping.
design = lqr(reachable(lin), period=0.002)
for left in design.uncontrolled:
    print(f"mode {left.mode} ({left.frequency_hz:.2f} Hz) left out: {left.reason}")

# %%
# Open and closed loop
# --------------------
# The shell at its equilibrium, one top node kicked at 0.5 m/s, undamped: open loop it rings;
# closed loop (actuators on the controlled tendons, following their commands with a 10 ms lag)
# it settles, but for the mode no tendon moves. The kick
# also sets the shell drifting and turning, motions no tendon can stop: the figure shows the
# deformation alone, the tendons' largest departure from their equilibrium lengths. What is
# left in closed loop is mostly the uncontrolled mode (3.24 Hz), which stretches the tendons
# only to second order.
kick = np.zeros_like(eq.node_position)
kick[11] = [0.5, 0.0, 0.0]
start = State(0.0, eq.q, coordinates_from_nodes(shell, kick))
motors = actuators(shell, design.feedback.tendons, time_constant=0.01)
runs = {
    "open loop": simulate(shell, (0.0, 2.0), initial=start, sample_dt=0.005),
    "closed loop": simulate(
        shell,
        (0.0, 2.0),
        initial=start,
        controller=design.feedback,
        actuators=motors,
        sample_dt=0.005,
    ),
}
response = new_figure((7.0, 3.5))
ax = response.subplots()
for label, run in runs.items():
    stretched = np.abs(run.tendon_length - eq.tendon_length).max(axis=1)
    ax.plot(run.t, 1e3 * stretched, label=label)
    print(f"{label}: {1e3 * stretched[-40:].max():.2f} mm over the last 0.2 s")
ax.set_xlabel("t [s]")
ax.set_ylabel("largest tendon stretch [mm]")
ax.legend()

# %%
# Shape control
# -------------
# The outputs here are the height and the twist of the top ring over the bottom one
# (:func:`~tensegrity.analysis.shape_control.height_twist`, with analytic Jacobians).
# :func:`~tensegrity.analysis.shape_control.quasi_static` plans a sequence of equilibria: the
# shell shortened to 85 % of its height by the ``t1`` tendons alone (the twist left free: it
# turns), then twisted back with every tendon, each step the least change of the rest lengths
# that moves the outputs there, every tendon kept at 1 N or more.
bottom, top = shell_rings(3, 1)
output = height_twist(eq.node_position, bottom, top)
height = output.value(eq.node_position)[0]
phases = [{"targets": (0.85 * height, None), "actuators": "t1_*"}, (0.85 * height, 0.0)]
plan = quasi_static(shell, output, phases, start=eq, steps=[6, 3])
print(f"plan of {len(plan.equilibria) - 1} steps: {plan.message}")
print(f"twist after the first phase: {plan.outputs[6][1]:.3f} rad")

# %%
# :func:`~tensegrity.analysis.shape_control.closed_loop` plays the plan in time (2 s a
# phase, then 3 s to settle) as a feed-forward of rest lengths and states, with an LQR gain
# designed at the final equilibrium on the deviations, on the nonlinear model with its slack
# law.
loop = closed_loop(plan)
print(loop.message)
shape = new_figure((7.0, 4.5))
height_ax, twist_ax = shape.subplots(2, 1, sharex=True)
for ax, k, unit in ((height_ax, 0, "height [m]"), (twist_ax, 1, "twist [rad]")):
    ax.plot(loop.t, loop.reference_outputs[:, k], "--", color="0.5", label="plan")
    ax.plot(loop.t, loop.outputs[:, k], label="closed loop")
    ax.set_ylabel(unit)
height_ax.legend()
twist_ax.set_xlabel("t [s]")
