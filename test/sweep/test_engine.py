"""Dask execution, Parquet streaming and resume: deterministic, nothing lost, nothing redone."""

import json
import logging

import pyarrow.parquet as pq
import pytest

from bb_friction_ros.config import ConfigError
from bb_friction_ros.sweep import engine
from bb_friction_ros.sweep.engine import run_sweep
from bb_friction_ros.sweep.models import FAILED, OK

QUIET = {'progress': False, 'plots': False, 'log': lambda msg: None}


def results(out_dir):
    return pq.read_table(out_dir / 'results.parquet')


def parts(out_dir):
    """Return {part file name: (inode, mtime_ns)}."""
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns)
            for p in (out_dir / 'parts').glob('batch-*.parquet')}


def test_same_seed_same_table_local_or_external_scheduler(tmp_path, linear_mc):
    """The engine's own LocalCluster and an existing multi-process cluster agree exactly."""
    from distributed import LocalCluster
    spec = linear_mc()
    local = run_sweep(spec, tmp_path / 'local', workers=2, processes=False, **QUIET)
    assert local.complete and local.scheduler == 'local' and local.workers == 2
    external = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                            host='127.0.0.1', dashboard_address='127.0.0.1:0',
                            silence_logs=logging.ERROR)
    try:
        remote = run_sweep(spec, tmp_path / 'remote', scheduler=external.scheduler_address,
                           **QUIET)
    finally:
        external.close()
    assert remote.complete and remote.scheduler.startswith('tcp://127.0.0.1:')
    a, b = results(tmp_path / 'local'), results(tmp_path / 'remote')
    assert a.num_rows == spec.n_samples
    assert a.column('sample').to_pylist() == list(range(spec.n_samples))
    assert a.equals(b, check_metadata=True)
    assert set(a.column('status').to_pylist()) <= {OK, 'invalid', 'nonconverged'}


def test_interrupted_sweep_resumes_without_recomputing(tmp_path, linear_mc, client):
    spec = linear_mc()
    whole = run_sweep(spec, tmp_path / 'whole', client=client, **QUIET)
    out = tmp_path / 'resumed'
    first = run_sweep(spec, out, client=client, max_samples=6, **QUIET)
    assert not first.complete and not (out / 'results.parquet').exists()
    saved = parts(out)
    assert 6 <= first.n_computed < spec.n_samples
    assert len(saved) * spec.batch_size == first.n_computed
    second = run_sweep(spec, out, client=client, **QUIET)
    assert second.complete
    assert second.n_resumed == first.n_computed
    assert second.n_computed == spec.n_samples - first.n_computed
    redone = {f'batch-{b:06d}.parquet' for b in second.batches_submitted}
    assert not redone & set(saved)
    assert all(parts(out)[name] == stamp for name, stamp in saved.items())
    assert results(out).equals(results(tmp_path / 'whole'), check_metadata=True)
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['n_computed'] == spec.n_samples and summary['invocations'] == 2
    third = run_sweep(spec, out, client=client, **QUIET)
    assert third.complete and third.n_computed == 0 and not third.batches_submitted
    assert whole.n_resumed == 0


def test_failed_samples_are_rows_with_their_reason(tmp_path, linear_mc, client):
    spec = linear_mc(samples=20, random={'samples': 20, 'seed': 5, 'variables': {
        'theta_deg': {'dist': 'normal', 'mean': 2.0, 'std': 0.5},
        'friction_coefficient': {'dist': 'uniform', 'low': -0.1, 'high': 0.2}}})
    rep = run_sweep(spec, tmp_path, client=client, **QUIET)
    table = results(tmp_path)
    assert table.num_rows == spec.n_samples
    status = table.column('status').to_pylist()
    failed = [r for r, s in zip(table.to_pylist(), status) if s == FAILED]
    assert failed and OK in status
    for row in failed:
        assert row['friction_coefficient'] <= 0 and row['f_b2b_n'] is None
        assert 'linear_bearing.friction_coefficient' in row['reason']
        assert row['converged'] is False
    summary = rep.summary
    assert summary['n_failed'] == len(failed) and summary['n_samples'] == spec.n_samples
    assert summary['n_ok'] + summary['n_failed'] + summary['n_invalid'] \
        + summary['n_nonconverged'] == spec.n_samples
    assert sum(summary['failure_reasons'].values()) == len(failed)


