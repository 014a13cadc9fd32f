"""Chord parameters against hand-computed values, the claimed invariances, and the sparse
histogram transformer's contract."""

import numpy as np
import pytest
import scipy.sparse as sp
from sklearn.base import clone
from sklearn.exceptions import NotFittedError
from sklearn.utils import estimator_checks

from drake_continuum.features.chords import (
    ChordHistogram,
    ChordParams,
    ChordSet,
    bin_centres,
    bin_index,
    chords_from_points,
    object_chords,
    plane_normals,
    resample_centre_line,
    turning_axis,
    wrap_chords,
)
from synthetic_wraps import ARM_RADIUS, object_wraps, shape_contour, synthetic_wrap


def _unit(theta, phi):
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                     np.cos(theta)], axis=-1)


def _directions(chords):
    """Length and the three unit vectors of each chord: angle-wrap-free comparison."""
    return np.hstack([chords[:, :1], _unit(chords[:, 1], chords[:, 2]),
                      _unit(chords[:, 3], chords[:, 4]), _unit(chords[:, 5], chords[:, 6])])


def _moved(wrap, R, t):
    """The same wrap rotated by R and translated by t."""
    from dataclasses import replace
    return replace(wrap, samples_position=wrap.samples_position @ R.T + t,
                   samples_tangent=wrap.samples_tangent @ R.T,
                   samples_normal=wrap.samples_normal @ R.T)


def _rotation(seed):
    q, r = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_hand_computed_chord():
    p = np.array([[0.0, 0.0, 0.0], [0.0, 0.03, 0.04]])
    n = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    (chord,) = chords_from_points(p, n)
    # l = |(0, 3, 4)| cm = 5 cm; c = (0, 0.6, 0.8): theta = acos(0.8), phi = 90 deg;
    # n0 = +x: theta = 90 deg, phi = 0; n1 = -z: theta = 180 deg, phi = atan2(0, 0) = 0.
    expected = [0.05, np.arccos(0.8), np.pi / 2, np.pi / 2, 0.0, np.pi, 0.0]
    np.testing.assert_allclose(chord, expected, atol=1e-12)


def test_chords_point_from_base_to_tip_and_short_ones_are_dropped():
    p = np.array([[0, 0, 0], [0.02, 0, 0], [0.0201, 0, 0]])
    n = np.tile([0.0, 1.0, 0.0], (3, 1))
    chords = chords_from_points(p, n, min_length=0.005)
    assert len(chords) == 2  # the 0.1 mm pair (1, 2) is dropped
    np.testing.assert_allclose(chords[:, 1:3], [[np.pi / 2, 0.0]] * 2)  # along +x


def test_circle_wrap_resampling_and_chord_count():
    w = synthetic_wrap(shape_contour("circle", 0.03))
    R = 0.03 + ARM_RADIUS
    span = w.samples_arc_length[-1] - w.samples_arc_length[0]
    pts, nrm = resample_centre_line(w.samples_arc_length, w.samples_position,
                                    w.samples_normal, spacing=0.01)
    n = int(np.floor(span / 0.01)) + 1
    assert len(pts) == n
    np.testing.assert_allclose(np.linalg.norm(pts, axis=1), R, rtol=2e-3)  # on the circle
    np.testing.assert_allclose(np.linalg.norm(nrm, axis=1), 1.0)
    np.testing.assert_allclose(np.einsum("ij,ij->i", nrm, -pts / R), 1.0, atol=1e-3)
    chords = wrap_chords(w)
    assert len(chords) == n * (n - 1) // 2
    # On a circle every chord makes equal angles with both end normals (symmetry).
    d = _directions(chords)
    np.testing.assert_allclose(np.einsum("ij,ij->i", d[:, 1:4], d[:, 4:7]),
                               -np.einsum("ij,ij->i", d[:, 1:4], d[:, 7:10]), atol=2e-3)


def test_world_frame_is_translation_invariant_not_rotation_invariant():
    world = ChordParams(frame="world")
    w = synthetic_wrap(shape_contour("square", 0.08), start=0.3)
    base = wrap_chords(w, world)
    np.testing.assert_allclose(wrap_chords(_moved(w, np.eye(3), [0.3, -0.2, 0.1]), world),
                               base, atol=1e-9)
    rotated = wrap_chords(_moved(w, _rotation(1), np.zeros(3)), world)
    assert not np.allclose(_directions(rotated), _directions(base), atol=1e-3)


