"""Run independent jobs (the report's stages, bench-control, engine seeds) on the package's
one executor: the local Dask cluster of :func:`snake_pin.study.runner.dask_client`, for one
call or for a :class:`SharedCluster` block, one BLAS thread per job (:doc:`/architecture`).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from threadpoolctl import threadpool_limits

__all__ = ["SharedCluster", "run_jobs"]

Job = tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]


def _limited(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    """``fn(*args, **kwargs)`` with BLAS/OpenMP limited to one thread."""
    with threadpool_limits(limits=1):
        return fn(*args, **kwargs)


class SharedCluster:
    """One local Dask cluster for every call of :func:`run_jobs` in a ``with`` block,
    started on the first call that needs one, closed with its workers when the block ends.

    Parameters
    ----------
    workers
        Worker processes (default: the number of cores).
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        self._stack = contextlib.ExitStack()
        self._client: Any = None

    def client(self) -> Any:
        """The cluster's client, the cluster started on the first call.

        Returns
        -------
        distributed.Client
            The client.
        """
        if self._client is None:
            from ..study.runner import dask_client

            self._client = self._stack.enter_context(dask_client(None, self.workers))
        return self._client

    def __enter__(self) -> SharedCluster:
        return self

    def __exit__(self, *exc: Any) -> bool:
        # interrupted, the cluster's context kills the workers without waiting for their task
        return bool(self._stack.__exit__(*exc))


def iter_jobs(jobs: Sequence[Job], workers: int | None = None, *,
              cluster: SharedCluster | None = None) -> Iterator[tuple[int, Any]]:
    """``(index, result)`` of each job as it finishes (:func:`run_jobs`; with one worker or
    one job they run here); a job's exception, an interrupt or an early close cancels the
    pending jobs and kills the workers first."""
    workers = cluster.workers if cluster is not None else \
        workers or min(len(jobs), os.cpu_count() or 1)
    if workers <= 1 or len(jobs) <= 1:
        for index, (fn, args, kwargs) in enumerate(jobs):
            yield index, _limited(fn, args, kwargs)
        return
    from distributed import as_completed

    from ..study.runner import dask_client

    with (contextlib.nullcontext(cluster.client()) if cluster is not None
          else dask_client(None, workers)) as client:
        futures = {client.submit(_limited, fn, args, kwargs, pure=False): index
                   for index, (fn, args, kwargs) in enumerate(jobs)}
        try:
            for future in as_completed(list(futures), loop=client.loop):
                yield futures[future], future.result()
                future.release()
        except BaseException:
            with contextlib.suppress(Exception):
                client.cancel(list(futures), force=True)
            raise


def run_jobs(jobs: Sequence[Job], workers: int | None = None, *,
             cluster: SharedCluster | None = None) -> list[Any]:
    """Results of ``fn(*args, **kwargs)`` for each job, in order; a job's exception cancels
    the others and kills the workers.

    Parameters
    ----------
    jobs
        ``(fn, args, kwargs)`` triples (picklable).
    workers
        Worker processes (default: as many as jobs, at most the number of cores; with
        ``cluster``, its workers).
    cluster
        A cluster shared with other calls; None: one started for this call.

    Returns
    -------
    list
        The jobs' results, in the order of ``jobs``.
    """
    results: list[Any] = [None] * len(jobs)
    for index, result in iter_jobs(jobs, workers, cluster=cluster):
        results[index] = result
    return results
