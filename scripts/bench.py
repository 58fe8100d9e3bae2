#!/usr/bin/env python
"""Benchmarks of snake_pin's hot paths against the closed-form route, in one run.

Prints medians per call (timeit, several repeats) and the ratio closed-form / Pinocchio.
Usage: python scripts/bench.py [--quick] [--only dynamics,...]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import timeit
from collections.abc import Callable

import numpy as np

from snake_pin import Snake, SnakeParams, paper
from snake_pin.friction import FrictionModel, friction_forces


def median_us(fn: Callable[[], object], *, budget: float = 0.2, repeat: int = 7) -> float:
    """Median time per call in microseconds over ``repeat`` batches of ~``budget`` s."""
    number = max(1, int(budget / max(timeit.timeit(fn, number=3) / 3, 1e-7)))
    return statistics.median(timeit.repeat(fn, number=number, repeat=repeat)) / number * 1e6


def interleaved_us(fns: dict[str, Callable[[], object]], *, budget: float = 0.2,
                   rounds: int = 9) -> dict[str, tuple[float, float, float]]:
    """Median, 10th and 90th percentile us per call of each function, timed in interleaved
    rounds (A B C A B C ...) so that a neighbour's load hits every route alike."""
    numbers = {name: max(1, int(budget / rounds / max(timeit.timeit(fn, number=3) / 3, 1e-7)))
               for name, fn in fns.items()}
    samples: dict[str, list[float]] = {name: [] for name in fns}
    for _ in range(rounds):
        for name, fn in fns.items():
            samples[name].append(timeit.timeit(fn, number=numbers[name]) / numbers[name] * 1e6)
    out = {}
    for name, values in samples.items():
        deciles = statistics.quantiles(values, n=10)
        out[name] = (statistics.median(values), deciles[0], deciles[-1])
    return out


def table(title: str, header: list[str], rows: list[list[str]]) -> None:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print(f"\n## {title}\n")
    print("| " + " | ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print("| " + " | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) + " |")


def bench_dynamics(budget: float) -> None:
    """H, h and forward dynamics: Pinocchio path vs snake_pin.paper + numpy solve."""
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

            def fext_fd(q=q, dq=dq, tau=tau, snake=snake, params=params) -> np.ndarray:
                import pinocchio as pin

                fext = friction_forces(snake.model, snake.data, params, q, dq)
                return pin.aba(snake.model, snake.data, q, dq, snake.generalized_torque(tau),
                               fext)

            pairs = {
                "H": (lambda s=snake, q=q: s.inertia_matrix(q),
                      lambda p=params, q=q: paper.inertia_matrix(p, q)),
                "h": (lambda s=snake, q=q, dq=dq: s.bias(q, dq),
                      lambda p=params, q=q, dq=dq: paper.bias(p, q, dq)),
                "forward dynamics": (
                    lambda s=snake, q=q, dq=dq, t=tau: s.forward_dynamics(q, dq, t), closed_fd),
            }
            for name, (fast, slow) in pairs.items():
                if name == "H" and label != "iso":
                    continue  # H does not depend on friction
                t_fast, t_slow = median_us(fast, budget=budget), median_us(slow, budget=budget)
                route = ("twin" if not snake.friction.has_wheels else "wheeled twin") \
                    if snake.friction.uses_twin else "numpy"
                rows.append([str(n), name, f"{label} ({route})" if name != "H" else "-",
                             f"{t_fast:.1f}",
                             f"{t_slow:.1f}", f"{t_slow / t_fast:.1f}x"])
            if n == 10:
                t_ref = median_us(fext_fd, budget=budget)
                rows.append([str(n), "fwd dyn via pin.Force list (reference)", label,
                             f"{t_ref:.1f}", "-", "-"])
                numpy_route = FrictionModel(params)
                for route_label, route in (("twin", snake.friction), ("numpy", numpy_route)):
                    t_route = median_us(lambda f=route, q=q, dq=dq: f(q, dq), budget=budget)
                    rows.append([str(n), f"friction Q alone, {route_label} route", label,
                                 f"{t_route:.1f}", "-", "-"])
    table("Dynamics, median us per call", ["n", "quantity", "friction", "pinocchio [us]",
                                           "closed form [us]", "ratio"], rows)


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

            times = interleaved_us({
                "analytical": lambda s=snake, q=q, dq=dq, t=tau: s.dynamics_derivatives(q, dq, t),
                "central": central, "floor": floor}, budget=budget)
            (fast, f10, f90), (slow, s10, s90) = times["analytical"], times["central"]
            rows.append([str(n), label, f"{fast:.1f} ({f10:.1f}-{f90:.1f})",
                         f"{slow:.0f} ({s10:.0f}-{s90:.0f})", f"{slow / fast:.1f}x",
                         f"{times['floor'][0]:.1f}", f"{fast / times['floor'][0]:.1f}x"])
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
                                 c_y=(cy * scale).tolist())
        q = np.r_[0.1, -0.2, 0.3, rng.uniform(-1, 1, 9)]
        dq, tau = rng.normal(size=12), rng.normal(size=9)
        snakes = {"uniform": Snake(uniform), "per-link": Snake(hetero)}
        calls = {name: (lambda s=s, q=q, dq=dq, t=tau: s.forward_dynamics(q, dq, t))
                 for name, s in snakes.items()}
        times = interleaved_us(calls, budget=budget)
        per_link.append([label, f"{times['uniform'][0]:.1f}", f"{times['per-link'][0]:.1f}",
                         f"{times['per-link'][0] / times['uniform'][0]:.2f}"])
    table("Forward dynamics with friction at n = 10: per-link robot against uniform, median us",
          ["friction", "uniform (Table 1)", "per-link", "ratio"], per_link)


