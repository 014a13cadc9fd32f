"""The classifier on data whose answer is known, the portable model format, wrap loading,
the triangle baseline and the CLI commands."""

import json
import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from sklearn.decomposition import PCA

from drake_continuum import cli
from drake_continuum.features.cells import CellCounts
from drake_continuum.features.chords import ChordHistogram, ChordParams
from drake_continuum.features.triangles import sample_triangles, triangle_parameters
from drake_continuum.learning.evaluation import (
    evaluate,
    plot_confusion,
    splits,
    table1,
    write_table1,
)
from drake_continuum.learning.model import (
    FORMAT_VERSION,
    ChordModel,
    ModelFormatError,
    classify_wraps,
    load_model,
    save_model,
    train,
)
from drake_continuum.learning.pipeline import (
    REST_CLASS,
    ClassifierParams,
    GramPCA,
    ObjectFeatures,
    OccupiedColumns,
    SideMixture,
    fit_pipeline,
    make_pipeline,
    rest_class,
    training_labels,
)
from drake_continuum.learning.records import WrapDataWarning, load_wraps, object_record
from synthetic_wraps import (
    fixed_planes,
    object_wraps,
    separable_objects,
    shape_contour,
    write_collection,
)


@pytest.fixture(scope="module")
def separable():
    return [object_record(i, c, w) for i, c, w in separable_objects(8, 3)]


@pytest.fixture(scope="module")
def three_classes():
    rng = np.random.default_rng(5)
    out = []
    for i in range(5):
        for cat, kind, size, aspect in (("circle", "circle", 0.03, 1), ("square", "square",
                                        0.08, 1), ("ellipse", "ellipse", 0.06, 0.5)):
            contour = shape_contour(kind, size * rng.uniform(0.9, 1.1), aspect)
            out.append(object_record(f"{cat}{i}", cat, object_wraps(contour, 3, rng)))
    return out


def test_separable_wraps_are_classified_perfectly(separable):
    ev = evaluate(separable, n_splits=10, seed=0)
    assert ev.accuracy_mean == 1.0
    assert ev.per_class == {"circle": 1.0, "square": 1.0}
    assert ev.confusion.sum() == 10 * 8 and np.trace(ev.confusion) == 80


def test_uninformative_wraps_are_at_chance():
    """Every object is a circle of random radius with a random one of 4 labels."""
    rng = np.random.default_rng(7)
    objects = [object_record(f"o{i}", "abcd"[i % 4],
                             object_wraps(shape_contour("circle", rng.uniform(0.03, 0.06)), 3,
                                          rng)) for i in range(40)]
    ev = evaluate(objects, n_splits=20, seed=0)
    assert abs(ev.accuracy_mean - 0.25) < 0.12


def test_per_object_predictions_agree_with_the_confusion_matrix():
    """Two tallies of the same predictions: summing each object's predicted classes over the
    objects of a category gives the confusion matrix's row; each object is tested as often
    as it fell in a test half; misclassified() lists exactly the objects ever wrong, most
    often wrong first."""
    rng = np.random.default_rng(11)
    objects = [object_record(f"o{i}", "abc"[i % 3],
                             object_wraps(shape_contour("circle", rng.uniform(0.03, 0.06)), 3,
                                          rng)) for i in range(18)]
    ev = evaluate(objects, n_splits=12, seed=0)
    y = np.array([o.category for o in objects])
    for k, c in enumerate(ev.classes):
        np.testing.assert_array_equal(ev.predicted[y == c].sum(axis=0), ev.confusion[k])
    tested = np.zeros(len(objects), int)
    for _, test in splits(y, n_splits=12, seed=0):
        tested[test] += 1
    np.testing.assert_array_equal(ev.predicted.sum(axis=1), tested)
    wrong = ev.misclassified()
    own = np.array([ev.classes.index(c) for c in y])
    n_wrong = tested - ev.predicted[np.arange(len(y)), own]
    assert {r["object_id"] for r in wrong} == {f"o{i}" for i in np.flatnonzero(n_wrong)}
    rates = [r["wrong"] / r["tested"] for r in wrong]
    assert rates == sorted(rates, reverse=True) and len(wrong) > 0
    for r in wrong:
        assert sum(r["as"].values()) == r["wrong"] and r["category"] not in r["as"]


def test_triangle_baseline_on_the_same_splits(separable):
    y = [o.category for o in separable]
    a, b = splits(y, n_splits=5, seed=3), splits(y, n_splits=5, seed=3)
    assert all(np.array_equal(p[0], q[0]) and np.array_equal(p[1], q[1]) for p, q in zip(a, b))
    ev = evaluate(separable, n_splits=5, seed=3, method="triangles")
    assert ev.accuracy_mean >= 0.9


