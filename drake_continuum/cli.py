"""`drake-continuum`: the command-line tool.

Each subcommand is a pair of functions here: `_add_<name>(subparsers)` declares its
arguments (help texts end with the default and carry an example), `_run_<name>(args)` runs it
by calling the library. Commands are listed in COMMANDS at the bottom; only commands that work
are listed.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys

log = logging.getLogger("drake_continuum")


class UserError(Exception):
    """An error the user can fix; printed without a traceback."""


def _print_json(obj) -> None:
    json.dump(obj, sys.stdout, indent=2)
    sys.stdout.write("\n")


COMMANDS: list = []  # (name, add_function, run_function), filled below


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="drake-continuum",
        description="Object classification and recognition by continuum-arm wraps (Mao et al.), "
                    "on Drake.")
    parser.add_argument("-v", "--verbose", action="store_true", help="more logging")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, add, run in COMMANDS:
        p = add(sub)
        p.set_defaults(_run=run)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return args._run(args) or 0
    except (UserError, FileNotFoundError, ValueError) as e:
        print(f"drake-continuum {args.command}: error: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
