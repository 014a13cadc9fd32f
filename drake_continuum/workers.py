"""Local worker processes that end cleanly: a Ctrl-C is handled once, by the process that
started them (which stops them at once and says how to resume), not as a traceback from each
worker, and a worker whose parent died does not run on alone."""

from __future__ import annotations

import signal
from concurrent.futures import ProcessPoolExecutor


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
