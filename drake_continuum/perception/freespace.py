"""Free space as evidence: a camera that measured a point saw through everything before it.

A depth camera at eye e that measured a surface point p saw nothing on the segment from e to
p: an arm fitted across that segment would have hidden p, however well it explains the arm's
own points. The fit charges every such ray that passes through the fitted tube's core (the
tube less CORE_SLACK, for the fit's own error and flying pixels at the arm's silhouette), so
that the parts of the arm no point shows go where no camera could see: behind the object,
under the table, out of the frame.

Rays come from every view's cloud (each with its camera's eye): the non-arm points, binned by
direction from the eye (RAY_BIN rad, keeping the nearest point of a bin: what the camera saw
through up to there), each ray stopping MARGIN short of its point (depth noise, and the
tube flattened where it presses on the object).

FreeSpaceTerm is the smooth term the fit minimises: per ray, the core radius less the ray's
distance from the backbone, with the nearest arc length held fixed inside the Jacobian as for
the arm's points. `violations` is the exact check that does not share its geometry: the
core's triangle mesh ray cast along every ray (Open3D RaycastingScene), counting those that
hit it before their point.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import open3d as o3d
from scipy.spatial import cKDTree

from ..kinematics.arm import ArmConfig, ContinuumArm
from .cloud import row_norms

__all__ = ["RAY_BIN", "MARGIN", "CORE_SLACK", "ARM_CLEARANCE", "FreeRays", "free_rays",
           "merge_rays", "FreeSpaceTerm", "violations"]

RAY_BIN = 0.004  # rad: about two Kinect pixels, the density of the arm's own fitted points
MARGIN = 0.006  # m: a ray stops this short of its point
CORE_SLACK = 0.003  # m: a ray may pass this far inside the tube's surface unremarked
ARM_CLEARANCE = 0.006  # m: points this close to an arm point are the arm's, not free rays


@dataclass(frozen=True)
class FreeRays:
    """Rays along which the cameras saw nothing (their world-frame segments).

    Args:
        eyes: (V, 3) eye of each view, m.
        view: (M,) the view of each ray.
        direction: (M, 3) unit directions from the eye.
        length: (M,) free length of each ray, m (to its point less MARGIN).
    """

    eyes: np.ndarray
    view: np.ndarray
    direction: np.ndarray
    length: np.ndarray

    def __len__(self) -> int:
        return len(self.length)

    @property
    def origin(self) -> np.ndarray:
        return self.eyes[self.view]


def free_rays(points, eye, *, arm_points=None, ray_bin: float = RAY_BIN,
              margin: float = MARGIN) -> FreeRays:
    """The free rays of one view: its cloud's points seen from `eye`, less the arm's own."""
    points = np.asarray(points, float)
    eye = np.asarray(eye, float).reshape(3)
    if arm_points is not None and len(arm_points):
        # Only points in the arm's box grown by ARM_CLEARANCE can lie that near it: the
        # tree is asked about those alone (a few thousand of a cloud's 10^5).
        arm_points = np.asarray(arm_points, float)
        lo = arm_points.min(axis=0) - ARM_CLEARANCE
        hi = arm_points.max(axis=0) + ARM_CLEARANCE
        box = (points[:, 0] >= lo[0]) & (points[:, 0] <= hi[0]) & (points[:, 1] >= lo[1]) \
            & (points[:, 1] <= hi[1]) & (points[:, 2] >= lo[2]) & (points[:, 2] <= hi[2])
        near_arm = np.zeros(len(points), bool)
        near_arm[box] = np.isfinite(cKDTree(arm_points).query(
            points[box], distance_upper_bound=ARM_CLEARANCE)[0])
        points = points[~near_arm]
    d = points - eye
    dist = row_norms(d)
    keep = dist > margin
    if keep.all():
        d = d / dist[:, None]
    else:
        d, dist = d[keep] / dist[keep, None], dist[keep]
    # Bin directions on a cube of cells RAY_BIN wide and keep each bin's nearest point.
    key = np.floor(d / ray_bin).astype(np.int64) + (1 << 20)
    key = (key[:, 0] << 42) | (key[:, 1] << 21) | key[:, 2]
    pick = _nearest_of_each(key, dist)
    return FreeRays(eyes=eye[None], view=np.zeros(len(pick), np.int64), direction=d[pick],
                    length=dist[pick] - margin)


def _nearest_of_each(key, dist) -> np.ndarray:
    """Indices of the nearest point (least `dist`, the first of equals) of each `key`, in
    the keys' order: np.lexsort((dist, key)) cut to each key's first, from one stable sort
    of the keys alone (a sixth of the lexsort's cost: a depth image's keys come in runs)."""
    if len(key) == 0:
        return np.zeros(0, np.int64)
    order = np.argsort(key, kind="stable")
    key, dist = key[order], dist[order]
    new = np.ones(len(key), bool)
    new[1:] = key[1:] != key[:-1]
    group = np.cumsum(new) - 1
    at_min = np.flatnonzero(dist == np.minimum.reduceat(dist, np.flatnonzero(new))[group])
    first = np.ones(len(at_min), bool)
    first[1:] = group[at_min][1:] != group[at_min][:-1]
    return order[at_min[first]]


def merge_rays(rays: list[FreeRays]) -> FreeRays:
    """The rays of several views as one set."""
    offsets = np.cumsum([0] + [len(r.eyes) for r in rays])[:-1]
    return FreeRays(eyes=np.concatenate([r.eyes for r in rays]),
                    view=np.concatenate([r.view + o for r, o in zip(rays, offsets)]),
                    direction=np.concatenate([r.direction for r in rays]),
                    length=np.concatenate([r.length for r in rays]))


class FreeSpaceTerm:
    """Which rays pass through the tube's core at a configuration, and by how much.

    A ray's residual is the core radius less its distance from the backbone, for the rays
    closer than that (zero otherwise). The rays near a backbone sample are found by direction
    (one tree of ray directions a view): a ray passes within r of a point q only if its
    direction lies within about r / |q - e| of q's direction from the eye.
    """

    def __init__(self, arm: ContinuumArm, rays: FreeRays, *, slots: int = 256,
                 core_slack: float = CORE_SLACK):
        self.arm, self.rays, self.slots = arm, rays, slots
        self.core = arm.radius - core_slack
        self.origin = rays.origin
        self.trees = [cKDTree(rays.direction[rays.view == v]) for v in range(len(rays.eyes))]
        self.index = [np.flatnonzero(rays.view == v) for v in range(len(rays.eyes))]

    def distances(self, position, arc_length, tangent):
        """(ray indices, their distance from the backbone, nearest arc length) of the rays
        passing within the core radius of the backbone samples given."""
        step = float(np.max(np.diff(arc_length))) if len(arc_length) > 1 else 0.0
        reach = self.core + step / 2
        pairs_ray, pairs_sample = [], []
        for v, tree in enumerate(self.trees):
            if tree.n == 0:
                continue
            to = position - self.rays.eyes[v]
            dist = np.linalg.norm(to, axis=1)
            hits = tree.query_ball_point(to / dist[:, None], reach / np.maximum(dist, 1e-6)
                                         * 1.01)
            counts = np.fromiter(map(len, hits), np.int64, len(hits))
            if counts.sum() == 0:
                continue
            pairs_ray.append(self.index[v][np.concatenate(
                [np.asarray(h, np.int64) for h in hits if h])])
            pairs_sample.append(np.repeat(np.arange(len(hits)), counts))
        if not pairs_ray:
            return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
        ray = np.concatenate(pairs_ray)
        smp = np.concatenate(pairs_sample)
        gap, t = self._segment_gap(ray, position[smp])
        close = gap < self.core
        ray, smp, gap = ray[close], smp[close], gap[close]
        # Each ray's nearest sample, its arc length moved along the tangent to the ray.
        order = np.lexsort((gap, ray))
        first = np.ones(len(order), bool)
        first[1:] = ray[order][1:] != ray[order][:-1]
        pick = order[first]
        if len(pick) > self.slots:  # the deepest rays; the rest wait for the next iterate
            pick = pick[np.argsort(gap[pick])[:self.slots]]
        ray, smp, gap = ray[pick], smp[pick], gap[pick]
        foot = self.origin[ray] + self._t(ray, position[smp])[:, None] * \
            self.rays.direction[ray]
        sigma = arc_length[smp] + np.einsum("mi,mi->m", foot - position[smp], tangent[smp])
        sigma = np.clip(sigma, arc_length[0], arc_length[-1])
        return ray, gap, sigma

    def count(self, backbone) -> int:
        """Rays through the tube's core along backbone samples (arm.backbone)."""
        return len(self.distances(backbone.position, backbone.arc_length, backbone.tangent)[0])

    def _t(self, ray, q):
        along = np.sum((q - self.origin[ray]) * self.rays.direction[ray], axis=-1)
        return np.clip(along, 0.0, self.rays.length[ray])

    def _segment_gap(self, ray, q):
        """Distance of q (m, 3), or a batch of them (K, m, 3), from ray segment `ray` (m,)."""
        t = self._t(ray, q)
        foot = self.origin[ray] + t[..., None] * self.rays.direction[ray]
        return np.linalg.norm(q - foot, axis=-1), t

    def residuals(self, position, ray) -> np.ndarray:
        """(slots,) the core radius less each given ray's distance from the backbone point
        `position` (one a ray; a batch (K, rays, 3) gives (K, slots)), zero-padded: which
        rays fill the slots changes from iterate to iterate, which the cost (a sum over
        entries) does not see."""
        position = np.asarray(position, float)
        out = np.zeros(position.shape[:-2] + (self.slots,))
        if len(ray):
            r = self.core - self._segment_gap(ray, position)[0]
            out[..., :r.shape[-1]] = r
        return out


def violations(arm: ContinuumArm, config: ArmConfig, rays: FreeRays,
               *, core_slack: float = CORE_SLACK) -> np.ndarray:
    """(M,) mask of the rays that pass through the tube's core at `config` before reaching
    their point: ray casting the core's triangle mesh (Open3D RaycastingScene)."""
    from .depth_camera import raycast_mesh, tube_mesh

    core = replace(arm, radius=arm.radius - core_slack)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(raycast_mesh(tube_mesh(core, config, spacing=0.003, n_around=16)))
    r = np.concatenate([rays.origin, rays.direction], axis=1).astype(np.float32)
    t = scene.cast_rays(o3d.core.Tensor(r))["t_hit"].numpy()
    inside = scene.compute_occupancy(o3d.core.Tensor(rays.origin.astype(np.float32))).numpy()
    return (t < rays.length) | (inside > 0)
