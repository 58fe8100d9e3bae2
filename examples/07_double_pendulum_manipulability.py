"""
Dynamic manipulability of another robot: example-robot-data's double pendulum
==============================================================================

:func:`snake_pin.manipulability.dynamic_manipulability` is the paper's criterion for any
Pinocchio model: name the velocity indices that have no actuator and, optionally, a
task. With the default task (the unactuated coordinates themselves) D is the smallest
singular value of ``[H^-1]_{u,a}``, the map from the torques to the unactuated
accelerations, and R that of the coupling block ``H_ua``, exactly as for the snake's
head. With a task Jacobian J it is ``A = J H^-1 B``: Yoshikawa's dynamic manipulability
``J M^-1`` when every joint is actuated.

The double pendulum of `example-robot-data` (two revolute x joints) gives three robots:
the **pendubot** (elbow free), the **acrobot** (shoulder free) and the fully actuated arm.
"""

# %%
import example_robot_data
import matplotlib.pyplot as plt
import numpy as np
import pinocchio as pin

from snake_pin.manipulability import dynamic_manipulability

robot = example_robot_data.load("double_pendulum")
model = robot.model
# a frame at the tip of the second link (its centre of mass is 0.10 m from the elbow)
model.addFrame(pin.Frame("tip", 2, model.getFrameId("link2"),
                         pin.SE3(np.eye(3), np.array([0.0, 0.0, 0.2])), pin.FrameType.OP_FRAME))
data = model.createData()
elbow = np.linspace(-np.pi, np.pi, 181)


def criteria(unactuated: list[int], **task: object) -> np.ndarray:
    """(D, R) at shoulder angle 0 and every elbow angle."""
    values = [dynamic_manipulability(model, data, np.array([0.0, q2]), unactuated, **task)
              for q2 in elbow]
    return np.array([(m.D, m.R) for m in values])


pendubot = criteria([1])            # velocity index 1 (the elbow) has no motor
acrobot = criteria([0])             # the shoulder has no motor
# fully actuated: the tip's (y, z) velocity, rows 1 and 2 of its 6-D Jacobian
arm = criteria([], task="tip", rows=[1, 2])

# %%
# Checks
# ------
# For the fully actuated arm the tip cannot move along the arm when it is stretched
# (elbow at 0): D vanishes there and nowhere else on the grid away from +-pi.
stretched = np.argmin(np.abs(elbow))
print(f"arm D at the stretched posture: {arm[stretched, 0]:.1e}, "
      f"at elbow pi/2: {arm[np.argmin(np.abs(elbow - np.pi / 2)), 0]:.2f}")
assert arm[stretched, 0] < 1e-8 < arm[np.argmin(np.abs(elbow - np.pi / 2)), 0]
# With one actuator and one unactuated joint the task is 1-D: D = |[H^-1]_ua| and
# R = |H_ua|. H^-1 and H are symmetric, so the pendubot and the acrobot have the same D
# and R at every posture, and D > 0 wherever the coupling H_12 does not vanish.
assert np.allclose(pendubot, acrobot)
assert np.all(pendubot[:, 0] > 0) and np.all(pendubot[:, 1] > 0)

# %%
# Plot
# ----
fig, axes = plt.subplots(1, 2, figsize=(11, 3.6))
axes[0].plot(elbow, pendubot[:, 0], label="pendubot or acrobot: D = |[H^-1]_12|")
axes[0].plot(elbow, arm[:, 0], label="fully actuated: D of the tip (y, z)")
axes[0].set_xlabel("elbow angle q2 [rad]")
axes[0].set_yscale("log")
axes[0].legend(fontsize=8)
axes[0].set_title("D (shoulder at 0)", fontsize=10)
axes[1].plot(elbow, pendubot[:, 1])
axes[1].set_xlabel("elbow angle q2 [rad]")
axes[1].set_title("R = |H_12| (pendubot or acrobot)", fontsize=10)
fig.tight_layout()
plt.show()
