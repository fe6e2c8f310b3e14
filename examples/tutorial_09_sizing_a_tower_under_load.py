"""
Sizing a tower under load
=========================

A three-stage tower (Snelson's Needle Tower) standing on its base, steel rods and Dyneema
cables, under its own weight and 100 N down on each top node: the lightest members that carry
the load where the tower carries it, at its loaded and deformed equilibrium; the members'
utilisation there; and two checks in motion: the load put on slowly, which the design holds,
and all at once, which it does not. From the shell the same design is ``tensegrity design
--kind tower --m 3 --fixed-base --material steel,dyneema --prestress 50 --gravity 9.81 --load
...`` (``docs/cli.md``, ``docs/design.md``).
"""

# %%
# The tower and its load cases
# ----------------------------
# :func:`~tensegrity.design.catalogue.tower` stacks three prisms and form-finds them into a
# prestressed equilibrium; ``fixed_base=True`` fixes the three bottom nodes to the ground. A
# :class:`~tensegrity.design.sizing.LoadCase` is nodal forces [N] and gravity [m/s^2]. Its
# rods' masses and tendons' stiffnesses do not matter here: the sizing keeps the geometry and
# the members, and chooses their areas.
import numpy as np

from tensegrity import internal_damping, simulate
from tensegrity.design.catalogue import tower
from tensegrity.design.dynamic import dynamic_check
from tensegrity.design.loaded import mechanism_count, size_at_equilibrium
from tensegrity.design.materials import material
from tensegrity.design.sizing import LoadCase, size_members
from tensegrity.design.utilisation import run_utilisation
from tensegrity.plots.figures import figure_utilisation, new_figure

needle = tower(3, 3, fixed_base=True)
z = needle.node_position[:, 2]
top = np.flatnonzero(np.isclose(z, z.max()))
print(needle.n_nodes, "nodes,", needle.n_rods, "rods,", needle.n_tendons, "tendons")
print("fixed:", np.flatnonzero(needle.node_fixed).tolist(), "| top:", top.tolist())
print(f"height {z.max():.3f} m, rods {needle.rod_length[0]:g} m long")

gravity = np.array([0.0, 0.0, -9.81])
down = np.zeros((needle.n_nodes, 3))
down[top, 2] = -100.0
cases = [LoadCase("gravity", None, gravity), LoadCase("top", down, gravity)]
steel, dyneema = material("steel"), material("dyneema")
for m in (steel, dyneema):
    E, yield_, rho = m.youngs_modulus / 1e9, m.yield_strength / 1e6, m.density
    print(f"{m.name}: E {E:g} GPa, yield strength {yield_:g} MPa, density {rho:g} kg/m^3")

# %%
# Why not the linear sizing
# -------------------------
# A tensegrity tower is a mechanism stiffened by its prestress: the top load pushes along a
# motion no member resists at first, and the tower carries it only after it has moved.
# :func:`~tensegrity.design.sizing.size_members` balances the loads at the undeformed
# geometry, so it refuses this one (in one line naming the case).
print("mechanisms:", mechanism_count(needle))
try:
    size_members(
        needle, rod_material=steel, tendon_material=dyneema, load_cases=[cases[1]], prestress=50.0
    )
except ValueError as refused:
    print(refused)

# %%
# Sized at the loaded equilibrium
# -------------------------------
# :func:`~tensegrity.design.loaded.size_at_equilibrium` first puts every tendon at 50 N or
# more in the unloaded geometry (the prestress), then finds each case's equilibrium by load
# steps, each checked stable (:func:`~tensegrity.design.loaded.follow_load`), sizes the
# members for the forces there (yield, and Euler buckling of solid rods), and repeats until
# the areas no longer change. Where the areas the forces need would let the top load's path
# reach a limit point (the tower would snap through), the tendons are stiffened together:
# ``stability`` governs them.
sizing = size_at_equilibrium(
    needle, rod_material=steel, tendon_material=dyneema, load_cases=cases, prestress=50.0
)
print(sizing.message)
print(f"mass {sizing.total_mass:.3f} kg: rods {sizing.rod_mass.sum():.3f} kg, ", end="")
print(f"tendons {1e3 * sizing.tendon_mass.sum():.2f} g")
rod_d = 1e3 * np.sqrt(4 * sizing.rod_area / np.pi)
tendon_d = 1e3 * np.sqrt(4 * sizing.tendon_area / np.pi)
print("rod areas [mm^2], stage by stage:", np.round(1e6 * sizing.rod_area[::3], 2))
print("rod diameters [mm], stage by stage:", np.round(rod_d[::3], 2))
print(f"tendon diameters: {tendon_d.min():.3f} to {tendon_d.max():.3f} mm")
governs, count = np.unique(sizing.governs, return_counts=True)
print("governed by:", dict(zip(governs.tolist(), count.tolist(), strict=True)))
for name, moved in zip(sizing.cases[1:], sizing.displacement, strict=True):
    print(f"case {name!r}: largest displacement {1e3 * moved:.1f} mm")
