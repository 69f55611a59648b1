"""
Replay of a long recording: peak memory (RSS) and speed, against a bare read of the same bag.

A 10-minute, 1 kHz mcap bag must replay in bounded memory (target
<= 300 MB peak RSS).  The bag (nut_state and measured_torque at 1 kHz, axial_load at 100 Hz,
reversing nut motion) is generated once into ``--workdir`` (streamed, never held in memory).
Each figure is the peak RSS of a child process (``wait4``), and two baselines are measured in
the same run: a child that only reads every message of the bag with rosbags (the floor any
reader pays), and the same replay of a 6-second bag from the same generator (replay's fixed
cost: numpy, scipy, numba, matplotlib, the compiled model; about 270 MB here).  The long
replay's excess over the short one is what the recording's length costs.  ``--bb-friction
PATH`` measures another installation (e.g. an older checkout's ``.venv/bin/bb-friction``) on
the same bag.

Usage: .venv/bin/python bench/bench_replay.py [--minutes 10] [--workdir out/bench_replay]
       [--bb-friction PATH] [--no-bag]
"""

import argparse
import math
import os
from pathlib import Path
import subprocess
import sys
import time

READ_ONLY = """
import sys
from rosbags.rosbag2 import Reader
n = 0
with Reader(sys.argv[1]) as reader:
    for _ in reader.messages():
        n += 1
print(n)
"""


def recording(minutes, state_hz=1000.0, load_hz=100.0):
    """Yield the bench recording's events in log order (generated, nothing kept)."""
    from bb_friction_ros.bags import Event
    n = int(minutes * 60 * state_hz)
    every = int(state_hz / load_hz)
    period_s, peak = 20.0, 6.0               # reversing every 10 s, +-6 rad/s
    for k in range(n):
        t = k / state_hz
        if k % every == 0:
            yield Event("axial_load", t, value=1500.0 + 500.0 * math.sin(2 * math.pi * t / 7))
        w = peak * math.sin(2 * math.pi * t / period_s)
        angle = peak * period_s / (2 * math.pi) * (1 - math.cos(2 * math.pi * t / period_s))
        yield Event("nut_state", t, ("nut_joint",), (angle,), (w,))
        yield Event("measured_torque", t, value=0.2 * math.copysign(1.0, w) + 0.004 * w)


def bench_bag(work, minutes):
    """Return the bench bag of ``minutes``, generated into ``work`` the first time."""
    bag = work / f"bag_{minutes:g}min"
    if not bag.exists():
        from bb_friction_ros.bags import write_events
        work.mkdir(parents=True, exist_ok=True)
        t0 = time.perf_counter()
        write_events(bag, recording(minutes), storage="mcap")
        print(f"generated {bag} in {time.perf_counter() - t0:.0f} s")
    return bag


def child(cmd):
    """Run ``cmd``; return (wall s, peak RSS MiB, stdout) of that process alone (wait4)."""
    import tempfile
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        err.seek(0)
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n"
                             f"{err.read().decode()}")
        return wall, usage.ru_maxrss / 1024.0, out.read().decode().strip()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--workdir", default="out/bench_replay")
    ap.add_argument("--bb-friction", default=str(Path(sys.executable).parent / "bb-friction"))
    ap.add_argument("--short-minutes", type=float, default=0.1,
                    help="length of the short bag whose replay gives the fixed cost")
    ap.add_argument("--no-bag", action="store_true", help="replay with --no-bag")
    args = ap.parse_args()
    work = Path(args.workdir)
    bag, short = (bench_bag(work, m) for m in (args.minutes, args.short_minutes))
    size_mb = sum(p.stat().st_size for p in bag.iterdir()) / 1e6
    print(f"bag: {bag} ({size_mb:.0f} MB, {args.minutes:g} min at 1 kHz); load: "
          f"{os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f}")
    # Peak RSS is per child, so each run below is its own process: the read-only floor first.
    # The ROS wheels' .pth hook re-executes python once, in the same process (same pid).
    wall_r, rss_r, n = child([sys.executable, "-c", READ_ONLY, str(bag)])
    print(f"read only (rosbags, every message): {rss_r:7.0f} MB peak RSS, {wall_r:6.1f} s, "
          f"{n} messages")
    flags = ["--no-progress"] + (["--no-bag"] if args.no_bag else [])
    wall_s, rss_s, _ = child([args.bb_friction, "replay", str(short), "--out",
                              str(work / "replay_short"), *flags])
    print(f"replay of {args.short_minutes * 60:g} s (fixed cost): {rss_s:7.0f} MB peak RSS, "
          f"{wall_s:6.1f} s")
    wall, rss, out = child([args.bb_friction, "replay", str(bag), "--out",
                            str(work / "replay"), *flags])
    print(f"replay of {args.minutes:g} min ({args.bb_friction}"
          f"{' --no-bag' if args.no_bag else ''}): {rss:7.0f} MB peak RSS, {wall:6.1f} s, "
          f"{args.minutes * 60 / wall:.1f}x real time")
    print(f"replay {args.minutes:g} min - replay {args.short_minutes * 60:g} s: "
          f"{rss - rss_s:+.0f} MB; replay / read-only wall {wall / wall_r:.1f}x; "
          f"target <= 300 MB: {'met' if rss <= 300 else 'NOT met'}")
    print(f"summary: {out.splitlines()[0] if out else '-'}")
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
