"""
friction_node against the thinnest rclpy node, same client, same run; asserts nothing.

For each input rate, two processes are started one after the other: ``bench/thin_node.py``
(answers each nut_state with an empty FrictionPrediction of the same stamp, nothing else) and
the ``friction_node`` console script.  This process sends nut_state at the rate (and
axial_load at 100 Hz: 1 rev/s, reversing every 2 s, load 1500 +- 300 N) and times each
prediction back.  Per node and rate it reports: answered share, round trip p50/p99 (wall,
both DDS hops), CPU per input [us] and share of a core, RSS, and for friction_node the ratios
to the thin node, the profile rate and what its diagnostics say (shed, skipped, dropped).
The machine's load (``os.getloadavg``) is printed with every line: absolute times are noisy
on a shared 2-core machine; the ratios are the figure that counts.

``--kinds thin edge friction`` adds a diagnostic node, friction_node with the model's step
made free (``bench/diag_node.py``, which has more switches): the edge's own tail apart from
the model's.  ``--trace DIR`` splits each answer's time in the node by path.  Each
answer also carries the node's own ``model_latency_s`` (middleware receipt to publication),
printed as "in the node", so the DDS hops and the client's share are apart from the node's.
``--repeats 3`` runs the kinds three times, alternating, and prints the median ratio.

Run: .venv/bin/python bench/bench_node.py [--duration 10] [--rates 500 1000 2000]
     [--repeats 3] [--kinds thin edge friction]
"""

import argparse
import json
import os
import subprocess
import sys
import threading
import time

import numpy as np

from bb_friction_ros import interface
from bb_friction_ros.interface import local_domain_id

HERE = os.path.dirname(os.path.abspath(__file__))


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


def _p99_ms(lat_s):
    return float(np.percentile(lat_s, 99) * 1e3) if lat_s.size else float("nan")


def _p50_ms(lat_s):
    return float(np.percentile(lat_s, 50) * 1e3) if lat_s.size else float("nan")


