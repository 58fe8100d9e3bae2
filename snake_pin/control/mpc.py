"""Model-predictive head tracking: a receding-horizon Box-FDDP on the snake's OCP.

:class:`MPCController` solves the problem of :mod:`snake_pin.ocp` every ``resolve_period``
from the measured state, warm-started from the shifted plan, and applies the plan with its
Riccati feedback in between; passive joints get exactly zero torque (:doc:`/mpc`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import crocoddyl
import numpy as np

from .._options import documented, option
from .._validation import instance
from ..exceptions import ParameterError
from ..gaits import Serpenoid
from ..model import Snake
from ..ocp import CostWeights, TrackingProblem, reference_states
from ._options import check_fields, merged
from .base import Controller, ReferenceLaw, gait_for
from .reference import HeadReference, head_first_reference

__all__ = ["MPCController", "MPCOptions", "SolveStats"]


@documented
@dataclass(frozen=True)
class MPCOptions:
    """Settings of :class:`MPCController` (validated: the horizon at least one node, the
    resolve period a whole number of nodes within it; nodes of 20 ms or more diverge:
    :doc:`/mpc`)."""

    horizon: float = option(0.5, "length of the prediction", unit="s", low=0.0, open_low=True)
    node_dt: float = option(0.01, "step of the RK4 nodes", unit="s", low=0.0, open_low=True)
    resolve_period: float = option(0.04, "time between re-solves", unit="s", low=0.0,
                                   open_low=True)
    torque_bound: float = option(1.0, "bound on each |tau_i|", unit="N m", low=0.0,
                                 open_low=True)
    joint_limit: float = option(math.pi / 2, "the joint-limit barrier's |phi_i|", unit="rad",
                                low=0.0, open_low=True)
    iterations: int = option(2, "Box-FDDP iterations per warm-started re-solve", low=1)
    first_iterations: int = option(25, "iterations of the first (cold) solve", low=1)
    step_halvings: int = option(3, "line search: steps 1, 1/2, ..., 2^-step_halvings", low=0)
    feedback: bool = option(True, "apply the Riccati gains between re-solves")
    weights: CostWeights = option(CostWeights(), "the costs' weights")  # noqa: RUF009 (frozen)

    def __post_init__(self) -> None:
        check_fields(self)
        if self.horizon < self.node_dt * (1.0 - 1e-9):
            raise ParameterError(f"MPC horizon {self.horizon} s is shorter than one node "
                                 f"({self.node_dt} s)")
        ratio = self.resolve_period / self.node_dt
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise ParameterError(f"MPC resolve_period {self.resolve_period} s is not a whole "
                                 f"number of nodes of {self.node_dt} s")
        if self.resolve_period > self.horizon * (1.0 + 1e-9):
            raise ParameterError(f"MPC resolve_period {self.resolve_period} s exceeds the "
                                 f"horizon {self.horizon} s")

    @property
    def nodes(self) -> int:
        """Running nodes of the horizon (``horizon / node_dt``, rounded)."""
        return max(1, round(self.horizon / self.node_dt))

    @property
    def resolve_nodes(self) -> int:
        """Nodes between re-solves (``resolve_period / node_dt``)."""
        return round(self.resolve_period / self.node_dt)


@dataclass(frozen=True)
class SolveStats:
    """Totals of a controller's solves since its last reset.

    Parameters
    ----------
    solves, iterations, wall : int, int, float
        Solves, Box-FDDP iterations over them, wall time in the solver [s].
    """

    solves: int
    iterations: int
    wall: float


class MPCController(Controller):
    """Receding-horizon head tracking by Box-FDDP on the snake's optimal-control problem; its
    signals ``solve_cost`` and ``solve_iterations`` are the last solve's.

    Parameters
    ----------
    snake, reference, gait : Snake, callable, Serpenoid
        The plant's model (its friction and passive joints are the problem's); the others
        as for :class:`~snake_pin.control.lyapunov.LyapunovController` (gait: the prior).
    options : MPCOptions, optional
        The law's settings (default :class:`MPCOptions`).

    Raises
    ------
    ParameterError
        A bad robot (or every joint passive), reference, gait or ``options``.
    """

    name = "mpc"

    def __init__(self, snake: Snake, reference: HeadReference | None = None,
                 gait: Serpenoid | None = None, options: MPCOptions | None = None) -> None:
        if not instance(snake, Snake, "snake").params.actuated:
            raise ParameterError("every joint is passive: there is nothing to control")
        self.snake, n = snake, snake.n
        self.reference = (head_first_reference() if reference is None
                          else ReferenceLaw.checked_reference(reference))
        self.gait = gait_for(n, gait, Serpenoid(n, np.pi / 6, 1.5, 2.0))
        self.options = merged(MPCOptions, options, {})
        self._actuated = np.array(snake.params.actuated, dtype=int) - 1  # entries of tau
        self._build()
        self.reset()

    def _build(self) -> None:
        """The problem and its solver (not pickled: rebuilt on unpickling)."""
        o = self.options
        self._problem = TrackingProblem(self.snake, o.nodes, o.node_dt, o.weights,
                                        torque_bound=o.torque_bound,
                                        joint_limit=o.joint_limit)
        self._solver = crocoddyl.SolverBoxFDDP(self._problem.problem)
        self._solver.alphas = [2.0 ** -k for k in range(o.step_halvings + 1)]

    def __getstate__(self) -> dict[str, Any]:
        """The attributes to pickle: all but Crocoddyl's problem and solver."""
        state = self.__dict__.copy()
        for key in ("_problem", "_solver"):
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Unpickled: the problem and solver are built again (the plan is kept)."""
        self.__dict__.update(state)
        self._build()

    def reset(self) -> None:
        """Forget the plan and the solve statistics before a new run."""
        self._plan: tuple[float, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._next_solve = -math.inf
        self._solves = self._iterations = 0
        self._wall = 0.0
        self._last = {"solve_cost": math.nan, "solve_iterations": math.nan}

    @property
    def stats(self) -> SolveStats:
        """The solves since the last reset (count, iterations, wall time)."""
        return SolveStats(self._solves, self._iterations, self._wall)

    def _guess(self, x: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """A rollout from x under zero torque (x itself when the snake starts at rest)."""
        us = [np.zeros(self._problem.nu)] * self.options.nodes
        return list(self._problem.problem.rollout(us)), us

    def _solve(self, x: np.ndarray, t: float) -> None:
        """Re-solve from the measured state x at time t (warm-started from the plan)."""
        wall = time.perf_counter()
        o, problem, solver = self.options, self._problem, self._solver
        times = problem.node_times(t)
        references = reference_states(self.reference, self.gait, times)
        problem.set_reference(references)
        problem.set_state(x)
        if self._plan is None:
            xs, us = self._guess(x)
            iterations = o.first_iterations
        else:
            t_plan, plan_xs, plan_us, _ = self._plan
            shift = min(max(round((t - t_plan) / o.node_dt), 0), o.nodes)
            xs = list(plan_xs[shift:])
            us = [*plan_us[shift:], *([plan_us[-1]] * shift)]
            # the tail: the last planned torque rolled out (a repeated state would leave
            # gaps that later shifts carry into the horizon)
            for model, data, u in zip(problem.running[-shift:] if shift else [],
                                      problem.problem.runningDatas[-shift:] if shift else [],
                                      us[-shift:], strict=True):
                model.calc(data, xs[-1], u)
                xs.append(data.xnext.copy())
            xs[0] = x.copy()
            iterations = o.iterations
        solver.solve(xs, us, iterations, False)
        gains = np.array(solver.K) if o.feedback else None
        self._plan = (t, np.array(solver.xs), np.array(solver.us), gains)  # type: ignore[assignment]
        self._next_solve = t + o.resolve_period
        self._solves += 1
        self._iterations += solver.iter
        self._last = {"solve_cost": float(solver.cost), "solve_iterations": float(solver.iter)}
        self._wall += time.perf_counter() - wall

    def __call__(self, x: np.ndarray, t: float) -> np.ndarray:
        """Joint torques at (x, t): 0 on passive joints, within ``+-torque_bound``."""
        x = np.asarray(x, dtype=float)
        if self._plan is None or t >= self._next_solve - 1e-9 * max(1.0, abs(t)):
            self._solve(x, t)
        t_plan, xs, us, gains = self._plan  # type: ignore[misc]
        o = self.options
        s = (t - t_plan) / o.node_dt
        k = min(max(math.floor(s + 1e-9), 0), o.nodes - 1)
        u = us[k]
        if gains is not None:
            frac = min(max(s - k, 0.0), 1.0)
            planned = xs[k] + frac * (xs[k + 1] - xs[k])
            u = u - gains[k] @ (x - planned)
        tau = np.zeros(self.snake.n - 1)
        tau[self._actuated] = np.clip(u, -o.torque_bound, o.torque_bound)
        return tau

    def signals(self) -> dict[str, float]:
        return dict(self._last)
