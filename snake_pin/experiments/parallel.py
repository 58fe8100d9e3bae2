"""The executor's jobs of :mod:`snake_pin.runs.parallel`, importable by this name too
(scripts/bench.py imports them here)."""

from ..runs.parallel import iter_jobs, run_jobs

__all__ = ["iter_jobs", "run_jobs"]
