"""
Command-line interface: ``bb-friction <command>``.

Commands and their flags are contracts that users script against: add, never rename.
"""

import argparse
import errno
import json
import math
import os
from pathlib import Path
import sys

from bb_friction_ros import __version__
from bb_friction_ros.ball_screw import cli as screw_cli
from bb_friction_ros.discrepancy import cli as discrepancy_cli
from bb_friction_ros.servo import cli as servo_cli
from bb_friction_ros.sweep import cli as sweep_cli
from bb_friction_ros.config import BBFrictionError, ConfigError, load_linear_bearing


# errno values of a write that ran out of room: disk or quota full, file-size limit.
OUT_OF_SPACE = frozenset((errno.ENOSPC, errno.EDQUOT, errno.EFBIG))


def _int_at_least(lo):
    """Return an argparse type: an integer >= ``lo`` (a bad value exits 2 naming the flag)."""
    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < lo:
            raise argparse.ArgumentTypeError(f"must be >= {lo}, got {value}")
        return value
    return parse


def _positive_float(text):
    """Argparse type: a finite number > 0 (NaN, inf, 0 and negatives exit 2)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text}")
    return value


class OutputPathError(BBFrictionError):
    """An output path that cannot be written; the message names it."""


def check_out(path, new=False):
    """
    Check an output path before any work: a directory we may create or write into.

    ``new``: the path must not exist yet (a rosbag2 directory is created by its writer and
    never overwritten).  Nothing is created here, so a refused run leaves no trace.
    """
    path = Path(path)
    if new and (path.exists() or path.is_symlink()):
        raise OutputPathError(f"{path}: exists already; choose another path or delete it")
    if path.exists() and not path.is_dir():
        raise OutputPathError(f"{path}: is a file, not a directory")
    probe = path
    while not probe.exists():       # the nearest existing ancestor must be a writable dir
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise OutputPathError(f"{path}: {probe} is a file, not a directory")
    if probe.exists() and not os.access(probe, os.W_OK | os.X_OK):
        raise OutputPathError(f"{path}: {probe} is not writable")


def _add_linear_parser(sub):
    p = sub.add_parser("linear", help="two balls in a four-point-contact linear bearing "
                       "(paper Sec. 2.4)")
    p.add_argument("--config", help="YAML with a 'linear_bearing' mapping (default: built-in "
                   "Table 1 values)")
    p.add_argument("--theta-deg", type=float, default=2.0,
                   help="bottom-groove contact-angle deviation theta (dbeta_BL = -theta, "
                   "dbeta_BR = +theta) [deg]")
    p.add_argument("--rho", type=float, default=None,
                   help="side force ratio N_x/N_y on ball 1 (ball 2 gets -rho)")
    p.add_argument("--ny-n", type=float, default=None, help="vertical load per ball [N]")
    p.add_argument("--mu", type=float, default=None, help="friction coefficient")
    p.add_argument("--v-mm-s", type=float, default=None, help="top-groove velocity [mm/s]")
    p.add_argument("--dbeta-tr-deg", type=float, default=0.0,
                   help="top-right contact-angle deviation [deg]")
    p.add_argument("--dbeta-tl-deg", type=float, default=0.0,
                   help="top-left contact-angle deviation [deg]")
    p.add_argument("--model", choices=("numerical", "analytical"), default="numerical")
    p.add_argument("--json", action="store_true", help="print exactly one JSON object")
    p.set_defaults(func=_run_linear)


def _run_linear(args):
    from bb_friction_ros.linear_bearing.case_study import LinearPairCase
    overrides = {}
    for key, value in (("side_force_ratio", args.rho), ("vertical_load_n", args.ny_n),
                       ("friction_coefficient", args.mu),
                       ("groove_velocity_m_s", None if args.v_mm_s is None
                        else args.v_mm_s * 1e-3)):
        if value is not None:
            overrides[key] = value
    cfg = load_linear_bearing(args.config, overrides)
    for name in ("theta_deg", "dbeta_tr_deg", "dbeta_tl_deg"):
        value = getattr(args, name)
        if not math.isfinite(value) or abs(value) >= 90.0:
            raise ConfigError(f"--{name.replace('_', '-')}: must be finite and within "
                              f"(-90, 90) deg, got {value}")
    case = LinearPairCase(cfg)
    run = case.numerical if args.model == "numerical" else case.analytical
    import numpy as np
    with np.errstate(over="ignore", invalid="ignore"):   # an overflow is flagged in res
        res = run(math.radians(args.theta_deg), cfg.side_force_ratio,
                  math.radians(args.dbeta_tr_deg), math.radians(args.dbeta_tl_deg))
    if args.json:
        print(json.dumps(res.as_json(), allow_nan=False))
    elif not res.converged:
        print("NOT CONVERGED: " + "; ".join(res.notes), file=sys.stderr)
    else:
        rows = [("model", res.model),
                ("eps_1 (ball 1 alone)", f"{res.eps[0] * 100:+.4f} %"),
                ("eps_2 (ball 2 alone)", f"{res.eps[1] * 100:+.4f} %"),
                ("F_B2B", f"{res.f_b2b_n:.4f} N"),
                ("P_f (ball-groove, no B2B)", f"{res.p_f_w * 1e3:.4f} mW"),
                ("P_fB2B", f"{res.p_b2b_w * 1e3:.4f} mW"),
                ("(P_f + P_fB2B) / P_f", f"{(res.p_f_w + res.p_b2b_w) / res.p_f_w * 100:.2f} %"),
                ("converged", str(res.converged)),
                ("valid", "yes" if res.valid else "NO: " + "; ".join(res.notes)),
                ("solve time", f"{res.solve_time_s * 1e3:.3f} ms")]
        width = max(len(r[0]) for r in rows)
        for k, v in rows:
            print(f"{k:<{width}}  {v}")
    return 0 if res.converged else 3


def _add_reproduce_parser(sub):
    p = sub.add_parser("reproduce", help="reproduce the paper's tables and figures: "
                       "report.md, reproduction.json, PNGs")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--config", help="YAML with a 'linear_bearing' mapping (default: Table 1)")
    p.add_argument("--grid", type=_int_at_least(2), default=25,
                   help="theta and rho points of the Figs. 8-9 maps (numerical model; >= 2)")
    p.set_defaults(func=_run_reproduce)


def _run_reproduce(args):
    from bb_friction_ros.reproduce import reproduce
    report = reproduce(args.out, load_linear_bearing(args.config), grid=args.grid)
    print(f"report: {report}")
    return 0


def _add_replay_parser(sub):
    from bb_friction_ros.cli_flags import add_topic_arguments
    p = sub.add_parser("replay", help="run a rosbag2 recording (sqlite3 or mcap) through the "
                       "live node's model path, offline")
    p.add_argument("bag", help="rosbag2 directory")
    p.add_argument("--config", help="ball-screw YAML (default: bundled config/ball_screw.yaml)")
    p.add_argument("--params-file", help="the node's ROS params file (friction_node: "
                   "ros__parameters): every node parameter in it is read, config_file "
                   "included; the flags below override it")
    p.add_argument("--nut-joint", help="joint name in nut_state (overrides the params file)")
    p.add_argument("--model-rate-hz", type=float, help="least model steps per second of input "
                   "time (the floor when the nut creeps or stands)")
    p.add_argument("--model-step-deg", type=float, help="nut rotation between model steps")
    add_topic_arguments(p)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--no-bag", action="store_true", help="write no output bag (DIR/bag/), "
                   "only the CSV, summary and plots")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_run_replay)


def _replay_settings(args):
    """Return the node's parameters for replay: the params file, then the flags (checked)."""
    from bb_friction_ros.node_parameters import load_params_file, NODE_NAME, node_parameters

    def warn(name):
        print(f"bb-friction replay: warning: {args.params_file}: unknown parameter "
              f"{NODE_NAME}.{name} ignored", file=sys.stderr)

    settings = load_params_file(args.params_file, warn) if args.params_file else None
    changes = {}
    if args.nut_joint:
        changes["nut_joint"] = args.nut_joint
    if args.model_rate_hz is not None:
        changes["model_rate_hz"] = args.model_rate_hz
    if getattr(args, "model_step_deg", None) is not None:
        changes["model_step_deg"] = args.model_step_deg
    return node_parameters(changes, *([settings] if settings else []))


