"""Command-line interface: ``bb-friction <command>``."""

import argparse
import sys

from bb_friction_ros import __version__


def build_parser():
    """Return the top-level argument parser with one sub-parser per command."""
    parser = argparse.ArgumentParser(prog="bb-friction", description=__doc__)
    parser.add_argument("--version", action="version", version=__version__)
    parser.add_subparsers(dest="command", metavar="COMMAND")
    return parser


def main(argv=None):
    """Entry point of the ``bb-friction`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
