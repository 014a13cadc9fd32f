"""Exact against camera-observed wraps of a collection (experiments/observed.py): the mesh is
posed where the wraps saw it, each condition gives a record, and the evaluation runs."""

import re
import shutil

import numpy as np
import pytest
import trimesh

from drake_continuum.errors import InputError
from drake_continuum.experiments import observed
from drake_continuum.experiments.collect import collect
from drake_continuum.experiments.observed import (
    CONDITIONS,
    collection_scene,
    condition_records,
    evaluate_held_out,
    evaluate_observed,
    observe_object,
    observed_markdown,
)
from drake_continuum.objects.dataset import generate_dataset
from synthetic_wraps import fixed_planes


@pytest.fixture(scope="module")
def collection(tmp_path_factory):
    root = tmp_path_factory.mktemp("objects")
    generate_dataset(root, counts={"apple": 4, "cup": 4}, workers=1, progress=False)
    out = tmp_path_factory.mktemp("wraps") / "wraps"
    report = collect(root, out, fixed_planes(), workers=1, ids=["cup_000"], planes=[0],
                     progress=False)
    assert not report.failed
    return root, out


@pytest.fixture(scope="module")
def seen_cup(collection, tmp_path_factory):
    """cup_000 observed (camera seed 3) into a cache folder: (the result, the cache)."""
    cache = tmp_path_factory.mktemp("observed")
    return observe_object(collection[1], "cup_000", seed=3, cache=cache), cache


def test_the_mesh_is_posed_where_the_wraps_touched_it(collection):
    _, wraps, _, mesh = collection_scene(collection[1], "cup_000")
    p = np.concatenate([w.contacts.p for w in wraps if w.usable])
    assert len(p)
    gap = np.abs(trimesh.proximity.signed_distance(mesh, p))
    assert gap.max() < 0.002


def test_each_condition_gives_a_record_and_the_fits_figures(collection, seen_cup, monkeypatch):
    seen, cache = seen_cup
    assert set(seen["records"]) == set(CONDITIONS)
    assert np.isnan(seen["records"]["transparent"].view).all()
    assert not np.isnan(seen["records"]["one_view"].view).any()
    for name in ("one_view", "two_views", "transparent"):
        (fit,) = seen["fits"][name]  # one plane, one wrap
        assert fit["found"] and fit["tip_error_m"] < 0.005 and fit["cpu_s"] > 0
    # A second look reads the cache: nothing is observed, the records are the same.
    monkeypatch.setattr(observed, "_observe_conditions", _no_observing)
    again = observe_object(collection[1], "cup_000", seed=3, cache=cache)
    for name, record in seen["records"].items():
        np.testing.assert_allclose(again["records"][name].chords.values, record.chords.values,
                                   atol=1e-9)
        np.testing.assert_allclose(again["records"][name].descriptors, record.descriptors,
                                   atol=1e-9)
    assert again["fits"] == seen["fits"]
    with pytest.raises(AssertionError, match="observed again"):  # another seed: observed
        observe_object(collection[1], "cup_000", seed=4, cache=cache)


def test_a_damaged_cache_file_is_named(collection, seen_cup, tmp_path):
    """Seen: a cached .npz cut short or damaged inside gave a zipfile traceback."""
    cache = tmp_path / "cache"
    shutil.copytree(seen_cup[1], cache)
    npz = cache / "cup_000.npz"
    good = npz.read_bytes()
    middle = len(good) // 2
    flipped = good[:middle] + bytes([good[middle] ^ 0xFF]) + good[middle + 1:]
    for damaged in (good[:middle], flipped):
        npz.write_bytes(damaged)
        with pytest.raises(InputError, match=rf"^{re.escape(str(npz))}: unreadable observation "
                                             rf"cache \((BadZipFile|error): "):
            observe_object(collection[1], "cup_000", seed=3, cache=cache)


