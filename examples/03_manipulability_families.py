"""
D and R along posture families, and an (alpha, T_s) map
=========================================================

Section III of the paper measures how well the joint torques drive the head
``w = [x_h, y_h, theta_1]``: the **dynamic manipulability** D (eq. 30) is the smallest
singular value of the map from torques to head accelerations, and R (eq. 31) the
smallest singular value of the coupling block H12 of the inertia matrix. Both are zero
when the joints cannot push the head in some direction. With a **free joint** (no
actuator, Section III.2) the same definitions give D~ and R~ (eq. 42).

This example computes them along the paper's families (arcs, serpenoids of eq. 43) with
:func:`snake_pin.sweeps.sweep`, and R over a map of serpenoids with
:func:`snake_pin.sweeps.r_map`. Few points keep it fast; the command line
(``snake-pin sweep``) does the full resolution.
"""

# %%
# One posture
# -----------
import matplotlib.pyplot as plt
import numpy as np

from snake_pin import Serpenoid, Snake, SnakeParams, arc, straight
from snake_pin.manipulability import manipulability
from snake_pin.sweeps import r_map, sweep

snake = Snake(SnakeParams.table1())
n = snake.params.n
for name, q in (("straight", straight(n)), ("arc phi0 = pi/10", arc(n, np.pi / 10)),
                ("serpenoid", Serpenoid(n, alpha=np.pi / 4, ts=1.5).configuration(0.0))):
    m = manipulability(snake, q)
    print(f"{name:18s} D = {m.D:.3e}   R = {m.R:.3e}")
assert manipulability(snake, straight(n)).R < 1e-12   # the straight posture is singular

# %%
# Along the families, with and without a free joint 5
# ---------------------------------------------------
families = {}
for family in ("arc", "alpha"):
    families[family] = (sweep(snake, family, points=41),
                        sweep(snake, family, points=41, free_joint=5))

fig, axes = plt.subplots(2, 2, figsize=(10, 6), sharex="col")
for col, (fixed, free) in enumerate(families.values()):
    for row, key in enumerate(("D", "R")):
        ax = axes[row, col]
        ax.plot(fixed.values, getattr(fixed, key), label=f"{key} (all joints actuated)")
        ax.plot(free.values, getattr(free, key), "--", label=f"{key}~ (joint 5 free)")
        ax.set_ylabel(key)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[1, col].set_xlabel(fixed.label)
axes[0, 0].set_title("arcs: every joint at phi0 (Figs. 2-3)", fontsize=10)
axes[0, 1].set_title("serpenoids, T_s = 1.5 (Fig. 4)", fontsize=10)
fig.tight_layout()
plt.show()

# A free joint can only lower the criteria: fewer inputs, a smaller ellipsoid.
arc_fixed, arc_free = families["arc"]
assert np.all(arc_free.R <= arc_fixed.R + 1e-12)

# %%
# R over serpenoids: a map in (alpha, T_s)
# ----------------------------------------
# R vanishes on the axes (alpha = 0 or T_s = 0 is the straight posture) and grows with
# the winding.
rmap = r_map(snake, alpha_points=31, ts_points=26)
fig, ax = plt.subplots(figsize=(6, 4.2))
# rmap.R has one row per T_s value and one column per alpha value
mesh = ax.pcolormesh(rmap.alpha, rmap.ts, rmap.R, shading="auto", cmap="viridis")
fig.colorbar(mesh, ax=ax, label="R")
ax.set_xlabel("alpha [rad]")
ax.set_ylabel("T_s")
ax.set_title("R of the serpenoid (43), Table 1 robot", fontsize=10)
plt.show()
assert np.all(rmap.R[0, :] < 1e-12) and np.all(rmap.R[:, 0] < 1e-12)