def _run_replay(args):
    from bb_friction_ros.cli_flags import topics_from_args
    from bb_friction_ros.replay import replay
    settings = _replay_settings(args)
    try:
        summary = replay(args.bag, args.out, config=args.config, settings=settings,
                         topics=topics_from_args(args), progress=not args.no_progress,
                         write_bag=not args.no_bag)
    except (FileNotFoundError, BBFrictionError) as exc:   # BagError, NothingAccepted included
        print(f"bb-friction replay: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:      # no traceback; summary.json says complete: false
        print(f"bb-friction replay: interrupted; the outputs in {args.out} are partial "
              "(summary.json: \"complete\": false)", file=sys.stderr)
        return 130
    print(json.dumps({k: summary[k] for k in ("samples", "rejected", "nonconverged_steps",
                                              "speed_vs_realtime")
                      + (("rmse_nm",) if "rmse_nm" in summary else ())}))
    print(f"outputs in {args.out}")
    return 0


def _add_node_parser(sub):
    p = sub.add_parser("node", help="start the live friction_node (same as the friction_node "
                       "console script)")
    p.add_argument("--params-file", help="ROS params file with friction_node: ros__parameters")
    p.set_defaults(func=_run_node)


def _run_node(args):
    from bb_friction_ros.node_entry import main as node_main
    ros_args = ["--ros-args"] + (["--params-file", args.params_file] if args.params_file
                                 else [])
    return node_main(["bb-friction-node"] + ros_args)


def _add_feedforward_parser(sub):
    p = sub.add_parser("feedforward", help="friction feedforward along a planned trajectory: "
                       "each row's torque at its own time (a controller plays it back)")
    p.add_argument("trajectory", help="CSV with t_s, nut_angle_rad, nut_velocity_rad_s, "
                   "axial_load_n (the plan), or a rosbag2 directory with nut_state and "
                   "axial_load")
    p.add_argument("--config", help="ball-screw YAML or a discrepancy augmented.yaml "
                   "(default: bundled config/ball_screw.yaml)")
    p.add_argument("--settings", help="YAML with a 'feedforward' mapping: breakaway_lead_s, "
                   "model_step_deg")
    p.add_argument("--nut-joint", default="nut_joint", help="joint name in a bag's nut_state")
    p.add_argument("--out", required=True, help="output directory: feedforward.csv, "
                   "summary.json")
    p.set_defaults(func=_run_feedforward)


def _run_feedforward(args):
    from bb_friction_ros.config import bundled_config, load_section
    from bb_friction_ros.planned import (load_planned_settings, planned_feedforward,
                                         read_trajectory, write_feedforward)
    settings = load_planned_settings(load_section(args.settings, "feedforward")
                                     if args.settings else None)
    config = args.config or bundled_config("ball_screw.yaml")
    t, phi, w, load = read_trajectory(args.trajectory, args.nut_joint)
    ff = planned_feedforward(t, phi, w, load, config, settings)
    summary = write_feedforward(args.out, ff, config, args.trajectory)
    print(json.dumps({k: summary[k] for k in ("rows", "breakaway_rows", "nonconverged_rows",
                                              "max_abs_torque_ff_nm")}))
    print(f"outputs in {args.out}")
    return 0 if summary["nonconverged_rows"] == 0 else 1


def _add_demo_parsers(sub):
    p = sub.add_parser("make-demo-bag", help="generate the demo recording (reversing nut "
                       "motion, varying load, synthetic measured torque)")
    p.add_argument("--out", required=True, help="bag directory to create (must not exist)")
    p.add_argument("--storage", choices=("sqlite3", "mcap"), default="mcap")
    p.add_argument("--recording", help="demo_recording YAML (default: bundled)")
    p.set_defaults(func=_run_make_demo_bag, out_is_new=True)
    p = sub.add_parser("demo", help="play the demo recording through the live node "
                       "in-process, then replay it; write reports")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--speed", type=_positive_float, default=1.0,
                   help="playback speed factor (> 0)")
    p.set_defaults(func=_run_demo)