def _no_observing(*args):
    raise AssertionError("observed again")


def _scaled(w, f):
    from dataclasses import replace
    return replace(w, samples_position=f * w.samples_position,
                   contacts=replace(w.contacts, p=f * w.contacts.p))


def test_held_out_evaluation_and_the_table(seen_cup):
    records = seen_cup[0]
    # Another category: the same wraps twice the size (every chord twice as long).
    other = {**records, "category": "apple", "object_id": "apple_x",
             "wraps": {k: [_scaled(w, 2.0) for w in ws] for k, ws in records["wraps"].items()}}
    other["records"] = condition_records(other)
    objects = [records, other] * 3
    out = evaluate_held_out(objects[:4], objects[4:])
    assert out["n_train"] == 4 and out["n_test"] == 2
    for row in out["conditions"].values():  # the same records trained and tested: all right
        assert row["accuracy_mean"] == 1.0
    table = observed_markdown(out)
    assert "| fitted, one camera view | 100" in table and "n/a" in table


@pytest.mark.slow
def test_the_evaluation_reports_every_condition(collection):
    root, out = collection
    assert not collect(root, out, fixed_planes(), workers=1, planes=[0], progress=False).failed
    objects = [observe_object(out, oid, seed=k)
               for k, oid in enumerate([f"{c}_00{i}" for c in ("apple", "cup") for i in range(4)])]
    out = evaluate_observed(objects, n_splits=2)
    assert set(out["conditions"]) == {*CONDITIONS, "exact_touch_only"}
    for row in out["conditions"].values():
        assert 0.0 <= row["accuracy_mean"] <= 1.0
    assert out["conditions"]["one_view"]["found_fraction"] == 1.0


def test_objects_observed_on_workers_are_those_observed_in_one_process(collection, tmp_path,
                                                                       monkeypatch):
    root, out = collection
    assert not collect(root, out, fixed_planes(), workers=1, ids=["apple_000"], planes=[0],
                       progress=False).failed
    ids = ["apple_000", "cup_000"]
    one = observed.observed_records(out, ids, seed=3, workers=1)
    two = observed.observed_records(out, ids, seed=3, workers=2, cache=tmp_path)
    assert [o["object_id"] for o in two] == ids
    for a, b in zip(one, two):
        for name, wraps in a["wraps"].items():
            for w, v in zip(wraps, b["wraps"][name], strict=True):
                np.testing.assert_array_equal(w.final_config.as_vector(),
                                              v.final_config.as_vector())
            np.testing.assert_array_equal(a["records"][name].chords.values,
                                          b["records"][name].chords.values)
        assert [{**f, "cpu_s": 0} for fits in a["fits"].values() for f in fits] == \
            [{**f, "cpu_s": 0} for fits in b["fits"].values() for f in fits]
    # Held by the cache: read in this process, no worker started.
    monkeypatch.setattr(observed, "_observe_conditions", _no_observing)
    monkeypatch.setattr("drake_continuum.workers.local_pool", _no_observing)
    again = observed.observed_records(out, ids, seed=3, workers=2, cache=tmp_path)
    assert [o["fits"] for o in again] == [o["fits"] for o in two]


