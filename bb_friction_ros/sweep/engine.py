"""
Run a sweep on Dask distributed and stream its results to Parquet, resumably.

Layout of the output directory ``DIR``::

    DIR/manifest.json        the spec's canonical form and digest (a resume must match it)
    DIR/runs.jsonl           one line per invocation that computed: samples, wall time, workers
    DIR/parts/batch-N.parquet  one file per finished batch (Dask task), written atomically
    DIR/results.parquet      all samples, one row each, sorted by sample (when complete)
    DIR/summary.json, DIR/*.png   (report.py, plots.py; when complete)

Execution: the samples are cut into batches of ``spec.batch_size`` (a task per sample would
cost the scheduler more than the sample); each batch is one ``Client.submit`` of
``run_batch``, which computes the batch's inputs from the seed (spec.py) and runs the model on
each sample.  At most ``max_in_flight`` batches are submitted at a time (default
``IN_FLIGHT_PER_THREAD`` per worker thread): a new one goes in as one finishes
(``as_completed``), so the client's memory and a Ctrl-C's cancelling do not grow with the
sweep.  Results are written at once as a part file, so an interruption loses at most the
batches in flight.  A rerun with the same
spec and ``DIR`` submits only the batches that have no part file.  A batch whose task failed
(a worker died, say) is not written: it stays pending and the next run retries it; a failing
*sample* is a row with status ``failed`` and its reason (models.evaluate).  On a resume each
part's sample ids must be its batch's (a copied or renamed part is discarded and its batch
computed again); ``results.parquet`` is checked to hold every sample exactly once.

Memory: the results are compacted in memory; a sweep whose estimate
(``spec.results_bytes``) exceeds ``memory_limit_mib`` is refused before anything runs.

Cluster: by default a ``LocalCluster`` of ``workers`` single-threaded worker processes (all
cores) bound to 127.0.0.1; with ``scheduler`` an existing cluster (its workers must have
bb_friction_ros installed).  Results do not depend on which: every sample is seeded by its
own index.
"""

from contextlib import contextmanager
import dataclasses
import json
import logging
import os
from pathlib import Path
import sys
import time
import uuid

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from bb_friction_ros import __version__
from bb_friction_ros.config import ConfigError, format_bytes, LOCALHOST, MEMORY_LIMIT_MIB
from bb_friction_ros.sweep import CONNECT_TIMEOUT_S, IN_FLIGHT_PER_THREAD
from bb_friction_ros.sweep.files import fsync_dir, write_text_atomic
from bb_friction_ros.sweep.models import INVALID, MODELS, OK, evaluate

