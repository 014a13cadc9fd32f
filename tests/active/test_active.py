"""Active recognition: tallies, UCT and backpropagation by hand, known-answer searches."""

import json
import math

import numpy as np
import pytest

from drake_continuum.active.observation import (
    ActiveModel,
    fit_observation_model,
    load_observation_model,
    save_observation_model,
)
from drake_continuum.active.params import ActiveParams, ObjectWraps, plane_cost_matrix
from drake_continuum.active.policies import (
    evaluate_policies,
    plot_policy_curves,
    precomputed_execute,
    recognize,
    run_policy,
)
from drake_continuum.active.search import TreeSearch, strong_prediction
from drake_continuum.active.training import table_ii, table_ii_markdown
from drake_continuum.config import Config
from drake_continuum.errors import InputError
from drake_continuum.features.chords import bin_index
from synthetic_active import synthetic_objects, synthetic_planes, train_synthetic_classifier


@pytest.fixture(scope="module")
def problem():
    train = synthetic_objects(n_per_class=8, seed=0)
    test = synthetic_objects(n_per_class=2, seed=1)
    clf = train_synthetic_classifier(train)
    obs = fit_observation_model(train, clf.classes_, clf.edges_, plane_normals=synthetic_planes(),
                                neighbours=5)
    return ActiveModel(clf, obs), train, test


def test_yaml_holds_the_dataclass_defaults(tmp_path):
    from drake_continuum.config import DEFAULT_CONFIG, load_config
    assert load_config().active == ActiveParams()
    bad = tmp_path / "a.yaml"
    bad.write_text(DEFAULT_CONFIG.read_text()
                   .replace("  horizon: 5", "  horizon: 5\n  horizn: 4")
                   .replace("arm: arm.yaml", f"arm: {DEFAULT_CONFIG.parent / 'arm.yaml'}"))
    with pytest.raises(ValueError, match="active.horizn: unknown key"):
        load_config(bad)


def test_tallies_pair_every_two_wraps_of_an_object(problem):
    model, train, _ = problem
    obs = model.observations
    n_wraps = [len(o.wraps) for o in train]
    assert obs.n_observations == sum(n_wraps)
    assert len(obs.pair_from) == sum(w * (w - 1) for w in n_wraps)
    same = obs.obs_object[obs.pair_from] == obs.obs_object[obs.pair_to]
    assert same.all() and (obs.pair_from != obs.pair_to).all()
    np.testing.assert_array_equal(obs.pair_action, obs.obs_plane[obs.pair_to])
    cost = plane_cost_matrix(synthetic_planes())
    np.testing.assert_allclose(obs.pair_cost,
                               cost[obs.obs_plane[obs.pair_from], obs.obs_plane[obs.pair_to]])
    assert math.isclose(cost[0, 1], math.radians(22.5)) and math.isclose(cost[0, 4], math.pi / 2)
    # successor[i, a] is the wrap of i's own object on plane a
    i = 7
    for a in range(obs.n_planes):
        j = obs.successor[i, a]
        if a == obs.obs_plane[i]:
            assert j == -1
        else:
            assert obs.obs_object[j] == obs.obs_object[i] and obs.obs_plane[j] == a


def test_observation_at_bin_centres_rebuilds_the_histogram(problem):
    model, train, _ = problem
    obs = model.observations
    chords = train[0].wraps[2]
    cells = np.sort(bin_index(chords, obs.edges))
    i = int(np.flatnonzero((obs.obs_object == 0) & (obs.obs_plane == 2))[0])
    np.testing.assert_array_equal(np.sort(obs.cells(i)), cells)
    np.testing.assert_array_equal(np.sort(bin_index(obs.centres(i), obs.edges)), cells)


def test_a_training_wrap_matches_itself_first(problem):
    model, train, _ = problem
    obs = model.observations
    i = int(np.flatnonzero((obs.obs_object == 3) & (obs.obs_plane == 1))[0])
    succ, count = obs.training_successors
    y = obs.obs_class[i]
    assert succ[i, y, 4, 0] == obs.successor[i, 4]
    assert (count <= obs.neighbours).all() and count[i, :, 4].sum() > 0
    search = TreeSearch(model, ActiveParams())
    search.add_wrap(1, train[3].wraps[1])           # the same chords, seen as a real wrap
    real_succ, _ = search.observations.successors(search.history[-1][1])
    assert real_succ[y, 4, 0] == obs.successor[i, 4]


