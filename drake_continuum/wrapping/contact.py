"""Contacts between the arm and an object: positions and frames, one row a contact, and how
Drake's contact surfaces become them (contact_regions)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Contacts", "FIELDS", "REGION_TURN_MAX", "contact_regions"]

REGION_TURN_MAX = np.radians(30.0)  # a contact region's normal turns at most this much


@dataclass(frozen=True)
class Contacts:
    """A set of m contact regions {p, n, t, b} (the paper's section III).

    Args:
        p: (m, 3) contact centres (area-weighted centroid of a contact polygon), m.
        n: (m, 3) unit normals, pointing from the object into the arm.
        t: (m, 3) unit tangents: the arm's axis with its normal component removed.
        b: (m, 3) unit binormals, n x t.
        section: (m,) index (0-based) of the arm section in contact.
        arc_length: (m,) arc length along the arm of the contact, m.
        area: (m,) contact polygon area, m^2 (how deep the touch is).
    """

    p: np.ndarray
    n: np.ndarray
    t: np.ndarray
    b: np.ndarray
    section: np.ndarray
    arc_length: np.ndarray
    area: np.ndarray

    @classmethod
    def empty(cls) -> "Contacts":
        z3 = np.zeros((0, 3))
        return cls(z3, z3, z3, z3, np.zeros(0, int), np.zeros(0), np.zeros(0))

    def __len__(self) -> int:
        return len(self.p)

    @classmethod
    def concatenate(cls, items) -> "Contacts":
        items = [c for c in items if len(c)]
        if not items:
            return cls.empty()
        return cls(*(np.concatenate([getattr(c, f) for c in items]) for f in FIELDS))

    def to_arrays(self, prefix: str = "") -> dict:
        return {prefix + f: getattr(self, f) for f in FIELDS}

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "") -> "Contacts":
        return cls(*(np.asarray(arrays[prefix + f]) for f in FIELDS))


FIELDS = ("p", "n", "t", "b", "section", "arc_length", "area")


def contact_regions(surfaces, object_geometry, capsule_of, *, config,
                    arcs: np.ndarray, frames, k: int, kept: dict | None = None) -> Contacts:
    """The contact regions {p, n, t, b} of Drake contact surfaces (`WrapScene.contacts`).

    Args:
        surfaces: Drake ContactSurfaces, each pairing one capsule with the object or the
            table (those with the table are left out).
        object_geometry: the object's GeometryId.
        capsule_of: the capsule index of a surface.
        config, arcs, frames: the arm's configuration, its capsules' centre arc lengths and
            (positions, tangents, normals) there, (n_links,) and (n_links, 3) each.
        k: capsules a section.
        kept: each surface's summary (`_summary`) by surface, kept by the caller between
            calls: a capsule that has not moved keeps its surfaces, and reading one costs
            two Python calls a face.
    """
    summaries = []
    for s in surfaces:
        if object_geometry not in (s.id_M(), s.id_N()):
            continue
        if kept is None:
            summaries.append(_summary(s, object_geometry, capsule_of))
        elif (summary := kept.get(s)) is not None:
            summaries.append(summary)
        else:
            summaries.append(kept.setdefault(s, _summary(s, object_geometry, capsule_of)))
    if not summaries:
        return Contacts.empty()
    links, centroids, normals, areas = zip(*summaries)
    order = np.argsort(links)
    links = np.asarray(links)[order]
    centroids, normals = np.asarray(centroids)[order], np.asarray(normals)[order]
    areas = np.asarray(areas)[order]
    # A new region starts at a gap in the run, and where the run has turned by more than
    # REGION_TURN_MAX since the region began: the centroid and mean normal of a run hugging
    # a curved body (a 270 deg wrap) would lie inside the object and point nowhere in
    # particular.
    unit = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    turn = np.arccos(np.clip(np.einsum("mi,mi->m", unit[1:], unit[:-1]), -1.0, 1.0))
    bucket = np.floor(np.concatenate([[0.0], np.cumsum(turn)]) / REGION_TURN_MAX)
    region = np.concatenate([[0], np.cumsum((np.diff(links) > 1) | (np.diff(bucket) > 0))])
    m = region[-1] + 1
    area = np.bincount(region, weights=areas, minlength=m)
    p = np.stack([np.bincount(region, weights=areas * centroids[:, i], minlength=m)
                  for i in range(3)], axis=1) / area[:, None]
    n = np.stack([np.bincount(region, weights=normals[:, i], minlength=m)
                  for i in range(3)], axis=1)
    keep = (area > 0) & (np.linalg.norm(n, axis=1) > 0)
    p, n, area = p[keep], n[keep], area[keep]
    if not len(p):
        return Contacts.empty()
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    j = _nearest_link(frames[0], p, links[np.searchsorted(region, np.flatnonzero(keep))],
                      last=links[np.searchsorted(region, np.flatnonzero(keep), "right") - 1])
    section, arc, tangent = _nearest_on_arc(config, arcs, frames, k=k, p=p, j=j)
    t = tangent - np.einsum("mi,mi->m", tangent, n)[:, None] * n
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    b = np.stack([n[:, 1] * t[:, 2] - n[:, 2] * t[:, 1], n[:, 2] * t[:, 0] - n[:, 0] * t[:, 2],
                  n[:, 0] * t[:, 1] - n[:, 1] * t[:, 0]], axis=1)  # n x t, as numpy.cross
    return Contacts(p, n, t, b, section, arc, area)


def _summary(s, object_geometry, capsule_of) -> tuple:
    """(capsule, centroid, area-weighted normal out of the object, area) of one contact
    surface with the object."""
    mesh = s.poly_mesh_W()
    faces = range(mesh.num_faces())
    a = np.fromiter(map(mesh.area, faces), float, len(faces))
    fn = np.array(list(map(mesh.face_normal, faces)))
    sign = 1.0 if s.id_N() == object_geometry else -1.0
    return (capsule_of(s), np.asarray(mesh.centroid()), sign * (a[:, None] * fn).sum(0),
            a.sum())


def _nearest_link(centres, p, first, *, last) -> np.ndarray:
    """Index of the link, among first..last of each row, whose centre is nearest p."""
    k = np.arange(len(centres))
    d = np.linalg.norm(centres[None] - p[:, None], axis=2)
    d[(k[None] < first[:, None]) | (k[None] > last[:, None])] = np.inf
    return d.argmin(axis=1)


def _nearest_on_arc(config, arcs, frames, *, k: int, p, j):
    """Section, arc length and unit tangent of the centre-line point nearest each p, found in
    closed form on the circle of the section of link j (exact while the nearest point lies
    on that section; clipped to it otherwise)."""
    centre, t0, n0 = (a[j] for a in frames)
    section = j // k
    kappa = config.kappa[section]
    d = p - centre
    dt, dn = np.einsum("mi,mi->m", d, t0), np.einsum("mi,mi->m", d, n0)
    curved = kappa > 1e-9
    k_safe = np.where(curved, kappa, 1.0)
    # On the circle about centre + n0 / kappa, the point at arc offset u lies in the
    # direction sin(kappa u) t0 - cos(kappa u) n0 from the circle's centre.
    u = np.where(curved, np.arctan2(dt * k_safe, 1.0 - dn * k_safe) / k_safe, dt)
    starts = np.concatenate([[0.0], np.cumsum(config.s)])
    arc = np.clip(arcs[j] + u, starts[section], starts[section + 1])
    angle = kappa * (arc - arcs[j])
    tangent = np.cos(angle)[:, None] * t0 + np.sin(angle)[:, None] * n0
    return section, arc, tangent
