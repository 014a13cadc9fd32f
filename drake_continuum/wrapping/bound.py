"""The best conformity an arm can reach in a wrap plane: an upper bound on what any wrap by
Algorithm 1 can give there (issue 19: are its conformity goals reachable with this arm?).

The arm lies in the plane (each section bends towards the wrap's side or, with `signed`,
either way: phi 0 or pi), its base may point anywhere in the plane, its lengths and
curvatures keep the arm's limits, it touches the object and its tube nowhere presses more
than `press_depth` into it (Algorithm 1's `WrapParams.press_depth`; the 3-D signed distance
of the real surface, so parts of the object off the plane count) or into itself (an arm
wrapped more than a full turn meets its own first section). Over these
configurations it maximises the conformity measure of `WrapResult`: the fraction of the
centre line, sampled every `spacing` from where the wrapped part starts to the tip, whose
tube lies within `near` of the surface; the tip must turn theta (Algorithm 1's theta stop)
after that start.

Where the wrapped part starts: `WrapResult` starts it at the first contact, and a search
can game that, where Algorithm 1 cannot: pass the object at a few millimetres, curl round
in free air, and touch with the tip alone, a wrapped part of one sample, 100 % near
(with the turning counted from the base, as the theta stop does, it need not even pass
near). Algorithm 1 starts straight, passing the object at 1 mm, and touches before it
turns. So the bound starts the wrapped part where the arm first comes within `near` of the
object (`start="approach"`, the default): after it, every free-air stretch counts against
the wrap. On a wrap that touches where it first comes near (a hugging one) the two starts
agree; `start="contact"` with `turn="from_base"` is the literal, degenerate version.

The search: differential evolution over the 2n + 1 planar parameters (base angle, lengths,
bends), started from random points and the best of coarse grids of straight-then-curving
wraps (`_Search.seeds`), whose objective is the conformity on a fine sampling of the centre
line against a 1 mm grid of the signed distance in the plane, with penetration, missing
turn and missing contact as penalties; Nelder-Mead polishes the best few; the exact
measure (Open3D distances, the `WrapResult` sampling) decides between them. A global
optimum is not proved, so the benchmark runs two seeds and reports how far they differ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.ndimage import map_coordinates
from scipy.optimize import differential_evolution, minimize
from scipy.spatial import ConvexHull
from scipy.stats import qmc
from trimesh.nsphere import minimum_nsphere

from ..kinematics.arm import ArmConfig, ContinuumArm
from ..kinematics.jit import CACHE
from .conformity import NEAR, near_fraction, swept_angle
from .planes import WrapPlane, base_rotation, cross_section, cut_centroid

SELF_APART = 0.06  # m: points this far apart along the arm must not overlap (self-contact)

__all__ = ["BoundParams", "PlanarArm", "Measure", "BoundResult", "best_wrap", "measure",
           "planar_arm", "arm_config"]


@dataclass(frozen=True)
class BoundParams:
    """What the bound allows and how hard it searches.

    Args:
        theta: the tip turns at least this much, rad (Algorithm 1's 270 deg).
        press_depth: deepest the tube may press into the object, m (`WrapParams`' 1 mm).
        near: the conformity measure's gap, m (`conformity.NEAR`).
        contact: a tube this close to the surface touches, m (Drake's hydroelastic contact
            begins within 0.15 mm of the exact tube).
        spacing: the measure's sample spacing, m (`WrapParams`').
        signed: sections may bend away from the wrap's side as well.
        start: where the wrapped part starts: "approach" (the first point within near) or
            "contact" (the first touch, as `WrapResult`; see the module's docstring).
        turn: "after_start" (the turning after the wrapped part's start must reach theta)
            or "from_base" (the tip's turning from the base direction, as the theta stop).
        per_section: centre-line samples a section in the search.
        grid: spacing of the signed-distance grid in the plane, m.
        safety: the search keeps press_depth - safety, for the grid's and the sampling's
            error; the exact measure checks press_depth itself.
        popsize, maxiter, seed: differential evolution's.
        polish: how many of its best distinct members Nelder-Mead polishes.
    """

    theta: float = np.radians(270.0)
    press_depth: float = 1e-3
    near: float = NEAR
    contact: float = 1.5e-4
    spacing: float = 0.005
    signed: bool = False
    start: str = "approach"
    turn: str = "after_start"
    per_section: int = 160
    grid: float = 1e-3
    safety: float = 2e-4
    popsize: int = 20
    maxiter: int = 250
    seed: int = 0
    polish: int = 3


@dataclass(frozen=True)
class PlanarArm:
    """An in-plane configuration.

    Args:
        base_angle: direction of the base's z axis in the plane's (e1, e2) basis, rad.
        s: (n,) section lengths, m.
        bend: (n,) bend angles kappa * s, rad, positive towards the wrap's side.
    """

    base_angle: float
    s: np.ndarray
    bend: np.ndarray


@dataclass(frozen=True)
class Measure:
    """The conformity measure of a configuration.

    Args:
        conformity: fraction of the samples from the wrapped part's start to the tip within
            near (0 when it never comes near).
        from_contact: the same from the first contact, `WrapResult`'s (nan: no contact).
        turn: the turning the constraint measures (after the start, or from the base), rad.
        tip_heading: the tip's turning from the base direction, rad.
        press: deepest penetration of the tube, m (negative: clear everywhere).
        crossing: deepest overlap of the tube with itself (points SELF_APART apart along
            it), m (negative: none).
        start: arc length where the wrapped part starts, m (nan: none).
        touches: whether the tube touches the object (within `contact`).
        samples: (m, 3) the measured centre-line points (start to tip), world.
        wrap_angle: the angle they sweep about the cut's centroid, rad.
    """

    conformity: float
    from_contact: float
    turn: float
    tip_heading: float
    press: float
    crossing: float
    start: float
    touches: bool
    samples: np.ndarray
    wrap_angle: float

    def feasible(self, params: BoundParams, tol: float = 1e-5) -> bool:
        """Touches, presses no deeper than allowed into the object or itself, turns
        theta."""
        return bool(self.touches and max(self.press, self.crossing) <= params.press_depth + tol
                    and self.turn >= params.theta - 1e-9)


@dataclass(frozen=True)
class BoundResult:
    """The best configuration found in one plane.

    Args:
        plane_index: the plane's index.
        arm: the best configuration.
        measure: its exact measure.
        feasible: whether any configuration found is feasible (touches, presses into
            nothing deeper than allowed, turns theta). If none is, `arm` is the one that
            turns furthest among those that press no deeper, else the shallowest.
        evaluations: objective evaluations of the search.
        search_conformity: the search's own (grid) value of the best, for the record.
    """

    plane_index: int
    arm: PlanarArm
    measure: Measure
    feasible: bool
    evaluations: int
    search_conformity: float


def arm_config(arm: ContinuumArm, plane: WrapPlane, planar: PlanarArm):
    """(base rotation, ArmConfig) of the real arm for an in-plane configuration."""
    e1, e2 = plane.basis()
    ray = np.cos(planar.base_angle) * e1 + np.sin(planar.base_angle) * e2
    s = np.asarray(planar.s, float)
    bend = np.asarray(planar.bend, float)
    return base_rotation(plane, ray), ArmConfig(s, np.abs(bend) / s,
                                                np.where(bend < 0, np.pi, 0.0))


def planar_arm(arm: ContinuumArm, plane: WrapPlane, rotation, *, config: ArmConfig):
    """The in-plane configuration nearest a (wrap's) configuration, and how far (m) the
    real centre line lies from it: 0 for a wrap that stayed in its plane."""
    e1, e2 = plane.basis()
    z = np.asarray(rotation)[:, 2]
    planar = PlanarArm(float(np.arctan2(z @ e2, z @ e1)), np.asarray(config.s, float),
                       config.kappa * config.s * np.cos(config.phi))
    R, flat = arm_config(arm, plane, planar)
    a = np.linspace(0.0, float(np.sum(config.s)), 400)
    real = arm.with_base(rotation=rotation).backbone(config, a).position
    mine = arm.with_base(rotation=R).backbone(flat, a).position
    return planar, float(np.max(np.linalg.norm(real - mine, axis=1)))


def _heading_at(planar: PlanarArm, arc) -> np.ndarray:
    """Turning of the tangent from the base direction at arc lengths, rad."""
    ends = np.concatenate([[0.0], np.cumsum(planar.s)])
    i = np.clip(np.searchsorted(ends, arc, side="right") - 1, 0, len(planar.s) - 1)
    before = np.concatenate([[0.0], np.cumsum(planar.bend)])[i]
    return before + planar.bend[i] * (np.asarray(arc) - ends[i]) / planar.s[i]


def measure(scene, plane: WrapPlane, planar: PlanarArm,
            *, params: BoundParams = BoundParams(), step: float = 5e-4) -> Measure:
    """The exact measure of an in-plane configuration: the start, contact and penetration
    on a `step` sampling of the centre line, conformity on WrapResult's samples
    (near_fraction of scene.signed_distance every `spacing` from the start)."""
    arm = scene.arm
    R, config = arm_config(arm, plane, planar)
    posed = arm.with_base(rotation=R)
    total = float(np.sum(planar.s))
    fine = np.linspace(0.0, total, int(np.ceil(total / step)) + 1)
    gap = scene.signed_distance(posed.backbone(config, fine).position) - arm.radius
    tip = float(np.sum(planar.bend))
    touching = np.flatnonzero(gap <= params.contact)
    approach = np.flatnonzero(gap <= params.near)
    coarse = fine[::4]
    pts = posed.backbone(config, coarse).position
    apart = np.abs(coarse[:, None] - coarse[None, :]) >= SELF_APART
    dist = np.linalg.norm(pts[:, None] - pts[None, :], axis=-1)
    crossing = float(2 * arm.radius - np.where(apart, dist, np.inf).min())

    def part(first):
        arc = np.arange(first, total + 1e-12, params.spacing)
        pos = posed.backbone(config, arc).position
        return pos, near_fraction(pos, scene.signed_distance, arm.radius, near=params.near)

    from_contact = part(float(fine[touching[0]]))[1] if len(touching) else float("nan")
    starts = touching if params.start == "contact" else approach
    if not len(starts):
        turn = tip if params.turn == "from_base" else 0.0
        return Measure(0.0, from_contact, turn, tip, float(-gap.min()), crossing,
                       float("nan"), bool(len(touching)), np.zeros((0, 3)), 0.0)
    first = float(fine[starts[0]])
    turn = tip if params.turn == "from_base" else tip - float(_heading_at(planar, first))
    pos, conformity = part(first)
    angle = swept_angle(pos, plane.normal, cut_centroid(scene.object_trimesh, plane))
    return Measure(conformity, from_contact, turn, tip, float(-gap.min()), crossing, first,
                   bool(len(touching)), pos, angle)


class _PlaneField:
    """The object's 3-D signed distance on a grid in the plane, interpolated bilinearly;
    beyond the grid (more than `margin` from anything the tube could touch) it is 1 m."""

    def __init__(self, scene, plane: WrapPlane, spacing: float, *, margin: float):
        radius = scene.arm.radius
        cut = np.concatenate([cross_section(scene.object_trimesh, plane, offset) for offset
                              in np.linspace(-radius - NEAR, radius + NEAR, 9)])
        lo, hi = cut.min(0) - margin, cut.max(0) + margin
        self.lo, self.spacing = lo, spacing
        shape = np.ceil((hi - lo) / spacing).astype(int) + 1
        u = lo[0] + spacing * np.arange(shape[0])
        v = lo[1] + spacing * np.arange(shape[1])
        e1, e2 = plane.basis()
        uu, vv = np.meshgrid(u, v, indexing="ij")
        pts = plane.origin + uu.reshape(-1, 1) * e1 + vv.reshape(-1, 1) * e2
        self.values = scene.signed_distance(pts).reshape(shape)
        self.scene_trimesh = scene.object_trimesh

    def __call__(self, uv) -> np.ndarray:
        """(..., 2) plane coordinates -> (...) signed distance."""
        idx = (uv - self.lo) / self.spacing
        flat = idx.reshape(-1, 2).T
        return map_coordinates(self.values, flat, order=1, mode="constant",
                               cval=1.0).reshape(uv.shape[:-1])


@njit(cache=CACHE)
def _terms_of_one(x, n, d, f, field, lo, spacing, radius, limits, flags):
    """`_Search.terms` of one point, compiled: Nelder-Mead asks for one point at a time, where
    numpy's overhead is most of a vectorised call. limits = (bend_max, curvature_max, near,
    contact); flags = (start "approach", turn "from_base"). A test holds it to `terms`."""
    bend_max, curvature_max, near, contact = limits
    F, M = len(f), n * len(f)
    s, bend = x[1:1 + n], np.empty(n)
    for i in range(n):
        bend[i] = x[1 + n + i] * min(bend_max, curvature_max * s[i])
    before, start, pts = np.zeros(n), np.zeros((n, 2)), np.empty((M, 2))
    gap, turned, w = np.empty(M), np.empty(M), np.empty(M)
    for i in range(n):
        if i > 0:
            before[i] = before[i - 1] + bend[i - 1]
            y = np.pi * (bend[i - 1] / (2 * np.pi))  # np.sinc's arithmetic
            chord = s[i - 1] * (math.sin(y) / y if y != 0.0 else 1.0)
            mid = x[0] + d * before[i - 1] + d * bend[i - 1] / 2
            start[i, 0] = start[i - 1, 0] + chord * math.cos(mid)
            start[i, 1] = start[i - 1, 1] + chord * math.sin(mid)
        for k in range(F):
            m, b = i * F + k, bend[i] * f[k]
            y = np.pi * (b / (2 * np.pi))
            chord = s[i] * f[k] * (math.sin(y) / y if y != 0.0 else 1.0)
            mid = x[0] + d * before[i] + d * b / 2
            pts[m, 0] = start[i, 0] + chord * math.cos(mid)
            pts[m, 1] = start[i, 1] + chord * math.sin(mid)
            u, v = (pts[m, 0] - lo[0]) / spacing, (pts[m, 1] - lo[1]) / spacing
            if 0.0 <= u <= field.shape[0] - 1 and 0.0 <= v <= field.shape[1] - 1:
                a, c = min(int(u), field.shape[0] - 2), min(int(v), field.shape[1] - 2)
                u, v = u - a, v - c  # bilinear, as map_coordinates(order=1)
                value = ((1 - u) * ((1 - v) * field[a, c] + v * field[a, c + 1])
                         + u * ((1 - v) * field[a + 1, c] + v * field[a + 1, c + 1]))
            else:
                value = 1.0  # map_coordinates' mode="constant", cval=1
            gap[m], turned[m], w[m] = value - radius, before[i] + b, s[i] / F
    lowest = gap.min()
    reach = near if flags[0] else contact / 3
    first = np.argmax(gap <= max(reach, lowest + 1e-9))
    total = conformity = soft = 0.0
    for m in range(first, M):
        total += w[m]
        conformity += w[m] * (gap[m] <= near)
        soft += w[m] * math.exp(-max(gap[m] - near, 0.0) / 0.005)
    total, turn = max(total, 1e-12), bend.sum() - (0.0 if flags[1] else turned[first])
    arc = np.cumsum(w) - w / 2
    every = np.array([i * F + k for i in range(n) for k in range(0, F, 10)])
    closest = np.inf
    for a in every:
        for c in every:
            if abs(arc[a] - arc[c]) >= SELF_APART:
                dx, dy = pts[a, 0] - pts[c, 0], pts[a, 1] - pts[c, 1]
                closest = min(closest, math.sqrt(dx * dx + dy * dy))
    crossing = 2 * radius - closest
    return conformity / total, turn, max(-lowest, crossing), lowest, soft / total


class _Search:
    """The vectorised objective of the search over x = (base angle, s_1..n, t_1..n), bend_i
    = t_i * (largest bend of a section s_i long)."""

    def __init__(self, scene, plane: WrapPlane, params: BoundParams):
        self.arm, self.plane, self.params = scene.arm, plane, params
        self.field = _PlaneField(scene, plane, params.grid, margin=0.03)
        cut = cross_section(scene.object_trimesh, plane)
        centre = cut.mean(0)
        self.ref = float(np.arctan2(centre[1], centre[0]))
        self.f = (np.arange(params.per_section) + 0.5) / params.per_section
        self.evaluations = 0
        n = self.arm.n_sections
        t_lo = -1.0 if params.signed else 0.0
        self.bounds = ([(self.ref - np.pi, self.ref + np.pi)]
                       + [(self.arm.section_length_min, self.arm.section_length_max)] * n
                       + [(t_lo, 1.0)] * n)

    def planar(self, x) -> PlanarArm:
        n = self.arm.n_sections
        s = np.asarray(x[1:1 + n], float)
        return PlanarArm(float(x[0]), s, x[1 + n:] * self._largest_bend(s))

    def _largest_bend(self, s):
        return np.minimum(self.arm.bend_max, self.arm.curvature_max * s)

    def terms(self, X):
        """(P, 2n+1) -> (conformity, turn, press into the object or itself, min gap,
        partial-credit conformity) over the population."""
        arm, params, n = self.arm, self.params, self.arm.n_sections
        X = np.atleast_2d(X)
        if len(X) > 1000:  # in pieces: the self-contact test holds (P, m, m) distances
            parts = [self.terms(X[k:k + 1000]) for k in range(0, len(X), 1000)]
            return tuple(np.concatenate(t) for t in zip(*parts))
        self.evaluations += len(X)
        psi, s, t = X[:, 0], X[:, 1:1 + n], X[:, 1 + n:]
        bend = t * self._largest_bend(s)
        d = self.plane.direction
        # Section starts: heading and position, in the plane's (e1, e2) coordinates.
        before = np.concatenate([np.zeros((len(X), 1)), np.cumsum(bend, 1)[:, :-1]], 1)
        heads = psi[:, None] + d * before
        starts = np.zeros((len(X), n, 2))
        for i in range(1, n):  # a loop over sections (3)
            chord = s[:, i - 1] * np.sinc(bend[:, i - 1] / (2 * np.pi))
            mid = heads[:, i - 1] + d * bend[:, i - 1] / 2
            starts[:, i] = starts[:, i - 1] + chord[:, None] * np.stack(
                [np.cos(mid), np.sin(mid)], 1)
        tau = s[:, :, None] * self.f  # (P, n, F)
        b = bend[:, :, None] * self.f  # bend up to each sample
        chord = tau * np.sinc(b / (2 * np.pi))
        mid = heads[:, :, None] + d * b / 2
        pts = starts[:, :, None, :] + chord[..., None] * np.stack([np.cos(mid), np.sin(mid)], -1)
        gap = self.field(pts).reshape(len(X), -1) - arm.radius  # (P, M)
        turned = (before[:, :, None] + b).reshape(len(X), -1)
        w = np.repeat(s / params.per_section, params.per_section, axis=1)
        # The wrapped part's start; a configuration that never comes that close is scored
        # from its closest approach. One that does not touch is pulled into contact by a
        # penalty (below), so that the search sees the hugging arcs that hover a fraction
        # of a millimetre off.
        lowest = gap.min(1)
        reach = params.near if params.start == "approach" else params.contact / 3
        first = np.argmax(gap <= np.maximum(reach, lowest + 1e-9)[:, None], 1)
        after = np.arange(gap.shape[1])[None, :] >= first[:, None]
        near = gap <= params.near
        # Partial credit for a sample beyond near (decaying over 5 mm) guides the search
        # towards the surface where the fraction itself is flat; a sample near scores 1.
        close = np.exp(-np.maximum(gap - params.near, 0.0) / 0.005)
        total = np.maximum((w * after).sum(1), 1e-12)
        conformity = (w * near * after).sum(1) / total
        soft = (w * close * after).sum(1) / total
        tip = bend.sum(1)
        if params.turn == "from_base":
            turn = tip
        else:
            turn = tip - turned[np.arange(len(X)), first]
        # The arm passes through itself where points 6 cm apart along it (a bend of at most
        # 140 deg at the curvature limit: no closer than 4.7 cm when it does not) lie
        # closer than the tube's diameter: every 10th sample (the exact measure checks
        # every 2 mm).
        sub = pts[:, :, ::10].reshape(len(X), -1, 2)
        arc = (np.cumsum(w, 1) - w / 2).reshape(len(X), n, -1)[:, :, ::10].reshape(len(X), -1)
        apart = np.abs(arc[:, :, None] - arc[:, None, :]) >= SELF_APART
        dist = np.linalg.norm(sub[:, :, None] - sub[:, None], axis=-1)
        crossing = 2 * arm.radius - np.where(apart, dist, np.inf).min((1, 2))
        return conformity, turn, np.maximum(-lowest, crossing), lowest, soft

    def seeds(self) -> np.ndarray:
        """Coarse grids of wraps of one shape: the first section straight along a base
        direction to its closest approach to the object (or to where it would enter it),
        the rest bending equally at one curvature, together theta, for every base direction
        that sees the cut (1 deg apart) by every curvature of a geometric grid (1 1/m to
        the limit); and the wraps round circles about the cut's centre (`_circles`). They
        start the search near the hugging arcs, which random starts rarely hit (a bowl's
        9 cm ring: 29 % found without them, 100 % hugged)."""
        arm, params, n = self.arm, self.params, self.arm.n_sections
        cut = cross_section(self.field.scene_trimesh, self.plane)
        angles = np.arctan2(cut[:, 1], cut[:, 0])
        angles = self.ref + np.angle(np.exp(1j * (angles - self.ref)))
        psi = np.arange(angles.min() - 0.2, angles.max() + 0.2, np.radians(1.0))
        ray = np.arange(0.0, arm.section_length_max, 1e-3)
        pts = ray[None, :, None] * np.stack([np.cos(psi), np.sin(psi)], 1)[:, None, :]
        gap = self.field(pts) - arm.radius
        hits = gap <= 0.0
        s1 = np.where(hits.any(1), ray[np.argmax(hits, 1)], ray[np.argmin(gap, 1)])
        s1 = np.clip(s1, arm.section_length_min, arm.section_length_max)
        # 3 % apart: the curvatures whose arc stays within near of a circle of radius
        # rho span near / rho, 5 % at rho = 10 cm (a bowl's rim).
        kappa = np.exp(np.arange(0.0, np.log(arm.curvature_max) + 0.03, 0.03))
        rest = np.clip(params.theta / (n - 1) / kappa, arm.section_length_min,
                       arm.section_length_max)
        P, K = np.meshgrid(np.arange(len(psi)), np.arange(len(kappa)), indexing="ij")
        P, K = P.ravel(), K.ravel()
        X = np.zeros((len(P), 2 * n + 1))
        X[:, 0], X[:, 1] = psi[P], s1[P]
        X[:, 2:1 + n] = rest[K, None]
        X[:, 2 + n:] = np.minimum(1.0, kappa[K, None] * rest[K, None]
                                  / self._largest_bend(rest[K, None]))
        return np.vstack([X, self._circles(cut)])

    def _circles(self, cut) -> np.ndarray:
        """Wraps round circles fitted to the cut: about its centre (mean, box centre) and
        reaching its furthest point, its smallest enclosing circle, and the circles through
        three points of its convex hull 2, 4 and 8 cm apart (the round parts of an outline:
        a bowl's outside seen from the side). Each from the radius that presses as deep as
        allowed outwards to near, 0.5 mm apart: the base direction tangent to the circle
        (on the side the wrap turns towards), the first section to the tangent point, the
        rest on the circle together theta and a degree, or further."""
        arm, params, n = self.arm, self.params, self.arm.n_sections
        circles = [(c, np.linalg.norm(cut - c, axis=1).max())
                   for c in (cut.mean(0), (cut.min(0) + cut.max(0)) / 2)]
        circles.append(minimum_nsphere(cut))
        hull = cut[ConvexHull(cut).vertices]
        ring = np.vstack([hull, hull[:1]])
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(ring, axis=0), axis=1))])
        pts = np.stack([np.interp(np.arange(0.0, arc[-1], 0.01), arc, ring[:, k])
                        for k in (0, 1)], 1)
        for k in (2, 4, 8):
            a, b, c = np.roll(pts, k, 0), pts, np.roll(pts, -k, 0)
            for centre, radius in zip(*_circumcircles(a, b, c)):
                if 1 / arm.curvature_max - arm.radius <= radius <= 0.3:
                    circles.append((centre, radius))
        rows = []
        for centre, radius in circles:
            D = np.linalg.norm(centre)
            reach = radius + arm.radius
            rho = np.arange(reach - params.press_depth + params.safety, reach + params.near,
                            5e-4)
            rho = rho[(rho < D) & (1 / rho <= arm.curvature_max)]
            psi = np.arctan2(centre[1], centre[0]) - self.plane.direction * np.arcsin(rho / D)
            s1 = np.clip(np.sqrt(D ** 2 - rho ** 2), arm.section_length_min,
                         arm.section_length_max)
            # Round the circle by theta and a degree, or further: the wrapped part may
            # start after the tangent point (a bowl's far rim).
            for turn in np.linspace(params.theta + np.radians(1.0),
                                    (n - 1) * arm.bend_max, 3):
                rest = np.clip(turn / (n - 1) * rho, arm.section_length_min,
                               arm.section_length_max)
                t = np.minimum(1.0, rest / rho / self._largest_bend(rest))
                rows.append(np.column_stack([psi, s1] + [rest] * (n - 1)
                                            + [np.zeros_like(rho)] + [t] * (n - 1)))
        return np.vstack(rows)

    def objective(self, X, wall: float = 1e4, short: float = 10.0) -> np.ndarray:
        """To minimise: -conformity, plus penalties; `wall` weighs pressing beyond the
        allowed depth, per m, `short` the turning missing to theta, per rad. With the
        defaults any feasible point beats any infeasible one by far."""
        return self.penalised(self.terms(X), wall, short)

    def one(self, x) -> tuple:
        """`terms` of one point, compiled (`_terms_of_one`), as plain numbers."""
        self.evaluations += 1
        arm, p = self.arm, self.params
        return _terms_of_one(np.ascontiguousarray(x, float), arm.n_sections,
                             float(self.plane.direction), self.f, self.field.values,
                             self.field.lo, self.field.spacing, arm.radius,
                             (arm.bend_max, arm.curvature_max, p.near, p.contact),
                             (p.start == "approach", p.turn == "from_base"))

    def penalised(self, terms, wall: float = 1e4, short: float = 10.0) -> np.ndarray:
        """`objective` of terms already computed."""
        p = self.params
        conformity, turn, press, gap, soft = terms
        deficit = np.maximum(p.theta - turn, 0.0)
        excess = np.maximum(press - (p.press_depth - p.safety), 0.0)
        score = -(conformity + soft) / 2 + 30.0 * np.maximum(gap - p.contact / 3, 0.0)
        return score + short * deficit + wall * excess


def _circumcircles(a, b, c):
    """Centres (k, 2) and radii (k,) of the circles through a[i], b[i], c[i]; collinear
    triples are left out."""
    d = 2 * (a[:, 0] * (b[:, 1] - c[:, 1]) + b[:, 0] * (c[:, 1] - a[:, 1])
             + c[:, 0] * (a[:, 1] - b[:, 1]))
    ok = np.abs(d) > 1e-12
    a, b, c, d = a[ok], b[ok], c[ok], d[ok]
    sa, sb, sc = (a ** 2).sum(1), (b ** 2).sum(1), (c ** 2).sum(1)
    centre = np.stack([sa * (b[:, 1] - c[:, 1]) + sb * (c[:, 1] - a[:, 1])
                       + sc * (a[:, 1] - b[:, 1]),
                       sa * (c[:, 0] - b[:, 0]) + sb * (a[:, 0] - c[:, 0])
                       + sc * (b[:, 0] - a[:, 0])], 1) / d[:, None]
    return centre, np.linalg.norm(a - centre, axis=1)


def best_wrap(scene, plane: WrapPlane, *, params: BoundParams = BoundParams(),
              starts=()) -> BoundResult:
    """The best in-plane configuration of scene's arm in a plane (see the module's
    docstring). `starts`: PlanarArms the search also begins from (none for the bound)."""
    search = _Search(scene, plane, params)

    def x_of(planar: PlanarArm):
        t = np.asarray(planar.bend) / search._largest_bend(np.asarray(planar.s))
        angle = search.ref + np.angle(np.exp(1j * (planar.base_angle - search.ref)))
        return np.concatenate([[angle], planar.s, t])

    lo, hi = np.array(search.bounds).T
    size = params.popsize * len(lo)
    grid = search.seeds()
    # The search feels the limits as soft walls (1 per mm too deep, 1 per rad short of
    # theta), so that it can pass through the slightly infeasible configurations beside the
    # best ones (a bowl's outside hugged round from its far rim turns 262 deg after it comes
    # near); the polish then holds the limits (10 per mm, 10 per rad), and the exact
    # measure decides.
    soft = {"wall": 1e3, "short": 1.0}
    terms = search.terms(grid)
    order = np.argsort(search.penalised(terms, **soft))
    candidates = [grid[np.argmin(search.penalised(terms))]] + list(grid[order[:2]])
    grid = grid[order[:size // 4]]
    random = qmc.scale(qmc.LatinHypercube(len(lo), seed=params.seed).random(size - len(grid)),
                       lo, hi)
    de = differential_evolution(lambda X: search.objective(X.T, **soft), search.bounds,
                                vectorized=True, updating="deferred", maxiter=params.maxiter,
                                seed=params.seed, polish=False, init=np.vstack([grid, random]),
                                tol=0.0, atol=1e-4)
    order = np.argsort(de.population_energies)
    best = [de.population[order[0]]]
    for k in order[1:]:  # the best few distinct members
        if len(best) >= params.polish:
            break
        if min(np.max(np.abs(de.population[k] - c)) for c in best) > 0.05:
            best.append(de.population[k])
    candidates += best + [x_of(p) for p in starts]
    found = []
    options = {"xatol": 1e-6, "fatol": 1e-7, "maxiter": 1200, "adaptive": True}
    for x0 in candidates:
        x1 = minimize(lambda x: float(search.penalised(search.one(x), **soft)),
                      np.clip(x0, lo, hi), method="Nelder-Mead", bounds=search.bounds,
                      options=options).x
        x2 = minimize(lambda x: float(search.penalised(search.one(x))), x1,
                      method="Nelder-Mead", bounds=search.bounds, options=options).x
        for x in (x2, x0):
            planar = search.planar(np.clip(x, lo, hi))
            found.append((planar, measure(scene, plane, planar, params=params),
                          float(search.terms(np.clip(x, lo, hi)[None])[0][0])))

    def key(item):
        m = item[1]
        if m.feasible(params):
            return (2, m.conformity)
        if m.touches and max(m.press, m.crossing) <= params.press_depth + 1e-5:
            return (1, m.turn)  # none reaches theta: the one that turns furthest
        return (0, -max(m.press, m.crossing))
    planar, best, grid_value = max(found, key=key)
    return BoundResult(plane.index, planar, best, best.feasible(params), search.evaluations,
                       grid_value)
