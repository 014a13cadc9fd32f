"""Wrap planes (the paper's Fig. 4) and the movement cost between them.

A plane passes through the arm base. It is the tabletop plane rotated every alpha about the
world x axis (the line from the base towards the object) or about the world y axis, up to
90 deg. Following Fig. 4, planes rotated about x are wrapped clockwise and planes rotated
about y counter-clockwise, so the two families see the two sides of the object; with the
paper's alpha = 22.5 deg that is 10 planes, the paper's "10 or fewer" wraps an object.
Planes rotated about y tilt upwards, away from the table (downwards they would cut the table
first). `both_directions` wraps every plane both ways.

In its plane the arm starts straight along the ray from the base that passes the object's
cross-section at a small clearance, on the side given by the wrap direction, and bends
towards the object.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import trimesh

from ..errors import ConfigError, InputError

__all__ = ["PAPER_ALPHA_DEG", "PlaneCentre", "WrapPlane", "plane_normal", "make_plane",
           "enumerate_planes", "movement_cost", "cost_matrix", "cross_section",
           "start_direction", "base_rotation", "BaseClearanceError"]

PAPER_ALPHA_DEG = 22.5  # the paper's plane step about x and about y: 10 planes


class PlaneCentre(StrEnum):
    """Where the plane set is centred when collecting (planes.centre; members equal the
    configuration's strings): the depth camera's estimate of the object's position, as
    classify and recognize centre it, or the mark x = y = 0 a dataset's objects are set
    down on."""

    CAMERA = "camera"
    MARK = "mark"


@dataclass(frozen=True)
class WrapPlane:
    """A wrap plane through the arm base.

    Args:
        index: position in enumerate_planes().
        axis: "x" or "y", the world axis the tabletop plane was rotated about.
        angle: rotation angle, rad.
        direction: +1 to wrap counter-clockwise about the normal, -1 clockwise.
        normal: (3,) unit normal.
        origin: (3,) the arm base position.
    """

    index: int
    axis: str
    angle: float
    direction: int
    normal: np.ndarray
    origin: np.ndarray

    @property
    def label(self) -> str:
        turn = "ccw" if self.direction > 0 else "cw"
        return f"r{self.axis}{np.degrees(self.angle):g}-{turn}"

    def basis(self):
        """(e1, e2): in-plane unit vectors, e1 the projection of world x (towards the
        object), e2 = normal x e1."""
        x = np.array([1.0, 0.0, 0.0])
        e1 = x - (x @ self.normal) * self.normal
        e1 /= np.linalg.norm(e1)
        return e1, np.cross(self.normal, e1)

    def to_dict(self) -> dict:
        return {"index": self.index, "axis": self.axis, "angle_deg": float(np.degrees(self.angle)),
                "direction": self.direction, "normal": self.normal.tolist(),
                "origin": self.origin.tolist(), "label": self.label}


def plane_normal(axis: str, angle: float) -> np.ndarray:
    """Normal of the tabletop plane rotated by `angle` about world `axis` (y tilts upwards
    away from the base)."""
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([0.0, -s, c])
    if axis == "y":
        return np.array([-s, 0.0, c])
    raise InputError(f"plane axis must be 'x' or 'y', got {axis!r}")


def make_plane(origin, axis: str, angle_deg: float, *, direction: int | None = None,
               index: int = -1) -> WrapPlane:
    """One plane from its rotation; the default direction is the paper's for that axis."""
    if not np.isfinite(angle_deg):
        raise InputError(f"plane angle about {axis} must be a finite number of degrees, "
                         f"got {angle_deg}")
    if direction is None:
        direction = -1 if axis == "x" else 1
    if direction not in (-1, 1):
        raise InputError(f"wrap direction must be +1 or -1, got {direction}")
    angle = np.radians(angle_deg)
    return WrapPlane(index, axis, float(angle), int(direction), plane_normal(axis, angle),
                     np.asarray(origin, float))


def enumerate_planes(origin, alpha_deg: float = PAPER_ALPHA_DEG, both_directions: bool = False):
    """All wrap planes for angles 0, alpha, ... up to 90 deg about x, then about y."""
    if not 0 < alpha_deg <= 90:
        raise ConfigError(f"alpha must lie in (0, 90] deg, got {alpha_deg}")
    angles = np.arange(0.0, 90.0 + 1e-9, alpha_deg)
    planes = []
    for axis in ("x", "y"):
        default = -1 if axis == "x" else 1
        for a in angles:
            for d in ((default, -default) if both_directions else (default,)):
                planes.append(make_plane(origin, axis, a, direction=d, index=len(planes)))
    return planes


def movement_cost(a: WrapPlane, b: WrapPlane) -> float:
    """Rotation angle (rad) between two planes' normals: the base's re-orientation."""
    return float(np.arccos(np.clip(a.normal @ b.normal, -1.0, 1.0)))


def cost_matrix(planes) -> np.ndarray:
    N = np.array([p.normal for p in planes])
    return np.arccos(np.clip(N @ N.T, -1.0, 1.0))


def cross_section(mesh: trimesh.Trimesh, plane: WrapPlane, offset: float = 0.0) -> np.ndarray:
    """(k, 2) points of the object's cut by the plane (shifted by `offset` along its normal)
    in (e1, e2) coordinates about the base; empty when the plane misses the object."""
    segments = trimesh.intersections.mesh_plane(mesh, plane.normal,
                                                plane.origin + offset * plane.normal)
    if len(segments) == 0:
        return np.zeros((0, 2))
    pts = segments.reshape(-1, 3) - plane.origin
    e1, e2 = plane.basis()
    return np.stack([pts @ e1, pts @ e2], axis=1)


def cut_centroid(mesh: trimesh.Trimesh, plane: WrapPlane) -> np.ndarray:
    """(3,) world centroid of the plane's cut through the object (of its outline's
    segments, weighted by length), or the base position when the plane misses it."""
    segments = trimesh.intersections.mesh_plane(mesh, plane.normal, plane.origin)
    if len(segments) == 0:
        return plane.origin.copy()
    length = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    mid = segments.mean(axis=1)
    return (length[:, None] * mid).sum(0) / max(length.sum(), 1e-300)


class BaseClearanceError(ValueError):
    """The object's cut comes within the clearance of the arm base: no straight arm can
    start in that plane (a long object pointing at the base)."""


def start_direction(section_points: np.ndarray, plane: WrapPlane, clearance: float):
    """Start ray of the straight arm in the plane, passing the cut at `clearance`.

    Returns (unit 3-vector of the ray, distance along it to the tangent point). The ray
    lies on the side of the cut opposite the bending direction: a counter-clockwise wrap
    passes with the object on its left.
    """
    r = np.linalg.norm(section_points, axis=1)
    if np.any(r <= clearance):
        raise BaseClearanceError("the object's cut comes within the clearance of the arm "
                                 "base")
    ref = np.arctan2(*section_points.mean(0)[::-1])
    psi = np.angle(np.exp(1j * (np.arctan2(section_points[:, 1], section_points[:, 0]) - ref)))
    half = np.arcsin(clearance / r)
    if plane.direction > 0:
        k = np.argmin(psi - half)
        ang = ref + psi[k] - half[k]
    else:
        k = np.argmax(psi + half)
        ang = ref + psi[k] + half[k]
    e1, e2 = plane.basis()
    ray = np.cos(ang) * e1 + np.sin(ang) * e2
    return ray, float(np.sqrt(max(r[k] ** 2 - clearance ** 2, 0.0)))


def base_rotation(plane: WrapPlane, ray: np.ndarray) -> np.ndarray:
    """Base frame for a wrap: z along the start ray, x the in-plane bending direction."""
    z = ray / np.linalg.norm(ray)
    x = plane.direction * np.cross(plane.normal, z)
    return np.stack([x, np.cross(z, x), z], axis=1)
