"""Real wraps from depth-camera point clouds: segment the arm, fit its configuration.

Segmentation (Open3D): crop to the arm's reach, voxel-downsample, keep the points whose colour
is the arm's paint (ARM_COLOUR, orange: a hue that neither tables, skin nor grey or blue
objects share), remove the table plane (RANSAC), cluster (DBSCAN), then keep the clusters
that chain to the arm's base with gaps no longer than an occluder can hide. Keeping every
piece of the chain, not the largest cluster, matters: an object in front of the arm splits
it, and a fit to one piece loses the tip.

Fitting (scipy least_squares): per point, residual = distance to the backbone minus the tube
radius, with a soft-L1 loss for flying pixels and stray points. Each section is parameterised
by (s, u, v) with (u, v) = kappa (cos phi, sin phi), smooth through kappa = 0 where phi is
undefined. The nearest backbone arc length of each point is recomputed at every iterate and
held fixed inside the Jacobian: by the envelope theorem the derivative of the point-to-curve
distance is that of the distance at the fixed nearest point, so nine cheap forward
evaluations give the Jacobian without any nearest-point search. The start comes from medial
points ordered along the arm by geodesic distance from the base (a radius graph within each
piece, pieces walked in order from the base) and one arc fitted per section in turn.

Every configuration the fit considers keeps the arm's curvature and bend limits (kappa_i <=
min(curvature_max, bend_max / s_i)): the curvature is held to its limit, and residuals on the
excess lead an iterate that strayed beyond it back. Without the bend limit a section coils
through itself to reach points of another turn.

Starts are tried in turn until one fits well (soft-L1 RMS under GOOD_FIT). With the section
lengths known: the ordering that enters each piece at its nearest point, then the one that
enters it along the walk's direction (a tip curled back beside the gap an object opened
otherwise runs the far piece backwards), then the free-length fit's curvatures. With them
free, a start that splits the seen length wrongly converges to a wrap that runs on along an
overlapping turn: three splits of the seen length, the heading ordering, then the first
split matched by nearest points alone (when touching turns join in the radius graph, every
ordering cuts across them and its correspondences mislead); the fit is charged for running
more than OVERRUN past the seen length. A tip curled out of the camera's view stays
unobserved: the fit stops where the points stop.

Partly hidden arms (issue 16). With the camera's position, what it saw through is evidence
too (freespace.py): a solution that the cameras saw through is refined again with a term
charging every such ray, so hidden parts go where no camera could see. Several views of one
wrap are segmented one by one and fitted together. A prior (ConfigPrior, the commanded
configuration with its uncertainty) keeps what the points do not decide near the command,
and with free lengths lets the arm run on past its last seen point where no camera could see.
Every fit says how sure it is (confidence.py): per section the fraction seen, the tip's
standard deviation from the cost's curvature, and for a partly unseen arm the spread of
other solutions that explain the points equally well (the starts not yet tried and the
unseen sections bent otherwise), flagged ambiguous when their tips lie apart.
"""

from __future__ import annotations

import itertools
import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import open3d as o3d
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ..errors import DrakeContinuumError
from ..files import check_input_file, write_atomic
from ..kinematics.arm import ARM_COLOUR, ArmConfig, ContinuumArm

if TYPE_CHECKING:  # confidence.py imports this module
    from .confidence import FitConfidence

__all__ = ["CLOUD_SUFFIXES", "MM_EXTENT", "PointCloudError", "Cloud", "detect_units", "load_cloud",
           "SegmentParams", "Segmentation", "colour_gate", "segment_arm", "FitParams", "ArmFit",
           "order_along_arm", "ENTRY_REACH", "medial_polyline", "medial_points", "medial_length",
           "config_along", "centre_line", "START_SPLITS", "GOOD_FIT", "OVERRUN", "TIP_WEIGHT",
           "LIMIT_WEIGHT", "TIP_SLACK", "unseen_intervals", "fit_arm", "fit_cloud",
           "surface_deviation", "WrapSamples", "real_and_simulated_wraps", "chord_comparison",
           "first_contact_arc_length", "fig8", "compare_real", "compare_shipped_clouds",
           "LAST_POINT_TOL", "FREE_WEIGHT", "FREE_OK", "FREE_NFEV", "SHORTEN", "soft_l1_cost",
           "soft_l1_rms", "ConfigPrior", "merge_segmentations", "at_config"]

CLOUD_SUFFIXES = (".pcd", ".ply", ".xyz", ".xyzrgb", ".pts")
MM_EXTENT = 20.0  # a cloud spanning more than this many units is in millimetres


class PointCloudError(DrakeContinuumError):
    """A cloud cannot be used; the message names the file and the problem."""


@dataclass(frozen=True)
class Cloud:
    """A point cloud in metres.

    Args:
        points: (N, 3) positions, m.
        colours: (N, 3) RGB in [0, 1], or None when the file has no colour.
        source: where it came from (for messages).
        units: units of the file ("m" or "mm").
    """

    points: np.ndarray
    colours: np.ndarray | None = None
    source: str = "<array>"
    units: str = "m"


def detect_units(points: np.ndarray) -> str:
    """"mm" when the cloud spans more than MM_EXTENT units (a tabletop scene in metres spans
    a few metres at most; in millimetres anything larger than 2 cm spans more than 20)."""
    lo, hi = np.percentile(points, [1, 99], axis=0)
    return "mm" if np.max(hi - lo) > MM_EXTENT else "m"


def _header_says_empty(path: Path) -> bool:
    head = path.open("rb").read(4096).decode("ascii", errors="replace").lower()
    return any(line.split()[:2] in (["points", "0"], ["width", "0"])
               or line.split()[:3] == ["element", "vertex", "0"] for line in head.splitlines())


def load_cloud(path, units: str = "auto", drop_nonfinite: bool = False) -> Cloud:
    """Read a .pcd/.ply/.xyz cloud, check it, and return it in metres.

    Raises PointCloudError naming the file when it does not exist, cannot be read, holds no
    points, or holds NaN/infinite points (unless drop_nonfinite: organised clouds mark
    missing pixels with NaN).
    """
    path = Path(path)
    if units not in ("auto", "m", "mm"):
        raise PointCloudError(f"{path}: units must be auto, m or mm, got {units!r}")
    check_input_file(path, CLOUD_SUFFIXES, PointCloudError, "point-cloud")
    pcd = o3d.io.read_point_cloud(str(path))
    pts = np.asarray(pcd.points, dtype=float)
    if len(pts) == 0:
        if _header_says_empty(path):
            raise PointCloudError(f"{path}: holds no points")
        raise PointCloudError(f"{path}: cannot be read as a point cloud (not a valid "
                              f"{path.suffix} file)")
    cols = np.asarray(pcd.colors, dtype=float) if pcd.has_colors() else None
    finite = np.all(np.isfinite(pts), axis=1)
    if not finite.all():
        if not drop_nonfinite or not finite.any():
            raise PointCloudError(
                f"{path}: {int((~finite).sum())} of {len(pts)} points are NaN or infinite"
                + ("" if finite.any() else " (no usable point)")
                + ("" if drop_nonfinite else "; pass --drop-nan to discard them"))
        pts = pts[finite]
        cols = None if cols is None else cols[finite]
    found = detect_units(pts) if units == "auto" else units
    if found == "mm":
        pts = pts / 1000.0
    return Cloud(points=pts, colours=cols, source=str(path), units=found)


# --------------------------------------------------------------------------- segmentation

@dataclass(frozen=True)
class SegmentParams:
    """How the arm is cut out of a cloud.

    Args:
        voxel: voxel-grid downsampling, m (the fit needs no more than ~2,000 points).
        colour: the arm's RGB, or None to segment by geometry alone.
        hue_tol: accepted hue difference, fraction of the colour circle.
        saturation_min, value_min: the gate's floor on HSV saturation and value.
        table_threshold: RANSAC inlier distance of the table plane, m (4 sigma at 1.2 m).
        table_min_fraction: a plane with fewer inliers than this is not the table.
        dbscan_eps, dbscan_min_points: DBSCAN neighbourhood, m, and core size.
        min_piece: smallest cluster that counts as an arm piece, points.
        max_gap: longest gap an occluder may open between two pieces of the arm, m.
    """

    voxel: float = 0.004
    colour: tuple | None = ARM_COLOUR
    hue_tol: float = 0.06
    saturation_min: float = 0.45
    value_min: float = 0.12
    table_threshold: float = 0.008
    table_min_fraction: float = 0.15
    dbscan_eps: float = 0.012
    dbscan_min_points: int = 6
    min_piece: int = 12
    max_gap: float = 0.20


