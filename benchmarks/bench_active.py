"""Active recognition benchmark: time of one tree search, and MCTS vs greedy vs random.

On a synthetic problem the size of the paper's (10 categories, ~92 training objects, the 10
planes of alpha = 22.5 deg, 200 chords a wrap) with the real classifier (learning.model.train), or
on a wrap collection given with --wraps. Prints JSON.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from drake_continuum.active.params import ActiveParams
from drake_continuum.active.policies import POLICIES, build_active_model, evaluate_policies
from drake_continuum.active.search import TreeSearch
from drake_continuum.active.training import evaluate_active
from drake_continuum.config import load_config
from drake_continuum.features.chords import ChordSet
from drake_continuum.files import json_text
from drake_continuum.learning.model import train
from drake_continuum.learning.records import ObjectRecord
from synthetic_active import paper_plane_normals, synthetic_objects

CLASSES = tuple(f"c{k}" for k in range(10))
SIGNAL = {1: 0.3, 9: 0.8}   # 22.5 deg about x: weak; 90 deg about y: strong


def _record(obj) -> ObjectRecord:
    planes = sorted(obj.wraps)
    values = np.concatenate([obj.wraps[p] for p in planes])
    wrap = np.repeat(np.arange(len(planes)), [len(obj.wraps[p]) for p in planes])
    return ObjectRecord(obj.name, obj.label, ChordSet(values, wrap), np.zeros((0, 3)),
                        np.array(planes), np.ones(len(planes), bool))


def synthetic_model(params: ActiveParams, seed: int):
    kw = dict(classes=CLASSES, n_chords=200, signal=SIGNAL, n_planes=10)
    train_objects = synthetic_objects(n_per_class=9, seed=seed, **kw)
    test_objects = synthetic_objects(n_per_class=3, seed=seed + 1, **kw)
    t0 = time.perf_counter()
    clf = train([_record(o) for o in train_objects], seed=seed)
    model = build_active_model(clf, train_objects, paper_plane_normals(), params=params)
    model.observations.training_successors
    return model, test_objects, time.perf_counter() - t0


def time_searches(model, test_objects, params: ActiveParams, repeats: int) -> dict:
    """Median time of one search (default simulations) from 0, 1 and 2 real wraps."""
    times, calls = [], []
    for k in range(repeats):
        obj = test_objects[k % len(test_objects)]
        search = TreeSearch(model, params, rng=np.random.default_rng(k))
        for plane in sorted(obj.wraps)[:k % 3]:
            search.add_wrap(plane, obj.wraps[plane])
        res = search.search()
        times.append(res.time_s)
        calls.append(res.classifier_calls)
    return {"n_simulations": params.n_simulations, "horizon": params.horizon,
            "repeats": repeats, "median_s": statistics.median(times), "max_s": max(times),
            "median_classifier_calls": statistics.median(calls)}


def summarise(results: dict) -> dict:
    keys = ("accuracy_at_stop", "wraps_to_stop", "movement_cost_to_stop_rad", "strong_fraction")
    return {p: {k: round(r[k], 4) for k in keys} for p, r in results.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--wraps", default=None,
                        help="wrap collection to evaluate instead of the synthetic problem "
                             "(default: none)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--repeats", type=int, default=9, help="timed searches (default: 9)")
    parser.add_argument("--quick", action="store_true",
                        help="fewer held-out objects and simulations, for a smoke test")
    args = parser.parse_args(argv)
    params = load_config().active
    out = {"benchmark": "active", "params": params.__dict__}
    if args.wraps:
        report = evaluate_active(args.wraps, params=params, seed=args.seed)
        out["dataset"] = args.wraps
        out["policies"] = summarise(report["policies"])
        out["median_search_time_s"] = report["policies"]["mcts"]["median_search_time_s"]
    else:
        model, test_objects, t_fit = synthetic_model(params, args.seed)
        out["dataset"] = {"synthetic": True, "classes": len(CLASSES), "planes": 10,
                          "train_objects": len(model.observations.object_names),
                          "test_objects": len(test_objects), "chords_a_wrap": 200,
                          "signal": SIGNAL, "fit_s": round(t_fit, 3)}
        out["search"] = time_searches(model, test_objects, params, args.repeats)
        eval_params = load_config().active
        if args.quick:
            test_objects = test_objects[::5]
        t0 = time.perf_counter()
        out["policies"] = summarise(evaluate_policies(model, test_objects, policies=POLICIES,
                                                      params=eval_params, seed=args.seed))
        out["evaluation_s"] = round(time.perf_counter() - t0, 2)
    print(json_text(out))
    sys.stdout.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
