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


# Signals received during start-up.  An exception raised by a signal handler while a C
# extension initialises (scipy, numba) surfaces as "ImportError: initialization failed", not
# as the handler's exception, so the import's caller must know a signal came.
_received = []


def raise_shutdown(signum, frame):
    """Turn SIGTERM into an exception the start-up and spin code catch."""
    _received.append(signum)
    raise Shutdown(signum)


def raise_interrupt(signum, frame):
    """SIGINT as Python's default handler does, remembering that it came."""
    _received.append(signum)
    raise KeyboardInterrupt


def install_handlers():
    """SIGTERM raises Shutdown, SIGINT KeyboardInterrupt; both are remembered."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, raise_shutdown)
        signal.signal(signal.SIGINT, raise_interrupt)


def main(args=None):
    """Install the handlers, import the node, run it."""
    install_handlers()
    try:
        from bb_friction_ros.node import main as node_main
    except KeyboardInterrupt:       # SIGINT or SIGTERM (Shutdown) while importing
        return 0
    except ImportError:
        if _received:               # the signal's exception, re-raised by an extension's init
            return 0
        raise
    return node_main(args)


if __name__ == "__main__":
    sys.exit(main())
