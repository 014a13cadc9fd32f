"""The compiled kinematics against arm.py's numpy arc transforms and scipy's quaternions."""

import numpy as np
from scipy.spatial.transform import Rotation

from drake_continuum.kinematics import compiled
from drake_continuum.kinematics.arm import ArmConfig, arc_transforms, load_arm
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
            _, local = arc_transforms(s[b, i] * f, kappa[b, i], phi[b, i])
            np.testing.assert_allclose(points[b, 7 * i:7 * (i + 1)], p + local @ R.T, atol=1e-12)
            R_end, p_end = arc_transforms(s[b, i], kappa[b, i], phi[b, i])
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
            R_u, p_u = arc_transforms(u, kappa[b, j], phi[b, j])
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


def test_capsule_frames_are_the_numpy_capsule_poses_to_the_bit():
    """One call makes what the capsules' arc lengths (spread evenly within each section),
    the backbone there and Shepperd's quaternions of its frames make step by step in numpy:
    the same doubles, so contact answers kept by pose stay the same."""
    arm = load_arm()
    arm = arm.with_base(rotation=Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix())
    s, kappa, phi = _configs()
    k, half = 20, 0.01
    spread = np.linspace(0.0, 1.0, k)
    spread.flags.writeable = False  # as the scene passes it: the layout compiled ahead
    for b in range(len(s)):
        config = ArmConfig(s[b], kappa[b], phi[b])
        starts = np.concatenate([[0.0], np.cumsum(s[b])[:-1]])
        arc = (starts[:, None] + half + spread[None] * (s[b][:, None] - 2 * half)).ravel()
        bb = arm.backbone(config, arc)
        R = np.stack([bb.normal, bb.binormal, bb.tangent], axis=-1)
        poses = np.hstack([quaternions_wxyz(R), bb.position])
        got = compiled.capsule_frames(arm.base_rotation, arm.base_position, config.s,
                                      config.kappa, config.phi, spread, half)
        for mine, theirs in zip(got, (arc, bb.section, bb.position, bb.tangent, bb.normal,
                                      bb.binormal, poses)):
            np.testing.assert_array_equal(mine, theirs)


def _brute_distance(p, u, q, v, half, n=801):
    """The least distance over an n x n grid of points on the two segments (u, v unit):
    |w + a u - b v|^2 expanded, so the grid is two outer sums rather than n^2 vectors."""
    a = np.linspace(-half, half, n)
    w = p - q
    along = a * a + 2.0 * a * (u @ w)
    d2 = (w @ w + along[:, None] + (a * a - 2.0 * a * (v @ w))[None]
          - 2.0 * (u @ v) * np.outer(a, a))
    return float(np.sqrt(max(d2.min(), 0.0)))


def test_far_segments_within_matches_a_dense_search_and_the_parallel_case():
    rng = np.random.default_rng(3)
    half = 0.01
    for _ in range(200):
        p, q = rng.normal(scale=0.015, size=(2, 3))
        u, v = rng.normal(size=(2, 3))
        u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
        d = _brute_distance(p, u, q, v, half)
        pos, tan = np.stack([p, q]), np.stack([u, v])
        arc = np.array([0.0, 1.0])
        # The dense search is above the exact distance by at most its grid's half spacing.
        assert compiled.far_segments_within(pos, tan, arc, 0, half, 0.5, d + 1e-9)
        assert not compiled.far_segments_within(pos, tan, arc, 0, half, 0.5, d - 3e-5)
        # Pairs nearer than `far` along the arm, or both before `first`, are not asked.
        assert not compiled.far_segments_within(pos, tan, arc, 0, half, 1.5, d + 1e-3)
        assert not compiled.far_segments_within(pos, tan, arc, 2, half, 0.5, d + 1e-3)
    # Parallel segments overlapping along their length: the gap between them.
    pos = np.array([[0.0, 0.0, 0.0], [0.013, 0.0, 0.005]])
    tan = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    arc = np.array([0.0, 1.0])
    assert compiled.far_segments_within(pos, tan, arc, 1, half, 0.5, 0.0131)
    assert not compiled.far_segments_within(pos, tan, arc, 1, half, 0.5, 0.0129)


def test_compile_kernels_covers_the_layouts_a_wrap_passes():
    """After compile_kernels (what scripts/setup.sh runs) the default arm's centre lines, an
    IK batch and a frozen configuration's batch add no compiled version: a run after setup
    compiles nothing."""
    from drake_continuum.wrapping.scene import capsule_poses

    compiled.compile_kernels()
    kernels = (compiled.backbone_samples, compiled.batch_points, compiled.capsule_frames)
    before = [len(k.signatures) for k in kernels]
    arm = load_arm()
    s, kappa, phi = _configs(4)
    config = ArmConfig(s[3], kappa[3], phi[3])
    arm.backbone(config)
    capsule_poses(arm, config, 20, 0.02)  # posing a scene
    arm.batch_points(s, kappa, phi, np.linspace(0.0, 1.0, 5))
    arm.batch_points(config.s[None], config.kappa[None], config.phi[None], [0.0, 1.0])
    assert [len(k.signatures) for k in kernels] == before



def test_compile_kernels_covers_the_layouts_a_fit_passes():
    """A fit's residuals and Jacobians, with lengths known (broadcast, read-only) or free,
    on read-only points, add no compiled version of the tube distance after
    compile_kernels: a first fit after setup compiles nothing."""
    from drake_continuum.perception.residuals import Residuals

    compiled.compile_kernels()
    before = len(compiled.tube_distances.signatures)
    arm = load_arm()
    s, kappa, phi = _configs(4)
    config = ArmConfig(s[3], kappa[3], phi[3])
    points = arm.backbone(config).position
    points.setflags(write=False)
    u, v = config.kappa * np.cos(config.phi), config.kappa * np.sin(config.phi)
    for f, x in ((Residuals(arm, points, config.s), np.concatenate([u, v])),
                 (Residuals(arm, points, None), np.concatenate([config.s, u, v]))):
        f(x)
        f.jac(x)
        f.along(x[None], np.linspace(0.0, 0.2, len(points))[None])
    assert len(compiled.tube_distances.signatures) == before
