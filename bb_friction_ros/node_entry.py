"""
Console script ``friction_node``: take SIGTERM/SIGINT from the first instant, then start.

Importing rclpy, numba and the friction maps takes about a second, during which a supervisor
may already stop the node.  This module imports nothing heavy, so the signal handlers are in
place before that work starts; a signal at any moment of start-up then ends in a clean exit
(status 0, no traceback) instead of a KeyboardInterrupt or "context is invalid" traceback.
"""

import signal
import sys
import threading


class Shutdown(KeyboardInterrupt):
    """
    SIGTERM arrived; raised in the main thread by ``raise_shutdown``.

    A KeyboardInterrupt, so ``node.main`` ends on it as on SIGINT without importing this
    module (the node must not import its own entry point: layers, test_layers.py).
    """


def raise_shutdown(signum, frame):
    """Turn SIGTERM into an exception the start-up and spin code catch."""
    raise Shutdown(signum)


def install_handlers():
    """SIGTERM raises Shutdown (SIGINT already raises KeyboardInterrupt)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, raise_shutdown)


def main(args=None):
    """Install the handlers, import the node, run it."""
    install_handlers()
    try:
        from bb_friction_ros.node import main as node_main
    except KeyboardInterrupt:       # SIGINT or SIGTERM (Shutdown) while importing
        return 0
    return node_main(args)


if __name__ == "__main__":
    sys.exit(main())
