"""
``bb-friction servo-test RECORDING --loop LOOP.yaml --config MODEL --out DIR``: the servo test.

``add_servo_parser(subparsers)`` registers it on the main parser's sub-parsers.  Exit
status: 0 done (summary.json, report.md, modes/<mode>.csv); 2 a bad recording, spec, loop
file, model file or mode (the message names it).  docs/servo_test.md explains the plant, the
loop, the modes and the fits.
"""

import json
import sys


def add_servo_parser(subparsers):
    """Register ``servo-test`` on ``subparsers``."""
    from bb_friction_ros.servo.modes import ALL_MODES, BASE_MODES
    p = subparsers.add_parser(
        "servo-test", help="closed-loop servo test: following error, reversal glitches, "
        "cruise ripple and the ISO 230-4 circle with each friction feedforward, against a "
        "measured loop (docs/servo_test.md)")
    p.add_argument("recording", metavar="RECORDING", help="CSV with t_s, nut_angle_ref_rad "
                   "[, nut_angle_rad, torque_meas_nm, command_offset_nm, axial_load_n], one "
                   "row per servo sample; or a YAML reference spec (reference: kind: "
                   "reversal | constant_speed | circle)")
    p.add_argument("--loop", required=True, metavar="LOOP.yaml", help="loop: and plant: "
                   "sections (rate, gains, limit, inertia)")
    p.add_argument("--config", required=True, metavar="CONFIG_OR_MODEL_FILE",
                   help="the product's model file (what replay accepts, augmented.yaml "
                   "included); also the plant's unless --plant is given")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--modes", nargs="+", metavar="MODE", default=None,
                   help=f"feedforward modes (none always runs; default: "
                   f"{' '.join(BASE_MODES)}; all: {' '.join(ALL_MODES)})")
    p.add_argument("--plant", metavar="MODEL_FILE", help="the plant's model file, when the "
                   "axis differs from the product's model (a study: hidden effects)")
    p.add_argument("--config-y", metavar="MODEL_FILE", help="circle test: the Y axis's model "
                   "file (default: --config for both axes)")
    p.add_argument("--calibration", metavar="CSV", help="recording the baselines and the "
                   "rigid-body reference are fitted on (t_s, nut_angle_rad, torque_meas_nm "
                   "[, nut_velocity_rad_s]); default: a calibration run of the plant")
    p.add_argument("--measured-loop", action="store_true", help="require the recording's "
                   "nut_angle_rad and torque_meas_nm (the check against the measured loop)")
    p.add_argument("--no-safety-gate", action="store_true", help="a study of what the "
                   "feedforward safety gate costs: every mode's feedforward passes as computed "
                   "(a sign against its motion included), still counted; never what a "
                   "controller should run")
    p.add_argument("--no-plots", action="store_true", help="write no PNG figures")
    p.add_argument("--no-progress", action="store_true", help="no progress messages")
    p.add_argument("--json", action="store_true", help="print summary.json to stdout")
    p.set_defaults(func=run_servo_command)


def run_servo_command(args):
    """Handle ``bb-friction servo-test``; return the exit status."""
    from bb_friction_ros.servo.workflow import run_servo_test
    summary = run_servo_test(args.recording, args.loop, args.config, args.out,
                             modes=args.modes or (), progress=not args.no_progress,
                             plant=args.plant, calibration=args.calibration,
                             config_y=args.config_y, plots=not args.no_plots,
                             measured_loop=args.measured_loop,
                             safety_gate=not args.no_safety_gate)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print(summary["verdict"])
        ml = summary.get("measured_loop")
        if ml:
            n = ml["none"]
            print(f"measured loop: relative error angle {n['angle']:.3g}, velocity "
                  f"{n['velocity']:.3g}, torque {n['torque']:.3g}", end="")
            if ml.get("rigid_body"):
                print(f" (rigid-body reference: torque {ml['rigid_body']['torque']:.3g})")
            else:
                print(f" (no rigid-body reference: {ml['rigid_body_source']})")
    print(f"outputs in {args.out}", file=sys.stderr if args.json else sys.stdout)
    return 0
