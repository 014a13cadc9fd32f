"""objects.placement.stable_poses against trimesh's compute_stable_poses, the second
implementation of the same toppling graph: the same sides with the same probabilities on
generated objects, most probable first, in an order that does not hang on rounding."""

import numpy as np
import pytest
import trimesh

from drake_continuum.objects.generators import generate_object
from drake_continuum.objects.placement import (
    TIED_PROBABILITY,
    _most_probable_first,
    stable_poses,
)

OBJECTS = [("mug", 0), ("bottle", 1), ("bowl", 0), ("toilet_paper", 0), ("banana", 0),
           ("cup", 0), ("hammer", 0)]


@pytest.mark.parametrize("category,index", OBJECTS)
def test_stable_poses_equal_trimesh(category, index):
    """Every side trimesh finds, with its probability to rounding; ours most probable first
    (trimesh orders sides of equal probability by the last bits of their sums)."""
    mesh = generate_object(category, index, seed=0).posed.mesh
    transforms, probs = trimesh.poses.compute_stable_poses(mesh)
    theirs = np.asarray(transforms)[:, 2, :3]
    up, p = stable_poses(mesh)
    assert up.shape == theirs.shape
    match = [int(np.argmin(np.linalg.norm(theirs - u, axis=1))) for u in up]
    assert sorted(match) == list(range(len(theirs)))
    np.testing.assert_allclose(up, theirs[match], rtol=0, atol=1e-12)
    np.testing.assert_allclose(p, probs[match], rtol=1e-10, atol=0)
    assert np.all(np.diff(p) <= TIED_PROBABILITY)


@pytest.mark.parametrize("category,index", [("toilet_paper", 0), ("cup", 0)])
def test_equal_sides_keep_their_order_whatever_the_last_bits(category, index):
    """A symmetric object's equal sides: probabilities a few ulps apart in any direction
    (as another CPU's sums give) leave the order unchanged, where a plain sort on the
    probabilities reorders them."""
    up, p = stable_poses(generate_object(category, index, seed=0).posed.mesh)
    ties = np.isclose(p[:-1], p[1:], rtol=0, atol=TIED_PROBABILITY)
    assert ties.any()
    rng = np.random.default_rng(0)
    plain = []
    for _ in range(20):
        noisy = p * (1.0 + rng.uniform(-4e-16, 4e-16, p.shape))
        np.testing.assert_array_equal(_most_probable_first(up, noisy), np.arange(len(p)))
        plain.append(np.array_equal(np.argsort(-noisy, kind="stable"), np.arange(len(p))))
    assert not all(plain)


def test_a_brick_rests_on_its_broadest_side_most_often():
    """A 10 x 6 x 20 cm box: three pairs of sides, the 10 x 20 cm pair most probable."""
    box = trimesh.creation.box(extents=(0.10, 0.06, 0.20))
    up, p = stable_poses(box)
    assert len(up) == 6 and abs(p.sum() - 1.0) < 1e-12
    np.testing.assert_allclose(np.abs(up[0]), [0.0, 1.0, 0.0])
