"""
Command-line interface: ``bb-friction <command>``.

Commands and their flags are contracts that users script against: add, never rename.
"""

import argparse
import json
import math
import sys

from bb_friction_ros import __version__
from bb_friction_ros.config import ConfigError, load_linear_bearing


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
    res = run(math.radians(args.theta_deg), cfg.side_force_ratio,
              math.radians(args.dbeta_tr_deg), math.radians(args.dbeta_tl_deg))
    if args.json:
        print(json.dumps(res.as_json()))
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
    p.add_argument("--grid", type=int, default=25,
                   help="theta and rho points of the Figs. 8-9 maps (numerical model)")
    p.set_defaults(func=_run_reproduce)


def _run_reproduce(args):
    from bb_friction_ros.reproduce import reproduce
    report = reproduce(args.out, load_linear_bearing(args.config), grid=args.grid)
    print(f"report: {report}")
    return 0


def build_parser():
    """Return the top-level argument parser with one sub-parser per command."""
    parser = argparse.ArgumentParser(prog="bb-friction", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=__version__)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    _add_linear_parser(sub)
    _add_reproduce_parser(sub)
    try:
        from bb_friction_ros.ball_screw import cli as screw_cli
    except ImportError:
        screw_cli = None
    if screw_cli is not None:
        for name in ("add_screw_pair_parser", "add_screw_sim_parser"):
            if hasattr(screw_cli, name):
                getattr(screw_cli, name)(sub)
    return parser


def main(argv=None):
    """Entry point of the ``bb-friction`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        return args.func(args)
    except ConfigError as exc:
        print(f"bb-friction: config error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
