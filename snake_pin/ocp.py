"""The snake as a Crocoddyl optimal-control problem: head tracking along a timed reference.

:class:`ChainRootActuation` (the chain root's actuation with friction), Crocoddyl's C++ free
forward dynamics over it with the costs of :class:`CostWeights` (:func:`differential_model`:
only the friction crosses into Python) and the RK4 shooting problem
(:class:`TrackingProblem`). The problem, its costs and why RK4 at 10 ms: :doc:`/mpc`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import crocoddyl
import numpy as np

from ._options import documented, option
from ._validation import finite_number, instance, integer
from .exceptions import ParameterError
from .friction import FrictionData, FrictionModel
from .model import Snake

__all__ = ["ChainRootActuation", "CostWeights", "TrackingProblem", "differential_model"]

#: Names of the costs in each node's cost sum (Crocoddyl's CostModelSum keys).
COSTS = ("tracking", "torque", "joint_limit")
#: Bound used for the coordinates a barrier does not limit (Crocoddyl needs finite bounds).
_FREE = 1e9


@documented
@dataclass(frozen=True)
class CostWeights:
    """Weights of the tracking costs, each on half a squared residual (0 drops it); the
    heading's is small, as the head link swings with the gait."""

    head_position: float = option(2000.0, "on the head point's error", unit="1/m^2", low=0.0)
    heading: float = option(1.0, "on the head link's angle error", unit="1/rad^2", low=0.0)
    head_velocity: float = option(20.0, "on the head velocity's error", unit="s^2/m^2", low=0.0)
    gait: float = option(2.0, "on the joints' error to the gait prior", unit="1/rad^2", low=0.0)
    gait_velocity: float = option(0.05, "on the joints' velocity error to the gait prior",
                                  unit="s^2/rad^2", low=0.0)
    torque: float = option(0.5, "on the actuated torques", unit="1/(N m)^2", low=0.0)
    joint_limit: float = option(1000.0, "on the joint angles beyond the joint limit",
                                unit="1/rad^2", low=0.0)
    terminal: float = option(1.0, "scale of the state costs at the terminal node", unit="s",
                             low=0.0)

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, finite_number(
                getattr(self, f.name), f"cost weight {f.name}", non_negative=True))


def state_model(snake: Snake) -> crocoddyl.StateMultibody:
    """Crocoddyl's (Euclidean) state of ``snake``'s model: ``x = [q, q']``, nx = 2 (n + 2)."""
    return crocoddyl.StateMultibody(instance(snake, Snake, "snake").model)


class ChainRootActuation(crocoddyl.ActuationModelAbstract):
    """Actuation of the chain root with friction: ``tau = [0_3; E_a u] + Q(q, q')``.

    Parameters
    ----------
    state, snake, friction : crocoddyl.StateMultibody, Snake, bool
        The state of ``snake``'s model (:func:`state_model`), the robot (its actuated joints
        give u, its friction Q), whether to include the friction.

    Raises
    ------
    ParameterError
        ``snake`` is not a Snake, or every joint is passive.
    """

    def __init__(self, state: crocoddyl.StateMultibody, snake: Snake,
                 friction: bool = True) -> None:
        if not instance(snake, Snake, "snake").params.actuated:
            raise ParameterError("every joint is passive: there is nothing to actuate")
        #: velocity index of each input (the actuated joints' rows of E)
        self.rows = np.array([2 + k for k in snake.params.actuated], dtype=int)
        super().__init__(state, len(self.rows))
        self.nq = snake.nq
        self.friction = FrictionModel(snake.params, snake.model) if friction else None
        #: the friction's buffers, one set for all this model's datas (a node's RK4 stages:
        #: results are copied out at once; :ref:`perf-mpc`)
        self._friction: tuple[FrictionModel, FrictionData] | None = (
            None if self.friction is None else (self.friction, self.friction.create_data()))
        self.friction_data = None if self._friction is None else self._friction[1]

    def calc(self, data: Any, x: np.ndarray, u: np.ndarray | None = None) -> None:
        """Generalised force at state x under inputs u, written into ``data.tau``.

        Parameters
        ----------
        data, x : crocoddyl.ActuationDataAbstract, numpy.ndarray
            This model's data and the state ``[q, q']``.
        u : numpy.ndarray or None, optional
            The actuated joints' torques [N m]; None: friction alone.
        """
        nq, tau = self.nq, data.tau
        if self._friction is None:
            tau[:] = 0.0
        else:
            model, buffers = self._friction
            tau[:] = model.calc_force(buffers, x[:nq], x[nq:])
        if u is not None:
            tau[self.rows] += u

    def calcDiff(self, data: Any, x: np.ndarray,
                 u: np.ndarray | None = None) -> None:
        """Jacobians of the force ``[dQ/dq, dQ/dq']`` into ``data.dtau_dx`` (the damping twin's
        RNEA derivatives; ``dtau_du = E_a`` is constant, set by :meth:`createData`).

        Parameters
        ----------
        data, x : crocoddyl.ActuationDataAbstract, numpy.ndarray
            This model's data and the state ``[q, q']``.
        u : numpy.ndarray or None, optional
            The inputs (the Jacobians do not depend on them).
        """
        if self._friction is not None:
            nq, (model, buffers) = self.nq, self._friction
            model.calc_derivatives(buffers, x[:nq], x[nq:])
            data.dtau_dx[...] = buffers.jacobian

    def commands(self, data: Any, x: np.ndarray, tau: np.ndarray) -> None:
        """Inputs that give the generalised force tau (its actuated rows less friction).

        Parameters
        ----------
        data, x, tau : crocoddyl.ActuationDataAbstract, numpy.ndarray, numpy.ndarray
            This model's data (``data.u`` is written), the state and the generalised force.
        """
        nq = self.nq
        force = 0.0 if self.friction is None else self.friction(x[:nq], x[nq:])
        data.u[:] = (tau - force)[self.rows]

    def createData(self) -> Any:
        """A data of this model, with the constant ``dtau_du = E_a``.

        Returns
        -------
        crocoddyl.ActuationDataAbstract
            The data.
        """
        data = crocoddyl.ActuationDataAbstract(self)
        data.dtau_du[self.rows, np.arange(self.nu)] = 1.0
        return data


