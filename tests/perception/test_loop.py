"""The start made for a coil (medial.loop_config): sections 2 to n at the bend limit, bent
the same way, close a loop that no ordering of the points follows."""

import numpy as np
import pytest

from drake_continuum.kinematics.arm import ArmConfig, ContinuumArm, load_arm
from drake_continuum.perception import depth_camera as dc
from drake_continuum.perception import fitting
from drake_continuum.perception.cloud import Cloud
from drake_continuum.perception.fitting import fit_cloud
from drake_continuum.perception.medial import loop_config, medial_points

ARM = load_arm()
# A wrap of a small object: a 18 cm first section, then two 10 cm sections each bent half a
# turn (the bend limit) in one plane: a closed ring of radius 10 cm / pi = 3.2 cm.
PHI = -1.2
COIL = ArmConfig([0.18, 0.10, 0.10], [0.5, np.pi / 0.10, np.pi / 0.10], [PHI, PHI, PHI])


def _surface(config, step=0.003, around=16, arm=ARM):
    """Points on the tube's surface all round (no camera)."""
    bb = arm.backbone(config, arc_length=np.arange(0.0, float(np.sum(config.s)), step))
    ang = np.linspace(0, 2 * np.pi, around, endpoint=False)
    ring = np.cos(ang)[None, :, None] * bb.normal[:, None] \
        + np.sin(ang)[None, :, None] * bb.binormal[:, None]
    return (bb.position[:, None] + arm.radius * ring).reshape(-1, 3)


@pytest.mark.parametrize("lengths", [COIL.s, None], ids=["known", "free"])
def test_loop_start_is_the_coil_of_its_surface(lengths):
    # Closed form: the ring's plane holds section 1's end tangent and the ring's centre lies
    # along phi = PHI in that end's frame (a planar coil keeps phi from section to section);
    # both ring sections at the bend limit.
    pts = _surface(COIL)
    config, seen = loop_config(ARM, pts, medial_points(ARM, pts), lengths=lengths)
    assert config.phi[1] == pytest.approx(PHI, abs=0.1)
    assert config.phi[2] == config.phi[1]
    np.testing.assert_allclose(config.s, COIL.s, atol=0.01)
    np.testing.assert_allclose(config.kappa[1:], ARM.curvature_limit(config.s[1:]))
    assert seen == pytest.approx(np.sum(COIL.s), abs=0.02)  # the ring's length, unfolded
    # the start is near enough for the refinement: the tip within a ring's radius
    assert np.linalg.norm(ARM.tip_frame(config)[1] - ARM.tip_frame(COIL)[1]) < 0.03


@pytest.mark.parametrize("lengths", ["known", "free"])
def test_a_four_section_arms_coil_closes_on_sections_2_to_4(lengths):
    """An arm of four sections: sections 2 to 4 of 7.5 cm each bent a third of a turn close a
    ring of radius 22.5 cm / 2 pi = 3.6 cm; the start has four sections, 2 to 4 bent the
    same way round it, and shows the stem and one turn of the ring seen."""
    arm = ContinuumArm.from_dict({
        "n_sections": 4, "section_length_min": 0.075, "section_length_max": 0.30,
        "curvature_max": 40.0, "radius": 0.010, "bend_max": np.pi,
        "base_position": [-0.18, 0.0, 0.05], "base_rpy": [0.0, np.pi / 2, 0.0]})
    k = (2 * np.pi / 3) / 0.075
    coil = ArmConfig([0.18, 0.075, 0.075, 0.075], [0.5, k, k, k], [PHI] * 4)
    pts = _surface(coil, arm=arm)
    config, seen = loop_config(arm, pts, medial_points(arm, pts),
                               lengths=coil.s if lengths == "known" else None)
    assert config.phi[1] == pytest.approx(PHI, abs=0.1)
    assert config.phi[2] == config.phi[3] == config.phi[1]
    np.testing.assert_allclose(config.s, coil.s, atol=0.01)
    np.testing.assert_allclose(config.kappa[1:], k, rtol=0.1)
    assert seen == pytest.approx(np.sum(coil.s), abs=0.02)
    assert np.linalg.norm(arm.tip_frame(config)[1] - arm.tip_frame(coil)[1]) < 0.03


def test_a_straight_arm_is_no_loop():
    straight = ArmConfig([0.15, 0.15, 0.15], [0.5, 0.2, 0.3], [0.0, 1.0, 2.0])
    pts = _surface(straight)
    assert loop_config(ARM, pts, medial_points(ARM, pts), lengths=straight.s) is None
    assert loop_config(ARM, pts, medial_points(ARM, pts)) is None


@pytest.mark.parametrize("known", [True, False], ids=["known", "free"])
def test_a_coil_seen_by_the_camera_is_fitted(known, monkeypatch):
    # A noisy depth-camera cloud of the coil: the fit recovers the tip within 3 mm (lengths
    # known) or 6 mm (free), within the limits, and says it is no poor fit. With free lengths
    # and without the loop start the same fit ends far off (every ordering runs both ways
    # round the ring); with them known the free-length fit's curvatures find it, later.
    sim = dc.render_cloud(ARM, COIL, None, seed=5)
    cloud = Cloud(sim.points, sim.colours)
    truth = ARM.tip_frame(COIL)[1]
    lengths = COIL.s if known else None
    seg, fit = fit_cloud(cloud, ARM, lengths, eye=sim.camera.eye)
    assert np.linalg.norm(fit.tip - truth) < (3e-3 if known else 6e-3)
    ARM.check(fit.config)
    assert not fit.confidence.poor_fit
    if not known:
        monkeypatch.setattr(fitting, "loop_config", lambda *a, **k: None)
        seg, without = fit_cloud(cloud, ARM, lengths, eye=sim.camera.eye)
        assert np.linalg.norm(without.tip - truth) > 0.02
