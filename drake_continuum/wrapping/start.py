"""Where a wrap starts: the base's rotation into the plane, the base backed off a long
object that reaches into its clearance, and the straight start configuration passing the
object at the start clearance."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from ..errors import ConfigError
from ..kinematics.arm import ArmConfig
from .planes import BaseClearanceError, WrapPlane, base_rotation, cross_section, start_direction
from .scene import WrapScene

__all__ = ["BACKOFF_MARGIN", "base_backoff", "start_configuration", "start_lengths"]

# m, beyond the start clearance, that a base backed off (base_backoff) leaves the object.
BACKOFF_MARGIN = 0.005


def base_backoff(cut: np.ndarray, clearance: float, margin: float = BACKOFF_MARGIN) -> float:
    """How far (m) the base backs off along its approach in the plane (-e1): the least move
    from which on every point of the cut (k, 2, about the base; its segments' end points)
    clears the base by `clearance` + `margin`, which leaves the whole cut ahead of the base;
    0 when every point is already beyond `clearance` (then nothing moves, and the wraps are
    those of a fixed base).

    A long object lying with an end towards the robot reaches into the base's clearance in
    some planes; a robot backs its base off there rather than give up the plane. The plane
    and its cut stay the same; only the start point recedes."""
    if not np.any(np.linalg.norm(cut, axis=1) <= clearance):
        return 0.0
    c2 = (clearance + margin) ** 2
    x, r2 = cut[:, 0], (cut ** 2).sum(axis=1)
    disc = x ** 2 - r2 + c2  # |p + t e1|^2 >= c^2: t >= -x + sqrt(disc) where disc > 0
    need = np.where(disc > 0, -x + np.sqrt(np.maximum(disc, 0.0)), 0.0)
    return float(max(need.max(), 0.0))


def start_lengths(params, n_sections: int) -> np.ndarray:
    """Sections 2..n's lengths at the start from wrap.start_lengths: one value for each, or
    one for all; another count is refused, since repeating the list round an arm of other
    sections would give lengths the user never wrote."""
    given = np.asarray(params.start_lengths, dtype=float)
    if len(given) not in (1, n_sections - 1):
        raise ConfigError(
            f"wrap.start_lengths: the arm has {n_sections} sections, so give "
            f"{n_sections - 1} lengths (sections 2 to {n_sections}) or one for all; got "
            f"{len(given)} ({', '.join(f'{v:g}' for v in given)})")
    return np.resize(given, n_sections - 1)


def start_configuration(scene: WrapScene, plane: WrapPlane, params):
    """The base rotation, straight start configuration and base position for a plane
    (with `params` a WrapParams: its start_clearance, start_lengths, start_fit and theta)
    (the arm's own, or backed off along the plane by base_backoff), or None if the plane
    misses the object. BaseClearanceError if backing off would take the base below the
    table."""
    arm = scene.arm
    cut = cross_section(scene.object_trimesh, plane)
    if len(cut) == 0:
        return None
    # The tube is 2 radii thick across the plane: pass everything it could touch.
    slab = [cut if offset == 0.0 else cross_section(scene.object_trimesh, plane, offset)
            for offset in np.linspace(-arm.radius, arm.radius, 5)]  # the plane's own: cut
    cut = np.concatenate(slab)
    clearance = arm.radius + params.start_clearance
    back = base_backoff(cut, clearance)
    position = np.asarray(arm.base_position, dtype=float)
    if back > 0.0:
        cut = cut + [back, 0.0]
        position = position - back * plane.basis()[0]
        if position[2] < arm.radius:  # the table top is z = 0
            raise BaseClearanceError(
                f"the object's cut comes within the clearance of the arm base, and backing "
                f"the base off {back * 1000:.0f} mm along this plane would take it below "
                f"the table")
    ray, tangent_distance = start_direction(cut, plane, clearance)
    R = base_rotation(plane, ray)
    lo, hi = arm.section_limits()[:2]
    s1 = float(np.clip(tangent_distance, lo[0], hi[0]))
    if params.start_fit:
        # The tube's centre line goes round the cut at one radius out; 2-D hull's "area" is
        # its perimeter.
        radius = ConvexHull(cut).area / (2 * np.pi) + arm.radius
        rest = np.full(arm.n_sections - 1, params.theta * radius / (arm.n_sections - 1))
    else:
        rest = start_lengths(params, arm.n_sections)
    rest = np.clip(rest, lo[1:], hi[1:])
    return R, ArmConfig.straight(np.concatenate([[s1], rest])), position
