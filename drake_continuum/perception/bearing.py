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

A robot must not let a 1 deg turn of the object move its planes by much more than 1 deg
(a flip of the prediction is a defect). Two decisions above are thresholds on numbers the
camera's view moves: "round or not" (a 1 deg turn moved an apple's ratio by 0.07, across
the old hard threshold: its planes jumped by 136 deg) and the sign for a weak third
moment. Both now fall back on one canonical direction instead of on world x: the
direction `view` a round object's own camera footprint gives. The camera cuts off a round
object's far side, so its footprint is a "D" whose straight edge faces away from the
camera: its long axis lies across the line of sight, and its third moment across the axis
is positive towards the camera. That is the turn `view` = (the camera's horizontal
direction seen from the object) - 90 deg (view_turn; seed-0 apples, bottles and bowls that
counted as oriented read -140 to -160 deg with the default camera at -59 deg). So:
  * a weak third moment takes the axis direction nearest `view` (not nearest world x): a
    near-round object's sign then agrees whether its third moment is above SKEW_MIN or not;
  * roundness is not a threshold but a blend: the axes (mod 180 deg, as doubled angles)
    s * (the footprint's axis) + (1 - s) * (the view axis), s = max(roundness_weight(ratio),
    the side weight): 1 below ratio ROUND_FROM, 0 above ROUND_TO, smooth between; and 1
    once the larger third moment reaches 3 SKEW_MIN (a mug's handle decides its bearing
    even where its footprint is near round: mug_002 of seed 2, ratio 0.65, had its planes
    blended half-way to the view axis and flipped by 173 deg under a 1 deg turn before the
    side weight). A round object keeps `view` whatever its turn (any turn wraps it the
    same), an elongated or one-sided one follows its axis exactly (a turn of the object
    turns the planes alike), and one in between moves continuously with its ratio; near
    round, the side needs s * |third moment| >= SKEW_MIN, else the axis direction nearest
    `view` is taken. The camera's own ratio moves by up to 0.05 under a 1 deg turn, so
    within the band a 1 deg turn can still move the planes by several degrees (tests:
    closed form of the blend, an ellipsoid turned through the old threshold).
Without a camera direction (footprint_bearing(xy) alone) `view` is world x (turn 0).
A 180 deg choice cannot be continuous; it changes only where the third moment changes sign
or crosses SKEW_MIN, and no longer at world x's perpendicular for near-round objects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["BEARINGS", "ROUND_FROM", "ROUND_TO", "SKEW_MIN", "RASTER", "ISOLATED_RADIUS",
           "ISOLATED_MIN", "Bearing", "roundness_weight", "view_turn", "footprint_bearing",
           "camera_bearing", "points_bearing", "bearing_turn"]

BEARINGS = ("world", "object")  # planes.bearing: fixed to the robot, or oriented on the object
ROUND_FROM = 0.55   # minor / major second moment from which a footprint starts to count as
ROUND_TO = 0.75     # round, and from which it is round (the camera's view of a sphere, far
                    # side cut off, gives 0.6-0.85; the old hard threshold was 0.65)
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
    counts = np.array([len(n) for n in cKDTree(xy).query_ball_point(xy, ISOLATED_RADIUS)])
    keep = xy[counts > ISOLATED_MIN]  # counts include the point itself
    return keep if len(keep) >= 3 else xy


