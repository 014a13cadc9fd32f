"""Compiled constant-curvature kinematics (numba): centre-line samples and batched points.

A wrap asks for centre-line points a few thousand times (posing the capsules, bounding the
next contact, IK's finite differences), each time for a few dozen points. Written in numpy,
each call costs ~0.2 ms of per-operation overhead, most of it not arithmetic; compiled, a
call costs microseconds. The formulas are arm.py's (`arc_transforms`), which tests hold
these to. Compiled functions are cached on disk (numba's `cache=True`), so only the first
process after an install pays the ~10 s of compilation. Where numba finds no folder it can
write the cache in (a read-only install run by a user without a writable home folder), a
folder of the user's own under the temporary folder holds it, else nothing is cached.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from . import jit, proximity
from .jit import CACHE as _CACHE

__all__ = ["backbone_samples", "batch_points", "capsule_frames", "far_segments_within",
           "quaternions_wxyz", "tube_distances", "compile_kernels"]


def _sinc(y):
    """sin(y) / y, exact to rounding near 0."""
    if abs(y) < 1e-4:
        return 1.0 - y * y / 6.0
    return np.sin(y) / y


_sinc = njit(cache=_CACHE)(_sinc)  # jit decided once, at import; the other kernels follow
_cached = jit.cached  # (where the cache's decision was taken before it had its module)


@njit(cache=_CACHE)
def _radial_along(u, kappa):
    """A point u along an arc of curvature kappa, in its base frame: (towards the bend,
    along the start tangent) = ((1 - cos x) / kappa, sin x / kappa), x = kappa u."""
    x = kappa * u
    h = _sinc(0.5 * x)
    return u * 0.5 * x * h * h, u * _sinc(x)


@njit(cache=_CACHE)
def _arc(s, kappa, phi):
    """End pose of one arc in its base frame: (R (3, 3), p (3,)); R = Rz(phi) Ry(x) Rz(-phi)."""
    x = kappa * s
    radial, along = _radial_along(s, kappa)
    c, sn = np.cos(phi), np.sin(phi)
    cx, sx = np.cos(x), np.sin(x)
    R = np.empty((3, 3))
    R[0, 0] = c * c * cx + sn * sn
    R[0, 1] = c * sn * (cx - 1.0)
    R[0, 2] = c * sx
    R[1, 0] = R[0, 1]
    R[1, 1] = sn * sn * cx + c * c
    R[1, 2] = sn * sx
    R[2, 0] = -c * sx
    R[2, 1] = -sn * sx
    R[2, 2] = cx
    p = np.empty(3)
    p[0] = radial * c
    p[1] = radial * sn
    p[2] = along
    return R, p


@njit(cache=_CACHE)
def _sections(R_base, p_base, s, kappa, phi):
    """World poses of the base and every section end: R (n+1, 3, 3), p (n+1, 3)."""
    n = s.shape[0]
    R = np.empty((n + 1, 3, 3))
    p = np.empty((n + 1, 3))
    R[0] = R_base
    p[0] = p_base
    for i in range(n):
        Rl, pl = _arc(s[i], kappa[i], phi[i])
        p[i + 1] = p[i] + R[i] @ pl
        R[i + 1] = R[i] @ Rl
    return R, p


@njit(cache=_CACHE)
def backbone_samples(R_base, p_base, s, kappa, phi, arc):
    """Centre-line samples of one configuration at arc lengths `arc` (within [0, sum s]).

    Returns section (m,), position, tangent, normal, binormal (m, 3): a sample's frame is
    M Ry(kappa u), M = (section base) Rz(phi), u its arc length within the section.
    """
    n, m = s.shape[0], arc.shape[0]
    R0, p0 = _sections(R_base, p_base, s, kappa, phi)
    sec = np.empty(m, np.int64)
    pos, tan = np.empty((m, 3)), np.empty((m, 3))
    nor, binor = np.empty((m, 3)), np.empty((m, 3))
    for k in range(m):
        j, start = 0, 0.0
        while j < n - 1 and arc[k] >= start + s[j]:
            start += s[j]
            j += 1
        u = min(max(arc[k] - start, 0.0), s[j])
        c, sn = np.cos(phi[j]), np.sin(phi[j])
        x = kappa[j] * u
        radial, along = _radial_along(u, kappa[j])
        cx, sx = np.cos(x), np.sin(x)
        for r in range(3):
            mx = c * R0[j, r, 0] + sn * R0[j, r, 1]
            my = -sn * R0[j, r, 0] + c * R0[j, r, 1]
            mz = R0[j, r, 2]
            pos[k, r] = p0[j, r] + radial * mx + along * mz
            tan[k, r] = sx * mx + cx * mz
            nor[k, r] = cx * mx - sx * mz
            binor[k, r] = my
        sec[k] = j
    return sec, pos, tan, nor, binor


@njit(cache=_CACHE)
def batch_points(R_base, p_base, s, kappa, phi, fractions):
    """Section ends (B, n, 3) and centre-line points (B, n * F, 3) of B configurations, the
    points at `fractions` (F,) of each section's length, section by section."""
    B, n = s.shape
    F = fractions.shape[0]
    ends = np.empty((B, n, 3))
    points = np.empty((B, n * F, 3))
    R = np.empty((3, 3))
    R_next = np.empty((3, 3))
    p = np.empty(3)
    for b in range(B):
        R[:, :] = R_base
        p[:] = p_base
        for i in range(n):
            c, sn = np.cos(phi[b, i]), np.sin(phi[b, i])
            for f in range(F):  # in the section's base frame: radial (c, sn, 0), along z
                radial, along = _radial_along(s[b, i] * fractions[f], kappa[b, i])
                for r in range(3):
                    points[b, i * F + f, r] = p[r] + radial * (c * R[r, 0] + sn * R[r, 1]) \
                        + along * R[r, 2]
            Rl, pl = _arc(s[b, i], kappa[b, i], phi[b, i])
            for r in range(3):
                p[r] += R[r, 0] * pl[0] + R[r, 1] * pl[1] + R[r, 2] * pl[2]
                for col in range(3):
                    R_next[r, col] = R[r, 0] * Rl[0, col] + R[r, 1] * Rl[1, col] \
                        + R[r, 2] * Rl[2, col]
            R[:, :] = R_next
            ends[b, i] = p
    return ends, points


