"""
Sub-commands ``screw-pair`` (Table 5 two-ball module) and ``screw-sim`` (Sec. 3.4).

Registered on the main parser by ``add_screw_pair_parser`` and ``add_screw_sim_parser``.
A bad configuration exits with status 2 and names the key; a solver that did not converge is
reported as ``"converged": false`` (and exit status 1), never silently.
"""

import dataclasses
import json
import math
import sys

from bb_friction_ros.config import ConfigError

DEFAULT_CONFIG = None    # built-in defaults equal config/ball_screw.yaml


def _load(args):
    """Load the ball screw config named by ``--config`` (default: built-in values)."""
    from bb_friction_ros.model_file import load_ball_screw
    return load_ball_screw(args.config)


def _with_flags(cfg, flags):
    """
    Return ``cfg`` with ``operation`` fields set from command-line flags.

    ``flags``: (flag, field, value in SI) for the flags given.  A flag overrides the file
    whatever spelling the file uses (``module_theta1_deg`` or ``_rad``); each value is
    range-checked as a config value and a bad one is refused by its flag.
    """
    from bb_friction_ros.config import validate
    op = cfg.operation
    for flag, name, value, shown in flags:
        try:
            op = dataclasses.replace(op, **{name: value})
            validate(op, "operation")
        except (ConfigError, TypeError) as exc:
            raise ConfigError(f"{flag} {shown}: {exc}") from exc
    return dataclasses.replace(cfg, operation=op)


def _screw_pair(args):
    """Run the two-ball module and print its Table 5 quantities."""
    from bb_friction_ros.ball_screw.module import solve_two_ball_module
    from bb_friction_ros.ball_screw.screw_model import ScrewModel
    flags = [(flag, name, conv(value), value) for flag, name, value, conv in (
        ("--axial-load-n", "module_axial_load_n", args.axial_load_n, float),
        ("--theta1-deg", "module_theta1_rad", args.theta1_deg, math.radians),
        ("--theta2-deg", "module_theta2_rad", args.theta2_deg, math.radians))
        if value is not None]
    try:
        cfg = _with_flags(_load(args), flags)
    except ConfigError as exc:
        print(f"bb-friction screw-pair: {exc}", file=sys.stderr)
        return 2
    op = cfg.operation
    res = solve_two_ball_module(ScrewModel(cfg), op.module_theta1_rad, op.module_theta2_rad,
                                op.module_axial_load_n)
    # An unconverged solve's last iterate is no result: its numbers are null (as ``linear``).
    out = {"f_b2b_n": res.f_b2b_n, "friction_increase": res.friction_increase,
           "torque_nm": res.torque_nm, "torque_no_b2b_nm": res.torque_no_b2b_nm,
           "loss_w": res.loss_w}
    out = {k: float(v) if res.converged and math.isfinite(v) else None
           for k, v in out.items()}
    out.update(converged=bool(res.converged), solve_time_s=res.solve_time_s)
    if args.json:
        print(json.dumps(out, allow_nan=False))
    elif not res.converged:
        print(f"two-ball module: NOT CONVERGED at W = {op.module_axial_load_n:g} N, theta = "
              f"{math.degrees(op.module_theta1_rad):g} / "
              f"{math.degrees(op.module_theta2_rad):g} deg: no result", file=sys.stderr)
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
    try:
        cfg = _load(args)
        if args.steps is not None:
            # Same step size, a shorter (or longer) run: --steps N simulates the first N
            # steps of the configured run, duration_s / n_steps each.
            op = cfg.operation
            dt = op.duration_s / op.n_steps
            cfg = _with_flags(cfg, [("--steps", "n_steps", args.steps, args.steps)])
            cfg = _with_flags(cfg, [("--steps", "duration_s", args.steps * dt, args.steps)])
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
                   help="simulate only N steps of the configured step size "
                   "(operation.duration_s / operation.n_steps): a shorter or longer run")
    p.set_defaults(func=_screw_sim)
    return p
