"""Solid-modelling building blocks for the object generators.

Everything is a manifold3d `Manifold` until the end, so unions and differences stay closed
and 2-manifold; profiles are 2-D (r, z) polygons revolved about the z axis, and bent parts
(handles, spouts, bananas) are tubes swept along planar curves in the x-z plane.
"""

from __future__ import annotations

import numpy as np
import trimesh
from manifold3d import CrossSection, JoinType, Manifold, Mesh

__all__ = ["REVOLVE_SEGMENTS", "polygon_section", "revolve", "open_shell_section", "sweep",
           "circle_outline", "faceted_outline", "superellipse", "manifold_from_arrays",
           "manifold_to_trimesh", "smooth_step"]

REVOLVE_SEGMENTS = 64  # around the z axis: 5.6 degree facets, 0.2 mm sag on a 5 cm radius


def polygon_section(points_rz: np.ndarray) -> CrossSection:
    """A CrossSection from one simple polygon given in either winding."""
    pts = np.asarray(points_rz, dtype=float)
    x, y = pts[:, 0], pts[:, 1]
    if np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) < 0:
        pts = pts[::-1]
    return CrossSection([pts.tolist()])


def revolve(section: CrossSection, segments: int = REVOLVE_SEGMENTS) -> Manifold:
    """Revolve a section's x >= 0 half (x = radius, y = height) about the z axis."""
    return Manifold.revolve(section, circular_segments=segments)


def open_shell_section(outer_rz: np.ndarray, wall: float,
                       bottom: float) -> tuple[CrossSection, CrossSection]:
    """The (r, z) sections of an open vessel's filled outline and of its cavity.

    outer_rz: (n, 2) outer surface from the base edge (z = 0) up to the rim, radius > 0.
    The cavity is the solid offset inwards by `wall`, lifted so the floor is `bottom` thick,
    and extended past the rim so the vessel is open; the rim comes out flat. The wall is
    `outline - cavity`; keeping them apart lets handles be added before the cavity is carved
    (carving a shell's own inner surface again would leave coincident faces).
    """
    outer = np.asarray(outer_rz, dtype=float)
    rim_z = outer[-1, 1]
    tangent = outer[-1] - outer[-2]
    tangent /= np.linalg.norm(tangent)
    extension = outer[-1] + tangent * (3.0 * wall / max(tangent[1], 0.2))
    half = np.vstack([outer, extension])
    full = np.vstack([[[0.0, 0.0]], half, [[0.0, extension[1]]]])
    mirrored = full * [-1.0, 1.0]
    solid = polygon_section(np.vstack([full, mirrored[::-1][1:-1]]))
    cavity = solid.offset(-wall, JoinType.Round, circular_segments=24).simplify(2e-4)
    cavity = cavity.translate([0.0, bottom - wall])
    below_rim = CrossSection.square([4.0, rim_z]).translate([-2.0, 0.0])
    return (solid ^ below_rim).simplify(2e-4), cavity


def sweep(path: np.ndarray, half_widths: np.ndarray, section: np.ndarray,
          *, closed: bool = False) -> Manifold:
    """A tube along a planar curve in the x-z plane.

    path: (n, 3) centre line with y = 0. half_widths: (n, 2) semi-axes of the cross-section
    in the curve's plane and along y. section: (m, 2) unit cross-section outline (e.g. a
    circle or a rounded pentagon), counter-clockwise. Open tubes get flat end caps.
    """
    path = np.asarray(path, dtype=float)
    n, m = len(path), len(section)
    if closed:
        tangent = np.roll(path, -1, axis=0) - np.roll(path, 1, axis=0)
    else:
        tangent = np.gradient(path, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    binormal = np.array([0.0, 1.0, 0.0])
    normal = np.cross(binormal, tangent)
    a = half_widths[:, 0:1, None] * section[None, :, 0:1] * normal[:, None, :]
    b = half_widths[:, 1:2, None] * section[None, :, 1:2] * binormal[None, None, :]
    rings = path[:, None, :] + a + b
    verts = rings.reshape(-1, 3)
    i = np.arange(n if closed else n - 1)[:, None]
    j = np.arange(m)[None, :]
    v00 = i * m + j
    v01 = i * m + (j + 1) % m
    v10 = ((i + 1) % n) * m + j
    v11 = ((i + 1) % n) * m + (j + 1) % m
    faces = np.concatenate([np.stack([v00, v10, v11], -1).reshape(-1, 3),
                            np.stack([v00, v11, v01], -1).reshape(-1, 3)])
    if not closed:
        start, end = len(verts), len(verts) + 1
        verts = np.vstack([verts, path[0], path[-1]])
        ring0 = np.arange(m)
        ring1 = (n - 1) * m + np.arange(m)
        caps = [np.stack([np.full(m, start), ring0, np.roll(ring0, -1)], -1),
                np.stack([np.full(m, end), np.roll(ring1, -1), ring1], -1)]
        faces = np.vstack([faces] + caps)
    return manifold_from_arrays(verts, faces)


def circle_outline(m: int = 16) -> np.ndarray:
    """Unit circle with m points, counter-clockwise."""
    t = np.linspace(0.0, 2.0 * np.pi, m, endpoint=False)
    return np.column_stack([np.cos(t), np.sin(t)])


def faceted_outline(sides: int, facet: float, m: int = 20) -> np.ndarray:
    """A circle blended with a regular polygon: facet 0 is round, 1 a sharp polygon."""
    t = np.linspace(0.0, 2.0 * np.pi, m, endpoint=False)
    sector = 2.0 * np.pi / sides
    polygon_r = np.cos(np.pi / sides) / np.cos((t % sector) - sector / 2.0)
    r = (1.0 - facet) + facet * polygon_r / polygon_r.mean()
    return np.column_stack([r * np.cos(t), r * np.sin(t)])


def superellipse(a: float, b: float, exponent: float, *, n: int) -> np.ndarray:
    """(n, 2) points of |x/a|^e + |z/b|^e = 1; e = 2 is an ellipse, larger is boxier."""
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    c, s = np.cos(t), np.sin(t)
    p = 2.0 / exponent
    return np.column_stack([a * np.sign(c) * np.abs(c) ** p, b * np.sign(s) * np.abs(s) ** p])


def manifold_from_arrays(verts: np.ndarray, faces: np.ndarray) -> Manifold:
    """A Manifold from vertex and face arrays, turning the faces outward if they were inward."""
    verts = np.ascontiguousarray(verts, dtype=np.float32)
    faces = np.ascontiguousarray(faces, dtype=np.uint32)
    result = Manifold(Mesh(vert_properties=verts, tri_verts=faces))
    if result.volume() < 0 or result.is_empty():
        result = Manifold(Mesh(vert_properties=verts,
                               tri_verts=np.ascontiguousarray(faces[:, ::-1])))
    if result.is_empty():
        raise ValueError(f"swept solid is not a closed 2-manifold ({result.status()})")
    return result


def manifold_to_trimesh(solid: Manifold) -> trimesh.Trimesh:
    """A trimesh (float64 vertices, merged) of a Manifold's surface."""
    mesh = solid.to_mesh()
    verts = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    faces = np.asarray(mesh.tri_verts, dtype=np.int64)
    # process=False: a valid manifold may hold distinct vertices at one position (pinches);
    # merging them by position would make edges non-manifold.
    return trimesh.Trimesh(verts, faces, process=False)


def smooth_step(x: np.ndarray) -> np.ndarray:
    """0 below 0, 1 above 1, a C1 cosine blend between."""
    x = np.clip(x, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * x)