@pytest.mark.parametrize("n_splits", [0, -3, 2.5])
def test_an_evaluation_of_no_split_is_refused(separable, n_splits):
    """No split has no accuracy: refused, where it gave a mean of NaN over nothing."""
    from drake_continuum.errors import InputError
    with pytest.raises(InputError, match=f"n_splits must be a whole number of at least 1, "
                                         f"got {n_splits}"):
        evaluate(separable, n_splits=n_splits, progress=False)


def test_too_few_objects_to_train_are_named_as_plain_counts(separable):
    from drake_continuum.errors import InputError
    boxes = [o for o in separable if o.category == separable[0].category][:2]
    with pytest.raises(InputError) as e:
        train(boxes)
    assert str(e.value).endswith(f"got counts {{'{boxes[0].category}': 2}}")


def test_triangle_parameters_hand_computed():
    a, b, c = np.array([[0.0, 0, 0]]), np.array([[0.03, 0, 0]]), np.array([[0, 0.04, 0]])
    np.testing.assert_allclose(triangle_parameters(a, b, c), [[0.05, 0.04, np.pi / 2]])
    line = np.array([[0.0, 0, 0], [0.01, 0, 0], [0.02, 0.0001, 0]])  # 179.4 deg: rejected
    assert len(sample_triangles(line)) == 0
    pts = np.random.default_rng(0).random((30, 3))
    assert len(sample_triangles(pts, 100, np.random.default_rng(1))) == 100
    assert len(sample_triangles(pts[:8], 100)) == 56  # all C(8, 3) triples


def test_gram_pca_on_occupied_columns_equals_dense_pca():
    """Dropping never-occupied columns and PCA through the Gram matrix give sklearn's
    PCA of the full dense histogram: same variances, same projections up to sign."""
    rng = np.random.default_rng(4)
    X = [rng.normal(size=(rng.integers(20, 60), 7)) for _ in range(12)]
    h = ChordHistogram(bins=3).fit(X[:8])
    H_train, H_test = h.transform(X[:8]), h.transform(X[8:])
    occ = OccupiedColumns().fit(H_train)
    assert sp.issparse(occ.transform(H_train))
    dense = PCA(n_components=0.95, svd_solver="full").fit(H_train.toarray())
    gram = GramPCA(0.95).fit(occ.transform(H_train))
    assert gram.n_components_ == dense.n_components_
    np.testing.assert_allclose(gram.explained_variance_, dense.explained_variance_,
                               rtol=1e-9)
    z_dense = dense.transform(H_test.toarray())
    z_gram = gram.transform(occ.transform(H_test))
    np.testing.assert_allclose(np.abs(z_gram), np.abs(z_dense), atol=1e-12)


@pytest.mark.parametrize("inputs", ["chords", "records"])
@pytest.mark.parametrize("fixture", ["separable", "three_classes"])
def test_exported_model_matches_the_pipeline(fixture, inputs, request):
    objects = request.getfixturevalue(fixture)
    X = [o.chords.values for o in objects] if inputs == "chords" else objects
    y = [o.category for o in objects]
    pipe = fit_pipeline(X, y)
    model = ChordModel.from_pipeline(pipe, ChordParams())
    np.testing.assert_allclose(model.predict_proba(X), pipe.predict_proba(X), atol=1e-12)
    np.testing.assert_array_equal(model.predict(X), pipe.predict(X))
    # Chords alone (active recognition's cells): the descriptors at the training mean.
    chords = [o.chords for o in objects]
    np.testing.assert_allclose(model.predict_proba(chords), pipe.predict_proba(chords),
                               atol=1e-12)


