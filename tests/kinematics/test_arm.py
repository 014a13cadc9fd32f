"""Forward kinematics against closed forms."""

import numpy as np
import pytest
from pydrake.math import RollPitchYaw

from drake_continuum.kinematics.arm import ArmConfig, ArmLimitError, ContinuumArm, load_arm

ARM = ContinuumArm(n_sections=3, section_length_min=0.05, section_length_max=0.5,
                   curvature_max=50.0)


def test_straight_arm_is_a_line_along_base_z():
    c = ArmConfig.straight([0.1, 0.2, 0.3])
    R, p = ARM.section_frames(c)
    np.testing.assert_allclose(p[:, 2], [0, 0.1, 0.3, 0.6], atol=1e-15)
    np.testing.assert_allclose(p[:, :2], 0, atol=1e-15)
    for Ri in R:
        np.testing.assert_allclose(Ri, np.eye(3), atol=1e-15)


@pytest.mark.parametrize("angle", [np.pi / 2, np.pi])
def test_one_section_bent_to_quarter_and_half_circle(angle):
    r = 0.08
    c = ArmConfig([angle * r, 0.1, 0.1], [1 / r, 0, 0], [0, 0, 0])
    R, p = ARM.section_frames(c)
    # Circle of radius r centred at (r, 0, 0) in the x-z plane, starting at the origin.
    np.testing.assert_allclose(p[1], [r * (1 - np.cos(angle)), 0, r * np.sin(angle)], atol=1e-14)
    tangent = R[1][:, 2]
    np.testing.assert_allclose(tangent, [np.sin(angle), 0, np.cos(angle)], atol=1e-14)
    # Backbone points all lie on the circle.
    bb = ARM.backbone(c, np.linspace(0, angle * r, 50))
    np.testing.assert_allclose(np.linalg.norm(bb.position - [r, 0, 0], axis=1), r, atol=1e-14)
    # The normal points to the centre of curvature.
    to_centre = (np.array([r, 0, 0]) - bb.position) / r
    np.testing.assert_allclose(bb.normal, to_centre, atol=1e-12)


def test_phi_rotates_the_bending_plane():
    r, phi = 0.1, 0.7
    c0 = ArmConfig([0.15, 0.1, 0.1], [1 / r, 0, 0], [0, 0, 0])
    c1 = ArmConfig([0.15, 0.1, 0.1], [1 / r, 0, 0], [phi, phi, phi])
    Rz = RollPitchYaw([0, 0, phi]).ToRotationMatrix().matrix()
    _, p0 = ARM.section_frames(c0)
    _, p1 = ARM.section_frames(c1)
    np.testing.assert_allclose(p1, p0 @ Rz.T, atol=1e-14)


def test_frames_are_orthonormal_and_right_handed():
    rng = np.random.default_rng(0)
    c = ArmConfig(rng.uniform(0.05, 0.5, 3), rng.uniform(0, 50, 3), rng.uniform(-3, 3, 3))
    bb = ARM.backbone(c, n=97)
    F = np.stack([bb.normal, bb.binormal, bb.tangent], axis=-1)
    np.testing.assert_allclose(np.einsum("mji,mjk->mik", F, F), np.broadcast_to(np.eye(3), F.shape),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-12)
    # The tangent is the derivative of position (central differences).
    h = 1e-6
    a = np.linspace(0.01, c.s.sum() - 0.01, 13)
    d = (ARM.backbone(c, a + h).position - ARM.backbone(c, a - h).position) / (2 * h)
    np.testing.assert_allclose(d, ARM.backbone(c, a).tangent, atol=1e-7)


def test_tiny_curvature_matches_zero_continuously():
    c0 = ArmConfig([0.2, 0.2, 0.2], [0, 0, 0], [0.3, 1.0, 2.0])
    c1 = ArmConfig([0.2, 0.2, 0.2], [1e-9, 1e-9, 1e-9], [0.3, 1.0, 2.0])
    R0, p0 = ARM.section_frames(c0)
    R1, p1 = ARM.section_frames(c1)
    np.testing.assert_allclose(p1, p0, atol=1e-9)
    np.testing.assert_allclose(R1, R0, atol=1e-9)
    assert np.all(np.isfinite(ARM.backbone(c0, n=10).normal))


