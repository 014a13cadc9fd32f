"""Constrained inverse kinematics of the section end points, with Drake MathematicalProgram.

Decision variables per section are (s, u, v) with (u, v) = kappa (cos phi, sin phi): phi is
undefined at kappa = 0, and this parameterisation is smooth there. Limits are a bounding box
on s and the quadratic constraints u^2 + v^2 <= kappa_max^2 and s^2 (u^2 + v^2) <= bend_max^2
(the bend limit). Non-penetration keeps centre-line points at least one radius (less a
tolerance) from the object's real surface, measured by the scene's distance field (Open3D on
the real triangles, never Drake's convex hull).

Our forward kinematics is compiled numpy, not AutoDiff. The "auto" mode (the wrap's) solves
the constrained least-error problem as a sequence of small convex programs (SQP): each is
one MathematicalProgram with the end-point residual and the gap linearised at the current
point (constant matrices from one batched kinematics call and one distance-field call), so
no Python runs inside the solver. The "exact" and "least_squares" modes hand SNOPT the
nonlinear functions themselves, values with Jacobians through InitializeAutoDiff (central
differences of the batched kinematics, distance gradients from the closest surface points);
they are the reference the SQP is tested against.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from functools import cache

import numpy as np
from pydrake.autodiffutils import ExtractGradient, ExtractValue, InitializeAutoDiff
from pydrake.solvers import (
    MathematicalProgram,
    SnoptSolver,
    Solve,
    SolverOptions,
)

from ..checks import GAP, STEP, check_fields, count
from .arm import ArmConfig, ContinuumArm
from .pressing import presses
from .step_program import W_GAP, step_program
from .vertex import free_coordinates

__all__ = ["IKMode", "IKOptions", "IKResult", "bounds", "from_uv", "solve_ik", "to_uv"]


class IKMode(StrEnum):
    """The IK solvers (IKOptions.mode; members equal the configuration's strings)."""

    AUTO = "auto"
    EXACT = "exact"
    LEAST_SQUARES = "least_squares"


@dataclass(frozen=True)
class IKOptions:
    """Args:
        mode: an IKMode's value: "auto" (the least summed |end-point error| within the
            limits and clear of the object, by sequential convex programs: exact when the
            targets are reachable, the least-error point otherwise; ~2 ms), or SNOPT on the
            nonlinear program: "exact" (section ends as equality constraints; ~5 ms warm started) or
            "least_squares" (a slack form that tolerates unreachable targets and reports
            the residual; ~30 ms).
        newton: in "exact" and "auto" modes, first try Newton's method on the square system
            ends(q) = targets (9 equations, 9 unknowns) and keep its root when it passes every
            check below; otherwise, or when it does not converge, the MathematicalProgram
            solves. The root is isolated, so it is the point SNOPT's exact mode finds (tests
            compare the two); Newton finds it in ~0.5 ms. In "auto" mode a root that breaks
            up to three limits is followed by Newton's method on the system that keeps them
            (`_newton_at_limits`: the SQP's answer, ~2 ms against ~8).
        tolerance: largest accepted end-point error, m; a larger one is a failure.
        penetration_tolerance: allowed penetration of the arm surface into the object, m
            (a touching compliant arm overlaps the rigid surface slightly).
        n_collision_points: centre-line points checked against the object.
        one_sided: every section bends towards its base frame's x side (u >= 0), the side
            a wrap bends to (on in WrapParams). Free, a section's curvature could pass
            through zero to the other side, and the S it makes is beyond repair: enclosing
            only curves a section further the way it already bends (measured: 9 of 24
            wraps of a teapot, a toilet roll, a bottle and a banana ended in an S,
            stalled or at their limits).
    """

    mode: IKMode = IKMode.AUTO
    newton: bool = True
    tolerance: float = 1e-2
    penetration_tolerance: float = 1e-3
    n_collision_points: int = 60
    one_sided: bool = False

    def __post_init__(self):
        check_fields(self, tolerance=STEP, penetration_tolerance=GAP,
                     n_collision_points=count(1000))


@dataclass(frozen=True)
class IKResult:
    success: bool
    config: ArmConfig | None
    error: float  # largest end-point distance to its target, m
    message: str
    newton: bool = False  # found by Newton's method, without the MathematicalProgram


def to_uv(config: ArmConfig) -> np.ndarray:
    """(3n,) decision vector [s, u, v] a section."""
    return np.stack([config.s, config.kappa * np.cos(config.phi),
                     config.kappa * np.sin(config.phi)], axis=1).ravel()


def from_uv(x) -> ArmConfig:
    x = np.asarray(x, float).reshape(-1, 3)
    return ArmConfig(x[:, 0], np.hypot(x[:, 1], x[:, 2]), np.arctan2(x[:, 2], x[:, 1]))


def _with_gradient(f, jac, scalar=False):
    """Wrap a float function and its Jacobian for a MathematicalProgram evaluator (costs
    return a scalar, constraints a vector)."""
    def evaluator(x):
        if x.dtype == float:
            y = f(x)
        else:
            value = ExtractValue(x).ravel()
            y = InitializeAutoDiff(np.atleast_1d(f(value)), jac(value) @ ExtractGradient(x)).ravel()
        return y[0] if scalar else y
    return evaluator


class _Kinematics:
    """Section ends and collision points with their Jacobians for a decision vector, from one
    batched forward-kinematics call (central differences), cached for the last vector: a
    solver evaluates costs and constraints at the same point. With n_points = 0, the ends
    alone (Newton's method needs no more, and they cost a twentieth)."""

    def __init__(self, arm: ContinuumArm, n_points: int, h: float = 1e-7):
        self.arm, self.h = arm, h
        self.fractions = _fractions(arm, n_points) if n_points else np.zeros(0)
        self._x = None

    def __call__(self, x):
        x = np.asarray(x, float)
        if self._x is not None and x.shape == self._x.shape and (x == self._x).all():
            return self._out
        d = len(x)
        steps = _difference_steps(self.h, d)
        X = np.concatenate([x[None], x + steps, x - steps]).reshape(2 * d + 1, -1, 3)
        ends, pts = self.arm.batch_points(X[..., 0], np.hypot(X[..., 1], X[..., 2]),
                                          np.arctan2(X[..., 2], X[..., 1]), self.fractions)
        J_ends = ((ends[1:d + 1] - ends[d + 1:]) / (2 * self.h)).reshape(d, -1).T
        J_pts = ((pts[1:d + 1] - pts[d + 1:]) / (2 * self.h)).transpose(1, 2, 0)
        self._x, self._out = x.copy(), (ends[0], J_ends, pts[0], J_pts)
        return self._out


@cache
def _difference_steps(h: float, d: int) -> np.ndarray:
    """h times the (d, d) identity: the central differences' steps (made once, read-only)."""
    steps = h * np.eye(d)
    steps.flags.writeable = False
    return steps


def _fractions(arm, n_points):
    """Where the collision points lie within each section (0 = its start, 1 = its end)."""
    return np.linspace(0.0, 1.0, max(2, int(np.ceil(n_points / arm.n_sections))))


def solve_ik(arm: ContinuumArm, targets, warm_start: ArmConfig, distance_field=None,
             options: IKOptions = IKOptions()) -> IKResult:
    """Find a configuration whose section ends reach `targets` ((n, 3), m).

    Args:
        arm: the arm (limits and base pose).
        targets: desired section end points, one row a section.
        warm_start: the current configuration.
        distance_field: callable (k, 3) points -> signed distance (k,) to the object's real
            surface and its gradient (k, 3) (WrapScene.distance_field), or None for no object.
        options: IK settings.

    Returns:
        IKResult; success is False (with the reason) rather than a wrong configuration.
    """
    if options.newton and options.mode in (IKMode.EXACT, IKMode.AUTO):
        root = _newton(arm, targets, warm_start, distance_field, options)
        if isinstance(root, IKResult):
            return root
        if root is not None and options.mode == IKMode.AUTO:
            found = _newton_at_limits(arm, targets, root, distance_field, options)
            if found is not None:
                return found
    if options.mode == IKMode.AUTO:
        return _sqp(arm, targets, warm_start, distance_field, options)
    return _solve(arm, targets, warm_start, distance_field, options)


def _newton(arm, targets, warm_start, distance_field, options, iterations: int = 12,
            tol: float = 1e-10):
    """Newton's method on ends(q) = targets from the warm start: the result if it converges
    to an accepted configuration; the root (q) if it breaks a limit (`_newton_at_limits` may
    then keep the limits it breaks); else None (the caller then solves the program)."""
    targets = np.asarray(targets, float).reshape(arm.n_sections, 3)
    kin = _Kinematics(arm, 0)
    q = to_uv(warm_start)
    for _ in range(iterations):
        ends, J = kin(q)[:2]
        r = (ends - targets).ravel()
        if np.abs(r).max() < tol:
            break
        try:
            q = q - np.linalg.solve(J, r)
        except np.linalg.LinAlgError:
            return None
    else:
        return None
    if _limits(arm, q, options)[0].max() > 1e-9:
        return q
    return _accepted(arm, q, targets, kin, distance_field, options)


def _limits(arm, q, options):
    """The arm's limits at q as g(q) <= 0, with their gradients: (m,) and (m, 3n). Per
    section: bend s kappa <= bend_max, curvature kappa <= curvature_max, the length's two
    bounds and, one-sided, u >= 0."""
    n = arm.n_sections
    x = q.reshape(n, 3)
    s_min, s_max, kappa_max, bend_max = (a.tolist() for a in arm.section_limits())
    kappa = np.hypot(x[:, 1], x[:, 2]).tolist()
    m = 5 if options.one_sided else 4  # rows a section
    g, G = np.empty(m * n), np.zeros((m * n, 3 * n))
    # Python floats (the same doubles), written into place: Newton asks every iteration.
    for i, ((s, u, v), k) in enumerate(zip(x.tolist(), kappa)):
        ku, kv = (u / k, v / k) if k > 0 else (0.0, 0.0)
        r, c = m * i, 3 * i
        g[r:r + 4] = s * k - bend_max[i], k - kappa_max[i], s - s_max[i], s_min[i] - s
        G[r, c:c + 3] = k, s * ku, s * kv
        G[r + 1, c + 1:c + 3] = ku, kv
        G[r + 2, c], G[r + 3, c] = 1.0, -1.0
        if options.one_sided:
            g[r + 4], G[r + 4, c + 1] = -u, -1.0
    return g, G


# The largest summed miss the shortcut at the limits answers, m: near the root its vertex is
# the SQP's optimum (a wrap's advancing misses by at most ~3 mm); past that another may be
# better (random targets 2-30 % past the bend limit: one of 150 had 35 mm against 26 mm).
_NEWTON_MISS = 5e-3
# The most limits it keeps: in the wraps the tip's bend, often with section 1's u = 0.
_NEWTON_LIMITS = 3


def _newton_at_limits(arm, targets, root, distance_field, options, iterations: int = 12,
                      tol: float = 1e-10) -> IKResult | None:
    """The auto mode's answer (the least summed |end-point error|, _sqp) when Newton's root
    breaks a few limits, by an active-set Newton's method; else None (the program solves).
    With the limits C binding, the L1 optimum is a vertex: every end-point coordinate on its
    target but |C| of them (F, vertex.py), and g_C(q) = 0. Where Newton ends, a limit it
    breaks joins C, one whose multiplier pulls inwards leaves it, and F is chosen again when
    a coordinate off F buys the limits more cheaply (the L1 optimality conditions). The
    summed miss must be at most _NEWTON_MISS; the point must pass every check a root does."""
    targets = np.asarray(targets, float).reshape(arm.n_sections, 3).ravel()
    kin, q = _Kinematics(arm, 0), root.copy()
    g, G = _limits(arm, q, options)
    active, tried = np.flatnonzero(g > 1e-9), set()
    try:
        for _ in range(2 * _NEWTON_LIMITS):
            if not 0 < len(active) <= _NEWTON_LIMITS:
                return None
            ends, J = kin(q)[:2]
            free = free_coordinates(J, ends.ravel() - targets, (g[active], G[active]))
            if free is None or (tuple(active), tuple(free)) in tried:
                return None  # no regular vertex, or one tried before: no progress
            tried.add((tuple(active), tuple(free)))
            for _ in range(iterations):
                ends, J = kin(q)[:2]
                g, G = _limits(arm, q, options)
                F = np.append(np.delete(ends.ravel() - targets, free), g[active])
                if np.abs(F).max() < tol:
                    break
                q = q - np.linalg.solve(np.vstack([np.delete(J, free, axis=0), G[active]]), F)
            else:
                return None
            if np.any(np.delete(g, active) > 1e-9):
                active = np.flatnonzero((g > 1e-9) | np.isin(np.arange(len(g)), active))
                continue
            miss = ends.ravel() - targets
            W = np.linalg.solve(J.T, G[active].T)  # the limits' gradients in end coordinates
            nu = np.linalg.solve(W[free], np.sign(miss[free]))  # minus their multipliers
            if np.max(nu) > 1e-12:  # pulls inwards: the optimum lies inside that limit
                active = np.delete(active, np.argmax(nu))
                continue
            if np.max(np.abs(np.delete(W @ nu, free)), initial=0.0) <= 1.0 + 1e-9:
                break
        else:
            return None
    except np.linalg.LinAlgError:
        return None
    if np.abs(miss[free]).sum() > _NEWTON_MISS:
        return None
    if options.one_sided:  # a kept u = 0 is met to tol either side
        q.reshape(-1, 3)[:, 1] = np.maximum(q.reshape(-1, 3)[:, 1], 0.0)
    return _accepted(arm, q, targets.reshape(-1, 3), kin, distance_field, options)


def _accepted(arm, q, targets, kin, distance_field, options) -> IKResult | None:
    """A Newton point as an IKResult if it is within the limits, clear of the object and
    within the error tolerance, else None."""
    config = from_uv(q)
    if not arm.within_limits(config, tol=1e-9) or (options.one_sided
                                                   and np.any(q.reshape(-1, 3)[:, 1] < 0.0)):
        return None
    if distance_field is not None:
        x = q.reshape(1, -1, 3)
        points = arm.batch_points(x[..., 0], np.hypot(x[..., 1], x[..., 2]),
                                  np.arctan2(x[..., 2], x[..., 1]),
                                  _fractions(arm, options.n_collision_points))[1][0]
        if presses(distance_field, points, radius=arm.radius,
                   tolerance=options.penetration_tolerance):
            return None
    err = float(np.max(np.linalg.norm(kin(q)[0] - targets, axis=1)))
    if err > options.tolerance:
        return None
    return IKResult(True, config, err, "ok", newton=True)


def _solve(arm, targets, warm_start, distance_field, options) -> IKResult:
    targets = np.asarray(targets, float).reshape(arm.n_sections, 3)
    n = arm.n_sections
    prog = MathematicalProgram()
    x = prog.NewContinuousVariables(3 * n, "q")
    lo, hi = bounds(arm, options)
    x0 = np.clip(to_uv(warm_start), lo, hi)
    prog.AddBoundingBoxConstraint(lo, hi, x)
    _, _, kappa_max, bend_max = arm.section_limits()
    for i in range(n):
        s_i, u, v = x[3 * i], x[3 * i + 1], x[3 * i + 2]
        prog.AddConstraint(u * u + v * v <= kappa_max[i] ** 2)
        prog.AddConstraint(s_i * s_i * (u * u + v * v) <= bend_max[i] ** 2)

    kin = _Kinematics(arm, options.n_collision_points)

    def residual(q):
        return (kin(q)[0] - targets).ravel()

    def residual_jac(q):
        return kin(q)[1]

    if options.mode == IKMode.EXACT:
        prog.AddConstraint(_with_gradient(residual, residual_jac), np.zeros(3 * n),
                           np.zeros(3 * n), x)
    else:  # IKMode.LEAST_SQUARES
        # Slack form: ends(q) - targets = e with |e|^2 minimised. SNOPT converges far faster
        # on this than on the squared residual as one nonlinear cost.
        e = prog.NewContinuousVariables(3 * n, "e")
        eye = np.eye(3 * n)
        prog.AddConstraint(
            _with_gradient(lambda qe: residual(qe[:3 * n]) - qe[3 * n:],
                           lambda qe: np.hstack([residual_jac(qe[:3 * n]), -eye])),
            np.zeros(3 * n), np.zeros(3 * n), np.concatenate([x, e]))
        prog.AddQuadraticErrorCost(eye, np.zeros(3 * n), e)
        prog.SetInitialGuess(e, residual(x0))

    if distance_field is not None:
        cache = {}

        def gap_and_gradient(q):
            # The value and the gradient are asked for separately at one point: one
            # distance query serves both.
            if "q" in cache and np.array_equal(q, cache["q"]):
                return cache["out"]
            _, _, pts, J_pts = kin(q)
            d, grad = distance_field(pts)
            out = (d - arm.radius, np.einsum("mi,mij->mj", grad, J_pts))
            cache["q"], cache["out"] = np.array(q, float), out
            return out
        m = len(kin(x0)[2])
        prog.AddConstraint(_with_gradient(lambda q: gap_and_gradient(q)[0],
                                          lambda q: gap_and_gradient(q)[1]),
                           np.full(m, -options.penetration_tolerance), np.full(m, np.inf), x)

    prog.SetInitialGuess(x, x0)
    solver_options = SolverOptions()
    snopt = SnoptSolver().solver_id()
    solver_options.SetOption(snopt, "Major optimality tolerance", 1e-5)
    solver_options.SetOption(snopt, "Major feasibility tolerance", 1e-7)
    result = Solve(prog, solver_options=solver_options)
    q = result.GetSolution(x)
    err = float(np.max(np.linalg.norm(kin(q)[0] - targets, axis=1)))
    if not result.is_success():
        return IKResult(False, None, err, f"No IK found: solver {result.get_solver_id().name()} "
                                          f"reports {result.get_solution_result().name}")
    worst = None
    if distance_field is not None:
        worst = float(np.min(distance_field(kin(q)[2])[0]) - arm.radius)
    return _checked(arm, q, err, worst, options)


def bounds(arm: ContinuumArm, options: IKOptions = IKOptions()):
    """Bounds (lo, hi) of the decision vector [s, u, v] a section (each section's own
    limits)."""
    s_min, s_max, kappa_max, _ = arm.section_limits()
    u_min = np.zeros_like(kappa_max) if options.one_sided else -kappa_max
    lo = np.column_stack([s_min, u_min, -kappa_max]).ravel()
    hi = np.column_stack([s_max, kappa_max, kappa_max]).ravel()
    return lo, hi


def _checked(arm, q, err, worst_gap, options) -> IKResult:
    """The solver's point as an IKResult after the checks every mode shares: end-point error
    within the tolerance, limits, penetration (worst gap, m, or None without an object); the
    limits are then clipped away (a solver meets them only to its own tolerance)."""
    config = from_uv(q)
    if err > options.tolerance:
        return IKResult(False, None, err, f"No IK found: end points miss their targets by "
                                          f"{err * 1000:.1f} mm (tolerance "
                                          f"{options.tolerance * 1000:.1f} mm)")
    if not arm.within_limits(config, tol=1e-6):
        return IKResult(False, None, err, "No IK found: solution violates the arm's limits")
    if worst_gap is not None and worst_gap < -options.penetration_tolerance - 1e-4:
        return IKResult(False, None, err, f"No IK found: arm penetrates the object by "
                                          f"{-worst_gap * 1000:.1f} mm")
    s_ok = np.clip(config.s, *arm.section_limits()[:2])
    clipped = ArmConfig(s_ok, np.clip(config.kappa, 0.0, arm.curvature_limit(s_ok)), config.phi)
    return IKResult(True, clipped, err, "ok")


_SCALE = np.array([0.01, 1.0, 1.0])  # a unit step of (s, u, v): 1 cm, 1 1/m
_MAX_RADIUS = 4.0  # trust region, in unit steps: from kappa = 0 no step passes the bend limit
_W_LIMIT = 1e3  # merit of a radian (or 1/m) beyond the bend (or curvature) limit
_LIMIT_MARGIN = 1e-5  # rad (1/m) kept inside a linearised limit: the checks allow 1e-6


class _SQP:
    """One `_sqp` solve's fixed data (targets, box, scale, the step's program) and its two
    operations: a point's linearisation and merit (`evaluate`), and a step from it (`step`).
    Lengths in mm, steps in units of _SCALE."""

    def __init__(self, arm, targets, distance_field, options):
        self.arm = arm
        self.targets = np.asarray(targets, float).reshape(arm.n_sections, 3)
        self.distance_field = distance_field
        self.scale = np.tile(_SCALE, arm.n_sections)
        self.lo, self.hi = bounds(arm, options)
        self.tol = 1000 * options.penetration_tolerance
        self.kin = _Kinematics(arm, options.n_collision_points)
        self.program = step_program(3 * arm.n_sections)

    def evaluate(self, q) -> dict:
        """At q: the residual r and Jacobian J, collision gaps and gradients G, curvatures
        and the merit."""
        arm, n, scale, tol = self.arm, self.arm.n_sections, self.scale, self.tol
        ends, J, pts, J_pts = self.kin(q)
        st = {"q": q, "r": 1000 * (ends - self.targets).ravel(), "J": 1000 * J * scale,
              "gap": np.full(1, np.inf), "G": np.zeros((1, 3 * n))}
        if self.distance_field is not None:
            d, grad = self.distance_field(pts)
            st["gap"] = 1000 * (d - arm.radius)
            st["G"] = 1000 * np.einsum("mi,mij->mj", grad, J_pts) * scale
        x = q.reshape(n, 3)
        st["kappa"] = np.hypot(x[:, 1], x[:, 2])
        _, _, kappa_max, bend_max = arm.section_limits()
        excess = np.maximum(0.0, x[:, 0] * st["kappa"] - bend_max).sum() + np.maximum(
            0.0, st["kappa"] - kappa_max).sum()
        # 10 um of slack: the distances are float32, and a merit that counted their
        # rounding at an active constraint would reject good steps.
        st["merit"] = (np.abs(st["r"]).sum() + W_GAP * max(0.0, -tol - 0.01 - st["gap"].min())
                       + _W_LIMIT * excess)
        return st

    def step(self, st, radius):
        """The program's step z and its model merit, or (None, message)."""
        arm, n, scale, tol = self.arm, self.arm.n_sections, self.scale, self.tol
        q, gap, G = st["q"], st["gap"], st["G"]
        near = gap - np.abs(G).sum(axis=1) * radius < -tol
        rows, upper = [], []
        x = q.reshape(n, 3)
        _, _, kappa_max, bend_max = arm.section_limits()
        for i in range(n):
            s_i, k = x[i, 0], st["kappa"][i]
            if k < 1e-9:  # no gradient; within a trust region no step reaches a limit
                continue
            for value, grad, limit in ((s_i * k, [k, s_i * x[i, 1] / k, s_i * x[i, 2] / k],
                                        bend_max[i]),
                                       (k, [0.0, x[i, 1] / k, x[i, 2] / k], kappa_max[i])):
                row = np.zeros(3 * n)
                row[3 * i:3 * i + 3] = np.multiply(grad, _SCALE)
                if value + np.abs(row).sum() * radius > limit:
                    rows.append(row)
                    upper.append(limit - value - _LIMIT_MARGIN)
        return self.program.solve(
            st["J"], st["r"], lower=np.maximum((self.lo - q) / scale, -radius),
            upper=np.minimum((self.hi - q) / scale, radius), G=G[near], gap_lower=-tol - gap[near],
            L=np.array(rows).reshape(-1, 3 * n), limit_upper=np.array(upper))


def _sqp(arm, targets, warm_start, distance_field, options, iterations: int = 50) -> IKResult:
    """The least summed |end-point error| within the limits and clear of the object, by
    sequential convex programming with a trust region: exact when the targets are reachable,
    the least-error point otherwise.

    Each iteration solves one convex MathematicalProgram in the scaled step z = (q' - q) /
    scale, everything linearised at q from one batched kinematics call and one distance-field
    call (so no Python runs inside the solver), a linear program: minimise sum |r + J z| +
    w t subject to the box on q' and |z| <= radius; gap_i + G_i z + t >=
    -penetration_tolerance, t >= 0, for every collision point the step could bring to the
    object (t keeps the program feasible from a pressing start, at a price); each section's
    bend s kappa and curvature kappa, linearised, within their limits. Clarabel solves it
    in ~0.3 ms (OSQP when Clarabel fails). A step is kept when the merit (the objective,
    penetration beyond the tolerance, limit excess) falls by at least a tenth of what the
    program predicted; the trust region grows on good steps and shrinks on rejected ones.
    It stops after a small step the program predicted well (the point is then within ~10 um
    of the optimum, at most 25 measured; 2-3 programs a solve in the wraps), or after
    `iterations` with the last kept point. That point is then checked as the SNOPT modes'
    are (`_checked`), with the exact distances.

    Why the summed |error| and not its square: SNOPT's exact mode, which "auto" solved
    before, ends in elastic mode on unreachable targets, at the point of least summed
    constraint violation, and the wraps were tuned on it. It puts the error where it is
    cheapest and leaves the other ends on their targets (the tip on 93 % of the solves);
    least squares spreads it over every end. Measured on the 66 wraps of bench_wrap: same
    status as SNOPT on 65 (least squares: 61), final centre lines within 10 mm on 58 (49).
    """
    sqp = _SQP(arm, targets, distance_field, options)
    n, lo, hi, scale = arm.n_sections, sqp.lo, sqp.hi, sqp.scale
    q0 = np.clip(to_uv(warm_start), lo, hi)
    x0 = q0.reshape(n, 3)  # and within the bend limit, so that z = 0 meets the limit rows
    kappa0 = np.hypot(x0[:, 1], x0[:, 2])
    x0[:, 1:] *= (np.minimum(kappa0, arm.curvature_limit(x0[:, 0]))
                  / np.maximum(kappa0, 1e-300))[:, None]
    st, radius = sqp.evaluate(q0), 1.0
    for _ in range(iterations):
        dz, model = sqp.step(st, radius)
        if dz is None:  # neither solver solved the step's program; model says why
            return IKResult(False, None, float("nan"), model)
        size, predicted = np.max(np.abs(dz)), st["merit"] - model
        if size < 1e-9 or predicted <= 1e-12:
            break
        new = sqp.evaluate(np.clip(st["q"] + dz * scale, lo, hi))  # a solver meets bounds to ~1e-8
        if st["merit"] - new["merit"] >= 0.1 * predicted:
            # A small step the model predicted well: the next ones are far smaller, and
            # this point is within ~10 um of where stopping at |z| < 1e-7 ends (measured).
            converged = size < 3e-3 and st["merit"] - new["merit"] > 0.9 * predicted
            if st["merit"] - new["merit"] > 0.75 * predicted and size > 0.99 * radius:
                radius = min(2.0 * radius, _MAX_RADIUS)
            st = new
            if converged:
                break
        else:
            radius = 0.25 * size
    err = float(np.max(np.linalg.norm(st["r"].reshape(n, 3), axis=1))) / 1000
    worst = float(st["gap"].min()) / 1000 if distance_field is not None else None
    return _checked(arm, st["q"], err, worst, options)
