"""The station's depth camera: Drake's RgbdSensor (VTK, headless), the project's Kinect
error model as a system, and DepthImageToPointCloud.

The intrinsics, depth range and error model are perception.depth_camera's KinectModel, the
pose its CameraPose, so the station's cloud is measured as the batch camera's is; only the
renderer differs (VTK here, Open3D ray casting there)."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.perception import BaseField, DepthImageToPointCloud
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, PixelType, RgbdSensor

from ..perception.depth_camera import CameraPose, KinectModel, measured_depth

__all__ = ["RENDERER", "KinectNoise", "add_camera"]

RENDERER = "vtk"


class KinectNoise(LeafSystem):
    """Depth image in, the Kinect's measurement of it out (`measured_depth`: flying pixels,
    disparity noise and quantisation; inf where nothing is measured).

    Args:
        model: the sensor model.
        seed: the noise's seed; each image draws from (seed, time in microseconds), so a
            simulation is reproducible. None passes the image through unchanged.
    """

    def __init__(self, model: KinectModel, seed: int | None = 0):
        super().__init__()
        self._model, self._seed = model, seed
        blank = AbstractValue.Make(ImageDepth32F(model.width, model.height))
        self._depth = self.DeclareAbstractInputPort("depth_image", blank)
        self.DeclareAbstractOutputPort("depth_image", lambda: blank.Clone(), self._measure)

    def _measure(self, context, output) -> None:
        image = self._depth.Eval(context)
        out = output.get_mutable_value()
        if self._seed is None:
            out.mutable_data[:] = image.data
            return
        rng = np.random.default_rng([self._seed, int(round(context.get_time() * 1e6))])
        z = measured_depth(image.data[:, :, 0], self._model, rng)
        out.mutable_data[:, :, 0] = z.astype(np.float32)


def add_camera(builder, scene_graph, *, pose: CameraPose = CameraPose(),
               model: KinectModel = KinectModel(), seed: int | None = 0):
    """Add the depth camera looking at the scene: returns (RgbdSensor, KinectNoise,
    DepthImageToPointCloud). The cloud (world frame, m, with colours) has one point a pixel,
    NaN where nothing is measured."""
    if not scene_graph.HasRenderer(RENDERER):
        scene_graph.AddRenderer(RENDERER, MakeRenderEngineVtk(RenderEngineVtkParams()))
    info = CameraInfo(model.width, model.height, model.focal, model.focal,
                      (model.width - 1) / 2.0, (model.height - 1) / 2.0)
    core = RenderCameraCore(RENDERER, info, ClippingRange(0.01, 10.0), RigidTransform())
    X_WC = RigidTransform(RotationMatrix(pose.rotation()), np.asarray(pose.eye, float))
    sensor = builder.AddNamedSystem("camera", RgbdSensor(
        scene_graph.world_frame_id(), X_WC, ColorRenderCamera(core, False),
        DepthRenderCamera(core, DepthRange(model.z_min, model.z_max))))
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    noise = builder.AddNamedSystem("kinect_noise", KinectNoise(model, seed))
    builder.Connect(sensor.depth_image_32F_output_port(), noise.get_input_port())
    to_cloud = builder.AddNamedSystem("to_point_cloud", DepthImageToPointCloud(
        info, PixelType.kDepth32F, 1.0, BaseField.kXYZs | BaseField.kRGBs))
    builder.Connect(noise.get_output_port(), to_cloud.depth_image_input_port())
    builder.Connect(sensor.color_image_output_port(), to_cloud.color_image_input_port())
    builder.Connect(sensor.body_pose_in_world_output_port(), to_cloud.camera_pose_input_port())
    return sensor, noise, to_cloud