def test_sections_compose_end_to_end():
    """Two sections of one curvature and plane make one arc of their summed length."""
    r, phi = 0.07, 0.4
    split = ArmConfig([0.05, 0.08, 0.1], [1 / r, 1 / r, 0], [phi, phi, 0])
    whole = ArmConfig([0.13, 0.1, 0.1], [1 / r, 0, 0], [phi, 0, 0])
    R2, p2 = ARM.section_frames(split)
    R1, p1 = ARM.section_frames(whole)
    np.testing.assert_allclose(p2[2], p1[1], atol=1e-14)
    np.testing.assert_allclose(R2[2], R1[1], atol=1e-14)
    # A straight third section continues along the end tangent.
    np.testing.assert_allclose(p2[3], p2[2] + 0.1 * R2[2][:, 2], atol=1e-14)


def test_base_pose_moves_everything():
    arm = ARM.with_base([1, 2, 3], RollPitchYaw([0, np.pi / 2, 0]).ToRotationMatrix().matrix())
    _, p = arm.section_frames(ArmConfig.straight([0.1, 0.1, 0.1]))
    np.testing.assert_allclose(p[-1], [1.3, 2, 3], atol=1e-14)


def test_limits_name_the_section_and_the_limit():
    arm = load_arm()
    ok = ArmConfig.straight([0.2, 0.2, 0.2])
    arm.check(ok)
    with pytest.raises(ArmLimitError, match=r"section 2: curvature"):
        arm.check(ArmConfig([0.2, 0.2, 0.2], [0, 99, 0], [0, 0, 0]))
    with pytest.raises(ArmLimitError, match=r"section 3: length"):
        arm.check(ArmConfig([0.2, 0.2, 0.9], [0, 0, 0], [0, 0, 0]))
    with pytest.raises(ValueError, match="non-finite"):
        ArmConfig([0.2, np.nan, 0.2], [0, 0, 0], [0, 0, 0])
    with pytest.raises(ArmLimitError, match=r"section 1: bend angle"):  # at the tolerance
        arm.check(ArmConfig([0.2, 0.2, 0.2], [np.pi / 0.2 + 1e-6, 0, 0], [0, 0, 0]))
    arm.check(ArmConfig([0.1 - 1e-10, 0.2, 0.2], [0, 0, 0], [0, 0, 0]))  # within tol


def test_a_configuration_of_arrays_is_the_checked_one_frozen():
    """ArmConfig.of_arrays (enclosing's step, no copies) holds the arrays it is given, frozen
    as the checked constructor's."""
    s, kappa, phi = np.array([0.2, 0.3, 0.1]), np.array([1.0, 2.0, 3.0]), np.zeros(3)
    config = ArmConfig.of_arrays(s, kappa, phi)
    assert config.s is s and not s.flags.writeable and not phi.flags.writeable
    checked = ArmConfig(s, kappa, phi)
    np.testing.assert_array_equal(config.as_vector(), checked.as_vector())
    with pytest.raises(ValueError):
        config.kappa[0] = 5.0


def test_arm_yaml_errors_name_the_file(tmp_path):
    bad = tmp_path / "arm.yaml"
    bad.write_text("n_sections: 3\n")
    with pytest.raises(ValueError, match=str(bad)):
        ContinuumArm.from_yaml(bad)
    with pytest.raises(FileNotFoundError, match="nothere"):
        ContinuumArm.from_yaml(tmp_path / "nothere.yaml")


def test_the_shipped_five_section_arm_has_the_default_reach_and_base():
    """models/arm_5sections.yaml is compared with arm.yaml in BENCHMARKS.md on that basis:
    the same reach, tube, limits and base, only cut into five sections."""
    from drake_continuum.kinematics.arm import MODELS_DIR
    three, five = load_arm(), load_arm(MODELS_DIR / "arm_5sections.yaml")
    assert five.n_sections == 5
    assert five.n_sections * five.section_length_max == pytest.approx(
        three.n_sections * three.section_length_max)
    for name in ("curvature_max", "radius", "bend_max"):
        assert getattr(five, name) == getattr(three, name)
    np.testing.assert_allclose(five.base_position, three.base_position)
    np.testing.assert_allclose(five.base_rotation, three.base_rotation)
