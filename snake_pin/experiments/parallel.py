"""Run independent experiment jobs on the machine's cores (processes, not threads)."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

__all__ = ["run_jobs"]

Job = tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]


def run_jobs(jobs: Sequence[Job], workers: int | None = None) -> list[Any]:
    """Results of ``fn(*args, **kwargs)`` for each job, in order, on up to ``workers`` cores.

    Each job builds its own models in its process; results must be picklable (the
    package's dataclasses and arrays are).
    """
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    if workers <= 1 or len(jobs) <= 1:
        return [fn(*args, **kwargs) for fn, args, kwargs in jobs]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(fn, *args, **kwargs) for fn, args, kwargs in jobs]
        return [future.result() for future in futures]
