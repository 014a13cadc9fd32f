"""The fit's start: medial points ordered along the arm by geodesic distance from the base
(a radius graph within each piece, pieces walked in order from the base) and one arc
fitted per section in turn; a start for a coil (loop_config); the fit's settings (FitParams).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ..kinematics.arm import ArmConfig, ContinuumArm
from .residuals import Residuals, uv_config

__all__ = ["FitParams", "order_along_arm", "ENTRY_REACH", "medial_polyline", "medial_points",
           "medial_length", "config_along", "STEM_TOL", "LOOP_MIN_TURN", "LOOP_MIN_POINTS",
           "stem_length", "fit_ring", "loop_config"]


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
        tol: the refinement stops when a step changes the cost, or the parameters, by less
            than this fraction (least_squares' ftol and xtol; its default 1e-8 spent half the
            iterations on sub-micrometre steps).
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
    tol: float = 1e-5
    assess: bool = True


def order_along_arm(points: np.ndarray, base: np.ndarray, *, params: FitParams = FitParams(),
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
            entry, local = _aligned_entry(G, points, members[c], entry=entry, local=local,
                                          here=here, heading=heading)
        g[members[c]] = g_here + np.linalg.norm(points[entry] - here) + local
        far = members[c][np.argmax(local)]
        if heading is not None:
            back = members[c][local >= local.max() - ENTRY_REACH]
            heading = points[far] - points[back].mean(0)
        here, g_here = points[far], g[far]
        left.remove(c)
    return g


ENTRY_REACH = 0.03  # m: the stretch of a piece's end whose mean gives its direction


def _aligned_entry(G, points, members, *, entry, local, here, heading):
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


def medial_polyline(points, geodesic, base, *, bin_width):
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


def _section_arm(arm: ContinuumArm, R, p, *, section: int = 0) -> ContinuumArm:
    """Section `section` of the arm alone, with its own limits, based at (R, p)."""
    lo, hi, kappa, bend = (float(a[section]) for a in arm.section_limits())
    return replace(arm, n_sections=1, base_position=p, base_rotation=R, per_section=(),
                   section_length_min=lo, section_length_max=hi, curvature_max=kappa,
                   bend_max=bend)


def _fit_section_arc(arm1: ContinuumArm, s: float, targets, *, sigma, kappa_max):
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


def medial_points(arm: ContinuumArm, points, *, params: FitParams = FitParams(),
                  heading: bool = False):
    """medial_polyline of the points ordered from the arm's base: (centres, their arc
    lengths, each point's arc length); heading: enter pieces along the walk's direction."""
    g = order_along_arm(points, arm.base_position, params=params,
                        heading=arm.base_rotation[:, 2] if heading else None)
    return medial_polyline(points, g, arm.base_position, bin_width=params.bin_width)


def medial_length(arm: ContinuumArm, medial, params: FitParams = FitParams()) -> float:
    """The arm's length seen along its medial points, m."""
    sig = medial[1]
    return (sig[-1] + params.bin_width / 2) if len(sig) else arm.n_sections * arm.section_length_min