def _run_make_demo_bag(args):
    from bb_friction_ros.bags import write_events
    events = _demo_events(args.recording)
    write_events(args.out, events, storage=args.storage)
    print(f"demo recording: {args.out} ({sum(e.kind == 'nut_state' for e in events)} "
          "nut_state messages)")
    return 0


def _demo_events(recording=None):
    from bb_friction_ros.config import bundled_config
    from bb_friction_ros.trajectories import load_demo_recording, make_demo_events
    from bb_friction_ros.node_parameters import NodeParameters
    from bb_friction_ros.replay import run_events
    from bb_friction_ros.runner import build_runner, InputAssembler
    cfg = load_demo_recording(recording or bundled_config("demo_recording.yaml"))
    settings = NodeParameters(nut_joint=cfg.nut_joint)

    def predict(events):
        runner = build_runner(bundled_config("ball_screw.yaml"), settings.model_rate_hz)
        assembler = InputAssembler(settings.nut_joint, settings.max_axial_load_n)
        return [p.torque_total_nm for p in run_events(events, runner, assembler)]

    return make_demo_events(cfg, predict)


def _run_demo(args):
    import os
    from pathlib import Path
    from bb_friction_ros.demo import run_demo
    from bb_friction_ros.interface import local_domain_id, ros_log_dir_problem
    # DDS stays on this machine, on a domain of this run's own (set before rclpy.init).
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("ROS_DOMAIN_ID", str(local_domain_id()))
    problem = ros_log_dir_problem()
    if problem:     # an unwritable HOME: rclpy.init would fail with an RCLError traceback
        os.environ["ROS_LOG_DIR"] = str(Path(args.out).resolve() / "ros_log")
        print(f"bb-friction demo: {problem}; logging into {os.environ['ROS_LOG_DIR']}",
              file=sys.stderr)
    try:
        return run_demo(Path(args.out), _demo_events(), speed=args.speed)
    except KeyboardInterrupt:
        print(f"bb-friction demo: interrupted; the outputs in {args.out} are partial",
              file=sys.stderr)
        # DDS's own threads may still run (rclpy's context is shut down by the same SIGINT):
        # a normal interpreter exit then aborts ("terminate called without an active
        # exception", status 134); nothing is left to write, so leave at once.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)


