"""Benchmarks of bb-friction sweep; prints figures, asserts nothing.

Run: .venv/bin/python bench/bench_sweep.py [--linear-samples 10000] [--scaling-samples 4000]
                                            [--screw-samples 1000] [--skip-screw]

1. serial baseline: the linear-pair samples run in this process without Dask (us/sample);
2. linear-pair Monte Carlo (config/sweeps/linear_tolerance_mc.yaml, 10^4 samples) on a local
   cluster of all cores   [goal: <= 60 s on 2 cores];
3. throughput against workers: 1 and 2 local workers, and a LocalCluster whose scheduler runs
   in a separate process (reached by its tcp:// address, as a remote cluster would be), each
   warmed up first; the cost of the distributed path is the CPU time of client, scheduler and
   workers per sample against the serial CPU time per sample (CPU time, because the cores are
   shared: other engineers' load would distort a wall-time comparison);
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

import psutil

from bb_friction_ros.sweep import engine
from bb_friction_ros.sweep.spec import load_spec

ROOT = Path(__file__).resolve().parent.parent
# Batches of the warm-up sweep: enough for every worker to import the package and load its
# friction map before the timed sweep.
WARM_UP_BATCHES = 4
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
    """Run ``samples`` samples in this process (warm caches): (wall, CPU) us per sample."""
    spec = with_samples(spec, samples)
    engine.run_batch(spec, 0)                   # builds the friction map, imports
    t0, c0 = time.perf_counter(), time.process_time()
    for b in range(spec.n_batches):
        engine.run_batch(spec, b)
    return ((time.perf_counter() - t0) / spec.n_samples * 1e6,
            (time.process_time() - c0) / spec.n_samples * 1e6)


def tree_cpu_s(extra_pids=()):
    """CPU seconds (user + system) used so far by this process, its children and extra_pids'
    process trees: the client, scheduler, nannies and workers of a sweep."""
    roots = [psutil.Process()] + [psutil.Process(p) for p in extra_pids]
    procs = {p.pid: p for r in roots for p in [r] + r.children(recursive=True)}
    total = 0.0
    for p in procs.values():
        try:
            t = p.cpu_times()
        except psutil.NoSuchProcess:
            continue
        total += t.user + t.system
    return total


def timed_sweep(spec, out_dir, **kwargs):
    """Run a sweep into a new directory; return its RunReport."""
    rep = engine.run_sweep(spec, out_dir, progress=False, plots=False, log=lambda m: None,
                           **kwargs)
    assert rep.complete, 'sweep incomplete'
    return rep


def load():
    """Return the 1-minute load average: the cores are shared, so figures depend on it."""
    return os.getloadavg()[0]


def report_line(label, rep, serial_cpu_us, cpu_s, load_before):
    """Print one throughput line; the overhead is in CPU time, which other load leaves alone."""
    cpu_us = cpu_s / rep.n_computed * 1e6
    print(f'{label:<36} {rep.n_computed} samples  compute {rep.compute_wall_s:5.2f} s  '
          f'{rep.samples_per_s:6.1f} samples/s  CPU {cpu_us:5.0f} us/sample = serial '
          f'{cpu_us - serial_cpu_us:+5.0f} ({(cpu_us / serial_cpu_us - 1) * 100:+.1f} %)  '
          f'(load before {load_before:.2f})')


def warm_then_time(spec, out_dir, label, serial_cpu_us, extra_pids=(), **cluster):
    """On one cluster: a short warm-up sweep (imports, friction maps), then the timed one."""
    with engine.dask_client(**cluster) as (client, _):
        warm = with_samples(spec, WARM_UP_BATCHES * spec.batch_size)
        timed_sweep(warm, out_dir / 'warm-up', client=client)
        before, cpu0 = load(), tree_cpu_s(extra_pids)
        rep = timed_sweep(spec, out_dir / 'timed', client=client)
        cpu_s = tree_cpu_s(extra_pids) - cpu0
    report_line(label, rep, serial_cpu_us, cpu_s, before)


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
    serial, serial_cpu = serial_us_per_sample(linear, 2000)
    print(f'serial, no Dask (linear pair, numerical): {serial:.0f} us/sample wall, '
          f'{serial_cpu:.0f} us/sample CPU')

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        spec = with_samples(linear, args.linear_samples)
        before = load()
        rep = timed_sweep(spec, tmp / 'linear_mc')
        print(f'\nlinear-pair Monte Carlo, {spec.n_samples} samples, local cluster of {cores} '
              f'workers, batch {spec.batch_size}: wall {rep.wall_s:.1f} s (cluster start '
              f'included), compute {rep.compute_wall_s:.1f} s, {rep.samples_per_s:.0f} '
              f'samples/s (load before {before:.2f})   [goal: <= 60 s on 2 cores]')

        print('\nthroughput against workers (linear pair; workers warmed up first; CPU time '
              'of client, scheduler and workers against the serial CPU time = the cost of the '
              'distributed path per sample):')
        spec = with_samples(linear, args.scaling_samples)
        for n in (1, 2):
            warm_then_time(spec, tmp / f'local{n}', f'local, {n} worker(s)', serial_cpu,
                           workers=n)
        proc, address = external_cluster(2)
        try:
            warm_then_time(spec, tmp / 'external', 'scheduler in own process, 2 workers',
                           serial_cpu, extra_pids=(proc.pid,), scheduler=address)
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
