"""
``bb-friction discrepancy BAG_OR_CSV --out DIR``: the discrepancy workflow.

``add_discrepancy_parser(subparsers)`` registers it on the main parser's sub-parsers.  Exit
status: 0 analysed (summary.json says ``found`` or ``none``); 2 the input is unreadable or
lacks a measured torque (message on stderr), or the recording is too short or too flat to
tell (summary.json ``reason``/``missing`` and report.md say what is missing).  A bad config
or settings file raises ConfigError, which the main CLI prints with status 2.
"""

import json
import sys

# --baseline choices: "model" predicts with the ball-screw model, "zero" has no model (every
# term is identified from the measured torque).  Here, not in data.py: parsing the command
# line must not import the model stack.
BASELINES = ("model", "zero")


def add_discrepancy_parser(subparsers):
    """Register ``discrepancy`` on ``subparsers``."""
    from bb_friction_ros.cli_flags import add_topic_arguments
    p = subparsers.add_parser(
        "discrepancy", help="where and why measured friction differs from the model: "
        "residual per regime, physically named empirical terms, augmented.yaml, held-out "
        "RMSE before/after (docs/discrepancy.md)")
    p.add_argument("input", metavar="BAG_OR_CSV", help="rosbag2 directory (sqlite3 or mcap) "
                   "with measured_torque, or a CSV with t_s, nut_angle_rad, "
                   "nut_velocity_rad_s, axial_load_n, torque_meas_nm [, torque_pred_nm]")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--config", help="ball-screw YAML of the model (default: bundled "
                   "config/ball_screw.yaml); the base of DIR/augmented.yaml")
    p.add_argument("--settings", help="YAML with a 'discrepancy' mapping: thresholds and grids "
                   "(docs/discrepancy.md)")
    p.add_argument("--nut-joint", default="nut_joint", help="joint name in nut_state")
    p.add_argument("--model-rate-hz", type=float, default=100.0,
                   help="model steps per second of input time (as replay and the node)")
    add_topic_arguments(p)
    p.add_argument("--recompute-prediction", action="store_true",
                   help="CSV input: run the model even if the CSV has torque_pred_nm")
    p.add_argument("--validate", metavar="DATA2", help="a second recording (bag or CSV): the "
                   "augmented model is applied to it without refitting; writes "
                   "DIR/validation/prediction.csv and summary.json['validation']")
    p.add_argument("--baseline", choices=BASELINES, default="model",
                   help="model: residual = measured - the ball-screw model; zero: no model of "
                   "this screw, every term is identified from the measured torque (a CSV "
                   "whose torque_pred_nm is 0 does the same)")
    p.add_argument("--torque-constant-nm-per-a", type=float, metavar="K",
                   help="the measured torque is K [N m/A] times the motor current: the CSV "
                   "column motor_current_a, or the bag topic --current-topic")
    p.add_argument("--current-topic", default="motor_current",
                   help="bag topic of the motor current (std_msgs/Float64 or Float32, A; "
                   "its log time, put on the motion's clock through the nut states' log "
                   "times), read with --torque-constant-nm-per-a")
    physical = p.add_mutually_exclusive_group()
    physical.add_argument("--physical", action="store_true",
                          help="try the model's own parameters (contact-angle deviation, "
                               "friction coefficient, preload) as candidates: ~18-24 model "
                               "runs over the recording (settings discrepancy.physical).  On "
                               "by default whenever a model of the screw is in use; given "
                               "explicitly, a run that cannot try them says why")
    physical.add_argument("--no-physical", action="store_true",
                          help="do not try the model's own parameters: empirical terms only")
    p.add_argument("--no-plots", action="store_true", help="write no PNG figures")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--json", action="store_true", help="print summary.json to stdout")
    p.set_defaults(func=run_discrepancy_command)


def run_discrepancy_command(args):
    """Handle ``bb-friction discrepancy``; return the exit status."""
    from bb_friction_ros.cli_flags import topics_from_args
    from bb_friction_ros.discrepancy.data import InputProblem
    from bb_friction_ros.discrepancy.settings import load_settings
    from bb_friction_ros.discrepancy.workflow import OutputInUse, run_discrepancy
    from bb_friction_ros.node_parameters import NodeParameters
    settings = load_settings(args.settings)
    if args.physical or args.no_physical:
        import dataclasses
        settings = dataclasses.replace(settings, physical=dataclasses.replace(
            settings.physical, enabled=bool(args.physical)))
    replay_settings = NodeParameters(nut_joint=args.nut_joint,
                                     model_rate_hz=args.model_rate_hz)
    try:
        status, summary = run_discrepancy(
            args.input, args.out, config=args.config, settings=settings,
            replay_settings=replay_settings, topics=topics_from_args(args),
            recompute=args.recompute_prediction, plots=not args.no_plots,
            progress=not args.no_progress, validate_path=args.validate,
            baseline=args.baseline, torque_constant_nm_per_a=args.torque_constant_nm_per_a,
            current_topic=args.current_topic, physical_asked=args.physical)
    except (InputProblem, OutputInUse) as exc:
        print(f"bb-friction discrepancy: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:       # also from inside a model step (runner.interrupted)
        print(f"bb-friction discrepancy: interrupted; the outputs in {args.out} are partial "
              "(summary.json: \"complete\": false)", file=sys.stderr)
        return 130
    if args.json:
        print(json.dumps(summary, indent=2))
    if status == 2:
        print("bb-friction discrepancy: the recording cannot tell (verdict none):",
              file=sys.stderr)
        for m in summary["missing"]:
            print(f"  - {m}", file=sys.stderr)
    elif not args.json:
        effects = ", ".join(e["name"] for e in summary["effects"]) or "-"
        print(f"verdict: {summary['verdict']} ({effects}); held-out RMSE "
              f"{summary['rmse_before_nm']:.4g} -> {summary['rmse_after_nm']:.4g} N m; noise "
              f"{summary['noise_std_nm']:.3g} N m")
        v = summary.get("validation")
        if v:
            print(f"validation on {v['input']}: RMSE {v['rmse_before_nm']:.4g} -> "
                  f"{v['rmse_after_nm']:.4g} N m; relative error "
                  f"{v['relative_error_before']:.3g} -> {v['relative_error_after']:.3g}")
    print(f"outputs in {args.out}", file=sys.stderr if args.json else sys.stdout)
    return status
