"""Run meshcat's ZMQ/WebSocket bridge on 127.0.0.1 only (``python -m`` entry).

Both listeners bound to loopback, only requests for ``127.0.0.1`` or ``localhost``
answered, death with the parent (``--parent PID``, ``--stdin-eof``), never blocked on an
unread pipe (``--quiet``): :doc:`/promises` (The viewer's server) says how and why.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import signal
import sys
from typing import Any

import tornado.httpserver
import tornado.ioloop
import tornado.web
from meshcat.servers import zmqserver
from tornado.routing import HostMatches, Rule

__all__: list[str] = []

HOST = "127.0.0.1"
BACKLOG = 1024
LOCAL_HOSTS = r"(127\.0\.0\.1|localhost)$"
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


class LoopbackApplication(tornado.web.Application):
    """A tornado application whose ``listen`` binds 127.0.0.1 whatever address it is given."""

    def listen(self, port: int, address: str | None = None,
               **kwargs: Any) -> tornado.httpserver.HTTPServer:
        """Listen on ``127.0.0.1:port`` (``address`` ignored), :data:`BACKLOG` connections
        queued (tornado's 128 overflow in a burst, each dropped SYN costing a second)."""
        kwargs.setdefault("backlog", BACKLOG)
        return super().listen(port, HOST, **kwargs)


class LoopbackBridge(zmqserver.ZMQWebSocketBridge):
    """meshcat's bridge with its web app on :class:`LoopbackApplication` and ZMQ on 127.0.0.1."""

    def __init__(self, port: int | None = None) -> None:
        super().__init__(host=HOST, port=port)

    def make_app(self) -> LoopbackApplication:
        """Return meshcat's two routes on a loopback app, answering only a ``Host`` of
        :data:`LOCAL_HOSTS` (any other gets 404: DNS rebinding reaches nothing)."""
        return LoopbackApplication([Rule(HostMatches(LOCAL_HOSTS), [
            (r"/static/(.*)", zmqserver.StaticFileHandlerNoCache,
             {"path": zmqserver.VIEWER_ROOT, "default_filename": zmqserver.VIEWER_HTML}),
            (r"/", zmqserver.WebSocketHandler, {"bridge": self}),
        ])])


def _die_with_parent(parent: int) -> None:
    """SIGTERM this process when its parent exits; exit now if the parent is already gone."""
    if sys.platform.startswith("linux"):
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.prctl(_PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0) != 0:
            raise OSError(ctypes.get_errno(), "prctl(PR_SET_PDEATHSIG) failed")
    if os.getppid() != parent:  # the parent died before the request took effect
        sys.exit(0)


def _stop_on_stdin_eof(loop: tornado.ioloop.IOLoop) -> None:
    """Stop ``loop`` when standard input reaches end of file (the parent closed the pipe)."""
    fd = sys.stdin.fileno()

    def readable(_fd: int, _events: int) -> None:
        try:
            data = os.read(fd, 4096)
        except OSError:
            data = b""
        if not data:
            loop.remove_handler(fd)
            loop.stop()

    loop.add_handler(fd, readable, tornado.ioloop.IOLoop.READ)


def main(argv: list[str] | None = None) -> int:
    """Start the bridge, print its URLs, serve until interrupted, the parent dies or stdin ends.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, default=None,
                        help="web port on 127.0.0.1 (default: the first free one from 7000)")
    parser.add_argument("--parent", type=int, default=None, metavar="PID",
                        help="exit when this process (our parent) exits")
    parser.add_argument("--stdin-eof", action="store_true",
                        help="exit when standard input reaches end of file")
    parser.add_argument("--quiet", action="store_true",
                        help="send stdout and stderr to /dev/null once the URLs are printed")
    args = parser.parse_args(argv)
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, signal.SIG_DFL)
    if args.parent is not None:
        _die_with_parent(args.parent)
    bridge = LoopbackBridge(port=args.port)
    if args.stdin_eof:
        _stop_on_stdin_eof(bridge.ioloop)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    if args.quiet:  # stdout and stderr to /dev/null: no later print blocks on a full pipe
        sys.stderr.flush()
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        os.close(devnull)
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
