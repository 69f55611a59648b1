"""
Replay speed on one recording: this installation against a baseline, alternately, same run.

The target: replay >= 30x real time on the demo recording, with and without the
discrepancy workflow's augmented terms.  Each configuration (plain / ``--config AUGMENTED``,
with and without the output bag) is replayed ``--repeats`` times by each ``bb-friction``,
alternating, so both see the same machine load; the figure is replay's own
``speed_vs_realtime`` (summary.json: recording span / wall time of the streaming loop,
start-up and plots excluded), median of the repeats, and the ratio of the medians.  It also
checks that both wrote byte-identical prediction.csv files.

Usage: .venv/bin/python bench/bench_replay_speed.py --baseline OTHER/.venv/bin/bb-friction
       [--bag out/demo/demo_bag] [--augmented out/discrepancy/augmented.yaml] [--repeats 3]
"""

import argparse
import filecmp
import json
import os
from pathlib import Path
import statistics
import subprocess
import sys


def run(exe, bag, out, config, write_bag):
    cmd = [exe, "replay", str(bag), "--out", str(out), "--no-progress"]
    cmd += ["--config", str(config)] if config else []
    cmd += [] if write_bag else ["--no-bag"]
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, env=env)
    return json.loads((Path(out) / "summary.json").read_text())["speed_vs_realtime"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--baseline", required=True, help="the other bb-friction executable")
    ap.add_argument("--bb-friction", default=str(Path(sys.executable).parent / "bb-friction"))
    ap.add_argument("--bag", default="out/demo/demo_bag")
    ap.add_argument("--augmented", default="out/discrepancy/augmented.yaml")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workdir", default="out/bench_replay_speed")
    args = ap.parse_args()
    work = Path(args.workdir)
    print(f"load before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"{'configuration':28s} {'baseline x':>11s} {'this x':>8s} {'ratio':>6s}  csv")
    for config in (None, args.augmented):
        for write_bag in (False, True):
            name = f"{'augmented' if config else 'plain'}, {'bag' if write_bag else '--no-bag'}"
            speeds = {"base": [], "this": []}
            for _ in range(args.repeats):
                for who, exe in (("base", args.baseline), ("this", args.bb_friction)):
                    speeds[who].append(run(exe, args.bag, work / who, config, write_bag))
            same = filecmp.cmp(work / "base" / "prediction.csv",
                               work / "this" / "prediction.csv", shallow=False)
            b, t = statistics.median(speeds["base"]), statistics.median(speeds["this"])
            print(f"{name:28s} {b:11.1f} {t:8.1f} {t / b:6.2f}  "
                  f"{'identical' if same else 'DIFFERENT'}", flush=True)
    print(f"load after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
