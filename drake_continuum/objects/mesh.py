"""Loading and checking object meshes: every entry point that takes a user's mesh uses this."""

from __future__ import annotations

import numpy as np
import trimesh
import yaml

from ..arm import MODELS_DIR
from ..files import check_input_file
from ..errors import DrakeContinuumError

__all__ = ["MESH_SUFFIXES", "MeshError", "standard_pose", "load_mesh"]

MESH_SUFFIXES = (".obj", ".stl", ".ply", ".off")


class MeshError(DrakeContinuumError):
    """A mesh file cannot be used; the message names the file and the problem."""


def standard_pose() -> dict:
    """The fixed object pose of models/object_pose.yaml."""
    return yaml.safe_load((MODELS_DIR / "object_pose.yaml").read_text())


def load_mesh(path, require_watertight: bool = True) -> trimesh.Trimesh:
    """Read a triangle mesh and check that contact queries can use it.

    Raises MeshError naming the file when it does not exist, cannot be parsed, is empty,
    has non-finite vertices, or (with require_watertight) is not a closed surface: a
    rigid hydroelastic mesh must bound a volume.
    """
    path = check_input_file(path, MESH_SUFFIXES, MeshError, "mesh")
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
    return mesh
