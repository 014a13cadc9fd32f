"""`objects`: generate, import, place and look at object datasets.
"""

from __future__ import annotations

import sys

from .common import (
    UserError,
    add_json,
    check_limit_per_category,
    placement_kinds,
    print_json,
    set_down,
)

__all__ = ["COMMANDS"]


def _add_objects(subparsers):
    p = subparsers.add_parser(
        "objects", help="generate, import and look at object datasets",
        description="Object datasets: a folder of meshes in the standard pose plus "
                    "manifest.json. Example: drake-continuum objects generate --out data/objects")
    sub = p.add_subparsers(dest="objects_command", metavar="ACTION", required=True)
    g = sub.add_parser("generate", help="generate the paper's 185 objects (10 categories)")
    g.add_argument("--out", required=True, help="output folder, e.g. data/objects (required)")
    g.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    g.add_argument("--workers", type=int, default=None,
                   help="worker processes (default: number of CPUs)")
    i = sub.add_parser(
        "import", help="import meshes laid out as SRC/<label>/<name>.obj",
        description="Import meshes laid out as SRC/<label>/<name>.{obj,stl,ply,off}: each "
                    "folder name is a category label, kept as given (any two or more labels; "
                    "the paper's ten are also recognised in 3DNet's spellings). Example: "
                    "drake-continuum objects import my_meshes --out data/mine --units mm")
    i.add_argument("src", help="source folder, e.g. ~/3DNet/Cat10 (required)")
    i.add_argument("--out", required=True, help="output folder, e.g. data/real (required)")
    i.add_argument("--units", choices=["mm", "cm", "m"], default=None,
                   help="units of the source meshes; a mesh whose size fits only other "
                        "units is skipped naming them (default: guessed per mesh from its "
                        "size; a mesh whose size fits no unit or two is skipped asking for "
                        "--units)")
    i.add_argument("--list", dest="list_file", default=None,
                   help="import only the meshes named in this list, e.g. "
                        "data/zhang2016_185_objects.txt (default: all)")
    i.add_argument("--up", choices=["z", "y"], default="z",
                   help="the source meshes' up axis (default: z)")
    pl = sub.add_parser(
        "place", help="write placed copies of a dataset's objects (turned, on another side, "
                      "off the mark)",
        description="Write copies of a dataset's objects set down as a robot meets them: on "
                    "one of their stable sides (trimesh's stable poses), turned about the "
                    "vertical, off the mark the arm aims at. Kinds: " + "; ".join(
                        f"{k}: {v}" for k, v in placement_kinds().items()) + ". The copies "
                    "form a dataset of their own (ids OBJECT@KINDk, manifest records with "
                    "source_id and placement), the same for a seed; collect and evaluate "
                    "it like any other. Example: drake-continuum objects place data/objects "
                    "--out data/placed --placements turned=1,rest=1,nudged=1 --seed 1")
    pl.add_argument("dataset", help="dataset folder holding manifest.json (required)")
    pl.add_argument("--out", required=True, help="output folder, e.g. data/placed (required)")
    pl.add_argument("--placements", default=None,
                    help="placements of each object: N (N training placements: a rest pose "
                         "drawn by its probability, any turn) or KIND=N,... e.g. "
                         "turned=2,rest=1,nudged=1,jitter=2 (default: 1)")
    pl.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    pl.add_argument("--limit-per-category", type=int, default=None, metavar="K",
                    help="only the first K objects of each category (default: all)")
    pl.add_argument("--ids", default=None,
                    help="comma-separated object ids, e.g. mug_000,cup_003 (default: all)")
    pl.add_argument("--rest-pose", type=int, default=None,
                    help="instead of random placements, set every object down on this "
                         "stable pose (0: the most probable; default: as generated)")
    pl.add_argument("--turn", type=float, default=None,
                    help="... turned this many degrees about the vertical (default: 0)")
    pl.add_argument("--offset", default=None,
                    help="... this far off the mark, x,y in m, e.g. 0.01,0 (default: 0,0)")
    s = sub.add_parser("show", help="draw every object of a dataset into one PNG")
    s.add_argument("dir", help="dataset folder holding manifest.json (required)")
    s.add_argument("--png", default="gallery.png", help="output picture (default: gallery.png)")
    for action in (g, i, pl):
        action.add_argument("--force", action="store_true",
                            help="replace a dataset already in --out (default: refuse)")
    for action in (g, i, pl, s):
        add_json(action)
    return p


