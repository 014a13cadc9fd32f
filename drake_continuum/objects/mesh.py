"""Loading and checking object meshes: every entry point that takes a user's mesh uses this."""

from __future__ import annotations

import logging

import numpy as np
import trimesh
import yaml

from ..errors import DrakeContinuumError
from ..files import check_input_file
from ..kinematics.arm import MODELS_DIR

__all__ = ["MESH_SUFFIXES", "MeshError", "standard_pose", "load_mesh", "closed_mesh",
           "TRIANGLE_LIMIT", "size_warning", "surface_deviation", "simplify_mesh"]

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".off")

log = logging.getLogger(__name__)


class MeshError(DrakeContinuumError):
    """A mesh file cannot be used; the message names the file and the problem."""


_POSE_READ: dict = {}  # (mtime_ns, size) of models/object_pose.yaml -> its values


def standard_pose() -> dict:
    """The fixed object pose of models/object_pose.yaml (a copy of its values). The file is
    parsed again only when it changed: placing a dataset asks for it twice a copy, and
    parsing the YAML each time was a tenth of placing's CPU."""
    path = MODELS_DIR / "object_pose.yaml"
    stat = path.stat()
    key = (stat.st_mtime_ns, stat.st_size)
    if key not in _POSE_READ:
        _POSE_READ.clear()
        _POSE_READ[key] = yaml.safe_load(path.read_text())
    return dict(_POSE_READ[key])


def load_mesh(path, require_watertight: bool = True) -> trimesh.Trimesh:
    """Read a triangle mesh and check that contact queries can use it.

    Raises MeshError naming the file when it does not exist, cannot be parsed, is empty,
    has non-finite vertices, or (with require_watertight) is not a closed surface: a
    rigid hydroelastic mesh must bound a volume. A closed surface wound inside out (negative
    volume: contact would take its outside for its inside) is turned outward, with a
    warning.
    """
    path = check_input_file(path, MESH_SUFFIXES, MeshError, kind="mesh")
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many types for unreadable files
        raise MeshError(f"{path}: cannot be read as a mesh ({type(e).__name__}: {e})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f"{path}: holds no triangles")
    if not np.all(np.isfinite(loaded.vertices)):
        raise MeshError(f"{path}: has NaN or infinite vertex coordinates")
    mesh = trimesh.Trimesh(loaded.vertices, loaded.faces, process=True)
    if require_watertight and not mesh.is_watertight:
        raise MeshError(f"{path}: is not a closed surface (not watertight); repair it or "
                        f"import it with `drake-continuum objects import`")
    if mesh.is_watertight and mesh.volume < 0:
        mesh.invert()
        log.warning("%s: faces wound inside out (negative volume); turned outward", path)
    return mesh


def closed_mesh(mesh) -> trimesh.Trimesh:
    """`mesh` as contact and distance queries need it: a trimesh must be a closed surface
    (MeshError otherwise), anything else is a file read by load_mesh."""
    if isinstance(mesh, trimesh.Trimesh):
        if not mesh.is_watertight:
            raise MeshError("object mesh is not a closed surface (not watertight)")
        return mesh
    return load_mesh(mesh)


# A wrap's cost grows with the mesh: measured on this machine, a 442k-triangle scan took
# 15.7 s and 1.43 GB for one wrap, a 2k-triangle mug a fraction of a second.
TRIANGLE_LIMIT = 100_000


def size_warning(mesh: trimesh.Trimesh, name, limit: int | None = None) -> str | None:
    """The warning to give before wrapping a mesh of more than `limit` triangles (default
    TRIANGLE_LIMIT), or None."""
    limit = TRIANGLE_LIMIT if limit is None else limit
    if len(mesh.faces) <= limit:
        return None
    return (f"{name} has {len(mesh.faces):,} triangles (more than {limit:,}): each wrap may "
            f"take tens of seconds and over a gigabyte; --simplify MM decimates it to within "
            f"MM millimetres of its surface (e.g. --simplify 0.5)")


class _Surface:
    """A mesh's sample points (its vertices and `n_samples` area-uniform points) and an
    Open3D scene measuring exact point-to-triangle distances to it."""

    def __init__(self, mesh: trimesh.Trimesh, n_samples: int = 20000, seed: int = 0):
        import open3d as o3d

        rng = np.random.default_rng(seed)
        area = mesh.area_faces / mesh.area_faces.sum()
        faces = rng.choice(len(mesh.faces), n_samples, p=area)
        u, v = rng.random((2, n_samples))
        flip = u + v > 1
        u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
        tri = mesh.triangles[faces]
        on = tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])
        self.points = np.vstack([mesh.vertices, on]).astype(np.float32)
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                                 o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))

    def distance_to(self, points: np.ndarray) -> np.ndarray:
        import open3d as o3d
        return self.scene.compute_distance(o3d.core.Tensor(points)).numpy()


def surface_deviation(a, b) -> float:
    """Largest distance from either surface to the other (a sampled Hausdorff distance, m):
    each mesh's vertices and 20,000 area-uniform points on it, measured to the other
    surface with Open3D's exact point-to-triangle distance. a, b: trimesh meshes (or
    their _Surface)."""
    a = a if isinstance(a, _Surface) else _Surface(a)
    b = b if isinstance(b, _Surface) else _Surface(b)
    return float(max(b.distance_to(a.points).max(), a.distance_to(b.points).max()))


def simplify_mesh(mesh: trimesh.Trimesh, tolerance: float, min_triangles: int = 500
                  ) -> tuple[trimesh.Trimesh, float]:
    """The mesh with the fewest triangles Open3D's quadric decimation reaches, halving the
    count (each step decimating the last) while the result stays a closed surface within
    `tolerance` (m) of the original (surface_deviation); returns (mesh, its deviation).
    The original if no halving keeps to the tolerance."""
    import open3d as o3d

    if not tolerance > 0:
        raise MeshError(f"simplification tolerance must be a positive distance, got "
                        f"{tolerance}")
    original = _Surface(mesh)
    best, best_dev = mesh, 0.0
    current = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(np.asarray(mesh.vertices)),
                                        o3d.utility.Vector3iVector(np.asarray(mesh.faces)))
    target = len(mesh.faces) // 2
    while target >= min_triangles:
        current = current.simplify_quadric_decimation(target_number_of_triangles=target)
        candidate = trimesh.Trimesh(np.asarray(current.vertices), np.asarray(current.triangles),
                                    process=True)
        if not candidate.is_watertight or len(candidate.faces) >= len(best.faces):
            break
        dev = surface_deviation(original, candidate)
        if dev > tolerance:
            break
        best, best_dev = candidate, dev
        target //= 2
    return best, best_dev