def test_summary_contents(tmp_path, linear_mc, client):
    rep = run_sweep(linear_mc(), tmp_path, client=client, **QUIET)
    s = json.loads((tmp_path / 'summary.json').read_text())
    for key in ('n_samples', 'n_failed', 'n_nonconverged', 'wall_s', 'samples_per_s',
                'workers', 'outputs', 'sensitivity'):
        assert key in s
    f = s['outputs']['f_b2b_n']
    assert f['unit'] == 'N' and f['min'] <= f['q05'] <= f['q50'] <= f['q95'] <= f['max']
    assert s['workers'] == 2 and s['samples_per_s'] > 0
    assert s['sensitivity']['inputs'] == ['theta_rad', 'rho']
    assert rep.summary == s


def test_other_spec_in_the_same_directory_is_refused(tmp_path, linear_mc, client):
    run_sweep(linear_mc(samples=5), tmp_path, client=client, **QUIET)
    with pytest.raises(ConfigError, match='--out .*different sweep'):
        run_sweep(linear_mc(samples=6), tmp_path, client=client, **QUIET)


def test_broken_part_file_is_computed_again(tmp_path, linear_mc, client):
    spec = linear_mc(samples=15)
    run_sweep(spec, tmp_path, client=client, **QUIET)
    before = results(tmp_path)
    victim = tmp_path / 'parts' / 'batch-000001.parquet'
    victim.write_bytes(victim.read_bytes()[:100])          # a crash mid-write, say
    (tmp_path / 'parts' / 'batch-000002.parquet.tmp').write_bytes(b'torn')
    again = run_sweep(spec, tmp_path, client=client, **QUIET)
    assert again.batches_submitted == (1,)
    assert not list((tmp_path / 'parts').glob('*.tmp'))
    assert results(tmp_path).equals(before)


def test_failed_task_is_not_saved_and_retried_next_run(tmp_path, linear_mc, client,
                                                       monkeypatch):
    spec = linear_mc(samples=15)
    original = engine.run_batch

    def flaky(spec_, batch):
        if batch == 1:
            raise OSError('worker lost its disk')
        return original(spec_, batch)
    monkeypatch.setattr(engine, 'run_batch', flaky)
    first = run_sweep(spec, tmp_path, client=client, **QUIET)
    assert not first.complete and [b for b, _ in first.task_errors] == [1]
    assert 'worker lost its disk' in first.task_errors[0][1]
    assert 'batch-000001.parquet' not in parts(tmp_path)
    monkeypatch.setattr(engine, 'run_batch', original)
    second = run_sweep(spec, tmp_path, client=client, **QUIET)
    assert second.complete and second.batches_submitted == (1,)


def test_unreachable_scheduler_names_the_flag(tmp_path, linear_mc, monkeypatch):
    import socket
    with socket.socket() as sock:          # a free port nobody listens on
        sock.bind(('127.0.0.1', 0))
        port = sock.getsockname()[1]
    monkeypatch.setattr(engine, 'CONNECT_TIMEOUT_S', 1)
    with pytest.raises(ConfigError, match='--scheduler'):
        run_sweep(linear_mc(samples=5), tmp_path, scheduler=f'tcp://127.0.0.1:{port}', **QUIET)


