"""Whether an arm's centre-line points press into an object deeper than allowed, with the
object's distance field asked only about the points a cheap lower bound cannot show clear
(Open3D's closest points cost ~5 us a point; most of an arm lies well clear of the object).
"""

from __future__ import annotations

import numpy as np

__all__ = ["presses"]


def presses(distance_field, points, *, radius: float, tolerance: float) -> bool:
    """Whether a point's gap (signed distance less `radius`) is below -`tolerance`: the
    answer of np.min(distance_field(points)[0] - radius) < -tolerance.

    A field with `lower_bound(points, at_least)` ((k,), at most each point's signed
    distance; e.g. wrapping.distance.DistanceField) is asked only about the points whose
    bound leaves the answer open: a point whose bound's gap is at least -tolerance has a gap
    at least that."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    bound = getattr(distance_field, "lower_bound", None)
    if bound is not None:
        points = points[bound(points, np.full(len(points), radius - tolerance)) - radius
                        < -tolerance]
        if not len(points):
            return False
    return bool(np.min(distance_field(points)[0] - radius) < -tolerance)
