"""The station: the continuum arm, one object and the table in a Drake Diagram with named
ports, as Drake's hardware-station examples build theirs.

Ports (units SI):

- input  `arm_configuration`: (3n,) [s_1, kappa_1, phi_1, s_2, ...] (ArmConfig.as_vector).
- input  `base_pose`: RigidTransform X_WB of the arm's base; optional, the arm's own when
  not connected.
- output `touches`: Contacts, the contact regions {p, n, t, b, section} with the object (the
  paper's tactile skin), from SceneGraph's hydroelastic contact surfaces.
- output `body_poses`: list of RigidTransform X_WL, one a capsule (link j on section
  j // links_per_section).
- output `query_object`: SceneGraph's QueryObject.
- output `depth_image`, `color_image`, `point_cloud`: the camera's (with camera=True).

The arm is kinematic: ArmPoser poses each capsule on the constant-curvature arc and
MultibodyPositionToGeometryPose hands the poses to SceneGraph, so the plant holds the model
(bodies and geometry) but no state the arm's configuration would have to be written into.
"""

from __future__ import annotations

import numpy as np
import trimesh
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    Box,
    GeometryInstance,
    HydroelasticContactRepresentation,
    MakePhongIllustrationProperties,
    MeshcatVisualizer,
    PerceptionProperties,
    QueryObject,
    Rgba,
    SceneGraph,
    Sphere,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from ..config import Config, load_config
from ..errors import ConfigError
from ..kinematics.arm import ArmConfig, ContinuumArm
from ..objects.mesh import closed_mesh
from ..perception.depth_camera import TABLE_COLOUR, CameraPose, KinectModel
from ..wrapping.contact import Contacts, contact_regions
from ..wrapping.scene import (
    SceneOptions,
    WrapScene,
    capsule_poses,
    object_shape,
    register_scene,
)
from ._camera import add_camera

__all__ = ["ArmPoser", "Station", "TouchPins", "TouchSensor", "make_station"]


class _ArmInputs(LeafSystem):
    """The arm's two inputs, shared by the systems that read them."""

    def __init__(self, arm: ContinuumArm, k: int, link_length: float):
        super().__init__()
        self.arm, self._k, self._link_length = arm, k, link_length
        self._config = self.DeclareVectorInputPort("arm_configuration", 3 * arm.n_sections)
        self._base = self.DeclareAbstractInputPort("base_pose",
                                                   AbstractValue.Make(RigidTransform()))

    def posed(self, context):
        """(arm on its base, config, capsule arcs, backbone samples, (n_links, 7) poses)."""
        config = ArmConfig.from_vector(self._config.Eval(context))
        arm = self.arm
        if self._base.HasValue(context):
            X_WB = self._base.Eval(context)
            arm = arm.with_base(position=X_WB.translation(), rotation=X_WB.rotation().matrix())
        arm.check(config)
        return (arm, config, *capsule_poses(arm, config, self._k, self._link_length))


class ArmPoser(_ArmInputs):
    """Configuration in, the capsules' poses out: `positions` (the plant's free-body
    positions, for MultibodyPositionToGeometryPose) and `body_poses`."""

    def __init__(self, arm: ContinuumArm, plant: MultibodyPlant, bodies, k: int,
                 link_length: float):
        super().__init__(arm, k, link_length)
        self._plant = plant  # MultibodyPositionToGeometryPose holds it without owning it
        self._start = np.array([b.floating_positions_start() for b in bodies])
        self.DeclareVectorOutputPort("positions", plant.num_positions(), self._positions)
        self.DeclareAbstractOutputPort("body_poses", lambda: AbstractValue.Make([]),
                                       self._body_poses)

    def _positions(self, context, output: BasicVector) -> None:
        poses = self.posed(context)[-1]
        q = np.zeros(output.size())
        q[self._start[:, None] + np.arange(7)[None, :]] = poses
        output.SetFromVector(q)

    def _body_poses(self, context, output) -> None:
        bb = self.posed(context)[3]
        R = np.stack([bb.normal, bb.binormal, bb.tangent], axis=-1)
        output.set_value([RigidTransform(RotationMatrix(r), p) for r, p in zip(R, bb.position)])


