"""Point clouds from files (.pcd, .ply, .xyz, .xyzrgb, .pts), in metres.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from importlib.resources import files
from pathlib import Path

import numpy as np
import open3d as o3d

from ..errors import DrakeContinuumError
from ..files import check_input_file, regular_file

__all__ = ["CLOUD_SUFFIXES", "MM_EXTENT", "SAMPLE_CLOUDS", "PointCloudError", "Cloud",
           "detect_units", "load_cloud", "row_norms", "voxel_average", "read_sidecar",
           "sidecar_base", "sidecar_eyes", "sidecar_lengths"]

# The shipped sample clouds (real/data of the checkout, package drake_continuum.clouds), as a
# file-system path: Open3D opens files by name, and pip installs packages unzipped.
SAMPLE_CLOUDS = Path(str(files("drake_continuum.clouds")))


CLOUD_SUFFIXES = (".pcd", ".ply", ".xyz", ".xyzrgb", ".pts")
MM_EXTENT = 20.0  # a cloud spanning more than this many units is in millimetres


def row_norms(d) -> np.ndarray:
    """(N,) Euclidean length of each row of `d` (N, 3): np.linalg.norm(d, axis=1) summed in
    its order, x^2 + y^2 then + z^2, column by column (a third of its cost on a
    640 x 480 cloud, whose reduction over rows of three is mostly per-row overhead)."""
    return np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])


class PointCloudError(DrakeContinuumError):
    """A cloud cannot be used; the message names the file and the problem."""


@dataclass(frozen=True)
class Cloud:
    """A point cloud in metres.

    Args:
        points: (N, 3) positions, m.
        colours: (N, 3) RGB in [0, 1], or None when the file has no colour.
        source: where it came from (for messages).
        units: units of the file ("m" or "mm").
    """

    points: np.ndarray
    colours: np.ndarray | None = None
    source: str = "<array>"
    units: str = "m"


def detect_units(points: np.ndarray) -> str:
    """"mm" when the cloud spans more than MM_EXTENT units (a tabletop scene in metres spans
    a few metres at most; in millimetres anything larger than 2 cm spans more than 20)."""
    lo, hi = np.percentile(points, [1, 99], axis=0)
    return "mm" if np.max(hi - lo) > MM_EXTENT else "m"


def _header_says_empty(path: Path) -> bool:
    head = path.open("rb").read(4096).decode("ascii", errors="replace").lower()
    return any(line.split()[:2] in (["points", "0"], ["width", "0"])
               or line.split()[:3] == ["element", "vertex", "0"] for line in head.splitlines())


def load_cloud(path, units: str = "auto", drop_nonfinite: bool = False) -> Cloud:
    """Read a .pcd/.ply/.xyz cloud, check it, and return it in metres.

    Raises PointCloudError naming the file when it does not exist, cannot be read, holds no
    points, or holds NaN/infinite points (unless drop_nonfinite: organised clouds mark
    missing pixels with NaN).
    """
    path = Path(path)
    if units not in ("auto", "m", "mm"):
        raise PointCloudError(f"{path}: units must be auto, m or mm, got {units!r}")
    check_input_file(path, CLOUD_SUFFIXES, PointCloudError, kind="point-cloud")
    pcd = o3d.io.read_point_cloud(str(path))
    pts = np.asarray(pcd.points, dtype=float)
    if len(pts) == 0:
        if _header_says_empty(path):
            raise PointCloudError(f"{path}: holds no points")
        raise PointCloudError(f"{path}: cannot be read as a point cloud (not a valid "
                              f"{path.suffix} file)")
    cols = np.asarray(pcd.colors, dtype=float) if pcd.has_colors() else None
    finite = np.all(np.isfinite(pts), axis=1)
    if not finite.all():
        if not drop_nonfinite or not finite.any():
            raise PointCloudError(
                f"{path}: {int((~finite).sum())} of {len(pts)} points are NaN or infinite"
                + ("" if finite.any() else " (no usable point)")
                + ("" if drop_nonfinite else "; pass --drop-nan to discard them"))
        pts = pts[finite]
        cols = None if cols is None else cols[finite]
    found = detect_units(pts) if units == "auto" else units
    if found == "mm":
        pts = pts / 1000.0
    return Cloud(points=pts, colours=cols, source=str(path), units=found)


def voxel_average(points, colours, voxel: float) -> tuple[np.ndarray, np.ndarray]:
    """Open3D's `voxel_down_sample` in numpy: the mean point and colour of each occupied cell
    of a grid of `voxel` (m) whose corner lies half a cell below the points' minimum, the
    same points as Open3D's to the bit, in the cells' lexicographic order (Open3D's is its
    hash map's) and at a quarter of its cost on a 640 x 480 cloud."""
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    c = np.asarray(colours, dtype=float).reshape(-1, 3)
    if len(p) == 0:
        return p.copy(), c.copy()
    cell = np.floor((p - (p.min(axis=0) - voxel / 2)) / voxel).astype(np.int64)
    size = cell.max(axis=0) + 1
    key = (cell[:, 0] * size[1] + cell[:, 1]) * size[2] + cell[:, 2]
    _, which, count = np.unique(key, return_inverse=True, return_counts=True)

    def mean(a):
        return np.stack([np.bincount(which, a[:, j], len(count)) for j in range(3)], 1) / \
            count[:, None]
    return mean(p), mean(c)


def read_sidecar(cloud_path) -> dict:
    """The JSON sidecar beside a cloud (CLOUD.json, docs/clouds.md), {} when it has none.

    Its base pose ("base_position" and "base_rpy", 3 finite numbers each, given together)
    and camera position ("camera": {"eye": 3 finite numbers}) are checked here: a damaged
    sidecar raises PointCloudError naming it rather than being ignored, since a fit made
    on a default base is wrong while it reports itself confident.
    """
    path = Path(cloud_path).with_suffix(".json")
    if not path.exists():
        return {}
    regular_file(path, PointCloudError)
    try:
        meta = json.loads(path.read_text())
    except (OSError, ValueError) as e:
        raise PointCloudError(f"{path}: damaged sidecar (not JSON: {e})") from None
    if not isinstance(meta, dict):
        raise PointCloudError(f"{path}: damaged sidecar (not a JSON object)")
    if ("base_position" in meta) != ("base_rpy" in meta):
        raise PointCloudError(f"{path}: damaged sidecar (base_position and base_rpy come "
                              f"together)")
    for key in ("base_position", "base_rpy"):
        if key in meta:
            _three(meta[key], path, key)
    camera = meta.get("camera")
    if camera is not None:
        if not isinstance(camera, dict):
            raise PointCloudError(f"{path}: damaged sidecar (camera is not a JSON object)")
        if "eye" in camera:
            _three(camera["eye"], path, "camera.eye")
    return meta


def _three(value, path: Path, key: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=float).reshape(3)
    except (TypeError, ValueError):
        v = np.full(3, np.nan)
    if not np.all(np.isfinite(v)):
        raise PointCloudError(f"{path}: damaged sidecar ({key} must be 3 finite numbers, got "
                              f"{value!r})")
    return v


def sidecar_base(cloud_paths, tolerance: float = 1e-6):
    """(position (3,), roll-pitch-yaw (3,), sidecar path) of the arm base the clouds'
    sidecars record, None when none records one. Views fused into one fit must be views of
    one wrap: sidecars that record different base poses (beyond `tolerance`, m and rad of
    rotation) raise PointCloudError naming both."""
    from pydrake.math import RollPitchYaw

    found = None
    for cloud in cloud_paths:
        meta = read_sidecar(cloud)
        if "base_position" not in meta:
            continue
        path = Path(cloud).with_suffix(".json")
        p = _three(meta["base_position"], path, "base_position")
        rpy = _three(meta["base_rpy"], path, "base_rpy")
        if found is None:
            found = (p, rpy, path)
            continue
        R0 = RollPitchYaw(found[1]).ToRotationMatrix().matrix()
        R = RollPitchYaw(rpy).ToRotationMatrix().matrix()
        turn = np.arccos(np.clip((np.trace(R0.T @ R) - 1) / 2, -1, 1))
        if np.linalg.norm(p - found[0]) > tolerance or turn > tolerance:
            raise PointCloudError(
                f"{path}: the arm base {p.tolist()} m, rpy {rpy.tolist()} differs from "
                f"{found[2]}'s ({found[0].tolist()} m, rpy {found[1].tolist()}): views "
                f"fused into one fit must be of one wrap; fit them one by one")
    return found


def sidecar_eyes(cloud_paths) -> list | None:
    """The camera position (3,) each cloud's sidecar records, None when none records one.
    Views fitted together share one free-space term: when some sidecars have a camera and
    others not, raise PointCloudError naming the first without one, rather than fit without
    the evidence the others give."""
    eyes = [read_sidecar(c).get("camera", {}).get("eye") for c in cloud_paths]
    if all(e is None for e in eyes):
        return None
    missing = [c for c, e in zip(cloud_paths, eyes) if e is None]
    if missing:
        raise PointCloudError(f"{Path(missing[0]).with_suffix('.json')}: no 'camera' "
                              f"{{\"eye\": [x, y, z]}}, which the other views' sidecars give; "
                              f"give it, or --camera for every cloud")
    return [np.asarray(e, float) for e in eyes]


def sidecar_lengths(cloud_paths, n_sections: int, tolerance: float = 1e-9):
    """(section lengths (n,), sidecar path) of the commanded configuration the clouds'
    sidecars record ("config": {"s": [..]}), None when none records one: a soft arm's section
    lengths are set by its actuators, so the command says them better than the points do.
    Lengths that are not `n_sections` positive finite numbers, or views whose sidecars
    disagree, raise PointCloudError naming the sidecar."""
    found = None
    for cloud in cloud_paths:
        config = read_sidecar(cloud).get("config")
        if config is None:
            continue
        path = Path(cloud).with_suffix(".json")
        try:
            s = np.asarray(config["s"], dtype=float).reshape(-1)
        except (TypeError, ValueError, KeyError, IndexError):
            raise PointCloudError(f"{path}: damaged sidecar (config.s must be the section "
                                  f"lengths, m)") from None
        if len(s) != n_sections:
            raise PointCloudError(f"{path}: config.s gives {len(s)} section length(s) "
                                  f"{s.tolist()} for an arm of {n_sections} sections: give "
                                  f"the arm's description (--arm) or --lengths")
        if not np.all(np.isfinite(s)) or np.any(s <= 0):
            raise PointCloudError(f"{path}: damaged sidecar (config.s must be positive "
                                  f"lengths, m, got {s.tolist()})")
        if found is None:
            found = (s, path)
        elif np.max(np.abs(s - found[0])) > tolerance:
            raise PointCloudError(f"{path}: config.s {s.tolist()} differs from {found[1]}'s "
                                  f"{found[0].tolist()}: views fused into one fit must be of "
                                  f"one wrap; fit them one by one")
    return found
