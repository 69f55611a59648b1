"""
Console script ``friction_node``: take SIGTERM/SIGINT from the first instant, then start.

Importing rclpy, numba and the friction maps takes about a second, during which a supervisor
may already stop the node.  This module imports nothing heavy, so the signal handlers are in
place before that work starts; a signal at any moment of start-up then ends in a clean exit
(status 0, no traceback) instead of a KeyboardInterrupt or "context is invalid" traceback.
"""

import gc
import inspect
import os
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
# Until the node spins, a signal ends the process at once (status 0).  Raising there is not
# safe: an exception thrown into rclpy.init or the node's construction (rclpy chains our
# handler after its own) was seen to be swallowed, and the node then ran on until killed
# (colcon test, test_early_signal_exits_cleanly[15-0.3]).  Nothing is written or owed
# before the node spins, so there is nothing to clean up.
_starting = [True]


def _exit_now(signum):
    _received.append(signum)
    if _starting[0]:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(0)


def started():
    """
    Mark that the node spins: signals raise again from now on, so it shuts down in order.

    Also ends start-up's pause of the garbage collector (``main``): the objects alive now
    (modules, numba's registries, the model) are frozen out of its walks, so a full
    collection while the node answers does not walk them.  Start-up's own cyclic garbage
    (about 1300 objects, measured) is frozen with them, a one-off few hundred kB: collecting
    it first took 0.12 s holding the GIL, with the input thread already answering.
    """
    _starting[0] = False
    gc.freeze()
    gc.enable()


def raise_shutdown(signum, frame):
    """SIGTERM: exit at once during start-up; afterwards an exception the spin code catches."""
    _exit_now(signum)
    raise Shutdown(signum)


def raise_interrupt(signum, frame):
    """SIGINT: as SIGTERM, but KeyboardInterrupt (Python's default) once the node spins."""
    _exit_now(signum)
    raise KeyboardInterrupt


def install_handlers():
    """SIGTERM raises Shutdown, SIGINT KeyboardInterrupt; both are remembered."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, raise_shutdown)
        signal.signal(signal.SIGINT, raise_interrupt)


def main(args=None):
    """Install the handlers, import the node, run it (the collector paused until it spins)."""
    install_handlers()
    # Start-up (numpy, numba and its registries, rclpy, the friction maps) allocates some
    # 10^6 objects and creates few cycles; the collector's generation-2 walks over them cost
    # ~0.15-0.2 s of the ~1 s to ready (CPU, 6 runs alternated; docs/node_latency.md).
    # ``started`` turns it back on.
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        try:
            from bb_friction_ros.node import main as node_main
        except KeyboardInterrupt:       # SIGINT or SIGTERM (Shutdown) while importing
            return 0
        except ImportError:
            if _received:               # the signal's exception, re-raised by an extension
                return 0
            raise
        # rclpy's first log line (the ready line) finds its caller with inspect.getmodule,
        # which resolves the path of every module loaded (~1000: 74-121 ms, 9000 lstat
        # calls).  Started here, in a thread, that overlaps the model's loading (the kernels'
        # loading releases the GIL): from the node's own ready figure to the line seen by
        # bench_startup 40 -> 0-10 ms (docs/node_latency.md).
        threading.Thread(target=inspect.getmodule, args=(inspect.currentframe(),),
                         name="friction_log_caller_cache", daemon=True).start()
        return node_main(args, on_spin=started)
    finally:
        if was_enabled:
            gc.enable()


if __name__ == "__main__":
    sys.exit(main())