PART_PREFIX = "batch-"
RESULTS = "results.parquet"
MANIFEST = "manifest.json"
HISTORY = "runs.jsonl"
_ARROW_TYPES = {"float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_()}


@dataclasses.dataclass
class RunReport:
    """What one invocation of ``run_sweep`` did."""

    out_dir: Path
    n_samples: int
    n_resumed: int              # samples already saved when this run started
    n_computed: int             # samples computed and saved by this run
    complete: bool
    wall_s: float               # this invocation, from start to its last result
    compute_wall_s: float       # first task submitted to last result saved
    workers: int
    threads: int
    scheduler: str
    batches_submitted: tuple = ()
    task_errors: tuple = ()     # (batch, error) of tasks that failed; retried on rerun
    summary: dict = None

    @property
    def samples_per_s(self):
        """Return the samples computed per second of compute wall time (None if none)."""
        if not self.n_computed or not self.compute_wall_s:
            return None
        return self.n_computed / self.compute_wall_s


def table_schema(spec):
    """Return the Arrow schema of the results: ids, inputs (SI), outputs, status columns."""
    model = MODELS[spec.model]
    params = model.parameters(spec.base)
    fields = [pa.field(n, pa.int64()) for n in ("sample", "grid_index", "draw")]
    fields += [pa.field(n, pa.int64() if params[n].integer else pa.float64())
               for n in spec.input_names]
    fields += [pa.field(n, _ARROW_TYPES[model.output(n).dtype]) for n in spec.outputs]
    fields += [pa.field("converged", pa.bool_()), pa.field("status", pa.string()),
               pa.field("reason", pa.string())]
    units = {n: params[n].unit for n in spec.input_names}
    units.update({n: model.output(n).unit for n in spec.outputs})
    meta = {"bb_friction_sweep": json.dumps({"name": spec.name, "model": spec.model,
                                             "spec_digest": spec.digest(), "units": units})}
    return pa.schema(fields, metadata=meta)


def _python(value):
    """Return a numpy scalar as the Python number the config machinery expects."""
    return value.item() if isinstance(value, np.generic) else value


def run_batch(spec, batch):
    """Compute batch ``batch`` of ``spec`` (on a worker): {column: list or array}."""
    start, stop = spec.batch_bounds(batch)
    cols = spec.sample_inputs(start, stop)
    model = MODELS[spec.model]
    options = spec.option_map
    n = stop - start
    outs = {name: [None] * n for name in spec.outputs}
    status, reason = [None] * n, [None] * n
    for j in range(n):
        params = {name: _python(cols[name][j]) for name in spec.input_names}
        out, status[j], reason[j] = evaluate(model, spec.base, params, options,
                                             spec.config_names)
        if status[j] in (OK, INVALID):      # unconverged or failed: no numbers
            for name in spec.outputs:
                outs[name][j] = _python(out[name])
    cols.update(outs)
    cols["converged"] = [s in (OK, INVALID) for s in status]
    cols["status"], cols["reason"] = status, reason
    return cols


def batch_table(spec, columns, schema=None):
    """Return the Arrow table of one batch's columns."""
    return pa.Table.from_pydict(columns, schema=schema or table_schema(spec))


def _part_path(parts_dir, batch):
    return parts_dir / f"{PART_PREFIX}{batch:06d}.parquet"


def write_atomic(table, path):
    """
    Write a Parquet file so that it is either whole or absent, also after a power cut.

    The data are fsynced before the rename (otherwise the rename can reach the disk before
    the data, leaving a whole-looking name on a torn file), and the directory
    after it (so that the rename itself survives).
    """
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as fh:
        pq.write_table(table, fh)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    fsync_dir(path.parent)


def _part_problem(spec, schema, path):
    """
    Return (batch, rows, None) for a whole part file of this spec, else (None, None, why).

    ``why`` says what is wrong with this very file: each check sets its own reason, so a
    torn file is never described with another file's reason.
    """
    try:
        batch = int(path.stem[len(PART_PREFIX):])
    except ValueError:
        return None, None, "not a part file name (batch-NNNNNN.parquet)"
    if not 0 <= batch < spec.n_batches:
        return None, None, f"batch {batch} is outside this sweep's 0..{spec.n_batches - 1}"
    try:
        meta = pq.read_metadata(path)
        file_schema = meta.schema.to_arrow_schema()
    except (ValueError, OSError, pa.ArrowException) as exc:
        return None, None, f"unreadable part file ({type(exc).__name__}: {exc})"
    start, stop = spec.batch_bounds(batch)
    if meta.num_rows != stop - start:
        return None, None, f"part file holds {meta.num_rows} rows, not its batch's {stop - start}"
    if not file_schema.equals(schema, check_metadata=False):
        return None, None, "part file's columns are not this sweep's (a foreign part?)"
    try:
        ids = _sample_range(meta, path)
    except (ValueError, OSError, pa.ArrowException) as exc:
        return None, None, f"unreadable part file ({type(exc).__name__}: {exc})"
    if ids != (start, stop - 1):
        return None, None, (f"part file holds samples {ids[0]}..{ids[1]}, not its batch's "
                            f"{start}..{stop - 1} (a copied or renamed part?)")
    return batch, meta.num_rows, None


def completed_batches(spec, parts_dir, log=None):
    """
    Return {batch: rows} of the part files that are whole and match the spec.

    A part that cannot be read or has the wrong rows or schema (a crash while writing it, a
    full disk) is deleted so that its batch runs again, with its own reason in the log;
    leftover ``.tmp`` files too.
    """
    schema = table_schema(spec)
    done = {}
    for tmp in parts_dir.glob("*.tmp"):
        tmp.unlink()
    for path in sorted(parts_dir.glob(f"{PART_PREFIX}*.parquet")):
        batch, rows, why = _part_problem(spec, schema, path)
        if why is None:
            done[batch] = rows
        else:
            if log:
                log(f"sweep: discarding {path.name}: {why}; its batch is computed again")
            path.unlink()
    return done


def _sample_range(meta, path):
    """
    Return (min, max) of a part's ``sample`` column: from the Parquet statistics.

    With ``num_rows`` equal to the batch size, min and max equal to the batch's bounds
    rule out a part copied from another batch without reading the data;
    ``compact`` checks every id.  A file without statistics is read.
    """
    col = meta.schema.to_arrow_schema().get_field_index("sample")
    lo, hi = [], []
    for g in range(meta.num_row_groups):
        stats = meta.row_group(g).column(col).statistics
        if stats is None or not stats.has_min_max or stats.null_count:
            ids = pq.read_table(path, columns=["sample"]).column("sample").to_numpy()
            return (int(ids.min()), int(ids.max())) if ids.size else (None, None)
        lo.append(stats.min)
        hi.append(stats.max)
    return (int(min(lo)), int(max(hi))) if lo else (None, None)


def check_manifest(spec, out_dir):
    """Write DIR/manifest.json, or check that an existing one is of the same spec."""
    path = out_dir / MANIFEST
    digest = spec.digest()
    if path.exists():
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ConfigError(f"--out {out_dir}: unreadable {MANIFEST} ({exc})") from exc
        if old.get("spec_digest") != digest:
            raise ConfigError(
                f"--out {out_dir}: holds the results of a different sweep ({old.get('name')}, "
                f"spec digest {str(old.get('spec_digest'))[:12]}, this spec {digest[:12]}); "
                "use another --out directory, or delete it to start again")
        return
    manifest = {"name": spec.name, "model": spec.model, "spec_digest": digest,
                "n_samples": spec.n_samples, "n_batches": spec.n_batches,
                "batch_size": spec.batch_size, "source": spec.source,
                "package_version": __version__, "spec": spec.canonical()}
    write_text_atomic(path, json.dumps(manifest, indent=2))


def check_results_memory(spec, memory_limit_mib=None):
    """Refuse, before anything runs, a sweep whose results would not fit the memory limit."""
    limit_mib = MEMORY_LIMIT_MIB if memory_limit_mib is None else memory_limit_mib
    need = spec.results_bytes
    if need > limit_mib * 2**20:
        raise ConfigError(
            f"sweep {spec.name}: {spec.n_samples:,} samples (grid {spec.n_grid:,} x "
            f"{spec.samples:,} draws) need about {format_bytes(need)} of memory for "
            f"results.parquet, above the limit of {format_bytes(limit_mib * 2**20)} "
            "(--memory-limit-mib); make the grid or samples smaller, or split the sweep")


@contextmanager
def dask_client(workers=None, scheduler=None, processes=True, connect_timeout_s=None):
    """
    Yield (Client, description) of a new LocalCluster or an existing scheduler; close after.

    The local cluster binds the scheduler, workers and the HTTP endpoints to 127.0.0.1 on free
    ports and uses single-threaded workers: the models hold the GIL, so threads would not
    run in parallel.  ``connect_timeout_s``: how long an existing scheduler has to answer
    (default ``CONNECT_TIMEOUT_S``).
    """
    from distributed import Client, LocalCluster
    if scheduler is not None:
        timeout = CONNECT_TIMEOUT_S if connect_timeout_s is None else connect_timeout_s
        try:
            client = Client(scheduler, timeout=timeout)
        except (OSError, ValueError) as exc:     # refused, timed out, malformed address
            raise ConfigError(f"--scheduler {scheduler}: cannot connect within {timeout:g} s "
                              f"(--connect-timeout-s) ({exc})") from exc
        try:
            yield client, scheduler
        finally:
            client.close()
        return
    import dask
    n = workers or os.cpu_count() or 1
    # tcp also for in-process workers (processes=False would default to inproc): the tasks
    # and results then go through the same serialisation as on a real cluster.  The workers'
    # statistical profiler (a stack sample every 10 ms, for the dashboard) costs about 5 % of
    # a sample's CPU time and nobody reads it here: off.
    with dask.config.set({"distributed.worker.profile.enabled": False}):
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=processes,
                               protocol="tcp://", host=LOCALHOST,
                               dashboard_address=f"{LOCALHOST}:0", silence_logs=logging.ERROR)
    try:
        client = Client(cluster)
        try:
            yield client, "local"
        finally:
            client.close()
    finally:
        cluster.close()


