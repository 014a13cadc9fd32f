"""The fit's cost, batched over configurations: against ContinuumArm.backbone (a second
implementation of the centre line) and against scipy's central differences (the Jacobian)."""

import numpy as np
import pytest
from scipy.optimize._numdiff import approx_derivative

from drake_continuum.kinematics.arm import ArmConfig, load_arm
from drake_continuum.perception import freespace as fs
from drake_continuum.perception.residuals import (
    ConfigPrior,
    Residuals,
    centre_line,
    centre_lines,
)

ARM = load_arm()
CONFIGS = [ArmConfig([0.15, 0.20, 0.18], [2.0, 9.0, 14.0], [1.3, 1.4, 1.6]),
           ArmConfig([0.12, 0.12, 0.12], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]),
           ArmConfig([0.25, 0.10, 0.22], [5.0, 0.0, 12.0], [-2.0, 0.7, 3.0])]


def test_centre_lines_match_the_arms_backbone_for_every_configuration_of_a_batch():
    sigma = np.concatenate([np.linspace(0.0, 0.45, 97), [0.12, 0.15, 0.35, 0.24, 0.57]])
    s = np.array([c.s for c in CONFIGS])
    pos, tan = centre_lines(ARM, s, np.array([c.kappa for c in CONFIGS]),
                            np.array([c.phi for c in CONFIGS]), sigma)
    assert pos.shape == tan.shape == (3, len(sigma), 3)
    for k, cfg in enumerate(CONFIGS):
        inside = np.minimum(sigma, np.sum(cfg.s))  # past the tip: the tip (clipped)
        bb = ARM.backbone(cfg, arc_length=inside)
        assert pos[k] == pytest.approx(bb.position, abs=1e-12)
        assert tan[k] == pytest.approx(bb.tangent, abs=1e-12)
        one = centre_line(ARM, cfg, sigma)
        assert one[0] == pytest.approx(pos[k], abs=1e-15)
    # Arc lengths a configuration: each row its own.
    per = np.stack([sigma, sigma[::-1], sigma / 2])
    pos2, _ = centre_lines(ARM, s, np.array([c.kappa for c in CONFIGS]),
                           np.array([c.phi for c in CONFIGS]), per)
    for k, cfg in enumerate(CONFIGS):
        bb = ARM.backbone(cfg, arc_length=np.minimum(per[k], np.sum(cfg.s)))
        assert pos2[k] == pytest.approx(bb.position, abs=1e-12)


@pytest.mark.parametrize("lengths_known", [False, True])
def test_batched_jacobian_matches_central_differences_with_free_space_and_prior(lengths_known):
    """The Jacobian (forward differences of the batched cost, nearest arc lengths and rays
    held) against scipy's differences of the cost one configuration at a time, with
    every term on: points (caps at both ends), free lengths' tail, bend excess, free space,
    prior."""
    cfg = CONFIGS[0]
    rng = np.random.default_rng(3)
    total = float(np.sum(cfg.s))
    sig = rng.uniform(-0.01, total + 0.01, 400)
    bb = ARM.backbone(cfg, arc_length=np.clip(sig, 0, total))
    pts = bb.position + (ARM.radius + rng.normal(0, 0.002, len(sig)))[:, None] * bb.normal
    pts[sig > total] += 0.01 * bb.tangent[sig > total]
    eye = np.array([0.3, -0.5, 0.85])
    # Rays to points just behind the arm's far side (so some pass through a moved arm).
    target = bb.position[::4] + 0.05 * (bb.position[::4] - eye) / np.linalg.norm(
        bb.position[::4] - eye, axis=1)[:, None]
    rays = fs.free_rays(target, eye)
    term = fs.FreeSpaceTerm(ARM, rays)
    prior = ConfigPrior(ArmConfig(cfg.s + 0.01, cfg.kappa + 1.0, cfg.phi - 0.1))
    lengths = cfg.s if lengths_known else None
    f = Residuals(ARM, pts, lengths, free=term, prior=prior)
    uv = np.concatenate([cfg.kappa * np.cos(cfg.phi) + 0.3, cfg.kappa * np.sin(cfg.phi) - 0.2])
    x = uv if lengths_known else np.concatenate([cfg.s - 0.004, uv])
    near = f.nearest(f.config(x))
    assert len(near[3]) > 0  # rays pass through the moved arm: the term is exercised
    J = f.jac(x)
    # scipy's forward differences, one configuration an evaluation, the same steps.
    ref = approx_derivative(lambda y: f.full(y, near), x, method="2-point",
                            abs_step=1e-6 * np.maximum(1.0, np.abs(x)))
    assert J.shape == ref.shape
    assert J == pytest.approx(ref, rel=1e-6, abs=1e-9 * np.abs(ref).max())
    # Central differences agree but at kinks (a ray's end, a section boundary).
    central = approx_derivative(lambda y: f.full(y, near), x, method="3-point")
    assert np.mean(np.isclose(J, central, atol=1e-4 * np.abs(central).max())) > 0.99
    # The batch is the single evaluation, row by row.
    X = np.stack([x, x * 1.01, x + 0.001])
    F = f.full_batch(X, near)
    for k in range(3):
        assert F[k] == pytest.approx(f.full(X[k], near), abs=1e-15)