def test_interrupted_run_keeps_its_parts_and_history(tmp_path, linear_mc, client, monkeypatch):
    """Ctrl-C while results arrive: saved batches stay, the history counts them."""
    spec = linear_mc(samples=20)
    original = engine.write_atomic
    calls = []

    def interrupt_on_second(table, path):
        calls.append(path)
        if len(calls) == 2:
            raise KeyboardInterrupt
        original(table, path)
    monkeypatch.setattr(engine, 'write_atomic', interrupt_on_second)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(spec, tmp_path, client=client, **QUIET)
    monkeypatch.setattr(engine, 'write_atomic', original)
    assert len(parts(tmp_path)) == 1
    (record,) = engine.read_history(tmp_path)
    assert record['n_computed'] == spec.batch_size
    rest = run_sweep(spec, tmp_path, client=client, **QUIET)
    assert rest.complete and rest.n_computed == spec.n_samples - spec.batch_size


def test_bundled_figs_8_9_grid_reproduces_the_paper(tmp_path, repo_root, client):
    """config/sweeps/fig08_09_grid.yaml: max (P_f + P_fB2B)/P_f of Fig. 9(c) at the corners."""
    import numpy as np

    from bb_friction_ros import paper
    from invariants import paper_approx

    from bb_friction_ros.sweep.report import column
    from bb_friction_ros.sweep.spec import load_spec
    spec = load_spec(repo_root / 'config' / 'sweeps' / 'fig08_09_grid.yaml')
    rep = run_sweep(spec, tmp_path, client=client, **QUIET)
    assert rep.summary['n_ok'] == spec.n_samples == 625
    assert 100 * rep.summary['outputs']['friction_ratio']['max'] == paper_approx(
        paper.MAX_LOSS_RATIO)
    table = results(tmp_path)
    worst = int(np.argmax(column(table, 'friction_ratio')))
    theta, rho = column(table, 'theta_rad')[worst], column(table, 'rho')[worst]
    assert abs(np.degrees(theta)) == pytest.approx(3.0) and abs(rho) == pytest.approx(0.6)
    assert np.sign(theta) == -np.sign(rho)


# --- resume over damaged part files; sweeps too large for memory

def test_resume_over_a_copied_part_file_recomputes_its_batch(tmp_path, linear_mc, client):
    """A part copied over another batch's name is discarded, said, and computed again."""
    spec = linear_mc(samples=20)
    first = run_sweep(spec, tmp_path, client=client, max_samples=5, max_in_flight=1, **QUIET)
    assert parts(tmp_path).keys() == {'batch-000000.parquet'} and not first.complete
    part = tmp_path / 'parts' / 'batch-000000.parquet'
    (tmp_path / 'parts' / 'batch-000002.parquet').write_bytes(part.read_bytes())
    said = []
    rep = run_sweep(spec, tmp_path, client=client, **{**QUIET, 'log': said.append})
    assert rep.complete and rep.n_resumed == 5 and 2 in rep.batches_submitted
    assert any('batch-000002.parquet' in m and 'samples 0..4' in m and '10..14' in m
               for m in said), said
    assert results(tmp_path).column('sample').to_pylist() == list(range(20))


def _tear(path):
    """Cut a real part file in half, as a crash or a full disk mid-write leaves it."""
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


@pytest.mark.parametrize('torn', [0, 2])
def test_resume_over_a_torn_part_file_recomputes_it(tmp_path, linear_mc, client, torn):
    """A torn first part crashed the resume (UnboundLocalError 'why'); a torn
    later part was described with the previous file's reason.  Now each is "unreadable part
    file", discarded and computed again, and the results equal an uninterrupted run's."""
    spec = linear_mc(samples=20)
    whole = run_sweep(spec, tmp_path / 'whole', client=client, **QUIET)
    assert whole.complete
    out = tmp_path / 'out'
    first = run_sweep(spec, out, client=client, max_samples=15, max_in_flight=1, **QUIET)
    assert not first.complete and len(parts(out)) == 3
    name = f'batch-{torn:06d}.parquet'
    _tear(out / 'parts' / name)
    said = []
    rep = run_sweep(spec, out, client=client, **{**QUIET, 'log': said.append})
    assert rep.complete and torn in rep.batches_submitted and rep.n_resumed == 10
    discarded = [m for m in said if 'discarding' in m]
    assert len(discarded) == 1 and name in discarded[0], said
    assert 'unreadable part file' in discarded[0] and 'samples' not in discarded[0]
    assert results(out).equals(results(tmp_path / 'whole'))


