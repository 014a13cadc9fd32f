"""A one-picture look at a dataset: every object as a shaded 3-D view with its category.

All views share one scale (the standard pose's limits), so sizes compare across the picture.
Meshes are coarsened by vertex clustering for drawing only; matplotlib's depth sorting of
thousands of polygons per view would otherwise take minutes for 185 objects.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from ..files import write_atomic
from .dataset import Dataset
from .pose import PoseLimits

__all__ = ["CATEGORY_COLOURS", "display_mesh", "shade", "gallery_figure", "render_gallery"]

CATEGORY_COLOURS = {"apple": "#c0392b", "banana": "#f1c40f", "bottle": "#2e86c1",
                    "bowl": "#a04000", "cup": "#48c9b0", "donut": "#d35400",
                    "hammer": "#7f8c8d", "mug": "#8e44ad", "teapot": "#27ae60",
                    "toilet_paper": "#bdc3c7"}


def display_mesh(mesh: trimesh.Trimesh, cell: float = 0.004) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of a coarsened copy (vertex clustering on a `cell`-metre grid)."""
    v = np.asarray(mesh.vertices)
    keys = np.floor((v - v.min(axis=0)) / cell).astype(np.int64)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    faces = inverse.reshape(-1)[np.asarray(mesh.faces)]
    keep = (faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & \
           (faces[:, 0] != faces[:, 2])
    return v[first], faces[keep]


def shade(verts: np.ndarray, faces: np.ndarray, colour: str) -> np.ndarray:
    """RGBA per face from a fixed light, so shapes read without a renderer."""
    from matplotlib.colors import to_rgb
    tri = verts[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-15
    light = np.array([-0.4, -0.6, 0.7])
    light /= np.linalg.norm(light)
    k = 0.35 + 0.65 * np.clip(n @ light, 0.0, 1.0)
    rgb = np.asarray(to_rgb(colour))[None, :] * k[:, None]
    return np.column_stack([rgb, np.ones(len(k))])


def gallery_figure(dataset: Dataset, columns: int | None = None, dpi: int = 90):
    """The matplotlib Figure of render_gallery (the caller closes it).

    Constrained layout keeps the title and the bottom row's names on the canvas whatever the
    number of objects; the title is wrapped to the figure's width.
    """
    import textwrap

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    limits = PoseLimits.load()
    n = len(dataset)
    columns = columns or int(np.ceil(np.sqrt(n * 1.3)))
    rows = int(np.ceil(n / columns))
    width = max(columns * 1.4, 3.5)  # inches: room for a title even with one object
    fig = plt.figure(figsize=(width, rows * 1.6 + 0.5), dpi=dpi, layout="constrained")
    fig.get_layout_engine().set(w_pad=0.01, h_pad=0.01, wspace=0.0, hspace=0.0)
    r, h = limits.footprint_radius_max, limits.height_max
    for k, entry in enumerate(dataset):
        ax = fig.add_subplot(rows, columns, k + 1, projection="3d")
        verts, faces = display_mesh(entry.load())
        colour = CATEGORY_COLOURS.get(entry.category, "#888888")
        ax.add_collection3d(Poly3DCollection(verts[faces], facecolors=shade(verts, faces, colour),
                                             edgecolors="none"))
        ax.set_xlim(-r, r)
        ax.set_ylim(-r, r)
        ax.set_zlim(0.0, h)
        ax.set_box_aspect((2 * r, 2 * r, h), zoom=1.5)
        ax.view_init(elev=18, azim=-60)
        ax.set_axis_off()
        # the name under the cell (constrained layout makes room for it)
        ax.text2D(0.5, 0.0, entry.id, transform=ax.transAxes, ha="center", va="top",
                  fontsize=6)
    title = (f"{dataset.root.name}: {n} objects, "
             + ", ".join(f"{c} {m}" for c, m in dataset.counts().items()))
    chars = max(20, int(width * 72 / (10 * 0.6)))  # 10-point characters a line, roughly
    fig.suptitle(textwrap.fill(title, chars), fontsize=10)
    return fig


def render_gallery(dataset: Dataset, png_path, *, columns: int | None = None,
                   dpi: int = 90) -> Path:
    """Draw every object of the dataset into one PNG; returns its path."""
    import matplotlib.pyplot as plt
    fig = gallery_figure(dataset, columns, dpi)
    png_path = Path(png_path)
    try:
        write_atomic(png_path, lambda f: fig.savefig(f, format="png", dpi=dpi))
    finally:
        plt.close(fig)
    return png_path
