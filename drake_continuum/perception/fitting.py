"""Fitting the arm's configuration to its points (scipy least_squares on the residuals of
perception.residuals, from the starts of perception.medial).

Starts are tried in turn until one fits well (soft-L1 RMS under GOOD_FIT). With the section
lengths known: the ordering that enters each piece at its nearest point, then the one that
enters it along the walk's direction (a tip curled back beside the gap an object opened
otherwise runs the far piece backwards), then a coil's (medial.loop_config: sections 2 to n
round the ring of points, where every ordering runs both ways round), then the free-length
fit's curvatures. With them free, a start that splits the seen length wrongly converges to a
wrap that runs on along an overlapping turn: three splits of the seen length, the heading
ordering, a coil's, then the first split matched by nearest points alone (when touching
turns join in the radius graph, every ordering cuts across them and its correspondences
mislead); the fit is charged for running more than OVERRUN past the seen length (a coil's
start shows more of it seen: the ring that the ordering folds in two). A tip curled out of
the camera's view stays unobserved: the fit stops where the points stop.

Partly hidden arms (issue 16). With the camera's position, what it saw through is evidence
too (freespace.py): a solution that the cameras saw through is refined again with a term
charging every such ray, so hidden parts go where no camera could see. Several views of one
wrap are segmented one by one and fitted together. A prior (ConfigPrior, the commanded
configuration with its uncertainty) keeps what the points do not decide near the command,
and with free lengths lets the arm run on past its last seen point where no camera could see.
The commanded wrap plane (residuals.WrapPlane) holds a section no point shows in the plane
Algorithm 1 wrapped in, which otherwise turns out of it at no cost; when no start fits well,
the fit is started again with every section bent in that plane to one side, then the other
(_plane_starts). Knowing also which way the wrap turned (WrapPlane.turn) and where it
touched (TableTouch), a partly unseen arm is started once more with its hidden sections bent
as Algorithm 1 bent them (_turned_start): a section under the tabletop, where no camera sees,
otherwise bends either way at one cost, and which way a fit took was chance, with two views
as with one.
Every fit says how sure it is (confidence.py): per section the fraction seen, the tip's
standard deviation from the cost's curvature, and for a partly unseen arm the spread of
other solutions that explain the points equally well (the starts not yet tried and the
unseen sections bent otherwise), flagged ambiguous when their tips lie apart.

"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..kinematics.arm import ArmConfig, ContinuumArm
from .cloud import PointCloudError
from .confidence import UNEXPLAINED_MAX, FitConfidence, assess, seen_fractions, tip_may_continue
from .freespace import FreeSpaceTerm, free_rays, merge_rays
from .medial import FitParams, config_along, loop_config, medial_length, medial_points
from .residuals import (
    FREE_OK,
    GOOD_FIT,
    OVERRUN,
    ConfigPrior,
    TableTouch,
    WrapPlane,
    start_splits,
    table_above,
)
from .search import FitProblem, FitSearch, Start
from .segmentation import SegmentParams, merge_segmentations, segment_arm

__all__ = ["ArmFit", "fit_arm", "fit_cloud"]


@dataclass(frozen=True)
class ArmFit:
    """An arm configuration fitted to the arm's points.

    Args:
        config: the fitted configuration.
        residual: (M,) signed distance of each point from the fitted tube surface, m.
        arc_length: (M,) arc length of each point's nearest backbone point, m.
        unseen: ((start, end), ...) arc-length intervals with no point on them, m.
        lengths_known: whether the section lengths were given.
        n_points: points fitted; nfev: residual evaluations; time_s: wall time, s.
        initial: the configuration the refinement started from.
        confidence: how sure the fit is (None when FitParams.assess is off).
    """

    config: ArmConfig
    residual: np.ndarray
    arc_length: np.ndarray
    unseen: tuple
    lengths_known: bool
    n_points: int
    nfev: int
    time_s: float
    initial: ArmConfig
    tip: np.ndarray = field(default_factory=lambda: np.zeros(3))
    confidence: FitConfidence | None = None

    def stats(self, inlier: float = 0.005) -> dict:
        a = np.abs(self.residual)
        return {"n_points": int(self.n_points), "mean_abs_mm": 1e3 * float(a.mean()),
                "median_abs_mm": 1e3 * float(np.median(a)),
                "rms_mm": 1e3 * float(np.sqrt((a ** 2).mean())),
                "p95_abs_mm": 1e3 * float(np.percentile(a, 95)), "max_abs_mm": 1e3 * float(a.max()),
                "inlier_fraction": float((a <= inlier).mean())}

    def unseen_sections(self) -> list[dict]:
        starts = np.concatenate([[0.0], np.cumsum(self.config.s)])
        out = []
        for a, b in self.unseen:
            secs = [i + 1 for i in range(self.config.n_sections)
                    if a < starts[i + 1] and b > starts[i]]
            out.append({"from_m": float(a), "to_m": float(b), "sections": secs})
        return out

    def to_dict(self) -> dict:
        return {"config": self.config.to_dict(), "tip": self.tip.tolist(),
                "lengths_known": self.lengths_known, "residual": self.stats(),
                "unseen": self.unseen_sections(), "nfev": int(self.nfev),
                "time_s": float(self.time_s), "total_length_m": float(np.sum(self.config.s)),
                **({"confidence": self.confidence.to_dict()} if self.confidence else {})}


def _known_length_starts(problem: FitProblem):
    """Starts with the section lengths known, made as they are tried: from the ordering that
    enters each piece at its nearest point, then from the one that enters it along the
    walk's direction (a tip curled back beside the gap an object opened makes the nearest
    point of the piece beyond its far end: the first ordering runs that piece backwards)."""
    arm, points, lengths, params = problem.arm, problem.points, problem.lengths, problem.params
    for heading in (False, True):
        medial = medial_points(arm, points, params=params, heading=heading)
        yield Start(config_along(arm, points, medial, lengths=lengths, params=params), medial[2])
    # A coil (sections 2 and 3 round a small object, a closed loop): both orderings run
    # both ways round the ring; a start made for it, matched by nearest points alone.
    loop = loop_config(arm, points, medial, lengths=lengths, params=params)
    if loop is not None:
        yield Start(loop[0], np.full(len(points), np.nan))
    # Last, when none fits well (a turn of the wrap touching another joins them in the
    # radius graph, and both orderings cut across): the curvatures of the free-length fit,
    # whose several splits of the seen length search more widely, on the known lengths. It
    # has converged on nearest-point matches already, so it skips the ordering's prefit.
    # Its solutions rank by cost among those no longer than the known arm (by OVERRUN): the
    # seen length it otherwise holds them to is short wherever a section is hidden, and the
    # one solution within it can be the worst.
    free, _ = _searched(replace(problem, lengths=None, prior=None,
                                params=replace(params, assess=False)), None, None)
    total = float(np.sum(lengths)) + OVERRUN
    fits = sorted(free.fits, key=lambda c: (np.sum(c.refined.config.s) > total, c.cost,
                                            c.order))
    for c in [fits[0]] + ([free.best()] if free.best() is not fits[0] else []):
        cfg = c.refined.config
        yield Start(ArmConfig(lengths, np.minimum(cfg.kappa, arm.curvature_limit(lengths)),
                              cfg.phi), np.full(len(points), np.nan))


def _free_length_starts(problem: FitProblem, medial, total: float):
    """Starts with free section lengths, made as they are tried: several splits of the seen
    length (a wrong split converges to a wrap that runs on along an overlapping turn, a
    local minimum the others do not share), then the ordering that enters each piece along
    the walk's direction."""
    arm, points, params = problem.arm, problem.points, problem.params
    s_min, s_max = arm.section_limits()[:2]
    splits = np.clip(total * start_splits(arm.n_sections), s_min, s_max)
    for s in splits:
        yield Start(config_along(arm, points, medial, lengths=s, params=params), medial[2])
    aligned = medial_points(arm, points, params=params, heading=True)
    s = np.clip(np.full(arm.n_sections, medial_length(arm, aligned, params) / arm.n_sections),
                s_min, s_max)
    yield Start(config_along(arm, points, aligned, lengths=s, params=params), aligned[2])
    # A coil (sections 2 and 3 round a small object, a closed loop): every ordering runs
    # both ways round the ring; a start made for it, matched by nearest points alone.
    loop = loop_config(arm, points, medial, lengths=None, params=params)
    if loop is not None:  # with the length seen round the ring, which the ordering folded
        yield Start(loop[0], np.full(len(points), np.nan), loop[1])
    # Last, when no ordering fits (a turn touching another joins them in the radius graph,
    # and both orderings cut across): the first start without the ordering's prefit, whose
    # correspondences are then wrong; nearest-point matching alone from the medial arcs.
    yield Start(config_along(arm, points, medial, lengths=splits[0], params=params),
                np.full(len(points), np.nan))


