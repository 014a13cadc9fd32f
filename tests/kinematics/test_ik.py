"""Constrained IK of the section end points (ik.py) against known configurations."""

import numpy as np
import pytest
from scipy.optimize import minimize

from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm
from drake_continuum.kinematics.ik import IKOptions, from_uv, solve_ik, to_uv
from drake_continuum.wrapping.planes import enumerate_planes
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import WrapParams, start_configuration
from unchecked import unchecked

KNOWN = ArmConfig([0.20, 0.25, 0.30], [3.0, 8.0, 5.0], [0.3, 1.2, -0.5])
NEAR = ArmConfig([0.22, 0.23, 0.28], [2.5, 7.0, 5.5], [0.5, 1.0, -0.3])


@pytest.fixture(scope="module")
def arm():
    return load_arm()


def ends(arm, config):
    return arm.section_frames(config)[1][1:]


def test_uv_round_trip():
    q = to_uv(KNOWN)
    back = from_uv(q)
    np.testing.assert_allclose(back.s, KNOWN.s)
    np.testing.assert_allclose(back.kappa, KNOWN.kappa)
    np.testing.assert_allclose(back.phi, KNOWN.phi)


@pytest.mark.parametrize("mode,newton", [("exact", True), ("exact", False),
                                         ("least_squares", False), ("auto", True),
                                         ("auto", False)])
def test_recovers_known_configuration(arm, mode, newton):
    """Three end points fix three arcs (each starts tangent to the one before), so the known
    configuration is the only answer, by Newton's method and by SNOPT alike."""
    targets = ends(arm, KNOWN)
    result = solve_ik(arm, targets, NEAR, options=IKOptions(mode=mode, newton=newton))
    assert result.success, result.message
    assert result.message == "ok"
    assert result.error < 1e-5
    np.testing.assert_allclose(ends(arm, result.config), targets, atol=1e-5)
    np.testing.assert_allclose(result.config.s, KNOWN.s, atol=1e-4)
    np.testing.assert_allclose(result.config.kappa, KNOWN.kappa, atol=1e-2)
    np.testing.assert_allclose(np.angle(np.exp(1j * (result.config.phi - KNOWN.phi))), 0.0,
                               atol=1e-3)


def test_recovers_straight_section(arm):
    """kappa = 0 (phi undefined) is reached smoothly through the (u, v) parameterisation."""
    known = ArmConfig([0.2, 0.3, 0.25], [0.0, 6.0, 0.0], [0.0, 0.7, 0.0])
    result = solve_ik(arm, ends(arm, known), NEAR, options=IKOptions(mode="exact"))
    assert result.success, result.message
    np.testing.assert_allclose(ends(arm, result.config), ends(arm, known), atol=1e-5)
    assert result.config.kappa[0] < 1e-3 and result.config.kappa[2] < 1e-3


@pytest.mark.parametrize("mode", ["exact", "least_squares", "auto"])
def test_unreachable_target_is_failure(arm, mode):
    targets = ends(arm, KNOWN) + np.array([2.0, 0.0, 0.0])  # beyond the 1.2 m arm
    result = solve_ik(arm, targets, NEAR, options=IKOptions(mode=mode))
    assert not result.success
    assert result.config is None
    assert result.message.startswith("No IK found")
    if mode != "exact":  # the slack form reaches as close as it can and reports the miss
        assert "miss their targets" in result.message
        assert result.error > 1.0


def _reachable_cases(arm, rng, kappa_min: float, n: int = 20):
    """n random (configuration, warm start near it) pairs: curvatures from kappa_min to 0.8
    of each section's limit, the warm start a few mm, 0.5 1/m and 3 deg off."""
    for _ in range(n):
        s = rng.uniform(0.12, 0.35, 3)
        known = ArmConfig(s, rng.uniform(kappa_min, 0.8, 3) * arm.curvature_limit(s),
                          rng.uniform(-np.pi, np.pi, 3))
        warm = ArmConfig(np.clip(known.s + rng.normal(0, 0.005, 3), 0.1, 0.4),
                         np.clip(known.kappa + rng.normal(0, 0.5, 3), 0.0, None),
                         known.phi + rng.normal(0, 0.05, 3))
        yield known, warm


