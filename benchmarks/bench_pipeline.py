"""Where a reproduction's time goes, by step and by kind of work. Prints JSON.

Runs `make run`'s work (`reproduce --quick --no-second-dataset --no-observed`), or with
--defaults the quick reproduction with its defaults (`reproduce --quick`), or with --full the
full one without the second dataset, into a temporary folder, and reports each step's wall
time, the work by kind in CPU seconds (experiments/timing.py: wraps, camera, IK, contact
queries, training, active recognition, ...), the CPU time of this process and its workers, and
the share of it the kinds account for (work_over_cpu). Goals: `make run`
at most 60 s, the quick reproduction at most 5 min, the full one without the second dataset
at most 10 min (on two quiet cores). On a shared machine the wall times grow with the load;
the CPU time and the ratios between kinds stay comparable (the load is recorded beside them).

    python benchmarks/bench_pipeline.py [--defaults | --full] [--workers N] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import tempfile
import time
from pathlib import Path

from drake_continuum.experiments.reproduce import QUICK_PLACEMENTS, RunSettings, reproduce
from drake_continuum.experiments.timing import run_work, work_total

GOALS_S = {"make_run": 60.0, "quick": 300.0, "full": 600.0}


def _cpu_s() -> float:
    own, children = (resource.getrusage(w) for w in (resource.RUSAGE_SELF,
                                                     resource.RUSAGE_CHILDREN))
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def run(kind: str, out: Path, workers: int | None) -> dict:
    if kind == "make_run":
        settings = RunSettings(out=out, quick=True, placements=QUICK_PLACEMENTS,
                               second_dataset=False, observed=False, workers=workers)
    elif kind == "quick":  # the command line's --quick places QUICK_PLACEMENTS
        settings = RunSettings(out=out, quick=True, placements=QUICK_PLACEMENTS,
                               workers=workers)
    else:
        settings = RunSettings(out=out, second_dataset=False, workers=workers)
    load_before, cpu0, t0 = os.getloadavg()[0], _cpu_s(), time.perf_counter()
    reproduce(settings)
    wall, cpu = time.perf_counter() - t0, _cpu_s() - cpu0
    figures = json.loads((out / "summary.json").read_text())
    return {"run": kind, "wall_s": round(wall, 1), "goal_s": GOALS_S[kind],
            "cpu_s": round(cpu, 1), "workers": workers or os.cpu_count(),
            "load_before": load_before, "load_after": os.getloadavg()[0],
            "steps_s": {k: round(v.get("time_s", 0.0), 1) for k, v in figures.items()},
            "work_s": {k: round(v, 1) for k, v in run_work(figures).items()},
            "work_over_cpu": round(work_total(run_work(figures)) / cpu, 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--defaults", action="store_true",
                       help="the quick reproduction with its defaults")
    which.add_argument("--full", action="store_true",
                       help="the full reproduction without the second dataset")
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--keep", default=None, help="results folder to keep (default: a "
                                                     "temporary one)")
    args = parser.parse_args()
    kind = "quick" if args.defaults else "full" if args.full else "make_run"
    if args.keep:
        print(json.dumps(run(kind, Path(args.keep), args.workers), indent=1))
        return
    with tempfile.TemporaryDirectory(prefix="bench-pipeline-") as tmp:
        print(json.dumps(run(kind, Path(tmp) / "results", args.workers), indent=1))


if __name__ == "__main__":
    main()
