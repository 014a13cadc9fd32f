"""Ctrl-C and local worker processes: a Ctrl-C is handled once, by the process that started
the workers (which stops them at once and says how to resume), not as a traceback from each
worker; a Ctrl-C pressed again while the run is stopping does not cut the stopping short; a
worker whose parent died does not run on alone."""

from __future__ import annotations

import os
import signal
import sys
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from multiprocessing import get_context

__all__ = ["interruptible_once", "sigint_handled", "sigint_received", "stopping",
           "worker_setup", "sigint_held",
           "stop_workers", "main_not_rerun", "local_pool"]


def _on_sigint(signum, frame) -> None:
    """SIGINT handler of the command line: the first Ctrl-C raises KeyboardInterrupt, as
    Python's own handler does; one arriving while that KeyboardInterrupt is being handled (the
    `finally` blocks that stop workers, release the lock, remove temporary files) is ignored,
    so the stopping finishes and the run still ends with its message and status. A
    KeyboardInterrupt that some code swallowed (Python ignores exceptions in at-fork hooks and
    __del__) is not being handled any more, so the next Ctrl-C raises again. One landing
    inside an import ends the process at once with one line and status 130: a library
    interrupted in its initialisation prints its own failure (pydrake) or changes the exit
    status as the interpreter shuts down (Open3D), and nothing is written during an import
    (a lock or temporary file left behind is cleared by the next run)."""
    global _received
    _received = True
    if _importing(frame):
        os.write(2, _line.encode() + b"\n")
        os._exit(130)
    exc = sys.exc_info()[1]
    while exc is not None:
        if isinstance(exc, KeyboardInterrupt):
            return
        exc = exc.__context__
    raise KeyboardInterrupt


_received = False  # a Ctrl-C reached _on_sigint since interruptible_once
_line = "drake-continuum: interrupted"  # what a Ctrl-C inside an import prints


def sigint_received() -> bool:
    """Whether a Ctrl-C reached the command line's handler, even one whose KeyboardInterrupt
    a library swallowed (Python ignores exceptions raised in ctypes callbacks, such as
    rtree's): the run must still end as interrupted."""
    return _received


def sigint_handled() -> None:
    """Mark the Ctrl-C received so far as answered by the command itself (a served Meshcat
    page ends on Ctrl-C as it does on Enter), so the run does not end as interrupted."""
    global _received
    _received = False


def _importing(frame) -> bool:
    """Whether `frame` runs inside an import (importlib's frames are on its stack)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib._bootstrap"):
            return True
        frame = frame.f_back
    return False


def interruptible_once(line: str = "drake-continuum: interrupted") -> None:
    """Install the command line's SIGINT handler (_on_sigint) in the main thread; `line`: the
    run's message should a Ctrl-C end it inside an import."""
    global _received, _line
    _received, _line = False, line
    signal.signal(signal.SIGINT, _on_sigint)


def stopping() -> None:
    """The run is ending (its interruption was handled): ignore every further Ctrl-C, through
    the interpreter's own shutdown, so that the exit status stays the one the run chose
    (Python restores the default handler while it finalises, where a Ctrl-C would end the
    process by the signal instead)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def worker_setup() -> None:
    """Initializer of every pool: ignore SIGINT (a Ctrl-C reaches the whole process group;
    the parent handles it and ends the workers) and, on Linux, end when the parent dies, even
    by SIGKILL, rather than finish work nobody will store."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


@contextmanager
def sigint_held():
    """Hold Ctrl-C's SIGINT (blocked, not lost) while worker processes start: a spawned
    worker inherits the blocked signal through exec, so a Ctrl-C landing while it imports,
    before worker_setup runs, cannot end it with a KeyboardInterrupt traceback on the
    terminal; the parent receives the held signal when the block ends."""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def stop_workers(pool: ProcessPoolExecutor) -> None:
    """Cancel what is queued and end the running workers now (an interrupted run redoes
    their work on the next run) rather than wait for it to finish."""
    pool.shutdown(wait=False, cancel_futures=True)
    terminate = getattr(pool, "terminate_workers", None)  # Python 3.14
    if terminate is not None:
        terminate()
        return
    for process in list((getattr(pool, "_processes", None) or {}).values()):
        process.terminate()


@contextmanager
def main_not_rerun():
    """Start spawned workers without running the parent's main script in them. A spawned
    process imports the parent's `__main__` (to unpickle what it defines) and so reruns a
    plain script that lacks the `if __name__ == "__main__":` guard, calling the caller's
    code again in every worker. Tasks that need nothing from `__main__` hide it (its
    `__file__` and `__spec__`, which tell the worker what to import) while the pool runs."""
    main = sys.modules.get("__main__")
    saved = {k: main.__dict__[k] for k in ("__file__", "__spec__") if k in vars(main)} \
        if main is not None else {}
    try:
        if main is not None:
            main.__dict__.pop("__file__", None)
            main.__spec__ = None
        yield
    finally:
        if main is not None:
            main.__dict__.pop("__spec__", None)
            main.__dict__.update(saved)


@contextmanager
def local_pool(workers: int):
    """A pool of `workers` spawned processes (worker_setup in each) that do not rerun the
    caller's script (main_not_rerun). On an exception (Ctrl-C included) what is queued is
    cancelled and the workers end at once (stop_workers); otherwise their work is awaited."""
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn"),
                               initializer=worker_setup)
    with main_not_rerun():
        try:
            yield pool
        except BaseException:
            stop_workers(pool)
            raise
        pool.shutdown(wait=True)
