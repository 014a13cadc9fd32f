"""How far the depth camera's position estimate (locate.camera_estimate) lies from where
objects truly stand (their footprint centre), and how long it takes: every k-th object of
a dataset (placed copies included). Prints JSON.

Example: python benchmarks/bench_locate.py data/placed --every 3
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from drake_continuum.kinematics.arm import load_arm
from drake_continuum.objects.dataset import load_manifest
from drake_continuum.perception.locate import camera_estimate, footprint_centre


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dataset")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    arm = load_arm()
    errors, times, worst = [], [], []
    for e in list(load_manifest(args.dataset))[::args.every]:
        mesh = e.load()
        t0 = time.perf_counter()
        est = camera_estimate(mesh, arm, seed=args.seed)
        times.append(time.perf_counter() - t0)
        err = float(np.linalg.norm(est.xy - footprint_centre(mesh)))
        errors.append(err)
        worst.append((err, e.id))
    e_mm = 1000 * np.array(errors)
    print(json.dumps({
        "dataset": args.dataset, "n_objects": len(errors),
        "error_mm": {"median": float(np.median(e_mm)), "p90": float(np.percentile(e_mm, 90)),
                     "max": float(e_mm.max()), "within_20mm": float(np.mean(e_mm <= 20))},
        "time_s_median": float(np.median(times)),
        "worst": [{"object_id": i, "error_mm": round(1000 * x, 1)}
                  for x, i in sorted(worst, reverse=True)[:5]]}, indent=1))


if __name__ == "__main__":
    main()
