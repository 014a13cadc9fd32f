"""Segmenting the arm out of a point cloud.

With Open3D: crop to the arm's reach, voxel-downsample, keep the points whose colour
is the arm's paint (ARM_COLOUR, orange: a hue that neither tables, skin nor grey or blue
objects share), remove the table plane (RANSAC), cluster (DBSCAN), then keep the clusters
that chain to the arm's base with gaps no longer than an occluder can hide. Keeping every
piece of the chain, not the largest cluster, matters: an object in front of the arm splits
it, and a fit to one piece loses the tip.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from ..kinematics.arm import ARM_COLOUR, ContinuumArm
from .cloud import Cloud, PointCloudError, row_norms

__all__ = ["SegmentParams", "Segmentation", "colour_gate", "dominant_plane", "segment_arm",
           "merge_segmentations"]


def dominant_plane(points, threshold: float, *, iterations: int = 300, seed: int = 0,
                   score_points: int = 5000):
    """The plane most points lie within `threshold` of, by RANSAC: (a, b, c, d) with unit
    normal (a, b, c), c >= 0, and the indices of those points.

    Deterministic for a seed, which Open3D's segment_plane is not: its threads draw the
    samples, so two runs on one cloud could disagree about a point at the threshold, and a
    segmentation fed to a classifier or a fit must give the same answer twice. The best
    sample's inliers are refitted by least squares (the plane through their centroid normal
    to their least-variance direction) and counted again. Samples are scored on at most
    `score_points` of the points, drawn with the same seed: the plane a whole table holds
    wins on any few thousand of them, at a tenth of the cost on a 640 x 480 cloud.
    """
    p = np.asarray(points, float).reshape(-1, 3)
    if len(p) < 3:
        raise ValueError(f"a plane needs at least 3 points, got {len(p)}")
    rng = np.random.default_rng(seed)
    picks = np.stack([rng.choice(len(p), 3, replace=False) for _ in range(iterations)])
    a, b, c = p[picks[:, 0]], p[picks[:, 1]], p[picks[:, 2]]
    normal = np.cross(b - a, c - a)
    length = np.linalg.norm(normal, axis=1)
    ok = length > 1e-12  # three points in a line span no plane
    normal[ok] /= length[ok, None]
    offset = -np.einsum("ij,ij->i", normal, a)
    score = p if len(p) <= score_points else p[rng.choice(len(p), score_points, replace=False)]
    distance = score @ normal.T  # (points, samples), made absolute in place
    distance += offset
    count = np.count_nonzero(np.abs(distance, out=distance) <= threshold, axis=0)
    count[~ok] = -1
    best = int(np.argmax(count))
    inliers = p[np.abs(p @ normal[best] + offset[best]) <= threshold]
    centroid = inliers.mean(axis=0)
    n = np.linalg.svd(inliers - centroid, full_matrices=False)[2][-1]
    n = -n if n[2] < 0 else n  # upwards, as a table's
    model = np.append(n, -n @ centroid)
    return model, np.flatnonzero(np.abs(p @ n + model[3]) <= threshold)


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
    reach = row_norms(pts - arm.base_position) <= arm.length_max + 2 * arm.radius
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
        model, inl = dominant_plane(p, params.table_threshold)
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


def merge_segmentations(segs: list[Segmentation], voxel: float = 0.0) -> Segmentation:
    """The arm's points of several views of one wrap as one segmentation (pieces numbered
    on across the views). With `voxel`, one point a voxel of the union, the first view's
    first: each view is downsampled already, and where two views see the same surface their
    union holds twice the points, which adds no evidence a fit needs, only time."""
    offsets = np.cumsum([0] + [s.n_pieces for s in segs])[:-1]
    points = np.concatenate([s.points for s in segs])
    piece = np.concatenate([s.piece + o for s, o in zip(segs, offsets)])
    if voxel > 0:
        _, first = np.unique(np.floor(points / voxel).astype(np.int64), axis=0,
                             return_index=True)
        keep = np.sort(first)
        points, piece = points[keep], piece[keep]
    return Segmentation(points=points, piece=piece,
                        n_input=sum(s.n_input for s in segs),
                        n_colour=sum(s.n_colour for s in segs),
                        table_plane=segs[0].table_plane,
                        dropped_pieces=sum((s.dropped_pieces for s in segs), ()))