class TouchSensor(_ArmInputs):
    """The tactile skin: SceneGraph's hydroelastic contact surfaces between the capsules and
    the object, gathered into contact regions (`wrapping.contact.contact_regions`, as
    WrapScene.contacts gathers its own)."""

    def __init__(self, arm: ContinuumArm, arm_ids, object_geometry, k: int,
                 link_length: float):
        super().__init__(arm, k, link_length)
        self._link_of = {gid: j for j, gid in enumerate(arm_ids)}
        self._object = object_geometry
        self._query = self.DeclareAbstractInputPort("query_object",
                                                    AbstractValue.Make(QueryObject()))
        self.DeclareAbstractOutputPort("touches", lambda: AbstractValue.Make(Contacts.empty()),
                                       self._touches)

    def _capsule_of(self, surface) -> int:
        link = self._link_of
        return link[surface.id_M()] if surface.id_M() in link else link[surface.id_N()]

    def _touches(self, context, output) -> None:
        query = self._query.Eval(context)
        if not query.HasCollisions():
            output.set_value(Contacts.empty())
            return
        surfaces = query.ComputeContactSurfaces(HydroelasticContactRepresentation.kPolygon)
        _, config, arcs, bb, _ = self.posed(context)
        output.set_value(contact_regions(surfaces, self._object, self._capsule_of,
                                         config=config, arcs=arcs,
                                         frames=(bb.position, bb.tangent, bb.normal),
                                         k=self._k))


class Station(Diagram):
    """The station Diagram (`make_station` builds it), which also knows what it holds: the
    arm (`arm`, on its own base), the object (`object_mesh` in its frame, posed at `X_WO`)
    and the contact model (`options`)."""

    def __init__(self, builder: DiagramBuilder, arm: ContinuumArm, mesh: trimesh.Trimesh,
                 X_WO: RigidTransform, options: SceneOptions):
        super().__init__()
        builder.BuildInto(self)
        self.set_name("station")
        self.arm, self.object_mesh, self.X_WO, self.options = arm, mesh, X_WO, options

    def scene(self) -> WrapScene:
        """A WrapScene of the same arm, object and contact model (a controller's own, for
        the contact questions its enclosing motions ask)."""
        return WrapScene(self.arm, self.object_mesh, object_pose=self.X_WO,
                         options=self.options)


class TouchPins(LeafSystem):
    """Draws the touches in Meshcat every `period` s, each as a red ball just outside the
    tube along its normal (object to arm), and records them while Meshcat records (a fixed
    pool of `n_max` balls shown and hidden: a recording animates poses and visibility, not
    new geometry). Drake's ContactVisualizer draws a MultibodyPlant's contact results, which
    the kinematic arm's plant does not compute."""

    def __init__(self, meshcat, radius: float, period: float = 0.05, n_max: int = 16,
                 path: str = "/touches"):
        super().__init__()
        self._meshcat, self._offset, self._path, self._n = meshcat, 2 * radius + 0.004, path, n_max
        self._touches = self.DeclareAbstractInputPort("touches",
                                                      AbstractValue.Make(Contacts.empty()))
        for j in range(n_max):
            meshcat.SetObject(f"{path}/{j}", Sphere(0.003), Rgba(0.85, 0.1, 0.1, 1.0))
            meshcat.SetProperty(f"{path}/{j}", "visible", False)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._draw)
        self.DeclareForcedPublishEvent(self._draw)

    def _draw(self, context) -> None:
        touches, t = self._touches.Eval(context), context.get_time()
        heads = touches.p + self._offset * touches.n
        for j in range(self._n):
            shown = j < len(heads)
            if shown:
                self._meshcat.SetTransform(f"{self._path}/{j}", RigidTransform(heads[j]), t)
            self._meshcat.SetProperty(f"{self._path}/{j}", "visible", shown, t)