@dataclass(frozen=True)
class Segmentation:
    """The arm's points cut from a cloud.

    Args:
        points: (M, 3) arm points, m.
        piece: (M,) index of the chain piece of each point (0 nearest the base).
        n_input: points in the cloud; n_colour: points passing the colour gate (or all).
        table_plane: (4,) plane a x + b y + c z + d = 0 removed as the table, or None.
        dropped_pieces: sizes of the colour-matching clusters left out (not on the chain).
    """

    points: np.ndarray
    piece: np.ndarray
    n_input: int
    n_colour: int
    table_plane: np.ndarray | None
    dropped_pieces: tuple = ()

    @property
    def n_pieces(self) -> int:
        return int(self.piece.max()) + 1 if len(self.piece) else 0


def _hsv(rgb: np.ndarray) -> np.ndarray:
    rgb = np.clip(np.asarray(rgb, dtype=float), 0.0, 1.0)
    mx, mn = rgb.max(-1), rgb.min(-1)
    delta = mx - mn
    safe = np.where(delta > 0, delta, 1.0)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    h = np.where(mx == r, ((g - b) / safe) % 6, np.where(mx == g, (b - r) / safe + 2,
                                                         (r - g) / safe + 4)) / 6.0
    h = np.where(delta > 0, h, 0.0)
    s = np.where(mx > 0, delta / np.where(mx > 0, mx, 1.0), 0.0)
    return np.stack([h, s, mx], -1)


def colour_gate(colours: np.ndarray, params: SegmentParams) -> np.ndarray:
    """(N,) mask of colours that may be the arm's paint (hue near it, saturated, lit)."""
    hsv, ref = _hsv(colours), _hsv(np.asarray(params.colour, float))
    dh = np.abs(hsv[:, 0] - ref[0])
    dh = np.minimum(dh, 1.0 - dh)
    return (dh <= params.hue_tol) & (hsv[:, 1] >= params.saturation_min) & \
        (hsv[:, 2] >= params.value_min)


def _chain(pieces: list[np.ndarray], start: np.ndarray, max_gap: float) -> list[int]:
    """Indices of pieces reachable from `start` through gaps of at most max_gap, nearest
    first (each next piece is the one nearest any point already on the chain)."""
    trees = [cKDTree(p) for p in pieces]
    chain, reached = [], [np.asarray(start, float)[None]]
    left = set(range(len(pieces)))
    while left:
        pts = np.concatenate(reached)
        gaps = {k: trees[k].query(pts)[0].min() for k in left}
        k = min(gaps, key=gaps.get)
        if gaps[k] > max_gap:
            break
        chain.append(k)
        reached.append(pieces[k])
        left.remove(k)
    return chain


def segment_arm(cloud: Cloud, arm: ContinuumArm,
                params: SegmentParams = SegmentParams()) -> Segmentation:
    """Cut the arm's points out of a cloud (see the module docstring)."""
    src = cloud.source
    pts = cloud.points
    reach = np.linalg.norm(pts - arm.base_position, axis=1) <= arm.length_max + 2 * arm.radius
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts[reach]))
    use_colour = params.colour is not None and cloud.colours is not None
    if use_colour:
        pcd.colors = o3d.utility.Vector3dVector(cloud.colours[reach])
    pcd = pcd.voxel_down_sample(params.voxel)
    p = np.asarray(pcd.points)
    if len(p) == 0:
        raise PointCloudError(f"{src}: no arm: none of its {len(pts)} points lies within the "
                              f"arm's reach ({arm.length_max:.2f} m) of the base at "
                              f"{np.round(arm.base_position, 3).tolist()}")
    keep = colour_gate(np.asarray(pcd.colors), params) if use_colour else np.ones(len(p), bool)
    n_colour = int(keep.sum())

    plane = None
    if len(p) >= 3:
        o3d.utility.random.seed(0)
        model, inl = pcd.segment_plane(params.table_threshold, 3, 300)
        model = np.asarray(model, float)
        model /= np.linalg.norm(model[:3])
        # A planar wrap also fits a plane; the table is the one that misses the arm's base.
        base_off = abs(model[:3] @ arm.base_position + model[3])
        if len(inl) >= params.table_min_fraction * len(p) and base_off > 2 * arm.radius:
            plane = model
            on_plane = np.zeros(len(p), bool)
            on_plane[inl] = True
            keep &= ~on_plane | (use_colour & keep)
    cand = p[keep]
    what = "arm-coloured " if use_colour else ""
    if len(cand) == 0:
        hint = ("; if the arm is not painted ARM_COLOUR, segment without colour "
                "(--no-colour)") if use_colour else ""
        raise PointCloudError(f"{src}: no arm: no {what}points left after removing the table"
                              f"{hint}")
    labels = np.asarray(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(cand))
                        .cluster_dbscan(params.dbscan_eps, params.dbscan_min_points))
    ids, sizes = np.unique(labels[labels >= 0], return_counts=True)
    ids = ids[sizes >= params.min_piece]
    pieces = [cand[labels == k] for k in ids]
    chain = _chain(pieces, arm.base_position, params.max_gap) if pieces else []
    if not chain:
        near = min((np.linalg.norm(c - arm.base_position, axis=1).min() for c in pieces),
                   default=np.inf)
        raise PointCloudError(
            f"{src}: no arm: {len(cand)} {what}points in {len(pieces)} clusters, none within "
            f"{params.max_gap:.2f} m of the arm's base at "
            f"{np.round(arm.base_position, 3).tolist()} (nearest {near:.3f} m)")
    arm_pts = np.concatenate([pieces[k] for k in chain])
    piece = np.repeat(np.arange(len(chain)), [len(pieces[k]) for k in chain])
    dropped = tuple(int(len(pieces[k])) for k in range(len(pieces)) if k not in chain)
    return Segmentation(points=arm_pts, piece=piece, n_input=len(pts), n_colour=n_colour,
                        table_plane=plane, dropped_pieces=dropped)


# --------------------------------------------------------------------------- fitting

@dataclass(frozen=True)
class FitParams:
    """Arc-fitting settings.

    Args:
        loss_scale: soft-L1 scale, m (about twice the depth noise at 1 m).
        graph_radius: neighbourhood of the geodesic graph, m.
        bin_width: arc-length bin of the medial points, m.
        max_gap: longest gap between pieces the ordering walks across, m.
        seen_radius: a backbone point counts as seen when a point within this arc length of
            it lies on the tube, m; unseen intervals shorter than min_unseen are not reported.
        max_nfev: iteration cap of the joint refinement.
        assess: say how sure the fit is (FitConfidence): per-section seen fraction, tip
            uncertainty, other explanations of a partly unseen arm; False fits as before.
    """

    loss_scale: float = 0.003
    graph_radius: float = 0.012
    bin_width: float = 0.015
    max_gap: float = 0.25
    seen_radius: float = 0.006
    min_unseen: float = 0.015
    inlier: float = 0.005
    max_nfev: int = 60
    assess: bool = True