def test_a_few_points_past_the_tip_do_not_let_free_lengths_run_on():
    """Flying pixels behind the tip's edge lie along the arm's continuation: up to
    LAST_STRAYS of them there do not extend the seen length, so the tail charge of an arm
    10 mm longer is the closed form TIP_WEIGHT (10 mm - TIP_SLACK - the last ring's gap);
    one more point there does extend it."""
    from drake_continuum.perception.residuals import LAST_STRAYS, TIP_SLACK, TIP_WEIGHT

    cfg = CONFIGS[0]
    total = float(np.sum(cfg.s))
    sigma = np.arange(0.0, total + 1e-9, 0.002)  # the last ring at the tip itself
    bb = ARM.backbone(cfg, arc_length=sigma)
    ring = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    pts = (bb.position[:, None] + ARM.radius * (
        np.cos(ring)[None, :, None] * bb.normal[:, None]
        + np.sin(ring)[None, :, None] * bb.binormal[:, None])).reshape(-1, 3)
    longer = ArmConfig(cfg.s + np.array([0, 0, 0.010]), cfg.kappa, cfg.phi)
    ext = ARM.backbone(longer, arc_length=np.full(LAST_STRAYS + 1, total + 0.008))
    strays = ext.position + ARM.radius * ext.normal  # on the longer arm's surface, 8 mm on

    def tail(points):
        f = Residuals(ARM, points, None)
        return f.residuals(longer, *f.nearest(longer))[-2] / TIP_WEIGHT

    # (the ring of points at the tip projects within a fraction of a millimetre of it)
    assert tail(pts) == pytest.approx(0.010 - TIP_SLACK, abs=5e-4)
    assert tail(np.vstack([pts, strays[:LAST_STRAYS]])) == pytest.approx(0.010 - TIP_SLACK,
                                                                         abs=5e-4)
    assert tail(np.vstack([pts, strays])) == pytest.approx(0.002 - TIP_SLACK, abs=5e-4)


def test_merged_views_keep_one_point_a_voxel_and_their_pieces():
    from drake_continuum.perception.segmentation import Segmentation, merge_segmentations

    rng = np.random.default_rng(0)
    a = rng.uniform(0, 0.1, (500, 3))
    b = np.vstack([a[:300] + 1e-4, rng.uniform(0.2, 0.3, (100, 3))])  # overlap, then new
    segs = [Segmentation(points=a, piece=np.zeros(500, int), n_input=900, n_colour=500,
                         table_plane=None),
            Segmentation(points=b, piece=np.r_[np.zeros(300, int), np.ones(100, int)],
                         n_input=900, n_colour=400, table_plane=None)]
    both = merge_segmentations(segs)
    assert len(both.points) == 900
    voxel = 0.004
    one = merge_segmentations(segs, voxel)
    cells = {tuple(c) for c in np.floor(np.vstack([a, b]) / voxel).astype(int)}
    assert len(one.points) == len(cells)  # one a voxel of the union
    assert len({tuple(c) for c in np.floor(one.points / voxel).astype(int)}) == len(cells)
    # Each kept point is a point of a view, with that view's piece (numbered on).
    lookup = {tuple(p): k for p, k in zip(both.points, both.piece)}
    assert all(lookup[tuple(p)] == k for p, k in zip(one.points, one.piece))
    assert set(one.piece) == {0, 1, 2}


