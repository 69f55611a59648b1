"""
``bb-friction`` sub-commands of the sweep package: sweep, screw-verdict, linear-mitigate.

``add_sweep_parsers(subparsers)`` registers them on the main parser's sub-parsers.  Each
handler returns the exit status: 0 done (verdict: the nominal build passes), 1 the nominal
build fails the verdict, 3 the sweep is incomplete (``--max-samples`` reached or a task
failed; rerun to resume), 130 interrupted (saved batches are kept).  A bad spec raises
ConfigError, which the main CLI prints and turns into status 2.
"""

import argparse
import json
import math
import sys

from bb_friction_ros.config import MEMORY_LIMIT_MIB, ConfigError, load_linear_bearing
from bb_friction_ros.sweep import CONNECT_TIMEOUT_S, IN_FLIGHT_PER_THREAD

INCOMPLETE = 3
INTERRUPTED = 130


def _add_cluster_args(p):
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None,
                       help="worker processes of the local Dask cluster (default: all cores)")
    where.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                       help="address of an existing Dask scheduler (its workers need "
                       "bb_friction_ros installed)")
    p.add_argument("--connect-timeout-s", type=_positive(float), default=None, metavar="S",
                   help="how long --scheduler has to answer (default: "
                   f"{CONNECT_TIMEOUT_S:g} s)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    p.add_argument("--no-plots", action="store_true", help="write no PNG plots")


def _positive(kind):
    """Return an argparse type: a finite number > 0 of ``kind``, refused by its flag if not."""
    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            value = None
        if value is None or not math.isfinite(value) or value <= 0:
            raise argparse.ArgumentTypeError(f"must be a number > 0, got {text!r}")
        return value
    parse.__name__ = kind.__name__
    return parse


def add_sweep_parsers(subparsers):
    """Register ``sweep``, ``screw-verdict`` and ``linear-mitigate`` on ``subparsers``."""
    p = subparsers.add_parser("sweep", help="grid / Monte Carlo design study on Dask: "
                              "results.parquet, summary.json, plots (docs/sweeps.md)")
    p.add_argument("spec", metavar="SPEC.yaml", help="sweep specification")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="output directory; rerunning with the same DIR resumes")
    _add_cluster_args(p)
    p.add_argument("--max-samples", type=int, default=None, metavar="N",
                   help="stop after about N new samples (whole batches); rerun to resume")
    p.add_argument("--max-in-flight", type=_positive(int), default=None, metavar="N",
                   help="batches submitted at a time (default: "
                   f"{IN_FLIGHT_PER_THREAD} per worker thread); results are saved as they "
                   "finish and Ctrl-C cancels at most N")
    p.add_argument("--memory-limit-mib", type=_positive(float), default=MEMORY_LIMIT_MIB,
                   metavar="MIB", help="refuse a sweep whose results need more memory "
                   "(default: %(default)g MiB)")
    p.set_defaults(func=_run_sweep)

    p = subparsers.add_parser("screw-verdict", help="whole-screw torque-fluctuation verdict "
                              "(ISO 3408-3 spirit): nominal pass/fail and P(fail) under the "
                              "spec's tolerances")
    p.add_argument("spec", metavar="SPEC.yaml", help="whole_screw sweep spec with random "
                   "tolerances")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--band-pct", type=float, required=True,
                   help="allowed torque variation +-band around the reference [%%]")
    p.add_argument("--reference-torque-nm", type=float, default=None,
                   help="reference (nominal drag) torque [N m]; default: each run's mean")
    _add_cluster_args(p)
    p.add_argument("--json", action="store_true", help="print the verdict as JSON")
    p.set_defaults(func=_run_verdict)

    p = subparsers.add_parser("linear-mitigate", help="linear bearing: carriage deviations "
                              "matched to measured rail deviations (Eq. 22), B2B friction "
                              "before and after")
    p.add_argument("--dbeta-bl-deg", type=float, nargs="+", required=True,
                   help="measured bottom-left deviation(s), one per station [deg]")
    p.add_argument("--dbeta-br-deg", type=float, nargs="+", required=True,
                   help="measured bottom-right deviation(s), one per station [deg]")
    p.add_argument("--dbeta-tr-deg", type=float, default=0.0,
                   help="present top-right (carriage) deviation [deg]")
    p.add_argument("--dbeta-tl-deg", type=float, default=0.0,
                   help="present top-left (carriage) deviation [deg]")
    p.add_argument("--rho", type=float, nargs="+", default=None,
                   help="side force ratio(s) to predict at (default: the config's)")
    p.add_argument("--config", help="YAML with a 'linear_bearing' mapping")
    p.add_argument("--json", action="store_true", help="print exactly one JSON object")
    p.set_defaults(func=_run_mitigate)