@dataclass(frozen=True)
class ArmFit:
    """An arm configuration fitted to the arm's points.

    Args:
        config: the fitted configuration.
        residual: (M,) signed distance of each point from the fitted tube surface, m.
        arc_length: (M,) arc length of each point's nearest backbone point, m.
        unseen: ((start, end), ...) arc-length intervals with no point on them, m.
        lengths_known: whether the section lengths were given.
        n_points: points fitted; nfev: residual evaluations; time_s: wall time, s.
        initial: the configuration the refinement started from.
        confidence: how sure the fit is (None when FitParams.assess is off).
    """

    config: ArmConfig
    residual: np.ndarray
    arc_length: np.ndarray
    unseen: tuple
    lengths_known: bool
    n_points: int
    nfev: int
    time_s: float
    initial: ArmConfig
    tip: np.ndarray = field(default_factory=lambda: np.zeros(3))
    confidence: FitConfidence | None = None

    def stats(self, inlier: float = 0.005) -> dict:
        a = np.abs(self.residual)
        return {"n_points": int(self.n_points), "mean_abs_mm": 1e3 * float(a.mean()),
                "median_abs_mm": 1e3 * float(np.median(a)),
                "rms_mm": 1e3 * float(np.sqrt((a ** 2).mean())),
                "p95_abs_mm": 1e3 * float(np.percentile(a, 95)), "max_abs_mm": 1e3 * float(a.max()),
                "inlier_fraction": float((a <= inlier).mean())}

    def unseen_sections(self) -> list[dict]:
        starts = np.concatenate([[0.0], np.cumsum(self.config.s)])
        out = []
        for a, b in self.unseen:
            secs = [i + 1 for i in range(self.config.n_sections)
                    if a < starts[i + 1] and b > starts[i]]
            out.append({"from_m": float(a), "to_m": float(b), "sections": secs})
        return out

    def to_dict(self) -> dict:
        return {"config": self.config.to_dict(), "tip": self.tip.tolist(),
                "lengths_known": self.lengths_known, "residual": self.stats(),
                "unseen": self.unseen_sections(), "nfev": int(self.nfev),
                "time_s": float(self.time_s), "total_length_m": float(np.sum(self.config.s)),
                **({"confidence": self.confidence.to_dict()} if self.confidence else {})}


def order_along_arm(points: np.ndarray, base: np.ndarray, params: FitParams = FitParams(),
                    heading: np.ndarray | None = None):
    """Geodesic distance of each point from the base (NaN for points the walk misses).

    Within each connected piece of a radius graph: Dijkstra from the point where the walk
    enters it. Pieces are walked in order: the next is the one nearest the previous piece's
    far end, so a tip curled back near the arm's start does not short-cut the order. With a
    heading (the arm's direction at the base), a piece is entered at whichever of its two
    ends carries the walk's direction on (a wrap's tip curls back next to the gap an object
    opened, and the nearest point of the piece beyond is then its far end).
    """
    tree = cKDTree(points)
    pairs = tree.query_pairs(params.graph_radius, output_type="ndarray")
    w = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
    M = len(points)
    G = coo_matrix((w, (pairs[:, 0], pairs[:, 1])), shape=(M, M)).tocsr()
    n_comp, comp = connected_components(G, directed=False)
    members = [np.flatnonzero(comp == c) for c in range(n_comp)]
    g = np.full(M, np.nan)
    here, g_here = np.asarray(base, float), 0.0
    left = set(range(n_comp))
    while left:
        dists = {c: np.linalg.norm(points[members[c]] - here, axis=1) for c in left}
        c = min(left, key=lambda k: dists[k].min())
        if dists[c].min() > params.max_gap:
            break
        entry = members[c][dists[c].argmin()]
        local = dijkstra(G, directed=False, indices=entry)[members[c]]
        if heading is not None and local.max() > 2 * ENTRY_REACH:
            entry, local = _aligned_entry(G, points, members[c], entry, local, here, heading)
        g[members[c]] = g_here + np.linalg.norm(points[entry] - here) + local
        far = members[c][np.argmax(local)]
        if heading is not None:
            back = members[c][local >= local.max() - ENTRY_REACH]
            heading = points[far] - points[back].mean(0)
        here, g_here = points[far], g[far]
        left.remove(c)
    return g


ENTRY_REACH = 0.03  # m: the stretch of a piece's end whose mean gives its direction


def _aligned_entry(G, points, members, entry, local, here, heading):
    """Of a piece's two ends (the nearest point and the far end of the geodesic from it),
    the one whose inward direction best continues `heading` across the gap from `here`;
    (entry index, geodesic distances of the members from it)."""
    other = members[np.argmax(local)]
    local_o = dijkstra(G, directed=False, indices=other)[members]
    h = heading / max(np.linalg.norm(heading), 1e-9)

    def score(e, loc):
        inward = points[members[loc <= ENTRY_REACH]].mean(0) - points[e]
        inward /= max(np.linalg.norm(inward), 1e-9)
        return np.linalg.norm(points[e] - here) * (2.0 - inward @ h)

    return (entry, local) if score(entry, local) <= score(other, local_o) else (other, local_o)


def medial_polyline(points, geodesic, base, bin_width):
    """Centroids of points binned by geodesic distance, with arc length along them from the
    base (a first guess at the centre line, offset towards the camera by under a radius)."""
    ok = np.isfinite(geodesic)
    b = np.floor(geodesic[ok] / bin_width).astype(int)
    uniq, inv = np.unique(b, return_inverse=True)
    counts = np.bincount(inv)
    cen = np.stack([np.bincount(inv, weights=points[ok][:, i]) for i in range(3)], 1)
    g_mid = np.bincount(inv, weights=geodesic[ok])
    full = counts >= 3
    cen, g_mid = cen[full] / counts[full, None], g_mid[full] / counts[full]
    steps = np.linalg.norm(np.diff(np.vstack([base, cen]), axis=0), axis=1)
    sig = np.cumsum(steps)
    # Each point's arc length: its geodesic distance mapped through the bins' (g, sigma).
    point_sig = np.full(len(points), np.nan)
    if len(sig):
        point_sig[ok] = np.interp(geodesic[ok], g_mid, sig, left=None, right=None) \
            + np.maximum(geodesic[ok] - g_mid[-1], 0.0)
    return cen, sig, point_sig


def _section_arm(arm: ContinuumArm, R, p) -> ContinuumArm:
    return replace(arm, n_sections=1, base_position=p, base_rotation=R)


def _fit_section_arc(arm1: ContinuumArm, s: float, targets, sigma, kappa_max):
    """(u, v) of one section's arc through target points at local arc lengths sigma."""
    if len(targets) == 0:
        return 0.0, 0.0
    R, p0 = arm1.base_rotation, arm1.base_position
    d = targets - p0
    t = R[:, 2]
    perp = d - (d @ t)[:, None] * t
    k0 = 2 * np.linalg.norm(perp, axis=1) / np.maximum((d ** 2).sum(1), 1e-6)
    j = np.argmax(sigma)
    direction = R.T @ perp[j]
    phi0 = np.arctan2(direction[1], direction[0])
    kk = min(float(np.median(k0)), kappa_max)
    x0 = np.array([kk * np.cos(phi0), kk * np.sin(phi0)])
    sig = np.clip(sigma, 0.0, s)

    def res(x):
        cfg = ArmConfig([s], [np.hypot(*x)], [np.arctan2(x[1], x[0])])
        return (arm1.backbone(cfg, arc_length=sig).position - targets).ravel()

    sol = least_squares(res, x0, bounds=([-kappa_max] * 2, [kappa_max] * 2), max_nfev=30)
    return tuple(sol.x)


def _uv_config(arm: ContinuumArm, s, u, v):
    """The configuration of (s, u, v), its curvature held to the arm's curvature and bend
    limits (kappa_i <= min(curvature_max, bend_max / s_i)): a section bent past half a turn
    would coil through itself, and no real arm (nor any true wrap) does."""
    k = np.minimum(np.hypot(u, v), arm.curvature_limit(s))
    return ArmConfig(s, k, np.arctan2(v, u))


def medial_points(arm: ContinuumArm, points, params: FitParams = FitParams(),
                  heading: bool = False):
    """medial_polyline of the points ordered from the arm's base: (centres, their arc
    lengths, each point's arc length); heading: enter pieces along the walk's direction."""
    g = order_along_arm(points, arm.base_position, params,
                        arm.base_rotation[:, 2] if heading else None)
    return medial_polyline(points, g, arm.base_position, params.bin_width)


def medial_length(arm: ContinuumArm, medial, params: FitParams = FitParams()) -> float:
    """The arm's length seen along its medial points, m."""
    sig = medial[1]
    return (sig[-1] + params.bin_width / 2) if len(sig) else arm.n_sections * arm.section_length_min