def test_part_file_reasons_are_each_files_own(tmp_path, linear_mc, client):
    """A copied part and a torn part in one resume: each gets its own reason."""
    spec = linear_mc(samples=20)
    run_sweep(spec, tmp_path, client=client, max_samples=10, max_in_flight=1, **QUIET)
    p = tmp_path / 'parts'
    (p / 'batch-000002.parquet').write_bytes((p / 'batch-000000.parquet').read_bytes())
    (p / 'batch-000003.parquet').write_bytes((p / 'batch-000000.parquet').read_bytes())
    _tear(p / 'batch-000003.parquet')
    said = []
    assert engine.completed_batches(spec, p, log=said.append) == {0: 5, 1: 5}
    assert len(said) == 2
    assert 'batch-000002' in said[0] and 'samples 0..4' in said[0]
    assert 'batch-000003' in said[1] and 'unreadable part file' in said[1]
    assert 'samples' not in said[1]


def test_write_atomic_fsyncs_the_data_before_the_rename(tmp_path, linear_mc, monkeypatch):
    """The data reach the disk before the rename, and the rename after it.

    fsync has no other observable effect short of cutting the power, so the order of the
    real calls is recorded (they still run)."""
    import os
    spec = linear_mc(samples=5)
    table = engine.batch_table(spec, engine.run_batch(spec, 0))
    calls = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd):
        calls.append(('fsync', os.path.realpath(f'/proc/self/fd/{fd}')))
        return real_fsync(fd)

    def replace(a, b):
        calls.append(('replace', str(a), str(b)))
        return real_replace(a, b)

    monkeypatch.setattr(engine.os, 'fsync', fsync)
    monkeypatch.setattr(engine.os, 'replace', replace)
    path = tmp_path / 'batch-000000.parquet'
    engine.write_atomic(table, path)
    tmp = str(path) + '.tmp'
    assert calls == [('fsync', tmp), ('replace', tmp, str(path)),
                     ('fsync', str(tmp_path))]
    assert pq.read_table(path).num_rows == 5


def test_summary_and_manifest_are_fsynced_before_their_rename(
        tmp_path, linear_mc, client, monkeypatch):
    """The JSON files beside the parts (manifest, summary) are written like the parts:
    data fsynced, then renamed, then the directory fsynced (a torn summary.json would be
    read back as the sweep's result)."""
    import os
    calls = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd):
        calls.append(('fsync', os.path.basename(os.path.realpath(f'/proc/self/fd/{fd}'))))
        return real_fsync(fd)

    def replace(a, b):
        calls.append(('replace', os.path.basename(str(a)), os.path.basename(str(b))))
        return real_replace(a, b)

    monkeypatch.setattr(engine.os, 'fsync', fsync)
    monkeypatch.setattr(engine.os, 'replace', replace)
    run_sweep(linear_mc(samples=5), tmp_path / 'out', client=client, **QUIET)
    for name in ('summary.json', engine.MANIFEST):
        i = calls.index(('replace', name + '.tmp', name))
        assert calls[i - 1] == ('fsync', name + '.tmp') and calls[i + 1] == ('fsync', 'out')


