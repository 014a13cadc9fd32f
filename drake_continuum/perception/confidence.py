"""How sure a fit of the arm to a cloud is (pointcloud.fit_arm calls `assess`).

Per section the fraction of its arc length with points on it; the tip's standard deviation
from the curvature of the cost at the optimum (Gauss-Newton, points of ConfigPrior.NOISE,
each parameter otherwise known only to its range); for a partly unseen arm, other solutions
sought (the starts not tried yet, the unseen sections bent otherwise) and the spread of
the tips of those that explain the points, the free space and the prior equally well; and,
with free lengths and a camera, whether the arm may run on unseen past its last seen point.
A fit is ambiguous when equally good solutions put the tip far apart, partly unseen when
part of the arm has no point on it or may continue unseen, and poor when many of its points
lie off the tube.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..kinematics.arm import ArmConfig, ContinuumArm
from .freespace import violations
from .residuals import FREE_OK, ConfigPrior, Refined, soft_l1_cost
from .search import Candidate, FitSearch, Start

if TYPE_CHECKING:
    from collections.abc import Iterator

__all__ = ["AMBIGUOUS_TIP", "EQUAL_FIT", "EQUAL_FIT_MM", "EXTEND", "HIDDEN_RUN", "ALTERNATIVES",
           "UNEXPLAINED_MAX", "FitConfidence", "seen_fractions", "tip_may_continue", "assess"]

AMBIGUOUS_TIP = 0.008  # m: tips of equally good solutions this far apart make a fit ambiguous
EQUAL_FIT = 1.25  # point RMS within this factor (plus EQUAL_FIT_MM) explains them equally well
EQUAL_FIT_MM = 0.2
EXTEND = 0.04  # m: how far past its end the arm is lengthened to see whether it may go on
HIDDEN_RUN = 0.015  # m: it may go on unseen if this much more of it would stay hidden
ALTERNATIVES = 5  # other explanations sought for a partly unseen arm
UNEXPLAINED_MAX = 0.05  # a fit leaving more of the arm's points off the tube is poor
LENGTH_LADDER = 0.064  # m: the farthest a length is moved to see what the cost says of it
LONGER = 0.06  # m: a free last section this much longer is refitted to see if it explains


@dataclass(frozen=True)
class FitConfidence:
    """How sure a fit is.

    Args:
        seen_fraction: (n,) fraction of each section's arc length with points on it.
        tip_sigma: the tip's standard deviation from the curvature of the cost at the
            optimum (Gauss-Newton, points of ConfigPrior.NOISE, each parameter otherwise
            known only to its range), RMS over x, y, z, m. Parts no point or ray constrains
            show as a large value.
        tip_spread: the farthest tip of the other solutions that explain the points (and
            free space, and the prior) equally well, m (0 when none was found).
        n_solutions: solutions that explain them equally well, this one included.
        free_space_rays: rays seen through the fitted tube's core (exact ray cast), or None
            without a camera position.
        tip_may_continue: lengths free: the arm could run on past its last seen point
            where no camera could see it (None when unknown: lengths known or no camera).
        ambiguous: distinct solutions explain the points equally well (tip_spread or
            2 tip_sigma over AMBIGUOUS_TIP).
        partly_unseen: part of the arm has no point on it, or may continue unseen.
        unexplained: fraction of the arm's points farther than FitParams.inlier from the
            fitted tube.
        poor_fit: more than UNEXPLAINED_MAX of them: no start found the arm they show.

    A fit through whose tube the cameras saw more than FREE_OK rays (flying pixels aside) is
    contradicted by free space (`seen_through`): the arm cannot be where the fit puts it.
    """

    seen_fraction: tuple
    tip_sigma: float
    tip_spread: float
    n_solutions: int
    free_space_rays: int | None
    tip_may_continue: bool | None
    ambiguous: bool
    partly_unseen: bool
    unexplained: float = 0.0
    poor_fit: bool = False

    @property
    def seen_through(self) -> bool:
        """The cameras saw through the fitted tube's core along more than FREE_OK rays."""
        return self.free_space_rays is not None and self.free_space_rays > FREE_OK

    @property
    def confident(self) -> bool:
        """Neither ambiguous, nor partly unseen, nor a poor fit, nor seen through."""
        return not (self.ambiguous or self.partly_unseen or self.poor_fit or self.seen_through)

    @property
    def verdict(self) -> str:
        """One word for the fit: AMBIGUOUS, partly unseen, poor fit, seen through or
        confident (the first that holds)."""
        return next((word for word, holds in (
            ("AMBIGUOUS", self.ambiguous), ("partly unseen", self.partly_unseen),
            ("poor fit", self.poor_fit), ("seen through", self.seen_through)) if holds),
            "confident")

    @property
    def tip_uncertainty(self) -> float:
        """One figure for the tip, m: the larger of 2 tip_sigma and the spread."""
        return max(2 * self.tip_sigma, self.tip_spread)

    def to_dict(self) -> dict:
        return {"seen_fraction": [float(f) for f in self.seen_fraction],
                "tip_sigma_mm": 1e3 * self.tip_sigma, "tip_spread_mm": 1e3 * self.tip_spread,
                "tip_uncertainty_mm": 1e3 * self.tip_uncertainty,
                "n_solutions": int(self.n_solutions), "free_space_rays": self.free_space_rays,
                "tip_may_continue": self.tip_may_continue, "ambiguous": bool(self.ambiguous),
                "partly_unseen": bool(self.partly_unseen),
                "unexplained_fraction": float(self.unexplained), "poor_fit": bool(self.poor_fit),
                "seen_through": self.seen_through, "confident": self.confident}


