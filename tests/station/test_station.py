"""The station Diagram: its touches equal WrapScene's contact query, its camera's cloud lies
on the arm, object and table, its noise has the Kinect model's spread, and a wrap simulated
with the WrapController equals wrap()."""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.sensors import ImageDepth32F
from scipy.spatial import cKDTree

from drake_continuum.config import load_config
from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig
from drake_continuum.perception.depth_camera import KinectModel
from drake_continuum.station import KinectNoise, WrapController, make_station
from drake_continuum.wrapping.planes import enumerate_planes
from drake_continuum.wrapping.scene import WrapScene
from drake_continuum.wrapping.wrap import WrapParams, wrap

MUG = MODELS_DIR / "mug.obj"


@pytest.fixture(scope="module")
def config():
    return load_config()


@pytest.fixture(scope="module")
def scene(config):
    return WrapScene(config.arm(), MUG)


@pytest.fixture(scope="module")
def mug_wrap(config, scene):
    return wrap(scene, enumerate_planes(config.arm().base_position)[1])


def _fix(station, context, config: ArmConfig, X_WB: RigidTransform) -> None:
    station.GetInputPort("arm_configuration").FixValue(context, config.as_vector())
    station.GetInputPort("base_pose").FixValue(context, X_WB)


def test_touches_equal_the_scene_contact_query(config, scene, mug_wrap):
    """Every configuration of a wrap of the mug (free, touching, curled round it): the
    station's touches, from its own SceneGraph, equal WrapScene.contacts()."""
    arm = config.arm()
    station = make_station(config, object_mesh=MUG, table=False, camera=False)
    context = station.CreateDefaultContext()
    X_WB = RigidTransform(RotationMatrix(mug_wrap.base_rotation), arm.base_position)
    touched = 0
    for q in mug_wrap.configs:
        c = ArmConfig.from_vector(q)
        _fix(station, context, c, X_WB)
        got = station.GetOutputPort("touches").Eval(context)
        scene.arm = arm.with_base(rotation=mug_wrap.base_rotation)
        scene.set_config(c)
        want = scene.contacts()
        scene.arm = arm
        assert len(got) == len(want)
        for field in ("p", "n", "t", "b", "arc_length", "area"):
            np.testing.assert_allclose(getattr(got, field), getattr(want, field), atol=1e-12)
        np.testing.assert_array_equal(got.section, want.section)
        touched += len(want) > 0
    assert touched >= 3
    # body_poses: each capsule's centre on the arc, its z axis along the tangent (closed
    # form of the capsules' arc lengths: WrapScene.link_arc_lengths).
    poses = station.GetOutputPort("body_poses").Eval(context)
    c = ArmConfig.from_vector(mug_wrap.configs[-1])
    bb = arm.with_base(rotation=mug_wrap.base_rotation).backbone(c, scene.link_arc_lengths(c))
    np.testing.assert_allclose([X.translation() for X in poses], bb.position, atol=1e-12)
    np.testing.assert_allclose([X.rotation().col(2) for X in poses], bb.tangent, atol=1e-12)


def test_the_camera_sees_the_arm_object_and_table_where_they_are(config, scene, mug_wrap):
    """A noiseless cloud of the wrapped mug on the table: every point lies on the arm's tube
    (distance to the FK centre line minus the radius), the mug's surface or the table top."""
    arm = config.arm().with_base(rotation=mug_wrap.base_rotation)
    model = KinectModel(width=320, height=240, focal=262.5)  # half the pixels, same view
    station = make_station(config, object_mesh=MUG, table=True, kinect=model, noise_seed=None)
    context = station.CreateDefaultContext()
    c = ArmConfig.from_vector(mug_wrap.configs[-1])
    _fix(station, context, c, RigidTransform(RotationMatrix(arm.base_rotation),
                                             arm.base_position))
    xyz = station.GetOutputPort("point_cloud").Eval(context).xyzs().T
    xyz = xyz[np.isfinite(xyz).all(axis=1)]
    line = arm.backbone(c, n=4000).position  # 0.15 mm apart: exact to 1e-5 mm off the tube
    to_arm = np.abs(cKDTree(line).query(xyz)[0] - arm.radius)
    to_mug = np.abs(scene.signed_distance(xyz))
    gap = np.minimum(np.minimum(to_arm, to_mug), np.abs(xyz[:, 2]))
    assert len(xyz) > 0.8 * model.width * model.height  # the table fills most of the view
    assert (to_arm < 2e-3).sum() > 500  # the wrapped arm is in view
    # The capsules are chords of the arc (sagitta <= 2 mm at the curvature limit).
    assert np.percentile(gap, 99) < 2e-3 and gap.max() < 5e-3