@pytest.mark.parametrize("coarse", [0, 3])
def test_the_projection_equals_the_sparse_features_product_to_the_bit(three_classes, coarse):
    """The tree search's projection, built without sparse matrices, against the product of
    features_from_bins' rows and the PCA components: equal to the bit (a flipped last bit
    could turn a search's choice), with descriptor slots, extents and views partly unknown,
    an object without chords and cells the training never saw."""
    from drake_continuum.learning.params import ClassifierParams
    objects = _with_views(three_classes, np.random.default_rng(5))
    params = ClassifierParams(coarse=coarse, wrap_weight=0.4, extent_weight=0.8)
    model = ChordModel.from_pipeline(
        fit_pipeline(objects, [o.category for o in objects], params=params), ChordParams())
    assert model.uses_view and len(model.wrap_mean) and model.coarse == coarse
    rng = np.random.default_rng(6)
    cells = [model.bin_index(o.chords) for o in objects[:5]] + [
        np.zeros(0, np.int64), rng.integers(0, model.bins ** 7, 300)]
    n = len(cells)
    slots = rng.normal(size=(n, len(model.wrap_mean)))
    slots[rng.random(slots.shape) < 0.4] = np.nan
    extents, views = rng.normal(size=(n, 5)), rng.normal(size=(n, 3))
    views[2] = np.nan
    for kw in ({}, {"descriptor_slots": slots, "extents": extents, "views": views}):
        X = model.features_from_bins(cells, **kw)
        expected = np.asarray(X @ model.pca_components.T) - \
            model.pca_mean @ model.pca_components.T
        got = model._projected(cells, kw.get("descriptor_slots"), kw.get("extents"),
                               views=kw.get("views"))
        assert np.abs(expected).max() > 0.1
        np.testing.assert_array_equal(got, expected)
        # each row as the sum of a few CellCounts (active recognition's wraps): the same bits
        counted = [tuple(CellCounts.of(part) for part in np.array_split(rng.permutation(c), 3))
                   for c in cells]
        np.testing.assert_array_equal(model._projected(
            counted, kw.get("descriptor_slots"), kw.get("extents"), views=kw.get("views")),
            expected)
        # numpy's sum of the products over the first axis, row by row: the same bits
        for i, c in enumerate(cells[:3]):
            X_i = X[i].tocsr()
            products = X_i.data[:, None] * model.pca_components.T[X_i.indices]
            np.testing.assert_array_equal(got[i], products.sum(axis=0) - model.pca_mean @
                                          model.pca_components.T)


@pytest.fixture(scope="module")
def lying_and_standing():
    """Two categories, each standing (circle 3 cm / square 8 cm) and lying on another side
    (an ellipse 12 x 3 cm / a rectangle 16 x 5 cm): placed copies with their side."""
    rng = np.random.default_rng(7)
    out = []
    for i in range(6):
        for cat, kind, size, aspect in (("round", "circle", 0.03, 1), ("box", "square", 0.08, 1)):
            out.append(object_record(f"{cat}{i}", cat, object_wraps(
                shape_contour(kind, size * rng.uniform(0.9, 1.1), aspect), 3, rng)))
        for cat, kind, size, aspect in (("round", "ellipse", 0.12, 0.25),
                                        ("box", "square", 0.16, 0.3)):
            out.append(object_record(f"{cat}{i}@train0", cat, object_wraps(
                shape_contour(kind, size * rng.uniform(0.9, 1.1), aspect), 3, rng),
                side="other"))
    return out


def test_rest_classes_are_learnt_apart_and_count_for_their_category(lying_and_standing):
    """Copies on another side get a class of their own (at least REST_CLASS_MIN of them),
    the category's probability is the sum of its classes' (the SVM's own probabilities,
    summed by hand here), and the exported model and its saved copy agree with the
    pipeline."""
    objects = lying_and_standing
    y = [o.category for o in objects]
    labels = training_labels(objects, y)
    assert sorted(set(labels)) == sorted(["box", "round", rest_class("box"),
                                          rest_class("round")])
    assert all((lab.endswith(REST_CLASS)) == (o.side == "other")
               for lab, o in zip(labels, objects))
    # Fewer than REST_CLASS_MIN copies on another side stay in their category.
    few = [o for o in objects if o.side == "generated" or o.object_id in ("box0@train0",
                                                                           "box1@train0")]
    assert set(training_labels(few, [o.category for o in few])) == {"box", "round"}
    off = training_labels(objects, y, params=ClassifierParams(rest_classes=False))
    assert list(off) == y
    pipe = fit_pipeline(objects, y, params=ClassifierParams(standing_model=False))
    svm = pipe["svm"]
    assert list(svm.classes_) == ["box", "round"] and len(svm.svm_classes_) == 4
    inner = svm.estimator_.predict_proba(pipe[:-1].transform(objects))
    by_hand = np.column_stack([inner[:, [class_ == c or class_ == rest_class(c)
                                         for class_ in svm.svm_classes_]].sum(axis=1)
                               for c in svm.classes_])
    proba = pipe.predict_proba(objects)
    np.testing.assert_allclose(proba, by_hand, atol=1e-12)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0, atol=1e-12)
    assert np.mean(pipe.predict(objects) == np.array(y)) == 1.0
    model = ChordModel.from_pipeline(pipe, ChordParams())
    assert model.classes == ("box", "round") and len(model.svm_classes) == 4
    np.testing.assert_allclose(model.predict_proba(objects), proba, atol=1e-12)
    chords = [o.chords for o in objects]
    np.testing.assert_allclose(model.predict_proba(chords), pipe.predict_proba(chords),
                               atol=1e-12)


