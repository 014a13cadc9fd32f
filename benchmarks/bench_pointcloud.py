"""Point-cloud benchmark: fit arm configurations to simulated Kinect clouds of wraps.

Over random valid configurations curled round a cylinder, a box and the demo mug (see
depth_camera.curled_configs), each rendered with the Kinect v1 error model from the default
camera: tip error of the fit with section lengths known and free, and the time to segment
and fit one cloud. Prints JSON; the goals are a median tip error of at most 3 mm (lengths
known) and 6 mm (free) and at most 1 s a cloud.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

from drake_continuum import depth_camera as dc
from drake_continuum import pointcloud as pc
from drake_continuum.arm import MODELS_DIR, load_arm


def objects() -> dict:
    cyl = trimesh.creation.cylinder(radius=0.04, height=0.12)
    cyl.apply_translation((0, 0, 0.06))
    box = trimesh.creation.box(extents=(0.08, 0.10, 0.14))
    box.apply_translation((0, 0, 0.07))
    out = {"cylinder": cyl, "box": box}
    mug = MODELS_DIR / "mug.obj"
    if mug.exists():
        out["mug"] = trimesh.load(mug, force="mesh")
    return out


def run(n: int, seed: int, deform_mm: float) -> dict:
    arm = load_arm()
    rng = np.random.default_rng(seed)
    objs = objects()
    names = list(objs)
    rows = []
    for i in range(n):
        name = names[i % len(names)]
        cfg = dc.curled_configs(arm, objs[name], 1, rng)[0]
        sim = dc.render_cloud(arm, cfg, objs[name], deform=deform_mm / 1000.0, seed=seed + i)
        cloud = pc.Cloud(sim.points, sim.colours, source=f"case {i}")
        truth = arm.tip_frame(cfg)[1]
        row = {"case": i, "object": name, "n_points": len(sim.points),
               "true_config": cfg.to_dict()}
        for key, lengths in (("known", cfg.s), ("free", None)):
            t0 = time.perf_counter()
            seg, fit = pc.fit_cloud(cloud, arm, lengths)
            row[f"time_{key}_s"] = time.perf_counter() - t0
            row[f"tip_error_{key}_mm"] = 1e3 * float(np.linalg.norm(fit.tip - truth))
            row[f"fit_time_{key}_s"] = fit.time_s
        row["arm_points"] = len(seg.points)
        row["pieces"] = seg.n_pieces
        rows.append(row)
        print(f"case {i} {name}: tip known {row['tip_error_known_mm']:.2f} mm, free "
              f"{row['tip_error_free_mm']:.2f} mm, {row['time_known_s']:.2f} s, "
              f"{row['time_free_s']:.2f} s, pieces {seg.n_pieces}", file=sys.stderr)
    def col(k):
        return np.array([r[k] for r in rows])
    times = np.concatenate([col("time_known_s"), col("time_free_s")])
    summary = {
        "n_clouds": n, "seed": seed, "deform_mm": deform_mm, "objects": names,
        "tip_error_known_median_mm": float(np.median(col("tip_error_known_mm"))),
        "tip_error_known_p90_mm": float(np.percentile(col("tip_error_known_mm"), 90)),
        "tip_error_free_median_mm": float(np.median(col("tip_error_free_mm"))),
        "tip_error_free_p90_mm": float(np.percentile(col("tip_error_free_mm"), 90)),
        "time_per_cloud_median_s": float(np.median(times)),
        "time_per_cloud_max_s": float(times.max()),
        "fit_only_median_s": float(np.median(np.concatenate([col("fit_time_known_s"),
                                                              col("fit_time_free_s")]))),
        "clouds_with_split_arm": int((col("pieces") > 1).sum()),
    }
    summary["goals_met"] = {
        "tip_known_le_3mm": summary["tip_error_known_median_mm"] <= 3.0,
        "tip_free_le_6mm": summary["tip_error_free_median_mm"] <= 6.0,
        "time_le_1s": summary["time_per_cloud_median_s"] <= 1.0,
    }
    return {"summary": summary, "cases": rows}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=24, help="clouds (default: 24)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    parser.add_argument("--deform_mm", type=float, default=0.0,
                        help="tube flattening at contacts, mm (default: 0)")
    parser.add_argument("--out", type=Path, default=None,
                        help="also write the JSON here (default: none)")
    args = parser.parse_args(argv)
    result = run(args.n, args.seed, args.deform_mm)
    text = json.dumps(result["summary"], indent=2)
    print(text)
    if args.out:
        args.out.write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
