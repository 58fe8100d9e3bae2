"""Run meshcat's ZMQ/WebSocket bridge bound to 127.0.0.1 (``python -m`` entry).

meshcat's own server script offers no port option; this one does, and never listens
on anything but the loopback address. It prints ``zmq_url=...`` and ``web_url=...``
like meshcat's script, so :func:`snake_pin.viz.meshcat_view.start_server` can read them.
"""

from __future__ import annotations

import argparse
import sys

from meshcat.servers.zmqserver import ZMQWebSocketBridge

HOST = "127.0.0.1"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--port", type=int, default=None, help="web port (default: from 7000)")
    args = parser.parse_args(argv)
    bridge = ZMQWebSocketBridge(host=HOST, port=args.port)
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)
    try:
        bridge.run()
    except KeyboardInterrupt:
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
