"""
Your own structure from N, C_b and C_s
======================================

Any class 1 network comes from the field's three matrices (Skelton & de Oliveira's
convention): the node matrix ``N`` (3 x n, one column per node) and the connectivity matrices
of the bars ``C_b`` and of the strings ``C_s`` (one row per member, -1 at its tail, +1 at its
head). Here the three-bar prism (the "simplex") built by hand, brought to rest, then reshaped by
shortening one string: the rest-length control ``u`` of the paper (``Lbar = L0 - u``).
"""

# %%
# The matrices
# ------------
# Two triangles of radius 1 m, 1 m apart, the top one turned by 150 degrees (the prism's
# equilibrium twist); bar ``i`` joins bottom node ``i`` to top node ``i``; the strings are the
# two triangles and three "verticals" from bottom node ``i`` to top node ``i - 1``.
import numpy as np

from tensegrity import internal_damping, simulate
from tensegrity.model.connectivity import from_connectivity, to_connectivity
from tensegrity.plots.figures import figure_structure, figure_tendon_lengths

angle = 2 * np.pi * np.arange(3) / 3
bottom = np.stack([np.cos(angle), np.sin(angle), np.zeros(3)])
top = np.stack([np.cos(angle + np.radians(150)), np.sin(angle + np.radians(150)), np.ones(3)])
N = np.hstack([bottom, top])  # (3, 6) [m]


def members(pairs: list[tuple[int, int]]) -> np.ndarray:
    """Connectivity rows: -1 at each pair's tail, +1 at its head."""
    C = np.zeros((len(pairs), 6))
    for row, (tail, head) in enumerate(pairs):
        C[row, tail], C[row, head] = -1.0, 1.0
    return C


C_b = members([(0, 3), (1, 4), (2, 5)])
C_s = members([(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3), (0, 5), (1, 3), (2, 4)])

# %%
# The structure: bars of 1 kg, strings of 500 N/m whose rest lengths are 5 % short of their
# lengths in ``N`` (their prestrain). The bars' lengths are their lengths in ``N``.
prism = from_connectivity(N, C_b, C_s, rod_mass=1.0, tendon_stiffness=500.0, tendon_prestrain=0.05)
print(prism.n_rods, "bars,", prism.n_tendons, "strings")
print("bar lengths [m]:", np.round(prism.rod_length, 4))
N_back, C_b_back, C_s_back = to_connectivity(prism)  # and back, for any structure
print("same matrices:", np.allclose(N_back, N), np.array_equal(C_s_back, C_s))

# %%
# To rest
# -------
# Released with its strings stretched, it settles, damped, into its prestressed
# equilibrium; DOP853 locates every slack/taut switch on the way.
run = simulate(internal_damping(prism), (0.0, 10.0), steady_state=True, sample_dt=0.005)
print(run.message, "| switches:", run.nswitches)
at_rest = figure_structure(
    prism, run.node_position[-1], run.tendon_tension[-1], title="The prism at rest"
)

# %%
# Rest-length control
# -------------------
# A control ``u`` [m] shortens a string's rest length, ``Lbar = L0 - u``: pulling in the first
# vertical by 5 cm twists and squats the prism. Starting from the rest above, the structure
# moves to its new equilibrium; the figure shows the strings' lengths on the way, the pulled
# one shortening, the others following.
u = np.zeros(prism.n_tendons)
u[6] = 0.05
again = simulate(
    internal_damping(prism),
    (0.0, 10.0),
    initial=run.final_state,
    control=u,
    steady_state=True,
    sample_dt=0.005,
)
print(again.message)
lengths = figure_tendon_lengths(
    again.t, again.tendon_length, prism.tendon_name, title="Strings, one pulled in by 5 cm"
)
