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
import re
import signal
import sys
import threading
import traceback

from .. import workers
from ..errors import DrakeContinuumError
from . import active, experiments, learning, objects, perception, wrapping

__all__ = ["INTERNAL_ERROR", "RESUMABLE", "ORDER", "COMMANDS", "build_parser", "main"]

INTERNAL_ERROR = 70  # exit status of a bug (sysexits' EX_SOFTWARE); 1 is a user's error
RESUMABLE = ("collect", "reproduce")  # commands that continue where an interrupted run stopped

# The commands in the order `--help` lists them.
ORDER = ("objects", "evaluate", "train", "show-wraps", "train-active", "evaluate-active", "demo",
         "reproduce", "classify", "recognize", "collect", "wrap", "fit-cloud", "compare-real",
         "simulate-cloud", "classify-captures")
COMMANDS = sorted((c for m in (objects, learning, active, wrapping, experiments, perception)
                   for c in m.COMMANDS), key=lambda c: ORDER.index(c[0]))


class _Parser(argparse.ArgumentParser):
    """A parser that declares -v/-q, so that they are accepted before or after the command:
    add_subparsers makes every command's parser (and an action's, objects generate) of the
    parser's own class. Their default SUPPRESS keeps a command's parser from resetting a
    flag given before the command; the top-level parser's defaults are False."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS,
                          help="more logging on stderr, and a traceback on an internal error")
        self.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                          help="only warnings and errors on stderr, no progress bars")


class _AtLeast(logging.Filter):
    def __init__(self, level: int):
        super().__init__()
        self.level = level

    def filter(self, record) -> bool:
        return record.levelno >= self.level


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__
    parser = _Parser(
        prog="drake-continuum",
        description="Object classification and recognition by continuum-arm wraps (Mao et al.), "
                    "on Drake. Results go to stdout (--json: one JSON document), logs, "
                    "warnings and progress bars to stderr.")
    parser.add_argument("--version", action="version", version=f"drake-continuum {__version__}")
    parser.set_defaults(verbose=False, quiet=False)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, add, run in COMMANDS:
        add(sub).set_defaults(_run=run)
    return parser


def _caused_by_ctrl_c(e: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in `e`'s chain: a library may turn one into its own
    error (pybind11 makes an interrupted module initialisation "ImportError: initialization
    failed")."""
    seen = set()
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return True
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return False


def _interrupted(args, own_sigint: bool) -> int:
    """The one line and status of an interrupted run."""
    if own_sigint:
        workers.stopping()  # a Ctrl-C pressed again cannot change how the run ends
    print(_interrupted_line(args), file=sys.stderr)
    return 130  # 128 + SIGINT, as a shell reports it


def _interrupted_line(args) -> str:
    again = "; rerun the same command to resume" if args.command in RESUMABLE else ""
    return f"drake-continuum {args.command}: interrupted{again}"


# A list of numbers that starts with a minus sign (--offset -0.04,0.02): argparse takes a
# single negative number as a value, but a list for another option, and refuses the line.
_NEGATIVE_LIST = re.compile(r"-\d*\.?\d+(e[-+]?\d+)?(,-?\d*\.?\d+(e[-+]?\d+)?)+", re.I)


def _attached_lists(argv: list) -> list:
    """argv with each negative list of numbers after an option attached to it with '='."""
    out = []
    for token in argv:
        if (out and out[-1].startswith("--") and "=" not in out[-1]
                and _NEGATIVE_LIST.fullmatch(token)):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(_attached_lists(sys.argv[1:] if argv is None else list(argv)))
    if args.verbose and args.quiet:
        parser.error("-v/--verbose and -q/--quiet contradict each other; give one")
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    level = logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO
    logging.basicConfig(level=level, format="%(levelname)s %(name)s: %(message)s")
    ours = logging.getLogger("drake_continuum")  # also when basicConfig did nothing (tests)
    old_level = ours.level
    ours.setLevel(level)
    # Drake's own INFO lines ("Meshcat listening for connections at ..."): with -v only.
    # Its C++ logger hands records to logging.Logger.handle, which skips the level check
    # but applies filters.
    drake, quiet_drake = logging.getLogger("drake"), _AtLeast(logging.WARNING)
    if not args.verbose:
        drake.addFilter(quiet_drake)
    own_sigint = threading.current_thread() is threading.main_thread()
    if own_sigint:
        previous = signal.getsignal(signal.SIGINT)
        workers.interruptible_once(_interrupted_line(args))
    interrupted = False
    try:
        status = args._run(args) or 0
        if own_sigint and workers.sigint_received():  # its KeyboardInterrupt was swallowed
            interrupted = True
            return _interrupted(args, own_sigint)
        return status
    except (DrakeContinuumError, OSError) as e:  # input, settings, files: the user's to fix
        print(f"drake-continuum {args.command}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C: what is written is whole (files.write_atomic)
        interrupted = True
        return _interrupted(args, own_sigint)
    except Exception as e:  # anything else is a bug, unless a Ctrl-C caused it
        if _caused_by_ctrl_c(e):
            interrupted = True
            return _interrupted(args, own_sigint)
        if args.verbose:
            traceback.print_exc()
        where = ("the traceback above" if args.verbose
                 else "its traceback (run again with -v to see it)")
        print(f"drake-continuum {args.command}: internal error: {type(e).__name__}: {e}\n"
              f"This is a bug; please report it with the command line and {where}.",
              file=sys.stderr)
        return INTERNAL_ERROR
    finally:
        ours.setLevel(old_level)
        drake.removeFilter(quiet_drake)
        if own_sigint and not interrupted:  # called from Python: leave its handler as it was
            signal.signal(signal.SIGINT, previous)


if __name__ == "__main__":
    sys.exit(main())