def test_wrap_frame_is_rigid_motion_invariant():
    params = ChordParams(frame="wrap")
    w = synthetic_wrap(shape_contour("ellipse", 0.05, 0.6), start=0.2)
    base = _directions(wrap_chords(w, params))
    for seed in range(3):
        moved = _moved(w, _rotation(seed), np.random.default_rng(seed).normal(size=3))
        np.testing.assert_allclose(_directions(wrap_chords(moved, params)), base, atol=1e-9)


def test_wrap_frame_makes_a_circle_the_same_in_every_plane_and_start():
    params = ChordParams(frame="wrap")
    wraps = object_wraps(shape_contour("circle", 0.04), 4)
    d = [_directions(wrap_chords(w, params)) for w in wraps]
    for other in d[1:]:
        np.testing.assert_allclose(other, d[0], atol=2e-3)


def _spun_normals(w, seed):
    """The wrap with each sample's normal turned about its tangent by a random angle: a
    bending direction the centre line does not determine (a straight fitted section)."""
    from dataclasses import replace
    a = np.random.default_rng(seed).uniform(-np.pi, np.pi, len(w.samples_tangent))
    t, n = w.samples_tangent, w.samples_normal
    spun = np.cos(a)[:, None] * n + np.sin(a)[:, None] * np.cross(t, n)
    return replace(w, samples_normal=spun)


def test_plane_normals_of_a_planar_wrap_are_the_inward_normals():
    R = _rotation(4)
    w = synthetic_wrap(shape_contour("square", 0.08), rotation=R, start=0.3)
    # The square's sides are straight; the synthetic wrap's normals are its inward ones.
    axis = turning_axis(w.samples_tangent)
    np.testing.assert_allclose(abs(axis @ R[:, 2]), 1.0, atol=1e-9)  # the plane's normal
    n = plane_normals(w.samples_tangent, _spun_normals(w, 0).samples_normal)
    np.testing.assert_allclose(n @ axis, 0.0, atol=1e-9)  # in the plane
    np.testing.assert_allclose(np.einsum("ij,ij->i", n, w.samples_tangent), 0.0, atol=1e-9)
    # Within the synthetic wrap's own rounding at the corners (tangents by differences).
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n, w.samples_normal), -1, 1)))
    assert angle.max() < 4.0 and np.median(angle) < 1e-4


def test_plane_frame_ignores_the_bending_direction_the_world_frame_reads():
    w = synthetic_wrap(shape_contour("square", 0.08), start=0.3)
    spun = _spun_normals(w, 1)
    plane, world = ChordParams(frame="plane"), ChordParams(frame="world")
    np.testing.assert_allclose(wrap_chords(spun, plane), wrap_chords(w, plane), atol=1e-6)
    np.testing.assert_allclose(_directions(wrap_chords(w, plane)),
                               _directions(wrap_chords(w, world)), atol=0.07)
    assert not np.allclose(_directions(wrap_chords(spun, world)),
                           _directions(wrap_chords(w, world)), atol=1e-3)


def test_a_straight_line_keeps_its_normals():
    t = np.tile([1.0, 0.0, 0.0], (5, 1))
    n = np.tile([0.0, 0.0, 1.0], (5, 1))
    assert turning_axis(t) is None
    np.testing.assert_array_equal(plane_normals(t, n), n)


