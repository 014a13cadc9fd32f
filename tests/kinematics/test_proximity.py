"""The compiled proximity tests against second implementations: segment-triangle distances
against trimesh's closest points on a densely sampled segment, the hull planes' answers
with their memory against the same planes asked afresh in numpy, and the grid's triangle
answers against every triangle measured."""

from __future__ import annotations

import numpy as np
import trimesh

from drake_continuum.kinematics.proximity import (
    capsules_near_planes,
    capsules_near_triangles,
    segment_triangle_distance,
    triangle_grid,
)


def _random_triangle(rng):
    v = rng.normal(0.0, 0.02, (3, 3))
    if rng.random() < 0.1:  # a sliver, nearly a segment
        v[2] = v[0] + rng.uniform(0.0, 1.0) * (v[1] - v[0]) + rng.normal(0.0, 1e-7, 3)
    return v


def test_segment_triangle_distance_is_the_least_distance_of_the_segments_points():
    """Against trimesh's point-triangle closest points at 4,001 points of the segment: never
    above their least, and below it by at most the sampling's reach (half a sample spacing);
    0 where the segment crosses the triangle."""
    rng = np.random.default_rng(0)
    crossed = 0
    for _ in range(300):
        v = _random_triangle(rng)
        a, b = rng.normal(0.0, 0.03, 3), rng.normal(0.0, 0.03, 3)
        u = np.linspace(0.0, 1.0, 4001)[:, None]
        points = a + u * (b - a)
        closest = trimesh.triangles.closest_point(np.repeat(v[None], len(points), axis=0),
                                                  points)
        sampled = np.linalg.norm(points - closest, axis=1).min()
        mine = segment_triangle_distance(a, b, v)
        spacing = np.linalg.norm(b - a) / 4000
        assert mine <= sampled + 1e-12
        assert mine >= sampled - spacing / 2 - 1e-12
        crossed += mine == 0.0
    # and a segment through a triangle's face
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    assert segment_triangle_distance(np.array([0.2, 0.2, -1.0]), np.array([0.2, 0.2, 1.0]),
                                     v) == 0.0
    assert segment_triangle_distance(np.array([0.2, 0.2, 0.5]), np.array([0.3, 0.2, 2.0]),
                                     v) == 0.5


def _planes_afresh(position, tangent, first, half, reach, planes, box):
    a, b = position + half * tangent, position - half * tangent
    beyond = np.minimum(a @ planes[:, :3].T, b @ planes[:, :3].T) + planes[:, 3]
    boxed = ((np.minimum(a, b) - reach > box[1]) | (np.maximum(a, b) + reach < box[0]))
    near = ~(boxed.any(axis=1) | (beyond > reach).any(axis=1))
    near[:first] = False
    return near


def test_plane_memory_never_changes_an_answer():
    """Capsules wandering round a convex hull (steps of 0.2-5 mm, now and then a jump) get
    the answers of every plane asked afresh, with the memory skipping most scans."""
    rng = np.random.default_rng(1)
    hull = trimesh.creation.icosphere(subdivisions=2, radius=0.05).convex_hull
    planes = np.column_stack([hull.face_normals,
                              -np.einsum("fi,fi->f", hull.face_normals, hull.triangles[:, 0])])
    box = np.stack([hull.vertices.min(axis=0), hull.vertices.max(axis=0)])
    n, half, reach = 40, 0.01, 0.010001
    memory = (np.full(n, -1, np.int64), np.full((n, 6), np.nan), np.full(n, np.inf))
    position = rng.normal(0.0, 0.05, (n, 3))
    tangent = rng.normal(0.0, 1.0, (n, 3))
    answers = 0
    for step in range(400):
        position += rng.normal(0.0, rng.choice([0.0002, 0.001, 0.005]), (n, 3))
        if step % 50 == 0:
            position = rng.normal(0.0, 0.05, (n, 3))
        tangent += rng.normal(0.0, 0.05, (n, 3))
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        first = int(rng.integers(0, 10))
        near = capsules_near_planes(position, tangent, first, half, reach, planes, box, memory)
        expected = _planes_afresh(position, tangent, first, half, reach, planes, box)
        np.testing.assert_array_equal(near, expected)
        answers += expected[first:].sum()
    assert 0.05 < answers / (400 * 35) < 0.95  # both answers were given often


def test_grid_answers_are_every_triangles():
    """Capsules round a torus and a box (some touching, some grazing, some far) are near
    exactly where the least segment-triangle distance over all triangles is within reach;
    the triangle each remembers changes nothing."""
    rng = np.random.default_rng(2)
    mesh = trimesh.util.concatenate([
        trimesh.creation.torus(major_radius=0.05, minor_radius=0.02),
        trimesh.creation.box([0.04, 0.06, 0.02]).apply_translation([0.0, 0.0, 0.05])])
    # The layouts the scene passes (wrapping.apart: trimesh's read-only triangles, normals of
    # its own), so that no layout is compiled for this test alone; the reference reads a
    # writable copy, as the test above passes its triangle.
    triangles = np.ascontiguousarray(mesh.triangles)
    normals = np.array(mesh.face_normals)
    plain = np.array(triangles)
    boxes = np.concatenate([triangles.min(axis=1), triangles.max(axis=1)], axis=1)
    half, reach = 0.01, 0.010001
    cell = (half + reach) / 4
    corner = mesh.bounds[0] - 1e-9
    dims = np.floor((mesh.bounds[1] - corner) / cell).astype(np.int64) + 1
    start, members = triangle_grid(triangles, corner, cell, dims)
    grid = (corner, cell, dims, start, members, np.zeros(len(triangles) + 1, np.int64))
    n = 30
    hint = np.full(n, -1, np.int64)
    position = rng.uniform(mesh.bounds[0] - 0.02, mesh.bounds[1] + 0.02, (n, 3))
    counts = np.zeros(2, int)
    for _ in range(40):
        position += rng.normal(0.0, 0.003, (n, 3))
        tangent = rng.normal(0.0, 1.0, (n, 3))
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        asked = rng.random(n) < 0.8
        near = capsules_near_triangles(position, tangent, asked, half, reach,
                                       (triangles, normals, boxes), grid, hint)
        least = np.array([min(segment_triangle_distance(p + half * t, p - half * t, v)
                              for v in plain) for p, t in zip(position, tangent)])
        np.testing.assert_array_equal(near, asked & (least <= reach))
        counts += [(near).sum(), (asked & ~near & (least < 2 * reach)).sum()]
    assert counts.min() > 50  # touching capsules, and capsules that just miss