def closed_form_manipulability(params: SnakeParams, q: np.ndarray) -> tuple[float, float]:
    """D and R by the closed form: paper.inertia_matrix, Schur complement, numpy SVD."""
    h = paper.inertia_matrix(params, q)
    h11, h12, h22 = h[:3, :3], h[:3, 3:], h[3:, 3:]
    h22_inv = np.linalg.inv(h22)
    a = np.linalg.solve(h11 - h12 @ h22_inv @ h12.T, h12 @ h22_inv)
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
        fast = median_us(lambda s=snake, q=q: manipulability(s, q), budget=budget)
        fast5 = median_us(lambda s=snake, q=q: manipulability(s, q, free_joint=5), budget=budget)
        slow = median_us(lambda p=params, q=q: closed_form_manipulability(p, q), budget=budget)
        rows.append([str(n), "D and R, one posture", f"{fast:.1f} us", f"{slow:.1f} us",
                     f"{slow / fast:.1f}x"])
        rows.append([str(n), "D~ and R~ (joint 5 free)", f"{fast5:.1f} us", "-", "-"])
        phis = rng.uniform(-1.5, 1.5, (100_000, n - 1))
        times = []
        for _ in range(5):
            start = time.perf_counter()
            manipulability_R_batch(params, phis)
            times.append(time.perf_counter() - start)
        rate = len(phis) / statistics.median(times)
        single_rate = 1e6 / slow
        rows.append([str(n), "R batch (100k postures)", f"{rate:,.0f} /s",
                     f"{single_rate:,.0f} /s", f"{rate / single_rate:.0f}x"])
    table("Manipulability", ["n", "quantity", "snake_pin", "closed form", "ratio"], rows)


def _timed_run(fn: Callable[[], object], repeat: int) -> tuple[float, object]:
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def bench_runs(budget: float) -> None:
    """Closed-loop runs at 1 kHz control (RK4, dt = 1 ms): wall time and real-time factor."""
    from snake_pin.control import LyapunovController, PFLController
    from snake_pin.experiments import pfl, tracking
    from snake_pin.sim import simulate

    repeat = 1 if budget < 0.1 else 3
    rows, floor_rows = [], []
    cases = [
        ("PFL, VI.1 to breakdown (isotropic)", SnakeParams.table1(), 10.0, "pfl"),
        ("PFL, 20 s, c_y = 10 c_x", SnakeParams.table1(c_y=5.0), 20.0, "pfl"),
        ("Lyapunov-like, 60 s", tracking.tracking_params(), 60.0, "lyapunov"),
        ("Lyapunov-like, 60 s, joint 5 passive", tracking.tracking_params(passive=(5,)), 60.0,
         "lyapunov"),
    ]
    for label, params, t_final, kind in cases:
        snake = Snake(params)
        if kind == "pfl":
            ctrl, x0 = PFLController(snake), pfl.initial_state(params)
        else:
            ctrl, x0 = LyapunovController(snake), tracking.initial_state(params)
        wall, traj = _timed_run(lambda s=snake, c=ctrl, x=x0, t=t_final: simulate(s, c, x, t),
                                repeat)
        rows.append([label, f"{traj.t_end:.2f}", f"{wall:.2f}", f"{traj.t_end / wall:.1f}x",
                     f"{wall / max(len(traj) - 1, 1) * 1e6:.0f}"])
        controller_us, dynamics_us = _step_pieces(snake, ctrl, traj, budget)
        floor = controller_us + 3 * dynamics_us
        floor_rows.append([label, f"{controller_us:.1f}", f"{dynamics_us:.1f}", f"{floor:.0f}",
                           f"{1e3 / floor:.1f}x"])
    table("Closed-loop runs (simulate only, no post-processing)",
          ["run", "simulated [s]", "wall [s]", "real-time factor", "us per 1 ms step"], rows)
    table("Per-step floor of RK4 at 1 kHz: the controller plus three new dynamics evaluations",
          ["run", "controller [us]", "dynamics eval [us]", "floor [us/step]",
           "best real-time factor"], floor_rows)