def test_the_standing_model_is_mixed_in_by_the_probability_of_lying(lying_and_standing):
    """With rest classes, fit_pipeline adds a model of the standing objects alone, binned
    with the full model's edges, and predicts (1 - q) P_standing + q P_full with q the full
    model's rest-class probability: checked against the two pipelines fitted by hand, and
    the exported ChordModel (records and chords alone, as active recognition calls it)
    against the mixture."""
    objects = lying_and_standing
    y = np.array([o.category for o in objects])
    mix = fit_pipeline(objects, y)
    assert isinstance(mix, SideMixture)
    full = fit_pipeline(objects, y, params=ClassifierParams(standing_model=False))
    edges = full["histogram"].histogram_.edges_
    standing = np.array([o.side != "other" for o in objects])
    alone = make_pipeline(edges=edges).set_params(svm__estimator__cv=3).fit(
        [o for o, k in zip(objects, standing) if k], y[standing])
    np.testing.assert_array_equal(mix.standing_["histogram"].histogram_.edges_, edges)
    svm = full["svm"]
    inner = svm.estimator_.predict_proba(full[:-1].transform(objects))
    q = inner[:, [c.endswith(REST_CLASS) for c in svm.svm_classes_]].sum(axis=1)
    np.testing.assert_allclose(mix.lying_probability(objects), q, atol=1e-12)
    by_hand = (1 - q)[:, None] * alone.predict_proba(objects) \
        + q[:, None] * full.predict_proba(objects)
    proba = mix.predict_proba(objects)
    np.testing.assert_allclose(proba, by_hand, atol=1e-12)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0, atol=1e-12)
    # The lying copies are told apart from the standing ones (q near 1 against near 0).
    assert q[~standing].min() > 0.5 > q[standing].max()
    model = ChordModel.from_pipeline(mix, ChordParams())
    assert model.standing is not None and model.standing.svm_classes == ()
    np.testing.assert_allclose(model.predict_proba(objects), proba, atol=1e-12)
    chords = [o.chords for o in objects]
    np.testing.assert_allclose(model.predict_proba(chords), mix.predict_proba(chords),
                               atol=1e-12)
    # Cells given as CellCounts of the wraps reach both models: the same bits as the cells.
    cells = [model.bin_index(c) for c in chords]
    counted = [tuple(CellCounts.of(model.bin_index(c.values[c.wrap == w]))
                     for w in np.unique(c.wrap)) for c in chords]
    np.testing.assert_array_equal(model.predict_proba_bins(counted),
                                  model.predict_proba_bins(cells))
    # A category without 2 standing objects: the full model alone.
    few = [o for o in objects if o.side == "other" or o.object_id in ("round0", "round1")]
    assert not isinstance(fit_pipeline(few, [o.category for o in few]), SideMixture)


def test_rest_classes_model_round_trip(lying_and_standing, tmp_path):
    """The model with its standing model saved and loaded: the same probabilities; the
    standing model's arrays are covered by the checksum."""
    objects = lying_and_standing
    model = train(objects)
    assert model.standing is not None and model.info["n_standing_objects"] == 12
    save_model(model, tmp_path / "m")
    again = load_model(tmp_path / "m")
    assert again.svm_classes == model.svm_classes and again.classes == model.classes
    assert again.standing is not None
    np.testing.assert_allclose(again.predict_proba(objects), model.predict_proba(objects),
                               atol=1e-12)
    with np.load(tmp_path / "m" / "model.npz") as z:
        arrays = {k: np.array(z[k]) for k in z.files}
    arrays["standing.coef"] = arrays["standing.coef"] * 1.01
    np.savez(tmp_path / "m" / "model.npz", **arrays)
    with pytest.raises(ModelFormatError, match="SHA-256"):
        load_model(tmp_path / "m")


def test_rest_classes_refuse_an_unknown_side_and_a_category_named_like_one(
        lying_and_standing):
    import dataclasses

    from drake_continuum.errors import InputError
    objects = list(lying_and_standing)
    objects[-1] = dataclasses.replace(objects[-1], side=None)
    with pytest.raises(InputError, match=f"{objects[-1].object_id!r}.*side it stood on"):
        fit_pipeline(objects, [o.category for o in objects])
    named = [dataclasses.replace(o, category=rest_class("box")) if o.category == "box" else o
             for o in lying_and_standing]
    with pytest.raises(InputError, match="names the classifier's rest classes"):
        fit_pipeline(named, [o.category for o in named])


def _with_views(objects, rng):
    """The objects with a camera view: (height, long, short) m, a category's own sizes."""
    import dataclasses
    size = {"circle": (0.06, 0.06, 0.06), "square": (0.2, 0.09, 0.09),
            "ellipse": (0.03, 0.13, 0.07)}
    return [dataclasses.replace(o, view=np.array(size[o.category]) * rng.uniform(0.9, 1.1, 3))
            for o in objects]


