"""`collect`, `reproduce`: the experiments.
"""

from __future__ import annotations

import sys

from .common import (
    UserError,
    add_bearing,
    add_config_options,
    add_json,
    check_limit_per_category,
    command_config,
    print_json,
    shortcut,
)

__all__ = ["COMMANDS"]


def _check_cluster(scheduler) -> None:
    """--scheduler needs dask.distributed, an optional extra: say so before any work."""
    if scheduler is None:
        return
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        raise UserError("--scheduler needs Dask's distributed scheduler, which is not "
                        "installed: pip install 'drake-continuum[cluster]'") from None


def _add_reproduce(subparsers):
    p = subparsers.add_parser(
        "reproduce", help="the whole paper: dataset, wraps, Tables I-II, Fig. 5, 7, 8, report",
        description="Generate the dataset, collect every wrap, evaluate classification "
                    "(Table I, Fig. 7, the triangle baseline), active recognition (Table II and "
                    "the policy comparison) and the real-versus-simulated comparison (Fig. 8), "
                    "and write OUT/report.md and OUT/report.html. Resumes after an "
                    "interruption. Example: drake-continuum reproduce --quick --out results")
    p.add_argument("--out", default="results", help="results folder (default: results)")
    p.add_argument("--quick", action="store_true",
                   help="a first look: 4 objects a category (40), 20 splits and the "
                        "placements side=1,turned=1 of the first 2 a category (40 copies), "
                        "as much again for the "
                        "second dataset, and the camera study of 8 objects; `make run` is "
                        "this without the second dataset and the camera study (default: "
                        "off, the full 185 objects, 100 splits and every placement)")
    p.add_argument("--per-category", type=int, default=4,
                   help="objects a category with --quick, at least 4 so that a 50/50 split "
                        "trains on 2 (default: 4)")
    p.add_argument("--categories", default=None, metavar="A,B,...",
                   help="only these of the ten generated categories, at least two, e.g. "
                        "apple,bottle,mug (default: all ten)")
    p.add_argument("--splits", type=int, default=None,
                   help="random 50/50 splits (default: 100; 20 with --quick)")
    p.add_argument("--workers", type=int, default=None,
                   help="local processes for wrapping and active recognition (default: all "
                        "cores)")
    p.add_argument("--scheduler", default=None,
                   help="Dask scheduler address, e.g. tcp://10.0.0.5:8786, to wrap on a "
                        "cluster (default: local processes)")
    p.add_argument("--seed", type=int, default=0, help="seed of everything (default: 0)")
    p.add_argument("--redo", action="store_true",
                   help="OUT holds a run made with other settings: redo the steps they "
                        "change (default: refuse, naming the settings that differ)")
    p.add_argument("--placements", default=None,
                   help="placed copies of each object (objects place's KIND=N list): train "
                        "and side ones are trained on, the others tested, splits by object "
                        "(default: side=3,turned=1,rest=1,lying=1,nudged=1,jitter=1; with "
                        "--quick side=1,turned=1)")
    p.add_argument("--no-second-dataset", action="store_true",
                   help="skip the second generated dataset (seed + 1) (default: run it)")
    p.add_argument("--no-observed", action="store_true",
                   help="skip recognition from what the simulated camera sees of the arm "
                        "(minutes of cloud fitting) (default: run it)")
    p.add_argument("--results-md", default=None, metavar="FILE",
                   help="write the results page here, its images copied into an images/ "
                        "folder beside it, e.g. docs/results.md (default: OUT/results.md)")
    add_json(p)
    add_config_options(p)
    return p


def _checked_counts(text: str) -> str:
    from ..objects.placement_kinds import PlacementError, parse_counts
    try:
        parse_counts(text)
    except PlacementError as e:
        raise UserError(f"--placements: {e}") from None
    return text


def _run_reproduce(args):
    from pathlib import Path

    from ..errors import InputError
    from ..experiments.reproduce import PLACEMENTS, QUICK_PLACEMENTS, RunSettings, reproduce
    from ..experiments.settings import checked_categories
    config = command_config(args)
    _check_cluster(args.scheduler)
    if args.per_category < 4:
        raise UserError(f"--per-category must be at least 4 (a 50/50 split must train on 2 "
                        f"objects a category to calibrate the SVM), got {args.per_category}")
    placements = args.placements or (QUICK_PLACEMENTS if args.quick else PLACEMENTS)
    try:
        categories = None if args.categories is None else checked_categories(
            c.strip() for c in args.categories.split(","))
    except InputError as e:
        raise UserError(f"--{e}") from None
    report = reproduce(RunSettings(out=Path(args.out), quick=args.quick,
                                   per_category=args.per_category, categories=categories,
                                   splits=args.splits,
                                   workers=args.workers, scheduler=args.scheduler,
                                   seed=args.seed, config=config, redo=args.redo,
                                   placements=_checked_counts(placements),
                                   second_dataset=not args.no_second_dataset,
                                   observed=not args.no_observed,
                                   results_md=None if args.results_md is None
                                   else Path(args.results_md)))
    if args.json:
        print_json({"report": str(report), "html": str(report.with_suffix(".html")),
                     "summary": str(report.parent / "summary.json")})
    else:
        import json

        from ..experiments.timing import run_work, step_table, work_table
        figures = json.loads((report.parent / "summary.json").read_text())
        print(step_table(figures))
        print(work_table(run_work(figures)))
        print(f"wrote {report} and {report.with_suffix('.html')}")
    return 0


