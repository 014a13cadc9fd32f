"""Putting a mesh in the standard pose of models/object_pose.yaml, and its OBJ bytes."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from .mesh import standard_pose

__all__ = ["PoseLimits", "PosedMesh", "to_standard_pose", "pose_violations", "survives_obj",
           "welded_as_obj", "closed_as_obj", "closed_obj", "obj_bytes"]

@dataclass(frozen=True)
class PoseLimits:
    """The standard pose's limits (metres): footprint radius about the z axis and height."""
    footprint_radius_max: float
    height_max: float
    table_height: float = 0.0

    @classmethod
    def load(cls) -> "PoseLimits":
        d = standard_pose()
        return cls(float(d["footprint_radius_max"]), float(d["height_max"]),
                   float(d.get("table_height", 0.0)))


@dataclass(frozen=True)
class PosedMesh:
    """A mesh in the standard pose. mesh = scale * original + translation (no rotation)."""
    mesh: trimesh.Trimesh
    scale: float
    translation: np.ndarray  # (3,)

    def apply(self, point) -> np.ndarray:
        """Map a point of the original frame to the posed frame."""
        return self.scale * np.asarray(point, dtype=float) + self.translation


def to_standard_pose(mesh: trimesh.Trimesh, limits: PoseLimits | None = None) -> PosedMesh:
    """Stand the mesh on the table, footprint bounding box centred on the z axis.

    Scales down (never up) about the footprint centre only if the object would break the
    footprint radius or height limit, so real objects keep their real size when they fit.
    """
    limits = limits or PoseLimits.load()
    v = np.asarray(mesh.vertices, dtype=float)
    lo, hi = v.min(axis=0), v.max(axis=0)
    shift = np.array([-(lo[0] + hi[0]) / 2.0, -(lo[1] + hi[1]) / 2.0, -lo[2]])
    centred = v + shift
    radius = float(np.sqrt((centred[:, :2] ** 2).sum(axis=1)).max())
    height = float(hi[2] - lo[2])
    scale = min(1.0, limits.footprint_radius_max / radius, limits.height_max / height)
    if scale < 1.0:
        scale *= 1.0 - 1e-6  # stay strictly inside after rounding on disk
    posed = centred * scale
    posed[:, 2] += limits.table_height
    translation = shift * scale + [0.0, 0.0, limits.table_height]
    out = trimesh.Trimesh(posed, np.asarray(mesh.faces), process=False)
    return PosedMesh(out, scale, translation)


def pose_violations(mesh: trimesh.Trimesh, limits: PoseLimits | None = None,
                    tol: float = 1e-6) -> list[str]:
    """Why a mesh is not in the standard pose (empty list if it is)."""
    limits = limits or PoseLimits.load()
    v = np.asarray(mesh.vertices)
    problems = []
    if abs(v[:, 2].min() - limits.table_height) > tol:
        problems.append(f"lowest point at z={v[:, 2].min():.6f}, not on the table")
    centre = (v[:, :2].min(axis=0) + v[:, :2].max(axis=0)) / 2.0
    if np.abs(centre).max() > tol:
        problems.append(f"footprint centre at {centre.round(6).tolist()}, not at x=y=0")
    radius = np.sqrt((v[:, :2] ** 2).sum(axis=1)).max()
    if radius > limits.footprint_radius_max + tol:
        problems.append(f"footprint radius {radius:.4f} > {limits.footprint_radius_max}")
    height = v[:, 2].max() - limits.table_height
    if height > limits.height_max + tol:
        problems.append(f"height {height:.4f} > {limits.height_max}")
    return problems


def survives_obj(mesh: trimesh.Trimesh) -> bool:
    """Whether the mesh, written by obj_bytes and read back as load_mesh reads it (vertices
    merged), is still a closed surface: two vertices closer than the file's 0.1 um merge,
    and where a boolean left such a pair on different sheets the surface tears."""
    return _survives(mesh, _obj_text(mesh))


def _survives(mesh: trimesh.Trimesh, text: tuple[str, str]) -> bool:
    """survives_obj of a mesh whose _obj_text is `text`: its vertices read back from the
    text (a decimal number parses to the nearest double, as trimesh's OBJ reader parses it;
    a test compares the two), without trimesh's general OBJ reader (a fifth of placing a
    copy)."""
    vertices = np.fromstring(text[0].replace("v", " "), sep=" ").reshape(-1, 3)
    back = trimesh.Trimesh(vertices, np.asarray(mesh.faces), process=True)
    return back.is_watertight


def welded_as_obj(mesh: trimesh.Trimesh, tolerance: float = 1e-6) -> trimesh.Trimesh:
    """The mesh with vertices closer than `tolerance` (ten times the OBJ file's 0.1 um)
    merged into one and the faces that collapse dropped. A boolean can leave vertices a few
    nm apart (apple_010 of seed 13: 29 nm; mug_011 of seed 30: twelve pairs within 0.1 um);
    the file's rounding merges some of such a cluster and not others, tearing slivers, where
    merging the whole cluster closes the surface again."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    v = np.asarray(mesh.vertices, dtype=float)
    pairs = cKDTree(v).query_pairs(tolerance, output_type="ndarray")
    if not len(pairs):
        return mesh.copy()
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), (len(v), len(v)))
    _, label = connected_components(graph, directed=False)
    first = np.full(label.max() + 1, len(v))
    np.minimum.at(first, label, np.arange(len(v)))  # each cluster keeps its first vertex
    faces = first[label][np.asarray(mesh.faces)]
    keep = ((faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2])
            & (faces[:, 0] != faces[:, 2]))
    welded = trimesh.Trimesh(v, faces[keep], process=False)
    welded.update_faces(welded.unique_faces())
    welded.remove_unreferenced_vertices()
    return welded


def closed_as_obj(mesh: trimesh.Trimesh) -> trimesh.Trimesh | None:
    """The mesh as its OBJ file will read back closed: itself, or welded as the file would
    weld it (welded_as_obj) where the file's rounding would tear it; None if neither is.
    Every writer of an object file needs it: a mesh closed in one pose can tear in another,
    because the rounding that merges a pair depends on where the pair lies (hammer_026 of
    seed 71, turned onto its side)."""
    closed = closed_obj(mesh)
    return None if closed is None else closed[0]


def closed_obj(mesh: trimesh.Trimesh) -> tuple[trimesh.Trimesh, bytes] | None:
    """closed_as_obj's mesh and its obj_bytes, formatted once (None if neither closes)."""
    text = _obj_text(mesh)
    if _survives(mesh, text):
        return mesh, _joined(text)
    welded = welded_as_obj(mesh)
    text = _obj_text(welded)
    return (welded, _joined(text)) if _survives(welded, text) else None


def obj_bytes(mesh: trimesh.Trimesh) -> bytes:
    """Wavefront OBJ text with fixed formatting (0.1 um), so the same mesh gives the same bytes."""
    return _joined(_obj_text(mesh))


def _obj_text(mesh: trimesh.Trimesh) -> tuple[str, str]:
    """obj_bytes' vertex lines and face lines. One %-format of all the numbers at once
    ("%.7f" formats a float as f"{x:.7f}" does) costs half of formatting each line."""
    v = np.asarray(mesh.vertices, dtype=float)
    f = np.asarray(mesh.faces, dtype=np.int64) + 1
    return ("v %.7f %.7f %.7f\n" * len(v) % tuple(v.ravel().tolist()),
            "f %d %d %d\n" * len(f) % tuple(f.ravel().tolist()))


def _joined(text: tuple[str, str]) -> bytes:
    return ("# drake-continuum object, metres\n" + text[0] + text[1]).encode("ascii")
