"""Animated Meshcat scenes of a wrap (pydrake's built-in Meshcat).

`show_wrap` builds a WrapScene with a MeshcatVisualizer, animates a wrap's list of
configurations as a recording, draws contacts (spheres plus normal segments) and optional
chords, aims the camera at the object, and `save_html` writes a self-contained page
(Meshcat.StaticHtml) that any browser replays without a server.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files import write_atomic
from ..kinematics.arm import ArmConfig, ContinuumArm
from ..wrapping.contact import Contacts

__all__ = ["CONTACT_COLOR", "CHORD_COLOR", "make_meshcat", "set_camera", "draw_contacts",
           "draw_chords", "animate", "show_wrap", "save_html"]


CONTACT_COLOR = (0.85, 0.1, 0.1, 1.0)
CHORD_COLOR = (0.1, 0.35, 0.85, 1.0)


# ----------------------------------------------------------------- Meshcat
def make_meshcat():
    """A pydrake Meshcat server on a free localhost port (prints nothing; see web_url())."""
    from pydrake.geometry import Meshcat, MeshcatParams
    params = MeshcatParams()
    params.port = None  # first free port from 7000
    return Meshcat(params)


def set_camera(meshcat, target, distance: float = 0.45, elevation_deg: float = 35.0,
               azimuth_deg: float = -60.0) -> None:
    """Look at `target` from `distance` metres, so that a tabletop object fills the view."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    eye = np.asarray(target, float) + distance * np.array(
        [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    meshcat.SetCameraPose(eye, np.asarray(target, float))


def draw_contacts(meshcat, contacts: Contacts, path: str = "/contacts",
                  radius: float = 0.003, normal_length: float = 0.02) -> None:
    """Contacts as small red spheres with segments along their normals (object -> arm)."""
    from pydrake.geometry import Rgba, Sphere
    from pydrake.math import RigidTransform
    meshcat.Delete(path)
    color = Rgba(*CONTACT_COLOR)
    for i, p in enumerate(contacts.p):
        meshcat.SetObject(f"{path}/p{i}", Sphere(radius), color)
        meshcat.SetTransform(f"{path}/p{i}", RigidTransform(p))
    if len(contacts):
        meshcat.SetLineSegments(f"{path}/normals", contacts.p.T.copy(),
                                (contacts.p + normal_length * contacts.n).T.copy(), 2.0, color)


def draw_chords(meshcat, start, end, path: str = "/chords") -> None:
    """Chords as line segments from start (m, 3) to end (m, 3)."""
    from pydrake.geometry import Rgba
    start, end = np.atleast_2d(start), np.atleast_2d(end)
    meshcat.Delete(path)
    if len(start):
        meshcat.SetLineSegments(path, start.T.copy(), end.T.copy(), 1.0, Rgba(*CHORD_COLOR))


def animate(scene, configs, dt: float = 0.05) -> None:
    """Record the scene passing through `configs` (ArmConfigs or rows of as_vector()) and
    publish the recording: Meshcat replays it, and StaticHtml carries it."""
    if scene.visualizer is None:
        raise ValueError("animate: the WrapScene was built without a meshcat")
    configs = [c if isinstance(c, ArmConfig) else ArmConfig.from_vector(c) for c in configs]
    scene.visualizer.StartRecording(False)
    for i, config in enumerate(configs):
        scene.context.SetTime(i * dt)
        scene.set_config(config)
        scene.diagram.ForcedPublish(scene.context)
    scene.visualizer.StopRecording()
    scene.visualizer.PublishRecording()


def show_wrap(arm: ContinuumArm, object_mesh, configs, contacts: Contacts | None = None,
              chords=None, meshcat=None, object_pose=None, dt: float = 0.05,
              html_path=None):
    """Show a wrap in Meshcat: the object, the arm animated through `configs`, the final
    contacts and optional chords ((start, end) arrays), the camera on the object.

    Args:
        arm: the arm.
        object_mesh: a mesh path or trimesh.Trimesh (as WrapScene takes).
        configs: the wrap's configurations (ArmConfigs or a (k, 3n) array); at least one.
        contacts: contacts to draw (default: those of the last configuration).
        chords: optional (start (m, 3), end (m, 3)).
        meshcat: a pydrake Meshcat (default: a new one on a free port).
        object_pose: as WrapScene takes.
        dt: seconds between recorded configurations.
        html_path: also save the self-contained page there.

    Returns:
        (meshcat, scene). The URL is printed.
    """
    from ..wrapping.scene import WrapScene
    meshcat = meshcat if meshcat is not None else make_meshcat()
    scene = WrapScene(arm, object_mesh, object_pose=object_pose, meshcat=meshcat)
    configs = list(configs)
    if not configs:
        raise ValueError("show_wrap: no configurations to show")
    animate(scene, configs, dt)
    if contacts is None:
        contacts = scene.contacts()
    draw_contacts(meshcat, contacts)
    if chords is not None:
        draw_chords(meshcat, *chords)
    lo, hi = scene.object_trimesh.bounds
    set_camera(meshcat, (lo + hi) / 2, distance=max(0.3, 1.8 * float(np.linalg.norm(hi - lo))))
    meshcat.SetProperty("/Grid", "visible", False)  # a 10 m grid dwarfs a tabletop scene
    meshcat.SetProperty("/Axes", "visible", False)
    print(f"Meshcat: {meshcat.web_url()}")
    if html_path is not None:
        save_html(meshcat, html_path)
    return meshcat, scene


def save_html(meshcat, path) -> Path:
    """Write the scene (with its recording) as one self-contained HTML page, atomically."""
    return write_atomic(path, meshcat.StaticHtml().encode())


