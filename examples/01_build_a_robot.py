"""
Build a robot: presets, per-link parameters, robot files and URDF
=================================================================

A robot is a :class:`~snake_pin.SnakeParams` (validated, frozen); a
:class:`~snake_pin.Snake` is its Pinocchio model in the paper's coordinates
``q = [x_h, y_h, theta_1, phi_1 .. phi_{n-1}]``. This example builds the same kind of
robot four ways:

* a **preset**: the paper's Table 1 robot (``SnakeParams.table1()``);
* **per link**: any field takes one number or one value per link, head first;
* a **robot file**: the TOML file shipped in ``examples/robots/``;
* a **URDF**: ours (written by :func:`~snake_pin.write_urdf`) or anyone's planar chain of
  revolute z joints, read by :meth:`Snake.from_urdf <snake_pin.model.Snake.from_urdf>`.
"""

# %%
# A preset and a per-link robot
# -----------------------------
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from snake_pin import Snake, SnakeParams, load_robot, robot_paths, write_urdf
from snake_pin.viz.plots import draw_snake

table1 = SnakeParams.table1()
print(table1)

# Six links; a heavier, longer head and a battery tail. Scalars apply to every link.
custom = SnakeParams(n=6, name="my_snake",
                     link_length=[0.20, 0.12, 0.12, 0.12, 0.12, 0.15],
                     mass=[0.40, 0.18, 0.18, 0.18, 0.18, 0.30],
                     inertia=[1.4e-3, 2.2e-4, 2.2e-4, 2.2e-4, 2.2e-4, 5.6e-4],
                     c_x=0.5, c_y=5.0, passive=(3,))
print("link lengths [m]:", custom.link_lengths, " passive joints:", custom.passive)

# %%
# A robot file shipped with the package
# -------------------------------------
# :func:`~snake_pin.robot_paths` lists the shipped URDFs and example robot files;
# :func:`~snake_pin.load_robot` accepts a preset name, a ``.toml`` or a ``.urdf`` path,
# with keyword overrides.
paths = robot_paths()
print(sorted(paths))
camera = load_robot(paths["camera_head_snake.toml"])
print(camera.name, camera.n, "links, masses", camera.per_link("mass"))

# %%
# Through a URDF and back
# -----------------------
# The generated URDF carries the friction in a ``<snake_pin>`` element that other loaders
# ignore. Reading it back gives the same inertia matrix H(q), to rounding.
with tempfile.TemporaryDirectory() as tmp:
    urdf = write_urdf(custom, Path(tmp) / "my_snake.urdf")
    from_urdf = Snake.from_urdf(urdf)
snake = Snake(custom)
q = np.r_[0.0, 0.0, 0.3, np.linspace(-0.6, 0.6, custom.n - 1)]
gap = np.abs(from_urdf.inertia_matrix(q) - snake.inertia_matrix(q)).max()
print(f"max |H_urdf - H_params| = {gap:.1e}")
assert gap < 1e-10

# %%
# Draw them
# ---------
# Link frames sit at each link's centre of mass (as in the paper's Fig. 1); the orange
# dot is the head, a blue cross a passive joint.
fig, axes = plt.subplots(1, 3, figsize=(11, 3.4))
for ax, params, title in zip(axes, (table1, custom, camera),
                             ("Table 1 preset", "per-link, joint 3 passive",
                              "camera_head_snake.toml"), strict=True):
    robot = Snake(params)
    q = np.r_[0.0, 0.0, 0.0, np.full(params.n - 1, np.pi / 8)]
    draw_snake(ax, robot, q, frames=True)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x [m]")
axes[0].set_ylabel("y [m]")
fig.tight_layout()
plt.show()