def differential_model(snake: Snake, weights: CostWeights | None = None, *,
                       torque_bound: float = 1.0, joint_limit: float = math.pi / 2,
                       terminal: bool = False, friction: bool = True,
                       state: crocoddyl.StateMultibody | None = None
                       ) -> crocoddyl.DifferentialActionModelFreeFwdDynamics:
    """Crocoddyl's free forward dynamics of ``snake`` with the tracking costs (references 0).

    Parameters
    ----------
    snake, weights : Snake, CostWeights or None
        The robot (its friction and passive joints included) and the costs' weights.
    torque_bound, joint_limit : float, optional
        ``|u_i| <= torque_bound`` [N m] and the joint-limit barrier's ``|phi_i|`` [rad], > 0.
    terminal, friction : bool, optional
        A terminal model (state costs only, times ``weights.terminal``); include friction.
    state : crocoddyl.StateMultibody, optional
        The state to share (default a new :func:`state_model`).

    Returns
    -------
    crocoddyl.DifferentialActionModelFreeFwdDynamics
        The model; its cost sum holds those of ``COSTS`` whose weights are not all 0.

    Raises
    ------
    ParameterError
        A bad robot, weights or bound (one line).
    """
    instance(snake, Snake, "snake")
    weights = CostWeights() if weights is None else instance(weights, CostWeights, "weights")
    torque_bound = finite_number(torque_bound, "torque_bound", positive=True)
    joint_limit = finite_number(joint_limit, "joint_limit", positive=True)
    state = state_model(snake) if state is None else state
    actuation = ChainRootActuation(state, snake, friction=friction)
    nu, nq = actuation.nu, snake.nq
    costs = crocoddyl.CostModelSum(state, nu)
    scale = weights.terminal if terminal else 1.0
    nx = 2 * nq

    # the five tracking terms share the residual x - x_r(t): one weighted quadratic
    rates = np.zeros(nx)
    rates[0:2] = weights.head_position
    rates[2] = weights.heading
    rates[nq:nq + 2] = weights.head_velocity
    rates[3:nq] = weights.gait
    rates[nq + 3:] = weights.gait_velocity
    if np.any(rates > 0.0) and scale > 0.0:
        costs.addCost("tracking", crocoddyl.CostModelResidual(
            state, crocoddyl.ActivationModelWeightedQuad(rates),
            crocoddyl.ResidualModelState(state, np.zeros(nx), nu)), scale)
    if weights.joint_limit * scale > 0.0:
        upper = np.full(nx, _FREE)
        upper[3:nq] = joint_limit
        bounds = crocoddyl.ActivationBounds(-upper, upper)
        costs.addCost("joint_limit", crocoddyl.CostModelResidual(
            state, crocoddyl.ActivationModelQuadraticBarrier(bounds),
            crocoddyl.ResidualModelState(state, np.zeros(nx), nu)), weights.joint_limit * scale)
    if not terminal and weights.torque > 0.0:
        costs.addCost("torque", crocoddyl.CostModelResidual(
            state, crocoddyl.ResidualModelControl(state, nu)), weights.torque)
    model = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, actuation, costs)
    model.u_lb = np.full(nu, -torque_bound)
    model.u_ub = np.full(nu, torque_bound)
    return model