def test_objects_go_to_the_callers_pool_which_stays_open(collection, monkeypatch):
    """With `pool` (reproduce's run pool) an uncached object is submitted to it, even when
    one worker would do, and the pool is left running for the caller; no pool of its own
    is started."""
    from concurrent.futures import Executor, Future

    class Recording(Executor):
        def __init__(self):
            self.submitted, self.closed = [], False

        def submit(self, fn, /, *args, **kwargs):
            self.submitted.append(kwargs["object_id"])
            done = Future()
            done.set_result(fn(*args, **kwargs))
            return done

        def shutdown(self, wait=True, **kwargs):
            self.closed = True

    _, out = collection
    monkeypatch.setattr(observed, "observe_object", lambda **task: {"id": task["object_id"]})
    monkeypatch.setattr("drake_continuum.workers.local_pool", _no_observing)
    pool = Recording()
    got = observed.observed_records(out, ["cup_000"], seed=3, pool=pool)
    assert pool.submitted == ["cup_000"] and not pool.closed
    assert got == [{"id": "cup_000"}]
    # Queued before they are asked for (reproduce, as collect ends): taken, not queued again,
    # and the same records; a queue made for other objects is refused.
    timing = {}
    queued = observed.submit_observations(pool, out, ["cup_000"], seed=3)
    assert pool.submitted == ["cup_000"] * 2
    again = observed.observed_records(out, ["cup_000"], seed=3, submitted=queued,
                                      timing=timing)
    assert again == got and pool.submitted == ["cup_000"] * 2
    assert timing["observing_s"] >= 0
    with pytest.raises(ValueError, match="not those of these objects"):
        observed.observed_records(out, ["cup_000"], seed=4, submitted=queued)


def test_the_study_trains_on_the_whole_collection_and_tests_the_seen_objects(collection,
                                                                              tmp_path,
                                                                              monkeypatch):
    """observed_study's splits run over the whole collection (as Table I's), and each
    split tests the seen objects of its test half only: as many tests as the same splits
    put seen objects in their test halves."""
    from drake_continuum.learning.evaluation import splits

    root, out = collection
    ids = [f"{c}_00{i}" for c in ("apple", "cup") for i in range(4)]
    assert not collect(root, out, fixed_planes(), workers=1, ids=ids, planes=[0],
                       progress=False).failed

    def seen_as_exact(folder, object_ids, **options):  # the camera left out: exact wraps
        objects = [observed.exact_object(folder, oid) for oid in object_ids]
        for o in objects:
            o["records"] = {name: o["records"]["exact"] for name in CONDITIONS}
            o["fits"] = {name: [] for name in CONDITIONS}
        return objects

    monkeypatch.setattr(observed, "observed_records", seen_as_exact)
    monkeypatch.setattr(observed, "active_observed", lambda *args, **kwargs: {})
    result = observed.observed_study(out, tmp_path / "study", per_category=1, n_splits=5)
    assert (result["n_objects"], result["n_collection"]) == (2, 8)
    labels = ["apple", "cup"] + ["apple"] * 3 + ["cup"] * 3  # seen first, then the rest
    expected = sum(int(np.sum(test < 2)) for _, test in splits(labels, n_splits=5, seed=0))
    tested = sum(n for row in result["confusion_one_view"].values() for n in row.values())
    assert tested == expected < 5 * 4  # not every test-half object


def test_a_uniform_prior_reweights_by_the_training_frequencies(monkeypatch):
    """Bayes' rule for a change of prior, by hand: a model that answers apple 0.6 / cup 0.4,
    trained on 3 apples and 1 cup, answers cup under a uniform prior (0.6 / 0.75 < 0.4 /
    0.25) and apple as learnt."""
    class Fixed:
        classes_ = np.array(["apple", "cup"])

        def predict_proba(self, records):
            return np.tile([0.6, 0.4], (len(records), 1))

    monkeypatch.setattr(observed, "_split_models",
                        lambda objects, train_idx, tests, *rest: {n: Fixed() for n in tests})

    def made(category):
        return {"category": category, "records": {n: {} for n in CONDITIONS},
                "fits": {n: [] for n in CONDITIONS}}

    train, test = [made("apple")] * 3 + [made("cup")], [made("cup")]
    for prior, right in (("uniform", 1.0), ("training", 0.0)):
        out = evaluate_held_out(train, test, class_prior=prior)
        assert out["class_prior"] == prior
        assert {row["accuracy_mean"] for row in out["conditions"].values()} == {right}
    with pytest.raises(Exception, match="class_prior must be one of"):
        evaluate_held_out(train, test, class_prior="even")
