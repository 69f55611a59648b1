"""
Replay speed at 1 and 20 rev/s (the targets: >= 30x real time at 1 rev/s, >= 5x at 20).

Asserts nothing; prints the table.

For each speed a 6-second recording of steady rotation (nut_state at 1 kHz, axial_load
1500 N at 100 Hz, a measured torque at 1 kHz) is generated once into ``--workdir`` (mcap),
then ``bb-friction replay`` runs it in a child process, writing prediction.csv and the output
bag (``--no-bag`` too, for the split), median of ``--repeats``.  Figures: replay's own
``speed_vs_realtime`` (summary.json: recording span / wall time of the streaming loop:
reading, the model, writing; start-up and plots excluded), the same from the loop's CPU
time (``cpu_s``: on a machine shared with other work the wall time measures them too), and
the child's whole CPU time.  The split, in CPU seconds per second of recording: the model
(model steps from summary.json times the mean CPU time of the same steps measured
in-process, ``ModelRunner`` on the same samples), reading (a child that only reads every
message of the bag with rosbags), and the rest, replay's own per-message work.
``--bb-friction PATH`` measures another installation; ``--baseline PATH`` runs a second one
alternately with it, so both see the same load.  ``--steps-deg`` replays with other
``--model-step-deg`` (the speed side of the step's trade; its accuracy side is
bench_convergence.py).  Replay's work apart from the model, measured directly:
bench_replay_rest.py.

Usage: .venv/bin/python bench/bench_replay_rate.py [--speeds 1 20] [--repeats 3]
       [--steps-deg 1.8 3.6]
       [--workdir out/bench_replay_rate] [--bb-friction PATH] [--baseline PATH]
"""

import argparse
import json
import math
import os
from pathlib import Path
import resource
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
c0 = time.process_time()
n = 0
with Reader(sys.argv[1]) as reader:
    for _ in reader.messages():
        n += 1
print(n, time.process_time() - c0)
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
    """Run ``cmd``; return (its stdout, its CPU time [s], start-up and plots included)."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return out, (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)


def model_step_s(rev_s, step_deg=None):
    """Mean CPU time of a model step on this recording's samples, in-process (no I/O)."""
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.runner import build_runner, InputSample
    runner = build_runner(bundled_config("ball_screw.yaml"), 100.0, step_deg)
    w = 2.0 * math.pi * rev_s
    samples = [InputSample(100.0 + k / STATE_HZ, w * k / STATE_HZ, w, LOAD_N)
               for k in range(int(DURATION_S * STATE_HZ))]
    t0 = time.process_time()
    for s in samples:
        runner.process(s)
    cpu = time.process_time() - t0
    return cpu / runner.stats.model_steps, cpu, runner.stats.model_steps


def replay_once(exe, bag, out, write_bag, step_deg=None):
    """Return (summary.json, the child's CPU time) of one replay."""
    step = [] if step_deg is None else ["--model-step-deg", str(step_deg)]
    _, cpu = child([exe, "replay", str(bag), "--out", str(out), "--no-progress", *step]
                   + ([] if write_bag else ["--no-bag"]))
    return json.loads((out / "summary.json").read_text()), cpu


def _row(rev_s, step_deg, write_bag, name, runs, step_s, read_per_s):
    """One line of the table from one installation's ``runs`` (summary, child CPU)."""
    summaries = [r[0] for r in runs]
    x = statistics.median(s["speed_vs_realtime"] for s in summaries)
    cpus = [s.get("cpu_s") for s in summaries]
    x_cpu = DURATION_S / statistics.median(cpus) if None not in cpus else math.nan
    child_cpu = statistics.median(r[1] for r in runs)
    steps_per_s = summaries[0]["model_steps"] / DURATION_S
    model = steps_per_s * step_s
    # the loop's CPU per second of recording, less the model's and the reading's
    other = (1.0 / x_cpu if x_cpu == x_cpu else 1.0 / x) - model - read_per_s
    step = "dflt" if step_deg is None else f"{step_deg:g}"
    return (f"{rev_s:6g} {step:>5} {'bag+csv' if write_bag else 'csv':>8} {name:>5} {x:7.1f} "
            f"{x_cpu:6.1f} {child_cpu:9.2f} {steps_per_s:8.0f} {model:9.3f} "
            f"{read_per_s:8.3f} {other:9.3f}")


def main():
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.0, 20.0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workdir", default="out/bench_replay_rate")
    ap.add_argument("--bb-friction", default=str(Path(sys.executable).parent / "bb-friction"))
    ap.add_argument("--baseline", help="another bb-friction executable, run alternately with "
                    "--bb-friction in the same run (e.g. main's .venv/bin/bb-friction)")
    ap.add_argument("--steps-deg", type=float, nargs="+", default=[None],
                    help="replay's --model-step-deg (default: the node's default)")
    args = ap.parse_args()
    work = Path(args.workdir)
    print(f"load before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"{DURATION_S:g} s recordings, nut_state {STATE_HZ:g} Hz")
    print("x wall: summary's speed_vs_realtime (recording span / wall time of the streaming "
          "loop); x CPU: span / the loop's CPU time (cpu_s, where the installation reports "
          "it); child CPU: the whole command's CPU time, start-up and plots included")
    print(f"{'rev/s':>6} {'step°':>5} {'output':>8} {'who':>5} {'x wall':>7} {'x CPU':>6} "
          f"{'child CPU':>9} {'steps/s':>8} {'model s/s':>9} {'read s/s':>8} {'other s/s':>9}")
    who = [("this", args.bb_friction)] + ([("base", args.baseline)] if args.baseline else [])
    for rev_s in args.speeds:
        bag = bag_of(work, rev_s)
        n, read_s = child([sys.executable, "-c", READ_ONLY, str(bag)])[0].split()
        read_per_s = float(read_s) / DURATION_S
        for step_deg in args.steps_deg:
            step_s, _, _ = model_step_s(rev_s, step_deg)
            for write_bag in (True, False):
                runs = {name: [] for name, _ in who}
                for _ in range(args.repeats):
                    for name, exe in who:      # alternately: both see the same load
                        runs[name].append(replay_once(
                            exe, bag, work / f"replay_{rev_s:g}_{name}", write_bag, step_deg))
                for name, _ in who:
                    print(_row(rev_s, step_deg, write_bag, name, runs[name], step_s,
                               read_per_s), flush=True)
    print("model/read/other: CPU seconds per second of recording (1 / x CPU = their sum; "
          "other = replay's own per-message work: decoding, runner bookkeeping, alignment, "
          "CSV and bag writing); model from this installation's runner in-process")
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
