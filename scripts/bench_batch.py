#!/usr/bin/env python
"""Benchmark of the lockstep batch (snake_pin.batch) against single runs, in one run.

Lyapunov-like tracking runs of the Table 1 robot (n = 10, RK4 at dt = control_dt = 1 ms):

* baseline: one run through ``simulate`` of commit dc0b889 (the code as issue 14 was
  filed), from a checkout outside the repository (``git worktree add
  /tmp/snake_pin_dc0b889 dc0b889`` if it is missing), in a subprocess with PYTHONPATH set;
* today's ``simulate`` in a subprocess likewise (for reference);
* ``simulate_batch`` at B = 1, 8, 64, 256, 1024 in this process (per-run friction c_y in
  {10, 25, 50, 100} x c_x; ``--passive`` adds one failed joint per run, cycling 0..9).

Each round runs every case once, interleaved (baseline, B = 1, 8, ..., current), so a
neighbour's load hits them alike; the tables give medians and 10-90 % over the rounds of
simulated seconds per wall second, us per robot-step (one 1 ms control step of one run)
and the ratio to the baseline's median of the same rounds. A second table times the
model terms of the laws per robot: the batched closed form against a loop over runs
calling Pinocchio (CRBA + computeMinverse + RNEA), and the two forward-dynamics routes.

Usage: python scripts/bench_batch.py [--rounds 5] [--quick] [--passive]
       [--batches 1,8,64,256,1024] [--dynamics closed_form,aba]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # before Pinocchio's OpenMP starts

import numpy as np
from threadpoolctl import threadpool_limits

REPO = Path(__file__).resolve().parents[1]
BASELINE_COMMIT = "dc0b889"
BASELINE_TREE = Path("/tmp/snake_pin_dc0b889")
FRICTION_RATIOS = (10.0, 25.0, 50.0, 100.0)

_SINGLE = """
import sys, time
from threadpoolctl import threadpool_limits
from snake_pin import Snake, simulate
from snake_pin.control import LyapunovController
from snake_pin.experiments.tracking import initial_state, tracking_params
params = tracking_params(passive={passive})
snake = Snake(params)
controller = LyapunovController(snake)
x0 = initial_state(params)
simulate(snake, LyapunovController(snake), x0, 0.05)  # warm up
start = time.perf_counter()
traj = simulate(snake, controller, x0, {t_final})
print(traj.t_end / (time.perf_counter() - start))
"""


def baseline_tree() -> Path:
    """The dc0b889 checkout (made with git worktree if missing)."""
    if not (BASELINE_TREE / "snake_pin" / "__init__.py").is_file():
        subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach",
                        str(BASELINE_TREE), BASELINE_COMMIT], check=True,
                       stdout=subprocess.DEVNULL)
    return BASELINE_TREE


def single_rate(tree: Path, t_final: float, passive: bool) -> float:
    """Simulated seconds per wall second of one ``simulate`` run of the code in ``tree``."""
    code = _SINGLE.format(t_final=t_final, passive="(5,)" if passive else "()")
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run([sys.executable, "-c", code], env=env, check=True,
                         capture_output=True, text=True, cwd="/tmp")
    return float(out.stdout.strip().splitlines()[-1])


def batch_runs(size: int, passive: bool):
    """Robots, controllers and initial states of ``size`` tracking runs."""
    from snake_pin import Snake, SnakeParams
    from snake_pin.control import LyapunovController
    from snake_pin.experiments.tracking import initial_state, tracking_params

    robots: list[SnakeParams] = []
    snakes: dict[SnakeParams, Snake] = {}
    for b in range(size):
        failed = (b % 10,) if passive and b % 10 else ()
        params = tracking_params(c_y=0.5 * FRICTION_RATIOS[b % len(FRICTION_RATIOS)],
                                 passive=failed)
        robots.append(params)
        snakes.setdefault(params, Snake(params))
    controllers = [LyapunovController(snakes[p]) for p in robots]
    return robots, controllers, [initial_state(p) for p in robots]


def batch_rate(size: int, t_final: float, passive: bool, dynamics: str) -> float:
    """Simulated seconds per wall second of ``size`` runs in one lockstep batch."""
    from snake_pin.batch import simulate_batch

    robots, controllers, x0s = batch_runs(size, passive)
    stride = max(1, round(t_final / 1e-3))  # keep the first and last samples only
    start = time.perf_counter()
    result = simulate_batch(robots, controllers, x0s, t_final, stride=stride,
                            dynamics=dynamics)
    wall = time.perf_counter() - start
    return float(result.last_t.sum()) / wall


def spread(values: list[float]) -> tuple[float, float, float]:
    """Median, 10th and 90th percentile."""
    if len(values) < 2:
        return values[0], values[0], values[0]
    deciles = statistics.quantiles(values, n=10, method="inclusive")
    return statistics.median(values), deciles[0], deciles[-1]


def table(title: str, header: list[str], rows: list[list[str]]) -> None:
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print(f"\n## {title}\n")
    print("| " + " | ".join(h.ljust(w) for h, w in zip(header, widths, strict=True)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print("| " + " | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) + " |")


def bench_rates(rounds: int, sizes: list[int], budget: float, passive: bool,
                routes: list[str]) -> None:
    tree = baseline_tree()
    cases: list[tuple[str, int | None, str | None]] = [
        ("simulate @ dc0b889", None, None), ("simulate (this tree)", None, None)]
    cases += [(f"batch B = {b}" + (f", {r}" if len(routes) > 1 else ""), b, r)
              for r in routes for b in sizes]
    samples: dict[str, list[float]] = {label: [] for label, _, _ in cases}
    single_t = 2.0 * budget
    for round_index in range(rounds):
        for label, size, route in cases:
            if size is None or route is None:  # the single runs (a batch has both)
                where = tree if "dc0b889" in label else REPO
                samples[label].append(single_rate(where, single_t, passive))
            else:
                # about `budget` wall seconds per case at ~50 simulated s per wall s
                t_final = min(10.0, max(0.02, round(50.0 * budget / size, 3)))
                samples[label].append(batch_rate(size, t_final, passive, route))
        print(f"round {round_index + 1}/{rounds} done", file=sys.stderr, flush=True)
    base = statistics.median(samples["simulate @ dc0b889"])
    rows = []
    for label, _, _ in cases:
        median, low, high = spread(samples[label])
        rows.append([label, f"{median:.1f}", f"{low:.1f}-{high:.1f}",
                     f"{1e3 / median:.1f}", f"{median / base:.1f}x"])
    what = "one failed joint per run (cycling)" if passive else "all joints actuated"
    table(f"Lyapunov-like tracking, n = 10, {what}; {rounds} interleaved rounds",
          ["case", "sim-s per wall-s", "10-90 %", "us per robot-step", "vs dc0b889"], rows)


def bench_terms(budget: float) -> None:
    """Model terms per robot: batched closed form vs a loop of Pinocchio calls."""
    rows = []
    for size in (64, 256, 1024):
        rows += _terms_rows(size, budget)
    table("Model terms per robot (best of 5)", ["B", "what", "us per robot"], rows)


def _terms_rows(size: int, budget: float) -> list[list[str]]:
    import timeit

    import pinocchio as pin

    from snake_pin import Snake
    from snake_pin.control.batched import BatchTerms, FrictionCoefficients
    from snake_pin.experiments.tracking import tracking_params
    from snake_pin.model import paper_model

    params = tracking_params()
    snake = Snake(params)
    rng = np.random.default_rng(1)
    x = np.hstack((rng.normal(size=(size, 2)), np.pi + rng.normal(scale=0.3, size=(size, 1)),
                   rng.uniform(-1, 1, (size, 9)), rng.normal(size=(size, 12))))
    tau = rng.normal(size=(size, 9))
    terms, coeffs = BatchTerms(params), FrictionCoefficients([params] * size)
    pool = pin.ModelPool(paper_model(params), 1)
    model, data = snake.model, snake.data

    def closed_terms() -> object:
        fresh = x.copy()  # a new state array: no cached terms
        return terms.inertia(fresh), terms.bias(fresh, coeffs)

    def pinocchio_terms() -> object:
        out = []
        for row in x:
            q, v = row[:12], row[12:]
            out.append((pin.computeMinverse(model, data, q),
                        pin.nonLinearEffects(model, data, q, v) - snake.friction(q, v)))
        return out

    def closed_dynamics() -> object:
        return terms.forward_dynamics(x.copy(), coeffs, tau)

    def aba_dynamics() -> object:
        fresh = x.copy()
        force = terms.friction(fresh, coeffs).copy()
        force[:, 3:] += tau
        out = np.empty((12, size), order="F")
        pin.abaInParallel(1, pool, fresh[:, :12].T, fresh[:, 12:].T, force.T, out)
        return out

    rows = []
    for label, fn in (("H, h: closed form (batched)", closed_terms),
                      ("H^-1, h: Pinocchio loop (computeMinverse, RNEA, friction)",
                       pinocchio_terms),
                      ("q'': closed form, batched n x n solve", closed_dynamics),
                      ("q'': abaInParallel + numpy friction", aba_dynamics)):
        number = max(1, int(budget / max(timeit.timeit(fn, number=1), 1e-6)))
        best = min(timeit.repeat(fn, number=number, repeat=5)) / number
        rows.append([str(size), label, f"{best / size * 1e6:.2f}"])
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds")
    parser.add_argument("--quick", action="store_true", help="shorter cases")
    parser.add_argument("--passive", action="store_true",
                        help="one failed joint per run (and joint 5 in the single runs)")
    parser.add_argument("--batches", default="1,8,64,256,1024", help="batch sizes")
    parser.add_argument("--dynamics", default="closed_form",
                        help="forward-dynamics routes of the batch: closed_form,aba")
    args = parser.parse_args()
    sizes = [int(b) for b in args.batches.split(",") if b]
    routes = [r for r in args.dynamics.split(",") if r]
    budget = 1.0 if args.quick else 3.0
    start = time.perf_counter()
    with threadpool_limits(limits=1):  # one BLAS thread: the batches' matrices are tiny
        bench_rates(args.rounds, sizes, budget, args.passive, routes)
        bench_terms(0.05 if args.quick else 0.2)
    print(f"\n(total {time.perf_counter() - start:.1f} s; load average at the end "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
