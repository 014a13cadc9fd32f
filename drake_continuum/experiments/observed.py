"""Accuracy when the arm's shape is measured by the camera rather than known.

Trained on the exact wraps of a collection, the classifier is tested by object on the same
held-out objects four ways: (a) the exact configurations; (b) each wrap's configuration
fitted from one simulated depth camera view (perception.observe); (c) from two views on
opposite sides; (d) the object transparent: left out of the depth image, and classified by
the touch-only model (ClassifierParams.touch_only, no camera view of the object), which is
also reported on exact configurations to separate what the view is worth from what the fit
costs. Each held-out object's wraps are observed once (the split does not change what the
camera sees) and every split tests the observations of its held-out half.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..learning.evaluation import splits
from ..learning.pipeline import ClassifierParams
from ..learning.records import object_record, read_object_wraps, recorded_side, recorded_view
from ..perception.observe import observe_wraps

__all__ = ["CONDITIONS", "collection_scene", "observe_object", "observed_records",
           "evaluate_observed"]

# name: observe_wrap's options (None: the exact configuration)
CONDITIONS = {"exact": None, "one_view": {"views": 1}, "two_views": {"views": 2},
              "transparent": {"views": 1, "transparent": True}}


def collection_scene(folder, object_id: str, dataset=None):
    """(meta, wraps, arm, mesh) of one object of a collection: the arm it was wrapped with
    and its mesh where the wraps saw it (moved by the recorded centre, turned by the
    recorded bearing, as collect wrapped it)."""
    import yaml

    from ..kinematics.arm import ContinuumArm, load_arm
    from ..objects.mesh import load_mesh
    from ..objects.placement import arm_frame
    from .collect import wrapped_mesh_path

    meta, wraps = read_object_wraps(folder, object_id)
    arm_yaml = (meta.get("params") or {}).get("arm_yaml")
    arm = load_arm() if arm_yaml is None else ContinuumArm.from_dict(yaml.safe_load(arm_yaml))
    mesh = load_mesh(wrapped_mesh_path(folder, object_id, meta, dataset))
    centre = meta.get("centre") or (0.0, 0.0)
    turn = math.radians(float((meta.get("bearing") or {}).get("turn_deg", 0.0)))
    if turn or any(centre):
        mesh = arm_frame(mesh, centre, turn)
    return meta, wraps, arm, mesh


def observe_object(folder, object_id: str, *, seed: int = 0, chords=None,
                   dataset=None) -> dict:
    """Each condition's ObjectRecord of one object, and per fitted wrap its CPU time, tip
    error against the exact configuration (m) and whether the fit was confident."""
    from ..features.chords import ChordParams

    chords = chords or ChordParams()
    meta, wraps, arm, mesh = collection_scene(folder, object_id, dataset)
    oid, category = str(meta.get("object_id", object_id)), str(meta["category"])
    side = recorded_side(oid, meta)
    view = recorded_view(meta.get("view"), f"{Path(folder) / object_id}.json")
    out = {"object_id": oid, "category": category, "records": {}, "fits": {}}
    for name, options in CONDITIONS.items():
        if options is None:
            seen_wraps, fits = wraps, []
        else:
            seen = observe_wraps(wraps, arm, mesh, seed=seed, **options)
            seen_wraps = [o.wrap for o in seen]
            fits = [_fit_row(arm, w, o) for w, o in zip(wraps, seen) if w.usable]
        transparent = bool(options and options.get("transparent"))
        out["records"][name] = object_record(oid, category, seen_wraps, chords, side,
                                             None if transparent else view)
        out["fits"][name] = fits
    return out


def _fit_row(arm, exact, seen) -> dict:
    """One fitted wrap's figures (an unfound arm: tip error None)."""
    row = {"cpu_s": seen.cpu_s, "found": "error" not in seen.flags,
           "confident": bool(seen.flags.get("confident", False)), "tip_error_m": None}
    if row["found"]:
        wrap_arm = exact.arm(arm)
        row["tip_error_m"] = float(np.linalg.norm(
            wrap_arm.tip_frame(seen.wrap.final_config)[1]
            - wrap_arm.tip_frame(exact.final_config)[1]))
    return row


def observed_records(folder, object_ids, *, seed: int = 0, chords=None, dataset=None,
                     progress=None) -> list[dict]:
    """observe_object of each object; object k's camera noise is seeded seed + 10000 k."""
    out = []
    for k, oid in enumerate(object_ids):
        out.append(observe_object(folder, oid, seed=seed + 10000 * k, chords=chords,
                                  dataset=dataset))
        if progress is not None:
            progress(k + 1, len(object_ids), oid)
    return out


def evaluate_observed(objects: list[dict], n_splits: int = 10, seed: int = 0,
                      classifier: ClassifierParams = ClassifierParams(), chords=None) -> dict:
    """Accuracy of each condition over random stratified 50/50 splits by object, trained on
    the training half's exact wraps (the recommended model, and the touch-only one for the
    transparent condition and `exact_touch_only`); with the fits' figures a condition."""
    from ..learning.model import train

    labels = [o["category"] for o in objects]
    touch = classifier.touch_only()
    tests = {name: (name == "transparent") for name in CONDITIONS}
    tests["exact_touch_only"] = True
    correct = {name: [] for name in tests}
    confusion = {}
    for train_idx, test_idx in splits(labels, n_splits, seed):
        exact = [objects[i]["records"]["exact"] for i in train_idx]
        models = {False: train(exact, seed, chords, classifier),
                  True: train(exact, seed, chords, touch)}
        for name, touch_only in tests.items():
            source = "exact" if name == "exact_touch_only" else name
            records = [objects[i]["records"][source] for i in test_idx]
            model = models[touch_only]
            predicted = model.classes_[np.argmax(model.predict_proba(records), axis=1)]
            truth = [labels[i] for i in test_idx]
            correct[name].append(float(np.mean(predicted == np.asarray(truth))))
            if name == "one_view":
                for t, p in zip(truth, predicted):
                    confusion.setdefault(t, {}).setdefault(str(p), 0)
                    confusion[t][str(p)] += 1
    out = {"n_objects": len(objects), "n_splits": n_splits, "seed": seed, "conditions": {}}
    for name, accs in correct.items():
        source = "exact" if name == "exact_touch_only" else name
        fits = [f for o in objects for f in o["fits"][source]]
        found = [f for f in fits if f["found"]]
        tip = np.array([f["tip_error_m"] for f in found])
        row = {"accuracy_mean": float(np.mean(accs)), "accuracy_std": float(np.std(accs)),
               "touch_only_model": tests[name]}
        if fits:
            row.update(n_wraps=len(fits), found_fraction=len(found) / len(fits),
                       confident_fraction=float(np.mean([f["confident"] for f in fits])),
                       cpu_s_median=float(np.median([f["cpu_s"] for f in fits])),
                       tip_error_mm_median=1e3 * float(np.median(tip)) if len(tip) else None,
                       tip_error_mm_p90=1e3 * float(np.percentile(tip, 90)) if len(tip)
                       else None)
        out["conditions"][name] = row
    out["confusion_one_view"] = confusion
    return out
