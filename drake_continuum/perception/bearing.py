"""Which way an object lies on the table, from the depth camera: the turn of the plane set.

The wrap planes pass through the arm base, which stands on the world's -x side of the
object; a turned object is then cut by planes that meet another side of it, and a shape not
round about the vertical (a banana, a mug's handle, a teapot's spout) gives other wraps.
Oriented on the object instead, the base is moved about the vertical through the position
the arm is centred on (equivalently: the object is turned back about it) so that it
approaches along the object's principal horizontal axis, as it approaches the objects as
generated, whose long axis lies along world x.

The axis comes from what a robot has: the object's points in the simulated depth camera's
cloud (locate.camera_points), never the mesh's own geometry. Seen from about 60 deg above
the table the camera sees the top and the near side, whose horizontal projection covers
the footprint, except where a bulging side hides the far side's widest part: an apple's
far side looks cut off, its footprint's minor / major second moments 0.67-0.84 instead of 1
(seed-0 apples). Isolated points (flying pixels at silhouettes) are dropped, the convex hull
of the rest is filled on a 1 mm raster (the cloud's density, higher on steep near sides,
does not weigh) and its principal axes are the raster's second moments. (Kept only the
points whose surface faces up, which every side shows, open cups and mugs gave crescents:
worse.)

An axis leaves a 180 deg ambiguity. The hull's standardised third moments (a mug's handle,
a banana's bend, a bottle's neck make one side of the axis bigger) choose the sign when the
larger of them reaches SKEW_MIN: the turn then points the side the third moment is
positive towards (a long tail's, away from a hammer's head) along +x.

Otherwise (a shape symmetric about both axes) the axis direction within 90 deg of world x
is taken: the smallest turn, deterministic.

A robot must not let a 1 deg turn of the object move its planes by much more than 1 deg (a
flip of the prediction is a defect), and the camera's footprint ratio moves by 0.01-0.05
under a 1 deg turn (an apple's by 0.07 across the old hard threshold 0.65, which turned
its planes by 136 deg). So "round or not" is a blend, not a threshold: the axes (mod 180
deg, as doubled angles, so that no two opposite directions cancel) s * (the footprint's
axis) + (1 - s) * (world x), s = max(roundness_weight(ratio), the side weight): 1 below
ratio ROUND_FROM, 0 above ROUND_TO, smooth between; and 1 once the larger third moment
reaches 3 SKEW_MIN (a mug's handle decides its bearing even where its footprint is near
round: mug_002 of seed 2, ratio 0.65, had its planes blended half-way to a fixed direction
and flipped by 173 deg under a 1 deg turn before the side weight). A round object keeps
the world bearing whatever its turn (any turn wraps it the same), an elongated or one-
sided one follows its axis exactly (a turn of the object turns the planes alike), one in
between moves continuously with its ratio; near round the side needs s * |third moment| >=
SKEW_MIN. Within the band the camera's own ratio noise still moves the planes by several
degrees under a 1 deg turn (tests: the blend's closed form; an ellipsoid turned through
the blend band). A choice between two ends of an axis cannot be continuous: it flips
where the third moment crosses SKEW_MIN (bananas, hammers; measured: BENCHMARKS.md,
Placements).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from ..errors import InputError

__all__ = ["PlaneBearing", "BEARINGS", "ROUND_FROM", "ROUND_TO", "SKEW_MIN", "RASTER",
           "ISOLATED_RADIUS", "ISOLATED_MIN", "Bearing", "roundness_weight", "footprint_bearing",
           "camera_bearing", "points_bearing", "bearing_turn"]


class PlaneBearing(StrEnum):
    """planes.bearing: the plane set fixed to the robot, or oriented on the object (members
    equal the configuration's strings)."""

    WORLD = "world"
    OBJECT = "object"


BEARINGS = tuple(b.value for b in PlaneBearing)
ROUND_FROM = 0.55   # minor / major second moment from which a footprint starts to count as
ROUND_TO = 0.75     # round, and from which it is round (the camera's view of a sphere, far
                    # side cut off, gives 0.6-0.85)
SKEW_MIN = 0.05     # |standardised third moment| from which it decides the axis's sign
RASTER = 0.001      # m, the grid the hull is filled on
ISOLATED_RADIUS = 0.005  # m: a point with fewer than ISOLATED_MIN others this near (in the
ISOLATED_MIN = 5         # horizontal projection) is a flying pixel off a silhouette: dropped


@dataclass(frozen=True)
class Bearing:
    """How far to turn the plane set about the vertical (turn, rad in (-pi, pi]), with what
    it was decided from: ratio (minor / major second moment of the footprint hull), skew
    (the standardised third moment that chose the sign, 0 if none did), source."""
    turn: float
    ratio: float | None
    skew: float
    source: str

    def to_dict(self) -> dict:
        return {"turn_deg": round(math.degrees(self.turn), 4),
                "ratio": None if self.ratio is None else round(self.ratio, 4),
                "skew": round(self.skew, 4), "source": self.source}


def _wrap_angle(a: float) -> float:
    """a in (-pi, pi]."""
    a = math.remainder(a, 2.0 * math.pi)
    return math.pi if a <= -math.pi else a


def _filled_hull(xy: np.ndarray) -> np.ndarray:
    """(m, 2) raster points (RASTER apart) inside the convex hull of xy."""
    from matplotlib.path import Path
    from scipy.spatial import ConvexHull, QhullError
    try:
        hull = ConvexHull(xy)
    except QhullError:
        raise InputError("the footprint's points are collinear: no area to orient on") from None
    poly = xy[hull.vertices]
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    gx = np.arange(lo[0], hi[0] + RASTER, RASTER)
    gy = np.arange(lo[1], hi[1] + RASTER, RASTER)
    grid = np.stack(np.meshgrid(gx, gy), axis=-1).reshape(-1, 2)
    inside = grid[Path(poly).contains_points(grid)]
    return inside if len(inside) >= 3 else poly


def _dense(xy: np.ndarray) -> np.ndarray:
    """xy without its isolated points (ISOLATED_RADIUS, ISOLATED_MIN): a depth camera's
    flying pixels at silhouettes would stretch the hull."""
    from scipy.spatial import cKDTree
    counts = cKDTree(xy).query_ball_point(xy, ISOLATED_RADIUS, return_length=True)
    keep = xy[counts > ISOLATED_MIN]  # counts include the point itself
    return keep if len(keep) >= 3 else xy


def _smoothstep(x: float) -> float:
    """0 below 0, 1 above 1, 3x^2 - 2x^3 between: continuous with its slope."""
    x = min(max(x, 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def roundness_weight(ratio: float) -> float:
    """How much of the turn follows the footprint's own axis: 1 below ROUND_FROM, 0 above
    ROUND_TO, smoothstep between (continuous with its slope)."""
    return _smoothstep((ROUND_TO - ratio) / (ROUND_TO - ROUND_FROM))


def _skews(d, theta):
    """Standardised third moments of the centred raster d along the axis at theta and
    across it.

    `scipy.stats.skew` (bias=True) is this to 2e-11 relative (tests) but, re-centring the
    projections, moves the turn of 25 of 200 random footprints in the last bits, hence wraps.
    """
    axis = np.array([math.cos(theta), math.sin(theta)])
    return [float(np.mean((d @ e) ** 3) / np.mean((d @ e) ** 2) ** 1.5)
            for e in (axis, np.array([-axis[1], axis[0]]))]


def _side_weight(skews):
    """How one-sided the footprint is: 0 for a larger third moment up to SKEW_MIN, 1 from
    3 SKEW_MIN, smoothstep between."""
    return _smoothstep((max(abs(k) for k in skews) - SKEW_MIN) / (2 * SKEW_MIN))


def footprint_bearing(xy) -> Bearing:
    """The plane set's turn from (n, 2) points of an object's horizontal footprint (module
    docstring); InputError for fewer than 3 points or no area."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(xy) < 3 or not np.all(np.isfinite(xy)):
        raise InputError(f"a footprint needs at least 3 finite points, got {len(xy)}")
    pts = _filled_hull(_dense(xy))
    d = pts - pts.mean(axis=0)
    w, V = np.linalg.eigh(d.T @ d / len(d))
    ratio = float(w[0] / w[1]) if w[1] > 0 else 1.0
    u = V[:, 1]
    theta = math.atan2(u[1], u[0])
    skews = _skews(d, theta)
    s = max(roundness_weight(ratio), _side_weight(skews))
    if s == 0.0:
        return Bearing(0.0, ratio, 0.0, "round: world bearing")
    source = "depth camera: axis"
    if s < 1.0:  # axes (mod 180 deg) blended as doubled angles: no cancelling opposites
        theta = 0.5 * math.atan2(s * math.sin(2 * theta), s * math.cos(2 * theta) + (1 - s))
        source += f" blended {s:.2f} with the world bearing (near round)"
        skews = _skews(d, theta)  # about the blended axis
    k = int(np.argmax(np.abs(skews)))
    if s * abs(skews[k]) >= SKEW_MIN:  # a near-round footprint needs a stronger side
        turn = theta if skews[k] > 0 else theta + math.pi
        return Bearing(_wrap_angle(turn), ratio, skews[k], source + " and side")
    # The axis direction within 90 deg of world x.
    return Bearing(_wrap_angle(math.remainder(theta, math.pi)), ratio, 0.0, source)


def camera_bearing(world_mesh, arm, *, seed: int = 0, camera=None) -> Bearing:
    """The plane set's turn for an object where it stands, from the simulated depth
    camera's cloud of it (locate.camera_points)."""
    from .locate import camera_points
    return points_bearing(camera_points(world_mesh, arm, seed=seed, camera=camera))


def points_bearing(points) -> Bearing:
    """The plane set's turn from the object's points in the camera's cloud (their
    horizontal footprint)."""
    return footprint_bearing(np.asarray(points, dtype=float)[:, :2])


def bearing_turn(bearing: str, world_mesh, arm, *, seed: int = 0) -> Bearing:
    """The turn for a `planes.bearing` setting: 0 for "world", camera_bearing for "object"."""
    if bearing == PlaneBearing.WORLD:
        return Bearing(0.0, None, 0.0, "world")
    if bearing == PlaneBearing.OBJECT:
        return camera_bearing(world_mesh, arm, seed=seed)
    raise InputError(f"planes.bearing must be one of {', '.join(BEARINGS)}, got {bearing!r}")
