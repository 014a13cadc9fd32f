"""Point-cloud benchmark: fit arm configurations to simulated Kinect clouds of true wraps.

Wraps (wrap.py, Algorithm 1, with the table top as an obstacle as a real arm over a table
must: `--no-table` wraps through it, as the paper's simulation does) of generated objects
(dataset seed 0) on all 10 planes in turn, a category a wrap in rotation, each rendered by
the simulated Kinect from the default camera and from a second camera opposite it
(depth_camera.cameras_around). Every wrap is fitted, in one run, by:

  before      the fit as it was at --before REV (its pointcloud.py, read from git; one view)
  main_one_view, main_two_views, main_prior
              one_view, two_views and prior with the fit as it was at --main REV (the package
              after the subpackages, read from git): the "before" of a later change
  one_view    one view with its camera position: free space as evidence, assessment
  two_views   both views merged, each with its camera position
  prior       one view, with the true configuration perturbed by the stated uncertainty as
              the commanded configuration (--prior)

with section lengths known and free. Figures: tip error (against the true configuration)
median / p90 / p95, the fits whose tip error exceeds 10 mm ("failures") and among them those
flagged neither ambiguous, nor partly unseen, nor a poor fit ("confident wrong"), and the
time of one fit (segmentation included; wall and CPU time, the latter being what a busy
shared machine does not inflate). Prints the summary as JSON.

`--curled` runs the curled protocol instead: random curled configurations round a cylinder,
a box and the demo mug (depth_camera.curled_configs), default camera only.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

from drake_continuum.kinematics.arm import MODELS_DIR, ArmConfig, load_arm
from drake_continuum.perception import depth_camera as dc
from drake_continuum.perception.cloud import Cloud, PointCloudError
from drake_continuum.perception.fitting import fit_cloud
from drake_continuum.perception.residuals import ConfigPrior

FAIL_MM = 10.0
BEFORE = "5597ad1"  # the commit before issue 16
MAIN = "d8c4aad"  # main before the fit's speed-up (issue 16, second session)
VARIANTS = ("before", "main_one_view", "main_two_views", "one_view", "two_views", "prior")
PRIOR_SIGMA = {"sigma_s": 0.01, "sigma_kappa": 1.0, "sigma_phi": 0.2}


def wrap_cases(n: int, seed: int, objects_dir: Path, cache: Path | None, table: bool = True):
    """n true wraps: plane k % 10, categories in rotation, objects drawn with `seed`; with
    `table`, made with the table top as an obstacle (WrapParams.table), as a real arm over a
    table can only make them."""
    from drake_continuum.objects.dataset import generate_dataset, load_manifest
    from drake_continuum.wrapping.planes import enumerate_planes
    from drake_continuum.wrapping.scene import WrapScene
    from drake_continuum.wrapping.wrap import WrapParams, wrap

    if not (objects_dir / "manifest.json").exists():
        generate_dataset(objects_dir, seed=0)
    ds = load_manifest(objects_dir)
    cats = ds.categories
    rng = np.random.default_rng(seed)
    done = json.loads(cache.read_text()) if cache is not None and cache.exists() else {}
    arm = load_arm()
    planes = enumerate_planes(arm.base_position)
    out = []
    for k in range(n):
        plane = k % len(planes)
        cat = cats[(k + k // len(planes)) % len(cats)]
        entry = ds.by_category(cat)[int(rng.integers(len(ds.by_category(cat))))]
        key = f"{entry.id}/{plane}" + ("/table" if table else "")
        if key not in done:
            t0 = time.perf_counter()
            r = wrap(WrapScene(arm, entry.path), planes[plane], WrapParams(table=table))
            done[key] = {"config": r.final_config.to_dict(), "status": r.status,
                         "base_rotation": np.asarray(r.base_rotation).tolist(),
                         "wrap_s": time.perf_counter() - t0}
            if cache is not None:
                cache.write_text(json.dumps(done))
        w = done[key]
        out.append({"case": k, "object": entry.id, "path": entry.path, "plane": plane,
                    "status": w["status"], "config": ArmConfig.from_dict(w["config"]),
                    "base_rotation": np.asarray(w["base_rotation"])})
    return out


# The modules pointcloud.py imported, at their places since the subpackages.
MOVED = {"arm": "kinematics.arm", "chords": "features.chords", "scene": "wrapping.scene",
         "confidence": "perception.confidence", "freespace": "perception.freespace",
         "depth_camera": "perception.depth_camera"}


def module_at(rev: str):
    """drake_continuum/pointcloud.py as it was at git revision `rev`, before the subpackages
    (its imports pointed at the modules' new places; same package otherwise)."""
    import importlib.util
    import subprocess
    import tempfile

    root = Path(__file__).resolve().parent.parent
    text = subprocess.run(["git", "show", f"{rev}:drake_continuum/pointcloud.py"], cwd=root,
                          check=True, capture_output=True, text=True).stdout
    text = re.sub(r"^(\s*)from \.(\w+)",
                  lambda m: f"{m[1]}from drake_continuum.{MOVED.get(m[2], m[2])}", text, flags=re.M)
    path = Path(tempfile.mkdtemp()) / "pointcloud_before.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("drake_continuum._pointcloud_before", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def package_at(rev: str):
    """The drake_continuum package as it was at git revision `rev` (after the subpackages),
    importable beside this one as drake_continuum_at_<rev>: its perception.fitting."""
    import importlib
    import io
    import subprocess
    import tarfile
    import tempfile

    root = Path(__file__).resolve().parent.parent
    tar = subprocess.run(["git", "archive", rev, "drake_continuum"], cwd=root, check=True,
                         capture_output=True).stdout
    folder = Path(tempfile.mkdtemp())
    tarfile.open(fileobj=io.BytesIO(tar)).extractall(folder)
    name = f"drake_continuum_at_{re.sub(r'[^0-9A-Za-z]', '_', rev)}"
    (folder / "drake_continuum").rename(folder / name)
    sys.path.insert(0, str(folder))
    return importlib.import_module(f"{name}.perception.fitting")


def perturbed(config: ArmConfig, rng) -> ArmConfig:
    """The commanded configuration of a wrap: the true one off by the prior's uncertainty."""
    return ArmConfig(config.s + rng.normal(0, PRIOR_SIGMA["sigma_s"], config.n_sections),
                     np.maximum(config.kappa + rng.normal(0, PRIOR_SIGMA["sigma_kappa"],
                                                          config.n_sections), 0.0),
                     config.phi + rng.normal(0, PRIOR_SIGMA["sigma_phi"], config.n_sections))


def run(n: int, seed: int, objects_dir: Path, cache: Path | None, variants,
        before: str = BEFORE, main_rev: str = MAIN, table: bool = True) -> dict:
    old = module_at(before) if "before" in variants else None
    at_main = package_at(main_rev) if any(v.startswith("main_") for v in variants) else None
    base_arm = load_arm()
    rng = np.random.default_rng(seed + 7919)
    rows = []
    for case in wrap_cases(n, seed, objects_dir, cache, table):
        arm = base_arm.with_base(rotation=case["base_rotation"])
        cfg = case["config"]
        mesh = trimesh.load(case["path"], force="mesh")
        cams = dc.cameras_around(2)
        sims = [dc.render_cloud(arm, cfg, mesh, camera=c, seed=seed * 1000 + 2 * case["case"] + j)
                for j, c in enumerate(cams)]
        clouds = [Cloud(s.points, s.colours, source=f"case {case['case']} view {j}")
                  for j, s in enumerate(sims)]
        eyes = [np.asarray(c.eye) for c in cams]
        truth = arm.tip_frame(cfg)[1]
        prior = ConfigPrior(perturbed(cfg, rng), **PRIOR_SIGMA)
        row = {"case": case["case"], "object": case["object"], "plane": case["plane"],
               "wrap_status": case["status"], "true_config": cfg.to_dict(),
               "arm_min_z_m": float(arm.backbone(cfg, n=300).position[:, 2].min())}
        for variant in variants:
            fit_at = at_main.fit_cloud if variant.startswith("main_") else fit_cloud
            base = variant.removeprefix("main_")
            for key, lengths in (("known", cfg.s), ("free", None)):
                kw = {}
                if base in ("one_view", "prior"):
                    kw = {"eye": eyes[0], "prior": prior if base == "prior" else None}
                src = clouds if base == "two_views" else clouds[0]
                if base == "two_views":
                    kw = {"eye": eyes}
                t0, c0 = time.perf_counter(), time.process_time()
                try:
                    if variant == "before":
                        seg, fit = old.fit_cloud(old.Cloud(src.points, src.colours), arm,
                                                 lengths)
                    else:
                        seg, fit = fit_at(src, arm, lengths, **kw)
                except (PointCloudError, ValueError) as e:
                    row[f"{variant}_{key}"] = {"error": str(e)}
                    continue
                c = getattr(fit, "confidence", None)
                row[f"{variant}_{key}"] = {
                    "tip_error_mm": 1e3 * float(np.linalg.norm(fit.tip - truth)),
                    "time_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
                    "fit_s": fit.time_s,
                    "arm_points": len(seg.points), "pieces": seg.n_pieces,
                    **({} if c is None else {k: v for k, v in c.to_dict().items()})}
        rows.append(row)
        print(f"case {case['case']} {case['object']} plane {case['plane']} ({case['status']}): "
              + ", ".join(f"{k} {v['tip_error_mm']:.1f}" + ("A" if v.get("ambiguous") else "")
                          + ("U" if v.get("partly_unseen") else "")
                          + ("P" if v.get("poor_fit") else "") + f" {v['cpu_s']:.1f}s"
                          for k, v in row.items() if isinstance(v, dict) and "tip_error_mm" in v),
              file=sys.stderr, flush=True)
    return {"summary": {**summarise(rows, variants, n, seed), "table": table}, "cases": rows}


def summarise(rows, variants, n, seed) -> dict:
    """Figures over all wraps, and over those whose arm stays above the table top (without
    the table, `--no-table`, a wrap may pass under the top, where no camera can see it)."""
    out = {"n_wraps": n, "seed": seed, "planes": sorted({r["plane"] for r in rows}),
           "wrap_status": {s: sum(r["wrap_status"] == s for r in rows)
                           for s in sorted({r["wrap_status"] for r in rows})}}
    out.update(figures(rows, variants))
    above = [r for r in rows if r["arm_min_z_m"] >= 0.0]
    out["above_table"] = {"n_wraps": len(above), **figures(above, variants)}
    return out


def figures(rows, variants) -> dict:
    out = {}
    for variant in variants:
        for key in ("known", "free"):
            fits = [r[f"{variant}_{key}"] for r in rows]
            ok = [f for f in fits if "tip_error_mm" in f]
            e = np.array([f["tip_error_mm"] for f in ok])
            t = np.array([f["time_s"] for f in ok])
            cpu = np.array([f["cpu_s"] for f in ok])
            fail = [f for f in ok if f["tip_error_mm"] > FAIL_MM]
            s = {"fits": len(ok), "errors": len(fits) - len(ok),
                 "tip_error_median_mm": float(np.median(e)),
                 "tip_error_p90_mm": float(np.percentile(e, 90)),
                 "tip_error_p95_mm": float(np.percentile(e, 95)),
                 "tip_error_max_mm": float(e.max()),
                 "failures_over_10mm": len(fail),
                 "time_median_s": float(np.median(t)), "time_max_s": float(t.max()),
                 "cpu_median_s": float(np.median(cpu)), "cpu_max_s": float(cpu.max()),
                 "cpu_over_3s": int(np.sum(cpu > 3.0))}
            if variant != "before":
                s["confident_wrong"] = sum(bool(f["confident"]) for f in fail)
                s["poor_fit"] = sum(bool(f["poor_fit"]) for f in ok)
                s["ambiguous"] = sum(bool(f["ambiguous"]) for f in ok)
                s["partly_unseen"] = sum(bool(f["partly_unseen"]) for f in ok)
                s["ambiguous_but_right"] = sum(bool(f["ambiguous"]) and
                                               f["tip_error_mm"] <= FAIL_MM for f in ok)
            out[f"{variant}_{key}"] = s
    for a, b in (("main_one_view", "one_view"), ("main_two_views", "two_views"),
                 ("main_prior", "prior")):
        if a in variants and b in variants:
            # Same wraps, same clouds: how the tip error moved, fit by fit.
            d = [r[f"{b}_{k}"]["tip_error_mm"] - r[f"{a}_{k}"]["tip_error_mm"] for r in rows
                 for k in ("known", "free") if "tip_error_mm" in r[f"{a}_{k}"]
                 and "tip_error_mm" in r[f"{b}_{k}"]]
            out[f"{b}_vs_{a}"] = {"fits": len(d), "worse_by_over_1mm": int(np.sum(np.array(d) > 1)),
                                 "better_by_over_1mm": int(np.sum(np.array(d) < -1)),
                                 "changed_over_0_01mm": int(np.sum(np.abs(d) > 0.01)),
                                 "change_max_mm": float(np.max(d)) if d else None}
    if "one_view" in variants and "two_views" in variants:
        one = {r["case"] for r in rows if r["one_view_free"].get("tip_error_mm", 1e9) > FAIL_MM}
        two = {r["case"] for r in rows if r["two_views_free"].get("tip_error_mm", 1e9) > FAIL_MM}
        out["second_view_removes_free_failures"] = f"{len(one - two)} of {len(one)}"
    return out


# --------------------------------------------------------------------------- curled protocol

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


def run_curled(n: int, seed: int, deform_mm: float) -> dict:
    arm = load_arm()
    rng = np.random.default_rng(seed)
    objs = objects()
    names = list(objs)
    rows = []
    for i in range(n):
        name = names[i % len(names)]
        cfg = dc.curled_configs(arm, objs[name], 1, rng=rng)[0]
        sim = dc.render_cloud(arm, cfg, objs[name], deform=deform_mm / 1000.0, seed=seed + i)
        cloud = Cloud(sim.points, sim.colours, source=f"case {i}")
        truth = arm.tip_frame(cfg)[1]
        row = {"case": i, "object": name}
        for key, lengths in (("known", cfg.s), ("free", None)):
            t0 = time.perf_counter()
            seg, fit = fit_cloud(cloud, arm, lengths, eye=sim.camera.eye)
            row[f"time_{key}_s"] = time.perf_counter() - t0
            row[f"tip_error_{key}_mm"] = 1e3 * float(np.linalg.norm(fit.tip - truth))
        rows.append(row)
    def col(k):
        return np.array([r[k] for r in rows])
    times = np.concatenate([col("time_known_s"), col("time_free_s")])
    return {"summary": {
        "n_clouds": n, "seed": seed, "deform_mm": deform_mm, "objects": names,
        "tip_error_known_median_mm": float(np.median(col("tip_error_known_mm"))),
        "tip_error_free_median_mm": float(np.median(col("tip_error_free_mm"))),
        "tip_error_free_p90_mm": float(np.percentile(col("tip_error_free_mm"), 90)),
        "time_per_cloud_median_s": float(np.median(times)),
        "time_per_cloud_max_s": float(times.max())}, "cases": rows}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n", type=int, default=40, help="wraps (default: 40)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of the objects drawn and of the noise (default: 0)")
    parser.add_argument("--objects", type=Path, default=Path("out/bench-objects"),
                        help="generated objects (dataset seed 0), made when missing "
                             "(default: out/bench-objects)")
    parser.add_argument("--cache", type=Path, default=None,
                        help="JSON file keeping the wraps between runs (default: none)")
    parser.add_argument("--variants", default=",".join(VARIANTS),
                        help=f"fits to run (default: {','.join(VARIANTS)})")
    parser.add_argument("--before", default=BEFORE,
                        help=f"git revision whose fit is the 'before' (default: {BEFORE})")
    parser.add_argument("--main", default=MAIN,
                        help=f"git revision whose fit is the main_* variants' (default: {MAIN})")
    parser.add_argument("--no-table", dest="table", action="store_false",
                        help="wrap through the table top, as Algorithm 1 without the table "
                             "(default: the table is an obstacle)")
    parser.add_argument("--curled", action="store_true",
                        help="the earlier protocol: curled configurations (default: off)")
    parser.add_argument("--deform_mm", type=float, default=0.0,
                        help="--curled: tube flattening at contacts, mm (default: 0)")
    parser.add_argument("--out", type=Path, default=None,
                        help="also write the JSON with every case here (default: none)")
    args = parser.parse_args(argv)
    if args.curled:
        result = run_curled(args.n, args.seed, args.deform_mm)
    else:
        result = run(args.n, args.seed, args.objects, args.cache, args.variants.split(","),
                     args.before, args.main, args.table)
    print(json.dumps(result["summary"], indent=2))
    if args.out:
        args.out.write_text(json.dumps(result, indent=2, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
