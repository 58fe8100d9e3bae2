"""
Track a curved path with the head
=================================

The paper's head reference is a straight line, ``w_r = [0.1 t, 0, pi]``.
:mod:`snake_pin.paths` gives curved ones: a :class:`~snake_pin.paths.Path` is a planar
curve parametrised by arc length s (line, circle, arc, lane change, sinusoid, waypoint
spline), a :class:`~snake_pin.paths.Timing` moves along it at a constant speed, and a
:class:`~snake_pin.paths.PathReference` turns the two into the head reference
``w_r(t) = [p(s(t)), gamma(s(t)) + pi]`` (head first), with the same interface as
:class:`~snake_pin.control.reference.LinearReference`: the controllers take either.

Here the Lyapunov-like controller (Section VI.2) drives the Table 1 robot, with
wheel-like friction, through a lane change; the error is measured across the path
(:func:`~snake_pin.paths.cross_track_error`) and along it
(:func:`~snake_pin.paths.along_track`). The head sways with the gait and runs a few
centimetres to the right of the path (the law trades the head's error against the
gait's, see :mod:`snake_pin.control.lyapunov`), and it changes lanes.
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

from snake_pin import LyapunovController, Snake, SnakeParams, simulate
from snake_pin.gaits import initial_state
from snake_pin.paths import PathReference, Timing, along_track, cross_track_error, make_path
from snake_pin.viz.plots import draw_snake

params = SnakeParams.table1().replace(c_x=0.5, c_y=25.0)   # anisotropic: erratum 3
snake = Snake(params)
path = make_path("lane_change", offset=0.2, length=0.8, start=0.2)
reference = PathReference(path, Timing(speed=0.1, ramp=1.0))
controller = LyapunovController(snake, reference)

# start at rest at the head of the path, head first (theta_1 = pi along +x)
traj = simulate(snake, controller, initial_state(params.n, theta_1=np.pi), t_final=15.0)
print(traj.status)

# %%
# Errors across and along the path
# --------------------------------
head = traj.q[:, :2]
across = cross_track_error(path, head)
progress = along_track(path, head)
target = np.array([reference(t)[0][:2] for t in traj.t])
print(f"head at s = {progress[-1]:.2f} m of the path (reference at "
      f"{along_track(path, target[-1:])[0]:.2f} m)")
late = traj.t >= 10
print(f"cross-track error over the last 5 s: mean {100 * across[late].mean():.1f} cm, "
      f"RMS {100 * np.sqrt(np.mean(across[late] ** 2)):.1f} cm")
assert traj.status == "completed"
assert progress[-1] > 1.0                  # through the lane change (s = 0.2 .. 1.0 m)
assert head[late, 1].mean() > 0.1          # closer to the new lane (y = 0.2) than the old

# %%
# Plot
# ----
curve = np.array([reference(t)[0][:2] for t in np.linspace(0, 16, 200)])
fig, axes = plt.subplots(2, 1, figsize=(9, 6), gridspec_kw={"height_ratios": [2, 1]})
axes[0].plot(curve[:, 0], curve[:, 1], ":", color="k", label="path")
axes[0].plot(head[:, 0], head[:, 1], label="head")
for k in np.linspace(0, len(traj.t) - 1, 4).astype(int):
    draw_snake(axes[0], snake, traj.q[k], alpha=0.3 + 0.7 * k / (len(traj.t) - 1))
axes[0].legend(fontsize=8)
axes[0].set_title("a lane change of 0.2 m at 0.1 m/s (snapshots every 5 s)", fontsize=10)
axes[1].plot(traj.t, 100 * across)
axes[1].set_xlabel("t [s]")
axes[1].set_ylabel("cross-track error [cm]")
axes[1].grid(alpha=0.3)
fig.tight_layout()
plt.show()
