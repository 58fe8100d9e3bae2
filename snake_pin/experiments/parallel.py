"""Run independent experiment jobs on the machine's cores (processes, not threads).

The workers never outlive the run: on Linux each asks the kernel for SIGTERM when the
process that started it dies (``PR_SET_PDEATHSIG``, so even a ``kill -9`` of the parent
takes them along), they ignore SIGINT (Ctrl-C in a terminal reaches the whole process
group; the parent decides) and die on SIGTERM and SIGHUP. When the parent is interrupted
while it waits (KeyboardInterrupt, which ``snake-pin`` also raises for SIGTERM and SIGHUP)
or a job fails, the pool is terminated: pending jobs are dropped and running workers
killed before the exception goes on.

Every job runs with BLAS and OpenMP thread pools limited to one thread
(``threadpoolctl.threadpool_limits(1)``, in a worker or in the calling process alike):
the jobs are small-matrix work (n + 2 square), the pool already uses every core, and
multi-threaded BLAS on such matrices spins against the other jobs. Workers also get
``OMP_WAIT_POLICY=PASSIVE`` in their environment, so an OpenMP runtime they start (or a
process they spawn) sleeps instead of spinning while it waits (with a busy neighbour
on the other core, spinning OpenMP threads ran 5-10x slower). An OpenMP runtime already
loaded in the parent before the fork keeps its policy; the thread limit still holds.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from typing import Any

from threadpoolctl import threadpool_limits

__all__ = ["iter_jobs", "run_jobs"]

Job = tuple[Callable[..., Any], tuple[Any, ...], dict[str, Any]]

#: ``PR_SET_PDEATHSIG`` of <linux/prctl.h>.
_PR_SET_PDEATHSIG = 1


def _die_with_parent(parent: int | None) -> None:
    """Pool initializer: default SIGTERM/SIGHUP, no SIGINT, SIGTERM when the parent dies.

    ``parent`` is the pid the worker was forked from (None when the start method does
    not fork from us): if it is already gone, the worker leaves at once.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL)
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):  # no prctl: the parent's terminate() still works
            pass
    if parent is not None and os.getppid() != parent:
        os._exit(1)  # the parent died before the death signal was armed
    os.environ["OMP_WAIT_POLICY"] = "PASSIVE"


def _limited(fn: Callable[..., Any], args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
    """``fn(*args, **kwargs)`` with BLAS/OpenMP limited to one thread."""
    with threadpool_limits(limits=1):
        return fn(*args, **kwargs)


def _indexed(item: tuple[int, Job]) -> tuple[int, Any]:
    index, (fn, args, kwargs) = item
    return index, _limited(fn, args, kwargs)


def iter_jobs(jobs: Sequence[Job], workers: int | None = None) -> Iterator[tuple[int, Any]]:
    """``(index, fn(*args, **kwargs))`` of each job as it finishes, on up to ``workers`` cores.

    Parameters
    ----------
    jobs
        ``(fn, args, kwargs)`` triples. Each job builds its own models in its process;
        functions and results must be picklable (the package's dataclasses and arrays are).
    workers
        Processes to use (default: as many as jobs, at most the number of cores). With
        one worker or one job, the jobs run here, in order.

    Yields
    ------
    tuple of (int, Any)
        The job's index in ``jobs`` and its result, in the order the jobs finish: a
        caller keeps what finished when a later job fails or the run is interrupted.

    Raises
    ------
    BaseException
        An exception of a job, a KeyboardInterrupt while waiting, or the caller closing
        the iterator early: the pool's workers are terminated first.
    """
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    if workers <= 1 or len(jobs) <= 1:
        for index, (fn, args, kwargs) in enumerate(jobs):
            yield index, _limited(fn, args, kwargs)
        return
    context = multiprocessing.get_context()
    parent = os.getpid() if context.get_start_method() == "fork" else None
    pool = context.Pool(processes=workers, initializer=_die_with_parent, initargs=(parent,))
    try:
        yield from pool.imap_unordered(_indexed, list(enumerate(jobs)))
    except BaseException:
        pool.terminate()
        pool.join()
        raise
    pool.close()
    pool.join()


def run_jobs(jobs: Sequence[Job], workers: int | None = None) -> list[Any]:
    """Results of ``fn(*args, **kwargs)`` for each job, in order, on up to ``workers`` cores.

    Each job builds its own models in its process; results must be picklable (the
    package's dataclasses and arrays are). An exception of a job, or a KeyboardInterrupt
    while waiting, terminates the pool's workers and is raised again (see
    :func:`iter_jobs`).

    Parameters
    ----------
    jobs
        ``(fn, args, kwargs)`` triples.
    workers
        Processes to use (default: as many as jobs, at most the number of cores).

    Returns
    -------
    list
        The jobs' results, in the order of ``jobs``.
    """
    results: list[Any] = [None] * len(jobs)
    for index, result in iter_jobs(jobs, workers):
        results[index] = result
    return results
