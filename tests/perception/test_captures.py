"""A folder of captured wraps (perception/captures.py, `classify-captures`): simulated captures
of an object the model never saw classify as its exact wraps do, in order, and a sidecar
without what classification needs is named."""

import json

import numpy as np
import pytest

from drake_continuum import cli
from drake_continuum.kinematics.arm import MODELS_DIR, load_arm
from drake_continuum.learning.model import classify, load_model
from drake_continuum.objects.mesh import load_mesh
from drake_continuum.perception.captures import (
    CaptureError,
    captured_result,
    fit_capture,
    read_captures,
    write_captures,
)
from drake_continuum.perception.cloud import PointCloudError, sidecar_eyes
from drake_continuum.perception.depth_camera import CameraPose
from drake_continuum.perception.observe import observe_wrap
from drake_continuum.wrapping.planes import enumerate_planes
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import wrap
from synthetic_wraps import separable_objects, write_collection


@pytest.fixture(scope="module")
def scene():
    return WrapScene(load_arm(), load_mesh(MODELS_DIR / "mug.obj"))


@pytest.fixture(scope="module")
def setup(tmp_path_factory, scene):
    root = tmp_path_factory.mktemp("captures")
    write_collection(root / "wraps", separable_objects(4, 3))
    assert cli.main(["train", str(root / "wraps"), "--out", str(root / "model")]) == 0
    arm = scene.arm
    planes = enumerate_planes(arm.base_position, 22.5)
    wraps = [wrap(scene, planes[i]) for i in (2, 0)]  # captured in this order
    write_captures(arm, wraps, scene.object_trimesh, root / "mug", seed=4)
    return root, arm, wraps


def test_captured_wraps_classify_as_the_exact_ones(setup, capsys):
    root, _, wraps = setup
    capsys.readouterr()
    assert cli.main(["classify-captures", str(root / "model"), str(root / "mug"),
                     "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    exact = classify(load_model(root / "model"), sorted(wraps, key=lambda w: w.plane_index))
    assert out["category"] == exact.category
    for c, p in exact.probabilities.items():
        assert out["probabilities"][c] == pytest.approx(p, abs=0.05)
    assert [s["n_captures"] for s in out["steps"]] == [1, 2]
    assert [o["plane"] for o in out["observations"]] == [2, 0]  # the files' order
    assert all("ambiguous" in o and "confident" in o for o in out["observations"])


def test_a_captured_wrap_on_the_exact_arm_matches_the_wrap(setup):
    _, arm, wraps = setup
    w = wraps[0]
    again = captured_result(w.arm(arm), w.final_config, w.plane_index, w.plane_normal,
                            w.contacts.arc_length)
    np.testing.assert_allclose(again.samples_position, w.samples_position, atol=1e-9)
    assert again.tip_rotation == pytest.approx(w.tip_rotation, abs=1e-6)
    # Touch says where along the arm, not where round it: each contact lies on the tube at
    # its arc length, within the tube's diameter of the wrap's own.
    wrap_arm = w.arm(arm)
    centre = wrap_arm.backbone(w.final_config, again.contacts.arc_length).position
    np.testing.assert_allclose(np.linalg.norm(again.contacts.p - centre, axis=1), arm.radius)
    order = np.argsort(w.contacts.arc_length)
    assert np.all(np.linalg.norm(again.contacts.p - w.contacts.p[order], axis=1)
                  <= 2 * arm.radius + 1e-3)


def test_a_sidecar_without_the_plane_is_named(setup, tmp_path):
    root, arm, _ = setup
    folder = tmp_path / "bad"
    folder.mkdir()
    for p in (root / "mug").iterdir():
        (folder / p.name).write_bytes(p.read_bytes())
    side = folder / "capture_00.json"
    meta = json.loads(side.read_text())
    del meta["plane"]
    side.write_text(json.dumps(meta))
    with pytest.raises(CaptureError, match=r"capture_00\.json: no 'plane'"):
        read_captures(folder, arm)


def test_every_route_fits_a_capture_with_the_same_evidence(setup, scene, capsys):
    """observe_wrap, the capture folder (its sidecar) and `fit-cloud` fit one simulated
    capture: the same camera to the bit, base, section lengths and wrap plane, and tips that
    agree with each other and with the wrap's own (the cloud file holds float32 points)."""
    root, arm, wraps = setup
    w = wraps[0]  # capture_00.pcd, its noise seeded 4
    capture = read_captures(root / "mug", arm)[0]
    assert [tuple(e) for e in capture.eyes] == [CameraPose().eye]
    np.testing.assert_array_equal(capture.lengths, w.final_config.s)
    np.testing.assert_allclose(capture.arm.base_rotation, w.arm(arm).base_rotation, atol=1e-12)
    np.testing.assert_allclose(capture.arm.base_position, w.arm(arm).base_position, atol=1e-12)
    truth = w.arm(arm).tip_frame(w.final_config)[1]
    seen = observe_wrap(w, arm, scene.object_trimesh, seed=4).wrap
    tips = {"observe_wrap": w.arm(arm).tip_frame(seen.final_config)[1],
            "capture": capture.arm.tip_frame(
                fit_capture(capture, w.plane_normal).wrap.final_config)[1]}
    capsys.readouterr()
    assert cli.main(["fit-cloud", str(root / "mug" / "capture_00.pcd"), "--json", "--lengths",
                     ",".join(map(repr, w.final_config.s.tolist())), "--plane-normal",
                     ",".join(map(repr, w.plane_normal.tolist()))]) == 0
    tips["fit-cloud"] = np.array(json.loads(capsys.readouterr().out)["tip"])
    for route, tip in tips.items():
        assert np.linalg.norm(tip - truth) < 3e-3, route
        assert np.linalg.norm(tip - tips["observe_wrap"]) < 1e-3, route
    assert cli.main(["fit-cloud", str(root / "mug" / "capture_00.pcd"), "--plane-normal",
                     "0,0,0"]) == 1
    assert "--plane-normal: the wrap plane's normal must be 3 finite numbers" in \
        capsys.readouterr().err


def test_views_with_and_without_a_camera_are_refused(tmp_path):
    (tmp_path / "a.json").write_text(json.dumps({"camera": {"eye": [0.3, -0.5, 0.85]}}))
    (tmp_path / "b.json").write_text(json.dumps({"capture": "kinect"}))
    with pytest.raises(PointCloudError, match=r"b\.json: no 'camera'"):
        sidecar_eyes([tmp_path / "a.pcd", tmp_path / "b.pcd"])
    assert sidecar_eyes([tmp_path / "b.pcd"]) is None
    np.testing.assert_array_equal(sidecar_eyes([tmp_path / "a.pcd"])[0], [0.3, -0.5, 0.85])

