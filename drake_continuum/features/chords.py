"""Chord features of wraps and their sparse histogram (the paper's section IV-B).

A wrap is described by chords between points on the arm's centre line (its medial axis)
where it wraps the object. Each chord is 7 numbers (l, c_theta, c_phi, n0_theta, n0_phi,
n1_theta, n1_phi): its length, its direction c and the normals n0, n1 at its two ends, each
direction as polar angles on the unit sphere (theta = angle from +z in [0, pi], phi = azimuth
in (-pi, pi]). End 0 is the point nearer the arm's base, so every chord has one orientation.

Normals. We use the arm's own bending direction (`WrapResult.samples_normal`: the frame x
axis, towards the centre of curvature, i.e. towards the object). It is defined at every
centre-line point, including where the arm bridges a concavity without touching, and it is
what the arm's shape alone tells us (a real arm knows its curvature, not the object's
surface). Contact normals (flipped, `-Contacts.n`) exist only at the contact patches and
carry the mesh's facet noise; `chords_from_points` accepts them if a caller prefers.

Frame. `frame="world"` (default, the paper's): angles in the fixed robot/world frame. The paper
trains and tests every object in one pose relative to the robot, so the direction of a wrap
plane is itself information (a bottle cut vertically differs from one cut horizontally).
Chords are translation invariant in any frame (differences and directions only).
`frame="wrap"` expresses each wrap in its own frame (z = the arm's mean binormal t x n, x =
the first sample's tangent projected off z): the chords then depend only on the arm's
shape, invariant to any rotation and translation of the wrap; that also forgets which way is
up (4 to 8 points lost; measured: BENCHMARKS.md, Decisions). `frame="upright"` is between
the two: each wrap is only turned about the world vertical, so that the horizontal part of
its mean binormal points along +x (the first tangent's horizontal direction for a wrap whose
binormal is near vertical). Angles from the vertical stay (a bottle standing is still told
from one lying, a cut across from one along), azimuths become relative to the wrap's own
plane: an object turned about the vertical and cut by another of the fixed planes gives the
chords the original gave in that plane. As generated it classifies as the world frame does
(92.2 against 92.3 %) and objects turned or on another side 1.5 to 2 points better on the
development seed (not on the unseen one), and active recognition loses by it (two splits
of seed 0: MCTS -4.3 and +1.1 points, greedy -10): the planes' observations become alike,
and telling them apart is what the next-wrap choice works with. So it is an option, not
the default (measured: BENCHMARKS.md, Decisions). `frame="plane"` keeps the world frame's
angles but takes each end's normal in the wrap's own plane (`plane_normals`: the turning axis
of the whole centre line x the tangent) instead of the bending direction: an arm fitted to a
point cloud does not determine the bending direction of a nearly straight section, and the
wrap's plane it does (camera-observed wraps, experiments/observed.py).

Filtering (Fig. 3: neither too few nor too many chords). Points are resampled at a uniform
arc-length `spacing` (default 1 cm): the arm cannot bend tighter than its curvature limit
(radius 2.5 cm), so between points 1 cm apart it deviates from a straight line by at most
s^2 / 8R = 0.5 mm and closer points would only add near-duplicate chords; a 20 cm wrap gives
21 points and 210 chords, ten wraps the paper's 1,500 to 3,000 chords an object. Chords
shorter than `min_length` (default 5 mm, half a tube radius) join points the arm brought
back next to each other; their direction is ill-defined and they are dropped.

The histogram (`ChordHistogram`) has `bins` bins a dimension (7 ** 7 = 823,543 cells for
chords) and is kept sparse: one scipy CSR row per object. With `coarse` = c it also holds a
coarser c ** 7 histogram whose cells are unions of the fine ones (fine bin i of a dimension
falls in coarse bin floor(i c / bins)): about 92 training objects occupy the fine 7-D grid
very sparsely, and the coarse grid lets objects whose chords fall in neighbouring fine cells
still share features. Being nested, it is a function of the fine cells alone, so anything
that keeps only fine cells (active recognition) computes it exactly.

Wrap descriptors (`wrap_descriptors`): seven numbers of each wrap's arm shape, what the
arm's own sensing gives besides its centre line's chords: the wrapped arc length (first
contact to tip), the tip's rotation, the mean, largest and spread of the centre line's
curvature, its total turning and its diameter (largest distance between two of its points).
A chord histogram normalised to sum 1 forgets how much of the arm wrapped the object and
mixes all planes; these keep both, plane by plane (the classifier puts them in one slot a
plane).

Contact extent (`contact_extent`): five numbers of the object's size as the arm touched it,
from the contact centres of all its wraps: their extent along x, y and z, the highest one
and the farthest one from the object's vertical axis. Every chord histogram above is
normalised and every descriptor is of one wrap, so neither states the object's overall
size, which is what tells a banana from a bowl or a toilet roll from a mug (banana 73 ->
100 %, +3 points overall; measured: BENCHMARKS.md, Classification).
"""

