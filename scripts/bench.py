#!/usr/bin/env python
"""Benchmarks of snake_pin's hot paths, every figure against a reference timed in the same run.

The references: the closed form (``snake_pin.paper`` + numpy), central differences, the
closed-loop step of commit dc0b889 (the step before issue 13, run from a checkout of that
commit in a subprocess) and the floor of the Pinocchio calls one step makes. The two sides
of a ratio are timed in interleaved rounds (A B A B ...), so that a neighbour's load hits
both alike; each figure is the median over the rounds with its 10-90 % range.

Usage: python scripts/bench.py [--quick]
           [--only dynamics,friction_routes,derivatives,manipulability,runs,engine,
                   reproduce,failure_map,study,mpc]
           [--baseline COMMIT | --no-baseline] [--study-sizes 40,256,1000]
           [--study-rounds 1]

``--only reproduce`` (not in the default set: it runs the whole report twice) times
``snake-pin reproduce`` quiet and with the other core busy, alternately; ``--only
failure_map`` (not in the default set either) the report with and without its failure-map
stage, back to back; ``--only study`` (nor this one) a study's throughput in runs per wall
second at each of ``--study-sizes`` runs, this tree's ``run_study`` against the baseline
commit's (default 3801e7f, whose studies ran lockstep batches), taking turns per size;
``--only mpc`` (nor this one) the model-predictive controller's closed loop (3 s on the
line, 3 rounds; 1 s and 2 rounds with ``--quick``): wall per simulated second, of the
first (cold) solve and per re-solve, calls and line-search trials per re-solve, where it
goes (dynamics, derivatives, solver, plant), each lever of ``MPC_LEVERS`` as a ratio
against the default in the same round (and the friction's Jacobians of commit
``FRICTION_JACOBIANS_BASELINE``, imported from a checkout of it), the Lyapunov-like law on
the same run, and the routes per call.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import io
import json
import math
import os
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
import timeit
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path
from typing import Any
from unittest.mock import patch

import numpy as np

from snake_pin import Snake, SnakeParams, paper
from snake_pin.friction import friction_forces

#: The commit whose closed-loop step is the runs' reference route.
BASELINE = "dc0b889"
REPO = Path(__file__).resolve().parents[1]


# ----------------------------------------------------------------------- timing helpers
def interleaved_samples(fns: Mapping[str, Callable[[], object]], *, budget: float = 0.2,
                        rounds: int = 9) -> dict[str, list[float]]:
    """us per call of each function in each of ``rounds`` interleaved rounds (A B C A B C
    ...), each round of each function lasting about ``budget / rounds`` seconds."""
    numbers = {name: max(1, int(budget / rounds / max(timeit.timeit(fn, number=3) / 3, 1e-7)))
               for name, fn in fns.items()}
    samples: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            samples[name].append(timeit.timeit(fn, number=numbers[name]) / numbers[name] * 1e6)
    return samples


def spread(values: list[float]) -> tuple[float, float, float]:
    """Median, 10th and 90th percentile (the extremes for fewer than 3 values)."""
    if len(values) < 3:
        return statistics.median(values), min(values), max(values)
    deciles = statistics.quantiles(values, n=10, method="inclusive")
    return statistics.median(values), deciles[0], deciles[-1]


def interleaved_us(fns: Mapping[str, Callable[[], object]], *, budget: float = 0.2,
                   rounds: int = 9) -> dict[str, tuple[float, float, float]]:
    """Median, 10th and 90th percentile us per call of each function, timed in interleaved
    rounds (see :func:`interleaved_samples`)."""
    return {name: spread(values) for name, values in
            interleaved_samples(fns, budget=budget, rounds=rounds).items()}


def ratios(numerator: list[float], denominator: list[float]) -> tuple[float, float, float]:
    """Median and 10-90 % range of the per-round ratios (rounds paired by position)."""
    return spread([a / b for a, b in zip(numerator, denominator, strict=True)])


def show(stats: tuple[float, float, float], digits: int = 1, unit: str = "") -> str:
    """``median (p10-p90)`` with ``digits`` decimals."""
    median, low, high = stats
    return f"{median:.{digits}f}{unit} ({low:.{digits}f}-{high:.{digits}f})"


def table(title: str, header: list[str], rows: list[list[str]]) -> None:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print(f"\n## {title}\n")
    print("| " + " | ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print("| " + " | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) + " |")
    sys.stdout.flush()


# ------------------------------------------------------------------------- dynamics
def bench_dynamics(budget: float) -> None:
    """H, h and forward dynamics: Pinocchio path vs snake_pin.paper + numpy solve."""
    import pinocchio as pin

    rows = []
    for n in (10, 30, 100):
        for label, cy in (("iso", 0.5), ("aniso", 5.0)):
            params = SnakeParams.table1(n=n, c_y=cy)
            snake = Snake(params)
            rng = np.random.default_rng(n)
            q = np.r_[0.1, -0.2, 0.3, rng.uniform(-1, 1, n - 1)]
            dq = rng.normal(size=n + 2)
            tau = rng.normal(size=n - 1)
            e = paper.actuation_matrix(n)

            def closed_fd(q=q, dq=dq, tau=tau, params=params, e=e) -> np.ndarray:
                return np.linalg.solve(paper.inertia_matrix(params, q),
                                       e @ tau - paper.bias(params, q, dq))

            pairs: dict[str, tuple[Callable[[], object], Callable[[], object]]] = {
                "H": (partial(snake.inertia_matrix, q),
                      partial(paper.inertia_matrix, params, q)),
                "h": (partial(snake.bias, q, dq),
                      partial(paper.bias, params, q, dq)),
                "forward dynamics": (
                    partial(snake.forward_dynamics, q, dq, tau), closed_fd),
            }
            route = friction_route(snake)
            for name, (fast, slow) in pairs.items():
                if name == "H" and label != "iso":
                    continue  # H does not depend on friction
                times = interleaved_samples({"fast": fast, "slow": slow}, budget=budget)
                rows.append([str(n), name, f"{label} ({route})" if name != "H" else "-",
                             show(spread(times["fast"])), show(spread(times["slow"])),
                             show(ratios(times["slow"], times["fast"]), unit="x")])
            if n == 10:
                def fext_fd(q=q, dq=dq, tau=tau, snake=snake, params=params) -> np.ndarray:
                    fext = friction_forces(snake.model, snake.data, params, q, dq)
                    return pin.aba(snake.model, snake.data, q, dq,
                                   snake.generalized_torque(tau), fext)

                times = interleaved_samples({
                    "fast": partial(snake.forward_dynamics, q, dq, tau),
                    "slow": fext_fd}, budget=budget)
                rows.append([str(n), "forward dynamics against a pin.Force list", label,
                             show(spread(times["fast"])), show(spread(times["slow"])),
                             show(ratios(times["slow"], times["fast"]), unit="x")])
                def closed_q(q=q, dq=dq, params=params) -> np.ndarray:
                    return -paper.friction_matrix(params, q) @ dq

                times = interleaved_samples({
                    "fast": partial(snake.friction, q, dq), "slow": closed_q}, budget=budget)
                rows.append([str(n), "friction Q alone: twin against -C(q) q' of the closed "
                             "form", f"{label} ({route})",
                             show(spread(times["fast"])), show(spread(times["slow"])),
                             show(ratios(times["slow"], times["fast"]), unit="x")])
    table("Dynamics, us per call, median (10-90 %) of interleaved rounds",
          ["n", "quantity", "friction", "snake_pin [us]", "reference [us]",
           "reference / snake_pin"], rows)
    print("\nReference: the closed form (snake_pin.paper, numpy solve) unless the row names "
          "another route.")


def friction_route(snake: Snake) -> str:
    """Which route of the damping twin gives the robot's friction force Q."""
    friction = snake.friction
    if friction.uses_twin_crba:
        return "twin CRBA + 2 products"
    return "twin RNEA, 2 passes" if friction.has_wheels else "twin RNEA"


