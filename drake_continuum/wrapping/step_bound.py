"""The fast enclosing's distance bound (`wrap._curve_until_contact`): before how many steps of
section i's curving no centre-line point of the section and beyond can touch the object.

A point with clearance g that moves at most m a step cannot touch within (g - margin) / m
steps, and the bound is the least of that over the points. Open3D's signed distance to the
real surface costs ~3 us a point, and few points can decide the least: a lower bound on each
point's distance from the object's convex hull (`SurfaceDistance.lower_bound`) shows the
others further, and Open3D is asked about the points it leaves, the likeliest first. The
answer is the one every point's distance gives (a test compares them).
"""

from __future__ import annotations

import numpy as np

__all__ = ["MARGIN", "StepBound"]

MARGIN = 1e-3  # m: hydroelastic onset lies within 0.15 mm of the exact tube
_PER = 24  # bound points a section
_FRACTIONS = np.linspace(0.0, 1.0, _PER)
_FIRST = 6  # points asked first besides those within the margin: the likeliest to bound


class StepBound:
    """One wrap's bound in its scene (with the table as an obstacle or not), keeping the hull
    plane that bounded each point last.

    Args:
        scene: the WrapScene, posed on the wrap's base.
        table: whether the table stops a section as the object does.
    """

    def __init__(self, scene, table: bool):
        self.scene, self.table = scene, table
        self._hint = np.full(scene.arm.n_sections * _PER, -1, np.int64)

    def __call__(self, pair, *, i: int, left: int):
        """For section i between `pair`, a configuration and the one a step on: (the steps
        before which no point of the section and beyond can touch, 1 to left; whether a point
        lies within the margin; the most steps a query may look ahead, a tube radius of the
        fastest point's motion)."""
        arm, (config, nxt) = self.scene.arm, pair
        _, pts = arm.batch_points(np.array([config.s, nxt.s]),
                                  np.array([config.kappa, nxt.kappa]),
                                  np.array([config.phi, nxt.phi]), _FRACTIONS)
        here, after = pts[0, i * _PER:], pts[1, i * _PER:]
        step = after - here
        motion = 1.5 * np.sqrt((step * step).sum(axis=1)) + 1e-12  # linalg.norm's sum
        gap = self.gaps(here, motion, left=left, hint=self._hint[i * _PER:])
        cap = int(_least(gap, motion, left))  # the floor of a positive least: whole steps
        return max(cap, 1), bool((gap <= MARGIN).any()), max(1, int(arm.radius / motion.max()))

    def gaps(self, here, motion, *, left: int, hint) -> np.ndarray:
        """Each point's clearance, exact (Open3D's) wherever it can decide the bound; a lower
        bound elsewhere, beyond the margin and no fewer steps away than the least found.

        Every point gets a bound; those within the margin and the _FIRST with the fewest
        steps are asked; the others whose bound, from every plane, is still fewer steps
        than the least found so far, are asked after."""
        scene, table, r = self.scene, self.table, self.scene.arm.radius
        gap = scene.distance_bound(here, np.full(len(here), r + MARGIN), hint=hint,
                                   table=table) - r
        steps = np.where(gap > MARGIN, (gap - MARGIN) / motion, -np.inf)
        order = np.argsort(steps, kind="stable")  # those within the margin first (-inf)
        open_ = int(np.count_nonzero(steps < left))  # the others take left steps or more
        split = min(int(np.count_nonzero(steps == -np.inf)) + _FIRST, open_)
        first, rest = order[:split], order[split:open_]
        gap[first] = scene.signed_distance(here[first], table=table) - r
        least = _least(gap[first], motion[first], left)
        if len(rest) and steps[rest[0]] < least:
            rest = rest[steps[rest] < least]
            h = hint[rest]
            gap[rest] = scene.distance_bound(here[rest], r + MARGIN + least * motion[rest],
                                             hint=h, table=table) - r
            hint[rest] = h
            ask = rest[(gap[rest] - MARGIN) / motion[rest] < least]
            if len(ask):
                gap[ask] = scene.signed_distance(here[ask], table=table) - r
        return gap


def _least(gap, motion, left: int) -> float:
    """The fewest steps (a float) any of these points beyond the margin may take, or left."""
    far = gap > MARGIN
    return min(float(left), float(((gap[far] - MARGIN) / motion[far]).min())) if far.any() \
        else float(left)