def _step_pieces(snake: Snake, ctrl: object, traj: object, budget: float) -> tuple[float, float]:
    """Median us of one controller call and one dynamics evaluation on states of ``traj``
    (a new state each call, so no cache is hit)."""
    states = np.hstack((traj.q, traj.dq))[:: max(1, len(traj) // 64)]
    taus = traj.tau[:: max(1, len(traj) // 64)]
    count = len(states)
    k = iter(range(1 << 62))

    def control() -> object:
        i = next(k) % count
        return ctrl(states[i], 0.5)

    def dynamics() -> object:
        i = next(k) % count
        return snake.state_derivative(states[i], taus[i])

    return median_us(control, budget=budget), median_us(dynamics, budget=budget)


def bench_engine(budget: float) -> None:
    """The 60 s MuJoCo run (control at 1 kHz, two 0.5 ms engine steps per period).

    Also times MuJoCo alone: the recorded torques replayed open loop (no controller, no
    filter), the ceiling any controller code leaves.
    """
    import mujoco

    from snake_pin.engine.model import WheelSpec, build_engine_model
    from snake_pin.engine.run import identify_friction, run_engine
    from snake_pin.experiments.engine import summarize

    repeat = 1 if budget < 0.1 else 3
    rows = []
    for cone in ("elliptic", "pyramidal"):
        wheels = WheelSpec(cone=cone)
        friction = identify_friction(wheels=wheels)
        for label, params in (("60 s", SnakeParams.engine()),
                              ("60 s, joint 5 passive", SnakeParams.engine(passive=(5,)))):
            wall, run = _timed_run(lambda p=params, w=wheels, f=friction: run_engine(
                p, wheels=w, t_final=60.0, friction=f), repeat)
            traj = run.trajectory
            engine = build_engine_model(params, wheels)

            def replay(engine=engine, traj=traj) -> None:
                engine.set_paper_configuration(traj.q[0])
                for tau in traj.tau[:-1]:
                    engine.apply_torque(tau)
                    for _ in range(engine.wheels.substeps):
                        mujoco.mj_step(engine.model, engine.data)

            alone, _ = _timed_run(replay, 1)
            relative = summarize(traj)["rms_relative"]
            rows.append([f"{cone}, {label}", f"{traj.t_end:.1f}", f"{wall:.2f}",
                         f"{traj.t_end / wall:.1f}x", f"{traj.t_end / alone:.1f}x",
                         f"{100 * relative:.1f}"])
    table("MuJoCo closed loop", ["run", "simulated [s]", "wall [s]", "real-time factor",
                                 "MuJoCo alone", "RMS % of body"], rows)


BENCHES: dict[str, Callable[[float], None]] = {"dynamics": bench_dynamics,
                                               "derivatives": bench_derivatives,
                                               "manipulability": bench_manipulability,
                                               "runs": bench_runs, "engine": bench_engine}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="shorter timing batches")
    parser.add_argument("--only", default=",".join(BENCHES), help="comma-separated benches")
    args = parser.parse_args()
    budget = 0.05 if args.quick else 0.2
    names = [n for n in args.only.split(",") if n]
    unknown = [n for n in names if n not in BENCHES]
    if unknown:
        print(f"bench: unknown bench(es) {unknown}; choose from {list(BENCHES)}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    for name in names:
        BENCHES[name](budget)
    print(f"\n(total {time.perf_counter() - start:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