def test_newton_finds_the_root_snopt_finds(arm):
    """Newton's shortcut and the MathematicalProgram solve the same square system: on random
    reachable targets near random warm starts they agree to well within SNOPT's tolerance."""
    for known, warm in _reachable_cases(arm, np.random.default_rng(3), kappa_min=0.0):
        targets = ends(arm, known)
        by_newton = solve_ik(arm, targets, warm, options=IKOptions(mode="exact", newton=True))
        by_snopt = solve_ik(arm, targets, warm, options=IKOptions(mode="exact", newton=False))
        assert by_newton.success and by_snopt.success
        assert by_newton.error < 1e-9
        np.testing.assert_allclose(by_newton.config.s, by_snopt.config.s, atol=1e-6)
        np.testing.assert_allclose(by_newton.config.kappa, by_snopt.config.kappa, atol=1e-4)
        np.testing.assert_allclose(ends(arm, by_newton.config), ends(arm, by_snopt.config),
                                   atol=1e-6)


def test_newton_root_beyond_a_limit_goes_to_the_program(arm):
    """Targets whose exact root has a section shorter than allowed: Newton's root is refused
    and the program returns a configuration within the limits (or fails), never the root."""
    short = ArmConfig([0.2, 0.25, 0.08], [3.0, 8.0, 5.0], [0.3, 1.2, -0.5])
    assert not arm.within_limits(short)
    for newton in (True, False):
        result = solve_ik(arm, ends(arm, short), NEAR, options=IKOptions(newton=newton))
        if result.success:
            arm.check(result.config, tol=1e-6)


def test_bad_mode(arm):
    with pytest.raises(ValueError, match="IKOptions.mode: must be one of 'auto', 'exact', "
                                         "'least_squares', got 'newton'"):
        solve_ik(arm, ends(arm, KNOWN), NEAR, options=IKOptions(mode="newton"))


def test_result_respects_limits(arm):
    """Targets of a coiled arm (curvature 60 1/m, bend 15 rad a section, far beyond both
    limits) give the closest configuration within every limit."""
    coiled = ArmConfig([0.45, 0.45, 0.3], [60.0, 50.0, 60.0], [0.0, 0.5, 1.0])
    assert not arm.within_limits(coiled)
    result = solve_ik(arm, ends(arm, coiled), NEAR,
                      options=unchecked(IKOptions(mode="least_squares"), tolerance=10.0))
    assert result.success, result.message
    c = result.config
    assert np.all(c.s >= arm.section_length_min - 1e-9)
    assert np.all(c.s <= arm.section_length_max + 1e-9)
    assert np.all(c.kappa >= 0) and np.all(c.kappa <= arm.curvature_max + 1e-9)
    assert np.all(c.kappa * c.s <= arm.bend_max + 1e-6)
    arm.check(c, tol=1e-6)


@pytest.fixture(scope="module")
def mug_start(arm):
    """The straight start of the horizontal wrap of the shipped mug."""
    scene = WrapScene(arm, MODELS_DIR / "mug.obj")
    plane = enumerate_planes(arm.base_position)[0]
    R, start, _ = start_configuration(scene, plane, WrapParams())
    scene.arm = arm.with_base(rotation=R)
    return scene, start