def drive(rate_hz, duration_s, pid, context, warmup_s=1.0, rev_s=1.0):
    """Send nut_state at ``rate_hz``: ``warmup_s`` unmeasured, then ``duration_s`` timed."""
    from bb_friction_msgs.msg import FeedforwardProfile, FrictionPrediction
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import WrenchStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    node = Node(f"bench_client_{pid}", context=context)
    pub_state = node.create_publisher(JointState, interface.NUT_STATE, qos_profile_sensor_data)
    pub_load = node.create_publisher(WrenchStamped, interface.AXIAL_LOAD,
                                     qos_profile_sensor_data)
    sent, latency, diags, profiles = {}, [], [], []
    stepped = []        # per answer: True if its model state was computed for it (age 0)
    in_node = []        # per answer: the node's own model_latency_s (receipt to publication)
    lock = threading.Lock()
    measuring = [False]

    def on_pred(msg):
        t = time.perf_counter()
        key = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        with lock:
            t0 = sent.pop(key, None)
            if t0 is not None and measuring[0]:
                latency.append(t - t0)
                stepped.append(msg.model_age_s == 0.0)
                in_node.append(msg.model_latency_s)

    def on_diag(msg):
        for st in msg.status:
            if "friction" in st.name:
                diags.append(({kv.key: kv.value for kv in st.values}, st.message))

    def on_profile(msg):
        if measuring[0]:
            profiles.append((time.perf_counter(), len(msg.nut_angle_rad), msg.converged))

    reliable = QoSProfile(depth=interface.COLLECTOR_QOS_DEPTH,
                          reliability=ReliabilityPolicy.RELIABLE)
    node.create_subscription(FeedforwardProfile, interface.PROFILE, on_profile, reliable)
    node.create_subscription(DiagnosticArray, interface.DIAGNOSTICS, on_diag,
                             interface.OUTPUT_QOS_DEPTH)
    # The predictions are taken by a polling thread straight from a subscription of a node
    # no executor spins: the rclpy executor costs ~0.3 ms of Python per message, and at
    # 1-2 kHz this client would otherwise be the bottleneck it is meant to measure through.
    taker = Node(f"bench_taker_{pid}", context=context)
    sub_pred = taker.create_subscription(FrictionPrediction, interface.PREDICTION,
                                         on_pred, reliable)
    stop = [False]

    def poll():
        handle, mtype = sub_pred.handle, sub_pred.msg_type
        while not stop[0]:
            with handle:
                got = handle.take_message(mtype, False)
            if got is None:
                time.sleep(0.0001)
            else:
                on_pred(got[0])

    ex = SingleThreadedExecutor(context=context)
    ex.add_node(node)
    spin = threading.Thread(target=ex.spin, daemon=True)
    spin.start()
    poller = threading.Thread(target=poll, daemon=True)
    poller.start()
    deadline = time.monotonic() + 30
    while pub_state.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    omega = 2.0 * np.pi * rev_s
    n_warm, n = int(rate_hz * warmup_s), int(rate_hz * duration_s)
    angle = 0.0
    stamp0 = time.time()
    t_start = time.perf_counter()
    cpu0 = rss0 = t_meas0 = None
    for k in range(n_warm + n):
        if k == n_warm:
            with lock:
                measuring[0] = True
            cpu0, rss0, t_meas0 = _proc_cpu_s(pid), _proc_rss_mb(pid), time.perf_counter()
        delay = t_start + k / rate_hz - time.perf_counter()
        if delay > 0:
            time.sleep(delay)      # no busy wait: the client must not eat the node's core
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
    wall = time.perf_counter() - t_meas0
    time.sleep(1.5)             # late answers and one more diagnostics message
    cpu1, rss1 = _proc_cpu_s(pid), _proc_rss_mb(pid)
    with lock:
        measuring[0] = False
    stop[0] = True
    poller.join()
    ex.shutdown()
    node.destroy_node()
    taker.destroy_node()
    lat = np.array(latency)
    fresh = np.array(stepped, dtype=bool)
    own = np.array(in_node)
    diag, note = diags[-1] if diags else ({}, "")
    prof_t = np.array([p[0] for p in profiles])
    return {
        "rate_hz": rate_hz, "sent": n, "send_rate_hz": n / wall, "answered": int(lat.size),
        "answered_share": lat.size / n,
        "p50_ms": float(np.percentile(lat, 50) * 1e3) if lat.size else float("nan"),
        "p99_ms": float(np.percentile(lat, 99) * 1e3) if lat.size else float("nan"),
        # where the tail comes from: answers that waited for their own model step (age 0;
        # the thin node's answers all have age 0) and answers from a held state
        "p99_stepped_ms": _p99_ms(lat[fresh]), "p99_held_ms": _p99_ms(lat[~fresh]),
        "p50_stepped_ms": _p50_ms(lat[fresh]), "p50_held_ms": _p50_ms(lat[~fresh]),
        # the node's own share (middleware receipt to publication; the thin node sends 0)
        "in_node_p50_ms": _p50_ms(own), "in_node_p99_ms": _p99_ms(own),
        "in_node_p99_stepped_ms": _p99_ms(own[fresh]), "in_node_p99_held_ms": _p99_ms(own[~fresh]),
        "stepped_share": float(fresh.mean()) if fresh.size else float("nan"),
        "cpu_share": (cpu1 - cpu0) / (wall + 1.5),
        "cpu_us_per_input": 1e6 * (cpu1 - cpu0) / n,
        "rss_mb": (rss0, rss1),
        "profiles_per_s": prof_t.size / wall,
        "profile_points": profiles[0][1] if profiles else 0,
        "profiles_converged": sum(p[2] for p in profiles),
        "diagnostics": diag, "diagnostics_message": note,
    }


_DIAG = os.path.join(HERE, "diag_node.py")
# kind: (command, environment); the diagnostic kinds are bench/diag_node.py's switches
NODE_COMMANDS = {
    "thin": ([sys.executable, os.path.join(HERE, "thin_node.py")], {}),
    "friction": ([os.path.join(os.path.dirname(sys.executable), "friction_node")], {}),
    "edge": ([sys.executable, _DIAG], {"BENCH_FREE_STEP": "1"}),
    "noprofile": ([sys.executable, _DIAG], {"BENCH_NO_PROFILE": "1"}),
    "traced": ([sys.executable, _DIAG], {}),
    "handoff": ([sys.executable, _DIAG], {"BENCH_HANDOFF_ALL": "1"}),
    "nodefer": ([sys.executable, _DIAG], {"BENCH_NO_DEFER": "1"}),
    "spinnogil": ([sys.executable, _DIAG], {"BENCH_SPIN_PROFILE": "nogil"}),
    "spinpy": ([sys.executable, _DIAG], {"BENCH_SPIN_PROFILE": "py"}),
}


