"""Time touch-driven wraps (Algorithm 1) over a generated dataset and its planes, and
measure how closely they follow the object.

For K objects a category (default 2) of a generated dataset (generated here from --seed when
--dataset is not given), every default plane is wrapped with fast enclosing; then a subset of
those wraps (--compare, every category represented) is wrapped again with reference
enclosing for the speed-up in the same run, same wraps both ways. Times are wall clock on one
core (BLAS/OpenMP threads pinned to 1 before numpy, Open3D and Drake load), and CPU time
("fast_cpu", which load on a shared machine distorts less). Prints one JSON
object; record it in BENCHMARKS.md ("Wrapping").

Conformity is measured here from the stored samples and the scene's signed distance (the
fraction of the wrapped centre line whose tube lies within 5 mm of the surface), not read
from the result, so the script measures older code the same way: run it with
PYTHONPATH=<checkout of the old commit> for a before/after in one run. Where a wrap's
time goes (IK, posing, contact queries, the rest) is printed when the code records it.

    python benchmarks/bench_wrap.py [--per-category 2] [--compare 10] [--seed 0]
        [--set delta_max_factor=4]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import drake_continuum  # noqa: E402
from drake_continuum.objects.dataset import generate_dataset, load_manifest  # noqa: E402

if (Path(drake_continuum.__file__).parent / "wrapping").is_dir():
    from drake_continuum.kinematics.arm import load_arm
    from drake_continuum.wrapping.planes import enumerate_planes
    from drake_continuum.wrapping.scene import WrapScene
    from drake_continuum.wrapping.wrap import WrapParams, wrap
else:  # a checkout of 0.1.0 (before the subpackages, issue 18); asked by path, as an
    # editable install would serve the subpackages of the installed tree to an old one
    from drake_continuum.arm import load_arm
    from drake_continuum.planes import enumerate_planes
    from drake_continuum.scene import WrapScene
    from drake_continuum.wrap import WrapParams, wrap
try:
    from drake_continuum.files import json_text
except ImportError:  # before the one JSON writer
    import json

    def json_text(obj, indent=2):
        return json.dumps(obj, indent=indent, default=float)


def _stats(ms) -> dict:
    ms = np.asarray(ms, float)
    if not len(ms):
        return {"n": 0}
    return {"n": int(len(ms)), "median_ms": float(np.median(ms)),
            "p95_ms": float(np.percentile(ms, 95)), "max_ms": float(ms.max()),
            "mean_ms": float(ms.mean())}


NEAR = 0.005  # m, the conformity threshold: tube within this of the surface


def _median(x):
    x = [v for v in x if v == v]
    return float(np.median(x)) if x else None


def _mean(x):
    return float(np.mean(x)) if len(x) else None


def float_field(text: str) -> tuple[str, float]:
    """("name", value) of a --set FIELD=NUMBER."""
    name, sep, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise SystemExit(f"--set {text!r}: must be FIELD=NUMBER, e.g. delta_max_factor=4") \
            from None


def compiled_signatures() -> set:
    """(kernel, signature) of every numba kernel the wraps have compiled or loaded so far,
    of the kinematics modules this checkout has."""
    import importlib

    found = set()
    for name in ("compiled", "proximity"):
        try:
            module = importlib.import_module(f"drake_continuum.kinematics.{name}")
        except ImportError:  # an older checkout
            continue
        for attr, value in vars(module).items():
            found |= {(f"{name}.{attr}", str(s)) for s in getattr(value, "signatures", ())}
    return found


def pick_objects(dataset, per_category: int):
    return [e for c in dataset.categories for e in dataset.by_category(c)[:per_category]]


def run(dataset_dir, per_category: int, n_compare: int, seed: int, wrap_set=()) -> dict:
    dataset = load_manifest(dataset_dir)
    arm = load_arm()
    planes = enumerate_planes(arm.base_position)
    entries = pick_objects(dataset, per_category)
    rows, scenes, results = [], {}, {}
    fields = dict(float_field(kv) for kv in wrap_set)
    # One wrap first, untimed: numba loads its compiled kinematics and Drake and Open3D make
    # their first queries, ~0.2 s that otherwise landed on the first wrap timed. The
    # kernels' signatures loaded after it are reported ("compiled_while_timed": none, or
    # the timing includes their loading).
    wrap(WrapScene(arm, entries[0].load()), planes[0], WrapParams(method="fast", **fields))
    warm = compiled_signatures()
    t_all = time.perf_counter()
    for e in entries:
        scene = WrapScene(arm, e.load())
        scenes[e.id] = scene
        for p in planes:
            cpu = time.process_time()
            r = wrap(scene, p, WrapParams(method="fast", **fields))
            cpu = time.process_time() - cpu
            results[e.id, p.index] = r
            near = (float(np.mean(scene.signed_distance(r.samples_position) - arm.radius
                                  <= NEAR)) if len(r.samples_position) else float("nan"))
            rows.append({"id": e.id, "category": e.category, "plane": p.index,
                         "status": r.status, "ms": 1000 * r.time_s, "cpu_ms": 1000 * cpu,
                         "queries": r.n_queries,
                         "contacts": len(r.contacts), "conformity": near,
                         "timing": r.extra.get("timing")})
    fast_wall = time.perf_counter() - t_all
    compiled_while_timed = sorted(compiled_signatures() - warm)
    wrapped = [r for r in rows if r["status"] != "empty_cut"]
    usable = [r for r in wrapped if r["contacts"] > 0]

    # Reference on a subset: spread over categories and planes, the same wraps both ways.
    rng = np.random.default_rng(seed)
    order = rng.permutation(len(wrapped))
    by_cat, subset = Counter(), []
    for i in order:  # round-robin over categories
        r = wrapped[i]
        if by_cat[r["category"]] < -(-n_compare // len(dataset.categories)):
            subset.append(r)
            by_cat[r["category"]] += 1
        if len(subset) == n_compare:
            break
    compare = []
    for r in subset:
        ref = wrap(scenes[r["id"]], planes[r["plane"]],
                   WrapParams(method="reference", **fields))
        fast = results[r["id"], r["plane"]]
        line = [arm.with_base(rotation=w.base_rotation).backbone(w.final_config, n=400).position
                for w in (fast, ref)]
        compare.append({"final_difference_mm": 1000 * float(np.max(np.linalg.norm(
                            line[0] - line[1], axis=1))),
                        "id": r["id"], "plane": r["plane"], "fast_ms": r["ms"],
                        "reference_ms": 1000 * ref.time_s, "fast_queries": r["queries"],
                        "reference_queries": ref.n_queries,
                        "same_status": ref.status == r["status"]})
    fast_sum = sum(c["fast_ms"] for c in compare)
    ref_sum = sum(c["reference_ms"] for c in compare)
    per_object = Counter(r["id"] for r in usable)
    per_category = {}
    for c in dataset.categories:
        ms = [r["ms"] for r in wrapped if r["category"] == c]
        if ms:
            mine = [r for r in usable if r["category"] == c]
            per_category[c] = {"median_ms": float(np.median(ms)),
                               "wraps_per_object": len(mine)
                               / len([e for e in entries if e.category == c]),
                               "conformity_median": _median([r["conformity"] for r in mine]),
                               "contacts_mean": _mean([r["contacts"] for r in mine])}
    timed = [r["timing"] for r in wrapped if r["timing"]]
    where = None
    if timed:
        parts = ("ik", "pose", "prefilter", "contact_surfaces", "rest")
        total = sum(sum(t[k] for k in parts) for t in timed)
        where = {"share_of_time": {k: sum(t[k] for t in timed) / total for k in parts},
                 "median_ms_a_wrap": {k: 1000 * float(np.median([t[k] for t in timed]))
                                      for k in parts},
                 "median_ik_solves": float(np.median([t["ik_solves"] for t in timed])),
                 "median_ik_program_solves": float(np.median([t["ik_programs"] for t in timed])),
                 "median_contact_surface_queries": float(np.median(
                     [t["contact_surfaces_queries"] for t in timed]))}
    return {
        "benchmark": "wrap", "dataset": str(dataset_dir), "seed": seed, "wrap_set": fields,
        "objects": len(entries), "planes_per_object": len(planes),
        "wraps": len(rows), "wraps_nonempty_cut": len(wrapped),
        "status_counts": dict(Counter(r["status"] for r in rows)),
        "fast": _stats([r["ms"] for r in wrapped]),
        "fast_cpu": _stats([r["cpu_ms"] for r in wrapped]),
        "fast_complete_only": _stats([r["ms"] for r in wrapped if r["status"] == "complete"]),
        "queries_per_wrap_median": float(np.median([r["queries"] for r in wrapped])),
        "conformity_median": _median([r["conformity"] for r in usable]),
        "contact_regions_median": _median([r["contacts"] for r in usable]),
        "where_the_time_goes": where,
        "usable_wraps_per_object": {"mean": float(np.mean([per_object[e.id] for e in entries])),
                                    "min": int(min(per_object[e.id] for e in entries)),
                                    "max": int(max(per_object[e.id] for e in entries))},
        "per_category": per_category,
        "fast_wall_s": fast_wall,
        "compiled_while_timed": [f"{k} {s}" for k, s in compiled_while_timed],
        "speedup": {"n_wraps": len(compare),
                    "reference_over_fast_total_time": ref_sum / max(fast_sum, 1e-9),
                    "median_ratio": float(np.median([c["reference_ms"] / c["fast_ms"]
                                                     for c in compare])) if compare else None,
                    "fast": _stats([c["fast_ms"] for c in compare]),
                    "reference": _stats([c["reference_ms"] for c in compare]),
                    "queries_fast_median": float(np.median([c["fast_queries"] for c in compare])),
                    "queries_reference_median": float(np.median([c["reference_queries"]
                                                                 for c in compare])),
                    "same_status": int(sum(c["same_status"] for c in compare)),
                    "final_centre_line_difference_mm_max": max(
                        (c["final_difference_mm"] for c in compare), default=None)},
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                    "load_avg_1min": os.getloadavg()[0]},
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dataset", default=None,
                        help="generated dataset folder (default: generate one from --seed in a "
                             "temporary folder)")
    parser.add_argument("--per_category", "--per-category", dest="per_category", type=int,
                        default=2, help="objects a category (default: 2)")
    parser.add_argument("--compare", type=int, default=10,
                        help="wraps also run with reference enclosing (default: 10)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--set", dest="wrap_set", action="append", default=[],
                        metavar="FIELD=NUMBER",
                        help="a numeric WrapParams field for every wrap, e.g. "
                             "delta_max_factor=4 (repeatable; default: WrapParams())")
    args = parser.parse_args()
    if args.dataset is None:
        with tempfile.TemporaryDirectory() as tmp:
            generate_dataset(tmp, seed=args.seed, workers=1)
            out = run(tmp, args.per_category, args.compare, args.seed, args.wrap_set)
    else:
        out = run(args.dataset, args.per_category, args.compare, args.seed, args.wrap_set)
    print(json_text(out, indent=2))


if __name__ == "__main__":
    main()