@pytest.mark.parametrize("mode", ["least_squares", "auto"])
def test_no_penetration_with_object(mug_start, mode):
    """Targets of a configuration that curls through the mug: the solution stays outside
    its real surface (dense signed distance along the centre line)."""
    scene, start = mug_start
    arm = scene.arm
    through = ArmConfig(start.s, [0.0, 14.0, 20.0], [0.0, 0.0, 0.0])
    gap = scene.clearance(through, n=400)
    assert gap.min() < -0.01  # the target configuration goes deep into the mug
    options = unchecked(IKOptions(mode=mode), tolerance=1.0)
    result = solve_ik(arm, ends(arm, through), start, scene.distance_field, options)
    assert result.success, result.message
    dense = arm.backbone(result.config, n=600).position
    worst = float(np.min(scene.signed_distance(dense) - arm.radius))
    # The constraint holds at 60 points; between them the tube may sink a little further.
    assert worst > -(options.penetration_tolerance + 1e-3)
    assert result.error > 0.005  # it did not reach into the object


def test_reachable_target_near_object_exact(mug_start):
    """A small step of the clear start configuration is found exactly and stays clear."""
    scene, start = mug_start
    arm = scene.arm
    step = ArmConfig(start.s + 0.003, [0.3, 1.0, 2.0], [np.pi, np.pi, np.pi])  # bends away
    assert scene.clearance(step, n=400).min() > 0
    result = solve_ik(arm, ends(arm, step), start, scene.distance_field,
                      IKOptions(mode="exact"))
    assert result.success, result.message
    np.testing.assert_allclose(ends(arm, result.config), ends(arm, step), atol=1e-5)
    assert scene.clearance(result.config, n=600).min() > -1e-3


def test_one_sided_sections_never_bend_the_other_way(arm):
    """A target the arm reaches only by bending its middle section towards -x: free IK
    finds it; one-sided IK (the wrap's) keeps every section's u >= 0, so it fails or lands
    elsewhere, never on the reverse bend."""
    known = ArmConfig([0.2, 0.3, 0.25], [2.0, 6.0, 1.0], [0.0, np.pi, 0.0])
    free = solve_ik(arm, ends(arm, known), NEAR, options=IKOptions(mode="exact"))
    assert free.success
    np.testing.assert_allclose(ends(arm, free.config), ends(arm, known), atol=1e-5)
    assert free.config.kappa[1] * np.cos(free.config.phi[1]) < -1.0
    sided = solve_ik(arm, ends(arm, known), NEAR, options=IKOptions(one_sided=True))
    if sided.success:
        assert np.all(sided.config.kappa * np.cos(sided.config.phi) >= -1e-9)


def test_sqp_finds_the_root_newton_finds(arm):
    """Reachable targets: the auto mode's SQP (Newton's shortcut off) lands on the root
    Newton's method finds from the same warm start."""
    for known, warm in _reachable_cases(arm, np.random.default_rng(5), kappa_min=0.05):
        targets = ends(arm, known)
        by_newton = solve_ik(arm, targets, warm, options=IKOptions(mode="exact", newton=True))
        by_sqp = solve_ik(arm, targets, warm, options=IKOptions(mode="auto", newton=False))
        assert by_newton.success and by_newton.newton
        assert by_sqp.success and not by_sqp.newton
        assert by_sqp.error < 1e-6
        np.testing.assert_allclose(to_uv(by_sqp.config), to_uv(by_newton.config), atol=1e-4)