def config_along(arm: ContinuumArm, points, medial, lengths,
                 params: FitParams = FitParams()) -> ArmConfig:
    """One arc a section in turn through the medial points, then the section's own points."""
    cen, sig, point_sig = medial
    n = arm.n_sections
    s = np.asarray(lengths, float)
    u, v = np.zeros(n), np.zeros(n)
    R, p = arm.base_rotation, arm.base_position
    start = 0.0
    km = arm.curvature_max
    for i in range(n):  # a loop over sections (3); each fit is vectorised over points
        sel = (sig >= start) & (sig <= start + s[i] + 1e-9)
        arm1 = _section_arm(arm, R, p)
        if not sel.any() and i > 0:
            u[i], v[i] = u[i - 1], v[i - 1]
        else:
            u[i], v[i] = _fit_section_arc(arm1, s[i], cen[sel], sig[sel] - start, km)
        # The medial points lean towards the camera; refit to the section's own surface points.
        mine = points[(point_sig >= start) & (point_sig <= start + s[i])]
        if len(mine) >= 10:
            f = _Residuals(arm1, mine, s[i:i + 1], caps=False)
            sol = least_squares(f, np.array([u[i], v[i]]), jac=f.jac, bounds=([-km] * 2,
                                [km] * 2), loss="soft_l1", f_scale=params.loss_scale,
                                max_nfev=20)
            u[i], v[i] = sol.x
        cfg = _uv_config(arm, s[i:i + 1], u[i:i + 1], v[i:i + 1])
        Rs, ps = _section_arm(arm, R, p).section_frames(cfg)
        R, p = Rs[-1], ps[-1]
        start += s[i]
    return _uv_config(arm, s, u, v)


def centre_line(arm: ContinuumArm, cfg: ArmConfig, sigma):
    """Positions and unit tangents (m, 3) at arc lengths sigma: ContinuumArm.backbone without
    the normal frames, about three times faster (the fit evaluates it ~10 times an iterate)."""
    starts = np.concatenate([[0.0], np.cumsum(cfg.s)[:-1]])
    sec = np.clip(np.searchsorted(starts, sigma, side="right") - 1, 0, cfg.n_sections - 1)
    local = np.clip(sigma - starts[sec], 0.0, cfg.s[sec])
    R0, p0 = arm.section_frames(cfg)
    x = cfg.kappa[sec] * local
    cphi, sphi = np.cos(cfg.phi[sec]), np.sin(cfg.phi[sec])
    radial = local * 0.5 * x * np.sinc(x / (2 * np.pi)) ** 2  # s (1 - cos x) / x
    p_local = np.stack([radial * cphi, radial * sphi, local * np.sinc(x / np.pi)], -1)
    sx = np.sin(x)
    t_local = np.stack([cphi * sx, sphi * sx, np.cos(x)], -1)
    Rb = R0[sec]
    return (p0[sec] + np.einsum("mij,mj->mi", Rb, p_local),
            np.einsum("mij,mj->mi", Rb, t_local))


# Free lengths' starts: fractions of the seen length a section.
START_SPLITS = ((1 / 3, 1 / 3, 1 / 3), (0.3, 0.4, 0.3), (0.3, 0.3, 0.4))
GOOD_FIT = 0.0015  # m: the later starts are skipped once one fits with this soft-L1 RMS
OVERRUN = 0.06  # m: free lengths are charged for running this far past the seen length
TIP_WEIGHT = 20.0  # free lengths: weight of the arm's length beyond its last seen point
LIMIT_WEIGHT = 20.0  # weight of the bend beyond the limit, rad, times the section length
TIP_SLACK = 0.002  # m: the last surface point sampled lies up to half a voxel short of the tip
LAST_POINT_TOL = 0.003  # m: a point this near the tube counts towards the seen length
FREE_WEIGHT = 1.0  # a ray through the tube counts as much as a point off it
FREE_OK = 15  # rays through the tube's core that a good fit may keep (flying pixels)
FREE_NFEV = 30  # iteration cap of the refinement with the free-space term
SHORTEN = 0.008  # m: free lengths also try the fit with the last section this much shorter


class _Residuals:
    """Point-to-tube residuals with nearest arc lengths cached for the Jacobian."""

    def __init__(self, arm: ContinuumArm, points, lengths, caps: bool = True,
                 length_cap: float = np.inf, free=None, prior=None, charge_tail: bool = True):
        self.arm, self.points, self.lengths, self.caps = arm, points, lengths, caps
        self.length_cap, self.charge_tail = length_cap, charge_tail
        self.free, self.prior = free, prior  # FreeSpaceTerm, ConfigPrior or None
        self.n = arm.n_sections
        self.key = None

    def split(self, x):
        n = self.n
        if self.lengths is None:
            return x[:n], x[n:2 * n], x[2 * n:]
        return self.lengths, x[:n], x[n:]

    def config(self, x) -> ArmConfig:
        return _uv_config(self.arm, *self.split(x))

    def excess(self, x):
        """(n,) residuals of the bend limit: the configuration holds each curvature to its
        limit, which leaves no gradient beyond it; these lead an iterate that strayed there
        back (zero within the limits, so they do not move a fit that stays inside)."""
        s, u, v = self.split(x)
        over = np.maximum(np.hypot(u, v) - self.arm.curvature_limit(s), 0.0)
        return LIMIT_WEIGHT * s * s * over

    def nearest(self, cfg: ArmConfig):
        total = float(np.sum(cfg.s))
        bb = self.arm.backbone(cfg, n=max(int(total / 0.003), 20))
        _, j = cKDTree(bb.position).query(self.points)
        step = np.einsum("mi,mi->m", self.points - bb.position[j], bb.tangent[j])
        sigma = np.clip(bb.arc_length[j] + step, 0.0, total)
        near = (sigma, sigma >= total - 1e-12, sigma <= 1e-12)
        if self.free is None:
            return near
        return near + self.free.distances(bb.position, bb.arc_length, bb.tangent)[::2]

    def at(self, cfg: ArmConfig, sigma, at_tip, at_base):
        total = float(np.sum(cfg.s))
        sigma = np.where(at_tip, total, np.minimum(sigma, total))
        position, tangent = centre_line(self.arm, cfg, sigma)
        d = self.points - position
        axial = np.einsum("mi,mi->m", d, tangent)
        radial = np.linalg.norm(d - axial[:, None] * tangent, axis=1)
        beyond = self.caps & ((at_tip & (axial > 0)) | (at_base & (axial < 0)))
        # Beyond an end the tube is a flat-capped solid: distance to the cap disc.
        capped = np.hypot(axial, np.maximum(radial - self.arm.radius, 0.0))
        return np.where(beyond, capped, radial - self.arm.radius)

    def residuals(self, cfg: ArmConfig, sigma, at_tip, at_base):
        r = self.at(cfg, sigma, at_tip, at_base)
        if self.lengths is not None:
            return r
        if not self.charge_tail:
            # The commanded lengths say how far the arm runs on past its last seen point.
            return np.append(r, [0.0, 0.0])
        # Free lengths: nothing in the points stops the arm from running on past its last
        # seen point, so the part beyond it is charged as if TIP_WEIGHT points lay off it.
        total = float(np.sum(cfg.s))
        # The last point on the tube, measured along the arm past its end too: a point on
        # the end cap then ties the end to it (clipped to the end, it would let the arm run
        # on for free), and a stray point off the tube does not license it.
        sig = np.minimum(sigma, total)
        if at_tip.any():
            p_end, t_end = centre_line(self.arm, cfg, np.array([total]))
            sig = sig.copy()
            sig[at_tip] = total + (self.points[at_tip] - p_end[0]) @ t_end[0]
        on = np.abs(r) <= LAST_POINT_TOL
        last = sig[on].max() if on.any() else sig.max()
        return np.append(r, [TIP_WEIGHT * max(total - last - TIP_SLACK, 0.0),
                             TIP_WEIGHT * max(total - self.length_cap, 0.0)])

    def full(self, x, near):
        cfg = self.config(x)
        parts = [self.residuals(cfg, *near[:3]), self.excess(x)]
        if self.free is not None:
            ray, ray_sigma = near[3:]
            pos = centre_line(self.arm, cfg, np.minimum(ray_sigma, np.sum(cfg.s)))[0]
            parts.append(FREE_WEIGHT * self.free.residuals(pos, ray))
        if self.prior is not None:
            parts.append(self.prior.residuals(*self.split(x), lengths_free=self.lengths is None))
        return np.concatenate(parts)


    def __call__(self, x):
        self.key = (x.tobytes(), self.nearest(self.config(x)))
        return self.full(x, self.key[1])

    def jac(self, x):
        near = self.key[1] if self.key and self.key[0] == x.tobytes() else \
            self.nearest(self.config(x))
        r0 = self.full(x, near)
        J = np.empty((len(r0), len(x)))
        for k in range(len(x)):  # one column a parameter (9), each vectorised over points
            h = 1e-6 * max(1.0, abs(x[k]))
            xk = x.copy()
            xk[k] += h
            J[:, k] = (self.full(xk, near) - r0) / h
        return J


