"""Animated Meshcat scenes of a wrap (pydrake's built-in Meshcat).

`show_wrap` builds a WrapScene with a MeshcatVisualizer, animates a wrap's list of
configurations as a recording, draws contacts and optional chords, aims the camera at the
object, and `save_html` writes a self-contained page (Meshcat.StaticHtml) that any browser
replays without a server, with a title and a legend over the scene (Meshcat's own controls,
with the animation's play button, stay at the top right).

A contact lies on the arm's surface, inside its opaque tube as drawn: each is shown as a
pin along its normal (object -> arm) through the arm, with its head outside the tube.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files import write_atomic
from ..kinematics.arm import ArmConfig, ContinuumArm
from ..wrapping.contact import Contacts

__all__ = ["CONTACT_COLOR", "CHORD_COLOR", "make_meshcat", "set_camera", "contact_pins",
           "draw_contacts", "draw_chords", "animate", "show_wrap", "wrap_title", "page_overlay",
           "save_html"]


CONTACT_COLOR = (0.85, 0.1, 0.1, 1.0)
CHORD_COLOR = (0.1, 0.35, 0.85, 1.0)


# ----------------------------------------------------------------- Meshcat
def make_meshcat():
    """A pydrake Meshcat server on a free localhost port (prints nothing; see web_url())."""
    from pydrake.geometry import Meshcat, MeshcatParams
    params = MeshcatParams()
    params.port = None  # first free port from 7000
    return Meshcat(params)


def set_camera(meshcat, target, *, distance: float = 0.45, elevation_deg: float = 35.0,
               azimuth_deg: float = -60.0) -> None:
    """Look at `target` from `distance` metres, so that a tabletop object fills the view."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    eye = np.asarray(target, float) + distance * np.array(
        [np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    meshcat.SetCameraPose(eye, np.asarray(target, float))


def contact_pins(contacts: Contacts, tube_radius: float, *, head_radius: float = 0.003,
                 clearance: float = 0.004):
    """(start (c, 3), head (c, 3)) of the pins that show contacts: from each contact along
    its normal (object -> arm) across the tube's diameter, the head `clearance` beyond it,
    so it is seen outside the arm."""
    p, n = np.asarray(contacts.p, float), np.asarray(contacts.n, float)
    return p, p + (2 * tube_radius + head_radius + clearance) * n


def draw_contacts(meshcat, contacts: Contacts, tube_radius: float, *, path: str = "/contacts",
                  head_radius: float = 0.003) -> None:
    """Contacts as red pins (contact_pins): a segment along the normal, a sphere outside the
    tube."""
    from pydrake.geometry import Rgba, Sphere
    from pydrake.math import RigidTransform
    meshcat.Delete(path)
    color = Rgba(*CONTACT_COLOR)
    start, head = contact_pins(contacts, tube_radius, head_radius=head_radius)
    for i, q in enumerate(head):
        meshcat.SetObject(f"{path}/p{i}", Sphere(head_radius), color)
        meshcat.SetTransform(f"{path}/p{i}", RigidTransform(q))
    if len(start):
        meshcat.SetLineSegments(f"{path}/normals", start.T.copy(), head.T.copy(), 3.0, color)


def draw_chords(meshcat, start, end, *, path: str = "/chords") -> None:
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


def show_wrap(arm: ContinuumArm, object_mesh, configs, *, contacts: Contacts | None = None,
              chords=None, meshcat=None, object_pose=None, dt: float = 0.05,
              html_path=None, title: str | None = None):
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
        title: the saved page's title (see wrap_title), e.g. "mug_000, plane 3: complete".

    Returns:
        (meshcat, scene); the page is at meshcat.web_url() while this process runs.
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
    draw_contacts(meshcat, contacts, arm.radius)
    if chords is not None:
        draw_chords(meshcat, *chords)
    lo, hi = scene.object_trimesh.bounds
    set_camera(meshcat, (lo + hi) / 2, distance=max(0.3, 1.8 * float(np.linalg.norm(hi - lo))))
    meshcat.SetProperty("/Grid", "visible", False)  # a 10 m grid dwarfs a tabletop scene
    meshcat.SetProperty("/Axes", "visible", False)
    if html_path is not None:
        save_html(meshcat, html_path, title=title, chords=chords is not None)
    return meshcat, scene


def wrap_title(object_name: str, plane_label: str, result) -> str:
    """The page title of a wrap: object, plane, how it ended and its contacts."""
    n = len(result.contacts)
    return (f"{object_name}, {plane_label}: {result.status}, {n} contact{'s' * (n != 1)}, "
            f"tip turned {np.degrees(result.tip_rotation):.0f} deg")


def page_overlay(title: str | None, chords: bool = False) -> str:
    """The HTML of the title and legend drawn over the scene, top left (Meshcat's controls
    are top right)."""
    from html import escape

    from ..kinematics.arm import ARM_COLOUR
    from ..wrapping.scene import OBJECT_COLOR
    swatch = ('<span style="display:inline-block;width:12px;height:12px;margin:0 4px 0 10px;'
              'vertical-align:middle;background:{}"></span>{}')
    rgb = "rgb({:.0f},{:.0f},{:.0f})"
    items = [swatch.format(rgb.format(*(255 * np.array(ARM_COLOUR))), "arm"),
             swatch.format(rgb.format(*(255 * OBJECT_COLOR[:3])), "object"),
             swatch.format(rgb.format(*(255 * np.array(CONTACT_COLOR[:3]))),
                           "contact (pin along its normal, object to arm)")]
    if chords:
        items.append(swatch.format(rgb.format(*(255 * np.array(CHORD_COLOR[:3]))), "chords"))
    head = f'<div style="font-size:16px;font-weight:bold">{escape(title)}</div>' if title else ""
    return ('<div id="wrap-overlay" style="position:fixed;top:8px;left:8px;z-index:10;'
            'pointer-events:none;font-family:sans-serif;font-size:13px;color:#222;'
            'background:rgba(255,255,255,0.8);padding:6px 10px;border-radius:4px">'
            f'{head}<div>{"".join(items)}</div><div style="color:#555">drag to turn, scroll '
            'to zoom; the animation plays from Open Controls, Animations (top right)</div>'
            '</div>')


def save_html(meshcat, path, *, title: str | None = None, chords: bool = False) -> Path:
    """Write the scene (with its recording) as one self-contained HTML page, atomically, with
    `title` (also the browser tab's) and a legend over it."""
    from html import escape
    html = meshcat.StaticHtml()
    if title:
        html = html.replace("<title>Drake MeshCat</title>", f"<title>{escape(title)}</title>", 1)
    html = html.replace("<body>", "<body>\n" + page_overlay(title, chords), 1)
    return write_atomic(path, html.encode())