def test_the_view_block_is_the_standardised_camera_view(three_classes):
    """The view block after the histogram, descriptors and extent: each of height, long,
    short standardised by the training objects' mean and standard deviation (numpy's) and
    weighted view_weight / sqrt(3); chords alone give zeros there; no view in any training
    object gives no block; a view missing in one of them is refused by name."""
    import dataclasses

    from drake_continuum.errors import InputError
    objects = _with_views(three_classes, np.random.default_rng(3))
    V = np.array([o.view for o in objects])
    feats = ObjectFeatures(wrap_weight=0.4, extent_weight=0.8, view_weight=1.5).fit(objects)
    X = feats.transform(objects).toarray()
    expected = (V - V.mean(axis=0)) / V.std(axis=0) * 1.5 / np.sqrt(3)
    np.testing.assert_allclose(X[:, -3:], expected, atol=1e-12)
    no_view = ObjectFeatures(wrap_weight=0.4, extent_weight=0.8).fit(objects)
    np.testing.assert_allclose(X[:, :-3], no_view.transform(objects).toarray(), atol=1e-12)
    assert not feats.transform([o.chords for o in objects]).toarray()[:, -3:].any()
    plain = ObjectFeatures(view_weight=1.5).fit(three_classes)  # no views at all
    assert plain.n_features_ == plain.histogram_.n_cells_
    mixed = objects[:-1] + [dataclasses.replace(objects[-1], view=np.full(3, np.nan))]
    with pytest.raises(InputError, match=f"{objects[-1].object_id!r} has no camera view"):
        ObjectFeatures(view_weight=1.0).fit(mixed)


def test_a_model_with_the_view_matches_its_pipeline_and_needs_the_view(three_classes,
                                                                       tmp_path):
    from drake_continuum.errors import InputError
    objects = _with_views(three_classes, np.random.default_rng(4))
    y = [o.category for o in objects]
    pipe = fit_pipeline(objects, y)
    model = ChordModel.from_pipeline(pipe, ChordParams())
    assert model.uses_view
    np.testing.assert_allclose(model.predict_proba(objects), pipe.predict_proba(objects),
                               atol=1e-12)
    save_model(model, tmp_path / "m")
    np.testing.assert_allclose(load_model(tmp_path / "m").predict_proba(objects),
                               pipe.predict_proba(objects), atol=1e-12)
    # Cells alone plus the view (active recognition): the pipeline on chords with that view.
    import dataclasses
    cells_only = [dataclasses.replace(o, descriptors=np.zeros((0, 7)),
                                      contact_points=np.zeros((0, 3))) for o in objects]
    np.testing.assert_allclose(
        model.predict_proba_bins([model.bin_index(o.chords) for o in objects],
                                 views=np.array([o.view for o in objects])),
        pipe.predict_proba(cells_only), atol=1e-12)
    with pytest.raises(InputError, match="depth camera's view"):
        classify_wraps(model, [])


def test_active_recognition_starts_from_the_view(three_classes):
    """With the camera's view, the posterior before any wrap is the classifier on no chords
    and that view (not the training prior), and every later one includes it."""
    from drake_continuum.active.policies import build_active_model
    from drake_continuum.active.search import TreeSearch
    from drake_continuum.active.training import object_wraps_from_records
    from drake_continuum.errors import InputError
    objects = _with_views(three_classes, np.random.default_rng(5))
    clf = train(objects)
    normals = np.eye(3)[[0, 1, 2, 0]]
    active = build_active_model(clf, object_wraps_from_records(objects), normals)
    view = objects[1].view
    search = TreeSearch(active, view=view)
    expected = clf.predict_proba_bins([np.zeros(0, np.int64)], views=view[None])[0]
    np.testing.assert_allclose(search.proba(), expected, atol=1e-12)
    assert np.argmax(search.proba()) == list(clf.classes).index(objects[1].category)
    assert not np.allclose(TreeSearch(active).proba(), expected)
    chords = objects[1].chords.of_wraps([0]).values
    search.add_wrap(0, chords)
    np.testing.assert_allclose(
        search.proba(), clf.predict_proba_bins([clf.bin_index(chords)], views=view[None])[0],
        atol=1e-12)
    from drake_continuum.active.policies import recognize
    with pytest.raises(InputError, match="depth camera's view"):
        recognize(active, lambda plane: None)


def test_load_wraps_reads_the_recorded_side(tmp_path):
    from synthetic_wraps import separable_objects
    objects = separable_objects(2, 2)
    placed = [(f"{i}@{tag}", c, w) for i, c, w in objects for tag in ("rest0", "turned0")]
    sides = {o[0]: "other" for o in placed if o[0].endswith("rest0")}
    sides[placed[-1][0]] = None  # collected before the side was recorded
    write_collection(tmp_path / "w", objects + placed, sides=sides)
    got = {r.object_id: r.side for r in load_wraps(tmp_path / "w")}
    assert all(got[i] == "generated" for i, _, _ in objects)
    assert all(got[i] == ("other" if i.endswith("rest0") else "generated")
               for i, _, _ in placed[:-1])
    assert got[placed[-1][0]] is None