def bench_friction_routes(budget: float) -> None:
    """Anisotropic friction in the closed loop: one stage evaluation of RK4 (the friction
    force and ABA: ``Snake.calc_acceleration``) with Q from the twin's CRBA and two
    products against Q from its two RNEA passes, for several n; the crossing sets
    ``snake_pin.friction.WHEELED_TWIN_MAX_LINKS``."""
    from snake_pin import friction

    rows = []
    chosen = friction.WHEELED_TWIN_MAX_LINKS
    for n in (10, 20, 30, 32, 34, 36, 40, 50):
        params = SnakeParams.table1(n=n, c_y=25.0)
        snakes = {}
        try:  # the route is chosen when the robot is built: build one on each
            for route, limit in (("crba", n), ("rnea", n - 1)):
                friction.WHEELED_TWIN_MAX_LINKS = limit
                snakes[route] = Snake(params)
        finally:
            friction.WHEELED_TWIN_MAX_LINKS = chosen
        assert snakes["crba"].friction.uses_twin_crba
        assert not snakes["rnea"].friction.uses_twin_crba
        rng = np.random.default_rng(n)
        q = np.r_[0.1, -0.2, 0.3, rng.uniform(-1, 1, n - 1)]
        v, tau = rng.normal(size=n + 2), rng.normal(size=n - 1)
        calls = {}
        for route, snake in snakes.items():
            data = snake.create_data()
            torque = snake.calc_torque(data, tau).copy()  # E tau, as the plant holds it
            calls[route] = partial(snake.calc_acceleration, data, q, v, torque)
        assert np.allclose(calls["crba"](), calls["rnea"](), rtol=1e-9, atol=1e-9)
        times = interleaved_samples(calls, budget=budget)
        rows.append([str(n), "CRBA" if n <= chosen else "RNEA passes",
                     show(spread(times["crba"]), 2), show(spread(times["rnea"]), 2),
                     show(ratios(times["rnea"], times["crba"]), 2, "x")])
    table("Anisotropic friction (c_y = 50 c_x) in one closed-loop evaluation "
          "(Snake.calc_acceleration), us per call, median (10-90 %) of interleaved rounds",
          ["n", "route used", "twin CRBA + 2 products [us]", "twin RNEA, 2 passes [us]",
           "RNEA / CRBA"], rows)
    print(f"\nWHEELED_TWIN_MAX_LINKS = {chosen}: the twin's CRBA up to there, its RNEA "
          "passes beyond.")


def bench_derivatives(budget: float) -> None:
    """Analytical derivatives of q'' (friction included) against central differences of
    ``forward_dynamics`` (2 (2 nv + n - 1) evaluations), and per-link robots against
    uniform ones (the same code path must cost the same)."""
    import pinocchio as pin

    rows = []
    for n in (10, 30):
        rng = np.random.default_rng(n)
        for label, params in (("iso", SnakeParams.table1(n=n)),
                              ("aniso", SnakeParams.table1(n=n, c_y=25.0))):
            snake = Snake(params)
            q = np.r_[0.1, -0.2, 0.3, rng.uniform(-1, 1, n - 1)]
            dq, tau = rng.normal(size=n + 2), rng.normal(size=n - 1)
            eye_v, eye_t, step = np.eye(n + 2), np.eye(n - 1), 1e-6

            def central(s=snake, q=q, dq=dq, tau=tau, eye_v=eye_v, eye_t=eye_t,
                        step=step) -> object:
                fd = s.forward_dynamics
                return ([fd(q + step * e, dq, tau) - fd(q - step * e, dq, tau) for e in eye_v],
                        [fd(q, dq + step * e, tau) - fd(q, dq - step * e, tau) for e in eye_v],
                        [fd(q, dq, tau + step * e) - fd(q, dq, tau - step * e) for e in eye_t])

            def floor(s=snake, q=q, dq=dq) -> object:  # the ABA derivatives alone
                return pin.computeABADerivatives(s.model, s.data, q, dq, np.zeros(s.nv))

            times = interleaved_samples({
                "analytical": partial(snake.dynamics_derivatives, q, dq, tau),
                "central": central, "floor": floor}, budget=budget)
            rows.append([str(n), label, show(spread(times["analytical"])),
                         show(spread(times["central"]), 0),
                         show(ratios(times["central"], times["analytical"]), 1, "x"),
                         show(spread(times["floor"])),
                         show(ratios(times["analytical"], times["floor"]), 1, "x")])
    table("Derivatives of q'' with friction, median us (10-90 %), interleaved rounds",
          ["n", "friction", "analytical", "central differences", "speed-up",
           "computeABADerivatives alone", "analytical / floor"], rows)

    per_link = []
    rng = np.random.default_rng(7)
    for label, cy in (("iso", 0.5), ("aniso", 25.0)):
        uniform = SnakeParams.table1(c_y=cy)
        scale = rng.uniform(0.5, 2.0, 10)
        hetero = uniform.replace(mass=(0.182 * scale).tolist(),
                                 link_length=(0.12 * scale).tolist(),
                                 c_x=(0.5 * scale).tolist(), c_y=(cy * scale).tolist())
        q = np.r_[0.1, -0.2, 0.3, rng.uniform(-1, 1, 9)]
        dq, tau = rng.normal(size=12), rng.normal(size=9)
        snakes = {"uniform": Snake(uniform), "per-link": Snake(hetero)}
        calls = {name: partial(s.forward_dynamics, q, dq, tau)
                 for name, s in snakes.items()}
        times = interleaved_samples(calls, budget=budget)
        per_link.append([label, show(spread(times["uniform"])), show(spread(times["per-link"])),
                         show(ratios(times["per-link"], times["uniform"]), 2)])
    table("Forward dynamics with friction at n = 10: per-link robot against uniform, us, "
          "median (10-90 %)",
          ["friction", "uniform (Table 1)", "per-link", "ratio"], per_link)


def closed_form_manipulability(params: SnakeParams, q: np.ndarray) -> tuple[float, float]:
    """D and R by the closed form: paper.inertia_matrix, Schur complement, numpy SVD."""
    h = paper.inertia_matrix(params, q)
    h12, h22 = h[:3, 3:], h[3:, 3:]
    h22_inv = np.linalg.inv(h22)
    a = np.linalg.solve(h[:3, :3] - h12 @ h22_inv @ h12.T, h12 @ h22_inv)
    return (np.linalg.svd(a, compute_uv=False)[-1], np.linalg.svd(h12, compute_uv=False)[-1])


def bench_manipulability(budget: float) -> None:
    """One D+R evaluation (Pinocchio route vs closed form) and the batch R path."""
    from snake_pin.manipulability import manipulability, manipulability_R_batch

    rows = []
    for n in (10, 30):
        params = SnakeParams.table1(n=n)
        snake = Snake(params)
        rng = np.random.default_rng(n)
        q = np.r_[0.0, 0.0, 0.0, rng.uniform(-1, 1, n - 1)]
        phis = rng.uniform(-1.5, 1.5, (20_000, n - 1))
        times = interleaved_samples({
            "one": partial(manipulability, snake, q),
            "free": partial(manipulability, snake, q, free_joint=5),
            "closed": partial(closed_form_manipulability, params, q),
            "batch": partial(manipulability_R_batch, params, phis)},
            budget=4 * budget, rounds=7)
        per_posture = [t / len(phis) for t in times["batch"]]
        rows.append([str(n), "D and R, one posture", show(spread(times["one"])),
                     show(spread(times["closed"])), show(ratios(times["closed"], times["one"]),
                                                        unit="x")])
        rows.append([str(n), "D~ and R~ (joint 5 free), one posture",
                     show(spread(times["free"])), show(spread(times["closed"])),
                     show(ratios(times["closed"], times["free"]), unit="x")])
        rows.append([str(n), "R, batch of 20k postures (per posture)",
                     show(spread(per_posture), 2), show(spread(times["closed"])),
                     show(ratios(times["closed"], per_posture), 0, "x")])
    table("Manipulability, us per posture, median (10-90 %) of interleaved rounds",
          ["n", "quantity", "snake_pin [us]", "closed form D and R [us]",
           "closed form / snake_pin"], rows)


# ------------------------------------------------------------------- closed-loop runs
#: The runs: label, controller, robot (changes to tracking_params or SnakeParams.table1),
#: t_final [s] of the full run and of the interleaved segments.
RUNS: list[tuple[str, str, dict[str, Any], float, float]] = [
    ("Lyapunov-like, 60 s (c_y = 50 c_x)", "lyapunov", {}, 60.0, 5.0),
    ("Lyapunov-like, 60 s, joint 5 passive", "lyapunov", {"passive": [5]}, 60.0, 5.0),
    ("Lyapunov-like, 60 s, isotropic", "lyapunov", {"c_y": 0.5}, 60.0, 5.0),
    ("PFL, VI.1 to breakdown (isotropic)", "pfl", {}, 10.0, 10.0),
    ("PFL, 20 s, c_y = 10 c_x", "pfl", {"c_y": 5.0}, 20.0, 5.0),
]

