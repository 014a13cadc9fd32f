"""compare-real against the wrong object says so from the geometry alone: the fitted arm floats
beside it or cuts through it (the sidecar that would name the object is left behind)."""

import json
import logging
import shutil

import numpy as np
import pytest
from pydrake.math import RollPitchYaw

from drake_continuum.kinematics.arm import ArmConfig, load_arm
from drake_continuum.perception.cloud import SAMPLE_CLOUDS, load_cloud
from drake_continuum.perception.comparison import OBJECT_TOLERANCE, compare_real
from drake_continuum.perception.fitting import fit_cloud


@pytest.mark.parametrize("cloud, right, wrong, says", [
    ("box_0", "box.obj", "cylinder.obj", "does not touch the object"),
    ("cylinder_1", "cylinder.obj", "box.obj", "mm into the object"),
])
def test_the_wrong_object_is_flagged_and_the_right_one_is_not(tmp_path, caplog, cloud, right,
                                                               wrong, says):
    meta = json.loads((SAMPLE_CLOUDS / f"{cloud}.json").read_text())
    shutil.copy(SAMPLE_CLOUDS / f"{cloud}.pcd", tmp_path)  # without its sidecar
    arm = load_arm().with_base(np.asarray(meta["base_position"], float),
                               RollPitchYaw(meta["base_rpy"]).ToRotationMatrix().matrix())
    points = load_cloud(tmp_path / f"{cloud}.pcd")
    seg, fit = fit_cloud(points, arm, ArmConfig.from_dict(meta["config"]).s)
    with caplog.at_level(logging.WARNING):
        good = compare_real(points, seg, fit, arm, SAMPLE_CLOUDS / right)
    assert good["object_matches"] and "warning" not in good and not caplog.records
    assert -OBJECT_TOLERANCE * 1e3 <= good["object_check"]["closest_gap_mm"] <= 1.0
    with caplog.at_level(logging.WARNING):
        bad = compare_real(points, seg, fit, arm, SAMPLE_CLOUDS / wrong)
    assert not bad["object_matches"] and says in bad["warning"]
    assert says in caplog.text and str(SAMPLE_CLOUDS / wrong) in caplog.text
    # Off by more than the tolerance: floating beside it, or cutting through it.
    assert abs(bad["object_check"]["closest_gap_mm"]) > 2 * OBJECT_TOLERANCE * 1e3
