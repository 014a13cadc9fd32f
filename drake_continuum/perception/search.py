"""One fit's search: starts refined by least squares and ranked by one cost (fitting.fit_arm
tries them; confidence.assess adds alternatives to the same search).

A start is first moved onto the points at the arc lengths its ordering gave them (a wide
basin), then refined on nearest points with the problem's prior, and again with the
free-space term when the cameras saw through it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from scipy.optimize import least_squares

from ..kinematics.arm import ArmConfig, ContinuumArm
from .medial import FitParams
from .residuals import (
    FREE_NFEV,
    FREE_OK,
    HOPELESS,
    OVERRUN,
    SHORTEN,
    ConfigPrior,
    Refined,
    Residuals,
    TableTouch,
    WrapPlane,
    soft_l1_cost,
)

if TYPE_CHECKING:
    from .freespace import FreeSpaceTerm

__all__ = ["Candidate", "FitProblem", "FitSearch", "Start", "unseen_intervals"]


@dataclass(frozen=True, eq=False)
class FitProblem:
    """What a fit explains: the arm, its points (M, 3), m, the known section lengths (n,), m,
    or None to fit them too, the fit's parameters, the commanded configuration's prior and
    the commanded wrap plane and the contacts on the table (None: no prior, no plane, no
    contacts)."""

    arm: ContinuumArm
    points: np.ndarray
    lengths: np.ndarray | None
    params: FitParams
    prior: ConfigPrior | None = None
    plane: WrapPlane | None = None
    touch: TableTouch | None = None


class Start(NamedTuple):
    """A configuration to refine from, the arc length (M,), m, the ordering gave each point
    (NaN where it gave none, or None: matched by nearest points alone), and the length the
    start shows seen when more than the ordering's (a coil's), m."""

    config: ArmConfig
    point_sig: np.ndarray | None
    seen: float = 0.0


class Candidate(NamedTuple):
    """A start refined and scored. Candidates rank by `rank()`: first those that do not run
    past the seen length by more than OVERRUN, then by cost, then the start tried first.

    Args:
        over: it runs past the seen length by more than OVERRUN (its tail charged).
        cost: soft-L1 cost of points, free space and prior together (FitSearch.scorer).
        order: the place of its start in the order tried.
        refined: the refinement.
        start: the configuration it started from.
    """

    over: bool
    cost: float
    order: int
    refined: Refined
    start: ArmConfig

    def rank(self) -> tuple:
        return self.over, self.cost, self.order


def unseen_intervals(total: float, arc_length, residual, *,
                     params: FitParams = FitParams()):
    """Arc-length intervals of the backbone with no inlier point near them."""
    grid = np.arange(0.0, total + 1e-9, params.seen_radius / 2)
    a = np.sort(arc_length[np.abs(residual) <= params.inlier])
    if len(a) == 0:
        return ((0.0, total),)
    k = np.clip(np.searchsorted(a, grid), 1, len(a) - 1)
    near = np.minimum(np.abs(a[k] - grid), np.abs(a[k - 1] - grid))
    seen = near <= params.seen_radius
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (~seen).astype(int), [0]])))
    runs = edges.reshape(-1, 2)
    out = []
    for i, j in runs:
        lo, hi = grid[i], min(grid[j - 1], total)
        if hi - lo >= params.min_unseen:
            out.append((float(lo), float(hi)))
    return tuple(out)


def _prefit(problem: FitProblem, x0cfg: ArmConfig, point_sig):
    """(x0, lower bounds, upper bounds, cost): the start moved onto the points at the arc
    lengths the ordering gave them (cost 0 when the ordering gave too few)."""
    arm, points, lengths, params = problem.arm, problem.points, problem.lengths, problem.params
    s_min, s_max, km = arm.section_limits()[:3]
    uv0 = np.concatenate([x0cfg.kappa * np.cos(x0cfg.phi), x0cfg.kappa * np.sin(x0cfg.phi)])
    lo_uv, hi_uv = np.tile(-km, 2), np.tile(km, 2)
    if lengths is None:
        x0 = np.concatenate([np.clip(x0cfg.s, s_min, s_max), uv0])
        lo = np.concatenate([s_min, lo_uv])
        hi = np.concatenate([s_max, hi_uv])
    else:
        x0, lo, hi = uv0, lo_uv, hi_uv
    known = np.isfinite(point_sig)
    if known.sum() >= 10:
        # Correspondences from the ordering first: a wide basin, where nearest-point
        # matching would let a wrong start pull points onto the wrong turn of the wrap.
        fixed = Residuals(arm, points[known], lengths)
        sig_k = point_sig[known]
        pre = least_squares(lambda x: fixed.along(x[None], sig_k)[0], np.clip(x0, lo, hi),
                            jac=lambda x: fixed.along_jac(x, sig_k, lo, hi), bounds=(lo, hi),
                            loss="soft_l1", f_scale=3 * params.loss_scale,
                            max_nfev=params.max_nfev // 2)
        return pre.x, lo, hi, pre.cost
    return x0, lo, hi, 0.0


def _refine(problem: FitProblem, x0, bounds, *, length_cap=np.inf, free=None, max_nfev=None,
            charge_tail=True, restarts=True) -> Refined:
    """Nearest-point refinement from x0 within bounds (lower, upper), with the problem's prior
    and the free-space term when given; charge_tail False lets free lengths run on past the
    last seen point; restarts False skips the free lengths' second solves, for a start that
    has had them already, as does a first solve that leaves the points' soft-L1 RMS over
    HOPELESS."""
    arm, lengths, params = problem.arm, problem.lengths, problem.params
    lo, hi = bounds
    n = arm.n_sections
    fun = Residuals(arm, problem.points, lengths, length_cap=length_cap, free=free,
                     prior=problem.prior, plane=problem.plane, charge_tail=charge_tail,
                     touch=problem.touch)

    def solve(x):
        sol = least_squares(fun, np.clip(x, lo, hi), jac=fun.jac, bounds=(lo, hi),
                            loss="soft_l1", f_scale=params.loss_scale, x_scale="jac",
                            max_nfev=max_nfev or params.max_nfev, ftol=params.tol,
                            xtol=params.tol)
        cfg = fun.config(sol.x)
        near = fun.nearest(cfg)
        res = fun.at(cfg, *near[:3])
        return Refined(sol, cfg, near[0], res,
                        unseen_intervals(float(np.sum(cfg.s)), near[0], res, params=params),
                        sol.nfev, fun, len(near[3]) if free is not None else 0)

    out = solve(x0)
    nfev = out.nfev
    total = float(np.sum(out.config.s))
    # A start that converged this far off the points found another shape of arm: the
    # restarts below move its tip, and cannot make it fit.
    restarts = restarts and out.point_rms(params) <= HOPELESS
    if restarts and lengths is None and charge_tail and out.unseen and \
            out.unseen[-1][1] >= total - params.seen_radius:
        # The arm runs on past its last seen point: a local minimum the length prior could
        # not leave. Restart with the unseen tail cut off, from the distal sections back.
        x1 = out.sol.x.copy()
        cut = out.unseen[-1][1] - out.unseen[-1][0]
        for i in reversed(range(n)):
            take = min(cut, x1[i] - lo[i])
            x1[i] -= take
            cut -= take
        alt = solve(x1)
        nfev += alt.nfev
        if alt.sol.cost < out.sol.cost:
            out = alt
    if restarts and lengths is None:
        # Points round the tip hold the end in a shallow local minimum a few millimetres
        # past it (nearest points switch between the cap and the side): try it shorter.
        x1 = out.sol.x.copy()
        x1[n - 1] = max(x1[n - 1] - SHORTEN, lo[n - 1])
        alt = solve(x1)
        nfev += alt.nfev
        if alt.sol.cost < out.sol.cost:
            out = alt
    out.nfev = nfev
    return out


class FitSearch:
    """Starts of one fit refined in turn and ranked by one cost (fit_arm; confidence.assess
    adds alternatives).

    Invariants: `scorer.length_cap == total + OVERRUN`, and every candidate in `fits` is
    scored by `scorer` as it stands (a start that shows more of the arm seen raises `total`
    and scores them all again); `nfev` counts the residual evaluations of every refinement.
    Every solution is scored by the same cost: points, free space and prior together (with a
    prior, its lengths, not the seen length, rank how far the arm runs on).
    """

    def __init__(self, problem: FitProblem, *, free: FreeSpaceTerm | None = None,
                 total: float = np.inf):
        p = problem
        self.problem = problem
        self.free = free
        self.total = total  # the seen length, m (inf when unknown)
        self.scorer = Residuals(p.arm, p.points, p.lengths, length_cap=total + OVERRUN,
                                 free=free, prior=p.prior, plane=p.plane,
                                 charge_tail=p.prior is None, touch=p.touch)
        self.fits: list[Candidate] = []
        self.nfev = 0

    def best(self) -> Candidate:
        """The best candidate so far (Candidate.rank)."""
        return min(self.fits, key=Candidate.rank)

    def _see(self, seen: float) -> None:
        """Raise the seen length to `seen` and score the candidates again against it."""
        self.total = seen
        self.scorer.length_cap = seen + OVERRUN
        loss = self.problem.params.loss_scale
        self.fits[:] = [c._replace(
            over=c.over and float(np.sum(c.refined.config.s)) > seen + OVERRUN,
            cost=soft_l1_cost(self.scorer(c.refined.sol.x), loss)) for c in self.fits]

    def attempt(self, start: Start, *, prefit: bool = True, max_nfev: int | None = None,
                charge_tail: bool = True) -> Candidate:
        """Refine a start on the points (and prior), add it to `fits` and return it; only a
        solution that the cameras saw through, and that is not HOPELESS, is refined again
        with the free-space term, which costs more an iteration. prefit False skips the
        ordering's prefit; charge_tail False lets the arm run on past the seen length."""
        p, params = self.problem, self.problem.params
        if start.seen > self.total:
            self._see(start.seen)
        x0, lo, hi, _ = _prefit(p, start.config, start.point_sig if prefit
                                else np.full(len(p.points), np.nan))
        cap = self.total + OVERRUN if charge_tail else np.inf
        out = _refine(p, x0, (lo, hi), length_cap=cap, max_nfev=max_nfev,
                      charge_tail=charge_tail)
        self.nfev += out.nfev
        if self.free is not None:
            out.n_free = self.free.count(p.arm.backbone(out.config,
                                                        n=int(np.sum(out.config.s) / 0.003)))
            if out.n_free > FREE_OK and out.point_rms(params) <= HOPELESS:
                # From a solution that has had the restarts: the free-space term moves the
                # unseen parts, the points hold the rest.
                again = _refine(p, out.sol.x, (lo, hi), length_cap=cap, free=self.free,
                                max_nfev=FREE_NFEV, charge_tail=charge_tail, restarts=False)
                self.nfev += again.nfev
                out = again
        over = charge_tail and float(np.sum(out.config.s)) > self.total + OVERRUN
        candidate = Candidate(over, soft_l1_cost(self.scorer(out.sol.x), params.loss_scale),
                              len(self.fits), out, start.config)
        self.fits.append(candidate)
        return candidate
