"""Recognition from what the camera sees of the arm: trained on exact wraps, tested by object
on (a) exact configurations, (b) configurations fitted from one depth camera view, (c) two
views, (d) the object transparent (touch-only model); with the CPU time a fitted wrap costs
and its tip error (experiments/observed.py). Prints JSON.

Example (a collection of `collect --limit-per-category 4`):
    python benchmarks/bench_observe.py data/wraps --per-category 4 --splits 10 --camera-seed 7
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from drake_continuum.experiments.observed import evaluate_observed, observed_records
from drake_continuum.files import json_text, write_json


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
    parser.add_argument("--cache", default=None,
                        help="folder of the observed wraps, one file an object, reused by a "
                             "rerun with the same camera seed (default: <wraps>.observed "
                             "beside the collection)")
    parser.add_argument("--no-cache", action="store_true", help="observe every wrap again")
    parser.add_argument("--out", default=None, help="also write the JSON here")
    args = parser.parse_args(argv)
    folder = Path(args.wraps)
    index = json.loads((folder / "index.json").read_text())
    chosen, count = [], {}
    for entry in index["objects"]:
        oid, cat = entry["object_id"], entry["category"]
        if count.get(cat, 0) < args.per_category:
            chosen.append(oid)
            count[cat] = count.get(cat, 0) + 1
    cache = None if args.no_cache else Path(args.cache or folder.parent / f"{folder.name}.observed")
    t0 = time.perf_counter()
    objects = observed_records(
        folder, chosen, seed=args.camera_seed, dataset=args.dataset, cache=cache,
        progress=lambda k, n, oid: print(f"{k}/{n} {oid}", file=sys.stderr, flush=True))
    t_observe = time.perf_counter() - t0
    out = evaluate_observed(objects, args.splits, args.seed)
    out.update(collection=str(folder), camera_seed=args.camera_seed,
               per_category=args.per_category, observe_wall_s=round(t_observe, 1),
               paper_accuracy=0.759)
    if args.out:
        write_json(Path(args.out), out)
    print(json_text(out))
    return out


if __name__ == "__main__":
    main()
