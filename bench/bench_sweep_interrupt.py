"""A 10-million-sample sweep (batch 50): client memory, first parts, Ctrl-C.

Run: .venv/bin/python bench/bench_sweep_interrupt.py [--seconds 40] [--workers 2]

Starts ``bb-friction sweep`` on a 10^7-sample linear-pair Monte Carlo (200 000 batches),
prints the main process's RSS and the part files saved every 10 s, then sends SIGINT and
prints how long the command takes to exit (status 130) and how many parts it kept.  Before
the bounded window this bench measured: RSS 190 -> 455 MB (every task submitted up front),
0 parts in 40 s, 65 s to stop.  Prints figures and the load (uptime); asserts nothing.
"""

import argparse
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time

SPEC = """sweep:
  model: linear_pair
  batch_size: 50
  random:
    samples: 10000000
    seed: 1
    variables:
      theta_deg: {dist: normal, mean: 0.0, std: 1.5}
      rho: {dist: uniform, low: -0.6, high: 0.6}
"""


def rss_kb(pid):
    with open(f"/proc/{pid}/status") as f:
        return int(next(line for line in f if line.startswith("VmRSS")).split()[1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=int, default=40, help="run this long before SIGINT")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "spec.yaml").write_text(SPEC)
        out = tmp / "out"
        cmd = [sys.executable, "-m", "bb_friction_ros.cli", "sweep", str(tmp / "spec.yaml"),
               "--out", str(out), "--workers", str(args.workers), "--no-progress",
               "--no-plots"]
        # A child of a background shell inherits SIGINT ignored: restore it, as a terminal has.
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                preexec_fn=lambda: signal.signal(signal.SIGINT,
                                                                 signal.SIG_DFL))
        for t in range(10, args.seconds + 1, 10):
            time.sleep(10)
            parts = len(os.listdir(out / "parts")) if (out / "parts").is_dir() else 0
            print(f"t = {t:3d} s  parts saved {parts:5d}  "
                  f"main RSS {rss_kb(proc.pid) / 1024:.0f} MB", flush=True)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.communicate()
        print(f"SIGINT: exit {proc.returncode} after {time.monotonic() - t0:.1f} s; "
              f"parts kept {len(os.listdir(out / 'parts'))}")
    print("load:", os.popen("uptime").read().strip())


if __name__ == "__main__":
    main()
