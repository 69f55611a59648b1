"""
Sub-commands ``screw-pair`` (Table 5 two-ball module) and ``screw-sim`` (Sec. 3.4).

Registered on the main parser by ``add_screw_pair_parser`` and ``add_screw_sim_parser``.
A bad configuration exits with status 2 and names the key; a solver that did not converge is
reported as ``"converged": false`` (and exit status 1), never silently.
"""

import json
import math
import sys

from bb_friction_ros.config import ConfigError

DEFAULT_CONFIG = None    # built-in defaults equal config/ball_screw.yaml


def _load(args, overrides=None):
    """Load the ball screw config named by ``--config`` with command-line overrides."""
    from bb_friction_ros.model_file import load_ball_screw
    return load_ball_screw(args.config, overrides)


def _screw_pair(args):
    """Run the two-ball module and print its Table 5 quantities."""
    from bb_friction_ros.ball_screw.module import solve_two_ball_module
    from bb_friction_ros.ball_screw.screw_model import ScrewModel
    over = {"operation": {}}
    if args.axial_load_n is not None:
        over["operation"]["module_axial_load_n"] = args.axial_load_n
    if args.theta1_deg is not None:
        over["operation"]["module_theta1_deg"] = args.theta1_deg
    if args.theta2_deg is not None:
        over["operation"]["module_theta2_deg"] = args.theta2_deg
    try:
        cfg = _load(args, over)
    except ConfigError as exc:
        print(f"bb-friction screw-pair: {exc}", file=sys.stderr)
        return 2
    op = cfg.operation
    res = solve_two_ball_module(ScrewModel(cfg), op.module_theta1_rad, op.module_theta2_rad,
                                op.module_axial_load_n)
    out = {"f_b2b_n": res.f_b2b_n, "friction_increase": res.friction_increase,
           "torque_nm": res.torque_nm, "torque_no_b2b_nm": res.torque_no_b2b_nm,
           "loss_w": res.loss_w, "converged": res.converged,
           "solve_time_s": res.solve_time_s}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"two-ball module: theta = {math.degrees(op.module_theta1_rad):g} / "
              f"{math.degrees(op.module_theta2_rad):g} deg, W = {op.module_axial_load_n:g} N")
        print(f"  F_B2B              {res.f_b2b_n:.4f} N  (rear ball {res.rear_ball})")
        print(f"  friction increase  {100 * res.friction_increase:.2f} %")
        print(f"  T_f with / without B2B  {1e3 * res.torque_nm:.4f} / "
              f"{1e3 * res.torque_no_b2b_nm:.4f} N mm")
        print(f"  loss               {res.loss_w:.6g} W")
        print(f"  converged          {res.converged}  ({1e3 * res.solve_time_s:.1f} ms)")
    return 0 if res.converged else 1


def _screw_sim(args):
    """Run the whole-screw simulation and write its outputs."""
    from bb_friction_ros.ball_screw.simulation import run_whole_screw, summarize, \
        write_outputs
    over = {}
    if args.steps is not None:
        over = {"operation": {"n_steps": args.steps}}
    try:
        cfg = _load(args, over)
    except ConfigError as exc:
        print(f"bb-friction screw-sim: {exc}", file=sys.stderr)
        return 2
    results, screw = run_whole_screw(cfg)
    summary = summarize(results, screw.separation)
    write_outputs(results, summary, screw.separation, screw.loop, args.out)
    print(json.dumps(summary, indent=2))
    return 0 if summary["all_converged"] else 1


def _add_config(p):
    p.add_argument("--config", default=DEFAULT_CONFIG,
                   help="ball screw YAML (default: built-in values of config/ball_screw.yaml)")


def add_screw_pair_parser(subparsers):
    """Register ``screw-pair``: Table 5 two-ball module with B2B contact."""
    p = subparsers.add_parser("screw-pair", help="two-ball ball screw module (Table 5)")
    _add_config(p)
    p.add_argument("--theta1-deg", type=float, default=None, help="theta of ball 1 [deg]")
    p.add_argument("--theta2-deg", type=float, default=None, help="theta of ball 2 [deg]")
    p.add_argument("--axial-load-n", type=float, default=None,
                   help="axial load shared by the two balls [N]")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_screw_pair)
    return p


def add_screw_sim_parser(subparsers):
    """Register ``screw-sim``: whole ball screw with B2B contact (Sec. 3.4, Figs. 20-21)."""
    p = subparsers.add_parser("screw-sim", help="whole ball screw simulation (Sec. 3.4)")
    _add_config(p)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--steps", type=int, default=None,
                   help="override operation.n_steps (same step size: a shorter run)")
    p.set_defaults(func=_screw_sim)
    return p
