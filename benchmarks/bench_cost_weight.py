"""The tree search's movement weight (lambda of eq. 1, active.cost_weight): accuracy, wraps
and base movement at the stop of MCTS for each weight, and greedy's (which ignores
movement) once, on one split of a wrap collection by object (evaluate-active's). Prints JSON
(one entry a weight) and, with --md, a Markdown table.

Example (seed 0's wraps, its placed copies; train on the originals and their side copies,
test the held-out half's turned, other-side, lying and nudged copies):
  python benchmarks/bench_cost_weight.py WRAPS --placed PLACED --train-kinds generated,side \
      --weights 0.5,0.6,0.7,0.8 --md
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

from drake_continuum.active.training import evaluate_active
from drake_continuum.config import load_config


def _row(name: str, r: dict) -> dict:
    return {"policy": name, "accuracy_at_stop": r["accuracy_at_stop"],
            "wraps_to_stop": r["wraps_to_stop"],
            "movement_cost_to_stop_rad": r["movement_cost_to_stop_rad"],
            "by_kind": r.get("by_kind"), "n_objects": r["n_objects"]}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("wraps", help="wrap collection folder")
    parser.add_argument("--placed", action="append", default=[],
                        help="placed copies' wrap collection (repeatable), as evaluate-active")
    parser.add_argument("--train-kinds", default="generated",
                        help="records trained on, comma-separated (default: generated)")
    parser.add_argument("--test", action="append", default=[],
                        help="another dataset's wrap collection to test on (repeatable)")
    parser.add_argument("--weights", default="0.5,0.6,0.7,0.8",
                        help="cost weights to try, comma-separated (default: 0.5,0.6,0.7,0.8)")
    parser.add_argument("--seed", type=int, default=0, help="split and search seed (default: 0)")
    parser.add_argument("--md", action="store_true", help="also print a Markdown table")
    a = parser.parse_args(argv)
    cfg = load_config()
    common = dict(seed=a.seed, chords=cfg.chords, classifier=cfg.classifier,
                  placed=a.placed, test=a.test,
                  train_kinds=tuple(k for k in a.train_kinds.split(",") if k))
    rows = []
    greedy = evaluate_active(a.wraps, policies=("greedy",), params=cfg.active, **common)
    rows.append(_row("greedy", greedy["policies"]["greedy"]))
    for w in (float(v) for v in a.weights.split(",")):
        r = evaluate_active(a.wraps, policies=("mcts",), params=replace(cfg.active, cost_weight=w),
                            **common)
        rows.append(_row(f"mcts, cost_weight {w:g}", r["policies"]["mcts"]))
    print(json.dumps(rows, indent=1))
    if a.md:
        print("\n| policy | accuracy at stop | wraps | movement (rad) |\n|---|---:|---:|---:|")
        for r in rows:
            print(f"| {r['policy']} | {100 * r['accuracy_at_stop']:.1f} % | "
                  f"{r['wraps_to_stop']:.2f} | {r['movement_cost_to_stop_rad']:.2f} |")


if __name__ == "__main__":
    main()