#: Runs a closed loop per request line {"kind", "robot", "t_final"} with whatever
#: snake_pin is first on the path (this checkout or the baseline's), using only the API
#: both have; answers {"seconds", "steps", "t_end"}. Robots are built once per request kind.
WORKER = r"""
import json, sys, time
from snake_pin import Snake, SnakeParams
from snake_pin.control import LyapunovController, PFLController
from snake_pin.sim import simulate
try:
    from snake_pin.runs import pfl, tracking
except ImportError:  # a checkout from before snake_pin.runs (the baseline)
    from snake_pin.experiments import pfl, tracking

built = {}
def build(kind, robot):
    key = json.dumps([kind, robot], sort_keys=True)
    if key not in built:
        robot = {k: tuple(v) if isinstance(v, list) else v for k, v in robot.items()}
        if kind == "pfl":
            params = SnakeParams.table1(**robot)
            snake = Snake(params)
            built[key] = snake, PFLController(snake), pfl.initial_state(params)
        else:
            params = tracking.tracking_params(**robot)
            snake = Snake(params)
            built[key] = snake, LyapunovController(snake), tracking.initial_state(params)
    return built[key]

for line in sys.stdin:
    request = json.loads(line)
    snake, controller, x0 = build(request["kind"], request["robot"])
    start = time.perf_counter()
    traj = simulate(snake, controller, x0, request["t_final"])
    seconds = time.perf_counter() - start
    print(json.dumps({"seconds": seconds, "steps": len(traj) - 1, "t_end": traj.t_end}),
          flush=True)
"""


class Worker:
    """A Python process running ``script`` (default :data:`WORKER`) with ``root`` first on
    its path: one JSON request per line in, one JSON answer per line out."""

    def __init__(self, root: Path, script: str = WORKER) -> None:
        env = dict(os.environ, PYTHONPATH=str(root))
        self.process = subprocess.Popen(
            [sys.executable, "-P", "-c", script], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, text=True, env=env, cwd=tempfile.gettempdir())

    def request(self, request: dict) -> dict:
        assert self.process.stdin is not None and self.process.stdout is not None
        self.process.stdin.write(json.dumps(request) + "\n")
        self.process.stdin.flush()
        answer = self.process.stdout.readline()
        if not answer:
            raise RuntimeError(f"benchmark worker exited ({self.process.wait()})")
        return json.loads(answer)

    def run(self, kind: str, robot: dict, t_final: float) -> dict:
        return self.request({"kind": kind, "robot": robot, "t_final": t_final})

    def close(self) -> None:
        if self.process.stdin is not None:
            self.process.stdin.close()
        self.process.wait(timeout=60)


def baseline_checkout(commit: str) -> tuple[Path | None, str]:
    """A copy of ``commit``'s tree in the temporary folder (made once per resolved commit,
    from git), or None and why not (no git, no history: the baseline column is then
    skipped). The copy is named after the full hash, so a moving name (HEAD, a branch)
    never reuses another commit's tree."""
    try:
        commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--verify",
                                 f"{commit}^{{commit}}"], capture_output=True, check=True,
                                text=True, timeout=60).stdout.strip()
    except (OSError, subprocess.SubprocessError) as exc:
        detail = getattr(exc, "stderr", "") or str(exc)
        return None, (f"the {commit} column is skipped: git cannot resolve it "
                      f"({str(detail).strip()[:200]})")
    target = Path(tempfile.gettempdir()) / f"snake_pin_{commit}"
    if (target / "snake_pin" / "__init__.py").is_file():
        return target, f"{commit[:10]} from {target}"
    try:
        archive = subprocess.run(["git", "-C", str(REPO), "archive", "--format=tar", commit],
                                 capture_output=True, check=True, timeout=120).stdout
        staging = Path(tempfile.mkdtemp(prefix=f"snake_pin_{commit}.",
                                        dir=tempfile.gettempdir()))
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(staging, filter="data")
        try:
            staging.rename(target)
        except OSError:  # made meanwhile by another run
            pass
    except (OSError, subprocess.SubprocessError, tarfile.TarError) as exc:
        detail = getattr(exc, "stderr", b"") or str(exc).encode()
        return None, (f"the {commit} column is skipped: its tree could not be extracted with "
                      f"git archive ({detail.decode(errors='replace').strip()[:200]})")
    return target, f"{commit[:10]} from {target} (git archive)"


def baseline_package(commit: str) -> tuple[Any, str]:
    """``commit``'s snake_pin imported in this process as ``snake_pin_<hash>`` (from
    :func:`baseline_checkout`; its modules import each other relatively), or None and why
    not. Its classes are its own: give them its own parameters (``SnakeParams.from_dict``)."""
    target, why = baseline_checkout(commit)
    if target is None:
        return None, why
    name = f"snake_pin_{target.name.removeprefix('snake_pin_')[:10]}"
    if name in sys.modules:
        return sys.modules[name], why
    package = target / "snake_pin"
    spec = importlib.util.spec_from_file_location(name, package / "__init__.py",
                                                  submodule_search_locations=[str(package)])
    if spec is None or spec.loader is None:
        return None, f"the {commit} column is skipped: {package} is not a package"
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # an old tree that does not import beside this one
        del sys.modules[name]
        return None, f"the {commit} column is skipped: it does not import ({exc})"
    return module, why


def step_floor(snake: Snake, kind: str, states: np.ndarray, taus: np.ndarray,
               products: bool = False) -> Callable[[], None]:
    """A function making exactly the Pinocchio calls of one closed-loop step of
    ``simulate`` (see :class:`snake_pin.sim.ViscousPlant`), on the run's states in turn:
    the controller's (Lyapunov-like: the friction's, ABA, computeMinverse; PFL: the
    friction's, CRBA, nonLinearEffects), then three RK4 stages (the friction's and ABA
    each; the first stage comes from the controller). The friction's call is the damping
    twin's (:class:`snake_pin.friction.FrictionModel`): its RNEA (isotropic friction), its
    CRBA (with wheels, up to ``WHEELED_TWIN_MAX_LINKS`` links) or its two RNEA passes
    (longer robots). With ``products``, the twin's CRBA is the friction model's own
    ``calc_force`` instead: the CRBA and the two products that turn it into Q (the wheels'
    rolling speeds, then the force: the Schur complement), as the step makes them."""
    import pinocchio as pin

    friction = snake.friction
    model, data, nq, size = snake.model, snake.data, snake.nq, friction.size
    twin, zero = friction.twin, np.zeros(size)
    friction_data = friction.create_data()
    twin_data = friction_data.twin_data
    crba_route, wheels = friction.uses_twin_crba, friction.has_wheels
    world = pin.Convention.WORLD
    rnea, aba, crba = pin.rnea, pin.aba, pin.crba
    arguments = []
    for x, tau in zip(states, taus, strict=True):
        q_ext, v_ext = np.zeros(size), np.zeros(size)
        q_ext[:nq], v_ext[:nq] = x[:nq], x[nq:]
        torque = np.zeros(nq)
        torque[3:] = tau
        arguments.append((q_ext, v_ext, q_ext[:nq], v_ext[:nq], torque))
    cursor = iter(range(1 << 62))
    count = len(arguments)

    calc_force = friction.calc_force

    def friction_call(q_ext: np.ndarray, v_ext: np.ndarray, v: np.ndarray) -> None:
        if crba_route:
            if products:  # the same work as the step's: CRBA, rolling speeds, then -Q
                calc_force(friction_data, q_ext[:nq], v)
            else:
                crba(twin, twin_data, q_ext, world)
        elif wheels:  # the locked pass (w), the rolling pass (-Q)
            rnea(twin, twin_data, q_ext, zero, v_ext)
            rnea(twin, twin_data, q_ext, zero, v_ext)
        else:
            rnea(twin, twin_data, q_ext, zero, v_ext)

    def step() -> None:
        q_ext, v_ext, q, v, torque = arguments[next(cursor) % count]
        friction_call(q_ext, v_ext, v)
        if kind == "pfl":
            pin.crba(model, data, q, world)
            pin.nonLinearEffects(model, data, q, v)
        else:
            aba(model, data, q, v, torque, world)
            pin.computeMinverse(model, data)
        for _ in range(3):
            friction_call(q_ext, v_ext, v)
            aba(model, data, q, v, torque, world)

    return step


