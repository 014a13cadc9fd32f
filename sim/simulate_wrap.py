"""Simulate a wrap of the demo mug: wrap.html (the Meshcat recording) and cloud.ply here."""
import numpy as np
from pydrake.all import DiagramBuilder, Simulator

from drake_continuum.config import load_config
from drake_continuum.kinematics.arm import MODELS_DIR
from drake_continuum.perception.depth_camera import write_cloud
from drake_continuum.station import WrapController, make_station
from drake_continuum.viz.meshcat import draw_contacts, make_meshcat, save_html, set_camera
from drake_continuum.wrapping.planes import enumerate_planes

config, meshcat, builder = load_config(), make_meshcat(), DiagramBuilder()
station = builder.AddSystem(make_station(config, object_mesh=MODELS_DIR / "mug.obj",
                                         meshcat=meshcat))
plane = enumerate_planes(station.arm.base_position)[1]
controller = WrapController.AddToBuilder(builder, station, plane=plane, params=config.wrap)
simulator = Simulator(builder.Build())
meshcat.StartRecording()
simulator.AdvanceTo(np.inf)  # the controller ends the simulation when the wrap ends
meshcat.PublishRecording()
result = controller.result()
draw_contacts(meshcat, result.contacts, station.arm.radius)
set_camera(meshcat, [0.0, 0.0, 0.05])
save_html(meshcat, "wrap.html", title=f"mug, {plane.label}: {result.status}")
context = station.GetMyContextFromRoot(simulator.get_context())
cloud = station.GetOutputPort("point_cloud").Eval(context)
seen = np.isfinite(cloud.xyzs()).all(axis=0)
write_cloud("cloud.ply", cloud.xyzs().T[seen], cloud.rgbs().T[seen] / 255.0)
print(f"{result.status}: {len(result.contacts)} contacts, {seen.sum()} cloud points")
