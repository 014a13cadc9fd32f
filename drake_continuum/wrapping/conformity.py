"""How closely a wrap follows the object it wraps (the paper's premise: "the wraps are
closely conformed to the object contour").

Two numbers of a wrap's centre line from its first contact to the tip (the part the chords
describe): the fraction lying within the tube radius plus NEAR of the object's real surface,
and the angle it sweeps about the centroid of the plane's cut through the object. Together
with the number of contact regions they tell a wrap that hugs the object from one that
touches it once and curls in free air.
"""

from __future__ import annotations

import numpy as np

__all__ = ["NEAR", "near_fraction", "swept_angle"]

NEAR = 0.005  # m: a centre-line point this close to touching (beyond the tube) counts as near


def near_fraction(points, signed_distance, radius: float, *, near: float = NEAR) -> float:
    """Fraction of centre-line points whose tube lies within `near` of the surface.

    Args:
        points: (m, 3) centre-line points, m.
        signed_distance: callable (m, 3) -> (m,) signed distance to the object's surface.
        radius: the tube's radius, m.
        near: allowed gap between the tube and the surface, m.

    Returns nan for no points.
    """
    points = np.asarray(points, float).reshape(-1, 3)
    if not len(points):
        return float("nan")
    return float(np.mean(signed_distance(points) - radius <= near))


def swept_angle(points, normal, centre) -> float:
    """Angle (rad) that the points, in order, sweep about `centre` in the plane of `normal`:
    the range of their unwrapped polar angle (a full turn round the object is 2 pi)."""
    points = np.asarray(points, float).reshape(-1, 3)
    if len(points) < 2:
        return 0.0
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    d = points - np.asarray(centre, float)
    d -= np.outer(d @ n, n)
    e1 = d[np.argmax(np.linalg.norm(d, axis=1))]
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    angle = np.unwrap(np.arctan2(d @ e2, d @ e1))
    return float(angle.max() - angle.min())