def _progress(total, initial, enabled):
    from tqdm import tqdm
    return tqdm(total=total, initial=initial, unit="sample", file=sys.stderr,
                disable=not enabled, dynamic_ncols=True, smoothing=0.1)


@dataclasses.dataclass
class Tally:
    """Samples saved and task errors of one execution, kept up to date as parts arrive."""

    saved: int = 0
    errors: list = dataclasses.field(default_factory=list)


def default_in_flight(threads):
    """Return the batches kept in flight on ``threads`` worker threads."""
    return IN_FLIGHT_PER_THREAD * max(int(threads), 1)


def execute(client, spec, batches, parts_dir, bar, max_samples=None, tally=None,
            max_in_flight=None):
    """
    Run ``batches`` on ``client``, writing each part as it arrives.

    At most ``max_in_flight`` batches are submitted and not yet handled at any time (default:
    ``IN_FLIGHT_PER_THREAD`` per worker thread); the next is submitted as one finishes.
    Stops early (cancelling what is left) once ``max_samples`` samples are saved.  Returns
    the Tally (also updated in place if given, so an interrupted run knows what it saved).
    """
    from distributed import as_completed
    tally = tally if tally is not None else Tally()
    if max_in_flight is None:
        max_in_flight = default_in_flight(
            sum(w["nthreads"] for w in client.scheduler_info()["workers"].values()))
    if max_in_flight < 1:
        raise ConfigError(f"--max-in-flight: must be >= 1, got {max_in_flight}")
    schema = table_schema(spec)
    # Keys name the sweep and batch for the dashboard; the run token keeps them apart from the
    # keys of an earlier run on the same cluster, which may still be being cancelled.
    key_prefix = f"bb-friction-sweep-{spec.digest()[:12]}-{uuid.uuid4().hex[:8]}-"
    waiting = iter(batches)
    futures = {}

    def submit_next():
        batch = next(waiting, None)
        if batch is None:
            return None
        fut = client.submit(run_batch, spec, batch, key=f"{key_prefix}{batch}", retries=1)
        futures[fut] = batch
        return fut

    first = [submit_next() for _ in range(max_in_flight)]
    running = as_completed([f for f in first if f is not None])
    try:
        for fut in running:
            batch = futures.pop(fut)
            if fut.status == "finished":
                table = batch_table(spec, fut.result(), schema)
                fut.release()
                write_atomic(table, _part_path(parts_dir, batch))
                tally.saved += table.num_rows
                bar.update(table.num_rows)
            else:
                exc = fut.exception() if fut.status == "error" else None
                tally.errors.append((batch, repr(exc) if exc else fut.status))
                fut.release()
            if max_samples is not None and tally.saved >= max_samples:
                break
            nxt = submit_next()
            if nxt is not None:
                running.add(nxt)
    finally:
        left = [f for f in futures if not f.done()]
        if left:
            client.cancel(left)
    return tally