def soft_l1_cost(r, scale: float) -> float:
    """least_squares' soft-L1 cost of residuals r at the given scale."""
    return float(np.sum(scale ** 2 * (np.sqrt(1 + (np.asarray(r) / scale) ** 2) - 1)))


def soft_l1_rms(r, scale: float) -> float:
    """The RMS that the soft-L1 cost of residuals r corresponds to, m (what GOOD_FIT and
    'fits the points equally well' compare)."""
    z = (np.asarray(r) / scale) ** 2
    return scale * float(np.sqrt(np.mean(2 * (np.sqrt(1 + z) - 1)))) if len(z) else 0.0


@dataclass(frozen=True)
class ConfigPrior:
    """The commanded configuration with its uncertainty, as a Gaussian prior on the fit.

    A real arm knows roughly what it was told: where no point shows a section, the fit
    keeps it near the command instead of inventing a shape. The prior enters the least
    squares as residuals scaled by NOISE (the points' depth noise), so that its weight
    against the points is that of a Gaussian of the stated standard deviations against
    points of that noise; the soft-L1 loss makes it give way where many points disagree
    (a real arm pressed out of its commanded shape by the object).

    Args:
        config: the commanded configuration.
        sigma_s: standard deviation of each section length, m.
        sigma_kappa: of each curvature, 1/m.
        sigma_phi: of each bending direction, rad (as an arc: kappa * sigma_phi, 1/m).
    """

    config: ArmConfig
    sigma_s: float = 0.01
    sigma_kappa: float = 1.0
    sigma_phi: float = 0.2

    NOISE = 0.0015  # m

    def __post_init__(self):
        if min(self.sigma_s, self.sigma_kappa, self.sigma_phi) <= 0:
            raise PointCloudError(f"prior uncertainties must be positive, got sigma_s "
                                  f"{self.sigma_s}, sigma_kappa {self.sigma_kappa}, sigma_phi "
                                  f"{self.sigma_phi}")

    def residuals(self, s, u, v, lengths_free: bool = True) -> np.ndarray:
        c = self.config
        er = np.stack([np.cos(c.phi), np.sin(c.phi)])
        du = np.stack([u - c.kappa * er[0], v - c.kappa * er[1]])
        radial = np.einsum("in,in->n", du, er) / self.sigma_kappa
        across = (du[1] * er[0] - du[0] * er[1]) / np.hypot(c.kappa * self.sigma_phi,
                                                           self.sigma_kappa)
        parts = [radial, across] + ([(s - c.s) / self.sigma_s] if lengths_free else [])
        return self.NOISE * np.concatenate(parts)

    def to_dict(self) -> dict:
        return {"config": self.config.to_dict(), "sigma_s_m": self.sigma_s,
                "sigma_kappa_per_m": self.sigma_kappa, "sigma_phi_rad": self.sigma_phi}


def unseen_intervals(total: float, arc_length, residual, params: FitParams = FitParams()):
    """Arc-length intervals of the backbone with no inlier point near them."""
    grid = np.arange(0.0, total + 1e-9, params.seen_radius / 2)
    a = np.sort(arc_length[np.abs(residual) <= params.inlier])
    if len(a) == 0:
        return ((0.0, total),)
    k = np.clip(np.searchsorted(a, grid), 1, len(a) - 1)
    near = np.minimum(np.abs(a[k] - grid), np.abs(a[k - 1] - grid))
    seen = near <= params.seen_radius
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (~seen).astype(int), [0]])))
    runs = edges.reshape(-1, 2)
    out = []
    for i, j in runs:
        lo, hi = grid[i], min(grid[j - 1], total)
        if hi - lo >= params.min_unseen:
            out.append((float(lo), float(hi)))
    return tuple(out)