@pytest.mark.parametrize("lengths_known", [False, True])
def test_prefit_jacobian_is_least_squares_own_two_point_differences(lengths_known):
    """The prefit's cost at the ordering's arc lengths (points past either end, a curvature
    at its bend limit: the kinks) and its batched Jacobian against scipy's '2-point'
    differences one configuration at a time (least_squares' default), to the last bit, so
    the prefit goes as it went without the batch."""
    cfg = CONFIGS[2]
    rng = np.random.default_rng(5)
    total = float(np.sum(cfg.s))
    sig = rng.uniform(-0.01, total + 0.02, 300)
    bb = ARM.backbone(cfg, arc_length=np.clip(sig, 0, total))
    pts = bb.position + ARM.radius * bb.normal
    f = Residuals(ARM, pts, cfg.s if lengths_known else None)
    limit = float(ARM.curvature_limit(cfg.s[1:2])[0])  # section 2 at its bend limit
    uv = np.array([3.0, limit, 12.0, -2.0, 0.0, 1.0])
    x = uv if lengths_known else np.concatenate([cfg.s, uv])
    lo = np.full(len(x), -ARM.curvature_max)
    hi = -lo
    if not lengths_known:
        lo[:3], hi[:3] = ARM.section_length_min, ARM.section_length_max
        x[0] = ARM.section_length_max  # at a bound: the step turns back

    def one(y):  # the cost of one configuration, as the prefit had it before the batch
        c = f.config(y)
        end = float(np.sum(c.s))
        return np.append(f.at(c, np.minimum(sig, end), sig >= end, sig <= 0.0), f.excess(y))

    assert np.array_equal(f.along(x[None], sig)[0], one(x))
    ref = approx_derivative(one, x, method="2-point", bounds=(lo, hi), f0=one(x))
    assert np.array_equal(f.along_jac(x, sig, lo, hi), ref)


def test_point_residuals_are_the_distance_to_the_backbone_tube_and_its_flat_end_caps():
    """Residuals._at (compiled) against the tube measured from ContinuumArm.backbone: along
    the side, the distance from the centre line less the radius; past the tip or behind the
    base, the distance to the cap's disc (a point straight ahead of the tip on its axis: its
    axial distance)."""
    rng = np.random.default_rng(3)
    points = rng.uniform([-0.3, -0.3, 0.0], [0.3, 0.3, 0.5], (200, 3))
    sigma = rng.uniform(-0.02, 0.6, len(points))
    fun = Residuals(ARM, points, None)
    s = np.array([c.s for c in CONFIGS])
    total = s.sum(axis=1)
    at_tip = sigma >= 0.45
    at_base = sigma <= 0.0
    got = fun._at(s, np.array([c.kappa for c in CONFIGS]), np.array([c.phi for c in CONFIGS]),
                  sigma, at_tip, at_base)
    for k, cfg in enumerate(CONFIGS):
        arc = np.where(at_tip, total[k], np.clip(sigma, 0.0, total[k]))
        bb = ARM.backbone(cfg, arc_length=arc)
        d = points - bb.position
        axial = np.einsum("mi,mi->m", d, bb.tangent)
        side = np.linalg.norm(d - axial[:, None] * bb.tangent, axis=1) - ARM.radius
        beyond = (at_tip & (axial > 0)) | (at_base & (axial < 0))
        want = np.where(beyond, np.hypot(axial, np.maximum(side, 0.0)), side)
        assert got[k] == pytest.approx(want, abs=1e-12)
    tip_pos, tip_axis = ARM.tip_frame(CONFIGS[0])[1], ARM.backbone(
        CONFIGS[0], arc_length=[total[0]]).tangent[0]
    ahead = Residuals(ARM, (tip_pos + 0.01 * tip_axis)[None], None)
    cfg = CONFIGS[0]
    assert ahead._at(cfg.s[None], cfg.kappa[None], cfg.phi[None], np.array([total[0]]),
                     np.array([True]), np.array([False]))[0, 0] == pytest.approx(0.01, abs=1e-9)


