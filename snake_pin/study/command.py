"""The ``snake-pin study`` subcommand: its options and handler, for the CLI to mount.

A bad study file, folder, scheduler or security file is a
:class:`~snake_pin.study.errors.StudyError` (one line, exit 2, nothing run).
"""

from __future__ import annotations

import argparse
import functools
import sys
from typing import Any

from .._validation import float_arg, int_arg
from ..exceptions import RunInterrupted
from .errors import StudyError
from .runner import CONNECT_TIMEOUT, MAX_CONNECT_TIMEOUT, MAX_WORKERS, run_study

__all__: list[str] = []

_DESCRIPTION = """\
Run every run a study file describes on Dask, one Parquet row per run in DIR/runs, the page
in DIR/index.html, the summary in DIR/summary.json; runs already recorded are not run again
(after an interrupt, run the same command to finish). By default a local TLS cluster on
127.0.0.1; --scheduler uses an existing one (documentation: Concepts, Studies)."""


def add_study_parser(subparsers: Any, *, outcome: Any, interrupted_status: int = 130,
                     failed_status: int = 3) -> argparse.ArgumentParser:
    """Add the ``study`` subcommand to the CLI's ``subparsers``; its handler returns an
    ``outcome(payload=, text=, status=, note=)`` and is set as ``func``."""
    p = subparsers.add_parser("study", help="run a study (grids and random samples of runs) "
                              "on Dask, resumable", description=_DESCRIPTION)
    p.add_argument("study", metavar="STUDY.toml", help="the study file")
    p.add_argument("-o", "--output", required=True, metavar="DIR",
                   help="output folder (re-run the same command to finish an interrupted study)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="tcp://HOST:PORT or tls://HOST:PORT of an existing Dask scheduler "
                   "(default: a local cluster on 127.0.0.1, authenticated by TLS)")
    p.add_argument("--security", metavar="FILE",
                   help="with --scheduler: the cluster's TLS credentials, a YAML file of "
                   "Dask config (distributed.comm.tls.ca-file, client.cert, client.key; "
                   "default: Dask's own config)")
    p.add_argument("--connect-timeout", type=float_arg(0.0, MAX_CONNECT_TIMEOUT, open_low=True),
                   default=CONNECT_TIMEOUT, metavar="SECONDS",
                   help="longest wait for the scheduler to complete Dask's handshake "
                   f"(default {CONNECT_TIMEOUT:g})")
    p.add_argument("--workers", type=int_arg(1, MAX_WORKERS), metavar="N",
                   help=f"local worker processes, 1..{MAX_WORKERS} (default: one per core)")
    p.add_argument("--dashboard", action="store_true",
                   help="serve the local cluster's Dask dashboard on 127.0.0.1 (a random "
                   "port, printed on stderr); off by default")
    p.add_argument("--verbose", action="store_true",
                   help="log on stderr even when it is not a terminal")
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=functools.partial(_cmd_study, outcome=outcome,
                                          interrupted_status=interrupted_status,
                                          failed_status=failed_status))
    return p


def _log(message: str) -> None:
    print(f"snake-pin: {message}", file=sys.stderr, flush=True)


def _cmd_study(args: argparse.Namespace, *, outcome: Any, interrupted_status: int,
               failed_status: int) -> Any:
    local = "applies to the local cluster, not with --scheduler"
    for flag, wrong, why in (
            ("workers", args.scheduler is not None and args.workers is not None, local),
            ("dashboard", args.scheduler is not None and args.dashboard, local),
            ("security", args.scheduler is None and args.security is not None,
             "applies with --scheduler (the local cluster makes its own credentials)")):
        if wrong:
            raise StudyError(f"argument --{flag}: {why}")
    verbose = bool(args.verbose) or bool(args.dashboard) or sys.stderr.isatty()
    try:
        summary = run_study(args.study, args.output, scheduler=args.scheduler,
                            workers=args.workers, security=args.security,
                            connect_timeout=args.connect_timeout, dashboard=args.dashboard,
                            progress=None, log=_log if verbose else None)
    except RunInterrupted as exc:
        partial = exc.partial
        return outcome(payload=partial.to_dict(), text=partial.text(),
                       status=interrupted_status, note=str(exc))
    status = failed_status if summary.status == "incomplete" else 0
    return outcome(payload=summary.to_dict(), text=summary.text(), status=status,
                   note=summary.note if summary.status != "complete" else "")