def _starts(problem: FitProblem, initial: ArmConfig | None):
    """(starts, seen length, m): the Starts to try in turn, made as they are tried (the
    command first when there is a prior), and the length the points show seen (inf unless
    free lengths start from the medial points)."""
    arm, points, lengths, params, prior = (problem.arm, problem.points, problem.lengths,
                                           problem.params, problem.prior)
    total = np.inf
    if initial is not None:
        starts = iter([Start(initial, np.full(len(points), np.nan))])
    elif lengths is not None:
        starts = _known_length_starts(problem)
    else:
        medial = medial_points(arm, points, params=params)
        total = medial_length(arm, medial, params)
        starts = _free_length_starts(problem, medial, total)
    if prior is not None and initial is None:
        # The command first: on a partly hidden arm it is the start nearest the truth.
        c = prior.config
        s0 = c.s if lengths is None else lengths
        first = ArmConfig(s0, np.minimum(c.kappa, arm.curvature_limit(s0)), c.phi)
        starts = itertools.chain([Start(first, np.full(len(points), np.nan))], starts)
    return starts, total


def _searched(problem: FitProblem, initial: ArmConfig | None, free):
    """(FitSearch, the starts not yet tried): starts tried in turn until one fits well;
    otherwise the best fit wins, preferring any that does not run past the seen length by
    more than OVERRUN."""
    starts, total = _starts(problem, initial)
    search = FitSearch(problem, free=free, total=total)
    for start in starts:
        if _fits_well(search.attempt(start), problem.params):
            break  # a start that fits this well is not the wrong turn of a wrap
    return search, starts


