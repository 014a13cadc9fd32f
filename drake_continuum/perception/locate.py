"""Where the object stands, from what a robot has: its depth camera, or a person's word.

A robot is never given an object's exact geometry, so the position its wrap planes are
centred on must come from a sensor. `camera_estimate` renders the project's Kinect-like
cloud (depth_camera.render_cloud) of the scene with the arm parked upright beside its base
(fixed_scene.voxelled_cloud: the same voxelled cloud to the bit, re-rendering only the
object's window of the unchanging scene), and finds the object in it with Open3D: the
table is the dominant RANSAC plane (segmentation.dominant_plane) and everything within a
few millimetres of it is dropped; the arm is dropped by its paint (pointcloud.colour_gate)
and by its known pose (points near its own centre line), its mount by lying behind the
base; the object is the largest remaining DBSCAN cluster (cluster_dbscan) together with
every other cluster that comes within JOIN_GAP of it: a mug's handle or a teapot's spout
seen across a thin gap from the body is a cluster of its own in some views (mug_000 of
seed 2 turned by 1 deg lost its handle: 68 points, 11 mm from the body), and dropping it
made the footprint round. The estimate is the centre of the object's horizontal bounding
box: from about 60 deg above the table the camera sees an object's top and its near side,
so the box of what it sees covers most of the footprint (BENCHMARKS.md has the errors).
The same points give the plane set's bearing (perception.bearing), and the object's size
as the camera sees it (view_extent), which the classifier takes beside the wraps: known
before any wrap, it tells a lying bottle from a standing one and gives active recognition
something to go on at its first decision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["TABLE_CLEARANCE", "ARM_MARGIN", "CLUSTER_EPS", "CLUSTER_MIN_POINTS", "JOIN_GAP",
           "VOXEL", "LocateError", "Estimate", "parked_config", "camera_points", "camera_estimate",
           "points_estimate", "joined_clusters", "VIEW_EXTENT", "HEIGHT_PERCENTILE",
           "view_extent", "camera_view", "footprint_centre"]

TABLE_CLEARANCE = 0.006  # m: points this close to the table plane are the table (4 sigma)
ARM_MARGIN = 0.015       # m beyond the tube radius: points this near the arm's centre line
CLUSTER_EPS = 0.012      # m, DBSCAN neighbourhood
CLUSTER_MIN_POINTS = 8
JOIN_GAP = 0.025         # m: a cluster this near the largest one is part of the same object
VOXEL = 0.003            # m, downsampling before segmentation
VIEW_EXTENT = ("height", "long", "short")  # view_extent's numbers (m)
HEIGHT_PERCENTILE = 99.5  # the object's height: this percentile of its points' z (flying
#                           pixels above a silhouette would decide a maximum)


class LocateError(InputError):
    """The camera finds no object (the message says why)."""


@dataclass(frozen=True)
class Estimate:
    """A position estimate: xy (m), the points it came from, and how it was made."""
    xy: np.ndarray
    n_points: int
    source: str


def parked_config(arm):
    """The arm out of the way while the camera looks: the first section bent straight up
    (a quarter turn), the others straight, so the tube stands beside its base."""
    from ..kinematics.arm import ArmConfig
    n = arm.n_sections
    s = np.full(n, arm.section_length_min)
    kappa = np.zeros(n)
    kappa[0] = (math.pi / 2) / s[0]
    # phi = pi bends away from the base frame's x axis, which points down (base pitch 90 deg).
    return ArmConfig(s, kappa, np.full(n, math.pi))


def camera_points(world_mesh, arm, *, seed: int = 0, camera=None) -> np.ndarray:
    """(n, 3) points of the object as the simulated depth camera sees it (module docstring):
    the largest cluster left when table, arm and mount are removed, with the clusters that
    come within JOIN_GAP of it; LocateError when no object cluster is found."""
    import open3d as o3d
    from scipy.spatial import cKDTree

    from .depth_camera import CameraPose
    from .fixed_scene import voxelled_cloud
    from .segmentation import SegmentParams, colour_gate, dominant_plane
    config = parked_config(arm)
    # render_cloud's cloud through voxel_average, rendering only the object's window anew.
    pts, cols = voxelled_cloud(arm, config, world_mesh, camera=camera or CameraPose(),
                               seed=seed, voxel=VOXEL)
    plane, _ = dominant_plane(pts, TABLE_CLEARANCE / 2, seed=int(seed))  # normal upwards
    keep = pts @ plane[:3] + plane[3] > TABLE_CLEARANCE  # height above the table
    keep[keep] = ~colour_gate(cols[keep], SegmentParams())  # the table's points need no gate
    # Points near the arm's centre line are the arm: asked only of those still kept, by a
    # k-d tree (a table-sized cloud against every centre-line point would be most of the
    # time).
    backbone = arm.backbone(config, n=200).position[::4]
    near = cKDTree(backbone).query(pts[keep])[0]
    keep[keep] = near > arm.radius + ARM_MARGIN
    keep &= pts[:, 0] > arm.base_position[0] + ARM_MARGIN  # the mount behind the base
    obj = pts[keep]
    if len(obj) < CLUSTER_MIN_POINTS:
        raise LocateError("the depth camera sees no object on the table")
    sub = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(obj))
    labels = np.asarray(sub.cluster_dbscan(CLUSTER_EPS, CLUSTER_MIN_POINTS))
    if labels.max(initial=-1) < 0:
        raise LocateError("the depth camera sees no object cluster on the table")
    return joined_clusters(obj, labels)


def joined_clusters(points, labels) -> np.ndarray:
    """The points of the largest cluster (labels >= 0; -1 is noise) and of every other
    cluster whose nearest point lies within JOIN_GAP of it (module docstring)."""
    from scipy.spatial import cKDTree
    biggest = np.bincount(labels[labels >= 0]).argmax()
    tree = cKDTree(points[labels == biggest])
    keep = labels == biggest
    for c in set(labels[labels >= 0].tolist()) - {int(biggest)}:
        if tree.query(points[labels == c], distance_upper_bound=JOIN_GAP)[0].min() <= JOIN_GAP:
            keep |= labels == c
    return points[keep]


def camera_estimate(world_mesh, arm, *, seed: int = 0, camera=None) -> Estimate:
    """The object's position (x, y) from a simulated depth cloud of the scene (module
    docstring); LocateError when no object cluster is found."""
    return points_estimate(camera_points(world_mesh, arm, seed=seed, camera=camera))


def points_estimate(points) -> Estimate:
    """The position estimate from the object's points in the camera's cloud: the centre of
    their horizontal bounding box."""
    xy = np.asarray(points, dtype=float)[:, :2]
    centre = (xy.min(axis=0) + xy.max(axis=0)) / 2.0
    return Estimate(centre, int(len(xy)), "depth camera")


def view_extent(points) -> np.ndarray:
    """(3,) VIEW_EXTENT (m) of the object's points in the camera's cloud: its height
    (HEIGHT_PERCENTILE of z above the table) and the footprint's long and short extents, 4
    standard deviations of the points' horizontal positions along their principal axes
    (4 sigma is the width of a uniform strip times 1.15): turning the object about the
    vertical or moving it on the table leaves them unchanged. InputError for fewer than 3
    points or non-finite ones."""
    from ..objects.mesh import standard_pose
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    if len(p) < 3 or not np.all(np.isfinite(p)):
        raise InputError(f"the camera's view of the object needs at least 3 finite points, "
                         f"got {len(p)}")
    height = np.percentile(p[:, 2], HEIGHT_PERCENTILE) - float(
        standard_pose().get("table_height", 0.0))
    xy = p[:, :2] - p[:, :2].mean(axis=0)
    minor, major = np.linalg.eigvalsh(xy.T @ xy / len(xy))
    return np.array([height, 4.0 * np.sqrt(max(major, 0.0)), 4.0 * np.sqrt(max(minor, 0.0))])


def camera_view(world_mesh, arm, *, seed: int = 0, camera=None) -> np.ndarray:
    """(3,) view_extent of an object where it stands, from the simulated depth camera's cloud
    (camera_points): what the classifier takes beside the wraps."""
    return view_extent(camera_points(world_mesh, arm, seed=seed, camera=camera))


def footprint_centre(mesh) -> np.ndarray:
    """(x, y) centre of a mesh's horizontal bounding box: where it truly stands (for
    measuring an estimate's error in simulation; never used to line the arm up)."""
    v = np.asarray(mesh.vertices)
    return (v[:, :2].min(axis=0) + v[:, :2].max(axis=0)) / 2.0
