"""Time and peak memory of the paper's evaluation (100 random 50/50 splits) on a synthetic
dataset of the paper's size: 185 objects in 10 categories (the paper's counts), about 2,000
chords an object, and the triangle baseline on the same splits. Prints JSON."""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from drake_continuum.features.chords import ChordSet  # noqa: E402
from drake_continuum.files import json_text  # noqa: E402
from drake_continuum.learning.evaluation import evaluate  # noqa: E402
from drake_continuum.learning.records import ObjectRecord, object_record  # noqa: E402
from synthetic_wraps import object_wraps, shape_contour  # noqa: E402

# category: (count, contour kind, size m, aspect): shapes loosely like the paper's classes.
CATEGORIES = {"apple": (12, "circle", 0.04, 1.0), "banana": (6, "ellipse", 0.09, 0.2),
              "bottle": (51, "square", 0.07, 3.5), "bowl": (21, "ellipse", 0.07, 0.45),
              "cup": (10, "square", 0.08, 1.2), "donut": (10, "ellipse", 0.06, 0.3),
              "hammer": (28, "square", 0.03, 8.0), "mug": (32, "square", 0.09, 1.1),
              "teapot": (6, "ellipse", 0.08, 0.8), "toilet_paper": (9, "circle", 0.055, 1.0)}


def make_objects(chords_per_object: int = 2000, seed: int = 0):
    """Synthetic ObjectRecords; chords subsampled to chords_per_object where there are more."""
    rng = np.random.default_rng(seed)
    objects = []
    for cat, (count, kind, size, aspect) in CATEGORIES.items():
        for i in range(count):
            contour = shape_contour(kind, size * rng.uniform(0.8, 1.2),
                                    aspect * rng.uniform(0.85, 1.15))
            rec = object_record(f"{cat}_{i:02d}", cat, object_wraps(contour, 10, rng, 5e-4))
            c = rec.chords
            if len(c) > chords_per_object:
                keep = np.sort(rng.choice(len(c), chords_per_object, replace=False))
                rec = rec.__class__(**{**rec.__dict__,
                                       "chords": ChordSet(c.values[keep], c.wrap[keep])})
            objects.append(rec)
    return objects


def spread_objects(chords_per_object: int = 2000, seed: int = 0):
    """The worst case for the histogram: chords uniform in the 7-D box, so almost every
    chord occupies its own cell (about 1.6e5 occupied cells in a training half)."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(list(CATEGORIES), [v[0] for v in CATEGORIES.values()])
    return [ObjectRecord(f"o{i}", str(c), ChordSet(rng.random((chords_per_object, 7)),
                                                   np.zeros(chords_per_object, np.int64)),
                         rng.random((100, 3))) for i, c in enumerate(labels)]


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--splits", type=int, default=100, help="random splits (default 100)")
    parser.add_argument("--seed", type=int, default=0, help="seed (default 0)")
    parser.add_argument("--spread", action="store_true",
                        help="worst case: uniformly random chords, chords method only")
    args = parser.parse_args(argv)
    t0 = time.perf_counter()
    objects = (spread_objects if args.spread else make_objects)(seed=args.seed)
    t_data = time.perf_counter() - t0
    chords = evaluate(objects, args.splits, args.seed, method="chords")
    tri = chords if args.spread else evaluate(objects, args.splits, args.seed, method="triangles")
    out = {"dataset": "spread (worst case)" if args.spread else "synthetic wraps",
           "n_objects": len(objects), "n_splits": args.splits,
           "mean_chords_per_object": float(np.mean([len(o.chords) for o in objects])),
           "dataset_build_s": round(t_data, 2),
           "chords_evaluate_s": round(chords.time_s, 2),
           "chords_accuracy_mean": chords.accuracy_mean,
           "triangles_evaluate_s": None if args.spread else round(tri.time_s, 2),
           "triangles_accuracy_mean": None if args.spread else tri.accuracy_mean,
           "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}
    print(json_text(out))
    sys.stdout.write("\n")
    return out


if __name__ == "__main__":
    main()
