"""Benchmarks of bb-friction sweep (issue #7); prints figures, asserts nothing.

Run: .venv/bin/python bench/bench_sweep.py [--linear-samples 10000] [--scaling-samples 4000]
                                            [--screw-samples 1000] [--skip-screw]

1. serial baseline: the linear-pair samples run in this process without Dask (us/sample);
2. linear-pair Monte Carlo (config/sweeps/linear_tolerance_mc.yaml, 10^4 samples) on a local
   cluster of all cores   [goal: <= 60 s on 2 cores];
3. throughput against workers: 1 and 2 local workers, and a LocalCluster whose scheduler runs
   in a separate process (reached by its tcp:// address, as a remote cluster would be); the
   overhead per sample is (compute wall x workers) / samples - the serial time per sample;
4. whole-screw Monte Carlo (config/sweeps/whole_screw_tolerance_mc.yaml: 200 steps per build)
   [goal: 1000 builds <= 10 min locally]; with fewer builds the time for 1000 is extrapolated.

Everything binds to 127.0.0.1; every cluster is closed before the script ends.
"""

import argparse
import dataclasses
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

from bb_friction_ros.sweep import engine
from bb_friction_ros.sweep.spec import load_spec

ROOT = Path(__file__).resolve().parent.parent
SPECS = ROOT / 'config' / 'sweeps'
# A LocalCluster in its own process: prints its scheduler address, runs until stdin closes.
EXTERNAL_CLUSTER = """
import logging, sys
from distributed import LocalCluster
cluster = LocalCluster(n_workers=int(sys.argv[1]), threads_per_worker=1, processes=True,
                       protocol='tcp://', host='127.0.0.1', dashboard_address='127.0.0.1:0',
                       silence_logs=logging.ERROR)
print(cluster.scheduler_address, flush=True)
sys.stdin.read()
cluster.close()
"""


def with_samples(spec, samples):
    """Return the spec with ``samples`` random draws."""
    return dataclasses.replace(spec, samples=samples)


def serial_us_per_sample(spec, samples):
    """Run the first ``samples`` samples in this process (warm caches): us per sample."""
    spec = with_samples(spec, samples)
    engine.run_batch(spec, 0)                   # builds the friction map, imports
    t0 = time.perf_counter()
    for b in range(spec.n_batches):
        engine.run_batch(spec, b)
    return (time.perf_counter() - t0) / spec.n_samples * 1e6


def timed_sweep(spec, out_dir, **kwargs):
    """Run a sweep into a new directory; return its RunReport."""
    rep = engine.run_sweep(spec, out_dir, progress=False, plots=False, log=lambda m: None,
                           **kwargs)
    assert rep.complete, 'sweep incomplete'
    return rep


def load():
    """Return the 1-minute load average: the cores are shared, so figures depend on it."""
    return os.getloadavg()[0]


def report_line(label, rep, serial_us, load_before):
    """Print one throughput line."""
    overhead = rep.compute_wall_s * rep.workers / rep.n_computed * 1e6 - serial_us
    print(f'{label:<34} {rep.n_computed:>6} samples  wall {rep.wall_s:6.2f} s  compute '
          f'{rep.compute_wall_s:6.2f} s  {rep.samples_per_s:7.1f} samples/s  overhead '
          f'{overhead:+6.0f} us/sample  (load before {load_before:.2f})')


def external_cluster(n_workers):
    """Start a LocalCluster in a separate process; return (process, scheduler address)."""
    proc = subprocess.Popen([sys.executable, '-c', EXTERNAL_CLUSTER, str(n_workers)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    address = proc.stdout.readline().strip()
    if not address.startswith('tcp://127.0.0.1:'):
        proc.kill()
        raise RuntimeError(f'external cluster did not start: {address!r}')
    return proc, address


def stop(proc):
    """Let the external cluster close itself (stdin closed); kill it if it does not."""
    proc.stdin.close()
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def main():
    """Print the figures of the four benchmarks."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--linear-samples', type=int, default=10000)
    ap.add_argument('--scaling-samples', type=int, default=4000)
    ap.add_argument('--screw-samples', type=int, default=1000)
    ap.add_argument('--skip-screw', action='store_true')
    args = ap.parse_args()
    cores = os.cpu_count()
    print(f'machine: {cores} cores, load average {load():.2f} (shared: other work slows '
          'every figure); everything on 127.0.0.1')
    linear = load_spec(SPECS / 'linear_tolerance_mc.yaml')
    serial = serial_us_per_sample(linear, 2000)
    print(f'serial, no Dask (linear pair, numerical): {serial:.0f} us/sample')

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        spec = with_samples(linear, args.linear_samples)
        before = load()
        rep = timed_sweep(spec, tmp / 'linear_mc')
        print(f'\nlinear-pair Monte Carlo, {spec.n_samples} samples, local cluster of {cores} '
              f'workers, batch {spec.batch_size}: wall {rep.wall_s:.1f} s (cluster start '
              f'included), compute {rep.compute_wall_s:.1f} s, {rep.samples_per_s:.0f} '
              f'samples/s (load before {before:.2f})   [goal: <= 60 s on 2 cores]')

        print('\nthroughput against workers (linear pair):')
        spec = with_samples(linear, args.scaling_samples)
        for n in (1, 2):
            before = load()
            report_line(f'local, {n} worker(s)', timed_sweep(spec, tmp / f'local{n}',
                                                             workers=n), serial, before)
        proc, address = external_cluster(2)
        try:
            before = load()
            report_line('scheduler in own process, 2 workers', timed_sweep(
                spec, tmp / 'external', scheduler=address), serial, before)
        finally:
            stop(proc)

        if args.skip_screw:
            return
        screw = load_spec(SPECS / 'whole_screw_tolerance_mc.yaml')
        spec = with_samples(screw, args.screw_samples)
        before = load()
        rep = timed_sweep(spec, tmp / 'screw_mc')
        s = rep.summary
        per_1000 = rep.wall_s / spec.n_samples * 1000
        print(f'\nwhole-screw Monte Carlo, {spec.n_samples} builds x '
              f'{spec.base.operation.n_steps} steps, local cluster of {cores} workers: wall '
              f'{rep.wall_s:.1f} s, {rep.samples_per_s:.2f} builds/s, {per_1000 / 60:.1f} min '
              f'per 1000 builds (load before {before:.2f})   [goal: <= 10 min]')
        print(f'  builds: {s["n_ok"]} ok, {s["n_nonconverged"]} not converged, '
              f'{s["n_failed"]} failed; torque_band_rel q50 '
              f'{s["outputs"]["torque_band_rel"].get("q50")}')


if __name__ == '__main__':
    main()
