"""The located object's voxelled cloud re-rendering only its window (perception/fixed_scene.py)
against the whole image rendered and voxelled (render_cloud, voxel_average): to the bit."""

import math

import numpy as np
import pytest
import trimesh

from drake_continuum.kinematics.arm import load_arm
from drake_continuum.objects.generators import generate_object
from drake_continuum.objects.placement import Placement, place
from drake_continuum.perception import fixed_scene
from drake_continuum.perception.cloud import voxel_average
from drake_continuum.perception.depth_camera import CameraPose, KinectModel, render_cloud
from drake_continuum.perception.locate import VOXEL, parked_config

ARM = load_arm()
CONFIG = parked_config(ARM)


def _whole_image(mesh, seed, camera=CameraPose()):
    sim = render_cloud(ARM, CONFIG, mesh, camera=camera, seed=seed)
    return voxel_average(sim.points, sim.colours, VOXEL)


def _assert_same_bits(ours, theirs):
    assert len(ours[0]) > 50000  # the table's voxels are there
    for a, b in zip(ours, theirs):
        assert a.shape == b.shape
        np.testing.assert_array_equal(a, b)


def _box(extents, at):
    box = trimesh.creation.box(extents=extents)
    box.apply_translation(at)
    return box


@pytest.mark.parametrize("category, index, placement, seed", [
    ("mug", 0, None, 0),
    ("hammer", 1, Placement(None, math.radians(40), (0.03, -0.02)), 0),
    ("bottle", 0, Placement(0, math.radians(-75)), 0),  # laid down
    ("teapot", 2, None, 5),
])
def test_window_render_is_the_whole_image_to_the_bit(category, index, placement, seed):
    mesh = generate_object(category, index, seed=0).posed.mesh
    if placement is not None:
        mesh = place(mesh, placement)
    ours = fixed_scene.voxelled_cloud(ARM, CONFIG, mesh, seed=seed, voxel=VOXEL)
    _assert_same_bits(ours, _whole_image(mesh, seed))


def test_a_second_object_reuses_the_scene_and_stays_exact():
    first, second = (generate_object("bowl", i, seed=0).posed.mesh for i in (0, 1))
    fixed_scene.voxelled_cloud(ARM, CONFIG, first, voxel=VOXEL)
    cached = len(fixed_scene._SCENES)
    ours = fixed_scene.voxelled_cloud(ARM, CONFIG, second, voxel=VOXEL)
    assert len(fixed_scene._SCENES) == cached
    _assert_same_bits(ours, _whole_image(second, 0))


@pytest.mark.parametrize("where, mesh", [
    ("hides the table's lowest point", _box((0.2, 0.2, 0.4), (0.0, 0.0, 0.2))),
    ("below the table, past its left edge", _box((0.1, 0.1, 0.1), (-0.62, 0.0, -0.02))),
])
def test_a_moved_voxel_grid_averages_the_whole_cloud_again(monkeypatch, where, mesh):
    calls = []
    whole = fixed_scene._whole_cloud
    monkeypatch.setattr(fixed_scene, "_whole_cloud", lambda *a, **k: calls.append(1) or
                        whole(*a, **k))
    ours = fixed_scene.voxelled_cloud(ARM, CONFIG, mesh, voxel=VOXEL)
    assert calls, where
    _assert_same_bits(ours, _whole_image(mesh, 0))


def test_an_object_behind_the_camera_renders_the_whole_image():
    camera = CameraPose()
    mesh = _box((0.1, 0.1, 0.1), (0.6, -1.0, 1.2))  # behind the eye
    assert fixed_scene._box_window(mesh, camera, KinectModel()) is None
    _assert_same_bits(fixed_scene.voxelled_cloud(ARM, CONFIG, mesh, voxel=VOXEL),
                      _whole_image(mesh, 0))


def test_the_replay_refuses_draws_out_of_order():
    recorder = fixed_scene._Recorder(0)
    recorder.random((4, 5))
    recorder.standard_normal((4, 5))
    window = (slice(1, 3), slice(0, 2))
    replay = fixed_scene._Replay(recorder.draws, window)
    np.testing.assert_array_equal(replay.random((2, 2)), recorder.draws[0][1][window])
    with pytest.raises(AssertionError):
        replay.random((2, 2))  # a normal draw comes next
