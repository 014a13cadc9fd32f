"""The `drake-continuum` program: Ctrl-C is handled from its first instruction.

Importing the command line (pydrake, numba, scikit-learn) takes about a second, and a
KeyboardInterrupt raised inside an import can be swallowed by the library being imported,
leave a half-imported module behind (an internal error later) or print a traceback. Until
the command line installs its own handler, a Ctrl-C therefore ends the process at once
with one line and status 130: nothing has been written yet.
"""

import os
import signal

__all__ = ["main"]

INTERRUPTED = 130  # 128 + SIGINT, as a shell reports it


def _interrupted_at_start(signum, frame) -> None:
    os.write(2, b"drake-continuum: interrupted\n")
    os._exit(INTERRUPTED)


def main(argv=None) -> int:
    """Run the command line (cli.main) with Ctrl-C covered while it is imported."""
    signal.signal(signal.SIGINT, _interrupted_at_start)
    from .cli import main as run
    return run(argv)