class TrackingProblem:
    """The shooting problem: ``nodes`` RK4 steps of ``node_dt`` with the tracking costs.

    Parameters
    ----------
    snake, nodes, node_dt : Snake, int, float
        The robot, the number of running nodes (>= 1) and their RK4 step [s] (> 0).
    weights, torque_bound, joint_limit : optional
        As for :func:`differential_model`.

    Raises
    ------
    ParameterError
        A bad robot, node count, step, weights or bound (one line).

    Attributes
    ----------
    problem : crocoddyl.ShootingProblem
        The problem (x0 and references set by :meth:`set_state` and :meth:`set_reference`).
    running, terminal
        The integrated action models (their ``differential`` is the free forward dynamics).
    """

    def __init__(self, snake: Snake, nodes: int, node_dt: float = 0.01,
                 weights: CostWeights | None = None, *, torque_bound: float = 1.0,
                 joint_limit: float = math.pi / 2) -> None:
        self.snake = instance(snake, Snake, "snake")
        self.nodes = integer(nodes, "nodes", low=1)
        self.node_dt = finite_number(node_dt, "node_dt", positive=True)
        self.state = state_model(snake)
        options = dict(torque_bound=torque_bound, joint_limit=joint_limit, state=self.state)
        self.running = [crocoddyl.IntegratedActionModelRK(
            differential_model(snake, weights, **options), crocoddyl.RKType.four,
            self.node_dt) for _ in range(self.nodes)]
        self.terminal = crocoddyl.IntegratedActionModelRK(
            differential_model(snake, weights, terminal=True, **options),
            crocoddyl.RKType.four, 0.0)
        self.problem = crocoddyl.ShootingProblem(
            np.zeros(2 * snake.nq), self.running, self.terminal)
        # the state residuals of each node (shared C++ objects), whose reference is set
        self._residuals = [[item.cost.residual for name, item in
                            model.differential.costs.costs.todict().items()
                            if name == "tracking"]
                           for model in [*self.running, self.terminal]]
        self.nu = self.running[0].nu

    def set_state(self, x0: np.ndarray) -> None:
        """Set the initial state of the problem.

        Parameters
        ----------
        x0 : numpy.ndarray
            The state ``[q, q']``, length 2 (n + 2).
        """
        self.problem.x0 = np.asarray(x0, dtype=float)

    def set_reference(self, references: np.ndarray) -> None:
        """Set the state reference of each node's tracking costs.

        Parameters
        ----------
        references : numpy.ndarray
            Row k ``[w_r, phi_r, w_r', phi_r']`` at node k's time (:func:`reference_states`).
        """
        for residuals, row in zip(self._residuals, references, strict=True):
            for residual in residuals:
                residual.reference = row

    def node_times(self, t0: float) -> np.ndarray:
        """The times of the nodes 0 .. nodes from t0.

        Parameters
        ----------
        t0 : float
            Time of node 0 [s].

        Returns
        -------
        numpy.ndarray
            Shape (nodes + 1,) [s].
        """
        return t0 + self.node_dt * np.arange(self.nodes + 1)


def reference_states(reference: Any, gait: Any, times: np.ndarray) -> np.ndarray:
    """The reference state ``[w_r, phi_r, w_r', phi_r']`` at each time, (T, 2 (n + 2)).

    A reference with ``at`` (a PathReference) is evaluated at all times at once.
    """
    times = np.asarray(times, dtype=float)
    if hasattr(reference, "at"):
        w_r, dw_r, _ = reference.at(times)
    else:
        parts = [reference(float(t)) for t in times]
        w_r = np.array([p[0] for p in parts], dtype=float)
        dw_r = np.array([p[1] for p in parts], dtype=float)
    phi_r, dphi_r, _ = gait.derivatives(times[:, None])
    return np.hstack((w_r, phi_r, dw_r, dphi_r))