def test_successors_are_the_first_k_of_each_class_in_order_of_similarity(problem):
    """successors_of against a loop over the candidates, most similar first: per class and
    action, the tallied successors of the first `neighbours` training wraps that have one."""
    obs = problem[0].observations
    rng = np.random.default_rng(2)
    plane = 3
    sim = rng.random((4, obs.n_observations))
    sim[:, :5] = sim[:, 5:10]                       # ties keep the training order
    succ, count = obs.successors_of(sim, plane)
    on_plane = np.flatnonzero(obs.obs_plane == plane)
    for r in range(len(sim)):
        ranked = sorted(on_plane, key=lambda j: -sim[r, j])  # stable: ties in index order
        for y in range(obs.n_classes):
            for a in range(obs.n_planes):
                want = [obs.successor[j, a] for j in ranked
                        if obs.obs_class[j] == y and obs.successor[j, a] >= 0][:obs.neighbours]
                assert count[r, y, a] == len(want)
                np.testing.assert_array_equal(succ[r, y, a, :len(want)], want)
                assert (succ[r, y, a, len(want):] == -1).all()
    assert count.max() == obs.neighbours


def test_save_load_round_trip(problem, tmp_path):
    obs = problem[0].observations
    save_observation_model(obs, tmp_path)
    back = load_observation_model(tmp_path)
    for k in ("obs_cells", "obs_counts", "pair_from", "pair_to", "edges", "plane_normals"):
        np.testing.assert_array_equal(getattr(back, k), getattr(obs, k))
    assert list(back.classes) == list(obs.classes) and back.neighbours == obs.neighbours
    meta = json.loads((tmp_path / "observations.json").read_text())
    meta["format_version"] = 99
    (tmp_path / "observations.json").write_text(json.dumps(meta))
    with pytest.raises(ValueError, match="format version 99"):
        load_observation_model(tmp_path)


def test_reward_uct_and_discounted_backpropagation_by_hand(problem):
    model = problem[0]
    params = ActiveParams(cost_weight=0.4, discount=0.5, exploration=1.0)
    s = TreeSearch(model, params)
    # eq. 1: C = lambda/T sum(cost/pi) + (1 - lambda)(1 - max p)
    assert math.isclose(s.reward(0.5, 5, np.array([0.7, 0.2, 0.1])),
                        1 - (0.4 * 0.5 / 5 + 0.6 * 0.3))
    root = s._root()
    child = root.children[2] = s._root()
    child.depth = 1
    s._backpropagate([(root, 2), (child, 3)], 0.8, 2)
    s._backpropagate([(root, 2), (child, 1)], 0.6, 2)
    s._backpropagate([(root, 1)], 1.0, 2)           # a leaf reached by rollout below depth 1
    assert root.visits == 3 and child.visits == 2
    assert root.n_a[2] == 2 and math.isclose(root.w_a[2], 0.5 * 0.8 + 0.5 * 0.6)
    assert math.isclose(root.w_a[1], 0.5 * 1.0)
    assert math.isclose(child.w_a[3], 0.8) and math.isclose(child.w_a[1], 0.6)
    u = root.uct(1.0)
    assert math.isclose(u[2], 0.35 + math.sqrt(2 * math.log(3) / 2))
    assert math.isclose(u[1], 0.5 + math.sqrt(2 * math.log(3) / 1))
    assert u[0] == np.inf                           # untried actions come first
    root.feasible[3] = False
    assert root.uct(1.0)[3] == -np.inf


def test_search_statistics_add_up(problem):
    model = problem[0]
    s = TreeSearch(model, ActiveParams(horizon=2, n_simulations=120), rng=np.random.default_rng(3))
    res = s.search()
    root = s.root
    assert root.visits == 120 and root.n_a.sum() == 120
    for a, child in root.children.items():
        assert child.visits == root.n_a[a] - 1      # its first visit created it
        assert child.n_a.sum() == child.visits
    assert len(res.path) <= 2 and len(res.plan) == len(set(res.plan))


