"""The best conformity this arm can reach, plane by plane, against Algorithm 1's wraps of
the same planes (issue 19: is its goal reachable at all with this arm?).

For K objects a category (default 1: the speed benchmark's set) of a generated dataset and
every default wrap plane that cuts the object, `wrapping.bound.best_wrap` finds the in-plane
configuration of the arm (lengths, curvatures and bend within its limits, the tube pressing
at most 1 mm into the object, the tip turning 270 deg after the first contact) whose
centre line from the first contact to the tip lies near the surface over the largest
fraction, measured as WrapResult.conformity is. The same plane is wrapped by Algorithm 1
(the installed package) in the same run; its final configuration, taken into the plane, is a
feasible point when it stayed in the plane, touched no deeper than 1 mm and turned 270 deg
after its first contact, and the bound must then be at least its conformity (counted).
A second search seed (--seeds 2) shows how far the search is from converged.

Prints one JSON object; record it in BENCHMARKS.md. --figures DIR draws every plane (the
cut, the best arm, Algorithm 1's wrap). --arm YAML bounds another arm (then --no-wraps
skips Algorithm 1's wraps, which are the default arm's question).

    python benchmarks/bench_conformity_bound.py --dataset DS [--per-category 1] [--seeds 2]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

from drake_continuum.files import json_text  # noqa: E402
from drake_continuum.kinematics.arm import load_arm  # noqa: E402
from drake_continuum.objects.dataset import load_manifest  # noqa: E402
from drake_continuum.wrapping.bound import BoundParams, best_wrap, measure, planar_arm  # noqa: E402
from drake_continuum.wrapping.planes import cross_section, enumerate_planes  # noqa: E402
from drake_continuum.wrapping.scene import WrapScene  # noqa: E402
from drake_continuum.wrapping.wrap import WrapParams, wrap  # noqa: E402
from drake_continuum.wrapping.wrap_types import WrapStatus  # noqa: E402

GOAL = 0.5
GOAL_ROUND = 0.6  # apples, bowls, bottles, cups
ROUND = ("apple", "bowl", "bottle", "cup")
IN_PLANE = 1e-3  # m: a wrap whose centre line lies this close to its in-plane form
# A wrap nearly feasible: in its plane, pressing at most this deep, turning at least theta
# less this after its first contact (Algorithm 1's theta is from the base direction, and a
# wrap may stop a few degrees short of theta after its touch).
NEARLY_PRESS, NEARLY_TURN = 1.5e-3, np.radians(10.0)


def _median(x):
    x = [v for v in x if v is not None and v == v]
    return float(np.median(x)) if x else None


def _plane_coords(plane, points):
    e1, e2 = plane.basis()
    d = np.asarray(points).reshape(-1, 3) - plane.origin
    return np.stack([d @ e1, d @ e2], 1)


def draw(path, scene, plane, bound, actual, title):
    """The plane's cut, the best arm (its measured part bold) and Algorithm 1's wrap."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from drake_continuum.wrapping.bound import arm_config

    arm = scene.arm
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    seg = cross_section(scene.object_trimesh, plane).reshape(-1, 2, 2)
    for a, b in seg:
        ax.plot([a[0], b[0]], [a[1], b[1]], color="0.3", lw=1.2)
    R, config = arm_config(arm, plane, bound.arm)
    line = _plane_coords(plane, arm.with_base(rotation=R).backbone(config, n=400).position)
    ax.plot(*line.T, color="tab:blue", lw=0.8, label="best in-plane arm")
    if len(bound.measure.samples):
        part = _plane_coords(plane, bound.measure.samples)
        ax.plot(*part.T, color="tab:blue", lw=2.5,
                label=f"its measured part: {100 * bound.measure.conformity:.0f} % near")
    if actual is not None:
        posed = arm.with_base(rotation=actual.base_rotation)
        line = _plane_coords(plane, posed.backbone(actual.final_config, n=400).position)
        ax.plot(*line.T, color="tab:orange", lw=0.8, label="Algorithm 1's wrap")
        if len(actual.samples_position):
            part = _plane_coords(plane, actual.samples_position)
            ax.plot(*part.T, color="tab:orange", lw=2.5,
                    label=f"its measured part: {100 * actual.conformity:.0f} % near")
    ax.plot(0, 0, "ks", ms=5)
    ax.set_aspect("equal")
    c = seg.reshape(-1, 2)
    lo, hi = c.min(0) - 0.08, c.max(0) + 0.08
    ax.set_xlim(min(lo[0], -0.02), hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_xlabel("e1, m (towards the object)")
    ax.set_ylabel("e2, m")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(dataset_dir, per_category: int, seeds: int, params: BoundParams, arm_yaml=None,
        wraps: bool = True, figures=None, first_seed: int = 0) -> dict:
    dataset = load_manifest(dataset_dir)
    arm = load_arm(arm_yaml)
    planes = enumerate_planes(arm.base_position)
    entries = [e for c in dataset.categories for e in dataset.by_category(c)[:per_category]]
    rows = []
    t_all = time.perf_counter()
    for e in entries:
        scene = WrapScene(arm, e.load())
        for p in planes:
            if not len(cross_section(scene.object_trimesh, p)):
                continue
            row = {"id": e.id, "category": e.category, "plane": p.index}
            actual = None
            if wraps:
                actual = wrap(scene, p, WrapParams(press_depth=params.press_depth))
                scene.arm = arm
                row.update({"wrap_status": actual.status, "wrap_usable": actual.usable,
                            "wrap_conformity": actual.conformity})
                if actual.status != WrapStatus.START_IN_COLLISION:
                    flat, off = planar_arm(arm, p, actual.base_rotation, config=actual.final_config)
                    m = measure(scene, p, flat, params=params)
                    row.update({"wrap_off_plane_mm": 1000 * off,
                                "wrap_measured_here": m.conformity,
                                "wrap_measured_from_contact": m.from_contact,
                                "wrap_turn_after_start_deg": float(np.degrees(m.turn)),
                                "wrap_tip_heading_deg": float(np.degrees(m.tip_heading)),
                                "wrap_press_mm": 1000 * m.press,
                                "wrap_self_overlap_mm": 1000 * m.crossing,
                                "wrap_feasible": bool(off <= IN_PLANE and m.feasible(params)),
                                "wrap_nearly_feasible": bool(
                                    off <= IN_PLANE and m.touches
                                    and max(m.press, m.crossing) <= NEARLY_PRESS
                                    and m.turn >= params.theta - NEARLY_TURN)})
            t = time.perf_counter()
            found = [best_wrap(scene, p, params=replace(params, seed=k))
                     for k in range(first_seed, first_seed + seeds)]
            best = max(found, key=lambda b: (b.feasible, b.measure.conformity))
            m = best.measure
            row.update({"bound": m.conformity, "bound_by_seed": [b.measure.conformity
                                                                  for b in found],
                        "bound_from_contact": m.from_contact,
                        "bound_feasible": best.feasible,
                        "bound_turn_deg": float(np.degrees(m.turn)),
                        "bound_press_mm": 1000 * m.press,
                        "bound_self_overlap_mm": 1000 * m.crossing,
                        "bound_measured_length_m": float(len(m.samples) * params.spacing),
                        "bound_wrap_angle_deg": float(np.degrees(m.wrap_angle)),
                        "bound_s": best.arm.s.tolist(),
                        "bound_kappa": (best.arm.bend / best.arm.s).tolist(),
                        "bound_base_angle_deg": float(np.degrees(best.arm.base_angle)),
                        "search_s": time.perf_counter() - t,
                        "evaluations": int(sum(b.evaluations for b in found))})
            if row.get("wrap_nearly_feasible") and m.conformity < row["wrap_measured_here"]:
                # The wrap (or a point beside it) is one the search missed.
                row["bound_below_wrap"] = True
            rows.append(row)
            if figures is not None:
                Path(figures).mkdir(parents=True, exist_ok=True)
                title = (f"{e.id} plane {p.index} ({p.label}): best {100 * m.conformity:.0f} %"
                         + (f", Algorithm 1 {100 * actual.conformity:.0f} % ({actual.status})"
                            if actual is not None else ""))
                draw(Path(figures) / f"{e.id}_p{p.index}.png", scene, p, best, actual, title)

    def summary(sel):
        usable = [r for r in sel if r.get("wrap_usable")]
        out = {"planes": len(sel), "bound_median": _median([r["bound"] for r in sel]),
               "bound_mean": float(np.mean([r["bound"] for r in sel])),
               "bound_at_least_goal": int(sum(r["bound"] >= GOAL for r in sel)),
               "bound_feasible": int(sum(r["bound_feasible"] for r in sel))}
        if wraps:
            out.update({"wrap_usable": len(usable),
                        "wrap_median_usable": _median([r["wrap_conformity"] for r in usable]),
                        "bound_median_usable_planes": _median([r["bound"] for r in usable]),
                        "gap_median_usable": _median([r["bound"] - r["wrap_conformity"]
                                                      for r in usable])})
        return out

    feasible = [r for r in rows if r.get("wrap_feasible")]
    seeds_apart = [max(r["bound_by_seed"]) - min(r["bound_by_seed"]) for r in rows]
    return {
        "benchmark": "conformity_bound", "dataset": str(dataset_dir),
        "arm": str(arm_yaml or "models/arm.yaml"),
        "arm_limits": {"n_sections": arm.n_sections,
                       "section_length": [arm.section_length_min, arm.section_length_max],
                       "curvature_max": arm.curvature_max, "bend_max": arm.bend_max,
                       "radius": arm.radius},
        "params": {"theta_deg": float(np.degrees(params.theta)),
                   "press_depth": params.press_depth, "near": params.near,
                   "signed": params.signed, "start": params.start, "turn": params.turn,
                   "seeds": list(range(first_seed, first_seed + seeds)),
                   "popsize": params.popsize, "maxiter": params.maxiter},
        "objects": len(entries), "planes_with_cut": len(rows),
        "overall": summary(rows),
        "per_category": {c: summary([r for r in rows if r["category"] == c])
                         for c in dataset.categories if any(r["category"] == c for r in rows)},
        "goal": {"overall_median": GOAL, "round_median": GOAL_ROUND, "round": list(ROUND)},
        "wraps": None if not wraps else {
            "statuses": dict(Counter(r["wrap_status"] for r in rows)),
            "off_plane_over_1mm": int(sum(r.get("wrap_off_plane_mm", 0) > 1 for r in rows)),
            "feasible_in_bound": len(feasible),
            "nearly_feasible": int(sum(r.get("wrap_nearly_feasible", False) for r in rows)),
            "bound_below_feasible_wrap": int(sum(r.get("bound_below_wrap", False)
                                                 for r in feasible)),
            "bound_below_nearly_feasible_wrap": int(sum(r.get("bound_below_wrap", False)
                                                        for r in rows))},
        "search": {"seeds_apart_max": float(max(seeds_apart)) if rows else None,
                   "seeds_apart_over_5_points": int(sum(a > 0.05 for a in seeds_apart)),
                   "time_s_median": _median([r["search_s"] for r in rows])},
        "wall_s": time.perf_counter() - t_all,
        "rows": rows,
        "machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                    "load_avg_1min": os.getloadavg()[0]},
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dataset", required=True, help="generated dataset folder")
    parser.add_argument("--per_category", "--per-category", dest="per_category", type=int,
                        default=1, help="objects a category (default: 1)")
    parser.add_argument("--seeds", type=int, default=2,
                        help="search seeds a plane; the best counts (default: 2)")
    parser.add_argument("--first_seed", "--first-seed", dest="first_seed", type=int, default=0,
                        help="the first search seed (default: 0)")
    parser.add_argument("--arm", default=None, help="arm YAML (default: models/arm.yaml)")
    parser.add_argument("--no_wraps", "--no-wraps", dest="wraps", action="store_false",
                        help="skip Algorithm 1's wraps of the planes")
    parser.add_argument("--signed", action="store_true",
                        help="sections may bend either way (default: towards the wrap's side)")
    parser.add_argument("--start", choices=("approach", "contact"), default="approach",
                        help="where the wrapped part starts (default: approach, the first "
                             "point within 5 mm; see wrapping/bound.py)")
    parser.add_argument("--turn", choices=("after_start", "from_base"),
                        default="after_start", help="where theta is measured from "
                        "(default: after_start; from_base with --start contact is the "
                        "degenerate literal measure, see wrapping/bound.py)")
    parser.add_argument("--maxiter", type=int, default=BoundParams.maxiter,
                        help=f"differential evolution's generations (default: "
                             f"{BoundParams.maxiter})")
    parser.add_argument("--figures", default=None, help="draw every plane into this folder")
    args = parser.parse_args()
    params = BoundParams(signed=args.signed, start=args.start, turn=args.turn,
                         maxiter=args.maxiter)
    out = run(args.dataset, args.per_category, args.seeds, params, args.arm, args.wraps,
              args.figures, args.first_seed)
    print(json_text(out, indent=2))


if __name__ == "__main__":
    main()