def config_along(arm: ContinuumArm, points, medial, *, lengths,
                 params: FitParams = FitParams()) -> ArmConfig:
    """One arc a section in turn through the medial points, then the section's own points."""
    cen, sig, point_sig = medial
    n = arm.n_sections
    s = np.asarray(lengths, float)
    u, v = np.zeros(n), np.zeros(n)
    R, p = arm.base_rotation, arm.base_position
    start = 0.0
    for i in range(n):  # a loop over sections (3); each fit is vectorised over points
        sel = (sig >= start) & (sig <= start + s[i] + 1e-9)
        arm1 = _section_arm(arm, R, p, section=i)
        km = arm1.curvature_max
        if not sel.any() and i > 0:
            u[i], v[i] = u[i - 1], v[i - 1]
        else:
            u[i], v[i] = _fit_section_arc(arm1, s[i], cen[sel], sigma=sig[sel] - start,
                                          kappa_max=km)
        # The medial points lean towards the camera; refit to the section's own surface points.
        mine = points[(point_sig >= start) & (point_sig <= start + s[i])]
        if len(mine) >= 10:
            f = Residuals(arm1, mine, s[i:i + 1], caps=False)
            sol = least_squares(f, np.array([u[i], v[i]]), jac=f.jac, bounds=([-km] * 2,
                                [km] * 2), loss="soft_l1", f_scale=params.loss_scale,
                                max_nfev=20)
            u[i], v[i] = sol.x
        cfg = uv_config(arm1, s[i:i + 1], u[i:i + 1], v[i:i + 1])
        Rs, ps = arm1.section_frames(cfg)
        R, p = Rs[-1], ps[-1]
        start += s[i]
    return uv_config(arm, s, u, v)




# --------------------------------------------------------------------------- coils

STEM_TOL = 0.004  # m: the stem ends where one arc leaves the medial points this much more
LOOP_MIN_TURN = np.pi  # rad: a ring of points turning less than this is no loop
LOOP_MIN_POINTS = 20  # points off the stem, at least, for a ring to be fitted


def stem_length(arm: ContinuumArm, medial) -> float:
    """Arc length from the base over which one arc follows the medial points, m: where a
    coil's first section ends. The medial points lean towards the camera by under a radius,
    so an arc from the base misses even the first of them; the stem ends where the farthest
    miss grows by STEM_TOL over that first one."""
    cen, sig, _ = medial
    R, p = arm.base_rotation, arm.base_position
    arm1 = _section_arm(arm, R, p)
    first, end = None, float(sig[0]) if len(sig) else 0.0
    for j in range(1, len(sig)):  # a loop over 15 mm bins until the arc leaves them
        u, v = _fit_section_arc(arm1, sig[j], cen[:j + 1], sigma=sig[:j + 1],
                                kappa_max=arm1.curvature_max)
        arc = arm1.backbone(uv_config(arm1, [sig[j]], [u], [v]), arc_length=sig[:j + 1])
        miss = float(np.linalg.norm(arc.position - cen[:j + 1], axis=1).max())
        first = miss if first is None else first
        if miss > first + STEM_TOL:
            break
        end = float(sig[j])
    return end


def fit_ring(arm: ContinuumArm, points, first: ArmConfig, *, scale: float):
    """The circle that the points off the first section lie round, tangent to that section's
    line past its end (a coil: sections 2 and 3 bent the same way). A torus of the tube's
    radius is fitted (soft-L1 at `scale`) by where it touches the line (delta along it from
    the end), the angle psi of its centre about the line in the end's frame, and its radius.
    Returns (delta, psi, radius, turn: the angle round the circle from where it touches the
    line that the points on the torus reach, rad) or None when too few points lie off the
    first section or they lie round no circle that two sections could make."""
    R, p = arm.section_frames(first)
    e1, e2, t = R[-1][:, 0], R[-1][:, 1], R[-1][:, 2]
    stem = arm.backbone(first, n=max(int(float(np.sum(first.s)) / 0.003), 20)).position
    dist, _ = cKDTree(stem).query(points)
    ring = points[dist > 2 * arm.radius]
    if len(ring) < LOOP_MIN_POINTS:
        return None
    q = ring - p[-1]
    across = (q - (q @ t)[:, None] * t).mean(0)  # towards the circle's centre
    psi0 = float(np.arctan2(across @ e2, across @ e1))
    # A circle tangent to the line at the end: x^2 + y^2 = 2 r y in the plane (t, across).
    x, y = q @ t, q @ (across / max(np.linalg.norm(across), 1e-9))
    r_max = 2 * arm.section_length_max / np.pi
    r0 = float(np.clip(np.sum((x ** 2 + y ** 2) * y) / max(2 * np.sum(y ** 2), 1e-12),
                       1 / arm.curvature_max, r_max))

    def frame(z):
        delta, psi, r = z
        d = np.cos(psi) * e1 + np.sin(psi) * e2
        return p[-1] + delta * t + r * d, d

    def res(z):
        c, d = frame(z)
        w = ring - c
        h = w @ np.cross(t, d)
        rho = np.linalg.norm(w - h[:, None] * np.cross(t, d), axis=1)
        return np.hypot(rho - z[2], h) - arm.radius

    z = least_squares(res, [0.0, psi0, r0], loss="soft_l1", f_scale=scale, max_nfev=100,
                      bounds=([-arm.section_length_min, -np.inf, 1 / arm.curvature_max],
                              [arm.section_length_min, np.inf, r_max])).x
    if z[2] >= 0.99 * r_max:
        return None  # a line (or points round no circle an arm's two sections could make)
    on = np.abs(res(z)) <= 2 * scale
    c, d = frame(z)
    w = ring[on] - c
    # Round from the touching point (c - r d), the way the line runs on, as far as the
    # points on the torus reach (the ring's far side may be hidden behind its near side).
    angle = np.mod(np.arctan2(w @ t, -(w @ d)), 2 * np.pi)
    turn = float(np.percentile(angle, 98)) if on.sum() >= LOOP_MIN_POINTS else 0.0
    return float(z[0]), float(z[1]), float(z[2]), turn


