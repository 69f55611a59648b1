"""
Replay speed at 1 and 20 rev/s (issue 20, item 5: >= 30x real time at 1 rev/s, >= 5x at 20).

Asserts nothing; prints the table.

For each speed a 6-second recording of steady rotation (nut_state at 1 kHz, axial_load
1500 N at 100 Hz, a measured torque at 1 kHz) is generated once into ``--workdir`` (mcap),
then ``bb-friction replay`` runs it in a child process, writing prediction.csv and the output
bag (``--no-bag`` too, for the split).  The figure is replay's own ``speed_vs_realtime``
(summary.json: recording span / wall time of the streaming loop: reading, the model,
writing; start-up and plots excluded), median of ``--repeats``.  Two baselines in the same
run: a child that only reads every message of the bag with rosbags, and the model's share:
model steps (summary.json) times the mean step time of the same steps measured in-process
(``ModelRunner`` on the same samples), so what is neither reading nor the model is the
per-sample overhead of replay.  ``--bb-friction PATH`` measures another installation.

Usage: .venv/bin/python bench/bench_replay_rate.py [--speeds 1 20] [--repeats 3]
       [--workdir out/bench_replay_rate] [--bb-friction PATH]
"""

import argparse
import json
import math
import os
from pathlib import Path
import statistics
import subprocess
import sys
import time

DURATION_S = 6.0
STATE_HZ = 1000.0
LOAD_HZ = 100.0
LOAD_N = 1500.0

READ_ONLY = """
import sys, time
from rosbags.rosbag2 import Reader
t0 = time.perf_counter()
n = 0
with Reader(sys.argv[1]) as reader:
    for _ in reader.messages():
        n += 1
print(n, time.perf_counter() - t0)
"""


def recording(rev_s):
    """Yield the events of steady rotation at ``rev_s`` in log order."""
    from bb_friction_ros.bags import Event
    w = 2.0 * math.pi * rev_s
    every = int(STATE_HZ / LOAD_HZ)
    for k in range(int(DURATION_S * STATE_HZ)):
        t = 100.0 + k / STATE_HZ
        if k % every == 0:
            yield Event("axial_load", t, value=LOAD_N)
        yield Event("nut_state", t, ("nut_joint",), (w * (t - 100.0),), (w,))
        yield Event("measured_torque", t, value=0.2 + 0.004 * w)


def bag_of(work, rev_s):
    """The recording at ``rev_s``, generated the first time."""
    bag = work / f"steady_{rev_s:g}rev_s"
    if not bag.exists():
        from bb_friction_ros.bags import write_events
        work.mkdir(parents=True, exist_ok=True)
        write_events(bag, recording(rev_s), storage="mcap")
    return bag


def child(cmd):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    return subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout


def model_step_s(rev_s):
    """Mean wall time of a model step on this recording's samples, in-process (no I/O)."""
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.runner import build_runner, InputSample
    runner = build_runner(bundled_config("ball_screw.yaml"), 100.0)
    w = 2.0 * math.pi * rev_s
    samples = [InputSample(100.0 + k / STATE_HZ, w * k / STATE_HZ, w, LOAD_N)
               for k in range(int(DURATION_S * STATE_HZ))]
    t0 = time.perf_counter()
    for s in samples:
        runner.process(s)
    wall = time.perf_counter() - t0
    return wall / runner.stats.model_steps, wall, runner.stats.model_steps


def main():
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.0, 20.0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workdir", default="out/bench_replay_rate")
    ap.add_argument("--bb-friction", default=str(Path(sys.executable).parent / "bb-friction"))
    args = ap.parse_args()
    work = Path(args.workdir)
    print(f"load before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"{DURATION_S:g} s recordings, nut_state {STATE_HZ:g} Hz")
    print(f"{'rev/s':>6} {'output':>8} {'x real time':>11} {'steps/s':>8} "
          f"{'model s/s':>9} {'read s/s':>8} {'other s/s':>9}")
    for rev_s in args.speeds:
        bag = bag_of(work, rev_s)
        n, read_s = child([sys.executable, "-c", READ_ONLY, str(bag)]).split()
        read_per_s = float(read_s) / DURATION_S
        step_s, _, _ = model_step_s(rev_s)
        for write_bag in (True, False):
            speeds, steps = [], None
            for _ in range(args.repeats):
                out = work / f"replay_{rev_s:g}"
                child([args.bb_friction, "replay", str(bag), "--out", str(out),
                       "--no-progress"] + ([] if write_bag else ["--no-bag"]))
                summary = json.loads((out / "summary.json").read_text())
                speeds.append(summary["speed_vs_realtime"])
                steps = summary["model_steps"]
            x = statistics.median(speeds)
            steps_per_s = steps / DURATION_S
            model = steps_per_s * step_s
            other = 1.0 / x - model - read_per_s
            print(f"{rev_s:6g} {'bag+csv' if write_bag else 'csv':>8} {x:11.1f} "
                  f"{steps_per_s:8.0f} {model:9.3f} {read_per_s:8.3f} {other:9.3f}",
                  flush=True)
    print("model/read/other: seconds of wall time per second of recording "
          "(1 / x real time = their sum)")
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