def _least_error(arm, targets, warm, field=None, penetration_tolerance=1e-3):
    """A second implementation of the auto mode's problem: the least summed |end-point
    error| (mm) within the limits and, with a distance field, clear of the object at the
    same collision points, by scipy's SLSQP on the slack form ends(q) - targets = p - m,
    p, m >= 0, minimising sum(p + m). Returns the configuration."""
    n, d = arm.n_sections, 3 * arm.n_sections
    fractions = np.linspace(0.0, 1.0, 20)

    def points(v):
        x = v[:d].reshape(1, n, 3)
        ends, pts = arm.batch_points(x[..., 0], np.hypot(x[..., 1], x[..., 2]),
                                     np.arctan2(x[..., 2], x[..., 1]), fractions)
        return ends[0], pts[0]

    def limits(v):
        x = v[:d].reshape(n, 3)
        k2 = x[:, 1] ** 2 + x[:, 2] ** 2
        return np.concatenate([arm.bend_max ** 2 - x[:, 0] ** 2 * k2, arm.curvature_max ** 2 - k2])

    constraints = [{"type": "eq", "fun": lambda v: 1000 * (points(v)[0] - targets).ravel()
                    - v[d:2 * d] + v[2 * d:]}, {"type": "ineq", "fun": limits}]
    if field is not None:
        constraints.append({"type": "ineq", "fun": lambda v: 1000 * (
            field(points(v)[1])[0] - arm.radius + penetration_tolerance)})
    r0 = 1000 * (ends(arm, warm) - targets).ravel()
    v0 = np.concatenate([to_uv(warm), np.maximum(r0, 0.0), np.maximum(-r0, 0.0)])
    bounds = [(arm.section_length_min, arm.section_length_max),
              (-arm.curvature_max, arm.curvature_max),
              (-arm.curvature_max, arm.curvature_max)] * n + [(0.0, None)] * (2 * d)
    result = minimize(lambda v: v[d:].sum(), v0, jac=lambda v: np.r_[np.zeros(d), np.ones(2 * d)],
                      method="SLSQP", bounds=bounds, constraints=constraints,
                      options={"ftol": 1e-12, "maxiter": 1000})
    assert result.success, result.message
    return from_uv(result.x[:d])


def _summed_error(arm, config, targets):
    return float(np.abs(ends(arm, config) - targets).sum())


def test_sqp_meets_a_second_implementation_beyond_the_limits(arm):
    """Targets only reachable past the bend limit (a section bent 1.3 pi): no exact answer;
    the auto mode's point has scipy's least summed error, with the bend limit active."""
    over = ArmConfig([0.2, 0.25, 0.3], [3.0, 1.3 * np.pi / 0.25, 5.0], [0.3, 1.2, -0.5])
    assert not arm.within_limits(over)
    targets = ends(arm, over)
    by_sqp = solve_ik(arm, targets, NEAR, options=unchecked(IKOptions(newton=False), tolerance=1.0))
    assert by_sqp.success
    assert by_sqp.error > 0.01  # a real miss, not a root
    c = by_sqp.config
    assert c.kappa[1] * c.s[1] == pytest.approx(arm.bend_max, abs=1e-4)
    reference = _least_error(arm, targets, NEAR)
    summed = [_summed_error(arm, x, targets) for x in (c, reference)]
    assert summed[0] == pytest.approx(summed[1], rel=1e-4)
    np.testing.assert_allclose(ends(arm, c), ends(arm, reference), atol=2e-5)


def test_newton_at_a_limit_meets_the_sqp_and_a_second_implementation(arm):
    """Random targets just past one section's bend limit (0.5-5 %, as a wrap's advancing
    asks), free and one-sided: the auto mode's shortcut keeps the broken limit (every end
    coordinate on its target but one) and lands where the SQP lands (ends within 0.1 mm; the
    SQP runs to ~10 um of its optimum, the shortcut to 1e-10) with no more summed error,
    and on the first cases where scipy's least summed error lands."""
    rng = np.random.default_rng(0)
    answered = referenced = 0
    for _ in range(40):
        s = rng.uniform(0.12, 0.35, 3)
        kappa = rng.uniform(0.1, 0.8, 3) * arm.curvature_limit(s)
        i = rng.integers(3)
        kappa[i] = rng.uniform(1.005, 1.05) * arm.bend_max / s[i]
        if kappa[i] > arm.curvature_max:
            continue
        one_sided = bool(rng.integers(2))
        phi = rng.uniform(-1.2, 1.2, 3) if one_sided else rng.uniform(-np.pi, np.pi, 3)
        warm = ArmConfig(np.clip(s + rng.normal(0, 0.003, 3), 0.1, 0.4),
                         np.clip(kappa + rng.normal(0, 0.3, 3), 0.0,
                                 0.98 * arm.curvature_limit(s)), phi + rng.normal(0, 0.03, 3))
        targets = ends(arm, ArmConfig(s, kappa, phi))
        fast = solve_ik(arm, targets, warm, options=IKOptions(one_sided=one_sided))
        if not fast.newton:
            continue
        answered += 1
        c = fast.config
        arm.check(c, tol=1e-9)
        assert c.kappa[i] * c.s[i] == pytest.approx(arm.bend_max, abs=1e-9)
        assert np.sum(np.abs(ends(arm, c) - targets) > 1e-9) == 1  # a vertex of the L1 problem
        slow = solve_ik(arm, targets, warm, options=IKOptions(one_sided=one_sided, newton=False))
        others = [slow.config] + ([_least_error(arm, targets, warm)]
                                  if answered <= 3 and not one_sided else [])
        referenced += len(others) - 1
        for other in others:
            assert _summed_error(arm, c, targets) <= _summed_error(arm, other, targets) + 1e-9
            np.testing.assert_allclose(ends(arm, c), ends(arm, other), atol=1e-4)
    assert answered >= 20 and referenced >= 1