def seen_fractions(config: ArmConfig, unseen) -> np.ndarray:
    """(n,) fraction of each section's arc length outside the unseen intervals."""
    starts = np.concatenate([[0.0], np.cumsum(config.s)])
    hidden = np.zeros(config.n_sections)
    for lo, hi in unseen:
        hidden += np.maximum(np.minimum(hi, starts[1:]) - np.maximum(lo, starts[:-1]), 0.0)
    return np.clip(1.0 - hidden / config.s, 0.0, 1.0)


def _tip_sigma(arm: ContinuumArm, out: Refined, loss: float) -> float:
    """RMS standard deviation of the tip from the Gauss-Newton curvature at the optimum."""
    x = out.sol.x
    J = out.sol.jac
    n = arm.n_sections
    s_min, s_max, kappa_max = arm.section_limits()[:3]
    ranges = np.tile(2 * kappa_max, len(x) // n)
    if len(x) == 3 * n:
        ranges[:n] = s_max - s_min
    if len(x) == 3 * n:
        # The last length is held by one-sided terms (the tail charge past the last seen
        # point, the end cap's points), which the linearisation at the optimum does not see:
        # its zero column read as 'known only to its range' (a tip sigma of 300 mm on a
        # tip seen end on). Its spread is taken from the cost itself instead.
        ranges[n - 1] = min(ranges[n - 1], _length_spread(out, x, n - 1, loss))
    H = J.T @ J / ConfigPrior.NOISE ** 2 + np.diag(1.0 / ranges ** 2)
    # A parameter held at its bound is known to lie there (a length at its minimum).
    free = np.asarray(out.sol.active_mask) == 0
    cov = np.zeros_like(H)
    cov[np.ix_(free, free)] = np.linalg.pinv(H[np.ix_(free, free)])
    tip0 = arm.tip_frame(out.fun.config(x))[1]
    Jt = np.empty((3, len(x)))
    for k in range(len(x)):
        h = 1e-6 * max(1.0, abs(x[k]))
        xk = x.copy()
        xk[k] += h
        Jt[:, k] = (arm.tip_frame(out.fun.config(xk))[1] - tip0) / h
    return float(np.sqrt(max(np.trace(Jt @ cov @ Jt.T), 0.0)))


def _length_spread(out: Refined, x, k: int, loss: float) -> float:
    """The standard deviation of parameter k (a section length, m) from the profile of the
    fit's own cost (points, tail, free space, prior; nearest points found again): half the
    width of the interval over which the cost rises by less than 2 NOISE^2 (a chi-square of
    4: two standard deviations), over a fixed ladder of steps (1 mm doubling to LENGTH_LADDER
    m), so that the answer does not depend on anything but the cloud."""
    base = soft_l1_cost(out.fun(x), loss)
    reach = []
    for sign in (1.0, -1.0):
        width = LENGTH_LADDER
        for step in 0.001 * 2.0 ** np.arange(int(np.log2(LENGTH_LADDER / 0.001)) + 1):
            xk = x.copy()
            xk[k] = max(xk[k] + sign * step, 1e-3)
            if soft_l1_cost(out.fun(xk), loss) - base > 2 * ConfigPrior.NOISE ** 2:
                width = step
                break
        reach.append(width)
    out.fun(x)  # the residuals' nearest points as they were
    return float(sum(reach)) / 4


def _hidden_alternatives(arm: ContinuumArm, config: ArmConfig, seen, limit: int = 6):
    """Configurations that bend the mostly unseen sections otherwise (the other way, across,
    straight): starts for other explanations of a partly hidden arm."""
    out = []
    for i in np.flatnonzero(np.asarray(seen) < 0.5):
        k_half = 0.5 * float(arm.curvature_limit(config.s)[i])
        for kappa, dphi in ((config.kappa[i], np.pi), (k_half, np.pi / 2),
                            (k_half, -np.pi / 2), (0.0, 0.0)):
            k, p = config.kappa.copy(), config.phi.copy()
            k[i], p[i] = kappa, p[i] + dphi
            out.append(ArmConfig(config.s, k, p))
    return out[:limit]


def _longer_explains(search: FitSearch, out: Refined, params) -> bool:
    """Whether the arm with its last section LONGER longer, refined without the charge for
    running past the last seen point, explains the points as well (EQUAL_FIT) while no camera
    saw through the part past the fit's end (a stray ray or two ignored): then the points do
    not fix the free length, and the arm may run on behind what hid it (a wrap whose end
    curls on behind the object's body, bent more than the seen part alone shows). The
    alternative joins the search, where it counts towards the tips' spread."""
    arm, config = search.problem.arm, out.config
    total = float(np.sum(config.s))
    s = config.s.copy()
    s[-1] = min(s[-1] + LONGER, float(arm.section_limits()[1][-1]))
    if s[-1] - config.s[-1] < HIDDEN_RUN:
        return False
    start = ArmConfig(s, np.minimum(config.kappa, arm.curvature_limit(s)), config.phi)
    candidate = search.attempt(Start(start, None), prefit=False,
                               max_nfev=params.max_nfev // 3, charge_tail=False)
    alt = candidate.refined
    beyond = float(np.sum(alt.config.s)) - total
    hidden = beyond >= HIDDEN_RUN and alt.point_rms(params) <= \
        EQUAL_FIT * out.point_rms(params) + EQUAL_FIT_MM * 1e-3
    if hidden:
        arc = np.arange(total + arm.radius, total + beyond + 1e-9, 0.003)
        bb = arm.backbone(alt.config, arc_length=arc)
        hidden = len(search.free.distances(bb.position, bb.arc_length, bb.tangent)[0]) <= 2
    if not hidden:  # a camera saw through it, or it does not explain the points
        search.fits.remove(candidate)
    return hidden


def tip_may_continue(arm: ContinuumArm, config: ArmConfig, free) -> bool:
    """Whether the last section, lengthened (bent as it is, or straight), stays where no
    camera saw through for at least HIDDEN_RUN past its end: then the arm may run on unseen
    past its last seen point."""
    total = float(np.sum(config.s))
    for kappa in (config.kappa[-1], 0.0):
        s = config.s.copy()
        s[-1] += EXTEND
        k = config.kappa.copy()
        k[-1] = min(kappa, float(arm.curvature_limit(s)[-1]))
        longer = replace(arm, section_length_max=max(arm.section_length_max, s[-1]))
        arc = np.arange(total + arm.radius, total + EXTEND + 1e-9, 0.003)
        bb = longer.backbone(ArmConfig(s, k, config.phi), arc_length=arc)
        _, _, seen_at = free.distances(bb.position, bb.arc_length, bb.tangent)
        # Where the first ray passes through the lengthened arm (a stray ray or two ignored).
        first = np.sort(seen_at)[2] if len(seen_at) > 2 else np.inf
        if first - total >= HIDDEN_RUN:
            return True
    return False


def assess(search: FitSearch, best: Candidate, starts: Iterator[Start], *,
           rays=None) -> FitConfidence:
    """How sure the fit `best` of `search` is; for a partly unseen arm, other explanations
    are sought first (the starts not yet tried, the unseen sections bent otherwise) and added
    to the search. rays: freespace.FreeRays the cameras saw along (None: no camera)."""
    arm, lengths, params = search.problem.arm, search.problem.lengths, search.problem.params
    free = search.free
    out = best.refined
    seen = seen_fractions(out.config, out.unseen)
    may_continue = None
    if lengths is None and free is not None:
        # With a prior too: a fit that stopped at the last seen point although the command
        # runs on (and no camera saw there) is not sure where the tip is.
        may_continue = tip_may_continue(arm, out.config, free)
        if not may_continue and search.problem.prior is None:
            may_continue = _longer_explains(search, out, params)
    if out.unseen:
        # Up to ALTERNATIVES more starts: those not tried yet, then the unseen sections bent
        # otherwise (refined from the fit, so a few iterations do).
        tried = 0
        for start in itertools.islice(starts, ALTERNATIVES // 2):
            search.attempt(start)
            tried += 1
        # TODO(issue 33): "up to ALTERNATIVES" would leave ALTERNATIVES - tried; this
        # leaves ALTERNATIVES after a start not yet tried, one fewer without.
        limit = ALTERNATIVES if tried else ALTERNATIVES - 1
        for alt in _hidden_alternatives(arm, out.config, seen, limit):
            search.attempt(Start(alt, None), prefit=False, max_nfev=params.max_nfev // 3)
    ref = search.best().refined
    ref_tip = arm.tip_frame(ref.config)[1]
    ref_rms = ref.point_rms(params)

    def prior_chi2(o):
        p = o.fun.prior
        if p is None:
            return 0.0
        s, u, v = o.fun.split(o.sol.x)
        return float(np.sum((p.residuals(s, u, v, lengths is None) / p.NOISE) ** 2))

    def plane_cost(o):
        # What the wrap's plane charges (WrapPlane: out of it, against the commanded turn,
        # short of a curled limit): a hidden section bent as Algorithm 1 never bends it
        # explains the points as well, but is no other explanation of the wrap.
        plane = o.fun.plane
        if plane is None:
            return 0.0
        s, u, v = o.fun.split(o.sol.x)
        return soft_l1_cost(plane.residuals(s, u, v, limit=arm.curvature_limit(s)),
                            params.loss_scale)

    plane_slack = soft_l1_cost(params.inlier, params.loss_scale)  # one point off the tube

    equal = [c.refined for c in search.fits if not c.over
             and c.refined.point_rms(params) <= EQUAL_FIT * ref_rms + EQUAL_FIT_MM * 1e-3
             and c.refined.n_free <= ref.n_free + FREE_OK
             and prior_chi2(c.refined) <= prior_chi2(ref) + 4.0
             and plane_cost(c.refined) <= plane_cost(ref) + plane_slack]
    spread = max((float(np.linalg.norm(arm.tip_frame(o.config)[1] - ref_tip)) for o in equal),
                 default=0.0)
    distinct = 1 + sum(float(np.linalg.norm(arm.tip_frame(o.config)[1] - ref_tip))
                       > AMBIGUOUS_TIP for o in equal)
    sigma = _tip_sigma(arm, ref, params.loss_scale)
    n_rays = None if rays is None or free is None else \
        int(violations(arm, ref.config, rays).sum())
    ref_seen = seen_fractions(ref.config, ref.unseen)
    unexplained = float(np.mean(np.abs(ref.residual) > params.inlier))
    return FitConfidence(seen_fraction=tuple(ref_seen), tip_sigma=sigma, tip_spread=spread,
                         n_solutions=distinct, free_space_rays=n_rays,
                         tip_may_continue=may_continue,
                         ambiguous=bool(max(spread, 2 * sigma) > AMBIGUOUS_TIP),
                         partly_unseen=bool(ref.unseen) or bool(may_continue),
                         unexplained=unexplained, poor_fit=unexplained > UNEXPLAINED_MAX)