def test_object_features_blocks(three_classes):
    """The features are the chord histograms (fine, then coarse) followed by each plane's
    wrap descriptors standardised over the training objects (numpy's mean and std) and
    weighted by wrap_weight / sqrt(slots); chords alone give zeros there; with no coarse
    block and no descriptors they are the plain chord histogram."""
    train_objs, new = three_classes[:12], three_classes[12:]
    f = ObjectFeatures(coarse=3, wrap_weight=0.3).fit(train_objs)
    h = ChordHistogram(7, edges="quantile", power=0.5, coarse=3).fit(
        [o.chords.values for o in train_objs])
    D = np.array([o.descriptors.ravel() for o in train_objs])  # planes 0, 1, 2 in order
    assert f.n_planes_ == 3 and D.shape == (12, 21)
    mean, std = D.mean(axis=0), D.std(axis=0)
    assert np.sum(std < 1e-12) == 3  # every tip turns 270 deg: a constant is left at zero
    std[std < 1e-12] = 1.0
    F = f.transform(new).toarray()
    np.testing.assert_allclose(F[:, :h.n_cells_], h.transform([o.chords for o in new]).toarray())
    expected = (np.array([o.descriptors.ravel() for o in new]) - mean) / std * 0.3 / np.sqrt(21)
    np.testing.assert_allclose(F[:, h.n_cells_:], expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.abs(f.transform(train_objs)[:, h.n_cells_:].toarray()).sum(),
                               np.abs((D - mean) / std * 0.3 / np.sqrt(21)).sum())
    assert f.transform([o.chords for o in new])[:, h.n_cells_:].nnz == 0
    plain = ObjectFeatures(coarse=0, wrap_weight=0.0).fit(train_objs)
    np.testing.assert_allclose(
        plain.transform(new).toarray(),
        ChordHistogram(7, edges="quantile", power=0.5).fit(
            [o.chords.values for o in train_objs]).transform([o.chords for o in new]).toarray())
    p = ClassifierParams()
    assert (p.coarse, p.wrap_weight, p.extent_weight) == (0, 0.4, 0.8)


def test_contact_extent_block(three_classes):
    """The contact extent block is each object's (ptp x, ptp y, ptp z, top z, reach from the
    z axis) of its contact centres, standardised over the training objects and weighted by
    extent_weight / sqrt(5); chords alone (no contacts) give the training mean, zeros."""
    from drake_continuum.features.chords import contact_extent

    box = np.array([[0.01, -0.02, 0.0], [0.03, 0.02, 0.05], [-0.04, 0.0, 0.12]])
    np.testing.assert_allclose(contact_extent(box),
                               [0.07, 0.04, 0.12, 0.12, 0.04])  # reach: (-0.04, 0)
    assert np.isnan(contact_extent(np.zeros((0, 3)))).all()

    train_objs, new = three_classes[:12], three_classes[12:]
    f = ObjectFeatures(wrap_weight=0.0, extent_weight=0.5).fit(train_objs)
    h = ChordHistogram(7, edges="quantile", power=0.5).fit([o.chords.values for o in train_objs])

    def extent(o):
        p = o.contact_points
        return [*(p.max(axis=0) - p.min(axis=0)), p[:, 2].max(),
                np.sqrt(p[:, 0] ** 2 + p[:, 1] ** 2).max()]

    E = np.array([extent(o) for o in train_objs])
    expected = ((np.array([extent(o) for o in new]) - E.mean(axis=0)) / E.std(axis=0)
                * 0.5 / np.sqrt(5))
    F = f.transform(new).toarray()
    assert F.shape[1] == h.n_cells_ + 5
    np.testing.assert_allclose(F[:, h.n_cells_:], expected, rtol=1e-10, atol=1e-12)
    assert f.transform([o.chords for o in new])[:, h.n_cells_:].nnz == 0



