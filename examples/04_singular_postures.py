"""
Find singular postures (R = 0) beyond the straight one
========================================================

Along arcs and serpenoids the paper finds R = 0 only at the straight posture. A search
of the whole joint box ``|phi_i| <= pi/2`` finds more:
:func:`snake_pin.singular.find_singular_postures` minimises R from random starts
(L-BFGS-B on R^2, then a polish) and clusters the minima where R is numerically zero
into families. A dimension count predicts them: rank-deficient 3 x 9 matrices H12 have
codimension 7 in the 9-dimensional joint space, so a two-parameter family exists.

A handful of starts keeps this example fast; ``snake-pin singular --starts 200`` is the
real search.
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

from snake_pin import Snake, SnakeParams
from snake_pin.manipulability import manipulability
from snake_pin.singular import find_singular_postures
from snake_pin.viz.plots import draw_snake

params = SnakeParams.table1()
search = find_singular_postures(params, starts=16, seed=1)
print(f"{len(search.families)} families; 'zero' means R <= {search.threshold:.1e} "
      f"(typical R in the box: {search.R_typical:.1e})")
for k, family in enumerate(search.families):
    print(f"family {k}: {family.members} starts, R = {family.R:.1e}, "
          f"straight: {family.straight}")

# %%
# Check one family independently
# ------------------------------
# The search uses a vectorised closed form of H12; the Pinocchio route of
# :func:`~snake_pin.manipulability.manipulability` agrees that R (and D, by Theorem 1)
# vanishes there, while a random posture of the box is far from singular.
snake = Snake(params)
curled = np.r_[0.0, 0.0, 0.0, search.families[0].phi]
random = np.r_[0.0, 0.0, 0.0, np.random.default_rng(3).uniform(-np.pi / 2, np.pi / 2, 9)]
at_family, at_random = manipulability(snake, curled), manipulability(snake, random)
print(f"family 0: R = {at_family.R:.1e}, D = {at_family.D:.1e}")
print(f"random  : R = {at_random.R:.1e}, D = {at_random.D:.1e}")
assert at_family.R < 1e-6 * at_random.R
assert any(not family.straight for family in search.families)

# %%
# Draw the families
# -----------------
fig, axes = plt.subplots(1, len(search.families), figsize=(3.6 * len(search.families), 3.4),
                         squeeze=False)
for ax, family in zip(axes[0], search.families, strict=True):
    draw_snake(ax, snake, np.r_[0.0, 0.0, 0.0, family.phi])
    ax.set_title(f"R = {family.R:.0e} ({family.members} starts)", fontsize=10)
fig.suptitle("Singular postures of the Table 1 robot (every |phi_i| <= pi/2)", fontsize=11)
fig.tight_layout()
plt.show()
