"""Recognition from what the camera sees of the arm: trained on exact wraps, tested by object
on (a) exact configurations, (b) configurations fitted from one depth camera view, (c) two
views, (d) the object transparent (touch-only model); with the CPU time a fitted wrap costs
and its tip error (experiments/observed.py). Prints JSON.

Observations are cached a file an object beside the collection (<wraps>.observed), so a rerun
with other chord or classifier settings costs seconds. With --test another collection (another
dataset seed) is tested on, trained on every chosen object of the first; --active adds active
recognition at the stop rule. With --whole-collection each split trains on the exact wraps of
its whole training half of the collection and tests its observed objects, as reproduce's camera
study does (experiments.observed.observed_study, without its active part).

Example (a collection of `collect --limit-per-category 4`):
    python benchmarks/bench_observe.py data/wraps --per-category 4 --splits 10 --camera-seed 7
Reproduce's camera study (its settings: chord frame plane, camera seed = reproduce's seed):
    python benchmarks/bench_observe.py results/wraps --per-category 4 --splits 100 \
        --frame plane --camera-seed 0 --whole-collection
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from drake_continuum.active.training import CLASS_PRIORS
from drake_continuum.config import ObservedParams
from drake_continuum.experiments.observed import (
    CONDITIONS,
    TRAIN_ON,
    active_observed,
    evaluate_held_out,
    evaluate_observed,
    exact_object,
    observed_records,
)
from drake_continuum.features.chords import FRAMES, ChordParams
from drake_continuum.files import json_text, write_json
from drake_continuum.learning.params import ClassifierParams


def _chosen(folder: Path, per_category: int) -> list[str]:
    """The first `per_category` objects of each category in the collection's index."""
    index = json.loads((folder / "index.json").read_text())
    chosen, count = [], {}
    for entry in index["objects"]:
        oid, cat = entry["object_id"], entry["category"]
        if count.get(cat, 0) < per_category:
            chosen.append(oid)
            count[cat] = count.get(cat, 0) + 1
    return chosen


def _rest(folder: Path, chosen: list[str]) -> list[str]:
    """The collection's objects not chosen, in its index's order."""
    index = json.loads((folder / "index.json").read_text())
    return [str(e["object_id"]) for e in index["objects"] if str(e["object_id"]) not in chosen]


def _observed(folder: Path, per_category: int, args, chords) -> list[dict]:
    cache = None if args.no_cache else Path(args.cache or folder.parent / f"{folder.name}.observed")
    return observed_records(
        folder, _chosen(folder, per_category), seed=args.camera_seed, dataset=args.dataset,
        cache=cache, chords=chords, workers=args.workers,
        progress=lambda k, n, oid: print(f"{k}/{n} {oid}", file=sys.stderr, flush=True))


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("wraps", help="wrap collection folder (drake-continuum collect)")
    parser.add_argument("--per-category", type=int, default=4,
                        help="objects a category observed and evaluated (default 4)")
    parser.add_argument("--splits", type=int, default=10, help="random splits (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the splits (default 0)")
    parser.add_argument("--camera-seed", type=int, default=0,
                        help="seed of the depth camera's noise (default 0)")
    parser.add_argument("--dataset", default=None,
                        help="dataset folder of the meshes (default: the collection's)")
    parser.add_argument("--frame", default="world", choices=FRAMES,
                        help="frame of the chord angles (ChordParams.frame; default world)")
    parser.add_argument("--train-on", default="exact", choices=TRAIN_ON,
                        help="train on the exact wraps, or each condition on the training "
                             "objects' wraps observed the same way (default exact)")
    parser.add_argument("--test", default=None,
                        help="another collection (another dataset seed) to test on instead "
                             "of splits: trained on every chosen object of WRAPS "
                             "(default: 50/50 splits of WRAPS)")
    parser.add_argument("--test-per-category", type=int, default=2,
                        help="objects a category of --test (default 2)")
    parser.add_argument("--active", action="store_true",
                        help="also active recognition at the stop rule (with --test)")
    parser.add_argument("--cache", default=None,
                        help="folder of the observed wraps, one file an object, reused by a "
                             "rerun with the same camera seed (default: <wraps>.observed "
                             "beside the collection; with --test, beside each)")
    parser.add_argument("--no-cache", action="store_true", help="observe every wrap again")
    parser.add_argument("--no-plane", action="store_true",
                        help="fit without the wrap's plane (observe_wrap's plane_known False; "
                             "cached apart)")
    parser.add_argument("--workers", type=int, default=1,
                        help="processes observing the objects the cache does not hold "
                             "(default 1)")
    parser.add_argument("--tie-width", type=float, default=ObservedParams().tie_width,
                        help="the classifiers' classifier.tie_width, m or rad (default: "
                             "the config's observed.tie_width, reproduce's camera study's)")
    parser.add_argument("--class-prior", default="uniform", choices=CLASS_PRIORS,
                        help="the category prior classification and active recognition "
                             "answer under (train_active's class_prior; default uniform: the "
                             "objects tested come N a category)")
    parser.add_argument("--whole-collection", action="store_true",
                        help="train each split on its whole training half of the collection "
                             "(exact wraps) and test its observed objects, as reproduce's "
                             "camera study (default: the chosen objects alone)")
    parser.add_argument("--out", default=None, help="also write the JSON here")
    args = parser.parse_args(argv)
    classifier = ClassifierParams(tie_width=args.tie_width)
    folder = Path(args.wraps)
    chords = ChordParams(frame=args.frame)
    if args.no_plane:  # the cache key holds the conditions' options: cached apart
        for options in CONDITIONS.values():
            if options is not None:
                options["plane_known"] = False
    t0 = time.perf_counter()
    if args.test and args.train_on == "exact":  # trained on exact wraps: nothing to observe
        objects = [exact_object(folder, oid, chords) for oid in _chosen(folder, args.per_category)]
    else:
        objects = _observed(folder, args.per_category, args, chords)
    if args.test:
        args.cache = None
        test = _observed(Path(args.test), args.test_per_category, args, chords)
        out = evaluate_held_out(objects, test, args.seed, classifier, chords=chords,
                                train_on=args.train_on, class_prior=args.class_prior)
        if args.active:
            out["active"] = active_observed(folder, objects, test, seed=args.seed, chords=chords,
                                            classifier=classifier,
                                            class_prior=args.class_prior)
    elif args.whole_collection:
        seen = len(objects)
        objects += [exact_object(folder, oid, chords)
                    for oid in _rest(folder, _chosen(folder, args.per_category))]
        out = evaluate_observed(objects, args.splits, args.seed, classifier, chords=chords,
                                train_on=args.train_on, observed=seen,
                                class_prior=args.class_prior)
    else:
        out = evaluate_observed(objects, args.splits, args.seed, classifier, chords=chords,
                                train_on=args.train_on, class_prior=args.class_prior)
    out.update(collection=str(folder), test=args.test, camera_seed=args.camera_seed,
               tie_width=args.tie_width, class_prior=args.class_prior,
               frame=args.frame, per_category=args.per_category,
               whole_collection=args.whole_collection,
               wall_s=round(time.perf_counter() - t0, 1), paper_accuracy=0.759)
    if args.out:
        write_json(Path(args.out), out)
    print(json_text(out))
    return out


if __name__ == "__main__":
    main()