def _fits_well(candidate, params: FitParams) -> bool:
    """Whether a candidate fits well enough that no later start is tried."""
    return not candidate.over and candidate.refined.point_rms(params) < GOOD_FIT and \
        candidate.refined.n_free <= FREE_OK


def _plane_starts(problem: FitProblem, config: ArmConfig):
    """Starts with every section bent in the wrap's plane to one side, then the other, with
    the curvatures of `config`, then with its first section straight. Algorithm 1 bends
    every section towards the object in its plane; the orderings' starts are built section
    by section, and a first section bent the wrong way sends the rest the other way round, a
    minimum that every ordering can fall into (the points it leaves out seen through)."""
    arm = problem.arm
    n = problem.plane.in_base(arm).normal
    across = float(np.arctan2(n[0], -n[1]))  # the bend in the plane, about its normal
    for kappa in (config.kappa, np.r_[0.0, config.kappa[1:]]):
        for side in (0.0, np.pi):
            yield Start(ArmConfig(config.s, np.minimum(kappa, arm.curvature_limit(config.s)),
                                  np.full(arm.n_sections, across + side)), None)


def _in_the_plane(search: FitSearch) -> None:
    """The wrap plane's starts added to `search`: when no start fits well, every section
    bent in the plane to one side, then the other (_plane_starts); and when part of the arm
    is unseen and the wrap's turn is known, the hidden sections bent as Algorithm 1 bent
    them (_turned_start). The orderings' starts leave a hidden section bent whichever way
    the first refinement left it, at no cost from the points; the cost, the plane's prior in
    it, ranks the turned start with the rest."""
    problem, params = search.problem, search.problem.params
    if not _fits_well(search.best(), params):
        for start in list(_plane_starts(problem, search.best().refined.config)):
            if _fits_well(search.attempt(start, prefit=False), params):
                break
    if problem.plane.turn and search.best().refined.unseen:
        turned = _turned_start(problem, search.best().refined)
        if turned is not None:
            search.attempt(turned, prefit=False)