from __future__ import annotations

import functools
from dataclasses import asdict, dataclass
from enum import StrEnum

import numpy as np
import scipy.sparse as sp
from sklearn.base import BaseEstimator, TransformerMixin
from sklearn.utils.validation import check_is_fitted

from ..checks import STEP, between, check_fields
from .cells import contact_bounds, extent_of_bounds
from .chord_cells import bin_index, binned_cells, counted_cells, histograms_of_counts, remembering

__all__ = ["ChordFrame", "HistogramEdges", "EDGES",
           "CHORD_PARAMETERS", "WRAP_DESCRIPTORS", "CONTACT_EXTENT", "FRAMES", "UPRIGHT_MIN",
           "MIN_RANGE", "TIE_WIDTH", "ChordParams", "ChordSet", "polar_angles",
           "chord_parameters",
           "chords_from_points", "resample_centre_line", "wrap_frame", "upright_frame",
           "turning_axis", "plane_normals",
           "wrap_chords", "object_chords", "wrap_descriptors", "contact_extent", "bin_index",
           "off_ties", "bin_centres", "histogram_rows", "coarse_index", "histogram_features",
           "ChordHistogram"]

CHORD_PARAMETERS = ("l", "c_theta", "c_phi", "n0_theta", "n0_phi", "n1_theta", "n1_phi")
WRAP_DESCRIPTORS = ("arc_length", "tip_rotation", "curvature_mean", "curvature_max",
                    "curvature_std", "turning", "diameter")
CONTACT_EXTENT = ("extent_x", "extent_y", "extent_z", "top", "reach")


class ChordFrame(StrEnum):
    """The frame chords are taken in (ChordParams.frame; members equal the config's strings)."""

    WORLD = "world"
    WRAP = "wrap"
    UPRIGHT = "upright"
    PLANE = "plane"


class HistogramEdges(StrEnum):
    """How a ChordHistogram learns its bin edges (members equal the config's strings)."""

    UNIFORM = "uniform"
    QUANTILE = "quantile"


FRAMES = tuple(f.value for f in ChordFrame)
EDGES = tuple(e.value for e in HistogramEdges)
UPRIGHT_MIN = 0.2  # horizontal part of a unit binormal below which its azimuth is not used
MIN_RANGE = 1e-6  # m or rad: a histogram dimension narrower than this is taken as constant
TIE_WIDTH = 1e-3  # m or rad: quantile edges keep this far off a tie (off_ties)


