"""The fit's cost: per point, the distance to the arm's backbone minus the tube radius, and
the prior on the configuration (ConfigPrior).

Fitting (scipy least_squares): per point, residual = distance to the backbone minus the tube
radius, with a soft-L1 loss for flying pixels and stray points. Each section is parameterised
by (s, u, v) with (u, v) = kappa (cos phi, sin phi), smooth through kappa = 0 where phi is
undefined. The nearest backbone arc length of each point is recomputed at every iterate and
held fixed inside the Jacobian: by the envelope theorem the derivative of the point-to-curve
distance is that of the distance at the fixed nearest point, so nine cheap forward
evaluations give the Jacobian without any nearest-point search. The start comes from medial
points ordered along the arm by geodesic distance from the base (a radius graph within each
piece, pieces walked in order from the base) and one arc fitted per section in turn.

Every configuration the fit considers keeps the arm's curvature and bend limits (kappa_i <=
min(curvature_max, bend_max / s_i)): the curvature is held to its limit, and residuals on the
excess lead an iterate that strayed beyond it back. Without the bend limit a section coils
through itself to reach points of another turn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics.arm import ArmConfig, ContinuumArm, arc_transforms
from ..kinematics.compiled import tube_distances
from .cloud import PointCloudError

__all__ = ["centre_line", "centre_lines", "START_SPLITS", "start_splits", "GOOD_FIT", "HOPELESS",
           "OVERRUN", "TIP_WEIGHT", "LIMIT_WEIGHT", "TIP_SLACK", "LAST_POINT_TOL", "LAST_STRAYS",
           "FREE_WEIGHT", "FREE_OK", "FREE_NFEV", "SHORTEN", "soft_l1_cost", "soft_l1_rms",
           "PLANE_WEIGHT", "CURL_WEIGHT", "TOUCH_WEIGHT", "ConfigPrior", "WrapPlane", "TableTouch",
           "table_above", "Residuals", "Refined", "uv_config"]


def uv_config(arm: ContinuumArm, s, u, v):
    """The configuration of (s, u, v), its curvature held to the arm's curvature and bend
    limits (kappa_i <= min(curvature_max, bend_max / s_i)): a section bent past half a turn
    would coil through itself, and no real arm (nor any true wrap) does."""
    k = np.minimum(np.hypot(u, v), arm.curvature_limit(s))
    return ArmConfig(s, k, np.arctan2(v, u))


def _sin_over(x):
    """sin(x) / x, 1 at 0 (np.sinc without its generality: the fit calls it ~10^4 times)."""
    zero = x == 0
    return np.where(zero, 1.0, np.sin(x) / np.where(zero, 1.0, x))


def centre_lines(arm: ContinuumArm, s, kappa, phi, sigma):
    """Positions and unit tangents (K, m, 3) of K configurations at once: s, kappa, phi are
    (K, n), sigma the arc lengths (m,) or (K, m). ContinuumArm.backbone without the normal
    frames and batched over configurations: the fit's Jacobian evaluates ten configurations
    at the same arc lengths, and one pass over all of them costs little more than one."""
    s, kappa, phi = (np.atleast_2d(np.asarray(a, float)) for a in (s, kappa, phi))
    K, n = s.shape
    Rl, pl = arc_transforms(s, kappa, phi)  # (K, n, 3, 3), (K, n, 3)
    R0, p0 = np.empty((K, n, 3, 3)), np.empty((K, n, 3))
    R = np.broadcast_to(arm.base_rotation, (K, 3, 3))
    p = np.broadcast_to(arm.base_position, (K, 3))
    for i in range(n):  # a loop over sections (3), as ContinuumArm.section_frames
        R0[:, i], p0[:, i] = R, p
        p = p + np.einsum("kij,kj->ki", R, pl[:, i])
        R = R @ Rl[:, i]
    starts = np.concatenate([np.zeros((K, 1)), np.cumsum(s, axis=1)[:, :-1]], axis=1)
    sigma = np.broadcast_to(np.asarray(sigma, float), (K, np.shape(sigma)[-1]))
    # The section of each arc length: the starts at or before it, less one (searchsorted).
    sec = np.minimum((sigma[:, :, None] >= starts[:, None, 1:]).sum(-1), n - 1)
    kk = np.arange(K)[:, None]
    local = np.clip(sigma - starts[kk, sec], 0.0, s[kk, sec])
    x = kappa[kk, sec] * local
    cphi, sphi = np.cos(phi[kk, sec]), np.sin(phi[kk, sec])
    half = _sin_over(x / 2)
    radial = local * 0.5 * x * half * half  # s (1 - cos x) / x
    p_local = np.stack([radial * cphi, radial * sphi, local * _sin_over(x)], -1)
    sx = np.sin(x)
    t_local = np.stack([cphi * sx, sphi * sx, np.cos(x)], -1)
    Rb = R0[kk, sec]
    return (p0[kk, sec] + np.einsum("kmij,kmj->kmi", Rb, p_local),
            np.einsum("kmij,kmj->kmi", Rb, t_local))


def centre_line(arm: ContinuumArm, cfg: ArmConfig, sigma):
    """Positions and unit tangents (m, 3) of one configuration at arc lengths sigma."""
    position, tangent = centre_lines(arm, cfg.s[None], cfg.kappa[None], cfg.phi[None],
                                     np.asarray(sigma, float)[None])
    return position[0], tangent[0]


# Free lengths' starts: fractions of the seen length a section (three sections).
START_SPLITS = ((1 / 3, 1 / 3, 1 / 3), (0.3, 0.4, 0.3), (0.3, 0.3, 0.4))


def start_splits(n: int) -> np.ndarray:
    """(k, n) free lengths' starts for n sections, as START_SPLITS: equal, the middle
    section(s) a third longer, the last a third longer (duplicates left out)."""
    if n == 3:
        return np.asarray(START_SPLITS)
    middle, last = np.ones(n), np.ones(n)
    middle[(n - 1) // 2:n // 2 + 1] = last[-1] = 4 / 3
    rows = [np.full(n, 1 / n)]
    for w in (middle / middle.sum(), last / last.sum()):
        if not any(np.allclose(w, r) for r in rows):
            rows.append(w)
    return np.array(rows)
GOOD_FIT = 0.0015  # m: the later starts are skipped once one fits with this soft-L1 RMS
HOPELESS = 0.0045  # m: a start whose first solve leaves this soft-L1 RMS is not polished
OVERRUN = 0.06  # m: free lengths are charged for running this far past the seen length
TIP_WEIGHT = 20.0  # free lengths: weight of the arm's length beyond its last seen point
LIMIT_WEIGHT = 20.0  # weight of the bend beyond the limit, rad, times the section length
TIP_SLACK = 0.002  # m: the last surface point sampled lies up to half a voxel short of the tip
LAST_POINT_TOL = 0.003  # m: a point this near the tube counts towards the seen length
LAST_STRAYS = 4  # the farthest points on the tube that do not yet extend the seen length
FREE_WEIGHT = 1.0  # a ray through the tube counts as much as a point off it
FREE_OK = 15  # rays through the tube's core that a good fit may keep (flying pixels)
FREE_NFEV = 30  # iteration cap of the refinement with the free-space term
SHORTEN = 0.008  # m: free lengths also try the fit with the last section this much shorter
PLANE_WEIGHT = 0.3  # a section's bend out of the wrap's plane against one point (WrapPlane)
CURL_WEIGHT = 0.03  # a curled section short of its limit, a tenth of that (WrapPlane)
TOUCH_WEIGHT = 1.0  # a contact under the table counts as a point off the tube (TableTouch)


def _one_layout(a) -> np.ndarray:
    """`a` as C-ordered writeable floats: numba compiles one version of a kernel per array
    layout, and compile_kernels compiles this one ahead, so no fit pays a compilation."""
    return np.require(a, dtype=float, requirements=("C", "W"))


class Residuals:
    """Point-to-tube residuals with nearest arc lengths cached for the Jacobian."""

    def __init__(self, arm: ContinuumArm, points, lengths, *, caps: bool = True,
                 length_cap: float = np.inf, free=None, prior=None, plane=None,
                 charge_tail: bool = True, touch=None):
        self.arm, self.points, self.lengths, self.caps = arm, points, lengths, caps
        self.length_cap, self.charge_tail = length_cap, charge_tail
        self.free, self.prior = free, prior  # FreeSpaceTerm, ConfigPrior or None
        self.plane = None if plane is None else plane.in_base(arm)  # WrapPlane or None
        self.touch = touch  # TableTouch or None
        self.n = arm.n_sections
        self.key = None
        self._points = _one_layout(points)
        self._base = (_one_layout(arm.base_rotation), _one_layout(arm.base_position))

    def split(self, x):
        """(s, u, v) of parameters x (p,) or of a batch of them (K, p)."""
        n = self.n
        if self.lengths is None:
            return x[..., :n], x[..., n:2 * n], x[..., 2 * n:]
        return np.broadcast_to(self.lengths, x[..., :n].shape), x[..., :n], x[..., n:]

    def config(self, x) -> ArmConfig:
        return uv_config(self.arm, *self.split(x))

    def excess(self, x):
        """(n,) residuals of the bend limit: the configuration holds each curvature to its
        limit, which leaves no gradient beyond it; these lead an iterate that strayed there
        back (zero within the limits, so they do not move a fit that stays inside)."""
        s, u, v = self.split(x)
        over = np.maximum(np.hypot(u, v) - self.arm.curvature_limit(s), 0.0)
        return LIMIT_WEIGHT * s * s * over

    def nearest(self, cfg: ArmConfig):
        total = float(np.sum(cfg.s))
        bb = self.arm.backbone(cfg, n=max(int(total / 0.003), 20))
        # Each point's nearest sample by |b|^2 - 2 p.b about the samples' mean: one small
        # matrix product, a quarter of a k-d tree's cost for the ~100 samples of an arm.
        centre = bb.position.mean(axis=0)
        b = bb.position - centre
        j = np.argmin(np.einsum("ki,ki->k", b, b) - 2.0 * (self.points - centre) @ b.T, axis=1)
        step = np.einsum("mi,mi->m", self.points - bb.position[j], bb.tangent[j])
        sigma = np.clip(bb.arc_length[j] + step, 0.0, total)
        near = (sigma, sigma >= total - 1e-12, sigma <= 1e-12)
        if self.free is None:
            return near
        return near + self.free.distances(bb.position, bb.arc_length, bb.tangent)[::2]

    def _at(self, s, kappa, phi, sigma, at_tip, at_base):
        """(K, M) point residuals of K configurations (K, n) at fixed arc lengths (compiled:
        the fit's cost is mostly this, evaluated ten configurations at a time)."""
        total = s.sum(axis=1)[:, None]
        sigma = np.where(at_tip, total, np.minimum(sigma, total))
        # Beyond an end the tube is a flat-capped solid: distance to the cap disc.
        capped = np.where(at_tip, 1.0, np.where(at_base, -1.0, 0.0)) if self.caps else 0.0
        shape = (len(s), len(self.points))
        c = _one_layout
        return tube_distances(self._base[0], self._base[1], c(s), c(kappa), c(phi),
                              c(np.broadcast_to(sigma, shape)), self._points,
                              float(self.arm.radius), c(np.broadcast_to(capped, shape)))

    def at(self, cfg: ArmConfig, sigma, at_tip, at_base):
        return self._at(cfg.s[None], cfg.kappa[None], cfg.phi[None], sigma, at_tip,
                        at_base)[0]

    def _residuals(self, s, kappa, phi, sigma, at_tip, at_base):
        """(K, M or M + 2) the points' residuals and, free lengths, the tail's."""
        r = self._at(s, kappa, phi, sigma, at_tip, at_base)
        if self.lengths is not None:
            return r
        if not self.charge_tail:
            # The commanded lengths say how far the arm runs on past its last seen point.
            return np.concatenate([r, np.zeros((len(r), 2))], axis=1)
        # Free lengths: nothing in the points stops the arm from running on past its last
        # seen point, so the part beyond it is charged as if TIP_WEIGHT points lay off it.
        total = s.sum(axis=1)
        # The last point on the tube, measured along the arm past its end too: a point on
        # the end cap then ties the end to it (clipped to the end, it would let the arm run
        # on for free), and a stray point off the tube does not license it.
        sig = np.broadcast_to(np.minimum(sigma, total[:, None]), r.shape).copy()
        if at_tip.any():
            p_end, t_end = centre_lines(self.arm, s, kappa, phi, total[:, None])
            sig[:, at_tip] = total[:, None] + np.einsum(
                "kmi,ki->km", self.points[at_tip] - p_end, t_end[:, 0])
        on = np.abs(r) <= LAST_POINT_TOL
        # The LAST_STRAYS + 1-th farthest point on the tube: a flying pixel or two behind
        # the tip's edge (the camera looking down the arm) lie along its continuation.
        k = min(LAST_STRAYS, r.shape[1] - 1)
        farthest = -np.partition(-np.where(on, sig, -np.inf), k, axis=1)[:, k]
        last = np.where(on.sum(axis=1) > k, farthest,
                        np.where(on.any(axis=1), np.where(on, sig, -np.inf).max(axis=1),
                                 sig.max(axis=1)))
        tail = np.stack([TIP_WEIGHT * np.maximum(total - last - TIP_SLACK, 0.0),
                         TIP_WEIGHT * np.maximum(total - self.length_cap, 0.0)], axis=1)
        return np.concatenate([r, tail], axis=1)

    def residuals(self, cfg: ArmConfig, sigma, at_tip, at_base):
        return self._residuals(cfg.s[None], cfg.kappa[None], cfg.phi[None], sigma, at_tip,
                               at_base)[0]

    def full_batch(self, X, near):
        """(K, residuals) of K parameter vectors X (K, p) at fixed nearest arc lengths."""
        s, u, v = self.split(X)
        kappa = np.minimum(np.hypot(u, v), self.arm.curvature_limit(s))
        phi = np.arctan2(v, u)
        parts = [self._residuals(s, kappa, phi, *near[:3]), self.excess(X)]
        if self.free is not None:
            ray, ray_sigma = near[3:]
            pos = centre_lines(self.arm, s, kappa, phi,
                               np.minimum(ray_sigma, s.sum(axis=1)[:, None]))[0]
            parts.append(FREE_WEIGHT * self.free.residuals(pos, ray))
        if self.prior is not None:
            parts.append(self.prior.residuals(s, u, v, lengths_free=self.lengths is None))
        if self.plane is not None:
            parts.append(self.plane.residuals(s, u, v, limit=self.arm.curvature_limit(s)))
        if self.touch is not None:
            parts.append(self.touch.residuals(self.arm, (s, kappa, phi)))
        return np.concatenate(parts, axis=1)

    def along(self, X, sigma):
        """(K, M + n) residuals of K parameter vectors X (K, p) with each point held at the
        arc length an ordering gave it (past the arm's end: at the tip), and the bend
        limit's: the prefit's cost."""
        s, u, v = self.split(X)
        kappa = np.minimum(np.hypot(u, v), self.arm.curvature_limit(s))
        total = s.sum(axis=-1)[:, None]
        r = self._at(s, kappa, np.arctan2(v, u), np.minimum(sigma, total), sigma >= total,
                     sigma <= 0.0)
        return np.concatenate([r, self.excess(X)], axis=1)

    def along_jac(self, x, sigma, lo, hi):
        """least_squares' own '2-point' differences of `along` (its steps, turned back where
        they would cross a bound), the nine steps evaluated in one batch."""
        h = np.sqrt(np.finfo(float).eps) * np.where(x >= 0, 1.0, -1.0) * np.maximum(1.0,
                                                                                  np.abs(x))
        h = np.where((x + h < lo) | (x + h > hi), -h, h)
        X = np.tile(x, (len(x) + 1, 1))
        X[1:][np.diag_indices(len(x))] += h
        F = self.along(X, sigma)
        return ((F[1:] - F[0]) / (X[1:][np.diag_indices(len(x))] - x)[:, None]).T

    def full(self, x, near):
        return self.full_batch(x[None], near)[0]

    def __call__(self, x):
        self.key = (x.tobytes(), self.nearest(self.config(x)))
        return self.full(x, self.key[1])

    def jac(self, x):
        """Forward differences, one column a parameter (9), all evaluated in one batch."""
        near = self.key[1] if self.key and self.key[0] == x.tobytes() else \
            self.nearest(self.config(x))
        h = 1e-6 * np.maximum(1.0, np.abs(x))
        X = np.tile(x, (len(x) + 1, 1))
        X[1:][np.diag_indices(len(x))] += h
        F = self.full_batch(X, near)
        return ((F[1:] - F[0]) / h[:, None]).T


def soft_l1_cost(r, scale: float) -> float:
    """least_squares' soft-L1 cost of residuals r at the given scale."""
    return float(np.sum(scale ** 2 * (np.sqrt(1 + (np.asarray(r) / scale) ** 2) - 1)))


def soft_l1_rms(r, scale: float) -> float:
    """The RMS that the soft-L1 cost of residuals r corresponds to, m (what GOOD_FIT and
    'fits the points equally well' compare)."""
    z = (np.asarray(r) / scale) ** 2
    return scale * float(np.sqrt(np.mean(2 * (np.sqrt(1 + z) - 1)))) if len(z) else 0.0


@dataclass(frozen=True)
class ConfigPrior:
    """The commanded configuration with its uncertainty, as a Gaussian prior on the fit.

    A real arm knows roughly what it was told: where no point shows a section, the fit
    keeps it near the command instead of inventing a shape. The prior enters the least
    squares as residuals scaled by NOISE (the points' depth noise), so that its weight
    against the points is that of a Gaussian of the stated standard deviations against
    points of that noise; the soft-L1 loss makes it give way where many points disagree
    (a real arm pressed out of its commanded shape by the object).

    Args:
        config: the commanded configuration.
        sigma_s: standard deviation of each section length, m.
        sigma_kappa: of each curvature, 1/m.
        sigma_phi: of each bending direction, rad (as an arc: kappa * sigma_phi, 1/m).
    """

    config: ArmConfig
    sigma_s: float = 0.01
    sigma_kappa: float = 1.0
    sigma_phi: float = 0.2

    NOISE = 0.0015  # m

    def __post_init__(self):
        if min(self.sigma_s, self.sigma_kappa, self.sigma_phi) <= 0:
            raise PointCloudError(f"prior uncertainties must be positive, got sigma_s "
                                  f"{self.sigma_s}, sigma_kappa {self.sigma_kappa}, sigma_phi "
                                  f"{self.sigma_phi}")

    def residuals(self, s, u, v, lengths_free: bool = True) -> np.ndarray:
        """Residuals of (s, u, v), each (n,) or a batch (K, n): (2n or 3n,) or (K, ...)."""
        c = self.config
        er0, er1 = np.cos(c.phi), np.sin(c.phi)
        du0, du1 = u - c.kappa * er0, v - c.kappa * er1
        radial = (du0 * er0 + du1 * er1) / self.sigma_kappa
        across = (du1 * er0 - du0 * er1) / np.hypot(c.kappa * self.sigma_phi, self.sigma_kappa)
        parts = [radial, across] + ([(s - c.s) / self.sigma_s] if lengths_free else [])
        return self.NOISE * np.concatenate(parts, axis=-1)

    def to_dict(self) -> dict:
        return {"config": self.config.to_dict(), "sigma_s_m": self.sigma_s,
                "sigma_kappa_per_m": self.sigma_kappa, "sigma_phi_rad": self.sigma_phi}


@dataclass(frozen=True)
class WrapPlane:
    """The plane the wrap was commanded in (Algorithm 1 wraps in one plane), as a weak prior:
    each section's bend out of it is charged, so a section the camera does not see stays in
    the plane instead of turning anywhere at equal cost.

    The residual of section i is PLANE_WEIGHT * s_i^2 / 2 * (its curvature along the plane's
    normal): PLANE_WEIGHT times how far that bend moves the section's end out of the plane its
    own start spans with the normal. A section bent in the plane in its own frame keeps the
    arm in it (a bend about the normal turns the frame about the normal), and a section that
    earlier ones turned out of the plane is charged only for its own bend. Why the cloud
    always wins where it shows a section: that section's points move out with it, each
    charged by about as much as the whole plane term (0.3 of one point); a section seen at
    all shows tens of points (4 mm voxels), so the prior only decides between shapes the
    points explain equally well.

    In the plane a hidden section is still free to bend either way, by any amount: a wrap
    whose last section runs under the tabletop, where no camera sees, put the tip anywhere
    on a half circle at one cost (BENCHMARKS.md, Point clouds). Two facts of Algorithm 1
    decide it, each charged by how far the section's end moves: every section turns the tip
    the way the wrap was commanded to turn about the normal (`turn`; enclosing only ever
    grows a curvature towards the wrap's side), so a bend the other way is charged as the
    bend out of the plane is (PLANE_WEIGHT; it held in every wrap of a 40-object
    collection); and a section that touched nothing was curled by enclosing towards its
    bend limit (`curled`: the last section, when the tactile skin reads no contact on it),
    so a bend short of the limit is charged, but at CURL_WEIGHT only: a wrap that turned
    its tip far enough stops with that section part way, and there the points decide; the
    term is there to choose among shapes that no point or ray tells apart.

    Args:
        normal: the plane's unit normal in the world (the cloud's) frame.
        turn: +1 when the wrap turns counter-clockwise about `normal`, -1 clockwise, 0
            unknown (no turning prior).
        curled: indices of the sections curled to their bend limit (0-based).
    """

    normal: tuple
    frame: str = "world"
    turn: int = 0
    curled: tuple = ()

    def __post_init__(self):
        n = np.asarray(self.normal, float).reshape(-1)
        if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) < 1e-9:
            raise PointCloudError(f"the wrap plane's normal must be 3 finite numbers, not all "
                                  f"zero; got {self.normal!r}")
        if self.turn not in (-1, 0, 1):
            raise PointCloudError(f"the wrap's turn must be -1, 0 or +1, got {self.turn!r}")
        if self.curled and self.turn == 0:
            raise PointCloudError("curled sections need the wrap's turn (+1 or -1)")

    def in_base(self, arm: ContinuumArm) -> "WrapPlane":
        """This plane with its normal in the arm base's frame, where (u, v) bend."""
        if self.frame == "base":
            return self
        n = arm.base_rotation.T @ np.asarray(self.normal, float)
        return WrapPlane(tuple((n / np.linalg.norm(n)).tolist()), "base", self.turn,
                         tuple(int(i) for i in self.curled))

    def turning(self, u, v):
        """(n,) or (K, n) each section's curvature about the normal (base frame) in the
        wrap's sense, 1/m: positive where it turns the tip the commanded way."""
        return self.turn * (self.normal[1] * u - self.normal[0] * v)

    def bent(self, kappa) -> tuple:
        """(u, v) of in-plane bends by curvatures `kappa` (n,) in the wrap's sense (base
        frame; the turn must be known)."""
        n0, n1 = self.normal[0], self.normal[1]
        size = np.hypot(n0, n1)
        return self.turn * kappa * n1 / size, -self.turn * kappa * n0 / size

    def residuals(self, s, u, v, *, limit=None) -> np.ndarray:
        """(n,) or (K, n) residuals of sections (s, u, v), m, the normal in the base frame;
        with a known turn n more (bends against it) and one a curled section (short of
        `limit`, the sections' curvature limits)."""
        if self.frame != "base":
            raise PointCloudError("WrapPlane.residuals needs the normal in the base frame "
                                  "(in_base)")
        out = self.normal[0] * u + self.normal[1] * v  # the curvature along the normal
        half = PLANE_WEIGHT * 0.5 * s * s
        parts = [half * out]
        if self.turn:
            along = self.turning(u, v)
            parts.append(half * np.maximum(-along, 0.0))
            if self.curled:
                k = list(self.curled)
                parts.append(CURL_WEIGHT / PLANE_WEIGHT * half[..., k]
                             * np.maximum(limit[..., k] - along[..., k], 0.0))
        return np.concatenate(parts, axis=-1)