def loop_config(arm: ContinuumArm, points, medial, *, lengths=None,
                params: FitParams = FitParams()):
    """A start for a coil: a first section along the medial points, then sections 2 to n
    bent round the ring of points past it, in its plane, as far as they may (a wrap of a
    small object closes a loop, and no ordering of its points follows it: every ordering
    enters the ring and runs both ways round). With free lengths the first section ends
    where one arc stops following the medial points, moved to where the ring touches its
    line; sections 2 to n share the ring's turn.

    Returns (configuration, the length it shows seen, m: an ordering folds the ring in two
    and measures half of it; here the first section and the ring as far round as sections 2
    to n may turn) or None when the points past the first section do not turn at least
    LOOP_MIN_TURN round a ring."""
    s = None if lengths is None else np.asarray(lengths, float)
    s1 = stem_length(arm, medial) if s is None else float(s[0])
    short = arm.section_length_min
    ring_sections = arm.n_sections - 1

    def first_section(s1):
        c = config_along(arm, points, medial,
                         lengths=[s1] + [short] * ring_sections if s is None else s,
                         params=params)
        return ArmConfig(c.s[:1], c.kappa[:1], c.phi[:1])

    if s is None:  # the stem's end moved to where the ring touches its line
        ring = fit_ring(arm, points, first_section(np.clip(s1, short, arm.section_length_max)),
                        scale=params.loss_scale)
        if ring is None:
            return None
        s1 += ring[0]
    s1 = float(np.clip(s1, short, arm.section_length_max))
    first = first_section(s1)
    ring = fit_ring(arm, points, first, scale=params.loss_scale)
    if ring is None or ring[3] < LOOP_MIN_TURN:
        return None
    _, psi, r, turn = ring
    if s is None:
        lo, hi = (limit[1:] for limit in arm.section_limits()[:2])
        s = np.concatenate([[s1], np.clip(turn * r / ring_sections, lo, hi)])
    k = np.minimum(1.0 / r, arm.curvature_limit(s)[1:])
    # Seen: the ring as far round as its sections may turn (each at most its bend_max; the
    # points of a ring show one turn at most), which the points leave open where the ring's
    # far side or a less bent last section hides.
    bend = min(float(np.sum(arm.section_limits()[3][1:])), 2 * np.pi)
    phi = [first.phi[0]] + [psi] * ring_sections
    return ArmConfig(s, np.concatenate([first.kappa, k]), phi), \
        max(float(np.sum(s)), s1 + bend * r)
