"""The executor's jobs under their former module path: :mod:`snake_pin.runs.parallel`."""

from ..runs.parallel import iter_jobs, run_jobs

__all__ = ["iter_jobs", "run_jobs"]
