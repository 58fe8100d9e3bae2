"""Run independent experiment jobs on the machine's cores (processes, not threads).

The workers never outlive the run: on Linux each asks the kernel for SIGTERM when the
process that started it dies (``PR_SET_PDEATHSIG``, so even a ``kill -9`` of the parent
takes them along), they ignore SIGINT (Ctrl-C in a terminal reaches the whole process
group; the parent decides) and die on SIGTERM and SIGHUP. When the parent is interrupted
while it waits (KeyboardInterrupt, which ``snake-pin`` also raises for SIGTERM and SIGHUP)
or a job fails, the pool is terminated: pending jobs are dropped and running workers
killed before the exception goes on.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any

__all__ = ["run_jobs"]

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


def run_jobs(jobs: Sequence[Job], workers: int | None = None) -> list[Any]:
    """Results of ``fn(*args, **kwargs)`` for each job, in order, on up to ``workers`` cores.

    Each job builds its own models in its process; results must be picklable (the
    package's dataclasses and arrays are). An exception of a job, or a KeyboardInterrupt
    while waiting, terminates the pool's workers and is raised again.
    """
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    if workers <= 1 or len(jobs) <= 1:
        return [fn(*args, **kwargs) for fn, args, kwargs in jobs]
    context = multiprocessing.get_context()
    parent = os.getpid() if context.get_start_method() == "fork" else None
    pool = context.Pool(processes=workers, initializer=_die_with_parent, initargs=(parent,))
    try:
        pending = [pool.apply_async(fn, args, kwargs) for fn, args, kwargs in jobs]
        results = [result.get() for result in pending]
    except BaseException:
        pool.terminate()
        pool.join()
        raise
    pool.close()
    pool.join()
    return results
