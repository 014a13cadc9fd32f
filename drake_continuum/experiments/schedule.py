"""Where a reproduction's work runs, and when: one pool of local workers for the whole run,
and work started on it before the step that needs it, so that both cores stay busy.

The pool's queue is first in, first out. As `collect` starts, the placed copies are placed
and queued behind the originals, and the second dataset's collections behind them (a
thread each: `Ahead`); as `collect` ends, the camera study's fits are queued (between the
two). This process meanwhile runs the steps that train and evaluate, and takes each result
at its step, so a core that one of them leaves idle (a step's one-process part, the last
object of a collection) is taken by the work queued. Every piece of work is the one its
step would do, with the same seeds, so the figures do not depend on the order.
"""

from __future__ import annotations

import os
import threading
import time
from concurrent.futures import Executor, Future

from ..workers import local_pool, sigint_held

__all__ = ["POOL", "Ahead", "where", "run_pool", "start", "keep", "take", "take_timed",
           "ahead_cpu", "warm", "started_cpu", "end", "still_running"]

POOL: dict = {}  # the running reproduce's "stack" (which ends its pool) and its "pool"
_AHEAD: dict = {}  # name -> an Ahead thread or a Future, until its step takes it
_STARTED: list = []  # every Ahead of the run (ahead_cpu)


def where(s):
    """Where a step's collection runs: the Dask scheduler given, in this process (one
    worker), or the run's one pool of local workers, made as the run starts (warm) or at its
    first collection, whose workers keep their imports, numba kernels and last scene from
    one step to the next (about 4 s of CPU a worker each time); one a dead worker broke is
    replaced."""
    if s.scheduler is not None or s.workers == 1 or "stack" not in POOL:
        return s.scheduler
    if POOL["pool"] is None or getattr(POOL["pool"], "_broken", False):
        POOL["pool"] = POOL["stack"].enter_context(local_pool(s.workers or os.cpu_count()
                                                                or 1))
    return POOL["pool"]


def run_pool(s) -> Executor | None:
    """The run's pool of local workers (where), or None: work runs in this process or on
    a Dask cluster."""
    pool = where(s)
    return pool if isinstance(pool, Executor) else None


class Ahead(threading.Thread):
    """Work started before its step, in a thread of this process (a collection waits on the
    run's pool there). `take` waits for its result, or raises its error."""

    def __init__(self, work):
        # A daemon: a run that fails while it waits is not kept from ending by it.
        super().__init__(name="reproduce-ahead", daemon=True)
        self._work, self._result, self._error = work, None, None
        self._cpu_s, self._cpu_lock = None, threading.Lock()  # its CPU time once ended

    def run(self):
        try:
            self._result = self._work()
        except BaseException as e:  # raised again by take, in the step
            self._error = e
        finally:
            with self._cpu_lock:
                self._cpu_s = time.thread_time()

    def cpu_s(self) -> float:
        """The thread's CPU seconds so far (read while it runs, where the platform has
        per-thread clocks: Linux; elsewhere 0 until it ends)."""
        with self._cpu_lock:  # held: the thread cannot end while its clock is read
            if self._cpu_s is not None:
                return self._cpu_s
            if self.ident is None or not hasattr(time, "pthread_getcpuclockid"):
                return 0.0
            return time.clock_gettime(time.pthread_getcpuclockid(self.ident))

    def take(self):
        self.join()
        if self._error is not None:
            raise self._error
        return self._result


def still_running() -> None:
    """Raise when the run has ended (failed or interrupted): work run ahead calls it before
    each of its stages, so that none starts on a stopped pool."""
    if "stack" not in POOL:
        raise RuntimeError("the reproduction ended before this work started")


def start(name: str, work) -> Ahead:
    """Run `work` ahead in a thread, its result kept under `name` until taken."""
    ahead = Ahead(work)
    _AHEAD[name] = ahead
    _STARTED.append(ahead)
    ahead.start()
    return ahead


def ahead_cpu() -> float:
    """The CPU seconds of the work run ahead in this process so far: apart from the step
    running meanwhile, counted where its step takes it (take_timed)."""
    return sum(ahead.cpu_s() for ahead in _STARTED)


def keep(name: str, value) -> None:
    """Keep `value` under `name` until taken (work already queued by its own means)."""
    _AHEAD[name] = value


def take(name: str, default=None):
    """The result of the work started under `name` (waited for; its error raised), or
    `default` when none was started."""
    ahead = _AHEAD.pop(name, None)
    if ahead is None:
        return default
    if isinstance(ahead, Ahead):
        return ahead.take()
    return ahead.result() if isinstance(ahead, Future) else ahead


def take_timed(name: str) -> tuple:
    """(take(name), the CPU seconds of the thread that ran it ahead, or None: not run ahead
    in a thread)."""
    ahead = _AHEAD.get(name)
    result = take(name)
    return result, ahead.cpu_s() if isinstance(ahead, Ahead) else None


def warm(s) -> None:
    """Start the run's local workers now: each imports for seconds (collect.warm_worker)
    while this process makes the dataset and the gallery."""
    from .collect import warm_worker
    pool = run_pool(s)
    if pool is not None:
        with sigint_held():  # as collect starts them: a Ctrl-C waits until they exist
            keep("warm", [pool.submit(warm_worker)
                          for _ in range(getattr(pool, "_max_workers", 1))])


def started_cpu() -> float:
    """The CPU seconds the run's workers took to start (warm), counted once all have
    answered (0 until then, and after); a worker stopped first answers nothing."""
    futures = take("warm", [])
    if not all(f.done() for f in futures):
        keep("warm", futures)
        return 0.0
    by_worker = dict(f.result() for f in futures  # one that ran two: its later, whole figure
                     if not f.cancelled() and f.exception() is None)
    return sum(by_worker.values())


def end() -> None:
    """Wait for work run ahead that no step took (the run failed before it): the pool has
    been stopped by then, so it ends at once (a collection's cancelled objects recorded as
    failed, left to a rerun); the wait is bounded all the same."""
    for ahead in _AHEAD.values():
        if isinstance(ahead, Ahead):
            ahead.join(timeout=30.0)
    _AHEAD.clear()
    _STARTED.clear()
