"""
A robot rolling on the ground, and a model fitted to its motion
===============================================================

The three-bar robot standing on its base triangle, thrown sideways and spun: it tips over its
base's edge and rolls onto a side. Its ends touch down, stick and slip on a ground with Coulomb
friction; the engine locates every change of contact mode as an event. Then the identification
of issue 31: from three noisy markers at 30 Hz, the ground's kinetic friction and the cables'
stiffness are fitted back (the Jacobian from sensitivities integrated through those events).
"""

# %%
# The throw
# ---------
import numpy as np

from tensegrity import simulate
from tensegrity.analysis.identification import Experiment, fit
from tensegrity.design.catalogue import three_bar_robot
from tensegrity.engine.sensors import Sensor, measure
from tensegrity.model.ground import ground
from tensegrity.physics.dynamics import State, coordinates_from_nodes, initial_state
from tensegrity.plots.figures import figure_structure, new_figure

robot = three_bar_robot(stiffness=300.0, tension=20.0)
lifted = robot.node_position + np.array([0.0, 0.0, 0.005])  # 5 mm up
robot = robot.replace(node_position=lifted)
centre = robot.node_position.mean(axis=0)
spin = np.cross([0.0, -10.0, 0.0], robot.node_position - centre)  # 10 rad/s about -y
velocity = spin + np.array([-1.0, 0.0, 0.0])  # and 1 m/s along -x [m/s]
start = State(0.0, initial_state(robot).q, coordinates_from_nodes(robot, velocity))
scene = {"gravity": [0.0, 0.0, -9.81], "ground": ground(friction=0.8, kinetic_friction=0.6)}
run = simulate(robot, (0.0, 1.0), initial=start, sample_dt=0.01, **scene)
print(run.message)
print("contact events:", run.contact_counts)
landed = figure_structure(
    robot, run.node_position[-1], run.tendon_tension[-1], title="On its side after 1 s"
)

# %%
# Measured motion
# ---------------
# Three markers, one on an end of each bar (the base triangle's corners), as a motion-capture
# system would give them: 30 Hz, 1 mm of noise (:mod:`tensegrity.engine.sensors`).
names = robot.node_name[:3]
(series,) = measure(run, [Sensor("position", nodes=names, noise=1e-3, rate=30.0)], seed=0).series
markers = {n: (series.t, series.value[:, 3 * i : 3 * i + 3]) for i, n in enumerate(names)}

# %%
# The fit
# -------
# A model with the wrong friction (0.45) and cable stiffness (250 N/m) is fitted to the
# markers; the report gives each estimate with its standard error and 95 % interval.
guess = {"gravity": scene["gravity"], "ground": ground(friction=0.8, kinetic_friction=0.45)}
model = robot.replace(tendon_stiffness=np.full(robot.n_tendons, 250.0))
result = fit(
    model, Experiment(markers, 1e-3, start, options=guess), ["kinetic_friction", "tendon_stiffness"]
)
for p, value, error in zip(result.parameters, result.estimate, result.standard_error, strict=True):
    print(f"{p.name}: {value:.4f} +- {error:.1g}")
print("rms error:", result.rms_summary())

# %%
# The first marker's height, measured and as the fitted model moves it.
fitted = simulate(result.structure, (0.0, 1.0), initial=start, sample_dt=0.01, **result.options[0])
heights = new_figure((7.0, 3.5))
ax = heights.subplots()
t, xyz = markers[names[0]]
ax.plot(t, xyz[:, 2], ".", color="black", label="measured")
ax.plot(fitted.t, fitted.node_position[:, 0, 2], label="fitted model")
ax.set_xlabel("t [s]")
ax.set_ylabel(f"{names[0]} height [m]")
ax.legend()