def _check_workers(args):
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers: must be >= 1, got {args.workers}")


def _run_sweep(args):
    from bb_friction_ros.sweep.engine import run_sweep
    from bb_friction_ros.sweep.spec import load_spec
    _check_workers(args)
    if args.max_samples is not None and args.max_samples < 1:
        raise ConfigError(f"--max-samples: must be >= 1, got {args.max_samples}")
    spec = load_spec(args.spec)
    try:
        rep = run_sweep(spec, args.out, workers=args.workers, scheduler=args.scheduler,
                        max_samples=args.max_samples, progress=not args.no_progress,
                        plots=not args.no_plots, max_in_flight=args.max_in_flight,
                        connect_timeout_s=args.connect_timeout_s,
                        memory_limit_mib=args.memory_limit_mib)
    except KeyboardInterrupt:
        print(f"sweep: interrupted; saved batches are kept in {args.out}: run the same "
              "command again to resume", file=sys.stderr)
        return INTERRUPTED
    if not rep.complete:
        return INCOMPLETE
    s = rep.summary
    rate = rep.samples_per_s
    print(f"{s['n_samples']} samples ({s['n_ok']} ok, {s['n_invalid']} invalid, "
          f"{s['n_nonconverged']} not converged, {s['n_failed']} failed) in {args.out}; "
          f"{rep.n_computed} computed now in {rep.wall_s:.1f} s"
          + (f" ({rate:.1f} samples/s on {rep.workers} workers)" if rate else ""))
    return 0


def _run_verdict(args):
    from bb_friction_ros.sweep.spec import load_spec
    from bb_friction_ros.sweep.verdict import run_verdict
    _check_workers(args)
    if not math.isfinite(args.band_pct):
        raise ConfigError(f"--band-pct: must be finite, got {args.band_pct}")
    spec = load_spec(args.spec)
    try:
        result = run_verdict(spec, args.out, args.band_pct / 100.0, args.reference_torque_nm,
                             workers=args.workers, scheduler=args.scheduler,
                             progress=not args.no_progress, plots=not args.no_plots,
                             connect_timeout_s=args.connect_timeout_s)
    except KeyboardInterrupt:
        print(f"screw-verdict: interrupted; rerun to resume ({args.out})", file=sys.stderr)
        return INTERRUPTED
    if result is None:
        return INCOMPLETE
    if args.json:
        print(json.dumps(result))
    else:
        print(f"criterion: {result['criterion']}; band +-{args.band_pct:g} %, reference: "
              f"{result['reference']}")
        for row in result["rows"]:
            where = ", ".join(f"{k} = {v:g}" for k, v in row["grid_point"].items())
            nom = row["nominal_variation_rel"]
            verdict = {True: "PASS", False: "FAIL", None: "NO RESULT"}[row["nominal_pass"]]
            ci = row["p_fail_ci95"]
            p = row["p_fail"]
            print((f"[{where}] " if where else "")
                  + f"nominal: {verdict}"
                  + (f" (variation {nom * 100:.2f} %)" if nom is not None else "")
                  + (f"; P(fail) = {p:.3f} (95 % CI {ci[0]:.3f}-{ci[1]:.3f}) over "
                     f"{row['n_with_result']} builds" if p is not None else "")
                  + (f", {row['n_missing']} without result" if row["n_missing"] else ""))
    return 0 if result["nominal_pass"] else 1


def _run_mitigate(args):
    from bb_friction_ros.sweep.advisor import advise, format_advice
    cfg = load_linear_bearing(args.config)
    result = advise(cfg, [math.radians(x) for x in args.dbeta_bl_deg],
                    [math.radians(x) for x in args.dbeta_br_deg], args.rho,
                    (math.radians(args.dbeta_tr_deg), math.radians(args.dbeta_tl_deg)))
    if args.json:
        print(json.dumps(result))
    else:
        print("\n".join(format_advice(result)))
    return 0
