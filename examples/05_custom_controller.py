"""
Write and simulate your own controller
======================================

Every controller has one interface: ``controller(x, t) -> tau``, where
``x = [q, dq]`` is the full state (length 2(n + 2), paper coordinates) and ``tau`` the
n - 1 joint torques. Subclass :class:`snake_pin.Controller` (or pass any plain function)
and hand it to :func:`snake_pin.simulate`, which integrates the closed loop with RK4
under a zero-order hold and returns a :class:`~snake_pin.Trajectory`.

The controller written here is the classic one for lateral undulation: a PD loop on
each joint that follows a serpenoid gait (eq. 43). It ignores the head; with
anisotropic friction (wheels: c_y >> c_x) the body then slithers forward.
"""

# %%
# The controller
# --------------
import matplotlib.pyplot as plt
import numpy as np

from snake_pin import Controller, Serpenoid, Snake, SnakeParams, simulate
from snake_pin.viz.plots import draw_snake


class GaitPD(Controller):
    """Joint PD tracking of a serpenoid gait: tau = K_p (phi_r - phi) + K_d (phi_r' - phi')."""

    name = "gait_pd"

    def __init__(self, n: int, gait: Serpenoid, k_p: float = 2.0, k_d: float = 0.1) -> None:
        self.n, self.gait, self.k_p, self.k_d = n, gait, k_p, k_d
        self._error = 0.0

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        phi, dphi = x[3:self.n + 2], x[self.n + 5:]        # x = [q, dq], q = [w, phi]
        phi_r, dphi_r, _ = self.gait.derivatives(t)
        error = phi_r - phi
        self._error = float(np.sqrt(np.mean(error**2)))
        return self.k_p * error + self.k_d * (dphi_r - dphi)

    def signals(self) -> dict[str, float]:
        """Recorded by the simulator at every control step."""
        return {"joint_error": self._error}


# %%
# A run on a robot with wheel-like friction
# -----------------------------------------
params = SnakeParams.table1().replace(c_x=0.5, c_y=25.0)
snake = Snake(params)
n = params.n
gait = Serpenoid(n, alpha=np.pi / 6, ts=1.0, v=3.0)
x0 = np.r_[0.0, 0.0, 0.0, gait.angles(0.0), np.zeros(n + 2)]
traj = simulate(snake, GaitPD(n, gait), x0, t_final=4.0)
print(traj.status, f"{len(traj.t)} samples, last t = {traj.t[-1]:.2f} s")


def centre_of_mass(q: np.ndarray) -> np.ndarray:
    """Mass-weighted mean of the link CMs (link poses hold [x, y, theta] per link)."""
    poses = snake.link_poses(q)
    return params.per_link("mass") @ poses[:, :2] / params.per_link("mass").sum()


travel = np.linalg.norm(centre_of_mass(traj.q[-1]) - centre_of_mass(traj.q[0]))
print(f"the centre of mass moved {100 * travel:.1f} cm; "
      f"RMS joint error after 1 s <= {np.nanmax(traj.signals['joint_error'][traj.t > 1]):.3f} rad")
assert traj.status == "completed" and travel > 0.02

# %%
# Plain functions work too
# ------------------------
# Any ``f(x, t) -> tau`` is accepted; here, no torque at all: friction only takes energy
# out, so the kinetic energy never grows.
coast = simulate(snake, lambda x, t: np.zeros(n - 1), np.r_[traj.q[-1], traj.dq[-1]],
                 t_final=0.5)
energy = np.array([snake.kinetic_energy(q, dq) for q, dq in zip(coast.q, coast.dq,
                                                                 strict=True)])
print(f"coasting: kinetic energy {energy[0]:.2e} J -> {energy[-1]:.2e} J")
assert np.all(np.diff(energy) <= 1e-12)

# %%
# What it did
# -----------
fig, axes = plt.subplots(1, 2, figsize=(11, 3.8))
for k in np.linspace(0, len(traj.t) - 1, 5).astype(int):
    draw_snake(axes[0], snake, traj.q[k], alpha=0.35 + 0.65 * k / (len(traj.t) - 1))
axes[0].plot(traj.q[:, 0], traj.q[:, 1], ":", color="k", lw=1, label="head")
axes[0].set_title("snapshots every second (darker: later)", fontsize=10)
axes[0].legend(fontsize=8)
axes[1].plot(traj.t, traj.q[:, 3:6], lw=1)
axes[1].plot(traj.t, [gait.angles(t)[:3] for t in traj.t], ":", color="k", lw=1)
axes[1].set_xlabel("t [s]")
axes[1].set_ylabel("phi_1..phi_3 [rad]")
axes[1].set_title("joints (solid) and the gait (dotted)", fontsize=10)
fig.tight_layout()
plt.show()