def run_node(kind, rate_hz, duration_s, context, extra_args=(), rev_s=1.0, trace=None,
             rt_priority=0):
    """Start ``kind`` (NODE_COMMANDS), drive it, stop it; return the figures."""
    cmd, env = NODE_COMMANDS[kind]
    cmd = cmd + ([] if kind == "thin" else list(extra_args))
    if rt_priority:
        cmd = ["chrt", "-f", str(rt_priority)] + cmd
    env = {**os.environ, **env}
    if trace and kind != "thin":
        env["BENCH_TRACE"] = trace
        if kind == "friction":
            exe = cmd.index(NODE_COMMANDS["friction"][0][0])
            cmd = cmd[:exe] + [sys.executable, _DIAG] + cmd[exe + 1:]
    proc = subprocess.Popen(cmd, env=env)
    try:
        time.sleep(2.0 if kind == "thin" else 4.0)    # numba cache, friction maps
        if proc.poll() is not None:
            raise RuntimeError(f"{kind} node exited with {proc.returncode}")
        return drive(rate_hz, duration_s, proc.pid, context, rev_s=rev_s)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def trace_summary(path):
    """One line from a diag_node trace: where an answer's time in the node goes (p50/p99)."""
    t = np.load(path)
    wait = 1e-6 * (t["entered_ns"] - t["recv_ns"])       # receipt -> the schedule has it
    work = 1e-6 * (t["published_ns"] - t["entered_ns"])  # -> answer published
    inline = t["thread"] == 0
    stepped = t["stepped"] == 1
    parts = []
    for name, m in (("inline held", inline & ~stepped), ("inline stepped", inline & stepped),
                    ("model thread", ~inline)):
        if m.any():
            parts.append(f"{name} {100 * m.mean():.1f} %: to schedule p50/p99 "
                         f"{np.percentile(wait[m], 50):.3f}/{np.percentile(wait[m], 99):.3f}"
                         f" ms, to publish {np.percentile(work[m], 50):.3f}/"
                         f"{np.percentile(work[m], 99):.3f} ms")
    prof = t["span_kind"] == 0
    if prof.any() and (inline & ~stepped).any():
        # held answers whose time in the node overlapped a look-ahead profile's run
        start, end = t["span_start_ns"][prof], t["span_end_ns"][prof]
        order = np.argsort(start)
        start, end = start[order], np.maximum.accumulate(end[order])
        held = inline & ~stepped
        first = np.searchsorted(start, t["published_ns"][held]) - 1
        hit = (first >= 0) & (end[np.maximum(first, 0)] > t["recv_ns"][held])
        total = 1e-6 * (t["published_ns"][held] - t["recv_ns"][held])
        parts.append(f"held answers overlapping a profile {100 * hit.mean():.1f} %"
                     + (f", their in-node p99 {np.percentile(total[hit], 99):.3f} ms"
                        if hit.any() else "")
                     + (f", the others' {np.percentile(total[~hit], 99):.3f} ms"
                        if (~hit).any() else ""))
        if "span_cpu_ns" in t:
            wall = t["span_end_ns"][prof] - t["span_start_ns"][prof]
            parts.append(f"profile runs wall/CPU p50 {1e-6 * np.median(wall):.3f}"
                         f"/{1e-6 * np.median(t['span_cpu_ns'][prof]):.3f} ms")
    return "      trace: " + "; ".join(parts)


def _line(rate, kind, r, load):
    d = r["diagnostics"]
    extra = ""
    if kind != "thin":
        extra = (f"\n      answers: stepped {100 * r['stepped_share']:.0f} % p50/p99 "
                 f"{r['p50_stepped_ms']:.2f}/{r['p99_stepped_ms']:.2f} ms, held "
                 f"p50/p99 {r['p50_held_ms']:.2f}/{r['p99_held_ms']:.2f} ms | in the node "
                 f"(receipt to publication) p50 {r['in_node_p50_ms']:.3f} ms, p99 "
                 f"{r['in_node_p99_ms']:.3f} ms (stepped {r['in_node_p99_stepped_ms']:.3f}, "
                 f"held {r['in_node_p99_held_ms']:.3f})"
                 f"\n      profiles {r['profiles_per_s']:.0f}/s x "
                 f"{r['profile_points']} points | node: shed "
                 f"{d.get('shed_inputs', '?')}, skipped steps "
                 f"{d.get('skipped_steps', '?')}, dropped "
                 f"{d.get('dropped_inputs', '?')}, non-converged "
                 f"{d.get('nonconverged_steps', '?')}, step "
                 f"{d.get('last_step_s', '?')} s, coarse steps "
                 f"{d.get('coarse_steps', '?')} at {d.get('model_step_deg', '?')} deg, "
                 f"inline {d.get('answered_inline', '?')} of {d.get('published', '?')}, "
                 f"fast inputs {d.get('fast_inputs', '?')}")
    return (f"{rate:5.0f} Hz {kind:8s} answered {100 * r['answered_share']:6.2f} % "
            f"p50 {r['p50_ms']:6.2f} ms p99 {r['p99_ms']:6.2f} ms  CPU "
            f"{100 * r['cpu_share']:4.0f} % of a core ({r['cpu_us_per_input']:5.0f}"
            f" us/input)  RSS {r['rss_mb'][1]:4.0f} MB  load {load:.1f}{extra}")


