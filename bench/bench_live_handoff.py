"""
What a hand-off to the model thread costs an answer, without DDS; asserts nothing.

``live.LiveSchedule`` is fed 1 kHz nut-state inputs of a steady motion at 1500 N by a plain
thread, paced in real time, three ways in turn: every due step handed to the model thread
(``more_waiting=True``, as when the input thread's batch holds more inputs), a due step taken
in the feeding thread (``more_waiting=False``, the node's path when nothing else waits),
and the runner called directly (no schedule at all).  Prints p50/p99 from the call to the
answer for all inputs and for those that stepped, with the machine's load: a hand-off
waits for a scheduler wake-up, which a loaded machine makes long.

Run: .venv/bin/python bench/bench_live_handoff.py [--rev-s 1] [--inputs 3000] [--rounds 2]
"""

import argparse
import math
import os
import sys
import time

import numpy as np

from bb_friction_ros.config import bundled_config
from bb_friction_ros.live import LiveSchedule, Outputs
from bb_friction_ros.node_parameters import NodeParameters
from bb_friction_ros.runner import build_runner, InputAssembler

LOAD_N = 1500.0
RATE_HZ = 1000.0
JOINT = ("nut_joint",)


def run(mode, rev_s, n):
    """Feed ``n`` inputs; return (latencies [ms], stepped flags)."""
    p = NodeParameters(max_answer_age_s=1.0)
    sys.setswitchinterval(p.gil_switch_interval_s)       # as the node does
    runner = build_runner(bundled_config("ball_screw.yaml"), p.model_rate_hz)
    assembler = InputAssembler(p.nut_joint, p.max_axial_load_n)
    lat, stepped, t_in = [], [], {}

    def answer(pred, stamp, latency_s, thread=0):
        lat.append(time.perf_counter() - t_in[stamp])
        stepped.append(pred.stepped)

    live = LiveSchedule(runner, assembler, p, Outputs(answer=answer, groups=lambda *a: None,
                                                      profile=lambda *a: None,
                                                      log=lambda *a: None))
    live.start()
    live.on_axial_load(LOAD_N)
    w = 2 * math.pi * rev_s
    t0 = time.perf_counter()
    try:
        for k in range(n):
            delay = t0 + k / RATE_HZ - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            stamp = k / RATE_HZ
            t_in[stamp] = time.perf_counter()
            if mode == "direct":
                answer(runner.process(assembler.on_nut_state(stamp, JOINT, (w * stamp,),
                                                             (w,))), stamp, 0.0)
            else:
                live.on_nut_state(stamp, JOINT, (w * stamp,), (w,), time.time_ns(), stamp,
                                  mode == "model thread")
        time.sleep(0.2)
    finally:
        live.stop()
    return 1e3 * np.array(lat), np.array(stepped, dtype=bool)


def main():
    """Print one line per way and round."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--rev-s", type=float, default=1.0)
    ap.add_argument("--inputs", type=int, default=3000)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    for _ in range(args.rounds):
        for mode in ("model thread", "input thread", "direct"):
            lat, stepped = run(mode, args.rev_s, args.inputs)
            p50, p99 = np.percentile(lat, [50, 99])
            s50, s99 = np.percentile(lat[stepped], [50, 99])
            print(f"{args.rev_s:g} rev/s {mode:12s}: answered {lat.size}/{args.inputs}, "
                  f"p50 {p50:6.3f} p99 {p99:6.3f} ms; stepped ({stepped.sum()}) p50 "
                  f"{s50:6.3f} p99 {s99:6.3f} ms  (load {os.getloadavg()[0]:.1f})",
                  flush=True)


if __name__ == "__main__":
    main()
