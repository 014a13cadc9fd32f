"""Limits that differ by section: read from the arm file, checked, and kept by IK, the wrap and
the cloud fit."""

import numpy as np
import pytest
import trimesh
import yaml

from drake_continuum.errors import ConfigError
from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, ArmLimitError, ContinuumArm
from drake_continuum.kinematics.ik import IKOptions, bounds

# A 4-section arm whose distal section is shorter, less curved and bends less.
LAST = {"section_length_min": 0.05, "section_length_max": 0.15, "curvature_max": 15.0,
        "bend_max": 1.2}


def arm_file(folder, **change):
    d = yaml.safe_load((MODELS_DIR / "arm.yaml").read_text())
    d.update(n_sections=4, section_length_min=[0.075, 0.075, 0.075, LAST["section_length_min"]],
             section_length_max=[0.3, 0.3, 0.3, LAST["section_length_max"]],
             curvature_max=[40.0, 40.0, 40.0, LAST["curvature_max"]],
             bend_max=[np.pi, np.pi, np.pi, LAST["bend_max"]])
    d.update(change)
    path = folder / "arm4.yaml"
    path.write_text(yaml.safe_dump(d))
    return path


def test_a_list_gives_each_section_its_own_limits_and_a_number_every_section(tmp_path):
    arm = ContinuumArm.from_yaml(arm_file(tmp_path, radius=0.01))
    lo, hi, kappa, bend = arm.section_limits()
    np.testing.assert_array_equal(lo, [0.075, 0.075, 0.075, 0.05])
    np.testing.assert_array_equal(hi, [0.3, 0.3, 0.3, 0.15])
    np.testing.assert_array_equal(kappa, [40.0, 40.0, 40.0, 15.0])
    np.testing.assert_array_equal(bend, [np.pi] * 3 + [1.2])
    # The scalar fields hold the bound of any section.
    assert (arm.section_length_min, arm.section_length_max, arm.curvature_max) == (0.05, 0.3, 40)
    assert arm.length_max == pytest.approx(1.05)
    one = ContinuumArm.from_yaml(arm_file(tmp_path, curvature_max=30.0))
    np.testing.assert_array_equal(one.section_limits()[2], [30.0] * 4)
    # Section 4's curvature limit: the bend limit over its length, or its own maximum.
    np.testing.assert_allclose(arm.curvature_limit([0.2, 0.2, 0.2, 0.1]),
                               [np.pi / 0.2] * 3 + [12.0])
    assert arm.curvature_limit(0.1, section=3) == pytest.approx(12.0)
    with pytest.raises(ValueError, match="section="):
        arm.curvature_limit(0.1)
    with pytest.raises(ArmLimitError, match=r"section 4: curvature kappa = 20 1/m outside "
                                            r"\[0, 15\]"):
        arm.check(ArmConfig([0.1] * 4, [0, 0, 0, 20.0], [0] * 4))
    arm.check(ArmConfig([0.1] * 4, [0, 0, 20.0, 0], [0] * 4))  # section 3 may


@pytest.mark.parametrize("key, value, says", [
    ("curvature_max", [40.0, 40.0, 15.0], "curvature_max: must be one number or a list of "
                                          "n_sections = 4 numbers"),
    ("bend_max", [3.0, 3.0, 3.0, ".nan"], "bend_max: must be a finite number > 0 for every "
                                          "section"),
    ("section_length_max", [0.3, 0.3, 0.3, -1], "section_length_max: must be a finite number"),
    ("section_length_min", [0.075, 0.075, 0.075, 0.2], r"section_length_min: must be at most "
                                                       r"section_length_max \(0.15\) "
                                                       r"\(section 4\)"),
    ("bend_max", [3.0, 3.0, 3.0, 7.0], r"bend_max: must be at most 2 pi rad .*\(section 4\)"),
    ("curvature_max", [40.0, 40.0, 40.0, True], "curvature_max: must be a finite number"),
])
def test_a_bad_per_section_limit_is_refused_naming_the_file_and_key(tmp_path, key, value, says):
    path = arm_file(tmp_path, **{key: value})
    with pytest.raises(ConfigError, match=f"arm description {path}: {says}"):
        ContinuumArm.from_yaml(path)


