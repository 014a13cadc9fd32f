"""Which training makes recognition not care how an object stands: accuracy on placed
objects (as generated, turned, on another side, nudged) and the flip rate, for each way of
training, over random splits by object. Prints JSON (one entry a variant) and, with --md, a
Markdown table.

Variants: the chord angles' frame (world: the paper's; wrap: each wrap's own frame;
upright: each wrap turned about the vertical onto its plane), turn-invariant descriptor and
extent blocks (ClassifierParams.turn_invariant), the weights of those blocks, and training
on the originals only or also on their "train" placements (objects place --placements).
A variant is named by "+"-joined parts: a frame first, then any of "invariant",
"placements", "side" (also the "side" training placements), "norest" (no rest classes:
ClassifierParams.rest_classes false), "nomix" (no standing model mixed in:
ClassifierParams.standing_model false), "wrap=W" (wrap_weight), "extent=E" (extent_weight),
"view=V" (view_weight), "C=c" (svm_c), e.g.
"upright+placements+wrap=0+extent=0.4"; the names in VARIANTS are shorthands.

--objects-per-category K keeps the first K objects a category (with their placed copies:
a consistent subset of folders collected in full); --train-per-category K keeps the
"train" placements of only the first K objects a category (how the figures grow with the
number of training objects placed); --side-copies K keeps each object's first K "side"
copies (side0: its likeliest other side; side1..: sides drawn by probability). Objects are
numbered by their id's last "_" part.

--test WRAPS (repeatable): collections of another dataset (another seed) to test on; each
split then trains on the training half of the positional collections and tests on every
object of these (learning.placements.evaluate_placements, test_objects).

Example (wraps of a dataset and of its placed copies, `objects place ... --placements
train=2,turned=1,rest=1,nudged=1,jitter=1`):
  python benchmarks/bench_placements.py WRAPS PLACED_WRAPS --splits 20
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

from drake_continuum.features.chords import ChordParams
from drake_continuum.learning.pipeline import ClassifierParams
from drake_continuum.learning.placements import evaluate_placements, placements_table
from drake_continuum.learning.records import load_wraps
from drake_continuum.objects.placement import placement_kind, source_id

VARIANTS = {  # name: (frame, turn_invariant, train kinds)
    "world": ("world", False, ("generated",)),
    "world+invariant": ("world", True, ("generated",)),
    "wrap+invariant": ("wrap", True, ("generated",)),
    "world+placements": ("world", False, ("generated", "train")),
    "world+invariant+placements": ("world", True, ("generated", "train")),
    "wrap+invariant+placements": ("wrap", True, ("generated", "train")),
    "wrap+placements": ("wrap", False, ("generated", "train")),
}


def variant(name: str) -> tuple[str, ClassifierParams, tuple]:
    """(frame, classifier params, training kinds) of a variant name (module docstring)."""
    if name in VARIANTS:
        frame, invariant, kinds = VARIANTS[name]
        return frame, replace(ClassifierParams(), turn_invariant=invariant), kinds
    frame, *parts = name.split("+")
    params, kinds = ClassifierParams(), ("generated",)
    for part in parts:
        key, _, value = part.partition("=")
        if part == "invariant":
            params = replace(params, turn_invariant=True)
        elif part == "placements":
            kinds = ("generated", "train")
        elif part == "side":
            kinds = tuple(dict.fromkeys(kinds + ("side",)))
        elif part == "norest":
            params = replace(params, rest_classes=False)
        elif part == "nomix":
            params = replace(params, standing_model=False)
        elif key in ("wrap", "extent", "view") and value:
            params = replace(params, **{f"{key}_weight": float(value)})
        elif key == "C" and value:
            params = replace(params, svm_c=float(value))
        else:
            raise SystemExit(f"bench_placements: unknown variant part {part!r} in {name!r}")
    return frame, params, kinds


def _number(object_id: str) -> int:
    """The object's number in its category: the last "_" part of its source id."""
    return int(source_id(object_id).rsplit("_", 1)[1])


def _kept(object_id: str, args) -> bool:
    n = _number(object_id)
    if args.objects_per_category is not None and n >= args.objects_per_category:
        return False
    kind = placement_kind(object_id)
    if args.side_copies is not None and kind == "side" and \
            int(object_id.rsplit("side", 1)[1]) >= args.side_copies:
        return False
    return not (args.train_per_category is not None and kind == "train"
                and n >= args.train_per_category)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("wraps", nargs="+", help="wrap collections (originals, placed copies)")
    ap.add_argument("--splits", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    ap.add_argument("--triangles", action="store_true", help="also the triangle baseline")
    ap.add_argument("--md", action="store_true", help="also print a Markdown table")
    ap.add_argument("--objects-per-category", type=int, default=None, metavar="K",
                    help="only the first K objects a category and their copies (default: all)")
    ap.add_argument("--train-per-category", type=int, default=None, metavar="K",
                    help="training placements of the first K objects a category only "
                         "(default: all there are)")
    ap.add_argument("--side-copies", type=int, default=None, metavar="K",
                    help="only each object's first K side copies (default: all there are)")
    ap.add_argument("--test", action="append", default=[], metavar="WRAPS",
                    help="another dataset's wrap collection to test on (repeatable; default: "
                         "the other half of the positional ones)")
    ap.add_argument("--train-all", action="store_true",
                    help="with --test: one classifier trained on every positional record (as "
                         "reproduce trains the model it recommends), not one a split")
    args = ap.parse_args(argv)
    records, tests = {}, {}
    out = {}
    for name in args.variants.split(","):
        frame, params, kinds = variant(name)
        if frame not in records:
            records[frame] = [r for w in args.wraps
                              for r in load_wraps(w, ChordParams(frame=frame))
                              if _kept(r.object_id, args)]
            tests[frame] = [r for w in args.test for r in load_wraps(w, ChordParams(frame=frame))]
        t0 = time.perf_counter()
        r = evaluate_placements(records[frame], args.splits, args.seed, method="chords",
                                params=params, train_kinds=kinds,
                                progress=False, test_objects=tests[frame] or None,
                                train_all=args.train_all)
        r["wall_s"] = time.perf_counter() - t0
        out[name] = r
    if args.triangles:
        frame = next(iter(records))
        for kinds, name in ((("generated",), "triangles"),
                            (("generated", "train"), "triangles+placements")):
            out[name] = evaluate_placements(records[frame], args.splits, args.seed,
                                            method="triangles", params=ClassifierParams(),
                                            train_kinds=kinds,
                                            progress=False, test_objects=tests[frame] or None)
    brief = {k: {"kinds": {q: round(v["accuracy_mean"], 4) for q, v in r["kinds"].items()},
                 "kinds_balanced": {q: round(v["balanced_mean"], 4)
                                    for q, v in r["kinds"].items()},
                 "flip_rate": r["flips"]["rate"], "n_groups": r["n_groups"],
                 "n_records": {q: v["n_records"] for q, v in r["kinds"].items()},
                 "n_splits": r["n_splits"]} for k, r in out.items()}
    print(json.dumps(brief, indent=1), flush=True)
    if args.md:
        print(placements_table(out))


if __name__ == "__main__":
    main()