def test_compact_refuses_duplicate_sample_ids(tmp_path, linear_mc, client):
    """The last guard: results.parquet never counts a sample twice."""
    import pyarrow as pa
    spec = linear_mc(samples=10)
    run_sweep(spec, tmp_path, client=client, **QUIET)
    path = tmp_path / 'parts' / 'batch-000001.parquet'
    table = pq.read_table(path)
    ids = pa.array([5, 5, 7, 8, 9], pa.int64())           # min and max still 5..9
    pq.write_table(table.set_column(0, table.schema.field('sample'), ids), path)
    with pytest.raises(ConfigError, match='10 rows but 9 distinct sample ids of 10'):
        engine.compact(spec, tmp_path)


def test_huge_grid_refused_up_front_with_the_figure(tmp_path, linear_mc):
    """A 10^6 x 10^6 grid is refused before anything runs or is written."""
    from bb_friction_ros.sweep.spec import spec_from_mapping
    spec = spec_from_mapping({'model': 'linear_pair', 'grid': {
        'theta_deg': {'start': -2.0, 'stop': 2.0, 'num': 1_000_000},
        'rho': {'start': -0.6, 'stop': 0.6, 'num': 1_000_000}}})
    out = tmp_path / 'out'
    with pytest.raises(ConfigError, match=r'1,000,000,000,000 samples .* about [\d.]+ TiB of '
                       r'memory .*--memory-limit-mib'):
        run_sweep(spec, out, **QUIET)
    assert not out.exists()


def test_ten_million_samples_fit_the_default_limit(linear_mc):
    """The check refuses absurd sweeps, not the large ones a user runs."""
    spec = linear_mc(samples=10_000_000, batch_size=50)
    engine.check_results_memory(spec)
    with pytest.raises(ConfigError, match='--memory-limit-mib'):
        engine.check_results_memory(spec, memory_limit_mib=100)


class _SubmitSpy:
    """A real Client that records, at each submit, the batches submitted and not yet saved."""

    def __init__(self, client):
        self._client = client
        self.saved = 0
        self.in_flight_at_submit = []

    def submit(self, *args, **kwargs):
        self.in_flight_at_submit.append(len(self.in_flight_at_submit) - self.saved)
        return self._client.submit(*args, **kwargs)

    def __getattr__(self, name):
        return getattr(self._client, name)


def test_never_more_than_the_cap_in_flight(tmp_path, linear_mc, client, monkeypatch):
    """Batches are submitted in a bounded window and saved as they finish."""
    spec = linear_mc(samples=40)                 # 8 batches
    spy = _SubmitSpy(client)
    original = engine.write_atomic

    def count(table, path):
        original(table, path)
        spy.saved += 1
    monkeypatch.setattr(engine, 'write_atomic', count)
    rep = run_sweep(spec, tmp_path, client=spy, max_in_flight=2, **QUIET)
    assert rep.complete and len(spy.in_flight_at_submit) == spec.n_batches
    # Before each submit fewer than the cap are in flight: never more than 2 after it.
    assert max(spy.in_flight_at_submit) < 2, spy.in_flight_at_submit
    assert spy.in_flight_at_submit[:2] == [0, 1]


def test_default_window_is_per_worker_thread():
    assert engine.default_in_flight(2) == 2 * engine.IN_FLIGHT_PER_THREAD
    assert engine.default_in_flight(0) == engine.IN_FLIGHT_PER_THREAD


def test_unreachable_scheduler_short_timeout_said(tmp_path, linear_mc):
    """The connect timeout is a setting, a few seconds by default, and the error says so."""
    import socket
    import time
    assert engine.CONNECT_TIMEOUT_S <= 5
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        port = sock.getsockname()[1]
    t0 = time.monotonic()
    with pytest.raises(ConfigError, match=r'--scheduler tcp://127\.0\.0\.1:\d+: cannot connect '
                       r'within 0\.5 s \(--connect-timeout-s\)'):
        run_sweep(linear_mc(samples=5), tmp_path, scheduler=f'tcp://127.0.0.1:{port}',
                  connect_timeout_s=0.5, **QUIET)
    assert time.monotonic() - t0 < 30        # not the old 30 s (generous: a loaded machine)
