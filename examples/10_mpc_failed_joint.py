"""
MPC head tracking with a failed joint
=====================================

A joint whose motor fails turns free: the snake keeps n - 2 motors for n + 1 degrees of
freedom. The model-predictive controller (:class:`~snake_pin.control.MPCController`)
plans with that robot: its optimal-control problem drops the failed joint from the inputs,
so the joint gets exactly zero torque, and the other joints' torques stay within the
bound ``|tau_i| <= torque_bound`` (a box on Box-FDDP's controls, not a clip afterwards).

Here the 8-link wheeled robot of Section VI.3 runs on MuJoCo with joint 5 failed, its head
following a circle of radius one body length at 0.1 m/s.
:func:`~snake_pin.engine.run.run_engine` identifies the viscous model the MPC plans with
(coasting pushes of the straight snake on its wheels), then runs the MPC at 1 kHz on the
positions the engine gives and the velocities of the dirty derivative. The bound is set
below the motors' saturation to show the planned torques meeting it. A short run keeps
this example fast (the report runs 25 s from three perturbed starts: ``snake-pin
reproduce``).
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

from snake_pin import SnakeParams
from snake_pin.control import MPCOptions
from snake_pin.engine.run import run_engine
from snake_pin.paths import Circle, PathReference, Timing

T_FINAL = 4.0
FAILED = 5
BOUND = 3.0                                      # [N m]; the motors saturate at 10 N m
params = SnakeParams.engine(passive=(FAILED,))
body = params.body_length
reference = PathReference(Circle(radius=body), Timing(speed=0.1))
run = run_engine(params, t_final=T_FINAL, law="mpc", reference=reference,
                 mpc_options=MPCOptions(torque_bound=BOUND))
traj = run.trajectory
print(f"{traj.status}, {traj.meta['mpc']['solves']} solves of the "
      f"{traj.meta['mpc']['horizon']:g} s horizon")

# %%
# Head error and torques
# ----------------------
# The error is the distance from the head to where the timed reference is, in % of the
# body length; the failed joint's torque is zero throughout.
target = reference.at(traj.t)[0][:, :2]
error = 100 * np.hypot(*(traj.q[:, :2] - target).T) / body
late = traj.t >= T_FINAL / 2
print(f"RMS head error over the second half: {np.sqrt(np.mean(error[late] ** 2)):.2f} % "
      f"of the {body:.3g} m body")
peak = np.abs(traj.tau).max(axis=0)
print("peak |tau_i| [N m]: " + ", ".join(f"{v:.2f}" for v in peak))
assert traj.status == "completed"
assert peak[FAILED - 1] == 0.0
assert peak.max() <= BOUND + 1e-9

# %%
# Plot
# ----
fig, axes = plt.subplots(1, 2, figsize=(11, 4))
axes[0].plot(target[:, 0], target[:, 1], "k--", lw=1, label="reference")
axes[0].plot(traj.q[:, 0], traj.q[:, 1], color="#d9541a", label="head (MuJoCo)")
axes[0].set_xlabel("x [m]")
axes[0].set_ylabel("y [m]")
axes[0].set_aspect("equal", adjustable="datalim")
axes[0].set_title(f"head path, joint {FAILED} failed", fontsize=10)
axes[0].legend(fontsize=8)
for i in range(params.n - 1):
    style = {"color": "k", "lw": 2} if i == FAILED - 1 else {"lw": 0.8}
    axes[1].plot(traj.t, traj.tau[:, i], label=f"joint {i + 1}", **style)
for sign in (1, -1):
    axes[1].axhline(sign * BOUND, color="firebrick", ls=":", lw=1)
axes[1].set_xlabel("t [s]")
axes[1].set_ylabel("tau [N m]")
axes[1].set_title(f"joint torques, bound +-{BOUND:g} N m (dotted)", fontsize=10)
axes[1].legend(fontsize=7, ncol=2)
for ax in axes:
    ax.grid(alpha=0.3)
fig.tight_layout()
plt.show()