def test_model_round_trip_and_version_check(three_classes, tmp_path):
    model = train(three_classes, seed=0)
    assert model.coarse == 0 and model.n_planes == 3 and len(model.extent_mean) == 5
    save_model(model, tmp_path / "m")
    loaded = load_model(tmp_path / "m")
    for X in ([o.chords for o in three_classes], three_classes):
        np.testing.assert_array_equal(loaded.predict_proba(X), model.predict_proba(X))
    pipe = fit_pipeline(three_classes, [o.category for o in three_classes])
    np.testing.assert_allclose(loaded.predict_proba(three_classes),
                               pipe.predict_proba(three_classes), atol=1e-12)
    assert list(loaded.classes_) == ["circle", "ellipse", "square"]
    assert loaded.chord_params == model.chord_params
    np.testing.assert_array_equal(loaded.edges_, model.edges_)
    assert not list((tmp_path / "m").glob(".*tmp*"))

    meta = json.loads((tmp_path / "m" / "model.json").read_text())
    for other in (FORMAT_VERSION + 1, 3):  # 3: before the contact extent
        meta["format_version"] = other
        (tmp_path / "m" / "model.json").write_text(json.dumps(meta))
        with pytest.raises(ModelFormatError) as e:
            load_model(tmp_path / "m")
        msg = str(e.value)
        assert str(tmp_path / "m") in msg and f"version {other}" in msg \
            and f"version {FORMAT_VERSION}" in msg and "retrain" in msg
    with pytest.raises(ModelFormatError, match="not a drake-continuum model"):
        load_model(tmp_path / "nothing")


def test_active_recognition_pieces(three_classes):
    model = train(three_classes)
    chords = three_classes[0].chords
    idx = model.bin_index(chords)
    assert idx.shape == (len(chords),) and idx.max() < 7 ** 7
    centres = model.bin_centres(idx)
    np.testing.assert_array_equal(model.bin_index(centres), idx)
    # Accumulating wraps: probabilities of the first wrap, then of wraps 0 and 1.
    p1 = model.predict_proba([chords.of_wraps([0]), chords.of_wraps([0, 1])])
    np.testing.assert_allclose(p1.sum(axis=1), 1.0)
    np.testing.assert_allclose(model.predict_proba_bins([idx]), model.predict_proba([chords]))


def test_train_refuses_chord_settings_the_records_were_not_taken_with():
    """A model records its chord settings and takes a new object's chords with them: trained
    on chords taken otherwise, it would classify what it never learnt. train refuses,
    naming both; records taken with the scenario's settings train."""
    from drake_continuum.config import Config
    from drake_continuum.errors import InputError
    made = separable_objects(4, 2)
    default = [object_record(i, c, w) for i, c, w in made]
    wrap_frame = ChordParams(frame="wrap")
    with pytest.raises(InputError, match=r"taken with ChordParams\(spacing=0\.01, .*'world'.*"
                                         r"chords section is ChordParams\(.*'wrap'"):
        train(default, Config(chords=wrap_frame))
    own = [object_record(i, c, w, params=wrap_frame) for i, c, w in made]
    assert train(own, Config(chords=wrap_frame)).chord_params == wrap_frame


def test_classify_wraps_of_a_new_object(separable):
    model = train(separable)
    wraps = object_wraps(shape_contour("square", 0.08), 3, np.random.default_rng(99))
    category, proba = classify_wraps(model, wraps)
    assert category == "square" and proba.shape == (2,) and proba[1] > 0.5


def test_load_wraps_skips_a_corrupt_object(tmp_path):
    write_collection(tmp_path, separable_objects(3, 2))
    (tmp_path / "circle_01.npz").write_bytes(b"not an archive")
    with pytest.warns(WrapDataWarning, match="circle_01.npz"):
        objects = load_wraps(tmp_path)
    assert len(objects) == 5 and "circle_01" not in [o.object_id for o in objects]
    assert all(o.n_wraps == 2 and len(o.chords) > 0 for o in objects)