def test_ik_bounds_are_each_sections_own(tmp_path):
    arm = ContinuumArm.from_yaml(arm_file(tmp_path))
    lo, hi = bounds(arm)
    lo, hi = lo.reshape(4, 3), hi.reshape(4, 3)
    np.testing.assert_array_equal(lo[:, 0], [0.075, 0.075, 0.075, 0.05])
    np.testing.assert_array_equal(hi[:, 0], [0.3, 0.3, 0.3, 0.15])
    np.testing.assert_array_equal(hi[:, 1:], [[40, 40]] * 3 + [[15, 15]])
    np.testing.assert_array_equal(lo[:, 1:], -hi[:, 1:])
    np.testing.assert_array_equal(bounds(arm, IKOptions(one_sided=True))[0].reshape(4, 3)[:, 1],
                                  0.0)


def test_a_wrap_keeps_the_last_sections_own_limits(tmp_path):
    """A cylinder of 4 cm radius: the uniform arm's last section curves to 1 / 5 cm = 20 1/m
    round it; with 15 1/m and 1.2 rad for the last section, no configuration of the wrap
    passes them, and the first three still wrap."""
    from drake_continuum.wrapping.planes import make_plane
    from drake_continuum.wrapping.scene import WrapScene
    from drake_continuum.wrapping.wrap import WrapParams, wrap

    cylinder = trimesh.creation.cylinder(radius=0.04, height=0.15, sections=128)
    cylinder.apply_translation([0.0, 0.0, 0.075])
    arms = {"own": ContinuumArm.from_yaml(arm_file(tmp_path)),
            "uniform": ContinuumArm.from_yaml(arm_file(
                tmp_path, section_length_min=0.075, section_length_max=0.3, curvature_max=40.0,
                bend_max=float(np.pi)))}
    last = {}
    for name, arm in arms.items():
        r = wrap(WrapScene(arm, cylinder), make_plane(arm.base_position, "x", 0.0),
                 WrapParams())
        assert len(r.contacts.p) > 0
        configs = [ArmConfig.from_vector(q) for q in r.configs]
        last[name] = max(c.kappa[3] for c in configs + [r.final_config])
        for c in configs + [r.final_config]:
            arm.check(c)
        if name == "own":
            for c in configs + [r.final_config]:
                assert c.kappa[3] <= LAST["curvature_max"] + 1e-9
                assert c.kappa[3] * c.s[3] <= LAST["bend_max"] + 1e-9
                assert c.s[3] <= LAST["section_length_max"] + 1e-12
    assert last["uniform"] > LAST["curvature_max"]  # the limit binds: it is not idle


def test_a_cloud_fit_keeps_the_last_sections_own_limits(tmp_path):
    """A true configuration at the last section's limit: the free-length fit stays within
    it (a uniform limit would let it curve on) and finds the tip."""
    from drake_continuum.perception import depth_camera as dc
    from drake_continuum.perception.cloud import Cloud
    from drake_continuum.perception.fitting import fit_cloud

    arm = ContinuumArm.from_yaml(arm_file(tmp_path))
    truth = ArmConfig([0.12, 0.15, 0.14, 0.08], [2.0, 8.0, 12.0, 15.0], [1.3, 1.4, 1.5, 1.6])
    arm.check(truth)
    sim = dc.render_cloud(arm, truth, None, seed=3)
    _, fit = fit_cloud(Cloud(sim.points, sim.colours), arm)
    arm.check(fit.config, tol=1e-6)
    assert np.linalg.norm(fit.tip - arm.tip_frame(truth)[1]) < 3e-3


def test_fit_cloud_lengths_are_checked_against_each_sections_range(tmp_path, capsys):
    from drake_continuum import cli
    from drake_continuum.perception.cloud import SAMPLE_CLOUDS

    arm = arm_file(tmp_path)
    rc = cli.main(["fit-cloud", str(SAMPLE_CLOUDS / "cylinder_0.pcd"), "--arm", str(arm),
                   "--lengths", "0.2,0.2,0.2,0.2"])
    assert rc != 0
    assert "--lengths: section 4 must lie in [0.05, 0.15] m" in capsys.readouterr().err
