"""PNG pictures of wraps (matplotlib, headless Agg).

`plot_wrap` draws one final wrap (the object as a light shaded mesh, the arm's tube and
centre line, contacts with their normals), as in the paper's Fig. 5; `plot_wraps_grid` puts
several in one figure.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from ..files import write_atomic
from ..kinematics.arm import ArmConfig, ContinuumArm
from ..wrapping.contact import Contacts
from ..wrapping.wrap_types import WrapStatus
from .meshcat import CONTACT_COLOR

__all__ = ["wrap_figure", "plot_wrap", "wraps_grid_figure", "plot_wraps_grid", "wrap_cell",
           "plot_object_wraps", "wrap_chord_segments", "choose_wrap", "wrap_gallery"]


# ----------------------------------------------------------------- matplotlib
def _as_trimesh(mesh) -> trimesh.Trimesh:
    if isinstance(mesh, trimesh.Trimesh):
        return mesh
    from ..objects.mesh import load_mesh
    return load_mesh(mesh)


def _draw_wrap(ax, mesh, arm: ContinuumArm, *, config: ArmConfig, contacts: Contacts | None,
               title: str | None, max_faces: int = 6000, axis_labels: bool = True,
               zoom: float = 1.0) -> None:
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    mesh = _as_trimesh(mesh)
    if len(mesh.faces) > max_faces:  # a light drawing: matplotlib is slow on many faces
        try:  # trimesh's decimation needs the optional fast_simplification package
            mesh = mesh.simplify_quadric_decimation(face_count=max_faces)
        except (ImportError, AttributeError):
            pass
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    shade = 0.55 + 0.4 * np.clip(mesh.face_normals @ light, 0, 1)
    faces = Poly3DCollection(mesh.triangles, linewidths=0,
                             facecolors=np.column_stack([shade * 0.75, shade * 0.8, shade * 0.9,
                                                         np.full(len(shade), 0.35)]))
    ax.add_collection3d(faces)
    bb = arm.backbone(config, n=200)
    x, y, z = bb.position.T
    ax.plot(x, y, z, color=(0.95, 0.45, 0.05), lw=6.0, alpha=0.55, solid_capstyle="round")
    ax.plot(x, y, z, color=(0.5, 0.2, 0.0), lw=1.0)
    _, ends = arm.section_frames(config)
    ax.scatter(*ends.T, color=(0.3, 0.1, 0.0), s=8)
    points = [mesh.vertices, bb.position]
    if contacts is not None and len(contacts):
        ax.scatter(*contacts.p.T, color=CONTACT_COLOR[:3], s=18, depthshade=False)
        ax.quiver(*contacts.p.T, *(0.025 * contacts.n).T, color=CONTACT_COLOR[:3], lw=1.2)
        points.append(contacts.p)
    pts = np.vstack(points)
    centre, half = (pts.max(0) + pts.min(0)) / 2, (pts.max(0) - pts.min(0)).max() / 2
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1), zoom=zoom)
    ax.view_init(elev=55, azim=-70)
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # three ticks an axis: five run together
        axis.set_major_locator(MaxNLocator(3))
    if axis_labels:  # a grid names its units once, below the cells
        ax.set_xlabel("x (m)", fontsize=7)
        ax.set_ylabel("y (m)", fontsize=7)
        ax.set_zlabel("z (m)", fontsize=7)
    ax.tick_params(labelsize=6, pad=0)
    n_contacts = 0 if contacts is None else len(contacts)
    ax.set_title(title if title is not None else f"{n_contacts} contacts", fontsize=9)


def _save(fig, path) -> Path:
    path = Path(path)
    return write_atomic(path, lambda f: fig.savefig(f, format=path.suffix.lstrip(".") or "png"))


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def wrap_figure(mesh, arm: ContinuumArm, config: ArmConfig, *, contacts: Contacts | None,
                title: str | None = None, size_px=(800, 800), dpi: int = 100):
    """The matplotlib Figure of plot_wrap (the caller closes it)."""
    fig = _pyplot().figure(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi,
                           layout="constrained")
    # a little smaller than the axes: constrained layout does not see 3-D axis labels
    _draw_wrap(fig.add_subplot(projection="3d"), mesh, arm, config=config, contacts=contacts,
               title=title, zoom=0.9)
    return fig


def plot_wrap(mesh, arm: ContinuumArm, config: ArmConfig, *, contacts: Contacts | None, path,
              title: str | None = None, size_px=(800, 800), dpi: int = 100) -> Path:
    """Write a PNG of one wrap: the object, the arm, contacts with normals (object -> arm).

    Args:
        mesh: the object (trimesh.Trimesh in world coordinates, or a mesh path).
        arm, config: the arm and its final configuration.
        contacts: contacts to mark, or None.
        path: PNG to write (atomically).
        title: figure title (default: the number of contacts).
        size_px: (width, height) of the image in pixels.

    Returns:
        The path written.
    """
    fig = wrap_figure(mesh, arm, config, contacts=contacts, title=title, size_px=size_px, dpi=dpi)
    try:
        return _save(fig, path)
    finally:
        _pyplot().close(fig)


def wraps_grid_figure(items, *, ncols: int = 5, cell_px: int = 360, dpi: int = 100):
    """The matplotlib Figure of plot_wraps_grid (the caller closes it). Constrained layout
    places titles and tick labels whatever the grid; the axes' units are said once, below."""
    items = list(items)
    if not items:
        raise ValueError("plot_wraps_grid: no wraps to draw")
    ncols = min(ncols, len(items))
    nrows = -(-len(items) // ncols)
    fig = _pyplot().figure(figsize=(ncols * cell_px / dpi, nrows * cell_px / dpi), dpi=dpi,
                           layout="constrained")
    fig.get_layout_engine().set(w_pad=0.02, h_pad=0.02, wspace=0.0, hspace=0.0)
    for i, item in enumerate(items):
        ax = fig.add_subplot(nrows, ncols, i + 1, projection="3d")
        _draw_wrap(ax, item["mesh"], item["arm"], config=item["config"],
                   contacts=item.get("contacts"), title=item.get("title"), axis_labels=False)
    fig.supxlabel("x, y, z in metres (world frame)", fontsize=7)
    return fig


def plot_wraps_grid(items, path, *, ncols: int = 5, cell_px: int = 360, dpi: int = 100) -> Path:
    """Write a PNG grid of wraps (the paper's Fig. 5: one or two per category).

    Args:
        items: sequence of dicts with keys mesh, arm, config, contacts and optional title.
        path: PNG to write.
        ncols: wraps a row.
        cell_px: size of one wrap's square, pixels.
    """
    fig = wraps_grid_figure(items, ncols=ncols, cell_px=cell_px, dpi=dpi)
    try:
        return _save(fig, path)
    finally:
        _pyplot().close(fig)


def wrap_cell(mesh, arm: ContinuumArm, wrap, *, title: str) -> dict:
    """A plot_wraps_grid item of a stored WrapResult: its last configuration on the base
    pose of its plane."""
    return {"mesh": mesh, "arm": wrap.arm(arm),
            "config": ArmConfig.from_vector(wrap.configs[-1]), "contacts": wrap.contacts,
            "title": title}


def plot_object_wraps(mesh, arm: ContinuumArm, wraps, *, path, ncols: int = 5) -> Path:
    """Write a PNG grid of WrapResults of one object, one cell a wrap, titled with its
    plane, status and number of contacts."""
    def title(w):
        n = len(w.contacts)
        return f"plane {w.plane_index}: {w.status}, {n} contact{'' if n == 1 else 's'}"
    return plot_wraps_grid([wrap_cell(mesh, arm, w, title=title(w)) for w in wraps], path,
                           ncols=ncols)


def wrap_chord_segments(result, spacing: float = 0.01, min_length: float = 0.005):
    """(start (k, 3), end (k, 3)) of the chords of a wrap (chords.py's resampled centre-line
    points, every pair at least min_length apart), for draw_chords."""
    from ..features.chords import resample_centre_line
    points, _ = resample_centre_line(result.samples_arc_length, result.samples_position,
                                     result.samples_normal, spacing=spacing)
    i, j = np.triu_indices(len(points), k=1)
    keep = np.linalg.norm(points[j] - points[i], axis=1) >= min_length
    return points[i[keep]], points[j[keep]]


def choose_wrap(scene, planes, params=None):
    """The wrap to show of an object: on the first of `planes` that gives a complete wrap,
    else the one whose tip turned furthest."""
    from ..wrapping.wrap import WrapParams, wrap
    params = WrapParams() if params is None else params
    best = None
    for p in planes:
        r = wrap(scene, p, params)
        if best is None or r.tip_rotation > best.tip_rotation:
            best = r
        if r.status == WrapStatus.COMPLETE:
            return r
    return best


def wrap_gallery(dataset_dir, png, *, seed: int = 0, plane: int | None = None, params=None) -> Path:
    """Write the paper's Fig. 5: one wrap a category of a dataset, as a grid PNG.

    For each category one object is drawn at random (from `seed`) and wrapped on `plane`
    (default: the first of the 10 default planes that gives a complete wrap, else the wrap
    that turned furthest).

    Args:
        dataset_dir: folder holding manifest.json (objects.load_manifest).
        png: picture to write.
        seed: chooses the object of each category.
        plane: index into planes.enumerate_planes(), or None to search as above.
        params: wrap.WrapParams (default: the paper's, fast enclosing).

    Returns:
        The path written.
    """
    from ..kinematics.arm import load_arm
    from ..objects.dataset import load_manifest
    from ..wrapping.planes import enumerate_planes
    from ..wrapping.scene import WrapScene
    dataset = load_manifest(dataset_dir)
    arm = load_arm()
    planes = enumerate_planes(arm.base_position)
    rng = np.random.default_rng(seed)
    items = []
    for category in dataset.categories:
        members = dataset.by_category(category)
        entry = members[int(rng.integers(len(members)))]
        scene = WrapScene(arm, entry.load())
        best = choose_wrap(scene, [planes[plane]] if plane is not None else planes, params)
        label = planes[best.plane_index].label if best.plane_index >= 0 else "plane"
        items.append({"mesh": scene.object_trimesh,
                      "arm": best.arm(arm),
                      "config": best.final_config, "contacts": best.contacts,
                      "title": f"{entry.id} {label}: {best.status}, "
                               f"{np.degrees(best.tip_rotation):.0f} deg"})
    return plot_wraps_grid(items, png)
