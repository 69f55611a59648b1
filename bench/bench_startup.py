"""
friction_node start-up: launch to "ready", warm and cold numba cache, against a bare rclpy node.

For each run the ``friction_node`` console script is started and timed until its "ready"
log line (model built and warm; ``live.process_age_s`` in the line is the node's own
figure), then stopped with SIGINT.  The baseline is ``bench/thin_node.py`` (a bare rclpy node
with the same interface), timed until its subscription is matched by this process, which is
when it can take input.  "cold" runs the node with an
empty ``NUMBA_CACHE_DIR`` (every kernel compiled at start-up); "warm" uses the normal cache.
The machine's load is printed: absolute times on a shared 2-core machine are noisy; compare
medians in one run.

The package is byte-compiled first (``--no-bytecode``: not), as an installed package is.

Run: .venv/bin/python bench/bench_startup.py [--runs 5] [--cold-runs 1] [--no-bytecode]
"""

import argparse
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from bb_friction_ros.interface import local_domain_id

HERE = os.path.dirname(os.path.abspath(__file__))
READY_TIMEOUT_S = 120.0     # warm runs; a cold one gets --cold-timeout (the whole compile)


def time_to_ready(env, timeout_s=READY_TIMEOUT_S):
    """Start friction_node; return (wall seconds to the ready line, the line)."""
    exe = os.path.join(os.path.dirname(sys.executable), "friction_node")
    t0 = time.perf_counter()
    proc = subprocess.Popen([exe], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    found = []
    done = threading.Event()

    def read():
        for line in proc.stdout:
            if "ready" in line and not found:
                found.append((time.perf_counter() - t0, line.strip()))
                done.set()
        done.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        done.wait(timeout_s)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if not found:
        raise RuntimeError(f"friction_node printed no ready line (exit {proc.returncode})")
    return found[0]


def own_figures(line):
    """Return (seconds after launch, CPU seconds) from the node's ready line (nan if absent)."""
    m = re.search(r"([0-9.]+) s after launch \(([0-9.]+) s of CPU\)", line)
    return (float(m.group(1)), float(m.group(2))) if m else (float("nan"), float("nan"))


def time_thin(env):
    """Start the bare rclpy node; return wall seconds until its input is matched."""
    import rclpy
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from sensor_msgs.msg import JointState
    from bb_friction_ros import interface
    context = rclpy.Context()
    rclpy.init(context=context)
    node = Node(f"startup_probe_{os.getpid()}", context=context)
    pub = node.create_publisher(JointState, interface.NUT_STATE, qos_profile_sensor_data)
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, os.path.join(HERE, "thin_node.py")], env=env)
    try:
        while pub.get_subscription_count() == 0:
            if time.perf_counter() - t0 > READY_TIMEOUT_S:
                raise RuntimeError("thin node never subscribed")
            time.sleep(0.005)
        return time.perf_counter() - t0
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def main():
    """Time warm and cold start-ups and the bare node; print medians and the load."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--runs", type=int, default=5, help="warm-cache runs (and thin runs)")
    ap.add_argument("--cold-runs", type=int, default=1, help="runs with an empty numba cache")
    ap.add_argument("--cold-timeout", type=float, default=900.0,
                    help="seconds a cold run may take to compile (120 s was too short at "
                         "load 8 on 2 cores)")
    ap.add_argument("--no-bytecode", action="store_true",
                    help="do not byte-compile the package first: with PYTHONDONTWRITEBYTECODE "
                         "set (as in this project's shells) every start then compiles the "
                         "package's sources, ~0.1 s of CPU an installed package never pays")
    ap.add_argument("--rt-priority", type=int, default=0, metavar="P",
                    help="warm runs at SCHED_FIFO priority P (this process and the nodes it "
                         "starts): on a shared machine the others' load then barely delays "
                         "them, about as on a quiet one (cold runs stay at normal priority)")
    args = ap.parse_args()
    if args.runs < 0 or args.cold_runs < 0 or args.runs + args.cold_runs == 0:
        ap.error("--runs and --cold-runs: at least one run, none negative")
    if args.rt_priority:        # the nodes started from here inherit it
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(args.rt_priority))
    if not args.no_bytecode:
        # warm means every cache a deployed package has: pip and colcon byte-compile on
        # install; an editable checkout has bytecode only if Python may write it
        import compileall
        import bb_friction_ros
        compileall.compile_dir(os.path.dirname(bb_friction_ros.__file__), quiet=1)
    print(f"bytecode of the package: {'not compiled' if args.no_bytecode else 'compiled'}; "
          f"PYTHONDONTWRITEBYTECODE={os.environ.get('PYTHONDONTWRITEBYTECODE', '')!r}")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(local_domain_id()))
    env = os.environ.copy()
    time_to_ready(env)                        # fills the numba cache if it is empty
    load0 = os.getloadavg()[0]
    warm, thin, own = [], [], []
    for _ in range(args.runs):
        wall, line = time_to_ready(env)
        warm.append(wall)
        own.append(line)
        thin.append(time_thin(env))
    cold = []
    if args.rt_priority:        # a compile of a minute must not hold a core from the others
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    for _ in range(args.cold_runs):
        with tempfile.TemporaryDirectory() as cache:
            cold.append(time_to_ready({**env, "NUMBA_CACHE_DIR": cache},
                                      args.cold_timeout))
    if warm:        # --runs 0: the cold runs alone
        print(f"friction_node launch to ready, warm numba cache: median "
              f"{statistics.median(warm):.2f} s (runs: {', '.join(f'{t:.2f}' for t in warm)})")
        print(f"  its own line: {own[len(own) // 2]}")
        ages, cpus = zip(*(own_figures(line) for line in own))
        # CPU to ready is what the start-up costs; a loaded machine inflates the wall time more
        print(f"  its own figures: median {statistics.median(ages):.2f} s after launch, "
              f"{statistics.median(cpus):.2f} s of CPU (runs: "
              f"{', '.join(f'{c:.2f}' for c in cpus)})")
        print(f"bare rclpy node (bench/thin_node.py) launch to subscribed: median "
              f"{statistics.median(thin):.2f} s; friction_node / bare "
              f"{statistics.median(warm) / statistics.median(thin):.2f}")
    if cold:
        walls = [wall for wall, _ in cold]
        print(f"friction_node launch to ready, cold numba cache: median "
              f"{statistics.median(walls):.2f} s ({len(cold)} runs)" + (
                  f": the compile costs {statistics.median(walls) - statistics.median(warm):.2f}"
                  " s" if warm else ""))
        print(f"  its own line: {cold[len(cold) // 2][1]}")
    if args.rt_priority:
        print(f"warm runs at SCHED_FIFO priority {args.rt_priority} (--rt-priority)")
    print(f"machine load (1 min) at start / end: {load0:.2f} / {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
