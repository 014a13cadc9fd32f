"""The depth camera's voxelled cloud of one object after another in an unchanging scene.

Locating an object (locate.camera_points) looks at the table, the parked arm and its mount
with the object on the table; only the pixels that see the object, or border them, differ
from one object to the next: the rest of the image, its sensor errors (drawn from the same
seed) and the voxels it fills are the same every time. `voxelled_cloud` renders the scene
without the object once (per arm tube, mount, camera, sensor model, seed and voxel size),
then for each object casts only the rays of the window its bounding box projects to,
measures that window with the errors the whole image drew there, and averages again only
the voxels the window's points leave or enter. The result is render_cloud's cloud through
cloud.voxel_average to the bit (tests): the same voxels in the same order, each the mean of
the same points summed in the same order. Where a shortcut's premise fails (the window
holds the cloud's lowest point on an axis, or a point falls outside the scene's voxel
grid) it renders the whole image instead.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import trimesh

from ..kinematics.arm import ArmConfig, ContinuumArm
from .cloud import voxel_average
from .depth_camera import CameraPose, KinectModel, render_image, scene_parts

__all__ = ["MARGIN_PIXELS", "voxelled_cloud"]

MARGIN_PIXELS = 2  # the projected box is widened by this much against rounding in the rays
_CACHED_SCENES = 2  # scenes kept (each about 40 MB): the locating camera and one other


class _Recorder:
    """A generator that keeps what it draws (the whole image's sensor errors)."""

    def __init__(self, seed: int):
        self._rng, self.draws = np.random.default_rng(seed), []

    def random(self, shape):
        self.draws.append(("random", self._rng.random(shape)))
        return self.draws[-1][1]

    def standard_normal(self, shape):
        self.draws.append(("standard_normal", self._rng.standard_normal(shape)))
        return self.draws[-1][1]


class _Replay:
    """The recorded draws again, cut to a window: a window's pixels get the errors the
    whole image gave them. Draws asked in another order or shape than recorded raise."""

    def __init__(self, draws: list, window: tuple):
        self._draws, self._window, self._next = draws, window, 0

    def _take(self, kind: str, shape):
        recorded_kind, values = self._draws[self._next]
        cut = values[self._window]
        if recorded_kind != kind or cut.shape != tuple(shape):
            raise AssertionError(f"replay asked {kind}{tuple(shape)}, recorded "
                                 f"{recorded_kind}{cut.shape}")
        self._next += 1
        return cut

    def random(self, shape):
        return self._take("random", shape)

    def standard_normal(self, shape):
        return self._take("standard_normal", shape)


@dataclass(frozen=True)
class _Scene:
    """The scene without the object, measured and voxelled (flat per-pixel arrays)."""
    draws: list          # the whole image's sensor errors, in the order drawn
    points: np.ndarray   # (h * w, 3) world position of each pixel (valid ones)
    colours: np.ndarray  # (h * w, 3) measured colour of each pixel
    voxel_of: np.ndarray  # (h * w,) index of each valid pixel's voxel, -1 elsewhere
    low: np.ndarray      # (3,) the cloud's least coordinates (the voxel grid's corner)
    lowest: list         # per axis, the pixels holding that least coordinate
    size: np.ndarray     # (3,) voxels along each axis
    keys: np.ndarray     # (V,) sorted voxel keys
    means: np.ndarray    # (V, 3) voxel mean points
    colour_means: np.ndarray  # (V, 3)
    members: np.ndarray  # pixels of voxel v: members[starts[v]:starts[v + 1]], in order
    starts: np.ndarray


def _cells(points, low, voxel: float) -> np.ndarray:
    """voxel_average's cell of each point, for a grid whose least point is `low`."""
    return np.floor((points - (low - voxel / 2)) / voxel).astype(np.int64)


def _keys(cells, size) -> np.ndarray:
    return (cells[:, 0] * size[1] + cells[:, 1]) * size[2] + cells[:, 2]


def _static_scene(parts: dict, camera: CameraPose, model: KinectModel, *, seed: int,
                  voxel: float) -> _Scene:
    recorder = _Recorder(seed)
    image = render_image(parts, camera=camera, model=model, rng=recorder)
    valid = image["valid"].reshape(-1)
    pixels = np.flatnonzero(valid)
    points = np.zeros((valid.size, 3))
    points[pixels] = image["points"]
    colours = image["colour"].reshape(-1, 3)
    p = image["points"]
    low = p.min(axis=0)
    cells = _cells(p, low, voxel)
    size = cells.max(axis=0) + 1
    keys, which, count = np.unique(_keys(cells, size), return_inverse=True,
                                   return_counts=True)
    voxel_of = np.full(valid.size, -1, dtype=np.int64)
    voxel_of[pixels] = which
    means, colour_means = (np.stack([np.bincount(which, a[pixels, j], len(count))
                                     for j in range(3)], 1) / count[:, None]
                           for a in (points, colours))
    return _Scene(draws=recorder.draws, points=points, colours=colours,
                  voxel_of=voxel_of, low=low,
                  lowest=[pixels[p[:, j] == low[j]] for j in range(3)], size=size, keys=keys,
                  means=means, colour_means=colour_means,
                  members=pixels[np.argsort(which, kind="stable")],
                  starts=np.concatenate([[0], np.cumsum(count)]))


_SCENES: OrderedDict = OrderedDict()


def _scene_for(parts: dict, camera: CameraPose, model: KinectModel, *, seed: int,
               voxel: float) -> _Scene:
    """The cached _Scene of these parts (keyed by their vertices and faces), made if new."""
    digest = hashlib.blake2b(digest_size=16)
    for name, mesh in parts.items():
        digest.update(name.encode())
        digest.update(np.ascontiguousarray(mesh.vertices, dtype=float).tobytes())
        digest.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
    key = (digest.hexdigest(), camera, model, int(seed), float(voxel))
    if key in _SCENES:
        _SCENES.move_to_end(key)
        return _SCENES[key]
    scene = _static_scene(parts, camera, model, seed=seed, voxel=voxel)
    _SCENES[key] = scene
    while len(_SCENES) > _CACHED_SCENES:
        _SCENES.popitem(last=False)
    return scene


def _box_window(mesh: trimesh.Trimesh, camera: CameraPose, model: KinectModel):
    """(first row, end row, first column, end column) of the pixels whose rays may meet the
    mesh (its bounding box's projection, widened by MARGIN_PIXELS), None when the box is
    not wholly in front of the camera."""
    lo, hi = np.asarray(mesh.bounds, dtype=float)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    cam = (corners - np.asarray(camera.eye, float)) @ camera.rotation()
    if not np.all(cam[:, 2] > 1e-3):
        return None
    u = model.focal * cam[:, 0] / cam[:, 2] + (model.width - 1) / 2.0
    v = model.focal * cam[:, 1] / cam[:, 2] + (model.height - 1) / 2.0
    m = MARGIN_PIXELS
    r0, r1 = max(int(np.floor(v.min())) - m, 0), min(int(np.ceil(v.max())) + m + 1, model.height)
    c0, c1 = max(int(np.floor(u.min())) - m, 0), min(int(np.ceil(u.max())) + m + 1, model.width)
    return (r0, r1, c0, c1) if r0 < r1 and c0 < c1 else None


def _updated_voxels(parts: dict, scene: _Scene, box, *, camera: CameraPose,
                    model: KinectModel, voxel: float):
    """(points, colours) of the voxels with the object's window measured anew, None when
    the scene's voxel grid would not be the whole image's (module docstring)."""
    r0, r1, c0, c1 = box = (max(box[0] - 1, 0), min(box[1] + 1, model.height),
                            max(box[2] - 1, 0), min(box[3] + 1, model.width))
    # Grown by the ring whose flying pixels may change with the object's depths.
    seen = render_image(parts, camera=camera, model=model, rng=_Replay(
        scene.draws, (slice(r0, r1), slice(c0, c1))), window=box)
    flat = (np.arange(r0, r1)[:, None] * model.width + np.arange(c0, c1)[None, :]).reshape(-1)
    new = flat[seen["valid"].reshape(-1)]
    points, colours = seen["points"], seen["colour"][seen["valid"]]
    in_box = np.zeros(len(scene.voxel_of), bool)
    in_box[flat] = True
    # The grid's corner is the cloud's least point: still the scene's when no new point lies
    # below it and a pixel outside the window, or a new point, still holds it on each axis.
    # Otherwise the grid moves: every voxel is averaged again, from the whole cloud.
    if len(points) and np.any(points.min(axis=0) < scene.low) or not all(
            (~in_box[pix]).any() or (len(points) and points[:, j].min() == scene.low[j])
            for j, pix in enumerate(scene.lowest)):
        return _whole_cloud(scene, flat, new, window=(points, colours), voxel=voxel)
    cells = _cells(points, scene.low, voxel)
    if len(cells) and np.any(cells.max(axis=0) >= scene.size):
        return _whole_cloud(scene, flat, new, window=(points, colours), voxel=voxel)
    new_keys = _keys(cells, scene.size)
    # The voxels to average again: the scene's that the window's pixels leave or enter
    # (`old`, by index), and the window's new ones.
    at = np.minimum(np.searchsorted(scene.keys, new_keys), len(scene.keys) - 1)
    known = scene.keys[at] == new_keys
    left = scene.voxel_of[flat]
    untouched = np.ones(len(scene.keys), bool)
    untouched[left[left >= 0]] = False
    untouched[at[known]] = False
    old = np.flatnonzero(~untouched)
    touched = np.sort(np.concatenate([scene.keys[old], np.unique(new_keys[~known])]))
    # The scene's points of those voxels outside the window, then the window's, in pixel
    # order: the order voxel_average sums them in.
    lengths = scene.starts[old + 1] - scene.starts[old]
    first = np.repeat(scene.starts[old] - np.cumsum(lengths) + lengths, lengths)
    kept = scene.members[first + np.arange(lengths.sum())]
    kept = kept[~in_box[kept]]
    pixel = np.concatenate([kept, new])
    order = np.argsort(pixel, kind="stable")
    key = np.concatenate([scene.keys[scene.voxel_of[kept]], new_keys])[order]
    p = np.concatenate([scene.points[kept], points])[order]
    c = np.concatenate([scene.colours[kept], colours])[order]
    which = np.searchsorted(touched, key)
    count = np.bincount(which, minlength=len(touched))
    filled = count > 0
    means, colour_means = (
        (np.stack([np.bincount(which, a[:, j], len(touched)) for j in range(3)], 1)
         / np.where(filled, count, 1)[:, None])[filled] for a in (p, c))
    # The scene's other voxels with the new ones slotted in by key: row `source` of the
    # scene's voxels followed by the new ones.
    kept_voxels = np.flatnonzero(untouched)
    slot = np.searchsorted(scene.keys[kept_voxels], touched[filled]) + np.arange(len(means))
    source = np.empty(len(kept_voxels) + len(means), dtype=np.int64)
    fresh = np.zeros(len(source), bool)
    fresh[slot] = True
    source[slot] = len(scene.keys) + np.arange(len(means))
    source[~fresh] = kept_voxels
    return (np.concatenate([scene.means, means])[source],
            np.concatenate([scene.colour_means, colour_means])[source])


def _whole_cloud(scene: _Scene, flat, new, *, window: tuple, voxel: float):
    """voxel_average of the scene's cloud with the window's pixels (`flat`) replaced by its
    valid ones (`new`, their (points, colours) in `window`)."""
    valid = scene.voxel_of >= 0
    valid[flat] = False
    valid[new] = True
    points, colours = scene.points.copy(), scene.colours.copy()
    points[new], colours[new] = window
    return voxel_average(points[valid], colours[valid], voxel)


def voxelled_cloud(arm: ContinuumArm, config: ArmConfig, obj: trimesh.Trimesh, *,
                   camera: CameraPose = CameraPose(), model: KinectModel = KinectModel(),
                   seed: int = 0, voxel: float) -> tuple[np.ndarray, np.ndarray]:
    """voxel_average(cloud.points, cloud.colours, voxel) of render_cloud(arm, config, obj,
    camera=camera, model=model, seed=seed), to the bit, re-rendering only the object's
    window of a cached scene (module docstring)."""
    static = scene_parts(arm, config, None)
    parts = {**static, "object": obj}
    scene = _scene_for(static, camera, model, seed=seed, voxel=voxel)
    box = _box_window(obj, camera, model)
    if box is not None:
        updated = _updated_voxels(parts, scene, box, camera=camera, model=model, voxel=voxel)
        if updated is not None:
            return updated
    image = render_image(parts, camera=camera, model=model, rng=np.random.default_rng(seed))
    return voxel_average(image["points"], image["colour"][image["valid"]], voxel)
