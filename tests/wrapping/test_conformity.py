"""The conformity measure of a wrap, on a cylinder wrapped by hand-set arcs (closed form)."""

import numpy as np
import pytest
import trimesh

from drake_continuum.kinematics.arm import ArmConfig, ContinuumArm
from drake_continuum.wrapping.conformity import near_fraction, swept_angle
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import tip_heading

R, TUBE = 0.04, 0.01


def _cylinder_scene():
    cyl = trimesh.creation.cylinder(radius=R, height=0.2, sections=256)
    cyl.apply_translation([0.0, 0.0, 0.1])
    arm = ContinuumArm(radius=TUBE, base_position=[-0.2, 0.0, 0.05])
    return WrapScene(arm, cyl)


def _circle(radius, start_deg, stop_deg, n):
    a = np.radians(np.linspace(start_deg, stop_deg, n))
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.full(n, 0.05)], axis=1)


def test_an_arc_touching_the_cylinder_is_all_near_and_sweeps_its_angle():
    scene = _cylinder_scene()
    touching = _circle(R + TUBE, 30.0, 230.0, 201)  # the tube rests on the surface
    assert near_fraction(touching, scene.signed_distance, TUBE) == 1.0
    assert np.isclose(swept_angle(touching, [0, 0, 1], [0, 0, 0.05]), np.radians(200.0))


def test_half_touching_half_a_centimetre_off_counts_half():
    scene = _cylinder_scene()
    near = _circle(R + TUBE + 0.004, 0.0, 90.0, 50)  # 4 mm gap: near
    far = _circle(R + TUBE + 0.008, 90.0, 180.0, 50)  # 8 mm gap: not near
    path = np.concatenate([near, far])
    assert near_fraction(path, scene.signed_distance, TUBE) == 0.5
    # Beyond a half turn the unwrapped angle keeps counting: 300 deg, not 60.
    assert np.isclose(swept_angle(_circle(0.1, 0.0, 300.0, 61), [0, 0, 1], [0, 0, 0]),
                      np.radians(300.0))
    assert np.isnan(near_fraction(np.zeros((0, 3)), scene.signed_distance, TUBE))


def test_tip_heading_is_the_planar_bend_unwrapped_past_a_half_turn():
    # In-plane sections (phi = 0) turn the tip by the sum of kappa * s, here 1.2 + 1.5 + 1.6
    # = 4.3 rad (246 deg), which a plain angle between directions would report as 114 deg.
    arm = ContinuumArm()
    config = ArmConfig([0.3, 0.3, 0.4], [4.0, 5.0, 4.0], [0.0, 0.0, 0.0])
    assert np.isclose(tip_heading(arm, config), 4.3, atol=1e-9)
    # Bending the other way (phi = pi) turns it the other way.
    assert np.isclose(tip_heading(arm, ArmConfig([0.3, 0.3, 0.4], [4.0, 0.0, 0.0],
                                                 [np.pi, 0.0, 0.0])), -1.2, atol=1e-9)


@pytest.mark.parametrize("radius", [0.03, 0.04])
def test_a_wrap_of_a_cylinder_follows_its_surface(radius):
    """Algorithm 1 round a cylinder: the section after the first touch curves onto the
    surface instead of staying straight while the tip curls in free air (before the joint
    and rest rules of wrap._touch: 12 and 10 % near for 4 and 3 cm; a 5 cm one still
    stalls: BENCHMARKS.md)."""
    from drake_continuum.kinematics.arm import load_arm
    from drake_continuum.wrapping.planes import enumerate_planes
    from drake_continuum.wrapping.wrap import wrap

    arm = load_arm()
    cyl = trimesh.creation.cylinder(radius=radius, height=0.15, sections=128)
    cyl.apply_translation([0.0, 0.0, 0.075])
    scene = WrapScene(arm, cyl)
    result = wrap(scene, enumerate_planes(arm.base_position)[0])
    assert result.status == "complete"
    assert result.conformity >= 0.9
    assert result.contact_regions >= 3
    assert result.wrap_angle >= np.radians(200.0)
    # The stored measure is the measure of the stored samples.
    assert result.conformity == near_fraction(result.samples_position, scene.signed_distance,
                                              arm.radius)