def test_search_prefers_the_cheap_informative_plane_and_greedy_does_not(problem):
    model = problem[0]
    planes = [1, 2, 3, 4]   # 1: 22.5 deg, weak signal; 4: 90 deg, strong signal; 2, 3: none
    for seed in range(3):
        cheap = TreeSearch(model, ActiveParams(cost_weight=0.8, horizon=3, n_simulations=300),
                           available=planes, rng=np.random.default_rng(seed))
        assert cheap.search().plan[0] == 1
        costly = TreeSearch(model, ActiveParams(cost_weight=0.2, horizon=3, n_simulations=300),
                            available=planes, rng=np.random.default_rng(seed))
        assert 4 in costly.search().plan
    gain = TreeSearch(model, ActiveParams(cost_weight=0.8), available=planes
                      ).expected_information_gain()
    assert np.nanargmax(gain) == 4 and gain[4] > gain[1] > max(gain[2], gain[3])
    obj = problem[2][0]
    greedy = run_policy(model, precomputed_execute(obj), "greedy",
                        params=ActiveParams(cost_weight=0.8), available=planes)
    assert greedy.planes[0] == 4


def test_stop_rule():
    assert strong_prediction(np.array([0.6, 0.2, 0.2]))
    assert not strong_prediction(np.array([0.6, 0.21, 0.19]))   # not 3 times the next
    assert not strong_prediction(np.array([0.5, 0.1, 0.1]))     # not above 0.5
    assert strong_prediction(np.array([0.1, 0.75, 0.15]))


def test_recognition_is_deterministic_for_a_seed_and_stops_on_a_strong_prediction(problem):
    model, _, test = problem
    params = ActiveParams(n_simulations=60)
    obj = test[0]
    a = recognize(model, precomputed_execute(obj), Config(active=params), seed=5).to_dict()
    b = recognize(model, precomputed_execute(obj), Config(active=params), seed=5).to_dict()
    for r in (a, b):
        for it in r["iterations"]:
            it.pop("search_time_s")
    assert a == b
    assert a["stopped_because"] in ("strong_prediction", "max_iterations", "no_planes_left")
    assert 1 <= len(a["iterations"]) <= params.max_iterations
    p = [q for _, q in a["iterations"][-1]["top3"]]
    if a["stopped_because"] == "strong_prediction":
        assert p[0] > 0.5 and p[0] >= 3 * p[1]
    planes = [pl for it in a["iterations"] for pl in it["planes"]]
    assert len(planes) == len(set(planes)) == a["n_wraps"]


def test_unavailable_planes_are_never_wrapped(problem):
    model, _, test = problem
    obj = test[1]
    partial = ObjectWraps(obj.name, obj.label, {p: c for p, c in obj.wraps.items() if p != 4})
    calls = []

    def execute(plane):
        calls.append(plane)
        return partial.wraps.get(plane)

    tr = run_policy(model, execute, "random", params=ActiveParams(), seed=0, stop_early=False)
    assert 4 not in tr.planes and sorted(tr.planes) == [0, 1, 2, 3]
    assert tr.stopped_because == "no_planes_left"
    tr = run_policy(model, precomputed_execute(partial), "mcts",
                    params=ActiveParams(n_simulations=40), available=sorted(partial.wraps))
    assert 4 not in tr.planes


def test_policy_evaluation_curves_and_table(problem, tmp_path):
    model, _, test = problem
    params = ActiveParams(n_simulations=30)
    res = evaluate_policies(model, test[:3], params=params, seed=0)
    assert set(res) == {"mcts", "greedy", "random"}
    for r in res.values():
        assert 0 <= r["accuracy_at_stop"] <= 1 and r["wraps_to_stop"] >= 0
        assert len(r["accuracy_vs_wraps"]["accuracy"]) == params.max_iterations * params.horizon + 1
    png = plot_policy_curves(res, tmp_path / "curves.png")
    assert png.stat().st_size > 1000
    rows = table_ii(model, test, categories=("a", "b"), params=params)
    # labels that are not the paper's: every label of the held-out objects by default
    assert list(table_ii(model, test, params=params)) == sorted({o.label for o in test})
    md = table_ii_markdown(rows)
    assert len(rows["a"]["iterations"]) == params.max_iterations
    assert md.count("\n") == 2 + 2 * params.max_iterations



