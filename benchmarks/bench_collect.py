"""Time to collect every wrap (10 planes, the paper's parameters) of a subset of the paper's
185 objects (the first K of each category), and the extrapolation to all 185. Prints JSON;
the goal is the full dataset in at most 10 minutes on 2 cores.

The extrapolation weights each category's mean object time (measured in its worker) by the
category's count in the full dataset (51 bottles, 6 bananas, ...). `extrapolated_full_185_s`
scales the subset's wall time by that ratio, so it keeps the subset's parallel efficiency,
start-up cost and whatever else loaded the machine; `extrapolated_full_185_s_idle` divides
the weighted CPU time of the objects by the workers: the wall time on otherwise idle cores.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from collections import Counter, defaultdict

import numpy as np

from drake_continuum.experiments.collect import collect
from drake_continuum.files import json_text
from drake_continuum.objects.dataset import generate_dataset, load_manifest
from drake_continuum.objects.generators import CATEGORY_COUNTS

GOAL_S = 600.0


def run(per_category: int, workers: int, seed: int) -> dict:
    with tempfile.TemporaryDirectory(prefix="bench-collect-") as tmp:
        data, wraps = os.path.join(tmp, "objects"), os.path.join(tmp, "wraps")
        generate_dataset(data, seed=seed, progress=False)
        dataset = load_manifest(data)
        load_before = os.getloadavg()[0]
        start = time.perf_counter()
        report = collect(data, wraps, workers=workers, limit_per_category=per_category,
                         progress=False)
        seconds = time.perf_counter() - start
        statuses = Counter()
        for oid in report.done:
            meta = json.loads(open(os.path.join(wraps, f"{oid}.json")).read())
            statuses.update(w["status"] for w in meta["wraps"])
    load_after = os.getloadavg()[0]
    ms = 1e3 * np.asarray(report.wrap_times_s)
    attempted = ms[ms > 1.0]  # empty cuts return at once; they are not wraps made
    by_category = defaultdict(list)
    for oid, t in report.object_times_s.items():
        by_category[dataset.by_id(oid).category].append(t)
    cpu_by_category = defaultdict(list)
    for oid, t in report.object_cpu_s.items():
        cpu_by_category[dataset.by_id(oid).category].append(t)
    mean = {c: float(np.mean(v)) for c, v in by_category.items()}
    mean_cpu = {c: float(np.mean(v)) for c, v in cpu_by_category.items()}
    full_work = sum(CATEGORY_COUNTS[c] * mean[c] for c in mean)
    subset_work = sum(report.object_times_s.values())
    full_s = seconds * full_work / subset_work
    full_idle_s = sum(CATEGORY_COUNTS[c] * mean_cpu[c] for c in mean_cpu) / workers
    return {
        "objects": len(report.done), "failed": report.failed, "workers": workers,
        "cpus": os.cpu_count(), "seconds": round(seconds, 1), "wraps": report.n_wraps,
        "wraps_by_status": dict(statuses),
        "wrap_ms_median": round(float(np.median(ms)), 1),
        "wrap_ms_p95": round(float(np.percentile(ms, 95)), 1),
        "wrap_ms_median_excluding_empty_cuts": round(float(np.median(attempted)), 1),
        "wrap_ms_p95_excluding_empty_cuts": round(float(np.percentile(attempted, 95)), 1),
        "object_s_mean_by_category": {c: round(v, 2) for c, v in mean.items()},
        "object_cpu_s_mean_by_category": {c: round(v, 2) for c, v in mean_cpu.items()},
        "cpu_s_of_wall_s": round(sum(report.object_cpu_s.values()) / subset_work, 2),
        "extrapolated_full_185_s": round(full_s, 0),
        "extrapolated_full_185_s_idle": round(full_idle_s, 0),
        "extrapolated_full_185_s_unweighted": round(seconds / len(report.done) * 185, 0),
        "goal_s": GOAL_S, "meets_goal": bool(full_s <= GOAL_S),
        "meets_goal_idle": bool(full_idle_s <= GOAL_S),
        "load_average_before_after": [round(load_before, 2), round(load_after, 2)],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--per-category", type=int, default=2,
                        help="objects a category (default: 2, i.e. 20 objects)")
    parser.add_argument("--workers", type=int, default=2, help="worker processes (default: 2)")
    parser.add_argument("--seed", type=int, default=0, help="dataset seed (default: 0)")
    args = parser.parse_args()
    print(json_text(run(args.per_category, args.workers, args.seed), indent=1))


if __name__ == "__main__":
    main()