def roundness_weight(ratio: float) -> float:
    """How much of the turn follows the footprint's own axis: 1 below ROUND_FROM, 0 above
    ROUND_TO, smoothstep between (continuous with its slope)."""
    x = min(max((ROUND_TO - ratio) / (ROUND_TO - ROUND_FROM), 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def _skews(d, theta):
    """Standardised third moments of the centred raster d along the axis at theta and
    across it."""
    axis = np.array([math.cos(theta), math.sin(theta)])
    return [float(np.mean((d @ e) ** 3) / np.mean((d @ e) ** 2) ** 1.5)
            for e in (axis, np.array([-axis[1], axis[0]]))]


def _side_weight(d, theta):
    """How one-sided the footprint is: 0 for a larger third moment up to SKEW_MIN, 1 from
    3 SKEW_MIN, smoothstep between."""
    x = min(max((max(abs(k) for k in _skews(d, theta)) - SKEW_MIN) / (2 * SKEW_MIN), 0.0), 1.0)
    return x * x * (3.0 - 2.0 * x)


def view_turn(camera_xy, object_xy) -> float:
    """The canonical turn (module docstring): the horizontal direction from the object to
    the camera, less 90 deg."""
    d = np.asarray(camera_xy, dtype=float)[:2] - np.asarray(object_xy, dtype=float)[:2]
    return _wrap_angle(math.atan2(d[1], d[0]) - math.pi / 2)


def footprint_bearing(xy, view: float = 0.0) -> Bearing:
    """The plane set's turn from (n, 2) points of an object's horizontal footprint (module
    docstring); view: the canonical turn (rad; view_turn for a camera's footprint, 0 =
    world x). InputError for fewer than 3 points or no area."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(xy) < 3 or not np.all(np.isfinite(xy)):
        raise InputError(f"a footprint needs at least 3 finite points, got {len(xy)}")
    pts = _filled_hull(_dense(xy))
    d = pts - pts.mean(axis=0)
    w, V = np.linalg.eigh(d.T @ d / len(d))
    ratio = float(w[0] / w[1]) if w[1] > 0 else 1.0
    u = V[:, 1]
    theta = math.atan2(u[1], u[0])
    s = max(roundness_weight(ratio), _side_weight(d, theta))
    if s == 0.0:
        return Bearing(_wrap_angle(view), ratio, 0.0, "round: view bearing")
    source = "depth camera: axis"
    if s < 1.0:  # axes (mod 180 deg) blended as doubled angles: no cancelling opposites
        theta = 0.5 * math.atan2(s * math.sin(2 * theta) + (1 - s) * math.sin(2 * view),
                                 s * math.cos(2 * theta) + (1 - s) * math.cos(2 * view))
        source += f" blended {s:.2f} with the view bearing (near round)"
    skews = _skews(d, theta)
    k = int(np.argmax(np.abs(skews)))
    if s * abs(skews[k]) >= SKEW_MIN:  # a near-round footprint needs a stronger side
        turn = theta if skews[k] > 0 else theta + math.pi
        return Bearing(_wrap_angle(turn), ratio, skews[k], source + " and side")
    # The axis direction within 90 deg of the canonical one.
    return Bearing(_wrap_angle(view + math.remainder(theta - view, math.pi)), ratio, 0.0, source)


def camera_bearing(world_mesh, arm, seed: int = 0, camera=None) -> Bearing:
    """The plane set's turn for an object where it stands, from the simulated depth
    camera's cloud of it (locate.camera_points)."""
    from .depth_camera import CameraPose
    from .locate import camera_points
    camera = camera or CameraPose()
    seen = camera_points(world_mesh, arm, seed, camera)
    return points_bearing(seen, camera)


def points_bearing(points, camera=None) -> Bearing:
    """The plane set's turn from the object's points in a camera's cloud (camera: the
    CameraPose they were seen from, default CameraPose()), canonical turn view_turn."""
    from .depth_camera import CameraPose
    from .locate import points_estimate
    camera = camera or CameraPose()
    points = np.asarray(points, dtype=float)
    return footprint_bearing(points[:, :2],
                             view_turn(camera.eye, points_estimate(points).xy))


def bearing_turn(bearing: str, world_mesh, arm, seed: int = 0) -> Bearing:
    """The turn for a `planes.bearing` setting: 0 for "world", camera_bearing for "object"."""
    if bearing == "world":
        return Bearing(0.0, None, 0.0, "world")
    if bearing == "object":
        return camera_bearing(world_mesh, arm, seed)
    raise InputError(f"planes.bearing must be one of {', '.join(BEARINGS)}, got {bearing!r}")
