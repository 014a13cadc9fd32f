"""Synthetic wraps with known geometry, for tests and benchmarks of chords and classifiers.

A wrap is the arm's centre line lying on an object's cross-section contour offset by the arm
radius, from a start point until its tangent has turned `turn` (the paper's theta = 270 deg),
with normals pointing at the object, placed in a 3-D plane. Contacts lie on the contour.
"""

from __future__ import annotations

import numpy as np

from drake_continuum.wrapping.contact import Contacts
from drake_continuum.wrapping.wrap_types import WrapResult

ARM_RADIUS = 0.01


def rounded_rectangle(a: float, b: float, corner: float, n: int = 400):
    """CCW points (n', 2) and outward unit normals of a rectangle with half sizes a, b and
    rounded corners of radius `corner` (a = b = corner: a circle). Straight edges are the gaps
    between the corner arcs; arc-length resampling fills them."""
    corner = min(corner, a, b)
    m = max(n // 4, 2)
    pts, nrm = [], []
    for q, (sx, sy) in enumerate([(1, 1), (-1, 1), (-1, -1), (1, -1)]):
        psi = np.linspace(q * np.pi / 2, (q + 1) * np.pi / 2, m)
        u = np.column_stack([np.cos(psi), np.sin(psi)])
        pts.append(np.array([sx * (a - corner), sy * (b - corner)]) + corner * u)
        nrm.append(u)
    return np.concatenate(pts), np.concatenate(nrm)


def ellipse(a: float, b: float, n: int = 400):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    p = np.column_stack([a * np.cos(t), b * np.sin(t)])
    nr = np.column_stack([np.cos(t) / a, np.sin(t) / b])
    return p, nr / np.linalg.norm(nr, axis=1)[:, None]


def _resample(points, values, spacing):
    s = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    keep = np.concatenate([[True], np.diff(s) > 1e-12])
    s, values = s[keep], values[keep]
    s_new = np.arange(0, s[-1], spacing)
    out = np.column_stack([np.interp(s_new, s, values[:, k]) for k in range(values.shape[1])])
    return s_new, out


def plane_rotation(axis: str, angle: float) -> np.ndarray:
    """Rotation of the table plane (x-y) about the world x or y axis by angle."""
    c, s = np.cos(angle), np.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def synthetic_wrap(contour, rotation=np.eye(3), origin=np.zeros(3), start: float = 0.0,
                   turn: float = 1.5 * np.pi, arm_radius: float = ARM_RADIUS,
                   spacing: float = 0.002, contact_spacing: float = 0.01,
                   plane_index: int = 0, time_s: float = 0.2, noise: float = 0.0,
                   rng=None) -> WrapResult:
    """A WrapResult around a closed contour (points, outward normals) in the plane whose
    x, y axes are rotation's first two columns; start is a fraction of the contour."""
    rng = np.random.default_rng(0) if rng is None else rng
    p2, n2 = contour
    n = len(p2)
    i0 = int(start * n) % n
    p2, n2 = np.roll(p2, -i0, axis=0), np.roll(n2, -i0, axis=0)
    p2, n2 = np.vstack([p2, p2, p2[:1]]), np.vstack([n2, n2, n2[:1]])  # two laps
    psi = np.unwrap(np.arctan2(n2[:, 1], n2[:, 0]))
    end = int(np.searchsorted(psi - psi[0], turn)) + 1
    q = p2[:end] + arm_radius * n2[:end]  # arm centre line
    s, vals = _resample(q, np.hstack([q, n2[:end], p2[:end]]), spacing)
    centre, out_n, surface = vals[:, :2], vals[:, 2:4], vals[:, 4:6]
    out_n /= np.linalg.norm(out_n, axis=1)[:, None]
    tangent = np.gradient(centre, s, axis=0)
    tangent /= np.linalg.norm(tangent, axis=1)[:, None]
    E = np.asarray(rotation, dtype=float)[:, :2]

    def to3(v, point=False):
        return (origin if point else 0) + v @ E.T

    pos = to3(centre, True) + noise * rng.standard_normal((len(s), 3))
    ci = np.arange(0, len(s), max(int(round(contact_spacing / spacing)), 1))
    cn, ct = to3(out_n[ci]), to3(tangent[ci])
    contacts = Contacts(p=to3(surface[ci], True) + noise * rng.standard_normal((len(ci), 3)),
                        n=cn, t=ct, b=np.cross(cn, ct), section=np.zeros(len(ci), int),
                        arc_length=s[ci], area=np.full(len(ci), 1e-5))
    return WrapResult(plane_index=plane_index, plane_normal=np.asarray(rotation)[:, 2],
                      base_rotation=np.asarray(rotation, dtype=float),
                      status="complete", configs=np.zeros((1, 9)), contacts=contacts,
                      samples_arc_length=s + 0.1, samples_position=pos,
                      samples_tangent=to3(tangent), samples_normal=to3(-out_n),
                      tip_rotation=turn, n_queries=100, time_s=time_s)


PLANES = [("x", a) for a in np.radians([0, 15, 30, 45, 60])] + \
         [("y", a) for a in np.radians([15, 30, 45, 60, 75])]


def object_wraps(contour, n_wraps: int = 10, rng=None, noise: float = 0.0):
    """n_wraps wraps of one contour in the paper-like planes, random start points."""
    rng = np.random.default_rng(0) if rng is None else rng
    return [synthetic_wrap(contour, plane_rotation(*PLANES[k % len(PLANES)]),
                           start=rng.random(), plane_index=k, noise=noise,
                           time_s=float(rng.uniform(0.1, 0.4)), rng=rng)
            for k in range(n_wraps)]


def shape_contour(kind: str, size: float, aspect: float = 1.0):
    """A category-like contour: 'circle' (radius), 'square' (side), 'ellipse' (semi-axis)."""
    if kind == "circle":
        return rounded_rectangle(size, size, size)
    if kind == "square":
        return rounded_rectangle(size / 2, size / 2 * aspect, 0.005)
    return ellipse(size, size * aspect)


def write_collection(folder, objects, params: dict | None = None, sides: dict | None = None
                     ) -> None:
    """A wrap collection on disk in collect.py's format: <id>.npz (every WrapResult via
    to_arrays(prefix=f"w{k}_")), <id>.json and index.json recording `params` as the
    collection's parameters (default: collection.run_params of the shipped configuration
    with the planes fixed to the robot and centred on the mark, the paper's setting);
    objects is [(id, category, wraps)]. A placed copy's (id with '@') json
    records its placement's side: sides[id], default "generated"; None: no placement
    recorded (as collected before 0.4.0)."""
    import json
    from pathlib import Path

    from drake_continuum.experiments.collection import run_params
    from drake_continuum.wrapping.wrap_types import WRAPS_FORMAT, WRAPS_FORMAT_VERSION

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for object_id, category, wraps in objects:
        arrays = {}
        for k, w in enumerate(wraps):
            arrays.update(w.to_arrays(prefix=f"w{k}_"))
        np.savez(folder / f"{object_id}.npz", **arrays)
        meta = {"format": WRAPS_FORMAT, "format_version": WRAPS_FORMAT_VERSION,
                "object_id": object_id, "category": category, "n_wraps": len(wraps),
                "wraps": [{"plane_index": w.plane_index, "status": w.status,
                           "time_s": w.time_s, "n_contacts": len(w.contacts)} for w in wraps]}
        side = (sides or {}).get(object_id, "generated")
        if "@" in object_id and side is not None:
            meta["placement"] = {"kind": object_id.split("@")[1].rstrip("0123456789"),
                                 "side": side}
        (folder / f"{object_id}.json").write_text(json.dumps(meta))
    (folder / "index.json").write_text(json.dumps(
        {"format": WRAPS_FORMAT, "format_version": WRAPS_FORMAT_VERSION,
         "objects": [{"object_id": o, "category": c} for o, c, _ in objects],
         "params": run_params(fixed_planes()) if params is None else params}))


def fixed_planes(**wrap):
    """The shipped configuration with the plane set fixed to the robot and centred on the
    mark (the paper's planes), its wrap section changed by `wrap`."""
    from dataclasses import replace

    from drake_continuum.config import load_config
    shipped = load_config()
    return replace(shipped, wrap=replace(shipped.wrap, **wrap),
                   planes=replace(shipped.planes, bearing="world", centre="mark"))


def separable_objects(n_per_class: int = 6, n_wraps: int = 4, seed: int = 0):
    """[(id, category, wraps)]: circles of radius 3 cm and squares of side 8 cm (+-5 %)."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n_per_class):
        for cat, kind, size in (("circle", "circle", 0.03), ("square", "square", 0.08)):
            contour = shape_contour(kind, size * rng.uniform(0.95, 1.05))
            out.append((f"{cat}_{i:02d}", cat, object_wraps(contour, n_wraps, rng)))
    return out
