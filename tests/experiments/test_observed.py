"""Exact against camera-observed wraps of a collection (experiments/observed.py): the mesh is
posed where the wraps saw it, each condition gives a record, and the evaluation runs."""

import numpy as np
import pytest
import trimesh

from drake_continuum.experiments.collect import collect
from drake_continuum.experiments.observed import (
    CONDITIONS,
    collection_scene,
    evaluate_observed,
    observe_object,
)
from drake_continuum.objects.dataset import generate_dataset


@pytest.fixture(scope="module")
def collection(tmp_path_factory):
    root = tmp_path_factory.mktemp("objects")
    generate_dataset(root, counts={"apple": 4, "cup": 4}, workers=1, progress=False)
    out = tmp_path_factory.mktemp("wraps") / "wraps"
    report = collect(root, out, workers=1, ids=["cup_000"], planes=[0], progress=False)
    assert not report.failed
    return root, out


def test_the_mesh_is_posed_where_the_wraps_touched_it(collection):
    _, wraps, _, mesh = collection_scene(collection[1], "cup_000")
    p = np.concatenate([w.contacts.p for w in wraps if w.usable])
    assert len(p)
    gap = np.abs(trimesh.proximity.signed_distance(mesh, p))
    assert gap.max() < 0.002


def test_each_condition_gives_a_record_and_the_fits_figures(collection):
    seen = observe_object(collection[1], "cup_000", seed=3)
    assert set(seen["records"]) == set(CONDITIONS)
    assert np.isnan(seen["records"]["transparent"].view).all()
    assert not np.isnan(seen["records"]["one_view"].view).any()
    for name in ("one_view", "two_views", "transparent"):
        (fit,) = seen["fits"][name]  # one plane, one wrap
        assert fit["found"] and fit["tip_error_m"] < 0.005 and fit["cpu_s"] > 0


@pytest.mark.slow
def test_the_evaluation_reports_every_condition(collection):
    root, out = collection
    assert not collect(root, out, workers=1, planes=[0], progress=False).failed
    objects = [observe_object(out, oid, seed=k)
               for k, oid in enumerate([f"{c}_00{i}" for c in ("apple", "cup") for i in range(4)])]
    out = evaluate_observed(objects, n_splits=2)
    assert set(out["conditions"]) == {*CONDITIONS, "exact_touch_only"}
    for row in out["conditions"].values():
        assert 0.0 <= row["accuracy_mean"] <= 1.0
    assert out["conditions"]["one_view"]["found_fraction"] == 1.0
