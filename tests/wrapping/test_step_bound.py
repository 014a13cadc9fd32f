"""The hull's lower bound on the distance to an object, and the two questions that ask Open3D
only about the points it leaves open: the fast enclosing's step bound and IK's penetration
check, each against the same question asked about every point."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm
from drake_continuum.kinematics.pressing import presses
from drake_continuum.wrapping.distance import BOUND_SLACK, SurfaceDistance, hull_planes
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.step_bound import MARGIN, StepBound


def _objects():
    """The shipped mug (a handle and a cavity the hull hides) and a standing torus."""
    torus = trimesh.creation.torus(major_radius=0.06, minor_radius=0.015)
    torus.apply_transform(trimesh.transformations.euler_matrix(0.2, np.pi / 2, 0.0))
    torus.apply_translation([0.0, 0.0, 0.08])
    return {"mug": trimesh.load(MODELS_DIR / "mug.obj"), "torus": torus}


@pytest.fixture(scope="module")
def arm():
    return load_arm()


@pytest.mark.parametrize("name", ["mug", "torus"])
def test_lower_bound_lies_below_open3d_and_a_full_scan_is_the_planes_maximum(name):
    """Points in and around the object: the bound never exceeds Open3D's signed distance
    (with the table too); asked to reach +inf it is every plane's maximum (numpy, to
    rounding) less the slack, and a second call that the hinted plane satisfies gives that
    plane's value."""
    mesh = _objects()[name]
    distances = SurfaceDistance(mesh)
    rng = np.random.default_rng(2)
    lo, hi = mesh.bounds
    points = lo - 0.05 + rng.random((3000, 3)) * (hi - lo + 0.1)
    exact = distances.signed_distance(points)
    hint = np.full(len(points), -1, np.int64)
    full = distances.lower_bound(points, np.full(len(points), np.inf), hint=hint)
    planes = hull_planes(mesh)
    every = (points @ planes[:, :3].T + planes[:, 3]).max(axis=1)  # (a matmul's rounding)
    assert np.allclose(full, every - BOUND_SLACK, rtol=0.0, atol=1e-15)
    assert np.all(full <= exact)
    assert np.mean(full > exact - 0.01) > 0.3  # not a bound that proves nothing
    hinted = distances.lower_bound(points, np.full(len(points), -np.inf), hint=hint)
    assert np.array_equal(hinted, full)  # the hint is the best plane
    moved = points + rng.normal(0.0, 0.01, points.shape)
    again = distances.lower_bound(moved, np.full(len(points), -np.inf), hint=hint)
    assert np.all(again <= distances.signed_distance(moved))
    table = distances.lower_bound(points, np.zeros(len(points)), hint=hint, table=True)
    assert np.all(table <= distances.signed_distance(points, table=True))


def _every_point(scene, pair, *, i, left, table):
    """The step bound with Open3D asked about every point (the loop's bound as written
    before the hull bound)."""
    per = 24
    fractions = np.linspace(0.0, 1.0, per)
    arm, (config, nxt) = scene.arm, pair
    _, pts = arm.batch_points(np.array([config.s, nxt.s]), np.array([config.kappa, nxt.kappa]),
                              np.array([config.phi, nxt.phi]), fractions)
    here, after = pts[0, i * per:], pts[1, i * per:]
    step = after - here
    motion = 1.5 * np.sqrt((step * step).sum(axis=1)) + 1e-12
    gap = scene.signed_distance(here, table=table) - arm.radius
    near = gap <= MARGIN
    far = ~near
    cap = min(left, int(((gap[far] - MARGIN) / motion[far]).min()) if far.any() else left)
    return max(cap, 1), bool(near.any()), max(1, int(arm.radius / motion.max()))


def _curls(arm, rng, n):
    """Random configurations and each one a small curving step on."""
    for _ in range(n):
        s = rng.uniform(0.1, 0.3, 3)
        kappa = rng.uniform(0, 0.8, 3) * arm.curvature_limit(s)
        phi = rng.normal(0, 0.3, 3)
        dk = rng.uniform(0.02, 0.3, 3)
        yield ArmConfig(s, kappa, phi), ArmConfig(s, kappa + dk, phi)


@pytest.mark.parametrize("name", ["mug", "torus"])
def test_step_bound_is_the_bound_every_point_gives(arm, name):
    """Curls round the object, one bound after another (the hints carried between them), with
    and without the table: the same (steps, near, look-ahead) as asking every point, and
    the cases seen include points within the margin and bounds short of `left`."""
    scene = WrapScene(arm, _objects()[name])
    rng = np.random.default_rng(5)
    seen = set()
    for table in (False, True):
        bound = StepBound(scene, table)
        for pair in _curls(arm, rng, 150):
            i, left = int(rng.integers(0, 3)), int(rng.integers(2, 400))
            want = _every_point(scene, pair, i=i, left=left, table=table)
            assert bound(pair, i=i, left=left) == want
            seen.add((want[1], want[0] < left))
    assert {(True, True), (False, True), (False, False)} <= seen


@pytest.mark.parametrize("name", ["mug", "torus"])
def test_presses_is_the_answer_every_point_gives(arm, name):
    """IK's penetration check through the scene's field (hull bound, then Open3D on the
    points left) against Open3D on every point, pressing and clear cases both seen."""
    scene = WrapScene(arm, _objects()[name])
    field = scene.field()
    rng = np.random.default_rng(6)
    answers = []
    for config, _ in _curls(arm, rng, 200):
        points = arm.backbone(config, n=60).position
        for tolerance in (1e-3, 0.02):
            want = bool(np.min(field(points)[0] - arm.radius) < -tolerance)
            assert presses(field, points, radius=arm.radius, tolerance=tolerance) == want
            assert presses(field.__call__, points, radius=arm.radius,
                           tolerance=tolerance) == want
            answers.append(want)
    assert 10 < sum(answers) < len(answers) - 10
