"""The start made for a coil (medial.loop_config): sections 2 and 3 at the bend limit, bent
the same way, close a loop that no ordering of the points follows."""

import numpy as np
import pytest

from drake_continuum.kinematics.arm import ArmConfig, load_arm
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


def _surface(config, step=0.003, around=16):
    """Points on the tube's surface all round (no camera)."""
    bb = ARM.backbone(config, arc_length=np.arange(0.0, float(np.sum(config.s)), step))
    ang = np.linspace(0, 2 * np.pi, around, endpoint=False)
    ring = np.cos(ang)[None, :, None] * bb.normal[:, None] \
        + np.sin(ang)[None, :, None] * bb.binormal[:, None]
    return (bb.position[:, None] + ARM.radius * ring).reshape(-1, 3)


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
