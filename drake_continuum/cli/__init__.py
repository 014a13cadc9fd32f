"""`drake-continuum`: the command-line tool.

One module a command group (objects, wrapping, experiments, learning, active, perception);
each command is a pair of functions there: `_add_<name>(subparsers)` declares its arguments
(help texts end with the default and carry an example), `_run_<name>(args)` runs it by
calling the library and prints the result. Each module lists its commands in COMMANDS; only
commands that work are listed. What the commands share is in cli.common.
"""

from __future__ import annotations

import argparse
import logging
import sys
import traceback

from ..errors import DrakeContinuumError
from . import active, experiments, learning, objects, perception, wrapping

__all__ = ["INTERNAL_ERROR", "RESUMABLE", "ORDER", "COMMANDS", "build_parser", "main"]

INTERNAL_ERROR = 70  # exit status of a bug (sysexits' EX_SOFTWARE); 1 is a user's error
RESUMABLE = ("collect", "reproduce")  # commands that continue where an interrupted run stopped

# The commands in the order `--help` lists them.
ORDER = ("objects", "evaluate", "train", "show-wraps", "train-active", "evaluate-active", "demo",
         "reproduce", "classify", "recognize", "collect", "wrap", "fit-cloud", "compare-real",
         "simulate-cloud")
COMMANDS = sorted((c for m in (objects, learning, active, wrapping, experiments, perception)
                   for c in m.COMMANDS), key=lambda c: ORDER.index(c[0]))


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
    except (DrakeContinuumError, OSError) as e:  # input, settings, files: the user's to fix
        print(f"drake-continuum {args.command}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C: what is written is whole (files.write_atomic)
        again = "; rerun the same command to resume" if args.command in RESUMABLE else ""
        print(f"drake-continuum {args.command}: interrupted{again}", file=sys.stderr)
        return 130  # 128 + SIGINT, as a shell reports it
    except Exception as e:  # anything else is a bug
        if args.verbose:
            traceback.print_exc()
        where = ("the traceback above" if args.verbose
                 else "its traceback (run again with -v to see it)")
        print(f"drake-continuum {args.command}: internal error: {type(e).__name__}: {e}\n"
              f"This is a bug; please report it with the command line and {where}.",
              file=sys.stderr)
        return INTERNAL_ERROR


if __name__ == "__main__":
    sys.exit(main())
