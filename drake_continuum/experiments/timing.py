"""Where a run's time goes: each step's wall time, and the CPU time of each kind of work.

A step's wall time is what the run waited at it; on a shared machine it grows with the load.
The work by kind is CPU time (user plus system), which the load barely moves: added up over
the kinds it is about the CPU time of the whole run, this process and its workers, however
many cores they shared.

A collection's workers clock each object's parts (`object_work`, the worker's CPU time): the
depth camera's look at it, reading its mesh and building its scene, and its wraps (each
wrap's own thread CPU time, of which Drake's contact queries and the IK solves are parts).
Each step of a reproduction adds its own CPU time under its kind (`step_clock`: this
process, all its threads, and the worker processes it started and ended), less the work run
ahead in threads of this process meanwhile, which counts where its step takes it (placing
copies, generating a dataset; the rest, such as storing a collection's results, "other").
The start of the run's workers (their imports, about 2 s of CPU each) is "other" too. Not
counted: what the run does before its first step and after its last (imports, the report),
and the workers' time between their tasks (taking a task, returning a result).
"""

from __future__ import annotations

import resource
import time
from contextlib import contextmanager

from ..markdown import markdown_table

__all__ = ["KINDS", "Work", "step_clock", "object_work", "run_work", "work_total",
           "work_table", "step_table"]

# The kinds of work, in the order a table lists them. "wraps" includes "ik" and "contact
# queries" (posing the arm, the cheap no-contact test and Drake's hydroelastic answer).
KINDS = ("dataset", "camera", "scene", "wraps", "ik", "contact queries", "training",
         "active recognition", "figures", "other")
_PARTS = {"ik": "wraps", "contact queries": "wraps"}  # kinds that are part of another


class Work(dict):
    """CPU seconds by kind (KINDS), added up over objects and steps."""

    def add(self, *others: dict) -> "Work":
        for other in others:
            for k, v in other.items():
                self[k] = self.get(k, 0.0) + float(v)
        return self

    @contextmanager
    def timed(self, kind: str):
        """Add the CPU time of the block, in this thread, to `kind`."""
        t0 = time.thread_time()
        try:
            yield
        finally:
            self[kind] = self.get(kind, 0.0) + time.thread_time() - t0


def step_clock() -> float:
    """CPU seconds of this process (every thread: numerical libraries compute in their own)
    and of every child process ended so far (a step's own pools, once shut down). The run's
    pool, ended only with the run, reports its workers' work itself."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def object_work(camera_s: float, object_s: float, wraps) -> dict:
    """One object's CPU seconds by kind, in its worker: the camera's, the object's whole
    (object_s: reading the mesh, the camera, the scene and the wraps) and its WrapResults'
    own (extra["timing"]: "cpu_s", of which "ik" and the contact queries' parts)."""
    wraps_s = ik = contact = 0.0
    for w in wraps:
        t = w.extra["timing"]
        wraps_s += t["cpu_s"]
        ik += t["ik"]
        contact += t["pose"] + t["prefilter"] + t["contact_surfaces"]
    return {"camera": camera_s, "scene": max(object_s - camera_s - wraps_s, 0.0),
            "wraps": wraps_s, "ik": ik, "contact queries": contact}


def run_work(figures: dict) -> Work:
    """A reproduction's work by kind: the sum of its steps' (figures: step -> its figures)."""
    return Work().add(*(v.get("work_s", {}) for v in figures.values()))


def work_total(work: dict) -> float:
    """The CPU seconds of all the work, each part counted once (in its whole)."""
    return sum(v for k, v in work.items() if k not in _PARTS)


def work_table(work: dict) -> str:
    """A Markdown table of CPU seconds by kind, parts indented under their whole."""
    return "\n".join(markdown_table(
        ("work", "CPU s"), [(f"of which {k}" if k in _PARTS else k, f"{work[k]:.1f}")
                            for k in KINDS if work.get(k)], align=("---", "---:"))) + "\n"


def step_table(figures: dict) -> str:
    """A Markdown table of each step's wall time (figures: step -> its figures)."""
    total = sum(v.get("time_s", 0.0) for v in figures.values())
    rows = [(k, f"{v.get('time_s', float('nan')):.1f}") for k, v in figures.items()]
    return "\n".join(markdown_table(("step", "wall s"), rows + [("total", f"{total:.1f}")],
                                     align=("---", "---:"))) + "\n"