def _untimed(tree):
    """A report without its timing fields (search times), which differ run to run."""
    if isinstance(tree, dict):
        return {k: _untimed(v) for k, v in tree.items() if "search_time" not in k}
    if isinstance(tree, list):
        return [_untimed(v) for v in tree]
    return tree


def test_runs_over_worker_processes_give_the_serial_results(problem):
    """Each run has its own seed: two workers give the serial run's planes, stops,
    probabilities and accuracies (every field but the search times), every policy and
    Table II; the serial run is the in-process loop, the second one forked workers."""
    model, _, test = problem
    params = ActiveParams(n_simulations=30)
    serial = evaluate_policies(model, test, params=params, seed=3, show_progress=False)
    forked = evaluate_policies(model, test, params=params, seed=3, show_progress=False,
                               workers=2)
    assert _untimed(forked) == _untimed(serial)
    assert forked["mcts"]["median_search_time_s"] > 0
    # the runs differ between objects, so the comparison can tell them apart
    assert len({tuple(r["planes"]) for r in serial["mcts"]["runs"]}) > 1
    assert (_untimed(table_ii(model, test, params=params, seed=3, workers=2))
            == _untimed(table_ii(model, test, params=params, seed=3)))
    with pytest.raises(InputError, match="workers must be at least 1"):
        evaluate_policies(model, test, params=params, workers=0)