def test_newton_at_two_limits_meets_the_sqp_and_a_second_implementation(arm):
    """Random targets just past two sections' bend limits (0.5-5 %): the shortcut keeps both
    (every end coordinate on its target but two, the vertex of the L1 problem with two
    limits binding) and lands where the SQP lands, with no more summed error, and on the
    first cases where scipy's least summed error lands."""
    rng = np.random.default_rng(1)
    answered = referenced = 0
    for _ in range(120):
        s = rng.uniform(0.12, 0.35, 3)
        kappa = rng.uniform(0.1, 0.8, 3) * arm.curvature_limit(s)
        over = rng.choice(3, 2, replace=False)
        kappa[over] = rng.uniform(1.005, 1.05, 2) * arm.bend_max / s[over]
        if np.any(kappa > arm.curvature_max):
            continue
        phi = rng.uniform(-np.pi, np.pi, 3)
        warm = ArmConfig(np.clip(s + rng.normal(0, 0.003, 3), 0.1, 0.4),
                         np.clip(kappa + rng.normal(0, 0.3, 3), 0.0,
                                 0.98 * arm.curvature_limit(s)), phi + rng.normal(0, 0.03, 3))
        targets = ends(arm, ArmConfig(s, kappa, phi))
        fast = solve_ik(arm, targets, warm)
        if not fast.newton or fast.error < 1e-9:
            continue
        c = fast.config
        arm.check(c, tol=1e-9)
        if not np.allclose(c.kappa[over] * c.s[over], arm.bend_max, atol=1e-9):
            continue  # the optimum keeps one of the two limits only
        answered += 1
        assert np.sum(np.abs(ends(arm, c) - targets) > 1e-9) == 2  # a vertex, two limits
        slow = solve_ik(arm, targets, warm, options=IKOptions(newton=False))
        others = [slow.config] + ([_least_error(arm, targets, warm)] if answered <= 2 else [])
        referenced += len(others) - 1
        for other in others:
            assert _summed_error(arm, c, targets) <= _summed_error(arm, other, targets) + 1e-9
            np.testing.assert_allclose(ends(arm, c), ends(arm, other), atol=1e-4)
    assert answered >= 6 and referenced >= 1


def _sphere(centre, radius):
    """The exact signed distance field of a sphere (value, gradient), in the form of
    WrapScene.distance_field."""
    def field(points):
        delta = np.asarray(points, float) - centre
        norm = np.linalg.norm(delta, axis=1)
        return norm - radius, delta / norm[:, None]
    return field