def test_table_and_figure(separable, tmp_path):
    rows = table1(separable)
    assert [r["category"] for r in rows] == ["circle", "square"]
    assert rows[0]["mean_wraps"] == 3 and 100 < rows[0]["mean_wrap_ms"] < 400
    write_table1(rows, tmp_path)
    assert "| circle | 8 |" in (tmp_path / "table1.md").read_text()
    assert json.loads((tmp_path / "table1.json").read_text()) == rows
    plot_confusion(evaluate(separable, 2), tmp_path / "c.png")
    assert (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG"


def test_cli_evaluate_and_train(tmp_path, capsys):
    write_collection(tmp_path / "wraps", separable_objects(4, 2))
    rc = cli.main(["evaluate", str(tmp_path / "wraps"), "--splits", "3", "--out",
                   str(tmp_path / "ev"), "--json"])
    assert rc == 0
    out = json.loads(capsys.readouterr().out)
    assert out["accuracy_mean"] == 1.0 and out["n_objects"] == 8
    assert {"accuracy_std", "baseline_accuracy_mean", "per_class"} <= set(out)
    for name in ("confusion.png", "confusion_triangles.png", "table1.md", "table1.json",
                 "evaluation.json"):
        assert (tmp_path / "ev" / name).is_file()
    assert cli.main(["train", str(tmp_path / "wraps"), "--out", str(tmp_path / "model")]) == 0
    assert load_model(tmp_path / "model").classes == ("circle", "square")
    capsys.readouterr()
    (tmp_path / "few").mkdir()
    write_collection(tmp_path / "few", separable_objects(2, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main(["evaluate", str(tmp_path / "few"), "--splits", "2"]) == 1
    assert "at least 4 objects" in capsys.readouterr().err


def test_cli_classify_wraps_a_mesh_with_its_descriptors(tmp_path, capsys, monkeypatch):
    """`classify MODEL MESH --json` wraps the mesh on every plane and classifies it from
    chords and wrap descriptors (classify_wraps), as the model was trained."""
    import json

    from drake_continuum import cli
    from drake_continuum.kinematics.arm import MODELS_DIR
    from drake_continuum.learning import model as C

    write_collection(tmp_path / "wraps", separable_objects(4, 4))
    assert cli.main(["train", str(tmp_path / "wraps"), "--out", str(tmp_path / "m")]) == 0
    seen, views = [], []
    original = C.classify_wraps

    def spy(model, wraps, view=None):
        seen.append(list(wraps))
        views.append(view)
        return original(model, wraps, view)
    monkeypatch.setattr(C, "classify_wraps", spy)
    capsys.readouterr()
    png = tmp_path / "wraps.png"
    assert cli.main(["classify", str(tmp_path / "m"), str(MODELS_DIR / "mug.obj"), "--json",
                     "--png", str(png)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["category"] in ("circle", "square")
    assert sum(out["probabilities"].values()) == pytest.approx(1.0)
    assert max(out["probabilities"], key=out["probabilities"].get) == out["category"]
    assert len(seen) == 1 and len(seen[0]) == 10  # every plane, usable or not, in order
    # The depth camera's view of the mug as it stands (its own height: 10.3 cm).
    from drake_continuum.kinematics.arm import load_arm
    from drake_continuum.objects.mesh import load_mesh
    from drake_continuum.perception.locate import camera_view
    mug = load_mesh(MODELS_DIR / "mug.obj")
    np.testing.assert_allclose(views[0], camera_view(mug, load_arm()), atol=1e-6)
    assert abs(views[0][0] - mug.extents[2]) < 0.005 and views[0][1] > views[0][2] > 0
    assert out["position"]["view"] == pytest.approx(list(views[0]), abs=1e-6)
    assert [w.plane_index for w in seen[0]] == list(range(10))
    assert out["n_wraps"] == sum(w.usable for w in seen[0]) >= 5
    # --png: one 360-pixel cell a usable wrap, 5 a row.
    from PIL import Image
    n = out["n_wraps"]
    assert out["png"] == str(png)
    assert Image.open(png).size == (min(n, 5) * 360, -(-n // 5) * 360)


def test_cli_classify_wraps_as_the_training_collection_did(tmp_path, capsys, monkeypatch):
    """A model records its collection's settings; `classify` wraps with them (here: 4 planes
    of 90 deg, wraps stopping at 200 deg of tip rotation instead of 270), and says so when
    --set changes one."""

    from dataclasses import replace

    from drake_continuum import cli
    from drake_continuum.experiments.collection import run_params
    from drake_continuum.kinematics.arm import MODELS_DIR
    from drake_continuum.learning import model as C
    scenario = fixed_planes(theta_deg=200.0)
    write_collection(tmp_path / "wraps", separable_objects(4, 4),
                     run_params(replace(scenario, planes=replace(scenario.planes,
                                                                 alpha_deg=90.0))))
    assert cli.main(["train", str(tmp_path / "wraps"), "--out", str(tmp_path / "m")]) == 0
    recorded = C.load_model(tmp_path / "m").info["settings"]["config"]
    assert recorded["wrap"]["theta_deg"] == 200.0 and recorded["planes"]["alpha_deg"] == 90.0
    seen = []
    original = C.classify_wraps
    monkeypatch.setattr(C, "classify_wraps",
                        lambda model, wraps, view=None: seen.append(list(wraps))
                        or original(model, wraps, view))
    capsys.readouterr()
    assert cli.main(["classify", str(tmp_path / "m"), str(MODELS_DIR / "mug.obj")]) == 0
    assert "warning" not in capsys.readouterr().err
    (wraps,) = seen
    assert [w.plane_index for w in wraps] == [0, 1, 2, 3]
    done = [w for w in wraps if w.status == "complete"]
    # With the default 270 deg every complete wrap would turn at least 270 deg.
    assert done and all(np.radians(200) <= w.tip_rotation < np.radians(270) for w in done)
    assert cli.main(["classify", str(tmp_path / "m"), str(MODELS_DIR / "mug.obj"),
                     "--set", "wrap.theta_deg=220"]) == 0
    assert ("warning: wraps differ from the training collection's in wrap.theta_deg "
            "(200.0 -> 220.0)") in capsys.readouterr().err