@njit(cache=_CACHE)
def quaternions_wxyz(R):
    """Unit quaternions (w, x, y, z) of rotation matrices (m, 3, 3), Shepperd's method
    (the largest of the four squared components first, so exact at 180 deg too).

    scipy's `Rotation.from_matrix(R).as_quat(scalar_first=True)` gives the same rotations
    (tests) but costs ~700 us for a pose's 40 matrices against ~2 us here (scipy 1.17).
    """
    m = R.shape[0]
    q = np.empty((m, 4))
    for k in range(m):
        a = R[k]
        t = a[0, 0] + a[1, 1] + a[2, 2]
        if t >= a[0, 0] and t >= a[1, 1] and t >= a[2, 2]:
            r = np.sqrt(1.0 + t)
            w, x, y, z = 0.5 * r, (a[2, 1] - a[1, 2]) / (2 * r), \
                (a[0, 2] - a[2, 0]) / (2 * r), (a[1, 0] - a[0, 1]) / (2 * r)
        elif a[0, 0] >= a[1, 1] and a[0, 0] >= a[2, 2]:
            r = np.sqrt(1.0 + a[0, 0] - a[1, 1] - a[2, 2])
            w, x, y, z = (a[2, 1] - a[1, 2]) / (2 * r), 0.5 * r, \
                (a[0, 1] + a[1, 0]) / (2 * r), (a[0, 2] + a[2, 0]) / (2 * r)
        elif a[1, 1] >= a[2, 2]:
            r = np.sqrt(1.0 - a[0, 0] + a[1, 1] - a[2, 2])
            w, x, y, z = (a[0, 2] - a[2, 0]) / (2 * r), (a[0, 1] + a[1, 0]) / (2 * r), \
                0.5 * r, (a[1, 2] + a[2, 1]) / (2 * r)
        else:
            r = np.sqrt(1.0 - a[0, 0] - a[1, 1] + a[2, 2])
            w, x, y, z = (a[1, 0] - a[0, 1]) / (2 * r), (a[0, 2] + a[2, 0]) / (2 * r), \
                (a[1, 2] + a[2, 1]) / (2 * r), 0.5 * r
        norm = np.sqrt(w * w + x * x + y * y + z * z)
        q[k, 0], q[k, 1], q[k, 2], q[k, 3] = w / norm, x / norm, y / norm, z / norm
    return q