def _turned_start(problem: FitProblem, refined) -> Start | None:
    """A start from the fit `refined` with each section that is mostly unseen bent in the
    wrap's plane the commanded way (WrapPlane.turn): to its bend limit when curled, else by
    the curvature of the section before it (a hidden section that touched the object goes
    on round it), None when no section is mostly unseen."""
    arm, config = problem.arm, refined.config
    hidden = np.flatnonzero(seen_fractions(config, refined.unseen) < 0.5)
    if len(hidden) == 0:
        return None
    plane = problem.plane.in_base(arm)
    limit = arm.curvature_limit(config.s)
    u, v = config.kappa * np.cos(config.phi), config.kappa * np.sin(config.phi)
    along = np.maximum(plane.turning(u, v), 0.0)
    for i in hidden:
        along[i] = limit[i] if i in plane.curled else \
            max(along[i], along[i - 1] if i > 0 else 0.0)
    bu, bv = plane.bent(np.minimum(along, limit))
    u, v = np.where(np.isin(np.arange(arm.n_sections), hidden), bu, u), \
        np.where(np.isin(np.arange(arm.n_sections), hidden), bv, v)
    return Start(ArmConfig(config.s, np.minimum(np.hypot(u, v), limit), np.arctan2(v, u)),
                 None)


def fit_arm(arm: ContinuumArm, points, lengths=None, params: FitParams = FitParams(),
            initial: ArmConfig | None = None, rays=None,
            prior: ConfigPrior | None = None, fallback=None,
            plane: WrapPlane | None = None, touch: TableTouch | None = None) -> ArmFit:
    """Fit every section's (s, kappa, phi) to the arm's points (see the module docstring).

    Args:
        lengths: (n,) known section lengths, m, or None to fit them too.
        initial: a starting configuration (default: from the medial points).
        rays: freespace.FreeRays the cameras saw along (default: none, no free-space term).
        prior: the commanded configuration with its uncertainty (default: none).
        fallback: a function giving one more start, tried when no start explains the points
            (all but UNEXPLAINED_MAX of them): several views' merged points, started from the
            first view's own fit (default: none).
        plane: the plane the wrap was commanded in, which holds sections the points do not
            show (residuals.WrapPlane; default: none, such a section bends any way).
        touch: the contacts' arc lengths and the table, which hold a hidden section that
            touched no lower than the table (residuals.TableTouch; default: none).
    """
    t0 = time.perf_counter()
    points = np.asarray(points, float)
    if len(points) < 10:
        raise PointCloudError(f"only {len(points)} arm points; at least 10 are needed to fit")
    if lengths is not None:
        lengths = np.asarray(lengths, float).reshape(-1)
        if len(lengths) != arm.n_sections:
            raise PointCloudError(f"{len(lengths)} section lengths given; the arm has "
                                  f"{arm.n_sections} sections")
    if prior is not None and prior.config.n_sections != arm.n_sections:
        raise PointCloudError(f"the prior has {prior.config.n_sections} sections; the arm has "
                              f"{arm.n_sections}")
    free = FreeSpaceTerm(arm, rays) if rays is not None and len(rays) else None
    problem = FitProblem(arm, points, lengths, params, prior, plane, touch)
    search, starts = _searched(problem, initial, free)
    if plane is not None and initial is None:
        _in_the_plane(search)
    best = search.best()
    if fallback is not None and initial is None and \
            _unexplained_points(best.refined.residual, params) > UNEXPLAINED_MAX:
        # Merged views can join turns of the wrap that one view keeps apart, and no ordering
        # of them starts the fit well: start from the first view's own fit, and keep that
        # if it leaves fewer points unexplained. Assessed once, the fit that is kept (a
        # refit from the converged solution: a few iterations).
        quick = replace(params, assess=False)
        again = fit_arm(arm, points, lengths, quick, initial=fallback(), rays=rays, prior=prior,
                        plane=plane, touch=touch)
        if _unexplained_points(again.residual, params) < \
                _unexplained_points(best.refined.residual, params):
            if params.assess:
                again = fit_arm(arm, points, lengths, params, initial=again.config, rays=rays,
                                prior=prior, plane=plane, touch=touch)
            return replace(again, nfev=search.nfev + again.nfev,
                           time_s=time.perf_counter() - t0)
    if prior is not None and lengths is None and initial is None:
        # The command runs on well past the last seen point, and no camera could see there
        # (or none was given): let the prior's lengths carry the arm on unseen.
        short = np.sum(prior.config.s) - np.sum(best.refined.config.s)
        if short > 2 * prior.sigma_s * np.sqrt(arm.n_sections) and \
                (free is None or tip_may_continue(arm, best.refined.config, free)):
            c = prior.config
            search.attempt(Start(ArmConfig(c.s, np.minimum(c.kappa, arm.curvature_limit(c.s)),
                                           c.phi), None), prefit=False, charge_tail=False)
            best = search.best()
    confidence = None
    if params.assess:
        confidence = assess(search, best, starts, rays=rays)
        best = search.best()  # the alternatives may have found a better one
    out = best.refined
    return ArmFit(config=out.config, residual=out.residual, arc_length=out.arc_length,
                  unseen=out.unseen, lengths_known=lengths is not None, n_points=len(points),
                  nfev=search.nfev, time_s=time.perf_counter() - t0, initial=best.start,
                  tip=arm.tip_frame(out.config)[1], confidence=confidence)


