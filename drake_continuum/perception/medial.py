"""The fit's start: medial points ordered along the arm by geodesic distance from the base
(a radius graph within each piece, pieces walked in order from the base) and one arc
fitted per section in turn; the fit's settings (FitParams).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ..kinematics.arm import ArmConfig, ContinuumArm
from .residuals import _Residuals, _uv_config

__all__ = ["FitParams", "order_along_arm", "ENTRY_REACH", "medial_polyline", "medial_points",
           "medial_length", "config_along"]


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