def compact(spec, out_dir):
    """
    Merge the part files into DIR/results.parquet (sorted by sample); return the table.

    Refuses (ConfigError naming the directory) a set of parts that does not hold every
    sample exactly once: a results file never counts a sample twice.
    """
    schema = table_schema(spec)
    parts = sorted((out_dir / "parts").glob(f"{PART_PREFIX}*.parquet"))
    table = pa.concat_tables([pq.read_table(p, schema=schema) for p in parts])
    table = table.sort_by("sample").replace_schema_metadata(schema.metadata)
    ids = table.column("sample").to_numpy()
    if ids.size != spec.n_samples or np.any(ids != np.arange(spec.n_samples)):
        unique = np.unique(ids).size
        raise ConfigError(f"--out {out_dir}: the part files hold {ids.size} rows but "
                          f"{unique} distinct sample ids of {spec.n_samples}; delete "
                          f"{out_dir / 'parts'} to compute them again")
    write_atomic(table, out_dir / RESULTS)
    return table


def append_history(out_dir, rep):
    """Append this invocation's computing figures to DIR/runs.jsonl (one line per run)."""
    record = {"n_computed": rep.n_computed, "wall_s": rep.wall_s,
              "compute_wall_s": rep.compute_wall_s, "workers": rep.workers,
              "threads": rep.threads, "scheduler": rep.scheduler,
              "task_errors": len(rep.task_errors)}
    with open(out_dir / HISTORY, "a") as f:
        f.write(json.dumps(record) + "\n")


