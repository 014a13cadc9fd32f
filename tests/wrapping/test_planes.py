"""Wrap planes: enumeration, normals, movement cost, cross-sections, start ray, base frame."""

import numpy as np
import pytest

from drake_continuum.kinematics.arm import MODELS_DIR, load_arm
from drake_continuum.objects.mesh import load_mesh
from drake_continuum.wrapping.planes import (
    base_rotation,
    cost_matrix,
    cross_section,
    enumerate_planes,
    make_plane,
    movement_cost,
    plane_normal,
    start_direction,
)

ORIGIN = np.array([-0.18, 0.0, 0.05])


@pytest.fixture(scope="module")
def mug():
    return load_mesh(MODELS_DIR / "mug.obj")


def test_counts():
    assert len(enumerate_planes(ORIGIN)) == 10  # paper: alpha = 22.5 deg, "10 or fewer"
    both = enumerate_planes(ORIGIN, both_directions=True)
    assert len(both) == 20
    assert [p.index for p in both] == list(range(20))
    # Each plane twice, once each way.
    for a, b in zip(both[::2], both[1::2]):
        np.testing.assert_allclose(a.normal, b.normal)
        assert a.direction == -b.direction
    assert len(enumerate_planes(ORIGIN, alpha_deg=30.0)) == 8
    assert len(enumerate_planes(ORIGIN, alpha_deg=90.0)) == 4
    for bad in (0.0, -10.0, 91.0):
        with pytest.raises(ValueError, match="alpha"):
            enumerate_planes(ORIGIN, alpha_deg=bad)


def test_normals_as_specified():
    planes = enumerate_planes(ORIGIN)
    angles = np.radians([0.0, 22.5, 45.0, 67.5, 90.0])
    for p in planes:
        assert np.linalg.norm(p.normal) == pytest.approx(1.0)
        np.testing.assert_allclose(p.origin, ORIGIN)
    for a, p in zip(angles, planes[:5]):
        assert p.axis == "x" and p.direction == -1  # Fig. 4: rotated about x, clockwise
        np.testing.assert_allclose(p.normal, [0.0, -np.sin(a), np.cos(a)], atol=1e-12)
    for a, p in zip(angles, planes[5:]):
        assert p.axis == "y" and p.direction == 1  # about y, counter-clockwise, tilting up
        np.testing.assert_allclose(p.normal, [-np.sin(a), 0.0, np.cos(a)], atol=1e-12)
    np.testing.assert_allclose(planes[0].normal, [0, 0, 1], atol=1e-12)  # the tabletop plane
    np.testing.assert_allclose(planes[4].normal, [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(planes[9].normal, [-1, 0, 0], atol=1e-12)
    assert planes[4].label == "rx90-cw" and planes[9].label == "ry90-ccw"
    with pytest.raises(ValueError):
        plane_normal("z", 0.0)
    with pytest.raises(ValueError):
        make_plane(ORIGIN, "x", 10.0, direction=0)


def test_basis_orthonormal_in_plane():
    for p in enumerate_planes(ORIGIN, alpha_deg=15.0, both_directions=True):
        e1, e2 = p.basis()
        B = np.stack([e1, e2, p.normal])
        np.testing.assert_allclose(B @ B.T, np.eye(3), atol=1e-12)
        if abs(p.normal[0]) < 1 - 1e-9:
            assert e1[0] > 0  # e1 is world x projected into the plane: towards the object


def test_movement_cost_is_angle_between_normals():
    planes = enumerate_planes(ORIGIN)
    C = cost_matrix(planes)
    assert C.shape == (10, 10)
    np.testing.assert_allclose(C, C.T)
    np.testing.assert_allclose(np.diag(C), 0.0, atol=1e-7)
    rx0, rx22, rx45, rx90, ry45, ry90 = (planes[i] for i in (0, 1, 2, 4, 7, 9))
    assert movement_cost(rx0, rx90) == pytest.approx(np.pi / 2)
    assert movement_cost(rx22, rx45) == pytest.approx(np.radians(22.5))
    assert movement_cost(rx90, ry90) == pytest.approx(np.pi / 2)
    # (0, -s, c) . (-s, 0, c) = c^2 = 1/2 at 45 deg: 60 deg apart.
    assert movement_cost(rx45, ry45) == pytest.approx(np.radians(60.0))
    for i, a in enumerate(planes):
        for j, b in enumerate(planes):
            assert C[i, j] == pytest.approx(movement_cost(a, b), abs=1e-7)
    both = enumerate_planes(ORIGIN, both_directions=True)
    assert movement_cost(both[0], both[1]) == pytest.approx(0.0, abs=1e-7)


def test_cross_section_empty_when_plane_misses(mug):
    planes = enumerate_planes(ORIGIN)
    # ry90 is the vertical plane x = -0.18 through the base, behind the 12 cm-wide mug.
    assert cross_section(mug, planes[9]).shape == (0, 2)
    cut = cross_section(mug, planes[0])
    assert cut.ndim == 2 and cut.shape[1] == 2 and len(cut) > 10
    # The horizontal cut at the base's height lies at that height: check in 3-D.
    e1, e2 = planes[0].basis()
    pts = ORIGIN + cut[:, :1] * e1 + cut[:, 1:] * e2
    np.testing.assert_allclose(pts[:, 2], ORIGIN[2], atol=1e-9)
    np.testing.assert_allclose(mug.nearest.on_surface(pts)[1], 0.0, atol=1e-6)


@pytest.mark.parametrize("index", range(9))
def test_start_ray_clears_cut_and_base_frame(mug, index):
    plane = enumerate_planes(ORIGIN, both_directions=True)[index]
    cut = cross_section(mug, plane)
    if not len(cut):
        pytest.skip("plane misses the mug")
    clearance = 0.015
    ray, tangent = start_direction(cut, plane, clearance)
    assert np.linalg.norm(ray) == pytest.approx(1.0)
    assert ray @ plane.normal == pytest.approx(0.0, abs=1e-12)  # the ray lies in the plane
    R = base_rotation(plane, ray)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 2], ray, atol=1e-12)  # z along the start ray
    assert R[:, 0] @ plane.normal == pytest.approx(0.0, abs=1e-12)  # x (bending) in the plane
    # Bending towards x curls about the plane normal in the wrap's direction.
    assert np.cross(R[:, 2], R[:, 0]) @ plane.normal == pytest.approx(plane.direction)
    e1, e2 = plane.basis()
    pts = cut[:, :1] * e1 + cut[:, 1:] * e2  # about the base
    # Every cut point lies on the bending side of the ray, at least `clearance` from it; the
    # tangent point at exactly the clearance, `tangent` along the ray.
    side = pts @ R[:, 0]
    assert side.min() == pytest.approx(clearance, abs=1e-9)
    k = side.argmin()
    assert pts[k] @ ray == pytest.approx(tangent, abs=1e-9)


def test_start_ray_refuses_cut_at_base():
    plane = make_plane(ORIGIN, "x", 0.0)
    with pytest.raises(ValueError, match="clearance"):
        start_direction(np.array([[0.005, 0.0], [0.1, 0.02]]), plane, 0.01)


def test_default_planes_pass_through_the_arm_base():
    arm = load_arm()
    for p in enumerate_planes(arm.base_position):
        np.testing.assert_allclose(p.origin, arm.base_position)