@njit(cache=_CACHE)
def capsule_frames(R_base, p_base, s, kappa, phi, spread, half):
    """The capsules of one configuration, k = len(spread) a section, each of half-length
    `half`, its centre at `spread` (0 to 1) of the section's length between its first and
    last centres: arc (n k,), backbone_samples at those arcs (section, position, tangent,
    normal, binormal) and poses (n k, 7) as free bodies' positions [qw, qx, qy, qz, x, y, z]
    (axis along the tangent). The arithmetic is numpy's of scene.capsule_poses in one call:
    posing is asked at every contact query."""
    n, k = s.shape[0], spread.shape[0]
    arc = np.empty(n * k)
    start = 0.0
    for i in range(n):  # each section's start, summed in order as numpy's cumsum
        for j in range(k):
            arc[i * k + j] = start + half + spread[j] * (s[i] - 2 * half)
        start += s[i]
    sec, pos, tan, nor, binor = backbone_samples(R_base, p_base, s, kappa, phi, arc)
    R = np.empty((n * k, 3, 3))
    R[:, :, 0], R[:, :, 1], R[:, :, 2] = nor, binor, tan
    poses = np.empty((n * k, 7))
    poses[:, :4] = quaternions_wxyz(R)
    poses[:, 4:] = pos
    return arc, sec, pos, tan, nor, binor, poses


@njit(cache=_CACHE)
def _segment_distance(p, u, q, v, half):
    """Distance between segments p + a u and q + b v (u, v unit, |a|, |b| <= half): the
    closest points' parameters in closed form, clamped, then each re-solved against the
    other's clamped point."""
    w0, w1, w2 = p[0] - q[0], p[1] - q[1], p[2] - q[2]
    uv = u[0] * v[0] + u[1] * v[1] + u[2] * v[2]
    uw = u[0] * w0 + u[1] * w1 + u[2] * w2
    vw = v[0] * w0 + v[1] * w1 + v[2] * w2
    denom = 1.0 - uv * uv
    a = 0.0 if denom < 1e-12 else (uv * vw - uw) / denom
    a = min(max(a, -half), half)
    b = min(max(vw + a * uv, -half), half)
    a = min(max(b * uv - uw, -half), half)
    d0 = w0 + a * u[0] - b * v[0]
    d1 = w1 + a * u[1] - b * v[1]
    d2 = w2 + a * u[2] - b * v[2]
    return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(cache=_CACHE)
def far_segments_within(position, tangent, arc, first, half, far, cutoff):
    """Whether the axes of two capsules (segments of length 2 half along `tangent` about
    `position`) at least `far` apart in `arc`, one of them from `first` on, come within
    `cutoff` of each other. Pairs whose centres lie further apart than 2 half + cutoff on
    some axis cannot, and are not measured."""
    n = position.shape[0]
    reach = 2.0 * half + cutoff
    for i in range(max(first, 0), n):
        for j in range(n):
            if j >= i and j >= first:  # a pair of capsules both from `first` on: once
                continue
            if abs(arc[i] - arc[j]) < far:
                continue
            if (abs(position[i, 0] - position[j, 0]) > reach
                    or abs(position[i, 1] - position[j, 1]) > reach
                    or abs(position[i, 2] - position[j, 2]) > reach):
                continue
            if _segment_distance(position[i], tangent[i], position[j], tangent[j],
                                 half) < cutoff:
                return True
    return False


