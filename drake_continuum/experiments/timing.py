"""Where a run's time goes: by step (wall time) and by kind of work.

A collection's workers time each object's parts (`object_work`): the depth camera's look at
it, building its scene, and its wraps, of which Drake's contact queries and the IK solves are
parts. The in-process steps add theirs (`Work.timed`): training and evaluating classifiers,
active recognition, figures. Work in worker processes is summed over the workers, so on two
cores a collection's kinds add up to about twice its wall time.
"""

from __future__ import annotations

import time
from contextlib import contextmanager

from ..markdown import markdown_table

__all__ = ["KINDS", "Work", "object_work", "run_work", "work_table", "step_table"]

# The kinds of work, in the order a table lists them. "wraps" includes "ik" and "contact
# queries" (posing the arm, the cheap no-contact test and Drake's hydroelastic answer).
KINDS = ("dataset", "camera", "scene", "wraps", "ik", "contact queries", "training",
         "active recognition", "figures", "other")
_PARTS = {"ik": "wraps", "contact queries": "wraps"}  # kinds that are part of another


class Work(dict):
    """Seconds by kind (KINDS), added up over objects and steps."""

    def add(self, *others: dict) -> "Work":
        for other in others:
            for k, v in other.items():
                self[k] = self.get(k, 0.0) + float(v)
        return self

    @contextmanager
    def timed(self, kind: str):
        """Add the wall time of the block to `kind`."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self[kind] = self.get(kind, 0.0) + time.perf_counter() - t0


def object_work(camera_s: float, wrap_object_s: float, wraps) -> dict:
    """One object's work (s) from its worker's clocks: the camera's time, the time of
    wrap_object (scene and wraps) and its WrapResults' own timings (extra["timing"])."""
    wraps_s = sum(float(w.time_s) for w in wraps)
    ik = contact = 0.0
    for w in wraps:
        t = w.extra.get("timing", {})
        ik += t.get("ik", 0.0)
        contact += t.get("pose", 0.0) + t.get("prefilter", 0.0) + t.get("contact_surfaces", 0.0)
    return {"camera": camera_s, "scene": max(wrap_object_s - wraps_s, 0.0), "wraps": wraps_s,
            "ik": ik, "contact queries": contact}


def run_work(figures: dict) -> Work:
    """A reproduction's work by kind: the sum of its steps' (figures: step -> its figures)."""
    return Work().add(*(v.get("work_s", {}) for v in figures.values()))


def work_table(work: dict) -> str:
    """A Markdown table of seconds by kind, parts indented under their whole."""
    return "\n".join(markdown_table(
        ("work", "s"), [(f"of which {k}" if k in _PARTS else k, f"{work[k]:.1f}")
                        for k in KINDS if work.get(k)], align=("---", "---:"))) + "\n"


def step_table(figures: dict) -> str:
    """A Markdown table of each step's wall time (figures: step -> its figures)."""
    total = sum(v.get("time_s", 0.0) for v in figures.values())
    rows = [(k, f"{v.get('time_s', float('nan')):.1f}") for k, v in figures.items()]
    return "\n".join(markdown_table(("step", "s"), rows + [("total", f"{total:.1f}")],
                                     align=("---", "---:"))) + "\n"
