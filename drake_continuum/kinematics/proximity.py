"""Compiled proximity tests that prove an arm's capsules apart from an object before a
contact query (`wrapping.apart`): against the face planes of the object's convex hull, and
against its triangles through a uniform grid. Each proves "apart" only where the arithmetic
shows it; any doubt (a NaN included) answers "near", and Drake's contact surfaces decide.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .jit import CACHE as _CACHE

__all__ = ["capsules_near_planes", "capsules_near_triangles", "planes_lower_bound",
           "segment_triangle_distance", "triangle_grid", "compile_kernels"]


@njit(cache=_CACHE)
def capsules_near_planes(position, tangent, first, half, reach, planes, box, memory):
    """Which capsules (axes of length 2 half along `tangent` about `position`) from `first`
    on no plane proves apart: (n,) True where capsule j >= first has both axis ends within
    `reach` of the inner side of every plane n.x + d <= 0 of `planes` (F, 4), and of the
    `box` (2, 3) faces. Only a plane both ends lie further than `reach` beyond separates.

    `memory` (face (n,), ends (n, 6), best (n,); -1, NaN and +inf before any scan), kept
    between calls, spares the scan of every plane: the plane that separated a capsule last
    is tried first, and a capsule that no plane separated (best separation `best` at ends
    `ends`) is not scanned again until its ends have moved further than reach - best (a
    plane's distance changes no faster than the point moves). A scan updates `memory`;
    nothing there changes an answer."""
    face, ends, best = memory
    n, F = position.shape[0], planes.shape[0]
    near = np.zeros(n, np.bool_)
    a, b = np.empty(3), np.empty(3)
    for j in range(max(first, 0), n):
        apart = False
        for r in range(3):
            a[r] = position[j, r] + half * tangent[j, r]
            b[r] = position[j, r] - half * tangent[j, r]
            if (min(a[r], b[r]) - reach > box[1, r]) or (max(a[r], b[r]) + reach < box[0, r]):
                apart = True
        if apart:
            continue
        f = face[j]
        if f >= 0 and _beyond(planes[f], a, b) > reach:
            continue
        moved = 0.0
        for e in range(2):
            m = 0.0
            for r in range(3):
                m += ((a[r] if e == 0 else b[r]) - ends[j, 3 * e + r]) ** 2
            moved = max(moved, np.sqrt(m))
        if best[j] + moved <= reach:  # (never while best is +inf: not scanned yet)
            near[j] = True
            continue
        top, arg = -np.inf, -1
        for f in range(F):
            d = _beyond(planes[f], a, b)
            if d > top:
                top, arg = d, f
        if top > reach:
            face[j] = arg
        else:
            near[j] = True
            best[j] = top
            ends[j, :3], ends[j, 3:] = a, b
    return near


@njit(cache=_CACHE)
def planes_lower_bound(points, planes, at_least, hint):
    """(k,) a lower bound on each point's signed distance to a solid that lies on the inner
    side of every plane n.x + d <= 0 of `planes` (F, 4; n unit): the largest n.x + d over the
    planes tried (outside, the distance to the solid is at least any plane's; inside, the
    surface is nearer than the planes). The plane `hint[j]` (-1: none) is tried first; where
    it gives less than `at_least[j]`, every plane is, and `hint[j]` keeps the best. `hint` is
    kept between calls and changes no bound a full scan gives, only the work."""
    k, F = points.shape[0], planes.shape[0]
    bound = np.empty(k)
    for j in range(k):
        x, y, z = points[j, 0], points[j, 1], points[j, 2]
        top = -np.inf
        f = hint[j]
        if f >= 0:
            top = planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z + planes[f, 3]
        if not top >= at_least[j]:
            for f in range(F):
                d = planes[f, 0] * x + planes[f, 1] * y + planes[f, 2] * z + planes[f, 3]
                if d > top:
                    top, hint[j] = d, f
        bound[j] = top
    return bound


@njit(cache=_CACHE)
def _beyond(plane, a, b) -> float:
    """How far the nearer of points a and b lies beyond `plane` (n.x + d, n unit)."""
    da = plane[0] * a[0] + plane[1] * a[1] + plane[2] * a[2] + plane[3]
    db = plane[0] * b[0] + plane[1] * b[1] + plane[2] * b[2] + plane[3]
    return min(da, db)


@njit(cache=_CACHE)
def triangle_grid(triangles, lo, cell, dims):
    """A uniform grid over triangles (T, 3, 3): cells of size `cell` from corner `lo`,
    `dims` (3,) cells an axis; returns (start (C + 1,), members) listing in members[start[c]:
    start[c + 1]] every triangle whose bounding box meets cell c (c = (i dims[1] + j) dims[2]
    + k)."""
    T = triangles.shape[0]
    first = np.empty((T, 3), np.int64)
    last = np.empty((T, 3), np.int64)
    count = np.zeros(dims[0] * dims[1] * dims[2] + 1, np.int64)
    for t in range(T):
        for r in range(3):
            a = min(triangles[t, 0, r], triangles[t, 1, r], triangles[t, 2, r])
            b = max(triangles[t, 0, r], triangles[t, 1, r], triangles[t, 2, r])
            first[t, r] = min(max(int((a - lo[r]) // cell), 0), dims[r] - 1)
            last[t, r] = min(max(int((b - lo[r]) // cell), 0), dims[r] - 1)
        for i in range(first[t, 0], last[t, 0] + 1):
            for j in range(first[t, 1], last[t, 1] + 1):
                for k in range(first[t, 2], last[t, 2] + 1):
                    count[(i * dims[1] + j) * dims[2] + k + 1] += 1
    start = np.cumsum(count)
    members = np.empty(start[-1], np.int64)
    fill = start[:-1].copy()
    for t in range(T):
        for i in range(first[t, 0], last[t, 0] + 1):
            for j in range(first[t, 1], last[t, 1] + 1):
                for k in range(first[t, 2], last[t, 2] + 1):
                    c = (i * dims[1] + j) * dims[2] + k
                    members[fill[c]] = t
                    fill[c] += 1
    return start, members


@njit(cache=_CACHE)
def capsules_near_triangles(position, tangent, asked, half, reach, mesh, grid, hint):
    """Which of the capsules `asked` (n,) (axes of length 2 half along `tangent` about
    `position`) come within `reach` of a triangle of `mesh` (triangles (T, 3, 3), unit
    normals (T, 3), bounding boxes (T, 6) as lo, hi), found through `grid` (corner (3,), cell
    size, dims (3,), start, members: triangle_grid's, and a (T + 1,) stamp array): (n,) True
    where one does. A triangle whose box or plane lies beyond reach is not measured. `hint`
    (n,) holds the triangle each capsule last came near (-1: none), tried first."""
    triangles, normals, boxes = mesh
    corner, cell, dims, start, members, stamp = grid
    n = position.shape[0]
    near = np.zeros(n, np.bool_)
    a, b, lo, hi = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    c0, c1 = np.empty(3, np.int64), np.empty(3, np.int64)
    for j in range(n):
        if not asked[j]:
            continue
        stamp[-1] += 1  # the last entry counts the capsules asked: a triangle's mark
        for r in range(3):
            a[r] = position[j, r] + half * tangent[j, r]
            b[r] = position[j, r] - half * tangent[j, r]
            lo[r], hi[r] = min(a[r], b[r]) - reach, max(a[r], b[r]) + reach
            c0[r] = min(max(int((lo[r] - corner[r]) // cell), 0), dims[r] - 1)
            c1[r] = min(max(int((hi[r] - corner[r]) // cell), 0), dims[r] - 1)
        t = hint[j]
        if t >= 0 and _triangle_within(a, b, t, reach, lo, hi, triangles, normals, boxes):
            near[j] = True
            continue
        for i in range(c0[0], c1[0] + 1):
            for jj in range(c0[1], c1[1] + 1):
                for k in range(c0[2], c1[2] + 1):
                    c = (i * dims[1] + jj) * dims[2] + k
                    for m in range(start[c], start[c + 1]):
                        t = members[m]
                        if stamp[t] == stamp[-1]:
                            continue
                        stamp[t] = stamp[-1]
                        if _triangle_within(a, b, t, reach, lo, hi, triangles, normals, boxes):
                            near[j] = True
                            hint[j] = t
                            break
                    if near[j]:
                        break
                if near[j]:
                    break
            if near[j]:
                break
    return near


@njit(cache=_CACHE)
def _triangle_within(a, b, t, reach, lo, hi, triangles, normals, boxes) -> bool:
    """Whether segment ab comes within `reach` of triangle t (lo, hi: ab's box grown by
    reach). True unless proven otherwise: a NaN never proves a triangle far."""
    for r in range(3):
        if boxes[t, r] > hi[r] or boxes[t, 3 + r] < lo[r]:
            return False
    v0 = (triangles[t, 0, 0], triangles[t, 0, 1], triangles[t, 0, 2])
    n = (normals[t, 0], normals[t, 1], normals[t, 2])
    pa, pb = (a[0], a[1], a[2]), (b[0], b[1], b[2])
    da, db = _dot(n, _sub(pa, v0)), _dot(n, _sub(pb, v0))
    if (da > reach and db > reach) or (da < -reach and db < -reach):
        return False
    v1 = (triangles[t, 1, 0], triangles[t, 1, 1], triangles[t, 1, 2])
    v2 = (triangles[t, 2, 0], triangles[t, 2, 1], triangles[t, 2, 2])
    return not (_segment_triangle(pa, pb, v0, v1, v2) > reach * reach)


@njit(cache=_CACHE)
def segment_triangle_distance(a, b, v):
    """Distance between segment ab (3,) each and triangle v (3, 3)."""
    return np.sqrt(_segment_triangle((a[0], a[1], a[2]), (b[0], b[1], b[2]),
                                     (v[0, 0], v[0, 1], v[0, 2]), (v[1, 0], v[1, 1], v[1, 2]),
                                     (v[2, 0], v[2, 1], v[2, 2])))


@njit(cache=_CACHE)
def _segment_triangle(a, b, v0, v1, v2):
    """Squared distance between segment ab and triangle v0 v1 v2 (3-tuples): 0 where the
    segment crosses the triangle, else the least of its ends' distances to the triangle and
    its distances to the triangle's edges (where the nearest points of a segment and a
    triangle lie)."""
    nrm = _cross(_sub(v1, v0), _sub(v2, v0))
    da, db = _dot(nrm, _sub(a, v0)), _dot(nrm, _sub(b, v0))
    if (da <= 0.0 <= db or db <= 0.0 <= da) and da != db:
        x = _add(a, _scale(_sub(b, a), da / (da - db)))
        if (_dot(nrm, _cross(_sub(v1, v0), _sub(x, v0))) >= 0.0
                and _dot(nrm, _cross(_sub(v2, v1), _sub(x, v1))) >= 0.0
                and _dot(nrm, _cross(_sub(v0, v2), _sub(x, v2))) >= 0.0):
            return 0.0
    d = min(_point_triangle(a, v0, v1, v2), _point_triangle(b, v0, v1, v2))
    d = min(d, _segments(a, b, v0, v1))
    d = min(d, _segments(a, b, v1, v2))
    return min(d, _segments(a, b, v2, v0))


@njit(cache=_CACHE)
def _point_triangle(p, a, b, c):
    """Squared distance from p to triangle abc, by the Voronoi regions of its corners,
    edges and face (Ericson, Real-Time Collision Detection, 5.1.5)."""
    ab, ac, ap = _sub(b, a), _sub(c, a), _sub(p, a)
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return _dot(ap, ap)
    bp = _sub(p, b)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return _dot(bp, bp)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        return _gap(p, _add(a, _scale(ab, d1 / (d1 - d3))))
    cp = _sub(p, c)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return _dot(cp, cp)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        return _gap(p, _add(a, _scale(ac, d2 / (d2 - d6))))
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 - d3 >= 0.0 and d5 - d6 >= 0.0:
        return _gap(p, _add(b, _scale(_sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6)))))
    denom = 1.0 / (va + vb + vc)
    return _gap(p, _add(a, _add(_scale(ab, vb * denom), _scale(ac, vc * denom))))


@njit(cache=_CACHE)
def _segments(p1, q1, p2, q2):
    """Squared distance between segments p1q1 and p2q2 (Ericson 5.1.9: the nearest points'
    parameters clamped in turn)."""
    d1, d2, r = _sub(q1, p1), _sub(q2, p2), _sub(p1, p2)
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    if a <= 1e-30 and e <= 1e-30:
        return _dot(r, r)
    if a <= 1e-30:
        s, t = 0.0, min(max(f / e, 0.0), 1.0)
    else:
        c = _dot(d1, r)
        if e <= 1e-30:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
        else:
            bb = _dot(d1, d2)
            denom = a * e - bb * bb
            s = min(max((bb * f - c * e) / denom, 0.0), 1.0) if denom > 0.0 else 0.0
            t = (bb * s + f) / e
            if t < 0.0:
                s, t = min(max(-c / a, 0.0), 1.0), 0.0
            elif t > 1.0:
                s, t = min(max((bb - c) / a, 0.0), 1.0), 1.0
    return _gap(_add(p1, _scale(d1, s)), _add(p2, _scale(d2, t)))


# 3-vectors as tuples: values on the stack, where arrays would be allocated at every step.
@njit(cache=_CACHE)
def _sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(cache=_CACHE)
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(cache=_CACHE)
def _scale(a, k):
    return (a[0] * k, a[1] * k, a[2] * k)


@njit(cache=_CACHE)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=_CACHE)
def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=_CACHE)
def _gap(a, b):
    """Squared distance between points a and b."""
    d = _sub(a, b)
    return _dot(d, d)


def compile_kernels() -> None:
    """Compile every kernel here (or load it from the disk cache); compiled.compile_kernels
    calls it."""
    position, tangent = np.zeros((2, 3)), np.array([[0.0, 0.0, 1.0]] * 2)
    memory = (np.full(2, -1), np.full((2, 6), np.nan), np.full(2, np.inf))
    box = np.array([[-1.0] * 3, [1.0] * 3])
    capsules_near_planes(position, tangent, 0, 0.01, 0.02, np.array([[0.0, 0.0, 1.0, -1.0]]),
                         box, memory)
    planes_lower_bound(position, np.array([[0.0, 0.0, 1.0, -1.0]]), np.zeros(2),
                       np.full(2, -1, np.int64))
    triangles = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    dims = np.array([2, 2, 2])
    fixed = triangles.copy()
    fixed.flags.writeable = False  # trimesh's mesh.triangles, as wrapping.apart passes them
    for tris in (triangles, fixed):
        start, members = triangle_grid(tris, box[0], 1.0, dims)
        mesh = (tris, np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 0.0, 1.0, 1.0, 0.0]]))
        capsules_near_triangles(position, tangent, np.ones(2, np.bool_), 0.01, 0.02, mesh,
                                (box[0], 1.0, dims, start, members, np.zeros(2, np.int64)),
                                np.full(2, -1))