def fit_cloud(cloud, arm: ContinuumArm, lengths=None,
              segment: SegmentParams = SegmentParams(), params: FitParams = FitParams(),
              eye=None, prior: ConfigPrior | None = None, plane: WrapPlane | None = None,
              touches=None):
    """Segment then fit: (Segmentation, ArmFit).

    Args:
        cloud: a Cloud, or several Clouds of the same wrap from different cameras.
        eye: the camera position (3,), or one a cloud: free space is evidence only when it
            is known (default: none).
        prior: the commanded configuration with its uncertainty (default: none).
        plane: the plane the wrap was commanded in (default: none; fit_arm).
        touches: the arc lengths of the wrap's contacts (the tactile skin's), held no lower
            than the table the segmentation found (TableTouch; default: none).
    """
    from threadpoolctl import threadpool_limits

    clouds = list(cloud) if isinstance(cloud, (list, tuple)) else [cloud]
    eyes = [None] * len(clouds) if eye is None else \
        ([eye] if np.ndim(eye) == 1 else list(eye))
    if len(eyes) != len(clouds):
        raise PointCloudError(f"{len(clouds)} clouds but {len(eyes)} camera positions")
    segs = [segment_arm(c, arm, segment) for c in clouds]
    seg = segs[0] if len(segs) == 1 else merge_segmentations(segs, segment.voxel)
    views = None
    if all(e is not None for e in eyes):
        views = [free_rays(c.points, e, arm_points=s.points) for c, e, s in zip(clouds, eyes, segs)]
    rays = None if views is None else merge_rays(views)
    touch = None
    if touches is not None and len(touches) and seg.table_plane is not None:
        touch = TableTouch(np.asarray(touches, float), table_above(seg.table_plane, arm))

    def first_view():
        """The first view's own fit (a start for the merged views)."""
        return fit_arm(arm, segs[0].points, lengths, replace(params, assess=False),
                       rays=None if views is None else views[0], prior=prior,
                       plane=plane, touch=touch).config

    try:
        # One BLAS thread: the Jacobians are thin (points x 9), and threads fighting over
        # them cost ten times the work on a busy machine.
        with threadpool_limits(limits=1):
            fit = fit_arm(arm, seg.points, lengths, params, rays=rays, prior=prior,
                          fallback=first_view if len(segs) > 1 else None, plane=plane,
                          touch=touch)
    except PointCloudError as e:
        raise PointCloudError(f"{', '.join(c.source for c in clouds)}: {e}") from None
    return seg, fit


def _unexplained_points(residual, params: FitParams) -> float:
    """Fraction of the points farther than params.inlier from the fitted tube."""
    return float(np.mean(np.abs(residual) > params.inlier))


