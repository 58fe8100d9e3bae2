"""Run independent jobs on Dask: the report's stages, bench-control, engine seeds.

The package has one executor: these jobs go to the same local Dask cluster a study runs
on, built by the study runner (:func:`snake_pin.study.runner.dask_client` on a local cluster:
one worker process per core with one thread each, everything on 127.0.0.1 and TLS with
credentials made for the call, workers started with ``OMP_WAIT_POLICY=PASSIVE`` and
one-thread BLAS/OpenMP). The cluster lives for one call, or for the block of a
:class:`SharedCluster` that several calls share (the report: one cluster for its stages).
It is closed, and its worker processes with it, when the jobs (or the block) are done,
when a job raises, when the caller is interrupted while it waits (KeyboardInterrupt, which
``snake-pin`` also raises for SIGTERM and SIGHUP: the pending jobs are cancelled and the
workers killed before the exception goes on) or when the caller closes the iterator
early. Worker processes also leave when the process that started them dies (Dask's nanny
pipe).

With one worker or one job the jobs run here, in order, without a cluster. Every job, in
a worker or here, runs with BLAS and OpenMP thread pools limited to one thread
(``threadpoolctl.threadpool_limits(1)``): the jobs are small-matrix work and the cluster
already uses every core.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from threadpoolctl import threadpool_limits

__all__ = ["SharedCluster", "iter_jobs", "run_jobs"]

Job = tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]


def _limited(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    """``fn(*args, **kwargs)`` with BLAS/OpenMP limited to one thread."""
    with threadpool_limits(limits=1):
        return fn(*args, **kwargs)


class SharedCluster:
    """One local Dask cluster for every call of :func:`run_jobs` in a ``with`` block.

    The cluster starts on the first call that needs one (none for a block whose calls all
    run here) and closes with its workers when the block ends, however it ends.

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
            The client of the block's local cluster.
        """
        if self._client is None:
            from ..study.runner import dask_client

            self._client = self._stack.enter_context(dask_client(None, self.workers))
        return self._client

    def __enter__(self) -> SharedCluster:
        return self

    def __exit__(self, *exc: Any) -> bool:
        # the exception goes to the cluster's context: interrupted, it kills the workers
        # without waiting for their running task
        return bool(self._stack.__exit__(*exc))


def iter_jobs(jobs: Sequence[Job], workers: int | None = None, *,
              cluster: SharedCluster | None = None) -> Iterator[tuple[int, Any]]:
    """``(index, fn(*args, **kwargs))`` of each job as it finishes, on up to ``workers`` cores.

    Parameters
    ----------
    jobs
        ``(fn, args, kwargs)`` triples. Each job builds its own models in its worker;
        functions, arguments and results must pickle (Dask's cloudpickle: the package's
        dataclasses and arrays do).
    workers
        Worker processes of the local Dask cluster (default: as many as jobs, at most the
        number of cores; with ``cluster``, its workers). With one worker or one job, the
        jobs run here, in order.
    cluster
        A cluster shared with other calls; None: one started for this call.

    Yields
    ------
    tuple of (int, Any)
        The job's index in ``jobs`` and its result, in the order the jobs finish: a
        caller keeps what finished when a later job fails or the run is interrupted.

    Raises
    ------
    BaseException
        An exception of a job, a KeyboardInterrupt while waiting, or the caller closing
        the iterator early: the pending jobs are cancelled and the cluster's workers
        killed first.
    """
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
    """Results of ``fn(*args, **kwargs)`` for each job, in order, on up to ``workers`` cores.

    An exception of a job, or a KeyboardInterrupt while waiting, cancels the other jobs,
    closes the cluster and is raised again (see :func:`iter_jobs`).

    Parameters
    ----------
    jobs
        ``(fn, args, kwargs)`` triples (picklable; see :func:`iter_jobs`).
    workers
        Worker processes (default: as many as jobs, at most the number of cores).
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