def test_kinect_noise_has_the_models_spread():
    """A wall sloping from 0.9 to 1.1 m (no depth edges, every quantisation phase): the
    depth error over z^2 has the model's spread sigma_coeff (closed form: a constant
    disparity error), and no bias."""
    model = KinectModel()
    noise = KinectNoise(model, seed=3)
    context = noise.CreateDefaultContext()
    true = np.broadcast_to(np.linspace(0.9, 1.1, model.width), (model.height, model.width))
    wall = ImageDepth32F(model.width, model.height)
    wall.mutable_data[:, :, 0] = true
    noise.get_input_port().FixValue(context, wall)
    z = noise.get_output_port().Eval(context).data[:, :, 0].astype(float)
    error = (z - wall.data[:, :, 0]) / true ** 2
    assert abs(error.std() - model.sigma_coeff) < 0.03 * model.sigma_coeff
    assert abs(error.mean()) < 0.03 * model.sigma_coeff
    context.SetTime(0.05)  # a later image draws other noise
    assert not np.array_equal(noise.get_output_port().Eval(context).data[:, :, 0], z)


def _simulate(station_builder_args, scene, plane, params):
    builder = DiagramBuilder()
    station = builder.AddSystem(make_station(**station_builder_args))
    controller = WrapController.AddToBuilder(builder, station, scene=scene, plane=plane,
                                             params=params)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(np.inf)
    return controller.result()


@pytest.mark.parametrize("k", [1, 2])
def test_a_simulated_wrap_equals_wrap(config, k):
    """The WrapController in a Simulator drives the same WrapStepper as wrap(): same status,
    configurations and contacts (the advancing motions read the station's touches)."""
    arm = config.arm()
    plane = enumerate_planes(arm.base_position)[k]
    params = WrapParams()
    want = wrap(WrapScene(arm, MUG), plane, params)
    got = _simulate(dict(config=config, object_mesh=MUG, table=False, camera=False),
                    WrapScene(arm, MUG), plane, params)
    assert got.status == want.status
    np.testing.assert_allclose(got.configs, want.configs, atol=1e-9)
    based = arm.with_base(rotation=want.base_rotation)
    np.testing.assert_allclose(based.backbone(got.final_config, n=400).position,
                               based.backbone(want.final_config, n=400).position, atol=1e-6)
    np.testing.assert_allclose(got.contacts.p, want.contacts.p, atol=1e-9)
    np.testing.assert_allclose(got.samples_position, want.samples_position, atol=1e-9)


class _Meshcat:
    """Records the calls TouchPins makes."""

    def __init__(self):
        self.visible, self.where = {}, {}

    def SetObject(self, path, shape, rgba):
        self.visible[path] = None

    def SetProperty(self, path, name, value, time_in_recording=None):
        self.visible[path] = (value, time_in_recording)

    def SetTransform(self, path, X, time_in_recording=None):
        self.where[path] = (X.translation(), time_in_recording)


def test_touch_pins_show_each_touch_outside_the_tube_and_hide_the_rest():
    from drake_continuum.station import TouchPins
    from drake_continuum.wrapping.contact import Contacts

    meshcat, radius = _Meshcat(), 0.01
    pins = TouchPins(meshcat, radius, n_max=4)
    assert all(v == (False, None) for v in meshcat.visible.values())
    p, n = np.array([[0.1, 0, 0], [0, 0.2, 0]]), np.array([[0, 0, 1.0], [1.0, 0, 0]])
    touches = Contacts(p, n, n[::-1], np.cross(n, n[::-1]), np.array([0, 2]),
                       np.array([0.1, 0.3]), np.array([1e-4, 2e-4]))
    context = pins.CreateDefaultContext()
    context.SetTime(0.25)
    pins.get_input_port().FixValue(context, touches)
    pins.ForcedPublish(context)
    assert [meshcat.visible[f"/touches/{j}"] for j in range(4)] == [
        (True, 0.25), (True, 0.25), (False, 0.25), (False, 0.25)]
    for j in range(2):  # a tube's diameter and 4 mm out along the normal
        np.testing.assert_allclose(meshcat.where[f"/touches/{j}"][0], p[j] + 0.024 * n[j])


def test_bad_input_is_named(config):
    from drake_continuum.errors import ConfigError
    from drake_continuum.kinematics.arm import ArmLimitError
    from drake_continuum.objects.mesh import MeshError

    with pytest.raises(ConfigError, match="make_station: config must be a Config"):
        make_station("models/config.yaml", object_mesh=MUG)
    with pytest.raises(MeshError, match="nowhere.obj: file not found"):
        make_station(config, object_mesh="nowhere.obj")
    station = make_station(config, object_mesh=MUG, camera=False)
    context = station.CreateDefaultContext()
    station.GetInputPort("arm_configuration").FixValue(
        context, ArmConfig([0.1, 0.9, 0.1], [0.0] * 3, [0.0] * 3).as_vector())
    with pytest.raises(ArmLimitError, match=r"section 2: length s = 0.9 m outside"):
        station.GetOutputPort("touches").Eval(context)