@dataclass(frozen=True)
class ChordParams:
    """How chords are taken from a wrap (module docstring gives the reasons).

    Args:
        spacing: arc-length spacing of the centre-line points, m.
        min_length: chords shorter than this are dropped, m.
        frame: a ChordFrame's value: "world" (angles in the fixed robot frame, the
            paper's), "upright" (each wrap turned about the vertical onto its own plane: the
            same chords however the object is turned about the vertical), "wrap" (in each
            wrap's own frame: invariant to rotating and moving the wrap) or "plane" (the
            world frame's angles, each end's normal in the wrap's own plane: its turning
            axis x tangent, `plane_normals`, defined where the arm runs straight).
    """

    spacing: float = 0.01
    min_length: float = 0.005
    frame: ChordFrame = ChordFrame.WORLD

    def __post_init__(self):
        check_fields(self, spacing=STEP, min_length=between(0, 1, " m", open_low=False))

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "ChordParams":
        return cls(spacing=float(d["spacing"]), min_length=float(d["min_length"]),
                   frame=str(d["frame"]))


@dataclass(frozen=True)
class ChordSet:
    """Chords of one object (or one wrap).

    Args:
        values: (k, 7) chord parameters, columns CHORD_PARAMETERS (m, rad).
        wrap: (k,) index of the wrap each chord came from (its position in the object's
            list of wraps).
    """

    values: np.ndarray
    wrap: np.ndarray

    def __post_init__(self):
        values = np.asarray(self.values, dtype=float).reshape(-1, len(CHORD_PARAMETERS))
        wrap = np.asarray(self.wrap, dtype=np.int64).reshape(-1)
        if len(values) != len(wrap):
            raise ValueError(f"ChordSet: {len(values)} chords but {len(wrap)} wrap indices")
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "wrap", wrap)

    def __len__(self) -> int:
        return len(self.values)

    @classmethod
    def empty(cls) -> "ChordSet":
        return cls(np.zeros((0, len(CHORD_PARAMETERS))), np.zeros(0, np.int64))

    @classmethod
    def concatenate(cls, items) -> "ChordSet":
        items = list(items)
        if not items:
            return cls.empty()
        return cls(np.concatenate([c.values for c in items]),
                   np.concatenate([c.wrap for c in items]))

    def of_wraps(self, wraps) -> "ChordSet":
        """The chords of the given wrap indices (an accumulated observation)."""
        keep = np.isin(self.wrap, np.asarray(list(wraps), dtype=np.int64))
        return ChordSet(self.values[keep], self.wrap[keep])