print("lowest frequency [Hz], unloaded and in each case:", np.round(sizing.frequency, 3))

# %%
# Utilisation per member
# ----------------------
# A member's utilisation is its force over what it can carry: a tendon's stress over its yield
# strength, a rod's compression over the larger of its yield and Euler loads
# (:mod:`~tensegrity.design.utilisation`). The design is fully stressed: every member sized by
# its own forces is at 1 in the case that governs it (here the top load); the tendons stiffened
# for stability stay below. The figure shows the tower at the top load's equilibrium, each
# member coloured by its utilisation there.
u = sizing.utilisation
print("largest utilisation in each case:")
for k, name in enumerate(sizing.cases):
    print(f"{name:>9}: rods {u.rod[k].max():.4f}, tendons {u.tendon[k].max():.4f}")
stiffened = np.array(sizing.governs[needle.n_rods :]) == "stability"
print(f"the stiffened tendons: {u.tendon[:, stiffened].max():.3f} at most")

loaded = sizing.equilibria[1]
at_the_top = figure_utilisation(
    sizing.structure,
    loaded.node_position,
    u.rod[2],
    u.tendon[2],
    title="Utilisation under the top load, at its equilibrium",
)

# %%
# Each member in each case, rods first:
members = new_figure((8.0, 3.6))
ax = members.subplots()
for k, (name, marker) in enumerate(zip(sizing.cases, "sox", strict=True)):
    ax.plot(np.concatenate([u.rod[k], u.tendon[k]]), marker, ls="none", mfc="none", label=name)
ax.axvline(needle.n_rods - 0.5, color="0.6", lw=0.8)
ax.axhline(1.0, color="0.3", lw=0.8, ls="--")
ax.set_xlabel(f"member (rods 0-{needle.n_rods - 1}, then tendons)")
ax.set_ylabel("utilisation")
ax.legend(loc="lower right")


# %%
# Checked in motion
# -----------------
# The sizing's equilibria come from the nonlinear statics; the engine checks them independently. The
# sized structure (:attr:`~tensegrity.design.sizing.Sizing.structure`), damped by
# :func:`~tensegrity.physics.dynamics.internal_damping`, stands under gravity while the top load
# grows over 2 s and is then held, until it comes to rest; its members' utilisation at every sample
# comes from :func:`~tensegrity.design.utilisation.run_utilisation`.
def slowly(t: float) -> np.ndarray:
    """The top load, grown linearly over 2 s [N]."""
    return min(t / 2.0, 1.0) * down


run = simulate(
    internal_damping(sizing.structure),
    (0.0, 20.0),
    external_force=slowly,
    gravity=gravity,
    steady_state=True,
    sample_dt=0.02,
)
print(run.message)
gap = np.abs(run.node_position[-1] - loaded.node_position).max()
print(f"at rest {gap:.1e} m from the sizing's equilibrium")
sank = 1e3 * (z[top] - run.node_position[-1, top, 2]).mean()
moved = 1e3 * np.linalg.norm(run.node_position[-1, top] - run.node_position[0, top], axis=1).max()
print(f"the top nodes moved {moved:.1f} mm: {sank:.1f} mm down, the rest a twist about the axis")
slow = run_utilisation(run, sizing.members, external_force=slowly)
over = slow.failures(run.structure)
print(f"largest utilisation over the run {slow.largest:.4f}; members over 1: {len(over)}")

# %%
# A static design is for loads put on slowly. Put on all at once and held,
# :func:`~tensegrity.design.dynamic.dynamic_check` (2 % of critical damping in each tendon)
# finds the members overshooting their limits: a load applied suddenly is another load case.
sudden = dynamic_check(sizing.structure, sizing.members, [cases[1]])[0]
print(f"applied suddenly: largest utilisation {sudden.largest:.3f}, fails: {sudden.fails}")
over = sudden.utilisation.failures(sizing.structure)
print(f"{len(over)} members over 1, e.g. {over[0]}")

motion = new_figure((8.0, 3.6))
sink, use = motion.subplots(1, 2)
sink.plot(run.t, 1e3 * (run.node_position[0, top, 2] - run.node_position[:, top, 2]).mean(axis=1))
sink.axhline(1e3 * (z[top] - loaded.node_position[top, 2]).mean(), color="0.3", lw=0.8, ls="--")
sink.set_xlabel("t [s]")
sink.set_ylabel("top nodes' sinking [mm]")
use.plot(slow.t, np.maximum(slow.samples.rod.max(axis=1), slow.samples.tendon.max(axis=1)))
peaks = sudden.utilisation.samples
use.plot(sudden.utilisation.t, np.maximum(peaks.rod.max(axis=1), peaks.tendon.max(axis=1)))
use.axhline(1.0, color="0.3", lw=0.8, ls="--")
use.set_xlabel("t [s]")
use.set_ylabel("largest utilisation")
use.legend(["load grown over 2 s", "load applied at t = 0"], loc="lower right")