@pytest.mark.parametrize("depth,straighter", [(0.005, 2.0), (0.01, 2.0), (0.02, 3.0)])
def test_sqp_against_a_sphere_meets_a_second_implementation(arm, depth, straighter):
    """Targets of a configuration whose middle section passes `depth` into a sphere, from a
    warm start clear of it (as a wrap's are; section 2 bent `straighter` 1/m less): the auto
    mode keeps every collision point's gap within the penetration tolerance with the
    constraint active, and its point is scipy's, of least summed error. (From a start
    inside the sphere the two can end in different local minima, either side of it.)"""
    known = ArmConfig([0.2, 0.25, 0.3], [3.0, 8.0, 5.0], [0.3, 1.2, -0.5])
    warm = ArmConfig(known.s, known.kappa - [0.0, straighter, 0.0], known.phi)
    points = arm.backbone(known, n=200)
    k = np.argmin(np.abs(points.arc_length - 0.2 - 0.125))  # the middle of section 2
    radius = 0.04  # the sphere's surface lies `depth` inside the tube's, on the bend side
    field = _sphere(points.position[k] + points.normal[k] * (radius + arm.radius - depth),
                    radius)
    targets = ends(arm, known)

    def gap(config):
        pts = arm.batch_points(*(np.atleast_2d(a) for a in (config.s, config.kappa,
                                                              config.phi)),
                               np.linspace(0.0, 1.0, 20))[1][0]
        return field(pts)[0] - arm.radius
    assert gap(warm).min() > 0.0 and gap(known).min() < -depth + 1e-3
    options = unchecked(IKOptions(newton=False), tolerance=1.0)
    by_sqp = solve_ik(arm, targets, warm, field, options)
    assert by_sqp.success
    assert by_sqp.error > 1e-3  # the sphere is in the way
    c = by_sqp.config
    assert gap(c).min() >= -options.penetration_tolerance - 1e-6
    assert gap(c).min() <= -options.penetration_tolerance + 1e-5  # active
    reference = _least_error(arm, targets, warm, field)
    summed = [_summed_error(arm, x, targets) for x in (c, reference)]
    assert summed[0] == pytest.approx(summed[1], rel=1e-4)
    np.testing.assert_allclose(ends(arm, c), ends(arm, reference), atol=2e-5)



@pytest.mark.parametrize("one_sided", [False, True])
def test_limits_meet_their_closed_forms_and_central_differences(arm, one_sided):
    """The limits Newton's method keeps (ik._limits), g(q) <= 0 section by section, equal
    their closed forms (bend s kappa, curvature kappa, the length's bounds, -u one-sided), and
    their gradients equal central differences of g; a straight section's kappa rows have no
    gradient in (u, v)."""
    from drake_continuum.kinematics import ik

    options = IKOptions(one_sided=one_sided)
    s_min, s_max, kappa_max, bend_max = arm.section_limits()
    m = 5 if one_sided else 4
    rng = np.random.default_rng(4)
    for straight in (None, 1):
        q = np.column_stack([rng.uniform(0.1, 0.3, 3), rng.normal(0, 6, 3),
                             rng.normal(0, 6, 3)])
        if straight is not None:
            q[straight, 1:] = 0.0
        g, G = ik._limits(arm, q.ravel(), options)
        kappa = np.hypot(q[:, 1], q[:, 2])
        rows = g.reshape(3, m)
        np.testing.assert_allclose(rows[:, 0], q[:, 0] * kappa - bend_max, atol=1e-12)
        np.testing.assert_allclose(rows[:, 1], kappa - kappa_max, atol=1e-12)
        np.testing.assert_allclose(rows[:, 2], q[:, 0] - s_max, atol=1e-12)
        np.testing.assert_allclose(rows[:, 3], s_min - q[:, 0], atol=1e-12)
        if one_sided:
            np.testing.assert_allclose(rows[:, 4], -q[:, 1], atol=1e-12)
        h = 1e-6
        for c in range(9):
            if straight is not None and c in (3 * straight + 1, 3 * straight + 2):
                column = G[:, c].reshape(3, m)[straight]
                np.testing.assert_array_equal(column[:2], 0.0)  # no direction to bend in
                continue
            step = np.zeros(9)
            step[c] = h
            diff = (ik._limits(arm, q.ravel() + step, options)[0]
                    - ik._limits(arm, q.ravel() - step, options)[0]) / (2 * h)
            np.testing.assert_allclose(G[:, c], diff, atol=1e-6)
