#!/usr/bin/env python
"""Record the end states of the reference closed-loop runs into tests/data/speed_baseline.npz.

The runs are those ``tests/test_speed_equivalence.py`` checks the fast simulator against:
the 60 s Lyapunov-like tracking runs (every joint actuated; joint 5 passive) and the
Section VI.1 PFL run (10 s asked for; it diverges at its breakdown, near 3.9 s). For each,
the file holds the final q, dq and t_end (keys ``<run>_q``, ``<run>_dq``, ``<run>_t_end``)
and the source it was made with (``source``).

The fixture was made once, before the speed work of issue 13, from commit e8edb99:

    python scripts/record_speed_fixture.py

Record from another checkout (e.g. the dc0b889 baseline) by putting it first on the path:

    git worktree add /tmp/snake_pin_dc0b889 dc0b889
    PYTHONPATH=/tmp/snake_pin_dc0b889 python scripts/record_speed_fixture.py -o OUT.npz

Only the public API is used (tracking_params, initial_state, the controllers, simulate),
so the script runs on both.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

DEFAULT = Path(__file__).resolve().parents[1] / "tests" / "data" / "speed_baseline.npz"

#: name -> (controller, passive joints, t_final [s])
RUNS = {"lyapunov": ("lyapunov", (), 60.0), "lyapunov_passive5": ("lyapunov", (5,), 60.0),
        "pfl_vi1": ("pfl", (), 10.0)}


def run(name: str):
    """The trajectory of run ``name`` (see :data:`RUNS`) with the importable snake_pin."""
    from snake_pin import Snake, SnakeParams
    from snake_pin.control import LyapunovController, PFLController
    from snake_pin.experiments import pfl, tracking
    from snake_pin.sim import simulate

    kind, passive, t_final = RUNS[name]
    if kind == "pfl":
        params = SnakeParams.table1()
        snake = Snake(params)
        return simulate(snake, PFLController(snake), pfl.initial_state(params), t_final)
    params = tracking.tracking_params(passive=passive) if passive else tracking.tracking_params()
    snake = Snake(params)
    return simulate(snake, LyapunovController(snake), tracking.initial_state(params), t_final)


def _source() -> str:
    import snake_pin

    folder = Path(snake_pin.__file__).resolve().parents[1]
    try:
        commit = subprocess.run(["git", "-C", str(folder), "rev-parse", "--short", "HEAD"],
                                capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown commit"
    return f"snake_pin at {folder} ({commit})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=DEFAULT, help="the .npz to write")
    args = parser.parse_args()
    arrays: dict[str, np.ndarray] = {"source": np.array(_source())}
    for name in RUNS:
        traj = run(name)
        arrays[f"{name}_q"] = traj.q[-1]
        arrays[f"{name}_dq"] = traj.dq[-1]
        arrays[f"{name}_t_end"] = np.array(traj.t_end)
        print(f"{name}: t_end = {traj.t_end:.3f} s, |dq|max = {np.abs(traj.dq[-1]).max():.3g}")
    np.savez(args.output, **arrays)  # type: ignore[arg-type]  # a **dict might hold allow_pickle
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