def main():
    """Run the nodes at each rate (``--repeats`` rounds), print each and the ratios."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--rates", type=float, nargs="+", default=[500.0, 1000.0, 2000.0])
    ap.add_argument("--json", help="also write all figures to this file")
    ap.add_argument("--rev-s", type=float, default=1.0, help="nut speed [rev/s] ("
                    "20 rev/s steps the model every 1.8 deg, 4000 steps/s)")
    ap.add_argument("--repeats", type=int, default=1,
                    help="rounds of all kinds, alternating; the ratios' median is printed")
    ap.add_argument("--kinds", nargs="+", default=["thin", "friction"],
                    choices=sorted(NODE_COMMANDS),
                    help="nodes per round; diagnostics (bench/diag_node.py): 'edge' = "
                         "friction_node with the model's step made free, 'noprofile' = no "
                         "look-ahead profiles, 'handoff' = every due step with inputs waiting "
                         "handed to the model thread (the rule before 2026-11-25), 'nodefer' = "
                         "groups and profile hand-off right after a step (before "
                         "2026-11-25), 'spinnogil' / 'spinpy' = each look-ahead profile "
                         "replaced by 0.5-0.6 ms of CPU without / with the GIL held (is a "
                         "profile's cost the GIL or a core?), 'traced' = as shipped")
    ap.add_argument("--trace", metavar="DIR",
                    help="run friction_node and the diagnostic kinds through "
                         "bench/diag_node.py with BENCH_TRACE: per answer, receipt -> "
                         "schedule -> publication, by path (inline held or stepped, model "
                         "thread); .npz files in DIR")
    ap.add_argument("--rt-priority", type=int, default=0, metavar="P",
                    help="run this client and the nodes (all their threads, DDS's too) "
                         "SCHED_FIFO at priority P (chrt): on a shared machine the other "
                         "processes then barely delay them, about as on a quiet one. A "
                         "diagnostic: a node at its default priority is the figure")
    ap.add_argument("--node-args", nargs=argparse.REMAINDER, default=[],
                    help="extra friction_node (and edge) arguments, e.g. --ros-args -p "
                         "max_answer_age_s:=0.01")
    args = ap.parse_args()
    sys.setswitchinterval(2.5e-4)     # the client is two Python threads too
    if args.rt_priority:    # before rclpy: DDS's threads inherit it
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(args.rt_priority))
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(local_domain_id()))
    import rclpy
    context = rclpy.Context()
    rclpy.init(context=context)
    results = []
    ratios = {}         # (rate, kind): [(p50 ratio, p99 ratio)] against thin, per round
    try:
        for rnd in range(args.repeats):
            for rate in args.rates:
                pair = {}
                for kind in args.kinds:
                    load = os.getloadavg()[0]
                    trace = None
                    if args.trace:
                        os.makedirs(args.trace, exist_ok=True)
                        trace = os.path.join(args.trace, f"{kind}_{rate:.0f}_{rnd}.npz")
                    r = run_node(kind, rate, args.duration, context, args.node_args,
                                 args.rev_s, trace, args.rt_priority)
                    r["kind"], r["load_1min"], r["round"] = kind, load, rnd
                    pair[kind] = r
                    results.append(r)
                    print(_line(rate, kind, r, load), flush=True)
                    if trace and kind != "thin" and os.path.exists(trace):
                        print(trace_summary(trace), flush=True)
                t = pair.get("thin")
                for kind, f in pair.items():
                    if kind == "thin" or t is None:
                        continue
                    ratios.setdefault((rate, kind), []).append(
                        (f["p50_ms"] / t["p50_ms"], f["p99_ms"] / t["p99_ms"]))
                    print(f"{rate:5.0f} Hz ratio {kind}/thin: p50 "
                          f"{f['p50_ms'] / t['p50_ms']:.2f}, p99 "
                          f"{f['p99_ms'] / t['p99_ms']:.2f}, CPU/input "
                          f"{f['cpu_us_per_input'] / t['cpu_us_per_input']:.2f}, RSS "
                          f"{f['rss_mb'][1] / t['rss_mb'][1]:.2f}", flush=True)
    finally:
        rclpy.try_shutdown(context=context)
    for (rate, kind), rs in sorted(ratios.items()):
        p50s, p99s = zip(*rs)
        print(f"{rate:5.0f} Hz {kind}/thin over {len(rs)} rounds: p99 ratio median "
              f"{np.median(p99s):.2f} ({', '.join(f'{x:.2f}' for x in p99s)}), p50 ratio "
              f"median {np.median(p50s):.2f}")
    if args.rt_priority:
        print(f"client and nodes ran SCHED_FIFO priority {args.rt_priority} (--rt-priority)")
    print(f"machine load at the end (1/5/15 min): "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(results, fh, indent=2, default=str)


if __name__ == "__main__":
    main()
