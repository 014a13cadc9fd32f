"""The ten categories' generators: for each, a frozen parameter dataclass, a
`sample_<category>(rng)` that draws one plausible instance with real-world sizes, and a
`make_<category>(params)` that builds its watertight solid in metres (generators.py holds
the registry and `generate_object`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from manifold3d import CrossSection, Manifold, OpType
from scipy.interpolate import PchipInterpolator

from . import shapes

__all__ = ["MugParams", "sample_mug", "make_mug", "mug_landmarks",
           "CupParams", "sample_cup", "make_cup", "BowlParams", "sample_bowl", "make_bowl",
           "BottleParams", "sample_bottle", "make_bottle", "ToiletPaperParams",
           "sample_toilet_paper", "make_toilet_paper", "AppleParams", "sample_apple", "make_apple",
           "DonutParams", "sample_donut", "make_donut", "BananaParams", "sample_banana",
           "make_banana", "HammerParams", "sample_hammer", "make_hammer", "TeapotParams",
           "sample_teapot", "make_teapot"]


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _handle_loop(x_left: float, x_right_inner: float, zc: float, *, b: float, exponent: float,
                 thickness: float, width: float) -> tuple[Manifold, float, float]:
    """A closed handle loop in the x-z plane whose inner edge reaches x_right_inner.

    Returns the solid, the loop centre x and its horizontal semi-axis.
    """
    a = 0.5 * (x_right_inner + thickness - x_left)
    xc = x_left + a
    loop = shapes.superellipse(a, b, exponent, n=72)
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
    handle, _, _ = _handle_loop(x_left, x_inner, zc, b=p.handle_half_height,
                                exponent=p.handle_exponent, thickness=p.handle_thickness,
                                width=p.handle_width)
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


# --- cup -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class CupParams:
    """A handle-less drinking cup: tapered revolved shell, optional rolled rim (metres)."""
    height: float
    bottom_radius: float
    top_radius: float
    flare: float           # profile exponent: 1 straight taper, < 1 bellied, > 1 flared
    wall: float
    bottom: float
    rim_radius: float      # rolled rim section radius, 0 for a plain rim


def sample_cup(rng: np.random.Generator) -> CupParams:
    height = _u(rng, 0.07, 0.15)
    top = _u(rng, 0.032, 0.05)
    wall = _u(rng, 0.0025, 0.005)
    return CupParams(height=height, bottom_radius=top * _u(rng, 0.6, 0.9), top_radius=top,
                     flare=_u(rng, 0.6, 1.6), wall=wall, bottom=_u(rng, 0.003, 0.015),
                     rim_radius=_u(rng, 0.6, 1.0) * wall if rng.random() < 0.5 else 0.0)


def make_cup(p: CupParams) -> Manifold:
    t = np.linspace(0.0, 1.0, 20)
    r = p.bottom_radius + (p.top_radius - p.bottom_radius) * t ** p.flare
    outer = np.column_stack([r, t * p.height])
    outline, cavity = shapes.open_shell_section(outer, p.wall, p.bottom)
    section = outline - cavity
    if p.rim_radius > 0.0:
        lip = CrossSection.circle(p.rim_radius, 20).translate(
            [p.top_radius - 0.5 * p.wall, p.height - p.rim_radius * 0.5])
        section = section + lip + lip.mirror([1.0, 0.0])
    return shapes.revolve(section)


# --- bowl ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class BowlParams:
    """An open revolved bowl: flat base, rounded wall rising to the rim, optional foot ring."""
    rim_radius: float
    depth: float
    base_fraction: float   # base radius / rim radius
    roundness: float       # profile exponent: small = round belly, 1 = conical
    wall: float
    foot: float            # foot ring height, 0 for none


def sample_bowl(rng: np.random.Generator) -> BowlParams:
    rim = _u(rng, 0.055, 0.125)
    return BowlParams(rim_radius=rim, depth=rim * _u(rng, 0.35, 0.85),
                      base_fraction=_u(rng, 0.3, 0.6), roundness=_u(rng, 0.35, 0.9),
                      wall=_u(rng, 0.003, 0.007),
                      foot=_u(rng, 0.004, 0.01) if rng.random() < 0.5 else 0.0)


def make_bowl(p: BowlParams) -> Manifold:
    t = np.linspace(0.0, 1.0, 24) ** 1.5
    base = p.base_fraction * p.rim_radius
    r = base + (p.rim_radius - base) * t ** p.roundness
    outer = np.column_stack([r, p.foot + t * (p.depth - p.foot)])
    if p.foot > 0.0:
        outer = np.vstack([[[base * 0.85, 0.0], [base * 0.85 + p.foot * 0.3, p.foot]],
                           outer[1:]])
    outline, cavity = shapes.open_shell_section(outer, p.wall, p.wall + p.foot)
    return shapes.revolve(outline - cavity)


# --- bottle --------------------------------------------------------------------------------

@dataclass(frozen=True)
class BottleParams:
    """A closed (capped) bottle: body, shoulder, neck and cap; optionally flattened."""
    height: float
    body_radius: float
    neck_radius: float
    shoulder_start: float  # fraction of the height where the shoulder begins
    shoulder_length: float  # fraction of the height
    shoulder_exponent: float  # < 1 rounded, > 1 conical-to-steep
    waist: float           # fractional inward curve of the body (grip), 0 for straight
    cap_height: float
    cap_extra: float       # cap radius minus neck radius
    flatten: float         # y scale of the body: 1 round, ~0.5 for cleaner-type bottles
    neck_offset: float     # x shift of the neck (cleaner bottles have off-centre necks)


def sample_bottle(rng: np.random.Generator) -> BottleParams:
    kind = rng.choice(["round", "round", "round", "squat", "cleaner"])
    if kind == "squat":
        height, body = _u(rng, 0.15, 0.19), _u(rng, 0.042, 0.056)
        start, length = _u(rng, 0.6, 0.8), _u(rng, 0.06, 0.15)
    else:
        height, body = _u(rng, 0.16, 0.30), _u(rng, 0.024, 0.048)
        start, length = _u(rng, 0.4, 0.72), _u(rng, 0.06, 0.28)
    cleaner = kind == "cleaner"
    return BottleParams(
        height=height, body_radius=body * (1.25 if cleaner else 1.0),
        neck_radius=_u(rng, 0.009, 0.017) if kind != "squat" else _u(rng, 0.015, 0.03),
        shoulder_start=start, shoulder_length=length,
        shoulder_exponent=_u(rng, 0.5, 2.0), waist=_u(rng, 0.0, 0.12) * (rng.random() < 0.4),
        cap_height=_u(rng, 0.008, 0.025), cap_extra=_u(rng, 0.0, 0.004),
        flatten=_u(rng, 0.45, 0.7) if cleaner else 1.0,
        neck_offset=_u(rng, -0.4, 0.4) * body if cleaner else 0.0)


def _bottle_profile(p: BottleParams) -> np.ndarray:
    z_cap = p.height - p.cap_height
    z_s = p.shoulder_start * z_cap
    z_n = min(z_s + p.shoulder_length * p.height, z_cap - 0.01)
    z = np.concatenate([np.linspace(0.004, z_s, 12)[:-1], np.linspace(z_s, z_n, 16),
                        [0.5 * (z_n + z_cap), z_cap]])
    body = p.body_radius * (1.0 - p.waist * np.sin(np.pi * np.clip(z / z_s, 0, 1)) ** 2)
    blend = shapes.smooth_step((z - z_s) / (z_n - z_s)) ** p.shoulder_exponent
    r = body + (p.neck_radius - body) * blend
    rc = p.neck_radius + p.cap_extra
    chamfer = min(0.004, 0.2 * p.body_radius)
    return np.vstack([[[0.0, 0.0], [p.body_radius - chamfer, 0.0]], np.column_stack([r, z]),
                      [[rc, z_cap], [rc, p.height - 0.002], [rc - 0.002, p.height],
                       [0.0, p.height]]])


def make_bottle(p: BottleParams) -> Manifold:
    solid = shapes.revolve(shapes.polygon_section(_bottle_profile(p)))
    if p.flatten == 1.0 and p.neck_offset == 0.0:
        return solid
    z_n = p.shoulder_start * (p.height - p.cap_height) + p.shoulder_length * p.height

    def squeeze(v: np.ndarray) -> np.ndarray:
        w = shapes.smooth_step((v[:, 2] - 0.6 * z_n) / (0.4 * z_n + 1e-9))
        out = v.copy()
        out[:, 1] *= p.flatten + (1.0 - p.flatten) * w
        out[:, 0] += p.neck_offset * w
        return out

    return solid.warp_batch(squeeze)


# --- toilet paper --------------------------------------------------------------------------

@dataclass(frozen=True)
class ToiletPaperParams:
    """A toilet paper roll: paper annulus around a cardboard core, slightly squashed."""
    height: float
    outer_radius: float    # smaller for a partly used roll
    core_radius: float     # core outer radius
    core_wall: float
    core_recess: float     # how far the core sits inside the paper at each end
    squash: float          # y scale


def sample_toilet_paper(rng: np.random.Generator) -> ToiletPaperParams:
    core = _u(rng, 0.019, 0.024)
    return ToiletPaperParams(height=_u(rng, 0.095, 0.115), outer_radius=_u(rng, 0.042, 0.065),
                             core_radius=core, core_wall=_u(rng, 0.0012, 0.002),
                             core_recess=_u(rng, 0.0, 0.003), squash=_u(rng, 0.88, 1.0))


def make_toilet_paper(p: ToiletPaperParams) -> Manifold:
    c = 0.0015  # soft paper edges
    paper = shapes.polygon_section(np.array([
        [p.core_radius, 0.0], [p.outer_radius - c, 0.0], [p.outer_radius, c],
        [p.outer_radius, p.height - c], [p.outer_radius - c, p.height],
        [p.core_radius, p.height]]))
    core = CrossSection.square([p.core_wall + 2e-4, p.height - 2.0 * p.core_recess]).translate(
        [p.core_radius - p.core_wall, p.core_recess])
    solid = shapes.revolve(paper + core)
    return solid.scale([1.0, p.squash, 1.0])


# --- apple ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class AppleParams:
    """A squashed, irregular sphere with a top and bottom dimple, five lobes and a stem."""
    radius: float
    squash: float          # height / width
    top_dimple: float      # fractional depth
    bottom_dimple: float
    lobes: float           # amplitude of the five bottom lobes
    noise: tuple           # (k, 5): direction xyz, frequency, amplitude of random bumps
    stem_length: float
    stem_radius: float
    stem_tilt: float       # radians


def sample_apple(rng: np.random.Generator) -> AppleParams:
    dirs = rng.normal(size=(5, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    noise = np.column_stack([dirs, rng.uniform(1.0, 3.0, 5), rng.uniform(0.005, 0.03, 5)])
    return AppleParams(radius=_u(rng, 0.032, 0.047), squash=_u(rng, 0.78, 0.98),
                       top_dimple=_u(rng, 0.12, 0.3), bottom_dimple=_u(rng, 0.04, 0.15),
                       lobes=_u(rng, 0.0, 0.04), noise=tuple(map(tuple, noise.tolist())),
                       stem_length=_u(rng, 0.008, 0.025), stem_radius=_u(rng, 0.0012, 0.0025),
                       stem_tilt=_u(rng, -0.5, 0.5))


def _apple_radius(p: AppleParams, u: np.ndarray) -> np.ndarray:
    """Radial scale of the unit directions u (n, 3): star-shaped, so the surface stays simple."""
    polar = np.arccos(np.clip(u[:, 2], -1.0, 1.0))
    azimuth = np.arctan2(u[:, 1], u[:, 0])
    r = np.ones(len(u))
    r -= p.top_dimple * np.exp(-(polar / 0.45) ** 2)
    r -= p.bottom_dimple * np.exp(-((np.pi - polar) / 0.4) ** 2)
    r += p.lobes * np.cos(5.0 * azimuth) * np.clip(-u[:, 2], 0.0, 1.0)
    noise = np.asarray(p.noise)
    r += (noise[:, 4] * np.sin(noise[:, 3] * (u @ noise[:, :3].T) * np.pi)).sum(axis=1)
    return r


def make_apple(p: AppleParams) -> Manifold:
    sphere = trimesh.creation.icosphere(subdivisions=4)
    u = np.asarray(sphere.vertices)
    v = u * _apple_radius(p, u)[:, None] * p.radius
    v[:, 2] *= p.squash
    body = shapes.manifold_from_arrays(v, np.asarray(sphere.faces))
    top = p.radius * p.squash * _apple_radius(p, np.array([[0.0, 0.0, 1.0]]))[0]
    s = np.linspace(0.0, 1.0, 8)[:, None]
    bend = np.column_stack([np.sin(p.stem_tilt * s[:, 0]), np.zeros(8),
                            np.cos(p.stem_tilt * s[:, 0])])
    path = np.array([0.0, 0.0, top - 0.006]) + (p.stem_length + 0.006) * s * bend
    widths = np.column_stack([np.linspace(1.3, 0.9, 8), np.linspace(1.3, 0.9, 8)]) * p.stem_radius
    return body + shapes.sweep(path, widths, shapes.circle_outline(10))


# --- donut ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class DonutParams:
    """A torus lying flat: varied radii, a slight ellipse, flattened and a little lumpy."""
    major_radius: float
    tube_radius: float
    ellipse: float         # x / y ratio of the ring
    flatten: float         # z scale of the tube
    lumps: tuple           # (3, 4): angular frequencies (u, v), phase, amplitude (fraction)


def sample_donut(rng: np.random.Generator) -> DonutParams:
    tube = _u(rng, 0.012, 0.026)
    major = tube + _u(rng, 0.007, 0.03)
    lumps = np.column_stack([rng.integers(2, 7, 3), rng.integers(1, 3, 3),
                             rng.uniform(0, 2 * np.pi, 3), rng.uniform(0.0, 0.05, 3)])
    return DonutParams(major_radius=major, tube_radius=tube, ellipse=_u(rng, 1.0, 1.12),
                       flatten=_u(rng, 0.7, 1.0), lumps=tuple(map(tuple, lumps.tolist())))


def make_donut(p: DonutParams, n_u: int = 64, n_v: int = 24) -> Manifold:
    u = np.linspace(0.0, 2 * np.pi, n_u, endpoint=False)[:, None]
    v = np.linspace(0.0, 2 * np.pi, n_v, endpoint=False)[None, :]
    lumps = np.asarray(p.lumps)
    rho = p.tube_radius * (1.0 + sum(a * np.sin(fu * u + fv * v + ph)
                                     for fu, fv, ph, a in lumps))
    ring = p.major_radius + rho * np.cos(v)
    verts = np.stack([ring * np.cos(u) * p.ellipse, ring * np.sin(u),
                      rho * np.sin(v) * p.flatten], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v), indexing="ij")
    a, b = i * n_v + j, i * n_v + (j + 1) % n_v
    c, d = ((i + 1) % n_u) * n_v + j, ((i + 1) % n_u) * n_v + (j + 1) % n_v
    faces = np.concatenate([np.stack([a, c, d], -1).reshape(-1, 3),
                            np.stack([a, d, b], -1).reshape(-1, 3)])
    return shapes.manifold_from_arrays(verts, faces)


# --- banana --------------------------------------------------------------------------------

@dataclass(frozen=True)
class BananaParams:
    """A curved, tapered, faceted tube lying on its back (ends up), with a stalk."""
    length: float          # along the centre line, without the stalk
    bend_radius: float
    radius: float          # thickest half-width
    facets: int
    facet_sharpness: float
    ovality: float         # y / in-plane half-width ratio
    stalk_length: float


def sample_banana(rng: np.random.Generator) -> BananaParams:
    return BananaParams(length=_u(rng, 0.15, 0.22), bend_radius=_u(rng, 0.11, 0.25),
                        radius=_u(rng, 0.014, 0.02), facets=int(rng.choice([4, 5, 5, 6])),
                        facet_sharpness=_u(rng, 0.3, 0.8), ovality=_u(rng, 0.85, 1.05),
                        stalk_length=_u(rng, 0.015, 0.03))


def make_banana(p: BananaParams, n: int = 40) -> Manifold:
    total = p.length + p.stalk_length
    s = np.linspace(0.0, total, n)
    angle = (s - 0.5 * p.length) / p.bend_radius
    path = np.column_stack([p.bend_radius * np.sin(angle), np.zeros(n),
                            p.bend_radius * (1.0 - np.cos(angle))])
    t = s / p.length
    fruit = 0.22 + 0.78 * np.sin(np.pi * np.clip(t, 0.0, 1.0)) ** 0.55
    stalk = 0.3 + 0.1 * np.clip((s - p.length) / p.stalk_length, 0.0, 1.0)
    r = p.radius * np.where(t < 0.8, fruit, np.maximum(stalk, fruit))
    widths = np.column_stack([r, r * p.ovality])
    return shapes.sweep(path, widths, shapes.faceted_outline(p.facets, p.facet_sharpness))


# --- hammer --------------------------------------------------------------------------------

@dataclass(frozen=True)
class HammerParams:
    """A hammer standing on its head, handle up. Head kinds: claw, ball_peen, mallet."""
    kind: str
    height: float          # overall, table to handle end
    head_length: float     # along x
    head_radius: float     # half-height of the head (face radius)
    handle_radii: tuple    # (a, b) elliptical half-widths of the handle at the head
    grip_swell: float      # fractional growth of the handle towards its end
    claw_drop: float       # how far the claw curves down (claw hammers)


def sample_hammer(rng: np.random.Generator) -> HammerParams:
    kind = str(rng.choice(["claw", "claw", "ball_peen", "mallet"]))
    head_r = _u(rng, 0.022, 0.038) if kind == "mallet" else _u(rng, 0.01, 0.016)
    a = _u(rng, 0.009, 0.014)
    return HammerParams(kind=kind, height=_u(rng, 0.24, 0.335),
                        head_length=_u(rng, 0.085, 0.13) if kind == "mallet"
                        else _u(rng, 0.095, 0.135),
                        head_radius=head_r, handle_radii=(a, a * _u(rng, 0.55, 0.8)),
                        grip_swell=_u(rng, 0.0, 0.35), claw_drop=_u(rng, 0.0, 0.012))


def _x_cylinder(x0: float, x1: float, r0: float, *, r1: float, z: float, n: int = 32) -> Manifold:
    return Manifold.cylinder(x1 - x0, r0, r1, n).rotate([0.0, 90.0, 0.0]).translate([x0, 0, z])


def _claw_head(p: HammerParams) -> Manifold:
    r, half = p.head_radius, 0.5 * p.head_length
    face = _x_cylinder(0.25 * half, half, r * 0.85, r1=r, z=r)
    block = Manifold.cube([0.7 * half, 1.3 * r, 1.6 * r], center=True).translate([0.0, 0, r])
    claw_x = np.linspace(-0.3 * half, -half, 6)
    drop = p.claw_drop * ((claw_x + 0.3 * half) / (0.7 * half)) ** 2
    thick = np.linspace(1.4 * r, 0.35 * r, 6)
    plates = [Manifold.cube([0.01, 1.2 * r, t], center=True).translate([x, 0, r - d])
              for x, t, d in zip(claw_x, thick, drop)]
    claw = Manifold.batch_boolean([Manifold.batch_hull([a, b]) for a, b in
                                   zip(plates[:-1], plates[1:])], OpType.Add)
    slot = Manifold.cube([0.7 * half, 0.25 * r, 3 * r], center=True).translate(
        [-half + 0.2 * half, 0, r])
    return face + block + (claw - slot)


def _ball_peen_head(p: HammerParams) -> Manifold:
    r, half = p.head_radius, 0.5 * p.head_length
    face = _x_cylinder(0.2 * half, half, r * 0.8, r1=r, z=r)
    ball_x = -half + r * 0.95
    # The body reaches the ball's centre: a long, thin head's ball would float free of it.
    body = _x_cylinder(min(-0.55 * half, ball_x), 0.25 * half, r * 0.75, r1=r * 0.8, z=r)
    ball = Manifold.sphere(r * 0.95, 32).translate([ball_x, 0, r])
    return face + body + ball


def _mallet_head(p: HammerParams) -> Manifold:
    r, half = p.head_radius, 0.5 * p.head_length
    return _x_cylinder(-half, half, r, r1=r, z=r, n=48)


def make_hammer(p: HammerParams) -> Manifold:
    head = {"claw": _claw_head, "ball_peen": _ball_peen_head, "mallet": _mallet_head}[p.kind](p)
    # The handle starts inside the head, below its axis: a handle end in the plane of the
    # axis shares edges with the head's cylinders, and the union then pinches there.
    z = np.linspace(0.5 * p.head_radius, p.height - 0.004, 24)
    t = (z - z[0]) / (z[-1] - z[0])
    grow = 1.0 + p.grip_swell * shapes.smooth_step((t - 0.5) / 0.4)
    a, b = p.handle_radii
    widths = np.column_stack([a * grow, b * grow])
    widths[-1] *= 0.8  # rounded end
    path = np.column_stack([np.zeros(24), np.zeros(24), z])
    return head + shapes.sweep(path, widths, shapes.circle_outline(16))


# --- teapot --------------------------------------------------------------------------------

@dataclass(frozen=True)
class TeapotParams:
    """A closed teapot (or jug): revolved body with lid and knob, swept spout and handle."""
    body_height: float
    belly_radius: float
    belly_z: float         # fraction of the body height
    base_fraction: float   # base radius / belly radius
    top_fraction: float    # opening radius / belly radius
    lid_height: float
    spout_length: float
    spout_rise: float      # fraction of the body height the spout tip rises above its root
    spout_radius: float    # at the root
    handle_half_height: float
    handle_hole: float


def sample_teapot(rng: np.random.Generator) -> TeapotParams:
    belly = _u(rng, 0.05, 0.075)
    height = belly * _u(rng, 1.1, 2.4)
    return TeapotParams(body_height=height, belly_radius=belly, belly_z=_u(rng, 0.3, 0.55),
                        base_fraction=_u(rng, 0.55, 0.85), top_fraction=_u(rng, 0.45, 0.7),
                        lid_height=_u(rng, 0.01, 0.03), spout_length=_u(rng, 0.04, 0.075),
                        spout_rise=_u(rng, 0.5, 0.95), spout_radius=_u(rng, 0.01, 0.016),
                        handle_half_height=_u(rng, 0.22, 0.32) * height,
                        handle_hole=_u(rng, 0.015, 0.03))


def _teapot_radius(p: TeapotParams, z: np.ndarray) -> np.ndarray:
    h, r = p.body_height, p.belly_radius
    knots_z = np.array([0.0, p.belly_z * h, h])
    knots_r = np.array([p.base_fraction * r, r, p.top_fraction * r])
    zz = np.array([0.0, 0.5 * p.belly_z * h, p.belly_z * h, 0.5 * (1 + p.belly_z) * h, h])
    rr = np.interp(zz, knots_z, knots_r)
    rr[1] = 0.5 * (rr[1] + r)
    rr[3] = 0.5 * (rr[3] + r)
    return PchipInterpolator(zz, rr)(z)


def make_teapot(p: TeapotParams) -> Manifold:
    h = p.body_height
    z = np.linspace(0.0, h, 28)
    r = _teapot_radius(p, z)
    rt = r[-1]
    lid_z = h + np.linspace(0.0, p.lid_height, 8)
    lid_r = (rt + 0.002) * np.cos(np.linspace(0.0, 1.2, 8))
    knob = 0.25 * rt
    top = lid_z[-1]
    profile = np.vstack([[[0.0, 0.0], [r[0] - 0.003, 0.0]], np.column_stack([r, z])[1:],
                         [[rt + 0.002, h]], np.column_stack([lid_r, lid_z])[1:],
                         [[0.4 * knob, top], [0.4 * knob, top + 0.006],
                          [knob, top + 0.01], [0.6 * knob, top + 0.016], [0.0, top + 0.017]]])
    body = shapes.revolve(shapes.polygon_section(profile))

    root = np.array([0.3 * p.belly_radius, 0.3 * h])
    tip = np.array([float(_teapot_radius(p, np.array([0.3 * h]))[0]) + p.spout_length,
                    0.3 * h + p.spout_rise * 0.7 * h])
    ctrl = np.array([tip[0] - 0.2 * p.spout_length, root[1]])
    s = np.linspace(0.0, 1.0, 16)[:, None]
    curve = (1 - s) ** 2 * root + 2 * s * (1 - s) * ctrl + s ** 2 * tip
    path = np.column_stack([curve[:, 0], np.zeros(16), curve[:, 1]])
    rad = p.spout_radius * np.linspace(1.0, 0.45, 16)
    spout = shapes.sweep(path, np.column_stack([rad, rad]), shapes.circle_outline(14))

    zc = p.belly_z * h + 0.1 * h
    zs = np.linspace(zc - p.handle_half_height, zc + p.handle_half_height, 20)
    thickness = 0.005
    x_left = float(_teapot_radius(p, zs).min()) - thickness - 0.003
    x_inner = float(_teapot_radius(p, np.array([zc]))[0]) + p.handle_hole
    handle, _, _ = _handle_loop(x_left, x_inner, zc, b=p.handle_half_height, exponent=2.6,
                                thickness=thickness, width=0.007)
    return body + spout + handle.mirror([1.0, 0.0, 0.0])