def read_history(out_dir):
    """Return the records of DIR/runs.jsonl (a torn last line, from a crash, is skipped)."""
    path = out_dir / HISTORY
    records = []
    if path.exists():
        for line in path.read_text().splitlines():
            try:
                records.append(json.loads(line))
            except ValueError:
                continue
    return records


@contextmanager
def _borrowed(client):
    yield client, client.scheduler.address


def run_sweep(spec, out_dir, workers=None, scheduler=None, processes=True, max_samples=None,
              progress=True, plots=True, log=None, client=None, max_in_flight=None,
              connect_timeout_s=None, memory_limit_mib=None):
    """
    Run (or resume) ``spec`` into ``out_dir``; return a RunReport.

    ``max_samples``: stop after saving about this many new samples (whole batches; a test
    and user hook for a bounded run, resumed by the next call).  When every batch is saved,
    the results are compacted and summarised (summary.json) and, with ``plots``, plotted.
    ``client``: an open distributed Client to use (left open) instead of a new cluster.
    ``max_in_flight``: batches submitted at a time (default: ``IN_FLIGHT_PER_THREAD`` per
    worker thread).  ``connect_timeout_s``: for ``scheduler`` (default
    ``CONNECT_TIMEOUT_S``).  ``memory_limit_mib``: refuse a sweep whose results need more
    (default ``config.MEMORY_LIMIT_MIB``).
    """
    from bb_friction_ros.sweep import report
    log = log or (lambda msg: print(msg, file=sys.stderr))
    t0 = time.perf_counter()
    check_results_memory(spec, memory_limit_mib)
    out_dir = Path(out_dir)
    parts_dir = out_dir / "parts"
    parts_dir.mkdir(parents=True, exist_ok=True)
    check_manifest(spec, out_dir)
    done = completed_batches(spec, parts_dir, log)
    n_resumed = sum(done.values())
    todo = [b for b in range(spec.n_batches) if b not in done]
    if n_resumed:
        log(f"sweep: resuming, {n_resumed} of {spec.n_samples} samples already saved")
    tally = Tally()
    rep = RunReport(out_dir=out_dir, n_samples=spec.n_samples, n_resumed=n_resumed,
                    n_computed=0, complete=False, wall_s=0.0, compute_wall_s=0.0, workers=0,
                    threads=0, scheduler=scheduler or "local", batches_submitted=tuple(todo))
    if todo:
        session = _borrowed(client) if client is not None \
            else dask_client(workers, scheduler, processes, connect_timeout_s)
        try:
            with session as (client, where):
                rep.scheduler = where
                info = client.scheduler_info()["workers"]
                rep.workers, rep.threads = len(info), sum(w["nthreads"] for w in info.values())
                bar = _progress(spec.n_samples, n_resumed, progress)
                t1 = time.perf_counter()
                try:
                    execute(client, spec, todo, parts_dir, bar, max_samples, tally,
                            max_in_flight)
                finally:
                    rep.compute_wall_s = time.perf_counter() - t1
                    bar.close()
        finally:    # also when interrupted: the history counts what was saved
            rep.n_computed, rep.task_errors = tally.saved, tuple(tally.errors)
            rep.wall_s = time.perf_counter() - t0
            append_history(out_dir, rep)
    else:
        rep.wall_s = time.perf_counter() - t0
    rep.complete = len(completed_batches(spec, parts_dir)) == spec.n_batches
    for batch, err in rep.task_errors:
        log(f"sweep: batch {batch} failed as a task ({err}); rerun to retry it")
    if rep.complete:
        table = compact(spec, out_dir)
        rep.summary = report.write_summary(spec, table, read_history(out_dir), out_dir)
        if plots:
            from bb_friction_ros.sweep import plots as plotting
            plotting.plot_all(spec, table, rep.summary, out_dir)
    else:
        log(f"sweep: {n_resumed + rep.n_computed} of {spec.n_samples} samples saved in "
            f"{out_dir}; run the same command again to resume")
    return rep
