"""
Replay's own CPU, the model step left out: everything ``bb-friction replay`` does but step.

Asserts nothing; prints the figures.

bench_replay_rate.py splits replay's CPU into the model, reading and "the rest" by
subtracting separately measured parts, so the rest carries the noise of three measurements.
Here it is measured directly: each replay runs in a child process in which
``WholeScrew.step`` (and ``step_path``, which takes an input's sub-steps and its own step
in one call) returns the results of the first ``RECORDED`` real calls over and
over (the contact groups still change, so the output bag still writes them; the CPU of the
real steps is subtracted), inside the streaming loop only: the runner's warm-up, the friction
sign check and the tables built on first use take real steps, and such tables go to the
bench's own cache (``WORKDIR/cache``), never the package's.  The runner's
schedule, reading, decoding, alignment, CSV, plotted series and the output bag run as in a
real replay.  Figure: the streaming loop's CPU time (summary.json ``cpu_s``), min and median of
``--repeats``, per second of recording.  ``--baseline DIR`` runs, alternately in the same
run, a copy of the package whose ``bb_friction_ros`` lies in DIR (e.g. a ``git archive`` of
an older commit): both see the same machine load.  Min is the figure to compare on a shared
machine (other work only ever adds CPU time: caches, frequency).

Usage: .venv/bin/python bench/bench_replay_rest.py [--speeds 1 20] [--repeats 7]
       [--workdir out/bench_replay_rate] [--baseline DIR] [--no-bag]
"""

import argparse
import json
import os
from pathlib import Path
import statistics
import subprocess
import sys

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_replay_rate import bag_of, DURATION_S  # noqa: E402  (the same recordings)

RECORDED = 200

CHILD = """
import json, sys, time
if sys.argv[1]:
    sys.path.insert(0, sys.argv[1])
from bb_friction_ros import replay as R
from bb_friction_ros.ball_screw.whole_screw import WholeScrew
real, recorded, k, real_s, active = WholeScrew.step, [], [0], [0.0], [False]
def step(self, *args, **kw):
    if not active[0]:
        return real(self, *args, **kw)
    if len(recorded) < int(sys.argv[5]):
        c0 = time.process_time()
        recorded.append(real(self, *args, **kw))
        real_s[0] += time.process_time() - c0
        return recorded[-1]
    k[0] = (k[0] + 1) % len(recorded)
    return recorded[k[0]]
WholeScrew.step = step
if hasattr(WholeScrew, "step_path"):
    real_path, recorded_path, kp = WholeScrew.step_path, [], [0]
    def step_path(self, *args, **kw):
        if not active[0]:
            return real_path(self, *args, **kw)
        if len(recorded_path) < int(sys.argv[5]):
            c0 = time.process_time()
            recorded_path.append(real_path(self, *args, **kw))
            real_s[0] += time.process_time() - c0
            return recorded_path[-1]
        kp[0] = (kp[0] + 1) % len(recorded_path)
        return recorded_path[kp[0]]
    WholeScrew.step_path = step_path
stream = R._stream
def timed_stream(*args, **kw):
    real_s[0] = 0.0     # the runner's warm-up steps are not in the loop's cpu_s
    active[0] = True
    try:
        return stream(*args, **kw)
    finally:
        active[0] = False
R._stream = timed_stream
s = R.replay(sys.argv[2], sys.argv[3], progress=False, write_bag=sys.argv[4] == "1")
print(json.dumps({"cpu_s": s["cpu_s"], "real_s": real_s[0], "file": R.__file__}))
"""


def rest_once(path, bag, out, write_bag):
    """
    Return the loop CPU [s] of one replay with recorded steps (``path``: package dir).

    Less the CPU of the real steps among the first ``RECORDED`` (a sixth of the model at
    1 rev/s, where the bag holds 1200 steps: counted as the rest until 2026-11-26).
    """
    # Tables the model builds on first use (mean_b2b's) go to the bench's own cache: built
    # while steps were replayed they would be wrong, and in the package's cache every later
    # run would read them (the recorded steps are only replayed inside the stream, too).
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               BB_FRICTION_CACHE=str(Path(out).resolve().parent / "cache"))
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    # -P: the bench's own directory (or the cwd) must not shadow the package measured
    res = subprocess.run([sys.executable, "-P", "-c", CHILD, path, str(bag), str(out),
                          "1" if write_bag else "0", str(RECORDED)],
                         check=True, capture_output=True, text=True, env=env)
    got = json.loads(res.stdout.strip().splitlines()[-1])
    if path and not got["file"].startswith(str(Path(path).resolve())):
        raise SystemExit(f"--baseline {path}: the child imported {got['file']} instead")
    return got["cpu_s"] - got["real_s"]


def main():
    """Print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.0, 20.0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--workdir", default="out/bench_replay_rate")
    ap.add_argument("--baseline", help="a directory holding another bb_friction_ros package")
    ap.add_argument("--no-bag", action="store_true", help="prediction.csv only")
    args = ap.parse_args()
    work = Path(args.workdir)
    print(f"load before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"{DURATION_S:g} s recordings; the model step replayed from {RECORDED} recorded "
          f"results; {'csv' if args.no_bag else 'bag + csv'}")
    print(f"{'rev/s':>6} {'who':>5} {'CPU s min':>9} {'median':>7} {'per s of rec':>12}")
    who = [("this", "")] + ([("base", args.baseline)] if args.baseline else [])
    for rev_s in args.speeds:
        bag = bag_of(work, rev_s)
        cpus = {name: [] for name, _ in who}
        for _ in range(args.repeats):
            for name, path in who:          # alternately: both see the same load
                cpus[name].append(rest_once(path, bag, work / f"rest_{rev_s:g}_{name}",
                                            not args.no_bag))
        for name, _ in who:
            lo, med = min(cpus[name]), statistics.median(cpus[name])
            print(f"{rev_s:6g} {name:>5} {lo:9.3f} {med:7.3f} {lo / DURATION_S:12.4f}",
                  flush=True)
        if args.baseline:
            # each pair ran back to back under the same load: its ratio is the fair figure
            ratios = [b / t for t, b in zip(cpus["this"], cpus["base"]) if t > 0]
            print(f"{rev_s:6g} base/this per pair: median {statistics.median(ratios):.2f}x "
                  f"(min {min(ratios):.2f}, max {max(ratios):.2f})", flush=True)
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