def _print_dataset(args, manifest, extra: dict | None = None) -> None:
    """What `objects generate/place` wrote: JSON, or one line a category."""
    from ..objects.dataset import load_manifest
    counts = load_manifest(manifest.parent).counts()
    if args.json:
        print_json({"manifest": str(manifest), "counts": counts, **(extra or {})})
        return
    print(f"wrote {manifest}: {sum(counts.values())} objects "
          f"({', '.join(f'{c} {n}' for c, n in counts.items())})")


def _run_objects(args):
    from ..objects.dataset import DatasetError, generate_dataset, load_manifest
    if args.objects_command == "generate":
        path = generate_dataset(args.out, seed=args.seed, workers=args.workers,
                                progress=not args.quiet, overwrite=args.force)
        _print_dataset(args, path)
    elif args.objects_command == "import":
        from ..objects.importer import import_folder
        report = import_folder(args.src, args.out, units=args.units, list_file=args.list_file,
                               up=args.up, overwrite=args.force)
        for path, reason in report.skipped:
            print(f"skipped {path}: {reason}", file=sys.stderr)
        for entry in report.missing:
            print(f"not found: {entry}", file=sys.stderr)
        dataset = load_manifest(report.manifest.parent)
        units = {}
        for o in dataset:
            units.setdefault(o.category, set()).add(o.params.get("units"))
        summary = {"manifest": str(report.manifest), "imported": len(report.imported),
                   "skipped": len(report.skipped), "not_found": len(report.missing),
                   "counts": dataset.counts(),
                   "units": {c: sorted(u) for c, u in units.items()}}
        if args.json:
            print_json(summary)
        else:
            above = " (listed above)" if report.skipped or report.missing else ""
            print(f"wrote {report.manifest}: imported {summary['imported']} meshes, skipped "
                  f"{summary['skipped']}, not found {summary['not_found']}{above}")
            for c, n in summary["counts"].items():
                print(f"  {c}: {n} meshes, units {', '.join(summary['units'][c])}")
    elif args.objects_command == "place":
        return _run_place(args)
    else:
        from ..objects.gallery import render_gallery
        try:
            dataset = load_manifest(args.dir)
        except DatasetError as e:
            raise UserError(str(e)) from None
        png = render_gallery(dataset, args.png)
        if args.json:
            print_json({"png": str(png), "n_objects": len(dataset)})
        else:
            print(f"wrote {png}")
    return 0


def _run_place(args):
    from ..objects.dataset import DatasetError
    from ..objects.placement import PlacementError, parse_counts, place_dataset
    given = set_down(args, "")
    if given is not None and args.placements is not None:
        raise UserError("--placements draws placements; --rest-pose/--turn/--offset give one: "
                        "use one or the other")
    check_limit_per_category(args)
    text = args.placements or "1"
    try:
        counts = {"train": int(text)} if text.strip().isdigit() else parse_counts(text)
        ids = (None if args.ids is None
               else [i.strip() for i in args.ids.split(",") if i.strip()])
        path = place_dataset(args.dataset, args.out, counts, seed=args.seed, ids=ids,
                             limit_per_category=args.limit_per_category, given=given,
                             overwrite=args.force,
                             progress=not args.quiet)
    except (PlacementError, DatasetError) as e:
        raise UserError(str(e)) from None
    _print_dataset(args, path)
    return 0


# (name, add_function, run_function) of each command here
COMMANDS = [
    ("objects", _add_objects, _run_objects),
]