def _turn(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_upright_frame_ignores_turns_about_the_vertical_not_tilts():
    """A wrap in a tilted plane, turned about z by any angle and moved, has the same upright
    chords; its angles from the vertical are the world frame's; tilting it changes them."""
    params = ChordParams(frame="upright")
    tilt = _rotation(4)  # a plane neither vertical nor horizontal
    w = _moved(synthetic_wrap(shape_contour("ellipse", 0.05, 0.6), start=0.2), tilt,
               np.zeros(3))
    base = wrap_chords(w, params)
    world = wrap_chords(w, ChordParams(frame="world"))
    np.testing.assert_allclose(base[:, [0, 1, 3, 5]], world[:, [0, 1, 3, 5]], atol=1e-9)
    for a in (0.3, 1.7, -2.9):
        turned = _moved(w, _turn(a), [0.1, -0.2, 0.05])
        np.testing.assert_allclose(_directions(wrap_chords(turned, params)),
                                   _directions(base), atol=1e-9)
        assert not np.allclose(_directions(wrap_chords(turned, ChordParams(frame="world"))),
                               _directions(world), atol=1e-3)
    tilted = wrap_chords(_moved(w, _rotation(5), np.zeros(3)), params)
    assert not np.allclose(_directions(tilted), _directions(base), atol=1e-3)


def test_upright_frame_of_a_horizontal_wrap_uses_its_first_tangent():
    """In the horizontal plane (binormal vertical) the binormal has no azimuth: the first
    tangent's is used, so the wrap's chords are still the same at any turn."""
    params = ChordParams(frame="upright")
    w = synthetic_wrap(shape_contour("square", 0.08), start=0.3)  # in the xy plane
    b = np.cross(w.samples_tangent, w.samples_normal).mean(axis=0)
    assert abs(b[2]) > 0.99 * np.linalg.norm(b)
    base = _directions(wrap_chords(w, params))
    for a in (0.5, 2.0):
        np.testing.assert_allclose(_directions(wrap_chords(_moved(w, _turn(a), np.zeros(3)),
                                                           params)), base, atol=1e-9)


def test_object_chords_tag_their_wrap():
    wraps = object_wraps(shape_contour("circle", 0.03), 3)
    cs = object_chords(wraps)
    assert isinstance(cs, ChordSet) and cs.values.shape[1] == 7
    assert set(cs.wrap) == {0, 1, 2}
    assert len(cs.of_wraps([1])) == len(wrap_chords(wraps[1]))


def test_histogram_is_sparse_normalised_and_shaped():
    rng = np.random.default_rng(0)
    X = [rng.normal(size=(k, 7)) for k in (50, 200, 0, 10)]
    H = ChordHistogram().fit(X).transform(X)
    assert sp.issparse(H) and H.format == "csr"
    assert H.shape == (4, 7 ** 7)
    np.testing.assert_allclose(np.asarray(H.sum(axis=1)).ravel(), [1, 1, 0, 1])
    assert H.nnz <= 260


def test_histogram_edges_come_from_training_only():
    rng = np.random.default_rng(1)
    train = [rng.uniform(0, 1, size=(100, 7)) for _ in range(3)]
    test = [rng.uniform(5, 6, size=(30, 7))]  # far outside the training range
    h = ChordHistogram(bins=7).fit(train)
    edges = h.edges_.copy()
    H = h.transform(test)
    np.testing.assert_array_equal(h.edges_, edges)
    np.testing.assert_allclose(edges[:, [0, -1]], np.stack([np.min(np.vstack(train), 0),
                                                            np.max(np.vstack(train), 0)], 1))
    # Every test chord lies beyond the last edge: all land in the last cell.
    assert H.nnz == 1 and H.indices[0] == 7 ** 7 - 1 and H.data[0] == 1.0
    assert ChordHistogram().fit(test).transform(test).indices[0] != 7 ** 7 - 1


def test_given_edges_are_kept_and_bin_like_the_histogram_they_came_from():
    """Edges given (another histogram's, as the standing model takes the full model's) are
    used as they are: the same cells as the histogram they came from, whatever chords the
    second one is fitted on; a wrong shape or a non-increasing row is refused."""
    rng = np.random.default_rng(2)
    first = ChordHistogram(bins=5, edges="quantile").fit([rng.normal(size=(200, 7))])
    other = [rng.normal(3.0, 0.1, size=(50, 7))]  # would give very different quantiles
    given = ChordHistogram(bins=5, edges=first.edges_).fit(other)
    np.testing.assert_array_equal(given.edges_, first.edges_)
    test = [rng.normal(size=(40, 7))]
    assert (given.transform(test) != first.transform(test)).nnz == 0
    with pytest.raises(ValueError, match="shape"):
        ChordHistogram(bins=4, edges=first.edges_).fit(other)
    flat = first.edges_.copy()
    flat[2, 3] = flat[2, 2]
    with pytest.raises(ValueError, match="increasing"):
        ChordHistogram(bins=5, edges=flat).fit(other)


def test_bin_centres_are_in_their_bins():
    rng = np.random.default_rng(2)
    h = ChordHistogram().fit([rng.normal(size=(500, 7))])
    idx = h.bin_index(rng.normal(size=(300, 7)))
    np.testing.assert_array_equal(bin_index(bin_centres(idx, h.edges_), h.edges_), idx)


def test_histogram_of_three_dimensions_for_triangles():
    rng = np.random.default_rng(3)
    h = ChordHistogram(bins=10).fit([rng.random((40, 3))])
    assert h.transform([rng.random((5, 3))]).shape == (1, 1000)


def test_sklearn_contract():
    """check_estimator feeds 2-D numeric arrays of arbitrary width, but this transformer's X
    is a list of per-object chord arrays (a ragged collection), so the data checks cannot
    apply; the checks of the parameter contract do, and are run here."""
    est = ChordHistogram(bins=5)
    for check in (estimator_checks.check_no_attributes_set_in_init,
                  estimator_checks.check_parameters_default_constructible,
                  estimator_checks.check_get_params_invariance,
                  estimator_checks.check_set_params):
        check("ChordHistogram", est)
    with pytest.raises(NotFittedError):
        est.transform([np.zeros((1, 7))])
    X = [np.random.default_rng(0).random((10, 7))]
    assert est.fit(X) is est
    assert clone(est).get_params() == est.get_params()
    assert not hasattr(clone(est), "edges_")


def test_quantile_edges_split_training_chords_evenly_and_power_is_applied():
    from drake_continuum.features.chords import ChordHistogram
    rng = np.random.default_rng(0)
    # A skewed first dimension (lengths) and a uniform second one.
    X = [np.column_stack([rng.exponential(0.05, 700), rng.uniform(-1, 1, 700)])
         for _ in range(3)]
    h = ChordHistogram(bins=7, edges="quantile", power=0.5).fit(X)
    values = np.concatenate(X)
    for k in range(2):
        per_bin = np.histogram(values[:, k], bins=h.edges_[k])[0]
        assert per_bin.min() >= 0.9 * len(values) / 7 and per_bin.max() <= 1.1 * len(values) / 7
    # Uniform edges leave the skewed dimension's upper bins nearly empty.
    u = ChordHistogram(bins=7).fit(X)
    assert np.histogram(values[:, 0], bins=u.edges_[0])[0][-1] < 0.02 * len(values)
    H = h.transform(X[:1])
    plain = ChordHistogram(bins=7, edges="quantile").fit(X).transform(X[:1])
    np.testing.assert_allclose(H.toarray(), np.sqrt(plain.toarray()))
    np.testing.assert_allclose(plain.sum(), 1.0)


def test_quantile_edges_keep_off_a_tie_and_a_camera_tilt_keeps_its_chords_in_one_bin():
    from drake_continuum.features.chords import TIE_WIDTH, off_ties
    rng = np.random.default_rng(1)
    # Theta of 700 chords: 30 % exactly horizontal (pi / 2), the rest spread; a second
    # dimension without a tie.
    theta = np.r_[np.full(300, np.pi / 2), rng.uniform(0.1, 3.0, 700)]
    X = [np.column_stack([theta, rng.uniform(-1, 1, 1000)])]
    q = np.quantile(X[0], np.linspace(0, 1, 8), axis=0).T
    assert np.any(np.abs(q[0] - np.pi / 2) < 1e-12)  # equal-frequency edges land on it
    h = ChordHistogram(bins=7, edges="quantile").fit(X)
    assert np.all(np.abs(h.edges_[0] - np.pi / 2) >= TIE_WIDTH - 1e-12)
    np.testing.assert_array_equal(h.edges_[1], q[1])
    np.testing.assert_array_equal(off_ties(q, X[0])[1], q[1])
    # The horizontal chords tilted either way by less than the width share one cell.
    tilted = np.column_stack([np.pi / 2 + rng.uniform(-0.9, 0.9, 50) * TIE_WIDTH,
                              np.full(50, 0.3)])
    assert len(set(h.bin_index(tilted).tolist())) == 1


@pytest.mark.parametrize("width", [0.003, 0.0])
def test_the_classifiers_tie_width_reaches_the_histograms_edges(width):
    """classifier.tie_width, through make_pipeline, is the distance of the edges from the
    tie: tilts within it share a cell, and 0 leaves the equal-frequency edges on it."""
    from drake_continuum.config import load_config
    from drake_continuum.learning.pipeline import ObjectFeatures, make_pipeline
    params = load_config(overrides=[f"classifier.tie_width={width}"]).classifier
    features = make_pipeline(params=params).named_steps["histogram"]
    assert isinstance(features, ObjectFeatures) and features.tie_width == width
    rng = np.random.default_rng(1)
    # 15 % of the chords horizontal: one equal-frequency edge lands on them.
    theta = np.r_[np.full(150, np.pi / 2), rng.uniform(0.1, 3.0, 850)]
    X = [np.column_stack([theta, rng.uniform(-1, 1, 1000)])]
    q = np.quantile(X[0][:, 0], np.linspace(0, 1, 8))
    assert np.sum(np.abs(q - np.pi / 2) < 1e-12) == 1
    h = ChordHistogram(bins=7, edges="quantile", tie_width=features.tie_width).fit(X)
    gap = np.min(np.abs(h.edges_[0] - np.pi / 2))
    if width:
        assert gap >= 0.95 * width  # the tie is found to width / 10
        tilted = np.column_stack([np.pi / 2 + rng.uniform(-0.9, 0.9, 50) * width,
                                  np.full(50, 0.3)])
        assert len(set(h.bin_index(tilted).tolist())) == 1
    else:
        assert gap < 1e-12

def test_coarse_block_is_the_histogram_of_the_merged_edges():
    """The nested coarse block equals numpy's 7-D histogram with every third-or-so edge of
    the fine grid (fine bins 0-2, 3-4, 5-6 of 7 make the 3 coarse bins)."""
    from drake_continuum.features.chords import coarse_index
    rng = np.random.default_rng(3)
    train = [rng.normal(size=(rng.integers(200, 400), 7)) for _ in range(4)]
    h = ChordHistogram(bins=7, edges="quantile", coarse=3).fit(train)
    assert h.n_cells_ == 7 ** 7 + 3 ** 7
    # New objects strictly inside the training range (numpy counts a value on the last
    # edge in the last bin by a rounded comparison; the edges are training values).
    X = [np.clip(rng.normal(size=(300, 7)), h.edges_[:, 0] + 1e-9, h.edges_[:, -1] - 1e-9)
         for _ in range(3)]
    H = h.transform(X).toarray()
    fine = ChordHistogram(bins=7, edges="quantile").fit(train).transform(X).toarray()
    np.testing.assert_array_equal(H[:, :7 ** 7], fine)  # the fine block is unchanged
    for x, row in zip(X, H):
        counts, _ = np.histogramdd(x, bins=[e[[0, 3, 5, 7]] for e in h.edges_])
        np.testing.assert_allclose(row[7 ** 7:], counts.ravel() / len(x), atol=1e-15)
    np.testing.assert_array_equal(coarse_index(np.arange(7), 7, 1, coarse=3), [0, 0, 0, 1, 1, 2, 2])
    hp = ChordHistogram(bins=7, edges="quantile", coarse=3, power=0.5).fit(train)
    np.testing.assert_allclose(hp.transform(X).toarray(), np.sqrt(H))
    with pytest.raises(ValueError, match="coarse"):
        ChordHistogram(bins=3, coarse=4).fit(train)


def test_wrap_descriptors_of_a_circle():
    """Around a circle the centre line has curvature 1 / R everywhere, turns by its length
    over R, and its diameter is that of the circle (it turns 270 deg)."""
    from drake_continuum.features.chords import WRAP_DESCRIPTORS, wrap_descriptors
    w = synthetic_wrap(shape_contour("circle", 0.03))
    R = 0.03 + ARM_RADIUS
    d = dict(zip(WRAP_DESCRIPTORS, wrap_descriptors(w)))
    span = w.samples_arc_length[-1] - w.samples_arc_length[0]
    assert d["arc_length"] == pytest.approx(1.5 * np.pi * R, abs=0.002)  # 2 mm samples
    assert d["tip_rotation"] == pytest.approx(1.5 * np.pi)
    # Tangents of a 400-gon sampled every 2 mm: curvature to a few per cent.
    assert d["curvature_mean"] == pytest.approx(1 / R, rel=2e-2)
    assert d["curvature_max"] == pytest.approx(1 / R, rel=3e-2)
    assert d["curvature_std"] < 0.1 / R
    assert d["turning"] == pytest.approx(span / R, rel=2e-2)
    assert d["diameter"] == pytest.approx(2 * R, rel=1e-3)
    from dataclasses import replace
    empty = replace(w, samples_position=np.zeros((0, 3)), samples_tangent=np.zeros((0, 3)),
                    samples_normal=np.zeros((0, 3)), samples_arc_length=np.zeros(0))
    np.testing.assert_array_equal(wrap_descriptors(empty), np.zeros(7))


def test_chords_and_the_diameter_equal_their_formulas_written_out_to_the_bit():
    """chords_from_points (pairs of points shared by wraps of one length) and
    wrap_descriptors' diameter (summed without the (m, m, 3) array) against the formulas
    written out: np.triu_indices each time, np.sum((p_i - p_j) ** 2, axis=-1)."""
    from dataclasses import replace

    from drake_continuum.features.chords import chord_parameters, wrap_descriptors
    rng = np.random.default_rng(5)
    w = synthetic_wrap(shape_contour("circle", 0.03))
    for m in [*range(2, 160, 3), 57, 57]:
        p = rng.normal(size=(m, 3)) * 10.0 ** rng.uniform(-3, 1)
        n = rng.normal(size=(m, 3))
        n /= np.linalg.norm(n, axis=1)[:, None]
        i, j = np.triu_indices(m, k=1)
        direct = chord_parameters(p[i], n[i], p[j], n[j])
        assert chords_from_points(p, n, 0.005).tobytes() == \
            direct[direct[:, 0] >= 0.005].tobytes()
        moved = replace(w, samples_position=p, samples_tangent=n, samples_normal=n,
                        samples_arc_length=np.cumsum(rng.uniform(0.001, 0.01, m)))
        diameter = np.sqrt(np.max(np.sum((p[:, None] - p[None]) ** 2, axis=-1)))
        assert wrap_descriptors(moved)[6].tobytes() == diameter.tobytes()


def _off_ties_by_hand(edges, values, width):
    """off_ties as its docstring says, every edge against every value."""
    out = np.array(edges, dtype=float, copy=True)
    d, nb1 = out.shape
    for k in range(d):
        v = values[:, k]
        for j in range(1, nb1 - 1):
            near = v[np.abs(v - out[k, j]) < width]
            if len(near) * 2 * (nb1 - 1) <= len(v):
                continue
            cells, counts = np.unique(np.round(near / (width / 10)), return_counts=True)
            tie = cells[np.argmax(counts)] * width / 10
            out[k, j] = tie - width if out[k, j] <= tie else tie + width
        out[k, 1:-1] = np.clip(out[k, 1:-1], out[k, 0], out[k, -1])
        out[k] = np.maximum.accumulate(out[k])
    return out


@pytest.mark.parametrize("width", [0.003, 1e-3, 0.0, 0.5])
def test_off_ties_equals_every_edge_against_every_value(width):
    """off_ties looks only at the values near some edge (one search a dimension): the same
    edges as comparing every value with every edge, with ties on edges, edges close enough
    to share values, and values off by a few ulps."""
    from drake_continuum.features.chords import off_ties

    rng = np.random.default_rng(4)
    values = rng.uniform(0, 3, size=(4000, 4))
    values[:2200, 0] = np.pi / 2 + rng.normal(0, 2e-4, 2200)    # a tie under an edge
    values[:900, 1] = 1.0                                         # an exact tie
    values[900:1800, 1] = np.nextafter(1.0, 2.0)
    values[:, 3] = np.round(values[:, 3], 1)                      # many small ties
    steps = np.linspace(0, 1, 8)
    edges = np.quantile(values, steps, axis=0).T
    edges[2, 3] = edges[2, 2] + 1e-4                              # windows that overlap
    edges[2] = np.maximum.accumulate(edges[2])
    got = off_ties(edges, values, width)
    np.testing.assert_array_equal(got, _off_ties_by_hand(edges, values, width))
    if width == 0.003:
        assert not np.array_equal(got, edges)                     # some edge moved