@dataclass(frozen=True)
class TableTouch:
    """Where the tactile skin touched, and the table the object stands on: every contact is
    on the object, so none lies under the tabletop. A section that runs under the table (a
    simulated wrap passes through it; no camera sees there) and touched the object is held
    by its contacts at least as high as the table, where the points and free space say
    nothing: each contact's centre-line point charged, as TOUCH_WEIGHT points off the tube,
    by how far it lies more than the tube's radius under the table's plane.

    Args:
        arc_length: (m,) arc lengths of the contacts, m.
        table: (4,) the table's plane a x + b y + c z + d = 0 (segmentation.Segmentation's),
            oriented so that the arm's base lies on its positive side (table_above).
    """

    arc_length: np.ndarray
    table: np.ndarray

    def residuals(self, arm: ContinuumArm, sections) -> np.ndarray:
        """(K, m) residuals at the contacts' arc lengths of K configurations, `sections`
        their (s, kappa, phi), each (K, n)."""
        s, kappa, phi = sections
        sigma = np.minimum(np.asarray(self.arc_length, float)[None], s.sum(axis=1)[:, None])
        pos = centre_lines(arm, s, kappa, phi, sigma)[0]
        height = pos @ self.table[:3] + self.table[3]
        return TOUCH_WEIGHT * np.maximum(-height - arm.radius, 0.0)


def table_above(table, arm: ContinuumArm) -> np.ndarray:
    """The plane (4,) a x + b y + c z + d = 0 scaled to a unit normal pointing to the side of
    the arm's base (above the table)."""
    plane = np.asarray(table, float) / np.linalg.norm(np.asarray(table, float)[:3])
    return plane if plane[:3] @ arm.base_position + plane[3] >= 0 else -plane


@dataclass
class Refined:
    """One start refined: the solution, its configuration, each point's arc length and
    residual, the unseen intervals, evaluations, the residual function, and the rays through
    the tube at the solution."""

    sol: object
    config: ArmConfig
    arc_length: np.ndarray
    residual: np.ndarray
    unseen: tuple
    nfev: int
    fun: "Residuals"
    n_free: int = 0

    def point_rms(self, params) -> float:
        return soft_l1_rms(self.residual, params.loss_scale)
