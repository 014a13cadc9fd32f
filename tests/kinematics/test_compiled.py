"""The compiled kinematics against arm.py's numpy arc transforms and scipy's quaternions."""

import numpy as np
from scipy.spatial.transform import Rotation

from drake_continuum.kinematics.arm import ArmConfig, _arc_transforms, load_arm
from drake_continuum.kinematics.compiled import quaternions_wxyz


def _configs(n=12, seed=0):
    rng = np.random.default_rng(seed)
    s = rng.uniform(0.05, 0.35, (n, 3))
    kappa = rng.uniform(0.0, 40.0, (n, 3))
    kappa[0] = 0.0  # straight
    kappa[1, 1] = 1e-9  # the sinc's series branch
    kappa[2, 2] = 1e-4 / 0.3  # just past it
    return s, kappa, rng.uniform(-np.pi, np.pi, (n, 3))


def test_batch_points_match_composed_numpy_arcs():
    arm = load_arm()
    arm = arm.with_base(rotation=Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix())
    s, kappa, phi = _configs()
    f = np.linspace(0.0, 1.0, 7)
    ends, points = arm.batch_points(s, kappa, phi, f)
    for b in range(len(s)):
        R, p = arm.base_rotation, arm.base_position
        for i in range(3):
            _, local = _arc_transforms(s[b, i] * f, kappa[b, i], phi[b, i])
            np.testing.assert_allclose(points[b, 7 * i:7 * (i + 1)], p + local @ R.T, atol=1e-12)
            R_end, p_end = _arc_transforms(s[b, i], kappa[b, i], phi[b, i])
            p, R = p + R @ p_end, R @ R_end
            np.testing.assert_allclose(ends[b, i], p, atol=1e-12)


def test_backbone_frames_match_the_arc_rotation():
    """A sample's (normal, binormal, tangent) is the section base's frame turned by the arc
    up to it, with normal along R's x rotated by phi: R_arc(u) Rz(phi)."""
    arm = load_arm()
    s, kappa, phi = _configs(4, seed=1)
    for b in range(4):
        config = ArmConfig(s[b], kappa[b], phi[b])
        bb = arm.backbone(config, n=50)
        R0, p0 = arm.section_frames(config)
        starts = np.concatenate([[0.0], np.cumsum(s[b])[:-1]])
        for k in range(50):
            j = bb.section[k]
            u = bb.arc_length[k] - starts[j]
            R_u, p_u = _arc_transforms(u, kappa[b, j], phi[b, j])
            frame = R0[j] @ R_u @ Rotation.from_euler("z", phi[b, j]).as_matrix()
            np.testing.assert_allclose(bb.position[k], p0[j] + R0[j] @ p_u, atol=1e-12)
            np.testing.assert_allclose(
                np.stack([bb.normal[k], bb.binormal[k], bb.tangent[k]], axis=1), frame,
                atol=1e-12)


def test_quaternions_match_scipy_including_half_turns():
    R = Rotation.random(200, random_state=2).as_matrix()
    R[:3] = Rotation.from_rotvec(np.pi * np.eye(3)).as_matrix()  # 180 deg about each axis
    q = quaternions_wxyz(R)
    expected = Rotation.from_matrix(R).as_quat()[:, [3, 0, 1, 2]]
    # q and -q are the same rotation
    np.testing.assert_allclose(np.abs(np.sum(q * expected, axis=1)), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-14)