def polar_angles(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta, phi) of unit vectors v (k, 3): theta from +z in [0, pi], phi in (-pi, pi]."""
    v = np.asarray(v, dtype=float)
    return np.arccos(np.clip(v[..., 2], -1.0, 1.0)), np.arctan2(v[..., 1], v[..., 0])


def chord_parameters(p0, n0, p1, n1) -> np.ndarray:
    """(k, 7) parameters of chords from p0 to p1 with unit normals n0, n1 (all (k, 3))."""
    d = np.asarray(p1, dtype=float) - np.asarray(p0, dtype=float)
    length = np.linalg.norm(d, axis=-1)
    c = d / np.maximum(length, np.finfo(float).tiny)[..., None]
    return np.column_stack([length, *polar_angles(c), *polar_angles(n0), *polar_angles(n1)])


def chords_from_points(points, normals, min_length: float = 0.005) -> np.ndarray:
    """(k, 7) chords of every pair i < j of ordered points (m, 3) with unit normals (m, 3).

    The order of the points (along the arm, base first) fixes each chord's direction.
    """
    points = np.asarray(points, dtype=float)
    normals = np.asarray(normals, dtype=float)
    i, j = _pairs(len(points))
    values = chord_parameters(points[i], normals[i], points[j], normals[j])
    return values[values[:, 0] >= min_length]


@functools.lru_cache(maxsize=256)
def _pairs(m: int) -> tuple[np.ndarray, np.ndarray]:
    """np.triu_indices(m, k=1), read-only: wraps of one length share them (tens of
    microseconds each to make, for each of a collection's thousands of wraps)."""
    pairs = np.triu_indices(m, k=1)
    for a in pairs:
        a.flags.writeable = False
    return pairs


def resample_centre_line(arc_length, position, normal, *, spacing: float):
    """Points and unit normals at uniform arc-length spacing, centred on the sampled span.

    Linear interpolation between the wrap's samples (which are much denser than `spacing`);
    the interpolated normals are renormalised.
    """
    s = np.asarray(arc_length, dtype=float)
    if len(s) < 2 or s[-1] - s[0] <= 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    span = s[-1] - s[0]
    n = int(np.floor(span / spacing + 1e-9)) + 1
    s_new = s[0] + (span - spacing * (n - 1)) / 2 + spacing * np.arange(n)
    k = np.clip(np.searchsorted(s, s_new, side="right") - 1, 0, len(s) - 2)
    w = ((s_new - s[k]) / np.maximum(s[k + 1] - s[k], np.finfo(float).tiny))[:, None]
    values = np.hstack([position, normal]).astype(float)
    out = (1 - w) * values[k] + w * values[k + 1]
    nrm = out[:, 3:] / np.maximum(np.linalg.norm(out[:, 3:], axis=1), 1e-12)[:, None]
    return out[:, :3], nrm


def wrap_frame(tangent, normal) -> np.ndarray:
    """(3, 3) rotation whose rows are the wrap frame's x, y, z axes in world coordinates.

    z = mean binormal t x n (the plane normal of a planar wrap, oriented by the bending
    direction), x = first tangent with its z component removed.
    """
    tangent = np.asarray(tangent, dtype=float)
    b = np.cross(tangent, np.asarray(normal, dtype=float)).mean(axis=0)
    z = b / np.linalg.norm(b)
    x = tangent[0] - (tangent[0] @ z) * z
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def upright_frame(tangent, normal) -> np.ndarray:
    """(3, 3) rotation about the world z axis (rows: the frame's axes in world coordinates)
    taking the horizontal part of the wrap's mean binormal t x n onto +x; when that part is
    shorter than UPRIGHT_MIN (a wrap in a near-horizontal plane), the first tangent's
    horizontal part instead. Identity if both are vertical."""
    tangent = np.asarray(tangent, dtype=float)
    b = np.cross(tangent, np.asarray(normal, dtype=float)).mean(axis=0)
    b /= max(np.linalg.norm(b), np.finfo(float).tiny)
    h = b[:2] if np.hypot(*b[:2]) >= UPRIGHT_MIN else tangent[0, :2]
    if np.hypot(*h) < 1e-9:
        return np.eye(3)
    c, s = h / np.hypot(*h)
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def turning_axis(tangent) -> np.ndarray | None:
    """(3,) unit axis the centre line turns about: the sum of t_i x t_(i+1) over
    consecutive unit tangents (m, 3), so each stretch counts by how much it turns and a
    straight one not at all; None when the line does not turn (under 1e-6 rad in all)."""
    t = np.asarray(tangent, dtype=float)
    axis = np.cross(t[:-1], t[1:]).sum(axis=0) if len(t) > 1 else np.zeros(3)
    size = np.linalg.norm(axis)
    return axis / size if size > 1e-6 else None


def plane_normals(tangent, normal, axis=None) -> np.ndarray:
    """(m, 3) unit normals of the centre line in the wrap's own plane: turning axis x
    tangent (towards the side the wrap turns to); where the tangent lies along that axis,
    and for a line that does not turn, the bending normals `normal` as they are. axis: the
    turning axis (None: turning_axis of these tangents, which must then run along the line).

    The bending normal (the frame's x axis) is the direction of the curvature vector, which
    vanishes where the arm runs straight: there it is set by the section's bending
    direction phi, which an arm fitted to a point cloud does not determine (a camera fit's
    normals on sections under 5 1/m were off by a median of 70 degrees). The wrap's turning
    axis is determined by the whole centre line, and for a wrap in a plane this normal equals
    the bending one wherever the arm curves towards the object."""
    t = np.asarray(tangent, dtype=float)
    out = np.array(normal, dtype=float, copy=True)
    axis = turning_axis(t) if axis is None else axis
    if axis is None:
        return out
    n = np.cross(axis, t)
    size = np.linalg.norm(n, axis=1)
    ok = size > 1e-6
    out[ok] = n[ok] / size[ok, None]
    return out


def wrap_chords(wrap, params: ChordParams = ChordParams()) -> np.ndarray:
    """(k, 7) chords of one WrapResult (none if it is not usable)."""
    if not wrap.usable:
        return np.zeros((0, len(CHORD_PARAMETERS)))
    normal = wrap.samples_normal
    if params.frame == ChordFrame.PLANE:
        normal = plane_normals(wrap.samples_tangent, normal)
    points, normals = resample_centre_line(wrap.samples_arc_length, wrap.samples_position,
                                           normal, spacing=params.spacing)
    if params.frame == ChordFrame.WRAP and len(points):
        R = wrap_frame(wrap.samples_tangent, wrap.samples_normal)
        points, normals = points @ R.T, normals @ R.T
    elif params.frame == ChordFrame.UPRIGHT and len(points):
        R = upright_frame(wrap.samples_tangent, wrap.samples_normal)
        points, normals = points @ R.T, normals @ R.T
    return chords_from_points(points, normals, params.min_length)


def object_chords(wraps, params: ChordParams = ChordParams()) -> ChordSet:
    """All chords of one object's wraps, each tagged with its wrap's index in `wraps`."""
    per_wrap = [wrap_chords(w, params) for w in wraps]
    if not per_wrap:
        return ChordSet.empty()
    return ChordSet(np.concatenate(per_wrap),
                    np.repeat(np.arange(len(per_wrap)), [len(c) for c in per_wrap]))


def wrap_descriptors(wrap) -> np.ndarray:
    """(7,) WRAP_DESCRIPTORS of one WrapResult (m, rad, 1/m, rad, m); zeros if not usable.

    Curvature is the turning angle between consecutive centre-line samples' tangents over
    their arc-length spacing; it needs three samples (zero with fewer).
    """
    out = np.zeros(len(WRAP_DESCRIPTORS))
    if not wrap.usable:
        return out
    s = np.asarray(wrap.samples_arc_length, dtype=float)
    t = np.asarray(wrap.samples_tangent, dtype=float)
    p = np.asarray(wrap.samples_position, dtype=float)
    out[0], out[1] = s[-1] - s[0], float(wrap.tip_rotation)
    if len(s) >= 3:
        angle = np.arccos(np.clip(np.sum(t[1:] * t[:-1], axis=1), -1.0, 1.0))
        kappa = angle / np.maximum(np.diff(s), np.finfo(float).tiny)
        out[2:6] = kappa.mean(), kappa.max(), kappa.std(), angle.sum()
    out[6] = np.sqrt(_max_squared_distance(p))
    return out


def _max_squared_distance(p: np.ndarray) -> float:
    """The largest squared distance between two of the points p (m, 3), each summed x, y, z
    in that order, as np.sum(d ** 2, axis=-1) sums it (the same bits: tests), without its
    (m, m, 3) array: a quarter of the time."""
    x, y, z = (p[:, k, None] - p[None, :, k] for k in range(3))
    return float(np.max((x * x + y * y) + z * z))


def contact_extent(points, turn_invariant: bool = False) -> np.ndarray:
    """(5,) CONTACT_EXTENT (m) of an object's contact centres (m, 3) in its standard pose
    (table at z = 0, the object's vertical axis on z); NaN (unknown) without contacts.

    Ranges and extremes rather than robust quantiles: an object has tens of contact
    centres, each the centre of a patch, so one of them is no outlier but the object's end.
    With turn_invariant the two horizontal ranges are taken along the contacts' own
    principal horizontal axes (longer first) instead of world x and y, so that turning the
    object about the vertical leaves them unchanged.
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    out = extent_of_bounds(contact_bounds(p)[None] if len(p) else np.zeros((0, 7)))
    if turn_invariant and len(p) > 1:
        xy = p[:, :2] - p[:, :2].mean(axis=0)
        _, _, axes = np.linalg.svd(xy, full_matrices=False)
        out[:2] = np.sort(np.ptp(xy @ axes.T, axis=0))[::-1]
    return out


def off_ties(edges, values, width: float = TIE_WIDTH) -> np.ndarray:
    """(d, bins + 1) `edges` with each interior edge that lands on a tie moved `width` off it.

    A tie is a value many chords share: a simulated wrap in a horizontal plane makes every
    chord and end normal horizontal (theta = pi/2), and equal-frequency edges fall on it; an
    arm fitted to a camera cloud tilts them by a milliradian or so, which would scatter them
    over both sides of the edge. An edge is on a tie when more than half a bin's values lie
    within `width` of it; the tie is their most common value (to width / 10), and the edge
    goes to tie - width or tie + width on its own side (an edge on the tie goes below it).
    values: (n, d) the chords the edges were learnt from."""
    out = np.array(edges, dtype=float, copy=True)
    d, nb1 = out.shape
    for k in range(d):
        v = values[:, k]
        close = _within_reach(v, out[k, 1:-1], width)  # one pass, not one an edge
        for j in range(1, nb1 - 1):
            near = close[np.abs(close - out[k, j]) < width]
            if len(near) * 2 * (nb1 - 1) <= len(v):
                continue
            cells, counts = np.unique(np.round(near / (width / 10)), return_counts=True)
            tie = cells[np.argmax(counts)] * width / 10
            out[k, j] = tie - width if out[k, j] <= tie else tie + width
        out[k, 1:-1] = np.clip(out[k, 1:-1], out[k, 0], out[k, -1])
        out[k] = np.maximum.accumulate(out[k])  # two edges on one tie: an empty bin
    return out


def _within_reach(v: np.ndarray, centres: np.ndarray, width: float) -> np.ndarray:
    """The values of v, in order, within 2 width (and a few ulps) of some centre: all those
    with |v - c| < width for any centre c, found in one search of the windows' bounds."""
    if not len(centres):
        return v[:0]
    reach = 2 * width + 4 * np.spacing(np.abs(centres))
    order = np.argsort(centres - reach)
    starts, ends = (centres - reach)[order], np.maximum.accumulate((centres + reach)[order])
    new = np.r_[True, starts[1:] > ends[:-1]]  # windows that overlap are joined
    bounds = np.column_stack([starts[new], np.r_[ends[:-1][new[1:]], ends[-1]]])
    inside = np.searchsorted(bounds.ravel(), v, side="right") % 2 == 1
    return v[inside]


def _as_array(x) -> np.ndarray:
    return x.values if isinstance(x, ChordSet) else np.asarray(x, dtype=float)


def bin_centres(flat_index: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(k, d) centres of the given flat histogram cells: the discretised chords."""
    d, nb1 = edges.shape
    idx = np.stack(np.unravel_index(np.asarray(flat_index, dtype=np.int64), (nb1 - 1,) * d),
                   axis=1)
    mid = (edges[:, 1:] + edges[:, :-1]) / 2
    return mid[np.arange(d), idx]


def histogram_rows(flat_indices, n_cells: int, normalize: bool = True) -> sp.csr_matrix:
    """CSR (n, n_cells): one row per array of flat cell indices, L1-normalised if asked."""
    counts = np.array([len(f) for f in flat_indices], dtype=np.int64)
    n = len(counts)
    if counts.sum() == 0:
        return sp.csr_matrix((n, n_cells))
    flat = np.concatenate([np.asarray(f, dtype=np.int64) for f in flat_indices])
    key = np.repeat(np.arange(n, dtype=np.int64), counts) * n_cells + flat
    uniq, c = np.unique(key, return_counts=True)
    rows, cols = np.divmod(uniq, n_cells)
    data = c / counts[rows] if normalize else c.astype(float)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))])
    return sp.csr_matrix((data, cols, indptr), shape=(n, n_cells))


def coarse_index(flat_index, bins: int, d: int, *, coarse: int) -> np.ndarray:
    """Flat cells of the nested coarse grid (coarse bins a dimension) holding the given flat
    cells of the fine grid (bins a dimension, d dimensions): fine bin i -> i coarse // bins."""
    idx = np.unravel_index(np.asarray(flat_index, dtype=np.int64), (bins,) * d)
    merge = np.arange(bins, dtype=np.int64) * coarse // bins
    return np.ravel_multi_index(tuple(merge[i] for i in idx), (coarse,) * d)


def histogram_features(flat_indices, bins: int, d: int, *, coarse: int = 0,
                       normalize: bool = True, power: float = 1.0) -> sp.csr_matrix:
    """CSR (n, bins ** d [+ coarse ** d]): the histogram of each array of fine flat cells,
    followed by that of the nested coarse grid if coarse > 0; each block normalised (if
    asked) and raised to `power` on its own. ChordHistogram and the exported model
    (classify.ChordModel) both build their features here."""
    blocks = [histogram_rows(flat_indices, bins ** d, normalize)]
    if coarse:
        cells = [coarse_index(f, bins, d, coarse=coarse) for f in flat_indices]
        blocks.append(histogram_rows(cells, coarse ** d, normalize))
    H = blocks[0] if len(blocks) == 1 else sp.hstack(blocks, format="csr")
    return H.power(power) if power != 1.0 else H


class ChordHistogram(TransformerMixin, BaseEstimator):
    """Sparse d-dimensional histogram of per-object feature rows (chords: d = 7).

    Input X is a list with one (k_i, d) array (or ChordSet) per object; the output is a
    scipy CSR matrix (n_objects, bins ** d). Bin edges are learned from the training data
    (`fit`) only: "uniform" between each dimension's minimum and maximum, or "quantile"
    (equal-frequency: each dimension's training chords split evenly over its bins, so that
    no bin of a skewed dimension such as chord length sits empty while another holds most
    chords; an edge that lands on a tie, such as the horizontal chords' theta = pi/2, is
    moved `tie_width` off it, `off_ties`: seen through a camera, such a chord keeps its value
    to a milliradian or a few); later data outside them is clipped into the end bins. Each row is
    normalised to sum 1, so objects with more wraps or chords compare on equal footing, and
    then raised to `power` (0.5 is the Hellinger map: a linear classifier on square-rooted
    histograms compares them by the Bhattacharyya coefficient, which suits histograms better
    than the Euclidean distance). An object without chords is a zero row. The triangle
    baseline uses this class with d = 3, uniform edges and power 1, as [1] did. With coarse
    = c > 0 the row continues with the nested c ** d histogram (module docstring;
    `histogram_features`), normalised and powered on its own.

    Args:
        bins: bins a dimension (the paper's 7).
        normalize: divide each row by its number of chords.
        edges: a HistogramEdges value ("uniform" or "quantile"), or a (d, bins + 1) array
            of edges given (another histogram's edges_, kept as they are: two classifiers
            that must bin chords alike, pipeline.SideMixture).
        power: exponent applied to the normalised histogram (1: none).
        coarse: bins a dimension of the nested coarse histogram appended (0: none; at
            most bins).
        tie_width: how far quantile edges keep off a tie (`off_ties`), m or rad: the tilt
            the wraps to be classified may have off a simulated wrap's exact plane.
    """

    def __init__(self, bins: int = 7, normalize: bool = True,
                 edges: str = HistogramEdges.UNIFORM.value, *,
                 power: float = 1.0, coarse: int = 0, tie_width: float = TIE_WIDTH):
        self.bins = bins
        self.normalize = normalize
        self.edges = edges
        self.power = power
        self.coarse = coarse
        self.tie_width = tie_width

    def fit(self, X, y=None):
        values = np.concatenate([_as_array(x) for x in X]) if len(X) else np.zeros((0, 0))
        if values.ndim != 2 or len(values) == 0:
            raise ValueError("ChordHistogram.fit: need at least one chord (rows of a 2-D array)")
        if int(self.bins) < 1:
            raise ValueError(f"ChordHistogram: bins must be >= 1, got {self.bins}")
        if not 0 <= int(self.coarse) <= int(self.bins):
            raise ValueError(f"ChordHistogram: coarse must be in [0, bins = {self.bins}], "
                             f"got {self.coarse}")
        if not isinstance(self.edges, str):
            given = np.asarray(self.edges, dtype=float)
            if given.shape != (values.shape[1], int(self.bins) + 1) \
                    or not np.all(np.diff(given, axis=1) > 0):
                raise ValueError(f"ChordHistogram: given edges must be increasing, of shape "
                                 f"({values.shape[1]}, {int(self.bins) + 1}); got shape "
                                 f"{given.shape}")
            self.edges_ = given.copy()
            return self._fitted(values)
        lo, hi = values.min(axis=0), values.max(axis=0)
        # A dimension spread less than MIN_RANGE is constant up to rounding (theta of every
        # chord of planar wraps in the wrap frame): centre a MIN_RANGE-wide range on it, so
        # that rounding noise does not scatter its chords over all its bins.
        mid, narrow = (lo + hi) / 2, hi - lo < MIN_RANGE
        lo = np.where(narrow, mid - MIN_RANGE / 2, lo)
        hi = np.where(narrow, mid + MIN_RANGE / 2, hi)
        if self.edges not in EDGES:
            raise ValueError(f"ChordHistogram: edges must be 'uniform' or 'quantile', "
                             f"got {self.edges!r}")
        steps = np.linspace(0, 1, int(self.bins) + 1)
        self.edges_ = lo[:, None] + (hi - lo)[:, None] * steps
        if self.edges == HistogramEdges.QUANTILE:
            q = np.quantile(np.ascontiguousarray(values.T), steps, axis=1).T  # row-wise: faster
            q[:, 0], q[:, -1] = self.edges_[:, 0], self.edges_[:, -1]
            # A dimension with repeated values (ties) would get empty zero-width bins:
            # it keeps uniform edges.
            distinct = np.all(np.diff(q, axis=1) > 1e-9, axis=1) & ~narrow
            self.edges_ = np.where(distinct[:, None],
                                   off_ties(q, values, float(self.tie_width)), self.edges_)
        return self._fitted(values)

    def _fitted(self, values):
        self.n_dims_ = values.shape[1]
        self.n_cells_ = int(self.bins) ** self.n_dims_ + (int(self.coarse) ** self.n_dims_
                                                          if int(self.coarse) else 0)
        return self

    def bin_index(self, values) -> np.ndarray:
        """(k,) flat cell index of each chord (k, d)."""
        check_is_fitted(self)
        return bin_index(_as_array(values), self.edges_)

    def transform(self, X) -> sp.csr_matrix:
        check_is_fitted(self)
        arrays = [_as_array(x) for x in X]
        for a in arrays:
            if a.ndim != 2 or (len(a) and a.shape[1] != self.n_dims_):
                raise ValueError(f"ChordHistogram.transform: expected (k, {self.n_dims_}) "
                                 f"arrays, got shape {a.shape}")
        if not int(self.coarse) and remembering():  # each object's counts, kept a split
            counted = counted_cells(arrays, self.edges_)
            H = histograms_of_counts(counted, self.n_cells_, self.normalize)
            return H.power(self.power) if self.power != 1.0 else H
        flat = binned_cells(arrays, self.edges_)  # once a split in an evaluation
        return histogram_features(flat, int(self.bins), self.n_dims_, coarse=int(self.coarse),
                                  normalize=self.normalize, power=self.power)

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.input_tags.two_d_array = False  # X is a list of per-object arrays
        tags.input_tags.sparse = False
        tags.requires_fit = True
        return tags