def _prefit(arm, points, lengths, params, x0cfg, point_sig):
    """(x0, lower bounds, upper bounds, cost): the start moved onto the points at the arc
    lengths the ordering gave them (cost 0 when the ordering gave too few)."""
    n, km = arm.n_sections, arm.curvature_max
    uv0 = np.concatenate([x0cfg.kappa * np.cos(x0cfg.phi), x0cfg.kappa * np.sin(x0cfg.phi)])
    lo_uv, hi_uv = np.full(2 * n, -km), np.full(2 * n, km)
    if lengths is None:
        x0 = np.concatenate([np.clip(x0cfg.s, arm.section_length_min, arm.section_length_max),
                             uv0])
        lo = np.concatenate([np.full(n, arm.section_length_min), lo_uv])
        hi = np.concatenate([np.full(n, arm.section_length_max), hi_uv])
    else:
        x0, lo, hi = uv0, lo_uv, hi_uv
    known = np.isfinite(point_sig)
    if known.sum() >= 10:
        # Correspondences from the ordering first: a wide basin, where nearest-point
        # matching would let a wrong start pull points onto the wrong turn of the wrap.
        fixed = _Residuals(arm, points[known], lengths)
        sig_k = point_sig[known]

        def along(x):
            cfg = fixed.config(x)
            total = float(np.sum(cfg.s))
            return np.append(fixed.at(cfg, np.minimum(sig_k, total), sig_k >= total,
                                      sig_k <= 0.0), fixed.excess(x))

        pre = least_squares(along, np.clip(x0, lo, hi), bounds=(lo, hi), loss="soft_l1",
                            f_scale=3 * params.loss_scale, max_nfev=params.max_nfev // 2)
        return pre.x, lo, hi, pre.cost
    return x0, lo, hi, 0.0


@dataclass
class _Refined:
    """One start refined: the solution, its configuration, each point's arc length and
    residual, the unseen intervals, evaluations, the residual function, and the rays through
    the tube at the solution."""

    sol: object
    config: ArmConfig
    arc_length: np.ndarray
    residual: np.ndarray
    unseen: tuple
    nfev: int
    fun: "_Residuals"
    n_free: int = 0

    def point_rms(self, params) -> float:
        return soft_l1_rms(self.residual, params.loss_scale)


def _refine(arm, points, lengths, params, x0, lo, hi, length_cap=np.inf, free=None,
            prior=None, max_nfev=None, charge_tail=True) -> _Refined:
    """Nearest-point refinement from x0 (with the free-space term and the prior, when given;
    charge_tail False lets free lengths run on past the last seen point)."""
    n = arm.n_sections
    fun = _Residuals(arm, points, lengths, length_cap=length_cap, free=free, prior=prior,
                     charge_tail=charge_tail)

    def solve(x):
        sol = least_squares(fun, np.clip(x, lo, hi), jac=fun.jac, bounds=(lo, hi),
                            loss="soft_l1", f_scale=params.loss_scale, x_scale="jac",
                            max_nfev=max_nfev or params.max_nfev)
        cfg = fun.config(sol.x)
        near = fun.nearest(cfg)
        res = fun.at(cfg, *near[:3])
        return _Refined(sol, cfg, near[0], res,
                        unseen_intervals(float(np.sum(cfg.s)), near[0], res, params),
                        sol.nfev, fun, len(near[3]) if free is not None else 0)

    out = solve(x0)
    nfev = out.nfev
    total = float(np.sum(out.config.s))
    if lengths is None and charge_tail and out.unseen and \
            out.unseen[-1][1] >= total - params.seen_radius:
        # The arm runs on past its last seen point: a local minimum the length prior could
        # not leave. Restart with the unseen tail cut off, from the distal sections back.
        x1 = out.sol.x.copy()
        cut = out.unseen[-1][1] - out.unseen[-1][0]
        for i in reversed(range(n)):
            take = min(cut, x1[i] - arm.section_length_min)
            x1[i] -= take
            cut -= take
        alt = solve(x1)
        nfev += alt.nfev
        if alt.sol.cost < out.sol.cost:
            out = alt
    if lengths is None:
        # Points round the tip hold the end in a shallow local minimum a few millimetres
        # past it (nearest points switch between the cap and the side): try it shorter.
        x1 = out.sol.x.copy()
        x1[n - 1] = max(x1[n - 1] - SHORTEN, arm.section_length_min)
        alt = solve(x1)
        nfev += alt.nfev
        if alt.sol.cost < out.sol.cost:
            out = alt
    out.nfev = nfev
    return out


def _known_length_starts(arm, points, lengths, params):
    """Starts with the section lengths known, made as they are tried: from the ordering that
    enters each piece at its nearest point, then from the one that enters it along the
    walk's direction (a tip curled back beside the gap an object opened makes the nearest
    point of the piece beyond its far end: the first ordering runs that piece backwards)."""
    for heading in (False, True):
        medial = medial_points(arm, points, params, heading=heading)
        yield config_along(arm, points, medial, lengths, params), medial[2]
    # Last, when neither fits well (a turn of the wrap touching another joins them in the
    # radius graph, and both orderings cut across): the curvatures of the free-length fit,
    # whose several splits of the seen length search more widely, on the known lengths. It
    # has converged on nearest-point matches already, so it skips the ordering's prefit.
    free = fit_arm(arm, points, None, replace(params, assess=False)).config
    yield (ArmConfig(lengths, np.minimum(free.kappa, arm.curvature_limit(lengths)), free.phi),
           np.full(len(points), np.nan))


def _free_length_starts(arm, points, medial, total, params):
    """Starts with free section lengths, made as they are tried: several splits of the seen
    length (a wrong split converges to a wrap that runs on along an overlapping turn, a
    local minimum the others do not share), then the ordering that enters each piece along
    the walk's direction."""
    splits = np.clip(total * np.asarray(START_SPLITS), arm.section_length_min,
                     arm.section_length_max)
    for s in splits:
        yield config_along(arm, points, medial, s, params), medial[2]
    aligned = medial_points(arm, points, params, heading=True)
    s = np.clip(np.full(arm.n_sections, medial_length(arm, aligned, params) / arm.n_sections),
                arm.section_length_min, arm.section_length_max)
    yield config_along(arm, points, aligned, s, params), aligned[2]
    # Last, when no ordering fits (a turn touching another joins them in the radius graph,
    # and both orderings cut across): the first start without the ordering's prefit, whose
    # correspondences are then wrong; nearest-point matching alone from the medial arcs.
    yield config_along(arm, points, medial, splits[0], params), np.full(len(points), np.nan)


def fit_arm(arm: ContinuumArm, points, lengths=None, params: FitParams = FitParams(),
            initial: ArmConfig | None = None, rays=None,
            prior: ConfigPrior | None = None) -> ArmFit:
    """Fit every section's (s, kappa, phi) to the arm's points (see the module docstring).

    Args:
        lengths: (n,) known section lengths, m, or None to fit them too.
        initial: a starting configuration (default: from the medial points).
        rays: freespace.FreeRays the cameras saw along (default: none, no free-space term).
        prior: the commanded configuration with its uncertainty (default: none).
    """
    from .confidence import assess, tip_may_continue
    from .freespace import FreeSpaceTerm

    t0 = time.perf_counter()
    points = np.asarray(points, float)
    if len(points) < 10:
        raise PointCloudError(f"only {len(points)} arm points; at least 10 are needed to fit")
    if lengths is not None:
        lengths = np.asarray(lengths, float).reshape(-1)
        if len(lengths) != arm.n_sections:
            raise PointCloudError(f"{len(lengths)} section lengths given; the arm has "
                                  f"{arm.n_sections} sections")
    if prior is not None and prior.config.n_sections != arm.n_sections:
        raise PointCloudError(f"the prior has {prior.config.n_sections} sections; the arm has "
                              f"{arm.n_sections}")
    free = FreeSpaceTerm(arm, rays) if rays is not None and len(rays) else None
    total = np.inf  # the seen length, when free lengths start from the medial points
    if initial is not None:
        starts = iter([(initial, np.full(len(points), np.nan))])
    elif lengths is not None:
        starts = _known_length_starts(arm, points, lengths, params)
    else:
        medial = medial_points(arm, points, params)
        total = medial_length(arm, medial, params)
        starts = _free_length_starts(arm, points, medial, total, params)
    if prior is not None and initial is None:
        # The command first: on a partly hidden arm it is the start nearest the truth.
        c = prior.config
        s0 = c.s if lengths is None else lengths
        first = ArmConfig(s0, np.minimum(c.kappa, arm.curvature_limit(s0)), c.phi)
        starts = itertools.chain([(first, np.full(len(points), np.nan))], starts)
    # Starts are tried in turn until one fits well; otherwise the best fit wins, preferring
    # any that does not run past the seen length by more than OVERRUN.
    fits, nfev = [], 0
    # Every solution is scored by the same cost: points, free space and prior together (with
    # a prior, its lengths, not the seen length, rank how far the arm runs on).
    scorer = _Residuals(arm, points, lengths, length_cap=total + OVERRUN, free=free,
                        prior=prior, charge_tail=prior is None)

    def attempt(k, x0cfg, point_sig, prefit=True, max_nfev=None, charge_tail=True):
        """Refine a start on the points (and prior); only a solution that the cameras saw
        through is refined again with the free-space term, which costs more an iteration."""
        nonlocal nfev
        x0, lo, hi, _ = _prefit(arm, points, lengths, params, x0cfg,
                                point_sig if prefit else np.full(len(points), np.nan))
        cap = total + OVERRUN if charge_tail else np.inf
        out = _refine(arm, points, lengths, params, x0, lo, hi, cap, None, prior, max_nfev,
                      charge_tail)
        nfev += out.nfev
        if free is not None:
            out.n_free = free.count(arm.backbone(out.config, n=int(np.sum(out.config.s) / 0.003)))
            if out.n_free > FREE_OK:
                again = _refine(arm, points, lengths, params, out.sol.x, lo, hi, cap, free,
                                prior, FREE_NFEV, charge_tail)
                nfev += again.nfev
                out = again
        over = charge_tail and float(np.sum(out.config.s)) > total + OVERRUN
        fits.append((over, soft_l1_cost(scorer(out.sol.x), params.loss_scale), k, out, x0cfg))
        return out, over

    for k, (x0cfg, point_sig) in enumerate(starts):
        out, over = attempt(k, x0cfg, point_sig)
        if not over and out.point_rms(params) < GOOD_FIT and out.n_free <= FREE_OK:
            break  # a start that fits this well is not the wrong turn of a wrap
    best = min(fits, key=lambda f: f[:3])
    if prior is not None and lengths is None and initial is None:
        # The command runs on well past the last seen point, and no camera could see there
        # (or none was given): let the prior's lengths carry the arm on unseen.
        short = np.sum(prior.config.s) - np.sum(best[3].config.s)
        if short > 2 * prior.sigma_s * np.sqrt(arm.n_sections) and \
                (free is None or tip_may_continue(arm, best[3].config, free)):
            c = prior.config
            attempt(len(fits), ArmConfig(c.s, np.minimum(c.kappa, arm.curvature_limit(c.s)),
                                         c.phi), None, prefit=False, charge_tail=False)
            best = min(fits, key=lambda f: f[:3])
    confidence = None
    if params.assess:
        confidence = assess(arm, points, lengths, params, best, fits, starts, attempt,
                            free, rays)
        best = min(fits, key=lambda f: f[:3])  # the alternatives may have found a better one
    out, x0cfg = best[3], best[4]
    return ArmFit(config=out.config, residual=out.residual, arc_length=out.arc_length,
                  unseen=out.unseen, lengths_known=lengths is not None, n_points=len(points),
                  nfev=nfev, time_s=time.perf_counter() - t0, initial=x0cfg,
                  tip=arm.tip_frame(out.config)[1], confidence=confidence)


def fit_cloud(cloud, arm: ContinuumArm, lengths=None,
              segment: SegmentParams = SegmentParams(), params: FitParams = FitParams(),
              eye=None, prior: ConfigPrior | None = None):
    """Segment then fit: (Segmentation, ArmFit).

    Args:
        cloud: a Cloud, or several Clouds of the same wrap from different cameras.
        eye: the camera position (3,), or one a cloud: free space is evidence only when it
            is known (default: none).
        prior: the commanded configuration with its uncertainty (default: none).
    """
    from threadpoolctl import threadpool_limits

    from .confidence import UNEXPLAINED_MAX
    from .freespace import free_rays, merge_rays

    clouds = list(cloud) if isinstance(cloud, (list, tuple)) else [cloud]
    eyes = [None] * len(clouds) if eye is None else \
        ([eye] if np.ndim(eye) == 1 else list(eye))
    if len(eyes) != len(clouds):
        raise PointCloudError(f"{len(clouds)} clouds but {len(eyes)} camera positions")
    segs = [segment_arm(c, arm, segment) for c in clouds]
    seg = segs[0] if len(segs) == 1 else merge_segmentations(segs)
    rays = None
    if all(e is not None for e in eyes):
        rays = merge_rays([free_rays(c.points, e, s.points)
                           for c, e, s in zip(clouds, eyes, segs)])
    try:
        # One BLAS thread: the Jacobians are thin (points x 9), and threads fighting over
        # them cost ten times the work on a busy machine.
        with threadpool_limits(limits=1):
            fit = fit_arm(arm, seg.points, lengths, params, rays=rays, prior=prior)
            if len(segs) > 1 and _unexplained(fit, params) > UNEXPLAINED_MAX:
                # Merged views can join turns of the wrap that one view keeps apart, and no
                # ordering of them starts the fit well: start from the first view's own fit.
                one = fit_arm(arm, segs[0].points, lengths, replace(params, assess=False),
                              rays=None if rays is None else
                              merge_rays([free_rays(clouds[0].points, eyes[0], segs[0].points)]),
                              prior=prior)
                again = fit_arm(arm, seg.points, lengths, params, initial=one.config,
                                rays=rays, prior=prior)
                if _unexplained(again, params) < _unexplained(fit, params):
                    fit = replace(again, time_s=fit.time_s + one.time_s + again.time_s)
    except PointCloudError as e:
        raise PointCloudError(f"{', '.join(c.source for c in clouds)}: {e}") from None
    return seg, fit


def _unexplained(fit: ArmFit, params: FitParams) -> float:
    return float(np.mean(np.abs(fit.residual) > params.inlier))


def merge_segmentations(segs: list[Segmentation]) -> Segmentation:
    """The arm's points of several views of one wrap as one segmentation (pieces numbered
    on across the views)."""
    offsets = np.cumsum([0] + [s.n_pieces for s in segs])[:-1]
    return Segmentation(points=np.concatenate([s.points for s in segs]),
                        piece=np.concatenate([s.piece + o for s, o in zip(segs, offsets)]),
                        n_input=sum(s.n_input for s in segs),
                        n_colour=sum(s.n_colour for s in segs),
                        table_plane=segs[0].table_plane,
                        dropped_pieces=sum((s.dropped_pieces for s in segs), ()))


# --------------------------------------------------------------------------- real vs simulated

def surface_deviation(arm: ContinuumArm, fit: ArmFit, points, spacing: float = 0.005) -> dict:
    """How far the measured arm lies from the simulated arm's surface at the fitted config.

    mean: mean |distance| of the points to the tube surface. Hausdorff: the larger of the
    farthest point from the surface and the farthest seen part of the surface from the
    points (backbone samples on seen arc lengths; the unseen parts and the tube's far side
    cannot be compared with what the camera did not see).
    """
    a = np.abs(fit.residual)
    total = float(np.sum(fit.config.s))
    grid = np.arange(0.0, total, spacing)
    seen = np.ones(len(grid), bool)
    for lo, hi in fit.unseen:
        seen &= ~((grid >= lo) & (grid <= hi))
    pos, _ = centre_line(arm, fit.config, grid[seen])
    back = cKDTree(points).query(pos)[0] - arm.radius if len(pos) else np.zeros(1)
    return {"mean_mm": 1e3 * float(a.mean()), "median_mm": 1e3 * float(np.median(a)),
            "points_to_surface_max_mm": 1e3 * float(a.max()),
            "surface_to_points_max_mm": 1e3 * float(np.max(back)),
            "hausdorff_mm": 1e3 * float(max(a.max(), np.max(back)))}


@dataclass(frozen=True)
class WrapSamples:
    """Centre-line samples of a wrap (first contact to tip), as chords.py reads them.

    Args:
        arc_length: (m,) arc lengths, m; position, normal: (m, 3).
    """

    arc_length: np.ndarray
    position: np.ndarray
    normal: np.ndarray


def real_and_simulated_wraps(arm: ContinuumArm, fit: ArmFit, points, first_contact: float,
                             spacing: float = 0.01, simulated: ArmConfig | None = None):
    """(real, simulated) WrapSamples on the arc lengths from first contact to the tip where
    the camera saw the arm, `spacing` apart.

    The real centre line is measured: each point moved one radius inwards along its
    direction from the fitted backbone, averaged per arc-length bin. The simulated one is the
    backbone of `simulated` (the commanded configuration; default the fitted one) at the same
    arc lengths. Both use that configuration's bending direction as normal (the arm's
    curvature, which a real arm reports, not the object's).
    """
    total = float(np.sum(fit.config.s))
    pos, tan = centre_line(arm, fit.config, fit.arc_length)
    d = points - pos
    perp = d - np.einsum("mi,mi->m", d, tan)[:, None] * tan
    centre = points - arm.radius * perp / np.maximum(np.linalg.norm(perp, axis=1), 1e-9)[:, None]
    inl = (np.abs(fit.residual) <= 2 * FitParams().inlier) & (fit.arc_length >= first_contact)
    b = np.floor((fit.arc_length[inl] - first_contact) / spacing).astype(int)
    nb = int(np.floor((total - first_contact) / spacing)) + 1
    counts = np.bincount(b, minlength=nb)
    sums = np.stack([np.bincount(b, weights=centre[inl][:, i], minlength=nb) for i in range(3)], 1)
    ok = counts >= 3
    arc = first_contact + spacing * (np.arange(nb)[ok] + 0.5)
    arc = np.minimum(arc, total)
    real = sums[ok] / counts[ok, None]
    sim_cfg = fit.config if simulated is None else simulated
    bb = arm.backbone(sim_cfg, arc_length=np.minimum(arc, float(np.sum(sim_cfg.s))))
    return (WrapSamples(arc, real, bb.normal), WrapSamples(arc, bb.position, bb.normal))


def chord_comparison(real: WrapSamples, sim: WrapSamples, model=None) -> dict:
    """Chord-histogram distance (total variation, 0 = same, 1 = disjoint) between the real
    and the simulated wrap and, with a trained model, the category each yields. Without a
    model the histogram's bins span both wraps' chords (7 a dimension, as the paper's)."""
    from ..features.chords import ChordHistogram, ChordParams, chords_from_points

    params = model.chord_params if model is not None else ChordParams()
    cr = chords_from_points(real.position, real.normal, params.min_length)
    cs = chords_from_points(sim.position, sim.normal, params.min_length)
    out = {"n_chords_real": len(cr), "n_chords_simulated": len(cs)}
    if len(cr) == 0 or len(cs) == 0:
        out["histogram_distance"] = None
        out["note"] = "too few seen centre-line points after the first contact for chords"
        return out
    if model is not None:
        from ..features.chords import histogram_rows
        n_cells = int((model.edges.shape[1] - 1) ** model.edges.shape[0])
        H = histogram_rows([model.bin_index(cr), model.bin_index(cs)], n_cells)
        proba = model.predict_proba([cr, cs])
        out["category_real"] = str(model.classes[int(np.argmax(proba[0]))])
        out["category_simulated"] = str(model.classes[int(np.argmax(proba[1]))])
        out["probabilities_real"] = dict(zip(map(str, model.classes), proba[0].tolist()))
        out["probabilities_simulated"] = dict(zip(map(str, model.classes), proba[1].tolist()))
        out["bins"] = "model"
    else:
        H = ChordHistogram(bins=7).fit([cr, cs]).transform([cr, cs])
        out["bins"] = "both wraps, 7 a dimension"
    out["histogram_distance"] = 0.5 * float(abs(H[0] - H[1]).sum())
    return out


def first_contact_arc_length(arm: ContinuumArm, config: ArmConfig, mesh,
                             tolerance: float = 0.003, n: int = 400) -> float | None:
    """Arc length where the arm at `config` first comes within `tolerance` of the object in
    the simulation scene (scene.WrapScene, its signed distance to the real surface), or None.

    A tolerance, not exact touch: a fitted configuration is a millimetre or two off the wrap
    that produced it and may stop just short of the surface (or, for a deformed real arm,
    pass into it).
    """
    from ..wrapping.scene import WrapScene

    scene = WrapScene(arm, mesh)
    gap = scene.clearance(config, n=n)
    hit = np.flatnonzero(gap <= tolerance)
    return float(np.sum(config.s) * hit[0] / (n - 1)) if len(hit) else None


def fig8(path, cloud: Cloud, seg: Segmentation, fit: ArmFit, arm: ContinuumArm, mesh=None,
         title: str = "") -> Path:
    """The paper's Fig. 8 for one wrap: the cloud, the segmented arm, the reconstruction
    (the arm at the fitted configuration, with the object) in three 3-D panels."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from .depth_camera import tube_mesh

    path = Path(path)
    lo = seg.points.min(0) - 0.05
    hi = seg.points.max(0) + 0.05
    if mesh is not None:
        lo, hi = np.minimum(lo, mesh.bounds[0]), np.maximum(hi, mesh.bounds[1])
    lo[2] = min(lo[2], 0.0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2
    fig = plt.figure(figsize=(15, 5))
    rng = np.random.default_rng(0)

    def axes(k, name):
        ax = fig.add_subplot(1, 3, k, projection="3d")
        ax.set_title(name)
        for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
            set_lim(c - half, c + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=35, azim=-60)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        return ax

    ax = axes(1, "point cloud")
    inside = np.all((cloud.points >= centre - half) & (cloud.points <= centre + half), axis=1)
    idx = np.flatnonzero(inside)
    idx = rng.choice(idx, min(len(idx), 15000), replace=False) if len(idx) else idx
    cols = cloud.colours[idx] if cloud.colours is not None else "0.4"
    ax.scatter(*cloud.points[idx].T, c=cols, s=0.5, depthshade=False)
    ax = axes(2, f"segmented arm ({seg.n_pieces} piece{'s' * (seg.n_pieces != 1)})")
    ax.scatter(*seg.points.T, c=seg.piece, cmap="tab10", vmin=0, vmax=9, s=1.5,
               depthshade=False)
    ax = axes(3, "reconstruction (simulated arm at the fitted configuration)")
    tube = tube_mesh(arm, fit.config, spacing=0.01, n_around=12)
    ax.add_collection3d(Poly3DCollection(tube.vertices[tube.faces], facecolor=ARM_COLOUR,
                                         edgecolor="none", alpha=0.9))
    if mesh is not None:
        ax.add_collection3d(Poly3DCollection(mesh.vertices[mesh.faces], facecolor="0.7",
                                             edgecolor="none", alpha=0.35))
    fig.suptitle(title)
    fig.tight_layout()
    write_atomic(path, lambda f: fig.savefig(f, format=path.suffix.lstrip(".") or "png", dpi=110))
    plt.close(fig)
    return path


def at_config(arm: ContinuumArm, fit: ArmFit, points, config: ArmConfig,
              params: FitParams = FitParams()) -> ArmFit:
    """The fit's points measured against the arm at another configuration (the commanded
    one): their residuals, arc lengths and unseen intervals there."""
    fun = _Residuals(arm, np.asarray(points, float), None)
    near = fun.nearest(config)
    res = fun.at(config, *near[:3])
    return replace(fit, config=config, residual=res, arc_length=near[0],
                   unseen=unseen_intervals(float(np.sum(config.s)), near[0], res, params),
                   tip=arm.tip_frame(config)[1])


def compare_real(cloud: Cloud, seg: Segmentation, fit: ArmFit, arm: ContinuumArm, object_path,
                 model=None, png=None, simulated: ArmConfig | None = None) -> dict:
    """Real against simulated wrap (section V-D): per-point deviation of the segmented arm from
    the simulated arm, the chord-histogram distance between the two wraps and, with a trained
    model, the category each yields; Fig. 8 to `png`.

    The simulated arm is at `simulated`, the commanded configuration when the arm saved it
    (as the paper did, "we also save the arm configurations of the wraps"), else at the
    fitted configuration.
    """
    from ..objects.mesh import load_mesh
    mesh = load_mesh(object_path)
    sim_fit = fit if simulated is None else at_config(arm, fit, seg.points, simulated)
    dev = surface_deviation(arm, sim_fit, seg.points)
    first = first_contact_arc_length(arm, sim_fit.config, object_path)
    out = {"cloud": cloud.source, "object": str(object_path), "fit": fit.to_dict(),
           "simulated_at": "fitted configuration" if simulated is None else
           "commanded configuration (--prior)", "deviation": dev, "first_contact_m": first}
    if first is None:
        out["chords"] = {"histogram_distance": None,
                         "note": "the simulated arm does not touch the object"}
    else:
        real, sim = real_and_simulated_wraps(arm, fit, seg.points, first, simulated=simulated)
        out["chords"] = chord_comparison(real, sim, model)
    if png is not None:
        out["png"] = str(fig8(png, cloud, seg, fit, arm, mesh,
                              title=f"{Path(cloud.source).name}: deviation mean "
                                    f"{dev['mean_mm']:.1f} mm, Hausdorff "
                                    f"{dev['hausdorff_mm']:.1f} mm"))
    return out


def compare_shipped_clouds(out_dir, model=None, data_dir=None) -> dict:
    """compare_real on every cloud shipped in real/data (each with its sidecar JSON: object
    mesh relative to the project folder, base pose and true configuration, whose section
    lengths are taken as known), with one Fig. 8 a cloud in out_dir; a table of figures."""
    from pydrake.math import RollPitchYaw

    from ..kinematics.arm import load_arm
    checkout = Path(__file__).resolve().parent.parent  # real/ is not in the wheel
    data_dir = Path(data_dir) if data_dir is not None else checkout / "real" / "data"
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows, first_png = [], None
    for path in sorted(data_dir.glob("*.pcd")):
        meta = json.loads(path.with_suffix(".json").read_text())
        arm = load_arm().with_base(np.asarray(meta["base_position"], float),
                                   RollPitchYaw(meta["base_rpy"]).ToRotationMatrix().matrix())
        truth = ArmConfig.from_dict(meta["config"])
        cloud = load_cloud(path)
        seg, fit = fit_cloud(cloud, arm, truth.s)
        png = out_dir / f"fig8_{path.stem}.png"
        r = compare_real(cloud, seg, fit, arm, checkout / meta["object"], model, png)
        tip_true = arm.tip_frame(truth)[1]
        row = {"cloud": path.name,
               "tip_error_mm": float(1000 * np.linalg.norm(fit.tip - tip_true)),
               "deviation_mean_mm": r["deviation"]["mean_mm"],
               "hausdorff_mm": r["deviation"]["hausdorff_mm"],
               "histogram_distance": r["chords"].get("histogram_distance"),
               "fit_s": fit.time_s, "png": png.name}
        for key in ("category_real", "category_simulated"):
            if key in r["chords"]:
                row[key] = r["chords"][key]
        rows.append(row)
        first_png = first_png or png
    return {"clouds": rows, "png": None if first_png is None else
            f"{out_dir.name}/{first_png.name}"}