def make_station(config: Config | None = None, *, object_mesh, X_WO: RigidTransform | None = None,
                 table: bool | None = None, camera: bool = True,
                 camera_pose: CameraPose = CameraPose(), kinect: KinectModel = KinectModel(),
                 noise_seed: int | None = 0, meshcat=None,
                 options: SceneOptions = SceneOptions()) -> Station:
    """The station Diagram (ports: the module's docstring).

    Args:
        config: the experiment configuration (its arm, and wrap.table for the table);
            default models/config.yaml.
        object_mesh: path of a closed triangle mesh in metres, or a trimesh.Trimesh.
        X_WO: the object's pose in the world (default identity: stored objects stand in
            their pose already).
        table: the table top under z = 0 takes part in contact (its touches are not the
            object's, so only the scene's queries change); default config.wrap.table. It is
            drawn either way: the object stands on it, and the camera sees it.
        camera: add the depth camera (RgbdSensor with VTK, Kinect noise, point cloud).
        camera_pose, kinect, noise_seed: the camera's pose, sensor model and noise seed
            (None: noiseless).
        meshcat: a pydrake Meshcat to draw the scene (MeshcatVisualizer) and the touches
            (TouchPins) in, or None.
        options: the contact model (capsules a section, resolution hint, modulus).
    """
    config = load_config() if config is None else config
    if not isinstance(config, Config):
        raise ConfigError(f"make_station: config must be a Config, got {type(config).__name__}")
    arm = config.arm()
    table = config.wrap.table if table is None else table
    X_WO = RigidTransform() if X_WO is None else X_WO
    mesh = closed_mesh(object_mesh)

    builder = DiagramBuilder()
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    plant = MultibodyPlant(0.0)
    plant.set_name("plant")
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    options = SceneOptions(**{**options.__dict__, "table": table})
    geometry = register_scene(plant, scene_graph, arm, object_shape(mesh), X_WO, options,
                              visual=object_shape(mesh, normals=True))
    _draw_table(scene_graph, plant.get_source_id())
    k = options.links_per_section
    link_length = arm.section_length_max / k

    poser = builder.AddNamedSystem("arm_poser", ArmPoser(arm, plant, geometry.bodies, k,
                                                         link_length))
    to_pose = builder.AddNamedSystem("to_geometry_pose", MultibodyPositionToGeometryPose(plant))
    builder.Connect(poser.GetOutputPort("positions"), to_pose.get_input_port())
    builder.Connect(to_pose.get_output_port(),
                    scene_graph.get_source_pose_port(plant.get_source_id()))
    touch = builder.AddNamedSystem("touch_sensor", TouchSensor(
        arm, geometry.arm_ids, geometry.object_geometry, k, link_length))
    builder.Connect(scene_graph.get_query_output_port(), touch.GetInputPort("query_object"))
    for name in ("arm_configuration", "base_pose"):
        builder.ExportInput(poser.GetInputPort(name), name)
        builder.ConnectInput(name, touch.GetInputPort(name))
    builder.ExportOutput(touch.GetOutputPort("touches"), "touches")
    builder.ExportOutput(poser.GetOutputPort("body_poses"), "body_poses")
    builder.ExportOutput(scene_graph.get_query_output_port(), "query_object")
    if camera:
        sensor, _, to_cloud = add_camera(builder, scene_graph, pose=camera_pose, model=kinect,
                                         seed=noise_seed)
        builder.ExportOutput(builder.GetSubsystemByName("kinect_noise").get_output_port(),
                             "depth_image")
        builder.ExportOutput(sensor.color_image_output_port(), "color_image")
        builder.ExportOutput(to_cloud.point_cloud_output_port(), "point_cloud")
    if meshcat is not None:
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat)
        pins = builder.AddNamedSystem("touch_pins", TouchPins(meshcat, arm.radius))
        builder.Connect(touch.GetOutputPort("touches"), pins.get_input_port())
    return Station(builder, arm, mesh, X_WO, options)


def _draw_table(scene_graph, source_id) -> None:
    """The table top as seen (illustration and perception; its collision geometry is
    register_scene's)."""
    colour = Rgba(*TABLE_COLOUR, 1.0)
    table = GeometryInstance(RigidTransform([0, 0, -0.025]), Box(1.5, 1.5, 0.05), "table_visual")
    table.set_illustration_properties(MakePhongIllustrationProperties(colour.rgba))
    perception = PerceptionProperties()
    perception.AddProperty("phong", "diffuse", colour)
    table.set_perception_properties(perception)
    scene_graph.RegisterAnchoredGeometry(source_id, table)


