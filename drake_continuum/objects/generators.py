"""Procedural objects for the paper's 10 categories, with real-world sizes and real variety.

Each category is a frozen parameter dataclass, a `sample_<category>(rng)` that draws one
plausible instance, and a `make_<category>(params)` that builds its watertight solid in
metres. Ranges overlap on purpose where people confuse classes (cup, mug and bowl; bottle and
toilet paper roll; apple and donut from the side): a dataset every descriptor gets right
teaches nothing. `generate_object` ties it together and puts the result in the standard pose.
"""

from __future__ import annotations

import dataclasses
import hashlib
from dataclasses import dataclass

import numpy as np
import trimesh
from manifold3d import CrossSection, Manifold

from . import shapes
from .pose import PosedMesh, to_standard_pose

CATEGORY_COUNTS = {"apple": 12, "banana": 6, "bottle": 51, "bowl": 21, "cup": 10,
                   "donut": 10, "hammer": 28, "mug": 32, "teapot": 6, "toilet_paper": 9}
CATEGORIES = tuple(CATEGORY_COUNTS)


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _handle_loop(x_left: float, x_right_inner: float, zc: float, b: float, exponent: float,
                 thickness: float, width: float) -> tuple[Manifold, float, float]:
    """A closed handle loop in the x-z plane whose inner edge reaches x_right_inner.

    Returns the solid, the loop centre x and its horizontal semi-axis.
    """
    a = 0.5 * (x_right_inner + thickness - x_left)
    xc = x_left + a
    loop = shapes.superellipse(a, b, exponent, 72)
    path = np.column_stack([xc + loop[:, 0], np.zeros(len(loop)), zc + loop[:, 1]])
    widths = np.tile([thickness, width], (len(path), 1))
    return shapes.sweep(path, widths, shapes.circle_outline(14), closed=True), xc, a


# --- mug -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class MugParams:
    """A mug: straight or barrel body, wall, floor and a loop handle (metres)."""
    height: float
    radius: float          # outer radius at mid-height
    taper: float           # fractional radius change from bottom to top (straight bodies)
    bulge: float           # fractional radius gain at mid-height (barrel bodies)
    wall: float
    bottom: float
    handle_z: float        # handle centre height as a fraction of the height
    handle_half_height: float
    handle_exponent: float  # 2 = oval handle, 4 = squarish
    handle_thickness: float  # tube semi-axis in the loop plane
    handle_width: float      # tube semi-axis across the loop plane
    hole_width: float        # clear gap between body and handle at the handle's middle


def sample_mug(rng: np.random.Generator) -> MugParams:
    height = _u(rng, 0.075, 0.125)
    barrel = rng.random() < 0.35
    thickness = _u(rng, 0.0035, 0.0065)
    half_height = _u(rng, 0.22, 0.36) * height
    z_room = 0.5 - (half_height + thickness + 0.008) / height
    return MugParams(
        height=height, radius=_u(rng, 0.034, 0.052),
        taper=0.0 if barrel else _u(rng, -0.12, 0.1),
        bulge=_u(rng, 0.05, 0.14) if barrel else 0.0,
        wall=_u(rng, 0.003, 0.006), bottom=_u(rng, 0.005, 0.01),
        handle_z=0.5 + _u(rng, -1.0, 1.0) * max(z_room, 0.0) * 0.6,
        handle_half_height=half_height, handle_exponent=_u(rng, 2.0, 4.0),
        handle_thickness=thickness, handle_width=_u(rng, 0.004, 0.009),
        hole_width=_u(rng, 0.012, 0.032))


def _mug_outer(p: MugParams, n: int = 24) -> np.ndarray:
    z = np.linspace(0.0, p.height, n)
    t = z / p.height
    r = p.radius * (1.0 + p.taper * (t - 0.5) + p.bulge * (np.sin(np.pi * t) - 0.7))
    foot = min(0.004, 0.5 * p.wall)
    return np.vstack([[[r[0] - foot, 0.0]], [[r[0], foot]], np.column_stack([r, z])[1:]])


def _mug_radius_at(p: MugParams, z: np.ndarray) -> np.ndarray:
    outer = _mug_outer(p)
    return np.interp(z, outer[:, 1], outer[:, 0])


def make_mug(p: MugParams) -> Manifold:
    outer = _mug_outer(p)
    outline, cavity = shapes.open_shell_section(outer, p.wall, p.bottom)
    zc = p.handle_z * p.height
    zs = np.linspace(zc - p.handle_half_height, zc + p.handle_half_height, 30)
    r_span = _mug_radius_at(p, zs)
    x_left = float(r_span.min()) - p.handle_thickness - 0.001
    x_inner = float(_mug_radius_at(p, np.array([zc]))[0]) + p.hole_width
    handle, _, _ = _handle_loop(x_left, x_inner, zc, p.handle_half_height, p.handle_exponent,
                                p.handle_thickness, p.handle_width)
    return (shapes.revolve(outline) + handle) - shapes.revolve(cavity)


def mug_landmarks(p: MugParams) -> dict:
    """Where the handle hole and the cavity are, in the mug's own frame (axis = z axis)."""
    zc = p.handle_z * p.height
    r_mid = float(_mug_radius_at(p, np.array([zc]))[0])
    rim_r = float(_mug_outer(p)[-1, 0])
    return {"handle_hole_center": [r_mid + 0.5 * p.hole_width, 0.0, zc],
            "handle_hole_radii": [0.5 * p.hole_width,
                                  p.handle_half_height - p.handle_thickness],
            "handle_half_width": p.handle_width,
            "cavity_axis_xy": [0.0, 0.0],
            "cavity_inner_radius": rim_r - p.wall,
            "cavity_depth": p.height - p.bottom}


# --- registry ------------------------------------------------------------------------------

SAMPLERS = {"mug": sample_mug}
MAKERS = {"mug": make_mug}


@dataclass(frozen=True)
class GeneratedObject:
    """One generated object in the standard pose.

    Attributes: category, index (within the category), id (e.g. "mug_007"), params (the
    generator's dataclass), posed (mesh, scale and translation applied).
    """
    category: str
    index: int
    id: str
    params: object
    posed: PosedMesh

    @property
    def mesh(self) -> trimesh.Trimesh:
        return self.posed.mesh

    def params_dict(self) -> dict:
        return dataclasses.asdict(self.params)


def object_rng(category: str, index: int, seed: int) -> np.random.Generator:
    """An independent stream per (seed, category, index): objects do not depend on each other."""
    key = int.from_bytes(hashlib.sha256(category.encode()).digest()[:4], "little")
    return np.random.default_rng([int(seed), key, int(index)])


def generate_object(category: str, index: int, seed: int = 0) -> GeneratedObject:
    """Sample and build object `index` of `category`, in the standard pose."""
    if category not in SAMPLERS:
        raise ValueError(f"unknown category {category!r} (known: {', '.join(CATEGORIES)})")
    params = SAMPLERS[category](object_rng(category, index, seed))
    solid = MAKERS[category](params)
    posed = to_standard_pose(shapes.manifold_to_trimesh(solid))
    return GeneratedObject(category, index, f"{category}_{index:03d}", params, posed)