def test_the_wrap_plane_charges_a_bend_against_the_wrap_and_a_curled_section_short_of_its_limit():
    """WrapPlane's rows against their closed forms: PLANE_WEIGHT s^2 / 2 times the bend out
    of the plane and times the bend about the normal against the wrap's turn, and for a
    curled section CURL_WEIGHT s^2 / 2 times its shortfall from the curvature limit; the
    turn's sense checked against the centre line itself (ContinuumArm.backbone: the tangent
    turns about the normal the commanded way)."""
    from drake_continuum.perception.residuals import CURL_WEIGHT, PLANE_WEIGHT, WrapPlane

    world_normal = ARM.base_rotation @ np.array([0.0, 1.0, 0.0])  # the base's x-z plane
    s = np.array([0.15, 0.20, 0.18])
    limit = ARM.curvature_limit(s)
    kappa = np.array([2.0, 9.0, 6.0])
    for turn in (1, -1):
        plane = WrapPlane(tuple(world_normal), turn=turn, curled=(2,)).in_base(ARM)
        u, v = plane.bent(kappa)
        cfg = ArmConfig(s, np.hypot(u, v), np.arctan2(v, u))
        bb = ARM.backbone(cfg, n=200)
        turned = np.cross(bb.tangent[:-1], bb.tangent[1:]) @ world_normal
        assert np.all(np.sign(turned[np.abs(turned) > 1e-9]) == turn)  # the commanded way
        half, curl = PLANE_WEIGHT * 0.5 * s * s, CURL_WEIGHT * 0.5 * s * s
        r = plane.residuals(s, u, v, limit=limit)
        assert r == pytest.approx(np.r_[0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                                        curl[2] * (limit[2] - kappa[2])], abs=1e-12)
        # The last section bent the other way: charged its whole bend, and its shortfall.
        u2, v2 = u.copy(), v.copy()
        u2[2], v2[2] = -u[2], -v[2]
        r2 = plane.residuals(s, u2, v2, limit=limit)
        assert r2[5] == pytest.approx(half[2] * kappa[2], rel=1e-12)
        assert r2[6] == pytest.approx(curl[2] * (limit[2] + kappa[2]), rel=1e-12)
        # Out of the plane: the first rows, as before.
        assert r2[:3] == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(Exception, match="turn"):
        WrapPlane(tuple(world_normal), curled=(2,))


def test_a_contact_under_the_table_is_charged_by_how_far_it_lies_under():
    """TableTouch against the centre line of ContinuumArm.backbone: a contact whose centre
    line lies h under the table's plane is charged TOUCH_WEIGHT (h - radius), one above it
    or less than a radius under nothing; the plane is oriented by the arm's base."""
    from drake_continuum.perception.residuals import TOUCH_WEIGHT, TableTouch, table_above

    cfg = CONFIGS[0]
    arc = np.array([0.05, 0.30, 0.50])
    z = ARM.backbone(cfg, arc_length=arc).position[:, 2]
    table_z = float(z[2]) + 0.0066  # the third contact 6.6 mm under: within the radius
    plane = table_above([0.0, 0.0, -2.0, 2.0 * table_z], ARM)  # given upside down
    assert plane[:3] @ ARM.base_position + plane[3] > 0
    r = TableTouch(arc, plane).residuals(ARM, (cfg.s[None], cfg.kappa[None], cfg.phi[None]))
    expected = TOUCH_WEIGHT * np.maximum(table_z - z - ARM.radius, 0.0)
    assert r[0] == pytest.approx(expected, abs=1e-12)
    assert table_z < ARM.base_position[2] and z[0] > table_z  # the first above the table
    assert r[0][0] == 0.0 and r[0][1] > 0.013 and r[0][2] == 0.0  # the second 23 mm under
