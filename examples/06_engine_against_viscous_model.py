"""
Run on MuJoCo and compare with the viscous model
================================================

Section VI.3 of the paper checks the head controller on a physics engine. snake_pin
uses MuJoCo: the same links (masses, inertias, lengths from the same
:class:`~snake_pin.SnakeParams`) ride on passive wheels with Coulomb contacts, and the
controller only sees positions (velocities come from a dirty derivative at 10 Hz).

:func:`snake_pin.engine.run.run_engine` first **identifies** the viscous coefficients the
controller's model uses (short coasting pushes of the straight snake on its wheels),
then runs the velocity-level Lyapunov-like law at 1 kHz along the head-first reference
``w_r = [0.1 t, 0, pi]``. The same controller on the viscous Pinocchio model with the
identified coefficients is the "twin". A short run keeps this example fast (the paper's
runs are 60 s: ``snake-pin engine``).
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

from snake_pin import Snake, SnakeParams, head_first_reference, simulate
from snake_pin.control import QuasiStaticLyapunovController
from snake_pin.engine.run import run_engine
from snake_pin.gaits import initial_state

T_FINAL = 8.0
params = SnakeParams.engine()
engine = run_engine(params, t_final=T_FINAL)
friction = engine.friction
print("identified: " + ", ".join(f"{k} = {friction[k]:.4g}" for k in ("c_x", "c_y", "c_theta")))
print("engine run:", engine.trajectory.status)

# %%
# The viscous twin
# ----------------
twin_params = params.replace(c_x=friction["c_x"], c_y=friction["c_y"],
                             c_theta=friction["c_theta"])
snake = Snake(twin_params)
controller = QuasiStaticLyapunovController(snake, head_first_reference())
twin = simulate(snake, controller, initial_state(params.n, theta_1=np.pi), T_FINAL)
print("viscous twin:", twin.status)

# %%
# Head against the reference
# --------------------------
# The head's error is measured against the body length sum(2 l_i).
body = params.link_lengths.sum()
fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
for traj, label, style in ((engine.trajectory, "MuJoCo (wheels, Coulomb)", "-"),
                           (twin, "Pinocchio, viscous (identified)", "--")):
    error = np.hypot(traj.q[:, 0] - 0.1 * traj.t, traj.q[:, 1])
    late = traj.t >= T_FINAL / 2
    rms = 100 * np.sqrt(np.mean(error[late] ** 2)) / body
    print(f"{label:32s} RMS head error over the second half: {rms:.1f} % of the body")
    assert traj.status == "completed" and rms < 20
    axes[0].plot(traj.q[:, 0], traj.q[:, 1], style, label=label)
    axes[1].plot(traj.t, 100 * error / body, style, label=label)
axes[0].plot(0.1 * engine.trajectory.t, 0 * engine.trajectory.t, ":", color="k",
             label="reference")
axes[0].set_xlabel("x_h [m]")
axes[0].set_ylabel("y_h [m]")
axes[0].set_title("head path", fontsize=10)
axes[0].legend(fontsize=8)
axes[1].set_xlabel("t [s]")
axes[1].set_ylabel("head error [% of body length]")
axes[1].set_title("head error", fontsize=10)
fig.tight_layout()
plt.show()
