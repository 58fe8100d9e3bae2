"""
H, h and q'' against the paper's closed form, and derivatives against differences
===================================================================================

:class:`~snake_pin.Snake` computes the equation of motion (20),
``H(q) q'' + h(q, q') = E tau``, with Pinocchio: H by CRBA (eq. 19), h by RNEA plus the
viscous friction of eqs. (10)-(13). :mod:`snake_pin.paper` writes the same matrices in
closed form with plain numpy and knows nothing of Pinocchio: the two agree to rounding.
:meth:`Snake.dynamics_derivatives <snake_pin.model.Snake.dynamics_derivatives>` gives
the analytical derivatives of q'' (friction included), which an optimal-control user
needs; here they are checked against central differences.
"""

# %%
# One random state of an anisotropic robot
# ----------------------------------------
import matplotlib.pyplot as plt
import numpy as np

from snake_pin import Snake, SnakeParams, paper

params = SnakeParams.table1().replace(c_y=25.0)   # sideways friction 50x c_x
snake = Snake(params)
n = params.n
rng = np.random.default_rng(0)
q = np.r_[rng.normal(size=2), rng.uniform(-np.pi, np.pi), rng.uniform(-1, 1, n - 1)]
dq = rng.normal(scale=0.5, size=n + 2)
tau = rng.normal(scale=0.01, size=n - 1)

# %%
# H, h and q'' both ways
# ----------------------
H, H_cf = snake.inertia_matrix(q), paper.inertia_matrix(params, q)
h, h_cf = snake.bias(q, dq), paper.bias(params, q, dq)
ddq = snake.forward_dynamics(q, dq, tau)
ddq_cf = np.linalg.solve(H_cf, paper.actuation_matrix(n) @ tau - h_cf)


def relative(a: np.ndarray, b: np.ndarray) -> float:
    """Largest entry of |a - b| over the largest entry of |b|."""
    return float(np.abs(a - b).max() / np.abs(b).max())


errors = {"H": relative(H, H_cf), "h": relative(h, h_cf), "q''": relative(ddq, ddq_cf)}
for name, err in errors.items():
    print(f"{name:4s} relative difference: {err:.1e}")
assert max(errors.values()) < 1e-10

# %%
# Derivatives of q'' against central differences
# -----------------------------------------------
der = snake.dynamics_derivatives(q, dq, tau)
step = 1e-6


def central(f, x: np.ndarray) -> np.ndarray:
    """Jacobian of f at x by central differences."""
    cols = []
    for i in range(x.size):
        e = np.zeros_like(x)
        e[i] = step
        cols.append((f(x + e) - f(x - e)) / (2 * step))
    return np.array(cols).T


fd_q = central(lambda x: snake.forward_dynamics(x, dq, tau), q)
fd_v = central(lambda x: snake.forward_dynamics(q, x, tau), dq)
fd_tau = central(lambda x: snake.forward_dynamics(q, dq, x), tau)
gaps = {"dq''/dq": relative(der.ddq_dq, fd_q), "dq''/dq'": relative(der.ddq_dv, fd_v),
        "dq''/dtau": relative(der.ddq_dtau, fd_tau)}
for name, err in gaps.items():
    print(f"{name:10s} vs central differences: {err:.1e}")
assert max(gaps.values()) < 1e-5

# %%
# What H looks like
# -----------------
# The first three rows and columns belong to w = [x_h, y_h, theta_1] (the unactuated
# block H11 of eq. 24); the rest to the joint angles. H is symmetric positive definite.
assert np.allclose(H, H.T) and np.linalg.eigvalsh(H).min() > 0
fig, axes = plt.subplots(1, 2, figsize=(9, 3.8))
image = axes[0].imshow(H, cmap="RdBu_r", vmin=-np.abs(H).max(), vmax=np.abs(H).max())
axes[0].set_title("H(q) from Pinocchio (CRBA)", fontsize=10)
fig.colorbar(image, ax=axes[0], shrink=0.8)
axes[1].bar(list(errors) + list(gaps), list(errors.values()) + list(gaps.values()),
            color=["#228b22"] * 3 + ["#2874a6"] * 3)
axes[1].set_yscale("log")
axes[1].set_title("relative differences", fontsize=10)
axes[1].tick_params(axis="x", labelrotation=30)
fig.tight_layout()
plt.show()