def test_cli_train_and_evaluate_active_on_a_collection(tmp_path, capsys):
    import json

    from drake_continuum.active.training import load_active_model
    from drake_continuum.cli import main
    from synthetic_wraps import separable_objects, write_collection

    write_collection(tmp_path / "wraps", separable_objects(4, 4))
    assert main(["train-active", str(tmp_path / "wraps"), "--out", str(tmp_path / "m")]) == 0
    model = load_active_model(tmp_path / "m")
    assert list(model.observations.classes) == ["circle", "square"]
    # Recognition sees the chords and contacts of the wraps made so far: its classifier is
    # the fine histogram and the contact extent, without the wrap descriptors.
    assert model.classifier.coarse == 0 and len(model.classifier.wrap_mean) == 0
    assert len(model.classifier.extent_mean) == 5
    assert model.class_prior is None
    assert main(["train-active", str(tmp_path / "wraps"), "--out", str(tmp_path / "u"),
                 "--class-prior", "uniform"]) == 0
    np.testing.assert_array_equal(load_active_model(tmp_path / "u").class_prior, [0.5, 0.5])
    capsys.readouterr()
    assert main(["evaluate-active", str(tmp_path / "wraps"), "--out", str(tmp_path / "out"),
                 "--simulations", "20", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert set(summary["policies"]) == {"mcts", "greedy", "random"}
    for name in ("active.json", "curves.png", "table2.md"):
        assert (tmp_path / "out" / name).is_file()
    assert main(["evaluate-active", str(tmp_path / "wraps"), "--workers", "0"]) == 1
    assert "--workers must be at least 1, got 0" in capsys.readouterr().err


def test_cli_recognize_a_mesh_with_a_model_of_fewer_planes(tmp_path, capsys):
    """A collection of the first 4 planes trains a model that `recognize` serves with the
    arm's first 4 planes (it was refused), choosing only among them."""
    import json

    from drake_continuum.cli import main
    from drake_continuum.kinematics.arm import MODELS_DIR
    from synthetic_wraps import separable_objects, write_collection

    write_collection(tmp_path / "wraps", separable_objects(4, 4))
    assert main(["train-active", str(tmp_path / "wraps"), "--out", str(tmp_path / "m")]) == 0
    capsys.readouterr()
    assert main(["recognize", str(tmp_path / "m"), str(MODELS_DIR / "mug.obj"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    planes = [p for it in out["iterations"] for p in it["planes"]]
    assert planes and all(0 <= p < 4 for p in planes)
    assert out["category"] in ("circle", "square")
    # The configuration reaches recognition: one tree search of at most 2 wraps.
    assert main(["recognize", str(tmp_path / "m"), str(MODELS_DIR / "mug.obj"), "--json",
                 "--set", "active.max_iterations=1", "--set", "active.horizon=2"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert len(out["iterations"]) == 1 and 1 <= out["n_wraps"] <= 2


def test_evaluate_active_on_another_dataset_tests_only_it_and_never_trains_on_it(tmp_path,
                                                                                monkeypatch):
    """With test collections (another seed), every test object comes from them, every
    training object from the pool's training half (of the training kinds), none from them;
    the ids may collide with the pool's."""
    import drake_continuum.active.training as T
    from synthetic_wraps import separable_objects, write_collection

    pool = separable_objects(6, 3)
    write_collection(tmp_path / "pool", pool)
    write_collection(tmp_path / "placed", [(f"{i}@{tag}", c, w) for i, c, w in pool
                                           for tag in ("train0", "turned0")])
    other = separable_objects(3, 3, seed=9)  # the same ids as the pool's first ones
    write_collection(tmp_path / "other", other)
    write_collection(tmp_path / "other_placed", [(f"{i}@{tag}", c, w) for i, c, w in other
                                                 for tag in ("turned0", "rest0", "train0")])
    trained = []
    original = T.train_active

    def spy(folder, **kw):
        trained.append([kw["records"][i] for i in kw["train_index"]])
        return original(folder, **kw)
    monkeypatch.setattr(T, "train_active", spy)
    report = T.evaluate_active(tmp_path / "pool", policies=("random",),
                               params=ActiveParams(n_simulations=5), placed=[tmp_path / "placed"],
                               train_kinds=("generated", "train"),
                               test=[tmp_path / "other", tmp_path / "other_placed"])
    other_ids = sorted([i for i, _, _ in other] + [f"{i}@{t}" for i, _, _ in other
                                                   for t in ("turned0", "rest0")])
    tested = sorted(r["object"] for r in report["policies"]["random"]["runs"])
    assert tested == other_ids  # generated, turned, rest; never their train copies
    (train,) = trained
    assert len(train) == report["n_train"] > 0
    pool_ids = {i for i, _, _ in pool} | {f"{i}@train0" for i, _, _ in pool}
    assert {t.object_id for t in train} <= pool_ids
    # None of the other dataset's records is trained on (their chords differ from the pool's).
    from drake_continuum.learning.records import load_wraps
    theirs = load_wraps(tmp_path / "other") + load_wraps(tmp_path / "other_placed")
    for t in train:
        assert not any(np.array_equal(t.chords.values, o.chords.values) for o in theirs)
    assert set(report["policies"]["random"]["by_kind"]) == {"generated", "turned", "rest"}
    # A plain evaluation tests generated objects only: no placement breakdown.
    plain = T.evaluate_active(tmp_path / "pool", policies=("random",),
                              params=ActiveParams(n_simulations=5))
    assert "by_kind" not in plain["policies"]["random"]


# --------------------------------------------------------------------------- contact extent

def _records_with_contacts(n_per_class=3, n_wraps=4):
    from drake_continuum.learning.records import object_record
    from synthetic_wraps import separable_objects

    objects = separable_objects(n_per_class, n_wraps)
    return objects, [object_record(oid, cat, wraps) for oid, cat, wraps in objects]


def test_each_wraps_contacts_come_back_from_its_record():
    from drake_continuum.active.training import object_wraps_from_records, wrap_contact_points

    objects, records = _records_with_contacts()
    for (_, _, wraps), record, obj in zip(objects, records,
                                          object_wraps_from_records(records)):
        points = wrap_contact_points(record)
        assert len(points) == len(wraps)
        for w, p in zip(wraps, points):
            np.testing.assert_array_equal(p, w.contacts.p)
            np.testing.assert_array_equal(obj.contacts[w.plane_index], w.contacts.p)


def test_partial_records_hold_the_chords_and_contacts_of_their_wraps():
    from drake_continuum.active.training import partial_records
    from drake_continuum.features.chords import ChordParams, wrap_chords

    objects, records = _records_with_contacts(n_per_class=2, n_wraps=5)
    rows = partial_records(records[:1], sizes=(1, 2, 4), per_size=3, seed=1)
    wraps = objects[0][2]
    assert [int(r.usable.sum()) for r in rows] == [1] * 3 + [2] * 3 + [4] * 3
    assert len({tuple(np.flatnonzero(r.usable)) for r in rows}) == 9  # distinct subsets
    for r in rows:
        kept = [w for w, u in zip(wraps, r.usable) if u]
        np.testing.assert_array_equal(r.contact_points,
                                      np.concatenate([w.contacts.p for w in kept]))
        np.testing.assert_allclose(r.chords.values, np.concatenate(
            [wrap_chords(w, ChordParams()) for w in kept]))
        assert r.object_id == records[0].object_id and r.category == records[0].category


class _ExtentSpy:
    """A classifier that learnt a contact extent block: records the extents it is given."""

    def __init__(self, edges, classes):
        self.edges_, self.classes_ = edges, np.asarray(classes)
        self.extent_mean = np.zeros(5)
        self.seen = []

    def predict_proba_bins(self, flat_indices, *, extents=None, views=None):
        self.seen.extend(np.asarray(extents, float))
        return np.full((len(flat_indices), len(self.classes_)), 1.0 / len(self.classes_))

    def predict_proba(self, X):
        raise AssertionError("the search gives cells")


def test_the_search_gives_the_contact_extent_of_the_wraps_so_far():
    from drake_continuum.features.chords import contact_extent

    rng = np.random.default_rng(3)
    train = [ObjectWraps(o.name, o.label, o.wraps,
                         contacts={p: rng.normal(size=(4 + p, 3)) for p in o.wraps})
             for o in synthetic_objects(n_per_class=3, seed=0)]
    edges = np.tile(np.linspace(0, 1, 8), (7, 1))
    spy = _ExtentSpy(edges, ["a", "b", "c"])
    obs = fit_observation_model(train, spy.classes_, edges, plane_normals=synthetic_planes())
    model = ActiveModel(spy, obs)
    real = rng.normal(size=(6, 3))
    search = TreeSearch(model, ActiveParams(n_simulations=5))
    search.add_wrap(1, train[4].wraps[1], real)
    search.proba()
    np.testing.assert_array_equal(spy.seen[-1], contact_extent(real))
    j = int(np.flatnonzero((obs.obs_object == 2) & (obs.obs_plane == 3))[0])
    search.posterior((j,))
    np.testing.assert_array_equal(spy.seen[-1], contact_extent(
        np.concatenate([real, train[2].contacts[3]])))
    # a recognition on precomputed wraps: after each wrap, the extent of those made
    spy.seen.clear()
    obj = train[7]
    tr = run_policy(model, precomputed_execute(obj), "random", params=ActiveParams(),
                    seed=0, stop_early=False, max_decisions=3)
    made = [contact_extent(np.concatenate([obj.contacts[p] for p in tr.planes[:k]]))
            for k in range(1, len(tr.planes) + 1)]
    assert len(tr.planes) == 3
    for e in made:
        assert any(np.array_equal(e, s) for s in spy.seen)


def test_the_active_model_learns_the_extent_of_some_wraps(tmp_path):
    """train_active keeps the contact extent and learns it from rows of some of each
    object's wraps, whose calibration folds keep an object whole."""
    from drake_continuum.active.training import (
        ACTIVE_EXTENT_WEIGHT,
        PARTIAL_PER_SIZE,
        PARTIAL_SIZES,
        load_active_model,
        save_active_model,
        train_active,
    )
    from drake_continuum.errors import MissingFileError
    from drake_continuum.features.chords import ChordParams
    from drake_continuum.learning.pipeline import ClassifierParams, fit_pipeline
    from drake_continuum.learning.records import load_wraps
    from synthetic_wraps import separable_objects, write_collection

    write_collection(tmp_path / "wraps", separable_objects(6, 4))
    touch = train_active(tmp_path / "wraps", classifier=ClassifierParams().touch_only())
    assert len(touch.classifier.extent_mean) == 5
    # each column standardised, the block weighted ACTIVE_EXTENT_WEIGHT / sqrt(5)
    records = load_wraps(tmp_path / "wraps", ChordParams())
    from drake_continuum.active.training import partial_records
    from drake_continuum.features.chords import contact_extent

    rows = records + partial_records(records)
    values = np.array([contact_extent(r.contact_points) for r in rows])
    np.testing.assert_allclose(touch.classifier.extent_mean, values.mean(axis=0))
    np.testing.assert_allclose(touch.classifier.extent_scale,
                               ACTIVE_EXTENT_WEIGHT / np.sqrt(5) / values.std(axis=0))
    n_rows = 12 * sum(min(PARTIAL_PER_SIZE, math.comb(4, k)) for k in PARTIAL_SIZES if k < 4)
    assert touch.classifier.info["n_objects"] == 12
    assert touch.classifier.info["n_partial_rows"] == n_rows
    save_active_model(touch, tmp_path / "m")
    back = load_active_model(tmp_path / "m")
    assert touch.class_prior is None and back.class_prior is None
    np.testing.assert_array_equal(back.observations.contacts, touch.observations.contacts)
    np.testing.assert_array_equal(back.observations.contact_indptr,
                                  touch.observations.contact_indptr)
    # the folds of a pipeline fitted on whole and partial records of the same objects
    pipe = fit_pipeline(rows, [r.category for r in rows], params=ClassifierParams(
        view_weight=0.0, wrap_weight=0.0))
    folds = pipe["svm"].estimator_.cv
    assert len(folds) == 3
    ids = np.array([r.object_id for r in rows])
    for train_idx, test_idx in folds:
        assert not set(ids[train_idx]) & set(ids[test_idx])
    assert sorted(np.concatenate([t for _, t in folds])) == list(range(len(rows)))
    even = train_active(tmp_path / "wraps", class_prior="uniform")
    n_classes = len(even.observations.classes)
    np.testing.assert_array_equal(even.class_prior, np.full(n_classes, 1 / n_classes))
    save_active_model(even, tmp_path / "f")
    np.testing.assert_array_equal(load_active_model(tmp_path / "f").class_prior,
                                  even.class_prior)
    (tmp_path / "f" / "prior.json").unlink()
    with pytest.raises(MissingFileError, match="retrain"):
        load_active_model(tmp_path / "f")


def test_a_uniform_class_prior_is_bayes_rule_for_a_change_of_prior(problem):
    """Training frequencies 8 : 2 : 2 of three classes and a classifier that learnt them:
    likelihoods L = (0.3, 0.6, 0.1) give it p = pi L / sum = (0.8, 0.4, 0.0667) / 1.2667;
    under a uniform prior the posterior is L / sum L = (0.3, 0.6, 0.1)."""
    model, train, test = problem
    picked = [o for o in train if o.label == "a"] + [o for o in train if o.label != "a"][::4]
    obs = fit_observation_model(picked, model.classifier.classes_, model.classifier.edges_,
                                plane_normals=synthetic_planes(), neighbours=5)
    pi = obs.class_prior
    np.testing.assert_allclose(pi, [8 / 12, 2 / 12, 2 / 12])
    uniform = ActiveModel(model.classifier, obs, np.full(3, 1 / 3))
    likelihood = np.array([0.3, 0.6, 0.1])
    learnt = pi * likelihood / (pi * likelihood).sum()
    np.testing.assert_allclose(uniform.reweighted(learnt[None]), [likelihood], rtol=1e-12)
    np.testing.assert_allclose(ActiveModel(model.classifier, obs).reweighted(learnt), learnt)
    # recognition plans on the classifier's probabilities and stops on them reweighted:
    # the same wraps, and each posterior the classifier's on those wraps divided by pi
    params = ActiveParams(n_simulations=30)
    plain = run_policy(ActiveModel(model.classifier, obs), precomputed_execute(test[0]),
                       params=params, seed=2, stop_early=False)
    even = run_policy(uniform, precomputed_execute(test[0]), params=params, seed=2,
                      stop_early=False)
    assert even.planes == plain.planes and len(even.planes) >= 2
    np.testing.assert_allclose(plain.proba[0], pi)
    np.testing.assert_allclose(even.proba[0], [1 / 3] * 3)
    for k in range(1, len(even.planes) + 1):
        chords = np.concatenate([test[0].wraps[a] for a in even.planes[:k]])
        p = model.classifier.predict_proba([chords])[0] / pi
        np.testing.assert_allclose(even.proba[k], p / p.sum(), rtol=1e-9)
    with pytest.raises(InputError, match="class_prior"):
        ActiveModel(model.classifier, obs, np.array([0.5, 0.5, 0.5]))


def test_train_active_takes_the_scenario_as_collect_and_train_do(tmp_path):
    """train_active(folder, scenario) trains with the scenario's chords, classifier and
    active sections, as the keyword call with those sections does; a keyword replaces one."""
    from drake_continuum.active.training import train_active
    from drake_continuum.features.chords import ChordParams
    from drake_continuum.learning.pipeline import ClassifierParams
    from synthetic_wraps import separable_objects, write_collection

    write_collection(tmp_path / "wraps", separable_objects(6, 3))
    scenario = Config(chords=ChordParams(frame="wrap"),
                      classifier=ClassifierParams().touch_only(),
                      active=ActiveParams(neighbours=3))
    by_scenario = train_active(tmp_path / "wraps", scenario, seed=0)
    by_keyword = train_active(tmp_path / "wraps", params=scenario.active, seed=0,
                              classifier=scenario.classifier, chords=scenario.chords)
    assert by_scenario.classifier.chord_params == ChordParams(frame="wrap")
    assert by_scenario.observations.neighbours == 3
    assert not by_scenario.classifier.uses_view and not by_keyword.classifier.uses_view
    for name in ("edges", "obs_cells", "obs_counts", "pair_from", "pair_to"):
        np.testing.assert_array_equal(getattr(by_scenario.observations, name),
                                      getattr(by_keyword.observations, name))
    replaced = train_active(tmp_path / "wraps", scenario, chords=ChordParams(), seed=0)
    assert replaced.classifier.chord_params == ChordParams()
    assert replaced.observations.neighbours == 3
    with pytest.raises(InputError, match="frame"):
        train_active(tmp_path / "wraps", scenario, frame="wrap")


class _CellsOnly:
    """A ChordModel that is given each set's cells, not its wraps' cell counts."""

    def __init__(self, classifier):
        self.classifier = classifier

    def __getattr__(self, name):
        if name == "takes_cell_counts":
            raise AttributeError(name)
        return getattr(self.classifier, name)


def test_the_search_sums_wraps_cell_counts_as_the_cells_together_to_the_bit(tmp_path):
    """A ChordModel takes each wrap's CellCounts and the wraps' contact bounds: every
    choice, probability and cost equals that of the sets' cells and points given whole."""
    from drake_continuum.active.training import object_wraps_from_records, train_active
    from drake_continuum.features.chords import ChordParams
    from drake_continuum.learning.records import load_wraps
    from synthetic_wraps import separable_objects, write_collection

    write_collection(tmp_path / "wraps", separable_objects(5, 4))
    records = load_wraps(tmp_path / "wraps", ChordParams())
    assert [r.category for r in records] == ["circle", "square"] * 5
    model = train_active(tmp_path / "wraps", records=records, train_index=range(6))
    assert model.classifier.takes_cell_counts and len(model.classifier.extent_mean) == 5
    whole = ActiveModel(_CellsOnly(model.classifier), model.observations)
    params = ActiveParams(n_simulations=40)
    for obj in object_wraps_from_records(records[6:]):
        for policy in ("mcts", "greedy"):
            runs = [run_policy(m, precomputed_execute(obj), policy, params=params, seed=3,
                               available=sorted(obj.wraps), stop_early=False)
                    for m in (model, whole)]
            assert runs[0].planes == runs[1].planes and runs[0].cost == runs[1].cost
            np.testing.assert_array_equal(runs[0].proba, runs[1].proba)
