"""
Sustained-input benchmark of friction_node (issue #5); prints figures, asserts nothing.

The node runs as its own process (the ``friction_node`` console script); this process sends
nut_state at the target rate (and axial_load at 100 Hz) and times each prediction back.
Reports per rate: prediction rate, input->prediction latency p50/p99 (wall, both DDS hops),
the node's CPU share, its memory at the start and end, and what the node's diagnostics say.

Run: .venv/bin/python bench/bench_node.py [--duration 30] [--rates 500 1000]
"""

import argparse
import os
import subprocess
import sys
import threading
import time

import numpy as np


def _proc_cpu_s(pid):
    with open(f"/proc/{pid}/stat") as fh:
        fields = fh.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _proc_rss_mb(pid):
    with open(f"/proc/{pid}/status") as fh:
        for line in fh:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def run_rate(rate_hz, duration_s, node_pid, context):
    """Send nut_state at ``rate_hz`` for ``duration_s``; return the measured figures."""
    from bb_friction_msgs.msg import FrictionPrediction
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    node = Node(f"bench_{int(rate_hz)}", context=context)
    pub_state = node.create_publisher(JointState, "nut_state", qos_profile_sensor_data)
    pub_load = node.create_publisher(WrenchStamped, "axial_load", qos_profile_sensor_data)
    sent, latency, node_latency, diags = {}, [], [], []
    lock = threading.Lock()

    def on_pred(msg):
        t = time.perf_counter()
        key = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        with lock:
            t0 = sent.pop(key, None)
            if t0 is not None:
                latency.append(t - t0)
                node_latency.append(msg.model_latency_s)

    def on_diag(msg):
        for st in msg.status:
            if "friction" in st.name:
                diags.append({kv.key: kv.value for kv in st.values})

    node.create_subscription(FrictionPrediction, "friction/prediction", on_pred,
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 10)
    ex = SingleThreadedExecutor(context=context)
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    deadline = time.monotonic() + 10
    while pub_state.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    omega = 2.0 * np.pi          # 1 rev/s, reversing every 2 s
    n = int(rate_hz * duration_s)
    t_start = time.perf_counter()
    cpu0, rss0 = _proc_cpu_s(node_pid), _proc_rss_mb(node_pid)
    angle = 0.0
    stamp0 = time.time()
    for k in range(n):
        target = t_start + k / rate_hz
        while True:
            now = time.perf_counter()
            if now >= target:
                break
            if target - now > 0.0015:
                time.sleep(target - now - 0.001)
        t_rec = k / rate_hz
        w = omega if int(t_rec // 2.0) % 2 == 0 else -omega
        angle += w / rate_hz
        stamp = stamp0 + t_rec
        sec, nsec = int(stamp), int((stamp - int(stamp)) * 1e9)
        if k % max(1, int(rate_hz / 100)) == 0:
            lm = WrenchStamped()
            lm.header.stamp.sec, lm.header.stamp.nanosec = sec, nsec
            lm.wrench.force.z = 1500.0 + 300.0 * np.sin(t_rec)
            pub_load.publish(lm)
        msg = JointState(name=["nut_joint"], position=[angle], velocity=[w])
        msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nsec
        with lock:
            sent[(sec, nsec)] = time.perf_counter()
        pub_state.publish(msg)
    wall = time.perf_counter() - t_start
    time.sleep(1.5)             # late predictions and one more diagnostics message
    cpu1, rss1 = _proc_cpu_s(node_pid), _proc_rss_mb(node_pid)
    ex.shutdown()
    node.destroy_node()
    lat = np.array(latency)
    # a report from the middle of the stream: the last one covers the idle time after it
    diag = dict(diags[len(diags) // 2]) if diags else {}
    if diags:
        diag["skipped_inputs"] = diags[-1].get("skipped_inputs")
        diag["dropped_inputs"] = diags[-1].get("dropped_inputs")
    return {"rate_hz": rate_hz, "sent": n, "send_rate_hz": n / wall,
            "predictions": int(lat.size), "prediction_rate_hz": lat.size / wall,
            "latency_p50_ms": float(np.percentile(lat, 50) * 1e3) if lat.size else None,
            "latency_p99_ms": float(np.percentile(lat, 99) * 1e3) if lat.size else None,
            "node_latency_p50_ms": float(np.percentile(node_latency, 50) * 1e3)
            if node_latency else None,
            "node_latency_p99_ms": float(np.percentile(node_latency, 99) * 1e3)
            if node_latency else None,
            "node_cpu_percent": 100.0 * (cpu1 - cpu0) / wall,
            "node_rss_mb": (rss0, rss1), "diagnostics": diag}


def main():
    """Start friction_node, drive it at each rate, print the figures."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--rates", type=float, nargs="+", default=[500.0, 1000.0])
    args = ap.parse_args()
    # this process is two Python threads too (sender, executor): measure the node, not our GIL
    sys.setswitchinterval(2.5e-4)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 101))
    exe = os.path.join(os.path.dirname(sys.executable), "friction_node")
    proc = subprocess.Popen([exe], env=os.environ.copy())
    import rclpy
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        time.sleep(3.0)          # friction maps from cache, discovery
        for rate in args.rates:
            r = run_rate(rate, args.duration, proc.pid, context)
            d = r["diagnostics"]
            print(f"{rate:6.0f} Hz for {args.duration:.0f} s: sent {r['send_rate_hz']:.0f}/s, "
                  f"predictions {r['prediction_rate_hz']:.0f}/s ({r['predictions']} of "
                  f"{r['sent']}), latency p50 {r['latency_p50_ms']:.2f} ms p99 "
                  f"{r['latency_p99_ms']:.2f} ms (inside the node: p50 "
                  f"{r['node_latency_p50_ms']:.2f} ms p99 {r['node_latency_p99_ms']:.2f} ms), "
                  f"node CPU {r['node_cpu_percent']:.0f} %, "
                  f"RSS {r['node_rss_mb'][0]:.0f} -> {r['node_rss_mb'][1]:.0f} MB; node says: "
                  f"model {d.get('model_rate_hz', '?')} Hz, step {d.get('last_step_s', '?')} s,"
                  f" skipped {d.get('skipped_inputs', '?')}, dropped "
                  f"{d.get('dropped_inputs', '?')}, non-converged "
                  f"{d.get('nonconverged_steps', '?')}", flush=True)
    finally:
        rclpy.try_shutdown(context=context)
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


if __name__ == "__main__":
    main()