def _add_collect(subparsers):
    p = subparsers.add_parser(
        "collect", help="make every wrap of every object of a dataset (resumable, parallel)",
        description="Wrap every object of a dataset in every plane (the paper's alpha = "
                    "22.5 deg, 10 planes; Algorithm 1 with the paper's parameters) and store "
                    "each object's wraps as <object_id>.npz + .json, with index.json. A rerun "
                    "skips finished objects and retries failed ones; a folder made with other "
                    "parameters is refused. Runs on local processes, or on a Dask cluster "
                    "with --scheduler. "
                    "Example: drake-continuum collect data/objects --out data/wraps --workers 2")
    p.add_argument("dataset", help="dataset folder (manifest.json + meshes), required")
    p.add_argument("--out", required=True, help="wrap collection folder to write, required")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default: all cores)")
    p.add_argument("--scheduler", default=None,
                   help="Dask scheduler address to run on a cluster instead, e.g. "
                        "tcp://10.0.0.5:8786 (default: local processes)")
    p.add_argument("--limit-per-category", type=int, default=None, metavar="K",
                   help="only the first K objects of each category, for quick runs "
                        "(default: all)")
    p.add_argument("--ids", default=None,
                   help="comma-separated object ids to wrap, e.g. mug_000,cup_003 "
                        "(default: all)")
    p.add_argument("--both-directions", action="store_true", default=None,
                   help="wrap every plane clockwise and counter-clockwise: 20 planes, a "
                        "shortcut for --set planes.both_directions=true (default: the "
                        "configuration's, Fig. 4's one direction a plane family, 10 planes)")
    add_bearing(p)
    p.add_argument("--prune", action="store_true",
                   help="first remove the stored objects the dataset no longer holds as "
                        "they were wrapped (an id its manifest does not list, or a changed "
                        "mesh), e.g. after placing a dataset again with other counts "
                        "(default: keep them, and refuse a changed mesh)")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (default: shown on stderr; -q hides it too)")
    add_json(p)
    add_config_options(p)
    return p


def _run_collect(args):
    from ..experiments.collect import CollectLockError, collect
    cfg = command_config(args, shortcut("planes.both_directions", args.both_directions),
                  shortcut("planes.bearing", args.bearing), uses=("arm", "planes", "wrap"))
    _check_cluster(args.scheduler)
    check_limit_per_category(args)
    ids = (None if args.ids is None
           else [i.strip() for i in args.ids.split(",") if i.strip()])
    try:
        report = collect(args.dataset, args.out, cfg, workers=args.workers,
                         scheduler=args.scheduler, ids=ids,
                         limit_per_category=args.limit_per_category,
                         progress=not (args.no_progress or args.quiet), prune=args.prune)
    except CollectLockError as e:
        raise UserError(str(e)) from None
    except OSError as e:  # e.g. a Dask scheduler that cannot be reached
        if args.scheduler is None:
            raise
        raise UserError(f"Dask scheduler {args.scheduler}: {type(e).__name__}: {e}") from None
    if report.pruned and not args.quiet:
        print(f"removed {len(report.pruned)} stored object(s) the dataset no longer holds as "
              f"wrapped: {', '.join(report.pruned)}", file=sys.stderr)
    for oid, message in report.failed.items():
        print(f"failed: {oid}: {message}", file=sys.stderr)
    if args.json:
        print_json(report.to_dict())
    else:
        print(f"wrapped {len(report.done)} objects ({report.n_wraps} wraps) in "
              f"{report.time_s:.0f} s; {len(report.skipped)} already done, "
              f"{len(report.failed)} failed{' (listed above)' if report.failed else ''}; "
              f"wrote {report.out_dir}")
        if report.work_s:
            from ..experiments.timing import work_table
            print("\nwork by kind, CPU seconds of the workers and of this process:\n"
                  + work_table(report.work_s))
    return 1 if report.failed else 0


# (name, add_function, run_function) of each command here
COMMANDS = [
    ("reproduce", _add_reproduce, _run_reproduce),
    ("collect", _add_collect, _run_collect),
]