@njit(cache=_CACHE)
def tube_distances(R_base, p_base, s, kappa, phi, sigma, points, radius, capped):
    """Signed distance (K, M) of points (M, 3) from the tube of `radius` about the centre
    lines of K configurations (K, n), each point measured at its own arc length sigma
    (K, M), clipped to its section as backbone_samples does. A point where `capped` (K, M) is
    +1 (at the tip) ahead of the tangent there, or -1 (at the base) behind it, lies beyond a
    flat end cap: its distance is to the cap's disc. The residual of a point fitted to the
    arm's tube, without the (K, M, 3) arrays of centre-line samples that numpy would make."""
    K, n = s.shape
    M = points.shape[0]
    out = np.empty((K, M))
    mx = np.empty((n, 3))  # each section's bending direction (base frame Rz(phi) x), world
    for k in range(K):
        R0, p0 = _sections(R_base, p_base, s[k], kappa[k], phi[k])
        for j in range(n):
            c, sn = np.cos(phi[k, j]), np.sin(phi[k, j])
            for r in range(3):
                mx[j, r] = c * R0[j, r, 0] + sn * R0[j, r, 1]
        for m in range(M):
            j, start = 0, 0.0
            while j < n - 1 and sigma[k, m] >= start + s[k, j]:
                start += s[k, j]
                j += 1
            u = min(max(sigma[k, m] - start, 0.0), s[k, j])
            x = kappa[k, j] * u
            radial, along = _radial_along(u, kappa[k, j])
            cx, sx = np.cos(x), np.sin(x)
            d0 = points[m, 0] - (p0[j, 0] + radial * mx[j, 0] + along * R0[j, 0, 2])
            d1 = points[m, 1] - (p0[j, 1] + radial * mx[j, 1] + along * R0[j, 1, 2])
            d2 = points[m, 2] - (p0[j, 2] + radial * mx[j, 2] + along * R0[j, 2, 2])
            t0 = sx * mx[j, 0] + cx * R0[j, 0, 2]
            t1 = sx * mx[j, 1] + cx * R0[j, 1, 2]
            t2 = sx * mx[j, 2] + cx * R0[j, 2, 2]
            axial = d0 * t0 + d1 * t1 + d2 * t2
            e0, e1, e2 = d0 - axial * t0, d1 - axial * t1, d2 - axial * t2
            off = np.sqrt(e0 * e0 + e1 * e1 + e2 * e2) - radius
            if capped[k, m] * axial > 0.0:
                off = np.sqrt(axial * axial + max(off, 0.0) ** 2)
            out[k, m] = off
    return out


def compile_kernels() -> bool:
    """Compile every kernel (or load it from the disk cache) for each array layout a run
    passes, and say whether they are cached on disk. numba compiles one version per layout:
    an arm's base rotation is Fortran-ordered (Drake's RotationMatrix) or C-ordered (the
    identity), a configuration's arrays read-only (ArmConfig) or writeable (IK's batches).
    drake_continuum.kernels.compile_all calls it (scripts/setup.sh, after an install), so that
    no run pays the ~12 s a process of compiling (the workers of a first collection would,
    each at once)."""
    def read_only(a):
        a = a.copy()
        a.setflags(write=False)
        return a

    s, kappa, phi = np.full(3, 0.1), np.full(3, 5.0), np.zeros(3)
    arc, fractions = np.linspace(0.0, 0.3, 8), np.linspace(0.0, 1.0, 4)
    for R in (np.eye(3), np.asfortranarray(np.eye(3))):
        for p in (np.zeros(3), read_only(np.zeros(3))):  # a station's arm: p read-only
            backbone_samples(R, p, *map(read_only, (s, kappa, phi)), arc)
            capsule_frames(R, p, *map(read_only, (s, kappa, phi, fractions)), 0.01)
        rows = [a[None, :] for a in (s, kappa, phi)]
        batch_points(R, np.zeros(3), *rows, fractions)
        batch_points(R, np.zeros(3), *map(read_only, rows), fractions)
    quaternions_wxyz(np.stack([np.eye(3)] * 2))
    position = np.zeros((4, 3))
    far_segments_within(position, position + [0.0, 0.0, 1.0], np.arange(4.0), 0, 0.01, 0.05,
                        0.02)
    rows = np.stack([s, kappa, phi])[:, None, :]
    tube_distances(np.eye(3), np.zeros(3), *rows, np.zeros((1, 4)), position, 0.01,
                   np.zeros((1, 4)))
    proximity.compile_kernels()
    return _CACHE
