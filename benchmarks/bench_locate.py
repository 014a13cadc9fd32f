"""How far the depth camera's position estimate (locate.camera_estimate) lies from where
objects truly stand (their footprint centre), and what locating an object costs: every k-th
object of one or more datasets (placed copies included). Prints JSON.

--record FILE writes what collect keeps of each located object (centre, bearing, view, the
object's points) with every float in hex; --against FILE compares this run's with such a
file, to the bit (record with one version, compare with another). The CPU is collect's
camera step (camera_points, view_extent, points_estimate, points_bearing) on one thread;
the first object of a process also renders what later ones reuse, so the mean counts it.

Example: python benchmarks/bench_locate.py data/dataset data/placed --every 3
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time

import numpy as np
from threadpoolctl import threadpool_limits

from drake_continuum.kinematics.arm import load_arm
from drake_continuum.objects.dataset import load_manifest
from drake_continuum.perception.bearing import points_bearing
from drake_continuum.perception.locate import (
    camera_points,
    footprint_centre,
    points_estimate,
    view_extent,
)


def _hex(values) -> list:
    return [float(v).hex() for v in np.atleast_1d(np.asarray(values, dtype=float))]


def located(mesh, arm) -> tuple[dict, float]:
    """(what collect keeps of the located object, bits in hex; CPU seconds)."""
    c0 = time.process_time()
    seen = camera_points(mesh, arm)
    view, centre, bearing = view_extent(seen), points_estimate(seen).xy, points_bearing(seen)
    cpu = time.process_time() - c0
    return {"centre": _hex(centre), "view": _hex(view), "turn": _hex(bearing.turn),
            "ratio": _hex(np.nan if bearing.ratio is None else bearing.ratio),
            "skew": _hex(bearing.skew), "n_points": int(len(seen)),
            "points_sha1": hashlib.sha1(np.ascontiguousarray(seen).tobytes()).hexdigest()}, cpu


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("datasets", nargs="+")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--record", help="write each object's located numbers (hex) here")
    ap.add_argument("--against", help="compare with numbers --record wrote")
    args = ap.parse_args(argv)
    arm = load_arm()
    errors, cpus, worst, record = [], [], [], {}
    entries = [e for d in args.datasets for e in list(load_manifest(d))[::args.every]]
    with threadpool_limits(1):  # as collect's workers
        for e in entries:
            mesh = e.load()
            record[e.id], cpu = located(mesh, arm)
            cpus.append(cpu)
            xy = np.array([float.fromhex(v) for v in record[e.id]["centre"]])
            err = float(np.linalg.norm(xy - footprint_centre(mesh)))
            errors.append(err)
            worst.append((err, e.id))
    e_mm = 1000 * np.array(errors)
    out = {"datasets": args.datasets, "n_objects": len(errors),
           "error_mm": {"median": float(np.median(e_mm)), "p90": float(np.percentile(e_mm, 90)),
                        "max": float(e_mm.max()), "within_20mm": float(np.mean(e_mm <= 20))},
           "cpu_s": {"first": cpus[0], "median": float(np.median(cpus)),
                     "mean": float(np.mean(cpus)), "mean_after_first": float(np.mean(cpus[1:]))
                     if len(cpus) > 1 else None},
           "worst": [{"object_id": i, "error_mm": round(1000 * x, 1)}
                     for x, i in sorted(worst, reverse=True)[:5]]}
    if args.record:
        with open(args.record, "w") as f:
            json.dump(record, f, indent=0)
    if args.against:
        with open(args.against) as f:
            theirs = json.load(f)
        common = sorted(set(theirs) & set(record))
        differ = [i for i in common if theirs[i] != record[i]]
        out["against"] = {"file": args.against, "compared": len(common),
                          "equal_to_the_bit": len(common) - len(differ), "differ": differ}
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