def bench_runs(budget: float, baseline: str | None = BASELINE) -> None:
    """Closed-loop runs at 1 kHz (RK4, dt = 1 ms): wall time, real-time factor, and the step
    against dc0b889's (interleaved segments in two worker processes) and against the floor
    of its Pinocchio calls (timed in this process in the same rounds)."""
    import snake_pin
    from snake_pin.control import LyapunovController, PFLController
    from snake_pin.runs import pfl, tracking
    from snake_pin.sim import simulate

    quick = budget < 0.1
    rounds = 3 if quick else 7
    repeat = 1 if quick else 3
    root, note = (None, "no baseline asked for") if baseline is None else \
        baseline_checkout(baseline)
    new = Worker(Path(snake_pin.__file__).resolve().parents[1])
    old = Worker(root) if root is not None else None
    rows = []
    try:
        for label, kind, robot, t_final, segment in RUNS:
            segment = min(segment, 2.0) if quick else segment
            fixed: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v
                                     for k, v in robot.items()}
            params = SnakeParams.table1(**fixed) if kind == "pfl" else \
                tracking.tracking_params(**fixed)
            snake = Snake(params)
            ctrl = PFLController(snake) if kind == "pfl" else LyapunovController(snake)
            x0 = pfl.initial_state(params) if kind == "pfl" else tracking.initial_state(params)
            walls, traj = [], None
            for _ in range(repeat):
                start = time.perf_counter()
                traj = simulate(snake, ctrl, x0, t_final)
                walls.append(time.perf_counter() - start)
            assert traj is not None
            wall = statistics.median(walls)
            pick = slice(None, None, max(1, len(traj) // 64))
            states = np.hstack((traj.q, traj.dq))[pick]
            floor = step_floor(snake, kind, states, traj.tau[pick])
            with_products = step_floor(snake, kind, states, traj.tau[pick], products=True) \
                if snake.friction.uses_twin_crba else None
            for worker in (new, old):  # warm-up: imports, first allocations
                if worker is not None:
                    worker.run(kind, robot, 0.01)
            us_new, us_old, us_floor, us_products = [], [], [], []
            for _ in range(rounds):
                if old is not None:
                    answer = old.run(kind, robot, segment)
                    us_old.append(answer["seconds"] / answer["steps"] * 1e6)
                answer = new.run(kind, robot, segment)
                us_new.append(answer["seconds"] / answer["steps"] * 1e6)
                number = max(1, int(budget / max(timeit.timeit(floor, number=3) / 3, 1e-7)))
                us_floor.append(timeit.timeit(floor, number=number) / number * 1e6)
                if with_products is not None:
                    us_products.append(timeit.timeit(with_products, number=number)
                                       / number * 1e6)
            if traj.t_end < t_final - 1e-9:
                label = f"{label} (ends at {traj.t_end:.2f} s: {traj.status})"
            rows.append([label, f"{wall:.2f}", f"{traj.t_end / wall:.1f}x",
                         show(spread(us_new)),
                         show(spread(us_old)) if us_old else "-",
                         show(ratios(us_old, us_new), 2, "x") if us_old else "-",
                         show(spread(us_floor)), show(ratios(us_new, us_floor), 2, "x"),
                         show(ratios(us_new, us_products), 2, "x") if us_products else "-"])
    finally:
        new.close()
        if old is not None:
            old.close()
    table(f"Closed-loop runs at 1 kHz (simulate only), us per step: median (10-90 %) of "
          f"{rounds} interleaved rounds",
          ["run", "wall [s]", "real-time factor", "us/step new", f"us/step {baseline}",
           "speed-up", "floor us/step", "new/floor", "new/(floor + products)"], rows)
    print(f"\nBaseline: {note}. Segments of at most 5 s (2 s with --quick) are run "
          "alternately by the two checkouts in worker processes; the floor (the Pinocchio "
          "calls one step makes, on the run's states) is timed here in the same rounds; "
          "with anisotropic friction also the floor plus the two products per twin CRBA "
          "that make Q from it (the last column). "
          "Wall time and real-time factor: the whole run in this process, median of "
          f"{repeat}.")


def interleaved_calls(fns: dict[str, Callable[[], object]],
                      rounds: int) -> dict[str, list[float]]:
    """Seconds of one call of each function in each of ``rounds`` interleaved rounds (A B C
    A B C ...), for calls long enough to time one by one (whole runs)."""
    samples: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            start = time.perf_counter()
            fn()
            samples[name].append(time.perf_counter() - start)
    return samples


#: Runs ``run_engine`` per request line {"cone", "t_final"} (cone null: the checkout's own
#: default) with whatever snake_pin is first on the path (this checkout or the
#: baseline's), using only the API both have; the friction model is identified once per
#: cone, outside the timing. Answers {"seconds", "steps", "cone", "status"}.
ENGINE_WORKER = r"""
import json, sys, time
from snake_pin.engine.model import WheelSpec
from snake_pin.engine.run import identify_friction, run_engine

identified = {}
for line in sys.stdin:
    request = json.loads(line)
    wheels = WheelSpec() if request["cone"] is None else WheelSpec(cone=request["cone"])
    if wheels.cone not in identified:
        identified[wheels.cone] = identify_friction(wheels=wheels)
    start = time.perf_counter()
    run = run_engine(wheels=wheels, t_final=request["t_final"],
                     friction=identified[wheels.cone])
    seconds = time.perf_counter() - start
    traj = run.trajectory
    print(json.dumps({"seconds": seconds, "steps": len(traj) - 1, "cone": wheels.cone,
                      "status": getattr(traj, "status", "completed")}), flush=True)
"""

#: Perturbed runs per robot and cone in the fidelity table (full, --quick).
ENGINE_SEEDS, QUICK_ENGINE_SEEDS = 7, 3
CONES = ("elliptic", "pyramidal")


def bench_engine_against_baseline(quick: bool, baseline: str | None) -> None:
    """The 60 s engine run (10 s with --quick) of this checkout against ``baseline``'s, in
    two worker processes taking turns: each round runs each cone on the baseline, then on
    this checkout. The first row pairs each checkout's default cone (the run
    ``snake-pin engine`` makes)."""
    import snake_pin

    t_run, rounds = (10.0, 2) if quick else (60.0, 3)
    root, note = (None, "no baseline asked for") if baseline is None else \
        baseline_checkout(baseline)
    workers = {"new": Worker(Path(snake_pin.__file__).resolve().parents[1], ENGINE_WORKER)}
    if root is not None:
        workers["old"] = Worker(root, ENGINE_WORKER)
    seconds: dict[tuple[str, str], list[float]] = {}
    default: dict[str, str] = {}
    try:
        for side, worker in workers.items():  # warm-up: imports, identification
            default[side] = worker.request({"cone": None, "t_final": 0.01})["cone"]
            for cone in CONES:
                worker.request({"cone": cone, "t_final": 0.01})
        for _ in range(rounds):
            for side in ("old", "new"):
                for cone in CONES:
                    if side not in workers:
                        continue
                    answer = workers[side].request({"cone": cone, "t_final": t_run})
                    if answer["status"] != "completed":
                        raise RuntimeError(f"{side} {cone} run: {answer['status']}")
                    seconds.setdefault((side, cone), []).append(answer["seconds"])
    finally:
        for worker in workers.values():
            worker.close()
    rows = []
    pairs = [(f"default: {default['new']}", default["new"], default.get("old"))]
    pairs += [(cone, cone, cone if "old" in workers else None) for cone in CONES]
    for label, mine_cone, their_cone in pairs:
        mine = seconds["new", mine_cone]
        theirs = seconds["old", their_cone] if their_cone is not None else None
        rows.append([label, show(spread(mine), 2), f"{t_run / statistics.median(mine):.1f}x",
                     their_cone or "-", show(spread(theirs), 2) if theirs else "-",
                     f"{t_run / statistics.median(theirs):.1f}x" if theirs else "-",
                     show(ratios(theirs, mine), 2, "x") if theirs else "-"])
    table(f"MuJoCo closed loop, {t_run:.0f} s run (velocity-level law, 1 kHz): wall time [s], "
          f"median (10-90 %) of {rounds} interleaved rounds",
          ["cone here", "wall [s]", "real-time factor", f"cone {baseline}",
           f"wall {baseline} [s]", f"real-time factor {baseline}", "speed-up"], rows)
    print(f"\nBaseline: {note}. Both checkouts run run_engine(wheels=WheelSpec(cone=...), "
          f"t_final={t_run:g}, friction=...) in worker processes taking turns, the friction "
          "identified beforehand (not timed); the first row pairs each checkout's default "
          "cone (WheelSpec().cone), the run `snake-pin engine` makes, and is the headline.")


def engine_breakdown(quick: bool) -> None:
    """Where a control period of this checkout's engine loop goes, per cone: the whole loop
    (run_engine), MuJoCo alone (the run's torques replayed open loop, two mj_step per
    period) and the controller alone (the velocity-level law on the run's states); the rest
    is the loop's own work (reading the state, the filter, checks, recording)."""
    import mujoco

    from snake_pin import Snake
    from snake_pin.control import QuasiStaticLyapunovController
    from snake_pin.engine.model import WheelSpec, build_engine_model
    from snake_pin.engine.run import identify_friction, run_engine

    t_run, rounds = (3.0, 3) if quick else (10.0, 5)
    rows = []
    for cone in CONES:
        wheels = WheelSpec(cone=cone)
        friction = identify_friction(wheels=wheels)
        traj = run_engine(wheels=wheels, t_final=t_run, friction=friction).trajectory
        engine = build_engine_model(SnakeParams.engine(), wheels)
        states = np.hstack((traj.q, traj.dq))[:-1]
        times = traj.t[:-1]
        snake = Snake(traj.params)

        def loop(wheels=wheels, friction=friction) -> None:
            run_engine(wheels=wheels, t_final=t_run, friction=friction)

        def replay(engine=engine, traj=traj) -> None:
            engine.set_paper_configuration(traj.q[0])
            for tau in traj.tau[:-1]:
                engine.apply_torque(tau)
                mujoco.mj_step(engine.model, engine.data, engine.wheels.substeps)

        def control(snake=snake, states=states, times=times, dt=wheels.control_dt) -> None:
            controller = QuasiStaticLyapunovController(snake, control_dt=dt)
            controller.prepare(times)
            for x, t in zip(states, times.tolist(), strict=True):
                controller(x, t)

        per_step = {name: [1e6 * value / len(times) for value in values] for name, values in
                    interleaved_calls({"loop": loop, "mujoco": replay, "controller": control},
                                      rounds).items()}
        glue = [a - b - c for a, b, c in zip(per_step["loop"], per_step["mujoco"],
                                             per_step["controller"], strict=True)]
        shares = {name: ratios(values, per_step["loop"]) for name, values in
                  (("mujoco", per_step["mujoco"]), ("controller", per_step["controller"]),
                   ("glue", glue))}
        rows.append([cone, show(spread(per_step["loop"])),
                     f"{show(spread(per_step['mujoco']))}, {100 * shares['mujoco'][0]:.0f} %",
                     f"{show(spread(per_step['controller']))}, "
                     f"{100 * shares['controller'][0]:.0f} %",
                     f"{show(spread(glue))}, {100 * shares['glue'][0]:.0f} %"])
    table(f"Engine loop of this checkout, us per control period (1 ms), median (10-90 %) of "
          f"{rounds} interleaved rounds on {t_run:.0f} s runs, share of the loop",
          ["cone", "whole loop", "MuJoCo alone", "controller alone", "loop's own work"], rows)


def engine_fidelity(quick: bool) -> None:
    """Identified friction of each cone against its contact models, and the tracking error
    of perturbed runs (a distribution: the engine runs are chaotic)."""
    from snake_pin.engine.model import WheelSpec
    from snake_pin.engine.run import identify_friction
    from snake_pin.runs.engine import PERTURBATION, engine_draw, perturbations
    from snake_pin.runs.parallel import run_jobs

    count, t_final = (QUICK_ENGINE_SEEDS, 20.0) if quick else (ENGINE_SEEDS, 60.0)
    robots = (("every joint actuated", SnakeParams.engine()),
              ("joint 5 passive", SnakeParams.engine(passive=(5,))))
    offsets = perturbations(count, 7, PERTURBATION, seed=0)
    identified = {cone: identify_friction(wheels=WheelSpec(cone=cone)) for cone in CONES}
    diagonal = {cone: identify_friction(wheels=WheelSpec(cone=cone), heading=math.pi / 4)
                for cone in CONES}
    jobs = [(engine_draw, (params, offset), {"wheels": WheelSpec(cone=cone),
                                             "t_final": t_final, "friction": identified[cone]})
            for cone in CONES for _, params in robots for offset in offsets]
    runs = iter(run_jobs(jobs))
    rows = []
    for cone in CONES:
        f = identified[cone]
        cells = []
        for _ in robots:
            rms = [next(runs).trajectory.summary["rms_percent"] for _ in offsets]
            cells.append(show(spread(rms), 2))
        off_x = 100 * (f["c_x"] / f["c_x_rolling_model"] - 1)
        off_y = 100 * (f["c_y"] / f["c_y_coulomb_model"] - 1)
        c_y_45 = diagonal[cone]["c_y"]
        off_45 = 100 * (c_y_45 / f["c_y_coulomb_model"] - 1)
        rows.append([cone, f"{f['c_x']:.4f} ({off_x:+.1f} %)", f"{f['c_y']:.2f} ({off_y:+.2f} %)",
                     f"{c_y_45:.2f} ({off_45:+.2f} %)", f"{f['c_theta']:.3g}", *cells])
    f = identified[CONES[0]]
    table(f"Cone fidelity: identified viscous model (identify_friction) against the contact "
          f"models, and RMS head error [% of body] over t >= 10 s of {count} runs of "
          f"{t_final:.0f} s from perturbed postures, median (10-90 %)",
          ["cone", "c_x [N s/m] (vs rolling)", "c_y [N s/m] (vs Coulomb)",
           "c_y at 45 deg [N s/m] (vs Coulomb)", "c_theta [N m s]",
           *(f"RMS %, {label}" for label, _ in robots)], rows)
    print(f"\nReferences (snake_pin.engine.run.identify_friction): c_x against the rolling "
          f"model 2 b / r^2 = {f['c_x_rolling_model']:.4f} N s/m (axle damping b, wheel "
          f"radius r), c_y against the Coulomb equivalent 1.5 mu m g / v0 = "
          f"{f['c_y_coulomb_model']:.2f} N s/m (the least-squares viscous fit of a Coulomb "
          f"deceleration from v0 = {f['speed']} m/s to rest). c_x and c_y: the straight "
          "snake coasting along the world x axis (as the runs head); c_y at 45 deg: coasting "
          "at 45 degrees to the world axes (identify_friction(heading=pi/4)), where a "
          "faithful Coulomb contact gives the same c_y. c_theta is the axle model "
          "2 d^2 b / r^2 for both cones, not a fit: a link turning about its own CM rolls its "
          "wheels, and in a coast of the whole snake that torque is swamped by the sliding "
          "wheels' (about 1e-5 of it). Offsets of the initial joint angles: "
          f"U(-{PERTURBATION:g}, {PERTURBATION:g}) rad, snake_pin.runs.engine."
          "perturbations(seed=0), the same for both cones.")


def bench_engine(budget: float, baseline: str | None = BASELINE) -> None:
    """The MuJoCo closed loop: this checkout's run against ``baseline``'s, where the loop's
    time goes, and the fidelity of each friction cone."""
    quick = budget < 0.1
    bench_engine_against_baseline(quick, baseline)
    engine_breakdown(quick)
    engine_fidelity(quick)


#: The report's stages before issues 14 and 15 added theirs (issue 13's 150 s target).
PAPER_STAGES = ("robot", "manipulability", "integrability", "pfl", "tracking", "engine")


def _timed_reproduce(quick: bool, only: list[str] | None = None
                     ) -> tuple[float, dict[str, float]]:
    """Wall time of ``snake-pin reproduce`` (every stage, or those in ``only``) in a fresh
    process and its stage times (from its ``--verbose`` log)."""
    import re
    import shutil

    folder = tempfile.mkdtemp(prefix="snake_pin_bench_reproduce_")
    try:
        command = [sys.executable, "-m", "snake_pin.cli", "reproduce", "-o", folder,
                   "--verbose"] + (["--quick"] if quick else [])
        for stage in only or []:
            command += ["--only", stage]
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - start
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    stages = {m.group(1): float(m.group(2)) for m in
              re.finditer(r"\] (\S+) done in ([0-9.]+) s", done.stderr)}
    return wall, stages


def bench_reproduce(budget: float) -> None:
    """``snake-pin reproduce`` quiet and with the other core busy (a CPU-bound loop in
    another process), alternately, and the busy/quiet ratio (issue 13, item 4)."""
    quick = budget < 0.1
    rounds = 1 if budget <= 0.2 else 2
    walls: dict[str, list[float]] = {"quiet": [], "busy": []}
    stages: dict[str, list[dict[str, float]]] = {"quiet": [], "busy": []}
    for _ in range(rounds):
        for condition in ("quiet", "busy"):
            spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"]) \
                if condition == "busy" else None
            try:
                wall, times = _timed_reproduce(quick)
            finally:
                if spinner is not None:
                    spinner.kill()
                    spinner.wait()
            walls[condition].append(wall)
            stages[condition].append(times)
    names = list(stages["quiet"][0])
    rows = []
    for condition in ("quiet", "busy"):
        per_stage = [statistics.median(t.get(name, math.nan) for t in stages[condition])
                     for name in names]
        paper = sum(v for name, v in zip(names, per_stage, strict=True)
                    if name in PAPER_STAGES)
        rows.append([condition, f"{statistics.median(walls[condition]):.1f}",
                     f"{paper:.1f}"] + [f"{v:.1f}" for v in per_stage])
    ratio = ratios(walls["busy"], walls["quiet"])
    table(f"snake-pin reproduce{' --quick' if quick else ''}, wall time [s] "
          f"(median of {rounds} alternating rounds)",
          ["condition", "whole", "paper's stages", *names], rows)
    print(f"\nbusy / quiet: {show(ratio, 2, 'x')}. Busy: a CPU-bound Python loop in another "
          "process for the whole run. \"paper's stages\": "
          f"{', '.join(PAPER_STAGES)} (issue 13's 150 s target; failure_map and "
          "bench_control came later).")


def bench_failure_map(budget: float) -> None:
    """What the failure-map stage adds to ``snake-pin reproduce``: the whole report and the
    report without that stage, back to back in alternating rounds (issue 14, item 8)."""
    from snake_pin.experiments.reproduce import stages

    quick = budget < 0.1
    rounds = 1 if quick else 2
    without = [name for name, _ in stages() if name != "failure_map"]
    walls: dict[str, list[float]] = {"whole report": [], "without failure_map": []}
    map_times: list[float] = []
    stage_times: list[dict[str, float]] = []
    for _ in range(rounds):
        wall, times = _timed_reproduce(quick)
        walls["whole report"].append(wall)
        map_times.append(times.get("failure_map", math.nan))
        stage_times.append(times)
        walls["without failure_map"].append(_timed_reproduce(quick, without)[0])
    added = [a - b for a, b in zip(walls["whole report"], walls["without failure_map"],
                                   strict=True)]
    rows = [[name, show(spread(values))] for name, values in walls.items()]
    rows.append(["difference", show(spread(added))])
    rows.append(["failure_map stage (its own log)", show(spread(map_times))])
    table(f"snake-pin reproduce{' --quick' if quick else ''} with and without the failure "
          f"map, wall time [s] (median of {rounds} alternating rounds)", ["run", "s"], rows)
    print("\nstages of the whole report [s]: " + ", ".join(
        f"{name} {statistics.median(t.get(name, math.nan) for t in stage_times):.1f}"
        for name in stage_times[0]))
    ratio = ratios(walls["whole report"], walls["without failure_map"])
    print(f"\nwith / without: {show(ratio, 2, 'x')} (issue 14's limit: the stage adds at "
          "most 120 s)")


#: Study sizes (runs) of ``--only study`` and the commit it compares to (lockstep batches).
STUDY_SIZES = (40, 256, 1000)
STUDY_BASELINE = "3801e7f"

#: The study of ``--only study``: Table 1, Lyapunov-like law, c_y / c_x = 50, 10 s runs from
#: noisy starts, one seed per run (no ``batch_size``: a baseline with batches uses its own
#: default).
STUDY_TEXT = """[study]
name = "bench_study"

[base]
robot = "table1"
controller = "lyapunov"
model = "viscous"
c_x = 0.5
c_y = 25.0
t_final = 10.0
error_window = 5.0
init_noise = 0.02

[axes.init_seed]
values = [{seeds}]
"""

#: Runs the study file argv[1] into the new folder argv[2] on argv[3] local workers with
#: whatever snake_pin is first on the path (this checkout or the baseline's), through its
#: own run_study; answers {"seconds", "recorded", "status"} (seconds: run_study alone).
STUDY_WORKER = r"""
import json, sys, time
from snake_pin.study import run_study

start = time.perf_counter()
summary = run_study(sys.argv[1], sys.argv[2], workers=int(sys.argv[3]), progress=False)
seconds = time.perf_counter() - start
print(json.dumps({"seconds": seconds, "recorded": summary.recorded,
                  "status": summary.status}), flush=True)
"""


def timed_study(root: Path, study: Path, workers: int) -> float:
    """Wall seconds of ``root``'s run_study on ``study`` into a fresh folder (a new process,
    ``root`` first on its path); the study must complete every run."""
    import shutil

    folder = Path(tempfile.mkdtemp(prefix="snake_pin_bench_study_"))
    try:
        done = subprocess.run([sys.executable, "-P", "-c", STUDY_WORKER, str(study),
                               str(folder / "out"), str(workers)],
                              env=dict(os.environ, PYTHONPATH=str(root)), cwd=folder,
                              capture_output=True, text=True, check=False)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    lines = done.stdout.strip().splitlines()
    if done.returncode != 0 or not lines:
        raise RuntimeError(f"study run of {root} failed ({done.returncode}): "
                           f"{done.stderr.strip()[-300:]}")
    answer = json.loads(lines[-1])
    if answer["status"] != "complete":
        raise RuntimeError(f"study run of {root}: {answer['status']}, "
                           f"{answer['recorded']} runs recorded")
    return float(answer["seconds"])


def bench_study(budget: float, baseline: str | None = STUDY_BASELINE,
                sizes: tuple[int, ...] = STUDY_SIZES, rounds: int = 1) -> None:
    """Study throughput (runs per wall second) of this tree's run_study against
    ``baseline``'s, each in its own process on a local cluster of one worker per core,
    on the same generated study of N runs; per size the two trees take turns (baseline,
    then this tree) for ``rounds`` rounds."""
    import snake_pin

    del budget  # whole studies: the sizes set the cost
    workers = os.cpu_count() or 1
    here = Path(snake_pin.__file__).resolve().parents[1]
    root, note = (None, "no baseline asked for") if baseline is None else \
        baseline_checkout(baseline)
    trees = {"baseline": root, "this tree": here} if root is not None else {"this tree": here}
    rows = []
    with tempfile.TemporaryDirectory(prefix="snake_pin_bench_studies_") as folder:
        for size in sizes:
            study = Path(folder) / f"study_{size}.toml"
            study.write_text(STUDY_TEXT.format(seeds=", ".join(map(str, range(size)))))
            rates: dict[str, list[float]] = {name: [] for name in trees}
            for _ in range(rounds):
                for name, tree in trees.items():
                    rates[name].append(size / timed_study(tree, study, workers))
            mine, theirs = rates["this tree"], rates.get("baseline")
            rows.append([str(size), show(spread(mine), 2),
                         show(spread(theirs), 2) if theirs else "-",
                         show(ratios(mine, theirs), 2, "x") if theirs else "-"])
    table(f"Study throughput, runs per wall second (10 s runs, Table 1, Lyapunov-like law, "
          f"{workers} local workers), median (10-90 %) of {rounds} interleaved round"
          f"{'s' if rounds != 1 else ''}",
          ["runs", "this tree [runs/s]", f"{baseline} [runs/s]", "this / baseline"], rows)
    print(f"\nBaseline: {note}. Each tree runs its own run_study in a process of its own "
          "(its checkout first on the path), into a fresh folder; the time is run_study's "
          "(cluster start and result files included, Python's start not).")


# ------------------------------------------------------------------------------ mpc
def _python_dam(snake: Snake) -> Any:
    """The other route for the OCP's dynamics: a Python differential action model whose
    calc/calcDiff call Snake.forward_dynamics and Snake.dynamics_derivatives (no costs: a
    lower bound on that route's cost per call)."""
    import crocoddyl

    from snake_pin.ocp import state_model

    nq, actuated = snake.nq, np.array(snake.params.actuated) - 1

    class PythonDynamics(crocoddyl.DifferentialActionModelAbstract):
        def __init__(self) -> None:
            crocoddyl.DifferentialActionModelAbstract.__init__(
                self, state_model(snake), len(actuated), 0)
            self.tau = np.zeros(snake.n - 1)

        def calc(self, data: Any, x: np.ndarray, u: np.ndarray | None = None) -> None:
            if u is not None:
                self.tau[actuated] = u
            data.xout[:] = snake.forward_dynamics(x[:nq], x[nq:], self.tau)

        def calcDiff(self, data: Any, x: np.ndarray,
                     u: np.ndarray | None = None) -> None:
            if u is not None:
                self.tau[actuated] = u
            d = snake.dynamics_derivatives(x[:nq], x[nq:], self.tau)
            data.Fx[:, :nq] = d.ddq_dq
            data.Fx[:, nq:] = d.ddq_dv
            data.Fu[:] = d.ddq_dtau[:, actuated]

        def createData(self) -> Any:
            return crocoddyl.DifferentialActionDataAbstract(self)

    return PythonDynamics()


#: The levers of the MPC's speed that bench_mpc runs against the default MPCOptions in the
#: same bench run (MPCOptions changes).
MPC_LEVERS: dict[str, dict[str, Any]] = {
    "default MPCOptions": {},
    "step_halvings=0 (one line-search trial)": {"step_halvings": 0},
    "step_halvings=1": {"step_halvings": 1},
    "iterations=1": {"iterations": 1},
    "first_iterations=50": {"first_iterations": 50},
}


#: The commit whose friction Jacobians (``FrictionModel.derivatives``: two passes of the
#: twin's RNEA derivatives, new arrays per call) bench_mpc runs the MPC with, as a lever.
FRICTION_JACOBIANS_BASELINE = "5a237a7"


def _mpc_run(snake: Snake, reference: Any, x0: np.ndarray, t_final: float,
             lever: dict[str, Any], calc_diff: Callable[..., None] | None = None
             ) -> dict[str, Any]:
    """One closed-loop MPC run with a lever: its wall (whole run, first solve, warm
    re-solves), the stage calc/calcDiff calls and line-search trials of the warm re-solves.
    ``calc_diff`` replaces the actuation's calcDiff (another route to the same Jacobians)."""
    import crocoddyl

    from snake_pin import ocp
    from snake_pin.control.mpc import MPCController, MPCOptions
    from snake_pin.sim import simulate

    actuation = ocp.ChainRootActuation
    counts = {"calc": 0, "calcDiff": 0}
    seconds = {"calc": 0.0, "calcDiff": 0.0}  # in the friction's Python callbacks
    plain = actuation.calc, actuation.calcDiff if calc_diff is None else calc_diff
    clock = time.perf_counter

    def counted(name: str, method: Callable[..., None]) -> Callable[..., None]:
        def call(self: Any, *args: Any) -> None:
            counts[name] += 1
            start = clock()
            method(self, *args)
            seconds[name] += clock() - start
        return call

    steps: list[float] = []

    class Steps(crocoddyl.CallbackAbstract):  # the accepted step of each iteration
        def __init__(self) -> None:
            crocoddyl.CallbackAbstract.__init__(self)

        def __call__(self, solver: Any) -> None:
            steps.append(solver.stepLength)

    solves: list[dict[str, Any]] = []
    with patch.object(actuation, "calc", counted("calc", plain[0])), \
            patch.object(actuation, "calcDiff", counted("calcDiff", plain[1])):
        controller = MPCController(snake, reference, options=MPCOptions(**lever))
        controller._solver.setCallbacks([Steps()])
        solve = controller._solve

        def timed(x: np.ndarray, t: float) -> None:
            before = (time.perf_counter(), counts["calc"], counts["calcDiff"], len(steps),
                      seconds["calc"], seconds["calcDiff"])
            solve(x, t)
            solves.append({"wall": time.perf_counter() - before[0],
                           "calc": counts["calc"] - before[1],
                           "calcDiff": counts["calcDiff"] - before[2],
                           "steps": steps[before[3]:],
                           "force": seconds["calc"] - before[4],
                           "jacobians": seconds["calcDiff"] - before[5]})

        controller._solve = timed  # type: ignore[method-assign]
        wall = time.perf_counter()
        traj = simulate(snake, controller, x0, t_final)
        wall = time.perf_counter() - wall
    warm = solves[1:]
    warm_steps = [s for solve_ in warm for s in solve_["steps"]]
    first_steps = solves[0]["steps"]
    return {"wall": wall, "first": solves[0]["wall"], "warm": sum(s["wall"] for s in warm),
            "solves": len(warm), "traj": traj, "controller": controller,
            "calc": sum(s["calc"] for s in warm) / len(warm),
            "calcDiff": sum(s["calcDiff"] for s in warm) / len(warm),
            "iterations": len(warm_steps) / len(warm),
            # trials of an iteration that accepts 2^-k: k + 1
            "trials": sum(1 - math.log2(s) for s in warm_steps) / max(len(warm_steps), 1),
            "first_trials": sum(1 - math.log2(s) for s in first_steps) / len(first_steps),
            "first_calc": solves[0]["calc"], "first_iterations": len(first_steps),
            "force": sum(s["force"] for s in warm),
            "jacobians": sum(s["jacobians"] for s in warm),
            "plant": wall - sum(s["wall"] for s in solves)}


def bench_mpc(budget: float) -> None:
    """The MPC's speed: wall per simulated second, per re-solve and where it goes, with the
    Lyapunov-like law on the same run; the levers (:data:`MPC_LEVERS`, and the friction
    Jacobians of :data:`FRICTION_JACOBIANS_BASELINE`) as ratios against the default in
    interleaved rounds; then the routes per call (the OCP's dynamics, the friction
    Jacobians against that commit's)."""
    import crocoddyl

    from snake_pin import ocp
    from snake_pin.control import LyapunovController
    from snake_pin.paths import Line, PathReference
    from snake_pin.runs.tracking import initial_state, tracking_params
    from snake_pin.sim import simulate

    quick = budget < 0.1
    t_final, rounds = (1.0, 2) if quick else (3.0, 3)
    params = tracking_params()
    snake, reference = Snake(params), PathReference(Line())
    x0 = initial_state(params)
    # the friction Jacobians of FRICTION_JACOBIANS_BASELINE, as its calcDiff made them
    baseline, why = baseline_package(FRICTION_JACOBIANS_BASELINE)
    levers: dict[str, tuple[dict[str, Any], Callable[..., None] | None]] = {
        name: (lever, None) for name, lever in MPC_LEVERS.items()}
    baseline_derivatives = None
    if baseline is None:
        print(f"\n({why})")
    else:
        old_params = importlib.import_module(f"{baseline.__name__}.params").SnakeParams
        old_friction = importlib.import_module(f"{baseline.__name__}.friction").FrictionModel
        baseline_derivatives = old_friction(old_params.from_dict(params.to_dict()),
                                            snake.model).derivatives

        def baseline_calc_diff(self: Any, data: Any, x: np.ndarray,
                               u: np.ndarray | None = None) -> None:
            nq, dtau_dx = self.nq, data.dtau_dx
            _, dtau_dx[:, :nq], dtau_dx[:, nq:] = baseline_derivatives(x[:nq], x[nq:])

        levers[f"friction Jacobians as at {FRICTION_JACOBIANS_BASELINE}"] = (
            {}, baseline_calc_diff)
    runs: dict[str, list[dict[str, Any]]] = {name: [] for name in levers}
    lyapunov_walls = []
    for _ in range(rounds):
        for name, (lever, calc_diff) in levers.items():
            runs[name].append(_mpc_run(snake, reference, x0, t_final, lever, calc_diff))
        lyapunov = LyapunovController(snake, reference)
        start = time.perf_counter()
        simulate(snake, lyapunov, x0, t_final)
        lyapunov_walls.append(time.perf_counter() - start)
    default = runs["default MPCOptions"]
    steady = {name: [(r["wall"] - r["first"]) / t_final for r in results]
              for name, results in runs.items()}
    rows = []
    for name, results in runs.items():
        first = results[0]
        rows.append([
            name, show(spread([r["wall"] / t_final for r in results]), 2),
            show(ratios([r["wall"] for r in results], [r["wall"] for r in default]), 2),
            show(spread([r["first"] for r in results]), 2),
            show(spread(steady[name]), 2),
            f"{1 / statistics.median(steady[name]):.2f}x",
            show(ratios(steady[name], steady["default MPCOptions"]), 2),
            show(spread([1e3 * r["warm"] / r["solves"] for r in results]), 0),
            f"{first['iterations']:.2f} / {first['trials']:.2f}",
            f"{first['calc']:.0f} / {first['calcDiff']:.0f}",
            f"{first['first_iterations']} / {first['first_trials']:.2f}"])
    rows.append(["Lyapunov-like law", show(spread([w / t_final for w in lyapunov_walls]), 3),
                 "-", "-", "-", f"{t_final / statistics.median(lyapunov_walls):.1f}x",
                 *["-"] * 5])
    status = {r["traj"].status for results in runs.values() for r in results}
    table(f"MPC head tracking and its levers, line, {t_final:g} s at 1 kHz (Table 1, c_y = "
          f"50 c_x, status {', '.join(sorted(status))}), median (10-90 %) of {rounds} "
          "interleaved rounds; steady = the run less its first (cold) solve; ratios: wall "
          "against the default's in the same round",
          ["run", "wall per simulated s [s]", "ratio to default", "first solve [s]",
           "steady wall per simulated s",
           "steady real-time factor", "steady ratio to default", "wall per re-solve [ms]",
           "iterations / line-search trials per iteration (re-solves)",
           "stage calc / calcDiff per re-solve", "first solve: iterations / trials"], rows)
    # where the default's steady wall goes: the friction's Python callbacks timed in the run
    # (each stage's actuation calc and calcDiff), the rest of the re-solves in Crocoddyl's
    # C++ (ABA and its derivatives, costs, Riccati, rollouts) and the glue
    run = default[0]
    traj = run["traj"]
    share: list[tuple[str, float]] = [
        (f"friction force (the actuation's calc, {run['calc']:.0f} per re-solve)",
         run["force"]),
        (f"friction Jacobians (the actuation's calcDiff, {run['calcDiff']:.0f} per re-solve)",
         run["jacobians"]),
        ("the rest of the re-solves (C++: ABA, its derivatives, costs, Riccati; glue)",
         run["warm"] - run["force"] - run["jacobians"]),
        ("plant simulation and feedback between re-solves", run["plant"])]
    steady_wall = run["wall"] - run["first"]
    trials = run["iterations"] * run["trials"] * 4 * run["controller"].options.nodes
    table("Where the default MPC's steady wall goes (first round; the friction's callbacks "
          f"timed in the run; {trials:.0f} of the {run['calc']:.0f} stage calcs per re-solve "
          "are line-search trials)", ["part", "wall [s]", "share"],
          [[name, f"{seconds_:.2f}", f"{100 * seconds_ / steady_wall:.0f} %"]
           for name, seconds_ in share])
    model = ocp.differential_model(snake)
    data = model.createData()
    x = np.r_[traj.q[len(traj) // 2], traj.dq[len(traj) // 2]]
    u = traj.tau[len(traj) // 2][np.array(params.actuated) - 1]
    # the routes, per call: the dynamics route
    python_route = _python_dam(snake)
    python_data = python_route.createData()
    nq = snake.nq
    friction_data = snake.friction.create_data()
    into_data = "friction force and Jacobians into a FrictionData (calc_derivatives)"
    as_before = f"friction force and Jacobians as at {FRICTION_JACOBIANS_BASELINE} (derivatives)"
    routes: dict[str, Callable[[], object]] = {
        "C++ free forward dynamics + Python friction actuation: calc": partial(
            model.calc, data, x, u),
        "Python action model over Snake (dynamics only): calc": partial(
            python_route.calc, python_data, x, u),
        "C++ free forward dynamics + Python friction actuation: calcDiff": partial(
            model.calcDiff, data, x, u),
        "Python action model over Snake (dynamics only): calcDiff": partial(
            python_route.calcDiff, python_data, x, u),
        into_data: partial(snake.friction.calc_derivatives, friction_data, x[:nq], x[nq:]),
        "friction force and Jacobians as new arrays (FrictionModel.derivatives)": partial(
            snake.friction.derivatives, x[:nq], x[nq:]),
    }
    if baseline_derivatives is not None:
        routes[as_before] = partial(baseline_derivatives, x[:nq], x[nq:])
    samples = interleaved_samples(routes, budget=budget)
    rows = [[name, show(spread(values))] for name, values in samples.items()]
    if as_before in samples:
        rows.append([f"ratio: calc_derivatives against {FRICTION_JACOBIANS_BASELINE}'s "
                     "derivatives (per round)",
                     show(ratios(samples[into_data], samples[as_before]), 2)])
    table("MPC routes, us per call, median (10-90 %) of interleaved rounds",
          ["route", "us per call"], rows)
    problem = ocp.TrackingProblem(snake, 2).problem
    problem.nthreads = 2
    print(f"\nCrocoddyl's threads: ShootingProblem.nthreads stays {problem.nthreads} after "
          f"setting 2 (crocoddyl {crocoddyl.__version__}'s wheel is built without "
          "multithreading); the friction is a Python callback, which holds the GIL anyway.")


#: The benches that run the whole report or whole studies (minutes each): not in the
#: default set.
WHOLE_REPORT = ("reproduce", "failure_map", "study")

BENCHES: dict[str, Callable[[float], None]] = {"dynamics": bench_dynamics,
                                               "friction_routes": bench_friction_routes,
                                               "derivatives": bench_derivatives,
                                               "manipulability": bench_manipulability,
                                               "runs": bench_runs, "engine": bench_engine,
                                               "study": bench_study,
                                               "reproduce": bench_reproduce,
                                               "failure_map": bench_failure_map,
                                               "mpc": bench_mpc}
#: Not in the default set: the report, the studies, and the MPC's closed loop (minutes).
NOT_DEFAULT = (*WHOLE_REPORT, "mpc")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter timing batches")
    parser.add_argument("--only", default=",".join(n for n in BENCHES if n not in NOT_DEFAULT),
                        help="comma-separated benches (default all but reproduce, "
                        "failure_map and study, which run the whole report: quiet and with "
                        "the other core busy; with and without the failure map; and whole "
                        "studies; and mpc, seconds of the MPC's closed loop)")
    parser.add_argument("--baseline", default=None,
                        help=f"commit the runs, the engine and the study compare to "
                        f"(default: {BASELINE} for the runs and the engine, "
                        f"{STUDY_BASELINE} for the study)")
    parser.add_argument("--no-baseline", action="store_true",
                        help="skip the baseline columns of the runs, the engine and the study")
    parser.add_argument("--study-sizes", default=",".join(map(str, STUDY_SIZES)),
                        help="comma-separated run counts of --only study "
                        f"(default {','.join(map(str, STUDY_SIZES))})")
    parser.add_argument("--study-rounds", type=int, default=1,
                        help="interleaved rounds per study size (default 1)")
    args = parser.parse_args()
    budget = 0.05 if args.quick else 0.2
    names = [n for n in args.only.split(",") if n]
    unknown = [n for n in names if n not in BENCHES]
    if unknown:
        print(f"bench: unknown bench(es) {unknown}; choose from {list(BENCHES)}", file=sys.stderr)
        return 2
    try:
        sizes = tuple(int(n) for n in args.study_sizes.split(",") if n.strip())
    except ValueError:
        sizes = ()
    if not sizes or min(sizes) < 1 or args.study_rounds < 1:
        print("bench: --study-sizes takes positive run counts (e.g. 40,256) and "
              "--study-rounds a positive integer", file=sys.stderr)
        return 2
    start = time.perf_counter()
    print(f"# python scripts/bench.py {' '.join(sys.argv[1:])}".rstrip())
    print(f"(load average at start: {', '.join(f'{x:.2f}' for x in os.getloadavg())})")
    for name in names:
        if name in ("runs", "engine"):
            bench = bench_runs if name == "runs" else bench_engine
            bench(budget, None if args.no_baseline else args.baseline or BASELINE)
        elif name == "study":
            bench_study(budget, None if args.no_baseline else args.baseline or STUDY_BASELINE,
                        sizes, args.study_rounds)
        else:
            BENCHES[name](budget)
    print(f"\n(total {time.perf_counter() - start:.1f} s; load average at the end: "
          f"{', '.join(f'{x:.2f}' for x in os.getloadavg())})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
