"""Distances from points to an object's real surface, by Open3D's raycasting scene on its
triangles: exact for the non-convex surface, which Drake's own signed-distance query is not
(it sees a mesh through its convex hull, docs/contact.md). The wrap's IK and conformity ask
them through WrapScene; a check that needs no contact asks them here, without building the
Drake scene (~0.4 s of CPU)."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import trimesh

__all__ = ["SurfaceDistance"]


class SurfaceDistance:
    """Signed distances (m, negative inside) to one mesh's surface, posed in the world."""

    def __init__(self, mesh: trimesh.Trimesh):
        self._scene = o3d.t.geometry.RaycastingScene()
        self._scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices), o3d.core.float32),
                                  o3d.core.Tensor(np.asarray(mesh.faces), o3d.core.uint32))

    def signed_distance(self, points, table: bool = False) -> np.ndarray:
        """(k,) signed distance from points to the surface; with `table`, to the nearer of
        it and the table top (z = 0)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        d = self._scene.compute_signed_distance(
            o3d.core.Tensor(p.astype(np.float32))).numpy().astype(float)
        return np.minimum(d, p[:, 2]) if table else d

    def distance_field(self, points, table: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance and its gradient at points: (k,) and (k, 3); with `table`, to the
        nearer of the object and the table top (z = 0), so IK keeps the arm above both.

        One closest-point query (plus Open3D's cheap ray-parity inside test) gives both:
        the gradient of the signed distance is (p - closest) / d, the unit vector from the
        surface (outwards), or the face normal on the surface itself. It is as exact as
        `signed_distance` and 7 times cheaper than differencing it (IK needs gradients).
        """
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        pts = o3d.core.Tensor(p.astype(np.float32))
        closest = self._scene.compute_closest_points(pts)
        inside = self._scene.compute_occupancy(pts).numpy() > 0.5
        delta = p - closest["points"].numpy()
        unsigned = np.linalg.norm(delta, axis=1)
        d = np.where(inside, -unsigned, unsigned)
        on_surface = unsigned < 1e-7
        grad = delta / np.where(on_surface, 1.0, d)[:, None]
        grad[on_surface] = closest["primitive_normals"].numpy()[on_surface]
        if table:
            lower = p[:, 2] < d
            d = np.where(lower, p[:, 2], d)
            grad[lower] = (0.0, 0.0, 1.0)
        return d, grad

    def clearance(self, arm, config, n: int = 200) -> np.ndarray:
        """(n,) gap between the arm's surface at `config` and the object along the arm
        (negative: penetration), at n evenly spaced centre-line points."""
        return self.signed_distance(arm.backbone(config, n=n).position) - arm.radius