def build_parser():
    """Return the top-level argument parser with one sub-parser per command."""
    parser = argparse.ArgumentParser(prog="bb-friction", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=__version__)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_linear_parser(sub)
    _add_reproduce_parser(sub)
    _add_replay_parser(sub)
    _add_node_parser(sub)
    _add_demo_parsers(sub)
    _add_feedforward_parser(sub)
    screw_cli.add_screw_pair_parser(sub)
    screw_cli.add_screw_sim_parser(sub)
    discrepancy_cli.add_discrepancy_parser(sub)
    servo_cli.add_servo_parser(sub)
    sweep_cli.add_sweep_parsers(sub)
    return parser


def main(argv=None):
    """Entry point of the ``bb-friction`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        # One check of --out for every sub-command that writes, before any work.
        if getattr(args, "out", None) is not None:
            check_out(args.out, new=getattr(args, "out_is_new", False))
        return args.func(args)
    except OutputPathError as exc:
        print(f"bb-friction {args.command}: --out {exc}", file=sys.stderr)
        return 2
    except ConfigError as exc:
        print(f"bb-friction: config error: {exc}", file=sys.stderr)
        return 2
    except BBFrictionError as exc:
        # Bad user input of any kind (one base class): the message, no traceback.  Any other
        # exception, a ValueError from numpy included, is a bug and keeps its traceback.
        print(f"bb-friction {args.command}: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        where = exc.filename
        if where is None and exc.errno in OUT_OF_SPACE and getattr(args, "out", None):
            # A write() on an open file fails without a filename:
            # the run's output directory is where the space ran out.
            where = args.out
        if where is None:
            raise
        # Disk full, permissions changed mid-run, ...: name the file, no traceback.
        print(f"bb-friction {args.command}: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
