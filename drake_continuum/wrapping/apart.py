"""Which capsules a contact query can leave out: those proven apart from the object before
Drake is asked (`WrapScene`'s queries).

A capsule's hydroelastic mesh lies within the exact capsule, and its contact surface with
the rigid object is the part of the object's triangles inside it: a capsule whose axis stays
further than its radius from every triangle has no contact surface. Two compiled tests prove
that (`kinematics.proximity`): the face planes of the object's convex hull (~0.1 us a
capsule a plane separated before: most capsules, far from the object), then the triangles
near the capsule through a uniform grid (exact segment-triangle distances, a few us a
capsule). Drake's contact surfaces cost ~0.07 ms for each capsule asked that touches
nothing and ~0.13 ms for one that touches (BENCHMARKS.md, Wrapping); they decide every
capsule the tests leave.
"""

from __future__ import annotations

import numpy as np
import trimesh

from ..kinematics.proximity import capsules_near_planes, capsules_near_triangles, triangle_grid
from .distance import hull_planes

__all__ = ["APART_MARGIN", "ApartTest"]

# m: a capsule must clear a plane or a triangle by this beyond its radius. Drake reads the
# object from an OBJ written to 8 decimals (5e-9 m of rounding) and poses a capsule from a
# quaternion; the margin covers both many times over.
APART_MARGIN = 1e-6


class ApartTest:
    """One object's convex hull planes and triangle grid (posed in the world), and the
    planes that last separated each capsule.

    Args:
        mesh: the object's triangle mesh, posed in the world.
        n_links: capsules of the arm.
        reach: how far from a capsule's axis it can touch (its radius), m.
        half: half the length of a capsule's axis, m.
    """

    def __init__(self, mesh: trimesh.Trimesh, n_links: int, *, reach: float, half: float):
        self.reach, self.half = reach + APART_MARGIN, half
        self.planes = hull_planes(mesh)  # a vertex beyond by ~1e-15 m, far within APART_MARGIN
        v = np.asarray(mesh.vertices, dtype=float)
        self.box = np.stack([v.min(axis=0), v.max(axis=0)])
        self._memory = (np.full(n_links, -1, np.int64), np.full((n_links, 6), np.nan),
                        np.full(n_links, np.inf))  # (+inf: no capsule scanned yet)
        self._hint = np.full(n_links, -1, np.int64)  # the triangle each capsule last neared
        self._mesh, self._grid = _triangle_mesh(mesh), self._triangle_grid(mesh)

    def _triangle_grid(self, mesh: trimesh.Trimesh) -> tuple:
        """Cells of a quarter of (half + reach): a capsule's box grown by its reach meets at
        most 10 a side, and few triangles outside it."""
        triangles = np.ascontiguousarray(mesh.triangles, dtype=float)
        cell = (self.half + self.reach) / 4
        corner = self.box[0] - 1e-9
        dims = np.maximum(np.floor((self.box[1] - corner) / cell).astype(np.int64) + 1, 1)
        start, members = triangle_grid(triangles, corner, cell, dims)
        return corner, cell, dims, start, members, np.zeros(len(triangles) + 1, np.int64)

    def near(self, position, tangent, first: int) -> np.ndarray:
        """(n,) True where capsule j >= first (its axis along `tangent` about `position`,
        (n, 3) each) is not proven apart from the object."""
        near = capsules_near_planes(position, tangent, int(first), self.half, self.reach,
                                    self.planes, self.box, self._memory)
        if not near.any():
            return near
        return capsules_near_triangles(position, tangent, near, self.half, self.reach,
                                       self._mesh, self._grid, self._hint)


def _triangle_mesh(mesh: trimesh.Trimesh) -> tuple:
    """(triangles (T, 3, 3), unit normals (T, 3), boxes (T, 6) as lo, hi); a degenerate
    triangle's normal is 0, so its plane proves nothing."""
    triangles = np.ascontiguousarray(mesh.triangles, dtype=float)
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(cross, axis=1, keepdims=True)
    normals = np.divide(cross, length, out=np.zeros_like(cross), where=length > 0)
    boxes = np.concatenate([triangles.min(axis=1), triangles.max(axis=1)], axis=1)
    return triangles, np.ascontiguousarray(normals), np.ascontiguousarray(boxes)
