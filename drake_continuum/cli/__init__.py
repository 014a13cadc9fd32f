"""`drake-continuum`: the command-line tool.

Each subcommand is a pair of functions here: `_add_<name>(subparsers)` declares its
arguments (help texts end with the default and carry an example), `_run_<name>(args)` runs it
by calling the library. Commands are listed in COMMANDS at the bottom; only commands that work
are listed.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import traceback

from ..errors import DrakeContinuumError

__all__ = ["main", "build_parser"]

log = logging.getLogger("drake_continuum")
INTERNAL_ERROR = 70  # exit status of a bug (sysexits' EX_SOFTWARE); 1 is a user's error


class UserError(DrakeContinuumError):
    """An error the user can fix; printed without a traceback."""


def _add_config_options(p, default="models/config.yaml"):
    """--config and --set: the experiment configuration of a command that wraps, collects,
    trains or recognises."""
    p.add_argument("--config", default=None, metavar="FILE",
                   help=f"experiment configuration YAML, e.g. my-config.yaml (default: "
                        f"{default})")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one configuration entry, e.g. --set wrap.delta=0.002 "
                        "(repeatable; default: none)")


def _config(args, *shortcuts):
    """The command's configuration: --config, then the command's own options given as
    "key=value" shortcuts (None values skipped), then --set (the most explicit wins)."""
    from ..config import load_config
    return load_config(args.config, [s for s in shortcuts if s is not None] + list(args.set))


def _shortcut(key: str, value):
    """"key=value" for an option that sets a configuration entry, None when not given."""
    from ..files import json_text
    if value is None:
        return None
    return f"{key}={json_text(value, indent=None)}"


def _print_json(obj) -> None:
    from ..files import json_text
    sys.stdout.write(json_text(obj) + "\n")


COMMANDS: list = []  # (name, add_function, run_function), filled below
RESUMABLE = ("collect", "reproduce")  # commands that continue where an interrupted run stopped


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
    i = sub.add_parser("import", help="import real meshes laid out as SRC/<category>/<name>.obj")
    i.add_argument("src", help="source folder, e.g. ~/3DNet/Cat10 (required)")
    i.add_argument("--out", required=True, help="output folder, e.g. data/real (required)")
    i.add_argument("--units", choices=["mm", "cm", "m"], default=None,
                   help="units of the source meshes (default: guessed per mesh from its size)")
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
                        f"{k}: {v}" for k, v in _placement_kinds().items()) + ". The copies "
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
    return p


def _run_objects(args):
    from ..objects.dataset import DatasetError, generate_dataset, load_manifest
    if args.objects_command == "generate":
        path = generate_dataset(args.out, seed=args.seed, workers=args.workers)
        _print_json({"manifest": str(path), "counts": load_manifest(args.out).counts()})
    elif args.objects_command == "import":
        from ..objects.importer import import_folder
        report = import_folder(args.src, args.out, units=args.units, list_file=args.list_file,
                               up=args.up)
        for path, reason in report.skipped:
            print(f"skipped {path}: {reason}", file=sys.stderr)
        for entry in report.missing:
            print(f"not found: {entry}", file=sys.stderr)
        _print_json({"manifest": str(report.manifest), "imported": len(report.imported),
                     "skipped": len(report.skipped), "not_found": len(report.missing)})
    elif args.objects_command == "place":
        return _run_place(args)
    else:
        from ..objects.gallery import render_gallery
        try:
            dataset = load_manifest(args.dir)
        except DatasetError as e:
            raise UserError(str(e)) from None
        print(render_gallery(dataset, args.png))
    return 0


def _placement_kinds() -> dict:
    from ..objects.placement import KINDS
    return KINDS


def _set_down(args, where: str):
    """The Placement of --rest-pose/--turn/--offset, or None when none is given."""
    import math

    from ..objects.placement import Placement
    if args.rest_pose is None and args.turn is None and args.offset is None:
        return None
    offset = (0.0, 0.0) if args.offset is None else tuple(_floats(args.offset, 2, "--offset"))
    return Placement(args.rest_pose, math.radians(args.turn or 0.0), offset)


def _run_place(args):
    from ..objects.dataset import DatasetError
    from ..objects.placement import PlacementError, parse_counts, place_dataset
    given = _set_down(args, "")
    if given is not None and args.placements is not None:
        raise UserError("--placements draws placements; --rest-pose/--turn/--offset give one: "
                        "use one or the other")
    text = args.placements or "1"
    try:
        counts = {"train": int(text)} if text.strip().isdigit() else parse_counts(text)
        ids = [i.strip() for i in args.ids.split(",") if i.strip()] if args.ids else None
        path = place_dataset(args.dataset, args.out, counts, args.seed, ids,
                             args.limit_per_category, given=given)
    except (PlacementError, DatasetError) as e:
        raise UserError(str(e)) from None
    from ..objects.dataset import load_manifest
    _print_json({"manifest": str(path), "counts": load_manifest(args.out).counts()})
    return 0


COMMANDS.append(("objects", _add_objects, _run_objects))


def _load_objects(wraps_dir, chords, strict: bool = False):
    """Wrap collection -> (ObjectRecords, skipped), chords as ChordParams `chords`; the
    objects left out are named on stderr, or with `strict` refused."""
    import warnings

    from ..learning.records import WrapDataWarning, load_collection
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", WrapDataWarning)
        objects, skipped = load_collection(wraps_dir, chords)
    for w in caught:
        print(f"warning: {w.message}", file=sys.stderr)
    if skipped and strict:
        raise UserError(f"{wraps_dir}: {len(skipped)} object(s) cannot be used (--strict): "
                        + "; ".join(f"{s['object_id']}: {s['reason']}" for s in skipped))
    for s in skipped:
        print(f"warning: skipped object {s['object_id']}: {s['reason']}", file=sys.stderr)
    return objects, skipped


def _add_strict(p):
    p.add_argument("--strict", action="store_true",
                   help="fail if any object of the collection is missing, damaged or failed "
                        "in collection (default: leave it out, named on stderr and in the "
                        "outputs)")


def _check_categories(objects, minimum: int) -> None:
    from collections import Counter
    counts = Counter(o.category for o in objects)
    few = {c: n for c, n in counts.items() if n < minimum}
    if len(counts) < 2 or few:
        raise UserError(f"need at least 2 categories with at least {minimum} objects each; "
                        f"got {dict(counts)}")


def _add_evaluate(subparsers):
    p = subparsers.add_parser(
        "evaluate", help="accuracy over random 50/50 splits, chords and the triangle baseline",
        description="Classify the objects of a wrap collection over random stratified 50/50 "
                    "splits (the paper's V-B) with chord histograms and with [1]'s triangle "
                    "histograms on the same splits; write the confusion matrices (PNG), "
                    "Table I (Markdown, JSON) and evaluation.json. "
                    "Example: drake-continuum evaluate data/wraps --out results/evaluate")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--splits", type=int, default=100, help="random splits (default: 100)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--frame", choices=["world", "wrap"], default=None,
                   help="frame of the chord angles, a shortcut for --set chords.frame=... "
                        "(default: the configuration's, world: the paper's)")
    p.add_argument("--out", default="results/evaluate",
                   help="output folder (default: results/evaluate)")
    p.add_argument("--placed", action="append", default=[], metavar="WRAPS",
                   help="also test on placed copies: the wrap collection of `objects place` "
                        "output (repeatable); accuracy as generated, turned, on another "
                        "side, nudged and the flip rate, splits by object, in "
                        "OUT/placements.md and .json (default: none)")
    p.add_argument("--train-kinds", default="generated",
                   help="with --placed, the records trained on: generated (the originals) "
                        "and/or train (their training placements), e.g. generated,train "
                        "(default: generated)")
    p.add_argument("--turn-invariant", action="store_true",
                   help="wrap descriptors pooled over planes and the contact extent along "
                        "the contacts' own horizontal axes, unchanged when the object turns, "
                        "a shortcut for --set classifier.turn_invariant=true (default: the "
                        "configuration's, off: one slot a plane and world x, y)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    _add_strict(p)
    _add_config_options(p)
    return p


def _turn_invariant(args):
    """--turn-invariant: a shortcut for --set classifier.turn_invariant=true."""
    return _shortcut("classifier.turn_invariant", True) if args.turn_invariant else None


def _evaluate_placed(args, objects, cfg) -> dict:
    """evaluate --placed: chords and triangles on placed copies; writes OUT/placements.*"""
    from pathlib import Path

    from ..files import write_atomic, write_json
    from ..learning.placements import evaluate_placements, placements_table
    kinds = tuple(k.strip() for k in args.train_kinds.split(",") if k.strip())
    bad = set(kinds) - {"generated", "train"}
    if bad or not kinds:
        raise UserError(f"--train-kinds must name generated and/or train, got "
                        f"{args.train_kinds!r}")
    records = list(objects)
    for folder in args.placed:
        records += _load_objects(folder, cfg.chords, args.strict)[0]
    results = {m: evaluate_placements(records, args.splits, args.seed, m, cfg.classifier, kinds)
               for m in ("chords", "triangles")}
    out = Path(args.out)
    table = placements_table(results)
    write_atomic(out / "placements.md", table.encode())
    write_json(out / "placements.json", results)
    return {"table": table, "results": results}


def _run_evaluate(args):
    from ..learning.evaluation import evaluate_to_folder
    if args.splits < 1:
        raise UserError(f"--splits must be at least 1, got {args.splits}")
    cfg = _config(args, _shortcut("chords.frame", args.frame), _turn_invariant(args))
    objects, skipped = _load_objects(args.wraps, cfg.chords, args.strict)
    _check_categories(objects, 4)
    summary = evaluate_to_folder(objects, args.out, args.splits, args.seed, cfg.classifier,
                                 skipped=skipped)
    del summary["table1"]
    summary["out"] = str(args.out)
    placed = _evaluate_placed(args, objects, cfg) if args.placed else None
    if placed:
        summary["placements"] = {
            m: {"kinds": {k: v["accuracy_mean"] for k, v in r["kinds"].items()},
                "flip_rate": r["flips"]["rate"]} for m, r in placed["results"].items()}
    if args.json:
        _print_json(summary)
    else:
        print(f"{len(objects)} objects, {args.splits} splits: chords "
              f"{summary['accuracy_mean']:.1%} +- {summary['accuracy_std']:.1%}, triangles "
              f"{summary['baseline_accuracy_mean']:.1%} +- "
              f"{summary['baseline_accuracy_std']:.1%}; wrote {args.out}")
        if skipped:
            print(f"left out {len(skipped)} object(s) of the collection (listed in "
                  f"evaluation.json): {', '.join(s['object_id'] for s in skipped)}")
        wrong = summary["misclassified"]
        if wrong:
            print(f"most often wrong (of {len(wrong)} ever wrong; all in evaluation.json):")
            for r in wrong[:5]:
                taken = ", ".join(f"{c} {n}" for c, n in r["as"].items())
                print(f"  {r['object_id']} ({r['category']}): wrong {r['wrong']} of "
                      f"{r['tested']} (as {taken})")
            print(f"see one: drake-continuum show-wraps {args.wraps} "
                  f"{wrong[0]['object_id']} --png wraps.png")
        if placed:
            print(f"placed objects ({args.splits} splits by object; {args.out}/placements.md):")
            print(placed["table"], end="")
    return 0


COMMANDS.append(("evaluate", _add_evaluate, _run_evaluate))


def _add_train(subparsers):
    p = subparsers.add_parser(
        "train", help="train the chord classifier on every object and save it",
        description="Fit the chord-histogram classifier on all objects of a wrap collection "
                    "and save it as model.json + model.npz (no pickle). "
                    "Example: drake-continuum train data/wraps --out models/classifier")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--out", required=True, help="model folder to write, required")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--frame", choices=["world", "wrap"], default=None,
                   help="frame of the chord angles, a shortcut for --set chords.frame=... "
                        "(default: the configuration's, world: the paper's)")
    p.add_argument("--placed", action="append", default=[], metavar="WRAPS",
                   help="also train on these collections' placed copies of kind train "
                        "(`objects place --placements N`, then collect; repeatable; "
                        "default: none)")
    p.add_argument("--turn-invariant", action="store_true",
                   help="wrap descriptors pooled over planes, contact extent along the "
                        "contacts' own horizontal axes, a shortcut for --set "
                        "classifier.turn_invariant=true (default: the configuration's, off)")
    _add_strict(p)
    _add_config_options(p)
    return p


def _run_train(args):
    from ..config import training_settings
    from ..learning.model import save_model, train
    from ..objects.placement import placement_kind
    cfg = _config(args, _shortcut("chords.frame", args.frame), _turn_invariant(args))
    settings = training_settings(cfg, args.wraps)
    objects, skipped = _load_objects(args.wraps, cfg.chords, args.strict)
    for folder in args.placed:
        more, also = _load_objects(folder, cfg.chords, args.strict)
        objects += [o for o in more if placement_kind(o.object_id) == "train"]
        skipped += also
    _check_categories(objects, 2)
    model = train(objects, seed=args.seed, params=cfg.chords, classifier=cfg.classifier)
    model.info["settings"] = settings
    save_model(model, args.out)
    _print_json({"model": str(args.out), "classes": list(model.classes),
                 **{k: v for k, v in model.info.items() if k != "settings"},
                 "skipped": skipped})
    return 0


COMMANDS.append(("train", _add_train, _run_train))


def _add_show_wraps(subparsers):
    p = subparsers.add_parser(
        "show-wraps", help="draw the stored wraps of one object of a collection",
        description="Draw every usable wrap that `collect` stored for OBJECT_ID on its mesh, "
                    "one cell a plane (e.g. an object `evaluate` lists as often wrong). The "
                    "mesh is found in the collection's dataset, or in --dataset, and must be "
                    "the one wrapped (same SHA-256). "
                    "Example: drake-continuum show-wraps results-full/wraps donut_003 --png "
                    "donut_003.png")
    p.add_argument("wraps", help="wrap collection folder (drake-continuum collect), required")
    p.add_argument("object_id", help="object to draw, e.g. bowl_003, required")
    p.add_argument("--png", required=True, help="picture to write, required")
    p.add_argument("--dataset", default=None,
                   help="folder holding the object's mesh (default: the collection's dataset "
                        "as recorded in its index.json)")
    p.add_argument("--json", action="store_true", help="print what was drawn as JSON")
    return p


def _run_show_wraps(args):
    import yaml

    from ..experiments.collect import wrapped_mesh_path
    from ..kinematics.arm import ContinuumArm, load_arm
    from ..learning.records import WrapFileError, read_object_wraps
    from ..objects.mesh import load_mesh
    from ..viz.plots import plot_object_wraps
    try:
        meta, wraps = read_object_wraps(args.wraps, args.object_id)
    except WrapFileError as e:
        raise UserError(f"{args.object_id}: {e}") from None
    try:
        mesh = load_mesh(wrapped_mesh_path(args.wraps, args.object_id, meta, args.dataset))
    except (OSError, ValueError) as e:  # MeshError is a ValueError
        raise UserError(str(e)) from None
    usable = [w for w in wraps if w.usable]
    if not usable:
        raise UserError(f"{args.object_id}: none of its {len(wraps)} wraps is usable "
                        f"(statuses: {', '.join(sorted({w.status for w in wraps}))})")
    n = len(usable)
    arm_yaml = (meta.get("params") or {}).get("arm_yaml")  # the arm the wraps were made with
    arm = load_arm() if arm_yaml is None else ContinuumArm.from_dict(yaml.safe_load(arm_yaml))
    png = plot_object_wraps(mesh, arm, usable, args.png)
    out = {"object_id": args.object_id, "category": meta.get("category"),
           "n_wraps": len(wraps), "n_usable": n, "planes": [w.plane_index for w in usable],
           "png": str(png)}
    if args.json:
        _print_json(out)
    else:
        print(f"{args.object_id} ({out['category']}): {n} of {len(wraps)} wraps drawn in {png}")
    return 0


COMMANDS.append(("show-wraps", _add_show_wraps, _run_show_wraps))


def _active_config(args):
    return _config(args, _shortcut("active.seed", args.seed),
                   _shortcut("active.n_simulations", args.simulations),
                   _shortcut("chords.frame", args.frame))


def _add_active_options(p):
    p.add_argument("--seed", type=int, default=None,
                   help="random seed of the split, classifier and searches, a shortcut for "
                        "--set active.seed=... (default: the configuration's, 0)")
    p.add_argument("--simulations", type=int, default=None,
                   help="simulations a tree search, a shortcut for --set "
                        "active.n_simulations=... (default: the configuration's, 200)")
    p.add_argument("--frame", choices=["world", "wrap"], default=None,
                   help="frame of the chord angles, a shortcut for --set chords.frame=... "
                        "(default: the configuration's, world: the paper's)")
    _add_strict(p)
    _add_config_options(p)


def _add_train_active(subparsers):
    p = subparsers.add_parser(
        "train-active", help="train the classifier and the observation tallies for recognition",
        description="Fit the chord classifier on every object of a wrap collection and tally "
                    "its wraps for active recognition (section IV-D.2); save both in one "
                    "folder (model.json/.npz, observations.json/.npz; no pickle). "
                    "Example: drake-continuum train-active data/wraps --out models/active")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--out", required=True, help="model folder to write, required")
    _add_active_options(p)
    return p


def _run_train_active(args):
    from ..active.training import save_active_model, train_active
    from ..config import training_settings
    cfg = _active_config(args)
    settings = training_settings(cfg, args.wraps)
    objects, skipped = _load_objects(args.wraps, cfg.chords, args.strict)
    _check_categories(objects, 2)
    model = train_active(args.wraps, params=cfg.active, seed=cfg.active.seed,
                         chords=cfg.chords, classifier=cfg.classifier, records=objects)
    model.classifier.info["settings"] = settings
    save_active_model(model, args.out)
    obs = model.observations
    _print_json({"model": str(args.out), "classes": [str(c) for c in obs.classes],
                 "n_observations": obs.n_observations, "n_pairs": int(len(obs.pair_from)),
                 "n_planes": obs.n_planes, "skipped": skipped})
    return 0


COMMANDS.append(("train-active", _add_train_active, _run_train_active))


def _add_evaluate_active(subparsers):
    p = subparsers.add_parser(
        "evaluate-active", help="active recognition on held-out objects: MCTS vs baselines",
        description="Train on one half of a stratified split of a wrap collection and "
                    "recognise every held-out object from its precomputed wraps with tree "
                    "search (MCTS), greedy information gain and random plane order; write "
                    "active.json, accuracy curves (curves.png) and Table II (table2.md). "
                    "Example: drake-continuum evaluate-active data/wraps --out results/active")
    p.add_argument("wraps", help="wrap collection folder (<object_id>.npz/.json), required")
    p.add_argument("--policy", choices=["mcts", "greedy", "random", "all"], default="all",
                   help="policy to evaluate (default: all)")
    p.add_argument("--out", default="results/active",
                   help="output folder (default: results/active)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--placed", action="append", default=[], metavar="WRAPS",
                   help="test on the held-out objects' placed copies (turned, on another "
                        "side, nudged) from this collection of `objects place` output "
                        "(repeatable), splitting by object (default: the originals)")
    p.add_argument("--train-kinds", default="generated",
                   help="with --placed, the records trained on: generated and/or train "
                        "(default: generated)")
    _add_active_options(p)
    return p


def _run_evaluate_active(args):
    from ..active.policies import POLICIES
    from ..active.training import evaluate_active
    cfg = _active_config(args)
    objects, _ = _load_objects(args.wraps, cfg.chords, args.strict)
    _check_categories(objects, 2)
    policies = POLICIES if args.policy == "all" else (args.policy,)
    kinds = tuple(k.strip() for k in args.train_kinds.split(",") if k.strip())
    if not kinds or set(kinds) - {"generated", "train"}:
        raise UserError(f"--train-kinds must name generated and/or train, got "
                        f"{args.train_kinds!r}")
    report = evaluate_active(args.wraps, policies=policies, params=cfg.active,
                             seed=cfg.active.seed, chords=cfg.chords,
                             classifier=cfg.classifier, out=args.out, placed=args.placed,
                             train_kinds=kinds)
    summary = {"n_train": report["n_train"], "n_test": report["n_test"], "out": str(args.out),
               "skipped": report["skipped"],
               "policies": {k: {m: v[m] for m in ("accuracy_at_stop", "wraps_to_stop",
                                                  "movement_cost_to_stop_rad",
                                                  "median_search_time_s", "by_kind")
                                if m in v}
                            for k, v in report["policies"].items()}}
    if args.json:
        _print_json(summary)
    else:
        for k, v in summary["policies"].items():
            kinds = "".join(f", {q} {a:.1%}" for q, a in v.get("by_kind", {}).items())
            print(f"{k}: accuracy {v['accuracy_at_stop']:.1%} after {v['wraps_to_stop']:.2f} "
                  f"wraps, movement {v['movement_cost_to_stop_rad']:.2f} rad{kinds}")
        print(f"wrote {args.out}")
    return 0


COMMANDS.append(("evaluate-active", _add_evaluate_active, _run_evaluate_active))


# ----------------------------------------------------------------- demo
# Curls around the shipped mug's body in the horizontal plane of the arm's base (z = 5 cm):
# section 1 swings out to -y, sections 2 and 3 follow a circle 0.5 mm inside the tube's
# touching radius about the body's axis, 270 deg round (through the handle's hole).
DEMO_CONFIG = {"s": [0.1402, 0.1373, 0.1373], "kappa": [4.408, 19.42, 19.42],
               "phi": [-1.5707963267948966, 1.5707963267948966, 1.5707963267948966]}


def _add_demo(subparsers):
    p = subparsers.add_parser(
        "demo", help="pose the arm around the mug, print its contacts, draw them",
        description="Pose the arm in a hand-chosen configuration that curls around the "
                    "shipped mug and touches it; print the contacts (position, normal from "
                    "the object into the arm, section) and draw them to OUT/demo.png. "
                    "Example: drake-continuum demo --out out/demo --html")
    p.add_argument("--out", default="out/demo", help="output directory (default: out/demo)")
    p.add_argument("--mesh", default=None,
                   help="object mesh in the standard pose; the pose is chosen for the "
                        "shipped mug (default: models/mug.obj)")
    p.add_argument("--html", action="store_true",
                   help="also write OUT/demo.html, a Meshcat page of the arm curling in "
                        "(default: off)")
    return p


def _contacts_table(contacts) -> str:
    rows = [f"{'#':>2} {'section':>7} {'arc (m)':>8}  {'p (m)':^26}  {'n (object -> arm)':^24}"
            f" {'area (mm^2)':>11}"]
    for i in range(len(contacts)):
        p, n = contacts.p[i], contacts.n[i]
        rows.append(f"{i:>2} {contacts.section[i] + 1:>7d} {contacts.arc_length[i]:>8.4f}  "
                    f"{p[0]:>8.4f} {p[1]:>8.4f} {p[2]:>8.4f}  "
                    f"{n[0]:>7.3f} {n[1]:>7.3f} {n[2]:>7.3f} {1e6 * contacts.area[i]:>11.1f}")
    return "\n".join(rows)


def _run_demo(args):
    from pathlib import Path

    import numpy as np

    from ..kinematics.arm import MODELS_DIR, ArmConfig, load_arm
    from ..viz import plots as viz
    from ..wrapping.scene import WrapScene
    arm = load_arm()
    mesh = Path(args.mesh) if args.mesh else MODELS_DIR / "mug.obj"
    config = ArmConfig.from_dict(DEMO_CONFIG)
    scene = WrapScene(arm, mesh)
    scene.set_config(config)
    contacts = scene.contacts()
    print(f"object {mesh}; arm s = {np.round(config.s, 4).tolist()} m, "
          f"kappa = {np.round(config.kappa, 3).tolist()} 1/m, "
          f"phi = {np.round(config.phi, 4).tolist()} rad")
    if len(contacts):
        print(f"{len(contacts)} contacts (sections numbered from 1 at the base):")
        print(_contacts_table(contacts))
    else:
        print("no contacts: the demo pose is chosen for the shipped mug")
    out = Path(args.out)
    png = viz.plot_wrap(scene.object_trimesh, arm, config, contacts, out / "demo.png",
                        title=f"{mesh.name}: {len(contacts)} contacts")
    print(f"wrote {png}")
    if args.html:
        curl = [ArmConfig(config.s, config.kappa * [1.0, a, a], config.phi)
                for a in np.linspace(0.6, 1.0, 25)]
        meshcat, _ = viz.show_wrap(arm, mesh, curl, contacts=contacts)
        print(f"wrote {viz.save_html(meshcat, out / 'demo.html')}")
    return 0


COMMANDS.append(("demo", _add_demo, _run_demo))


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
                   help="a first look: 4 objects a category and 20 splits, a few minutes "
                        "on 2 cores (default: off, the full 185 objects and 100 splits)")
    p.add_argument("--per-category", type=int, default=4,
                   help="objects a category with --quick, at least 4 so that a 50/50 split "
                        "trains on 2 (default: 4)")
    p.add_argument("--splits", type=int, default=100,
                   help="random 50/50 splits (default: 100; at most 20 with --quick)")
    p.add_argument("--workers", type=int, default=None,
                   help="local processes for wrapping (default: all cores)")
    p.add_argument("--scheduler", default=None,
                   help="Dask scheduler address, e.g. tcp://10.0.0.5:8786, to wrap on a "
                        "cluster (default: local processes)")
    p.add_argument("--seed", type=int, default=0, help="seed of everything (default: 0)")
    p.add_argument("--redo", action="store_true",
                   help="OUT holds a run made with other settings: redo the steps they "
                        "change (default: refuse, naming the settings that differ)")
    p.add_argument("--placements", default="train=2,turned=1,rest=1,nudged=1,jitter=1",
                   help="placed copies of each object (objects place's KIND=N list): train "
                        "ones are trained on, the others tested, splits by object (default: "
                        "train=2,turned=1,rest=1,nudged=1,jitter=1)")
    p.add_argument("--no-second-dataset", action="store_true",
                   help="skip the second generated dataset (seed + 1) (default: run it)")
    _add_config_options(p)
    return p


def _checked_counts(text: str) -> str:
    from ..objects.placement import PlacementError, parse_counts
    try:
        parse_counts(text)
    except PlacementError as e:
        raise UserError(f"--placements: {e}") from None
    return text


def _run_reproduce(args):
    from pathlib import Path

    from ..experiments.reproduce import RunSettings, reproduce
    config = _config(args)
    if args.per_category < 4:
        raise UserError(f"--per-category must be at least 4 (a 50/50 split must train on 2 "
                        f"objects a category to calibrate the SVM), got {args.per_category}")
    report = reproduce(RunSettings(out=Path(args.out), quick=args.quick,
                                   per_category=args.per_category, splits=args.splits,
                                   workers=args.workers, scheduler=args.scheduler,
                                   seed=args.seed, config=config, redo=args.redo,
                                   placements=_checked_counts(args.placements),
                                   second_dataset=not args.no_second_dataset))
    print(f"wrote {report} and {report.with_suffix('.html')}")
    return 0


COMMANDS.append(("reproduce", _add_reproduce, _run_reproduce))


def _add_simplify(p):
    p.add_argument("--simplify", type=float, default=None, metavar="MM",
                   help="decimate the mesh (Open3D quadric decimation) to the fewest "
                        "triangles that stay within MM millimetres of its surface, e.g. 0.5; "
                        "worth it above 100,000 triangles, where a wrap takes tens of seconds "
                        "(default: the mesh as given)")


def _sized_mesh(mesh, name, simplify_mm):
    """The mesh to wrap: as given, with a warning if it is large (objects.mesh.size_warning),
    or with --simplify decimated to within that many millimetres, saying what it did."""
    import math

    from ..objects.mesh import simplify_mesh, size_warning
    if simplify_mm is None:
        warning = size_warning(mesh, name)
        if warning:
            print(f"warning: {warning}", file=sys.stderr)
        return mesh
    if not (math.isfinite(simplify_mm) and simplify_mm > 0):
        raise UserError(f"--simplify must be a positive number of millimetres, got "
                        f"{simplify_mm}")
    low, deviation = simplify_mesh(mesh, simplify_mm / 1000.0)
    print(f"simplified {name}: {len(mesh.faces):,} -> {len(low.faces):,} triangles, at most "
          f"{1000 * deviation:.2f} mm from the original surface (--simplify {simplify_mm:g})",
          file=sys.stderr)
    return low


def _add_placed_mesh_options(p):
    """The options of a mesh where it stands (classify, recognize)."""
    p.add_argument("--units", choices=["m", "cm", "mm"], default="m",
                   help="units of the mesh's world coordinates (default: m)")
    p.add_argument("--rest-pose", type=int, default=None,
                   help="set the object down on this stable pose (0: the most probable; "
                        "trimesh's stable poses) at the mark (default: where it stands)")
    p.add_argument("--turn", type=float, default=None,
                   help="set it down turned this many degrees about the vertical "
                        "(default: where it stands)")
    p.add_argument("--offset", default=None,
                   help="set it down this far from the mark, x,y in m, e.g. 0.05,-0.02 "
                        "(default: where it stands)")
    p.add_argument("--position", default=None,
                   help="where you think the object is, x,y in m (within about 2 cm), e.g. "
                        "0.05,-0.02: the arm's planes are centred there (default: estimated "
                        "from the simulated depth camera's cloud)")


def _placed_scene(args, arm):
    """(WrapScene, world mesh, position info) of a mesh where it stands (or set down by
    --rest-pose/--turn/--offset), seen from `arm` lined up on --position or the depth
    camera's estimate; never on the mesh's own geometry."""
    import numpy as np

    from ..objects.importer import UNITS
    from ..objects.mesh import MeshError, load_mesh, standard_pose
    from ..objects.placement import PlacementError, arm_frame, check_clear, place
    from ..perception.locate import LocateError, camera_estimate, footprint_centre
    from ..wrapping.scene import WrapScene
    try:
        mesh = load_mesh(args.mesh)
    except MeshError as e:
        raise UserError(str(e)) from None
    mesh.apply_scale(UNITS[args.units])
    where = f"{args.mesh}"
    mesh = _sized_mesh(mesh, where, args.simplify)
    given = _set_down(args, "")
    try:
        if given is not None:
            mesh = place(mesh, given, where=f"{where} set down")
        table = float(standard_pose().get("table_height", 0.0))
        low = float(mesh.vertices[:, 2].min())
        if abs(low - table) > 0.002:
            raise UserError(f"{where}: its lowest point is at z = {low:.4f} m, not on the table "
                            f"(z = {table} m); move it there, or set it down with --turn 0")
        if args.position is not None:
            centre = np.array(_floats(args.position, 2, "--position"))
            if not np.all(np.isfinite(centre)):
                raise UserError(f"--position {args.position}: not two finite numbers")
            source = "--position"
        else:
            try:
                centre = camera_estimate(mesh, arm).xy
            except LocateError as e:
                raise UserError(f"{where}: {e}; give --position X,Y") from None
            source = "depth camera"
        local = arm_frame(mesh, centre)
        check_clear(local, arm, f"{where} centred on {np.round(centre, 4).tolist()}")
    except PlacementError as e:
        raise UserError(str(e)) from None
    error = float(np.linalg.norm(centre - footprint_centre(mesh)))
    log.info("%s: arm centred on (%.4f, %.4f) m from the %s (%.1f mm from the footprint "
             "centre)", where, centre[0], centre[1], source, 1000 * error)
    position = {"centre": np.asarray(centre, float).round(5).tolist(), "from": source,
                "error_mm": round(1000 * error, 2)}
    return WrapScene(arm, local), mesh, position


def _model_config(args, info):
    """The configuration a model's object is wrapped with: the one it records (its training
    collection's wraps), then --config/--set; warnings on stderr."""
    from ..config import model_config
    cfg, warnings = model_config(info, args.config, args.set)
    for w in warnings:
        print(f"warning: {w}", file=sys.stderr)
    return cfg


def _config_planes(cfg, arm):
    from ..wrapping.planes import enumerate_planes
    return enumerate_planes(arm.base_position, cfg.alpha_deg, cfg.both_directions)


def _add_classify(subparsers):
    p = subparsers.add_parser(
        "classify", help="wrap a new mesh on every plane and classify it",
        description="Wrap OBJECT_MESH where it stands in world coordinates (or set down "
                    "by --rest-pose/--turn/--offset) on every wrap plane, the arm lined up on "
                    "a position a robot would have (--position, or the simulated depth "
                    "camera's estimate; never the mesh's own geometry, never its "
                    "orientation), and classify its wraps with a trained model. "
                    "Example: drake-continuum classify results/model models/mug.obj --turn 90 "
                    "--json --png mug_wraps.png")
    p.add_argument("model", help="trained model folder (drake-continuum train), required")
    p.add_argument("mesh", help="object mesh (OBJ, STL, PLY, OFF), required")
    _add_placed_mesh_options(p)
    p.add_argument("--json", action="store_true", help="print {category, probabilities}")
    p.add_argument("--png", default=None,
                   help="also draw every usable wrap on the mesh, one cell a plane, to this "
                        "PNG (default: none)")
    _add_simplify(p)
    _add_config_options(p, "the settings the model records, its training collection's")
    return p


def _run_classify(args):
    import dataclasses

    from ..learning.model import classify, load_model
    from ..wrapping.wrap import wrap
    model = load_model(args.model)
    cfg = _model_config(args, model.info)
    arm = cfg.arm()
    planes = _config_planes(cfg, arm)
    # Every plane: the model's wrap descriptors are kept a plane, as in training.
    if len(planes) < model.n_planes:
        raise UserError(f"{args.model}: the model knows {model.n_planes} wrap planes, the "
                        f"configuration gives {len(planes)}")
    scene, _, position = _placed_scene(args, arm)
    wraps = [wrap(scene, p, cfg.wrap) for p in planes]
    if not any(w.usable for w in wraps):
        raise UserError(f"{args.mesh}: no wrap plane touched the object")
    result = classify(model, wraps)
    out = {**dataclasses.asdict(result), "position": position}
    if args.png:
        from ..viz.plots import plot_object_wraps
        out["png"] = str(plot_object_wraps(scene.object_trimesh, arm,
                                           [w for w in wraps if w.usable], args.png))
    if args.json:
        _print_json(out)
    else:
        print(f"{args.mesh}: {result.category} (p = "
              f"{result.probabilities[result.category]:.2f}, {result.n_wraps} wraps)")
        if args.png:
            print(f"wraps drawn in {out['png']}")
    return 0


COMMANDS.append(("classify", _add_classify, _run_classify))


def _add_recognize(subparsers):
    p = subparsers.add_parser(
        "recognize", help="active recognition of a mesh: tree search chooses the wraps",
        description="Recognise OBJECT_MESH by active wrapping (section IV-D): each iteration "
                    "a Monte Carlo tree search plans the next wraps, they are made in "
                    "simulation, and the accumulated chords are classified, until the "
                    "strong-prediction rule or the iteration limit. The mesh stands where "
                    "its world coordinates put it (or is set down by --rest-pose/--turn/"
                    "--offset); the arm is lined up on --position or the depth camera's "
                    "estimate. "
                    "Example: drake-continuum recognize results/active-model models/mug.obj "
                    "--turn 45")
    p.add_argument("model", help="model folder from `drake-continuum train-active`, required")
    p.add_argument("mesh", help="object mesh (OBJ, STL, PLY, OFF), required")
    _add_placed_mesh_options(p)
    p.add_argument("--seed", type=int, default=None,
                   help="seed, a shortcut for --set active.seed=... (default: the "
                        "configuration's)")
    p.add_argument("--json", action="store_true", help="print the iterations as JSON")
    p.add_argument("--meshcat", action="store_true",
                   help="animate the executed wraps in Meshcat (default: off)")
    p.add_argument("--html", default=None, help="save the animation as a page (default: none)")
    _add_simplify(p)
    _add_config_options(p, "the settings the model records, its training collection's")
    return p


def _run_recognize(args):
    from ..active.policies import recognize, simulated_execute
    from ..active.training import load_active_model
    model = load_active_model(args.model)
    if args.seed is not None:
        args.set = [f"active.seed={args.seed}"] + list(args.set)
    cfg = _model_config(args, model.classifier.info)
    arm = cfg.arm()
    known = model.observations.n_planes
    planes = _config_planes(cfg, arm)
    if known > len(planes):  # a model of fewer planes (the first ones) is served by these
        raise UserError(f"{args.model}: the model knows {known} wrap planes; the "
                        f"configuration gives {len(planes)} (alpha = {cfg.alpha_deg} deg)")
    scene, _, position = _placed_scene(args, arm)
    done = []
    out = recognize(model, simulated_execute(scene, planes, model.classifier.chord_params,
                                             cfg.wrap, log=done), params=cfg.active)
    if args.meshcat or args.html:
        from ..viz.plots import show_wrap
        configs = [c for w in done for c in w.configs] or [scene.config]
        last = done[-1] if done else None
        show_wrap(arm.with_base(rotation=last.base_rotation) if last else arm,
                  scene.object_trimesh, [c for c in last.configs] if last else configs,
                  last.contacts if last else None, html_path=args.html)
    if args.json:
        _print_json({**out.to_dict(), "position": position})
    else:
        for k, it in enumerate(out.iterations, 1):
            top = ", ".join(f"{c} {p:.2f}" for c, p in it.top3)
            print(f"iteration {k}: {it.n_wraps} wraps, movement {it.movement_cost:.2f} "
                  f"rad: {top}")
        print(f"{args.mesh}: {out.category} ({out.stopped_because})")
    return 0


COMMANDS.append(("recognize", _add_recognize, _run_recognize))


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
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (default: shown)")
    _add_config_options(p)
    return p


def _run_collect(args):
    from ..experiments.collect import CollectLockError, collect
    cfg = _config(args, _shortcut("planes.both_directions", args.both_directions))
    ids = [i.strip() for i in args.ids.split(",") if i.strip()] if args.ids else None
    try:
        report = collect(args.dataset, args.out, workers=args.workers,
                         scheduler=args.scheduler, ids=ids,
                         limit_per_category=args.limit_per_category,
                         progress=not args.no_progress, params=cfg.wrap,
                         alpha_deg=cfg.alpha_deg, both_directions=cfg.both_directions,
                         arm_yaml=cfg.arm_yaml)
    except CollectLockError as e:
        raise UserError(str(e)) from None
    except OSError as e:  # e.g. a Dask scheduler that cannot be reached
        if args.scheduler is None:
            raise
        raise UserError(f"Dask scheduler {args.scheduler}: {type(e).__name__}: {e}") from None
    for oid, message in report.failed.items():
        print(f"failed: {oid}: {message}", file=sys.stderr)
    _print_json(report.to_dict())
    return 1 if report.failed else 0


COMMANDS.append(("collect", _add_collect, _run_collect))


# ----------------------------------------------------------------- wrap
def _add_wrap(subparsers):
    p = subparsers.add_parser(
        "wrap", help="wrap one object on one plane (Algorithm 1) and show or save the wrap",
        description="Run the touch-driven wrap (the paper's Algorithm 1) of one object on one "
                    "plane: a default plane by index (--plane) or a plane rotated about world "
                    "x (--rx) or y (--ry). Prints a summary (or --json); --meshcat animates it "
                    "in Drake's Meshcat, --html saves that animation as one page, --png draws "
                    "the final wrap. Example: drake-continuum wrap models/mug.obj --plane 1 "
                    "--png out/wrap.png")
    p.add_argument("object", help="object mesh file, or an object id with --dataset (required)")
    p.add_argument("--dataset", default=None,
                   help="dataset folder (manifest.json) to look OBJECT up in as an id, e.g. "
                        "data/objects (default: OBJECT is a mesh file)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--plane", type=int, default=None,
                       help="index of a default plane (0-9: about x, then about y, every 22.5 "
                            "deg; default: none)")
    which.add_argument("--rx", type=float, default=None,
                       help="plane rotated this many degrees about world x (default: none)")
    which.add_argument("--ry", type=float, default=None,
                       help="plane rotated this many degrees about world y (default: none)")
    p.add_argument("--direction", choices=["cw", "ccw"], default=None,
                   help="wrap direction about the plane normal, with --rx/--ry (default: cw "
                        "about x, ccw about y, as the paper's Fig. 4)")
    p.add_argument("--method", choices=["fast", "reference"], default=None,
                   help="enclosing: fast (distance-bounded) or reference (a contact query "
                        "every step), a shortcut for --set wrap.method=... (default: the "
                        "configuration's, fast)")
    p.add_argument("--meshcat", action="store_true",
                   help="animate the wrap in Meshcat and print its URL (default: off)")
    p.add_argument("--chords", action="store_true",
                   help="with --meshcat/--html, also draw the wrap's chords (default: off)")
    p.add_argument("--no_wait", "--no-wait", dest="no_wait", action="store_true",
                   help="with --meshcat, exit at once instead of serving until Enter "
                        "(default: wait)")
    p.add_argument("--html", default=None,
                   help="save the Meshcat animation as a self-contained page, e.g. "
                        "out/wrap.html (default: none)")
    p.add_argument("--png", default=None,
                   help="draw the final wrap to this PNG, e.g. out/wrap.png (default: none)")
    p.add_argument("--json", action="store_true", help="print the result as JSON (default: off)")
    _add_simplify(p)
    _add_config_options(p)
    return p


def _wrap_object_mesh(args):
    """(mesh path, name) of the command's object."""
    from pathlib import Path

    from ..objects.dataset import DatasetError, load_manifest
    if args.dataset is None:
        path = Path(args.object)
        if not path.is_file():
            raise UserError(f"{path}: no such mesh file (give --dataset DIR to look it up "
                            f"as an object id)")
        return path, path.name
    try:
        entry = load_manifest(args.dataset).by_id(args.object)
    except (DatasetError, KeyError) as e:
        raise UserError(e.args[0] if e.args else str(e)) from None
    return entry.path, entry.id


def _wrap_plane(args, arm, cfg):
    import numpy as np

    from ..wrapping.planes import make_plane
    if args.plane is not None:
        planes = _config_planes(cfg, arm)
        if not 0 <= args.plane < len(planes):
            raise UserError(f"--plane must lie in 0..{len(planes) - 1}, got {args.plane}")
        if args.direction is not None:
            raise UserError("--direction goes with --rx or --ry; a default plane has its own")
        return planes[args.plane]
    axis, angle = ("x", args.rx) if args.rx is not None else ("y", args.ry)
    if not np.isfinite(angle):
        raise UserError(f"--r{axis} must be a finite angle in degrees, got {angle}")
    direction = None if args.direction is None else (1 if args.direction == "ccw" else -1)
    return make_plane(arm.base_position, axis, angle, direction)


def _run_wrap(args):
    import numpy as np

    from ..objects.mesh import MeshError, load_mesh
    from ..viz import plots as viz
    from ..wrapping.scene import WrapScene
    from ..wrapping.wrap import wrap
    cfg = _config(args, _shortcut("wrap.method", args.method))
    arm = cfg.arm()
    mesh, name = _wrap_object_mesh(args)
    plane = _wrap_plane(args, arm, cfg)
    try:
        loaded = load_mesh(mesh)
        sized = _sized_mesh(loaded, mesh, args.simplify)
        if sized is not loaded:
            mesh = sized  # WrapScene and the pictures take the simplified trimesh
        scene = WrapScene(arm, mesh)
    except MeshError as e:
        raise UserError(str(e)) from None
    result = wrap(scene, plane, cfg.wrap)
    summary = {"object": name, "plane": plane.to_dict(), "method": cfg.wrap.method,
               "status": result.status, "n_contacts": len(result.contacts),
               "tip_rotation_deg": float(np.degrees(result.tip_rotation)),
               "n_queries": int(result.n_queries), "time_ms": 1000.0 * result.time_s,
               "config": result.final_config.to_dict()}
    if "message" in result.extra:
        summary["message"] = result.extra["message"]
    wrap_arm = arm.with_base(rotation=result.base_rotation)
    if args.png:
        summary["png"] = str(viz.plot_wrap(
            scene.object_trimesh, wrap_arm, result.final_config, result.contacts, args.png,
            title=f"{name} {plane.label}: {result.status}, {len(result.contacts)} contacts"))
    meshcat = None
    if args.meshcat or args.html:
        chords = viz.wrap_chord_segments(result) if args.chords else None
        meshcat, _ = viz.show_wrap(wrap_arm, mesh, result.configs, result.contacts,
                                   chords=chords, html_path=args.html)
        if args.html:
            summary["html"] = str(args.html)
        summary["meshcat_url"] = meshcat.web_url()
    if args.json:
        _print_json(summary)
    else:
        print(f"{name} {plane.label} ({cfg.wrap.method}): {result.status}, "
              f"{len(result.contacts)} contacts, tip turned "
              f"{summary['tip_rotation_deg']:.0f} deg, {result.n_queries} contact queries, "
              f"{summary['time_ms']:.0f} ms" + (f"; {summary['message']}" if "message" in summary
                                                 else ""))
        for key in ("png", "html"):
            if key in summary:
                print(f"wrote {summary[key]}")
    if args.meshcat and not args.no_wait:
        try:
            input("Meshcat is serving; press Enter (or Ctrl-C) to quit.\n")
        except (EOFError, KeyboardInterrupt):
            pass
    return 0


COMMANDS.append(("wrap", _add_wrap, _run_wrap))


# ----------------------------------------------------------------- point clouds (real robot)
def _add_cloud_options(p):
    p.add_argument("--arm", default=None,
                   help="arm description YAML, e.g. models/arm.yaml (default: models/arm.yaml)")
    p.add_argument("--base_pose", "--base-pose", dest="base_pose", default=None,
                   help="arm base pose x,y,z,roll,pitch,yaw (m, rad) in the cloud's frame, e.g. "
                        "-0.18,0,0.05,0,1.5708,0 (default: the cloud's sidecar CLOUD.json if "
                        "it has one, else the arm YAML's)")
    p.add_argument("--lengths", default=None,
                   help="known section lengths s1,s2,s3 in m, e.g. 0.15,0.2,0.2 (default: "
                        "fitted)")
    p.add_argument("--units", choices=["auto", "m", "mm"], default="auto",
                   help="units of the cloud file (default: auto, millimetres when it spans "
                        "more than 20 units)")
    p.add_argument("--no_colour", "--no-colour", dest="no_colour", action="store_true",
                   help="segment by geometry alone, for an arm not painted the arm colour "
                        "(default: colour gate on)")
    p.add_argument("--drop_nan", "--drop-nan", dest="drop_nan", action="store_true",
                   help="discard NaN/infinite points (organised clouds) instead of failing "
                        "(default: fail)")
    p.add_argument("--camera", action="append", default=None,
                   help="camera position x,y,z (m) in the cloud's frame, once a cloud in their "
                        "order, e.g. 0.3,-0.5,0.85; what it saw through is evidence of where the "
                        "arm is not (default: the camera in each cloud's sidecar CLOUD.json if "
                        "it has one, else none)")
    p.add_argument("--prior", default=None,
                   help='the commanded configuration, a JSON file or text {"s":[..],"kappa":[..],'
                        '"phi":[..]} (or a sidecar holding one under "config"), which the fit '
                        "stays near where points do not decide (default: none)")
    p.add_argument("--prior_sigma", "--prior-sigma", dest="prior_sigma", default="0.01,1.0,0.2",
                   help="the prior's standard deviations: section length (m), curvature (1/m), "
                        "bending direction (rad) (default: 0.01,1.0,0.2)")
    p.add_argument("--json", action="store_true", help="print the result as JSON (default: off)")
    p.add_argument("--png", default=None,
                   help="draw cloud, segmented arm and reconstruction (the paper's Fig. 8) to "
                        "this PNG, e.g. out/fig8.png (default: none)")


def _floats(text, n, name):
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != n:
        raise UserError(f"{name} needs {n} comma-separated numbers, got {text!r}")
    return values


def _read_arm_config(text, name):
    """An ArmConfig from a JSON file or text (bare, or under "config" as in a sidecar)."""
    from pathlib import Path

    from ..kinematics.arm import ArmConfig
    try:
        if not text.lstrip().startswith("{"):
            text = Path(text).read_text()
        d = json.loads(text)
        return ArmConfig.from_dict(d.get("config", d))
    except OSError as e:
        raise UserError(f"{name} {text}: cannot be read ({e.strerror})") from None
    except (ValueError, KeyError, TypeError, AttributeError) as e:
        raise UserError(f"{name}: not an arm configuration ({e})") from None


def _sidecar(path):
    """The cloud's sidecar JSON as a dict, or {} when it has none or it cannot be read."""
    from pathlib import Path
    side = Path(path).with_suffix(".json")
    try:
        meta = json.loads(side.read_text()) if side.is_file() else {}
    except ValueError:
        meta = {}
    return meta if isinstance(meta, dict) else {}


def _cloud_arm_and_fit(args):
    """(cloud, arm, segmentation, fit, base source, prior) for the point-cloud commands; with
    several clouds (views of one wrap) the cloud returned is the first."""
    from pathlib import Path

    import numpy as np
    from pydrake.math import RollPitchYaw

    from ..kinematics.arm import load_arm
    from ..perception.cloud import load_cloud
    from ..perception.fitting import fit_cloud
    from ..perception.residuals import ConfigPrior
    from ..perception.segmentation import SegmentParams
    arm = load_arm(args.arm)
    clouds = [load_cloud(c, units=args.units, drop_nonfinite=args.drop_nan)
              for c in args.cloud]
    cloud = clouds[0]
    base_from = "arm description"
    sidecar = Path(args.cloud[0]).with_suffix(".json")
    if args.base_pose is not None:
        v = _floats(args.base_pose, 6, "--base-pose")
        arm = arm.with_base(np.array(v[:3]), RollPitchYaw(v[3:]).ToRotationMatrix().matrix())
        base_from = "--base-pose"
    elif sidecar.is_file():
        try:
            meta = json.loads(sidecar.read_text())
            arm = arm.with_base(np.asarray(meta["base_position"], float),
                                RollPitchYaw(meta["base_rpy"]).ToRotationMatrix().matrix())
            base_from = str(sidecar)
        except (ValueError, KeyError, TypeError):
            pass
    lengths = None if args.lengths is None else _floats(args.lengths, arm.n_sections,
                                                        "--lengths")
    if lengths is not None and not all(arm.section_length_min <= s <= arm.section_length_max
                                       for s in lengths):
        raise UserError(f"--lengths must lie in [{arm.section_length_min}, "
                        f"{arm.section_length_max}] m, got {lengths}")
    if args.camera is not None:
        if len(args.camera) != len(clouds):
            raise UserError(f"--camera given {len(args.camera)} times for {len(clouds)} "
                            f"cloud(s): give one camera position a cloud, in their order")
        eyes = [np.array(_floats(c, 3, "--camera")) for c in args.camera]
    else:
        eyes = [_sidecar(c).get("camera", {}).get("eye") for c in args.cloud]
        eyes = None if any(e is None for e in eyes) else [np.asarray(e, float) for e in eyes]
    prior = None
    if args.prior is not None:
        sig = _floats(args.prior_sigma, 3, "--prior-sigma")
        config = _read_arm_config(args.prior, "--prior")
        try:
            arm.check(config)
            prior = ConfigPrior(config, *sig)
        except ValueError as e:
            raise UserError(f"--prior: {e}") from None
    seg_params = SegmentParams(colour=None) if args.no_colour else SegmentParams()
    seg, fit = fit_cloud(clouds, arm, lengths, seg_params, eye=eyes, prior=prior)
    return cloud, arm, seg, fit, base_from, prior


def _print_fit(fit, seg, cloud, base_from):
    import numpy as np
    d = fit.to_dict()
    print(f"{cloud.source}: {seg.n_input} points ({cloud.units}), arm {len(seg.points)} points "
          f"in {seg.n_pieces} piece(s); base pose from {base_from}")
    for i in range(fit.config.n_sections):
        print(f"  section {i + 1}: s = {fit.config.s[i]:.4f} m, kappa = "
              f"{fit.config.kappa[i]:.3f} 1/m, phi = {np.degrees(fit.config.phi[i]):.1f} deg")
    r = d["residual"]
    print(f"  tip at {np.round(fit.tip, 4).tolist()} m; residual mean {r['mean_abs_mm']:.2f} mm, "
          f"median {r['median_abs_mm']:.2f} mm, p95 {r['p95_abs_mm']:.2f} mm, max "
          f"{r['max_abs_mm']:.2f} mm, inliers {100 * r['inlier_fraction']:.0f} %; "
          f"{fit.time_s:.2f} s")
    if not fit.unseen:
        print("  unseen: none (points along the whole arm)")
    for u in d["unseen"]:
        print(f"  unseen: arc length {u['from_m']:.3f} to {u['to_m']:.3f} m "
              f"(section {', '.join(map(str, u['sections']))})")
    c = fit.confidence
    if c is not None:
        seen = ", ".join(f"{100 * f:.0f} %" for f in c.seen_fraction)
        free = "no camera position" if c.free_space_rays is None else \
            f"{c.free_space_rays} rays seen through the fitted arm"
        more = "; the arm may continue unseen past its last seen point" \
            if c.tip_may_continue else ""
        verdict = "AMBIGUOUS" if c.ambiguous else ("partly unseen" if c.partly_unseen
                                                   else "confident")
        print(f"  seen per section: {seen}; free space: {free}{more}")
        print(f"  tip uncertainty {1e3 * c.tip_uncertainty:.1f} mm (sigma {1e3 * c.tip_sigma:.1f}"
              f" mm, spread {1e3 * c.tip_spread:.1f} mm over {c.n_solutions} distinct "
              f"solution(s)): {verdict}")


def _add_fit_cloud(subparsers):
    p = subparsers.add_parser(
        "fit-cloud", help="fit the arm's configuration to a depth-camera point cloud",
        description="Segment the arm (painted orange) from a .pcd/.ply cloud in the world "
                    "frame and fit every section's length, curvature and bending angle. "
                    "Example: drake-continuum fit-cloud real/data/cylinder_0.pcd --png "
                    "out/fit.png")
    p.add_argument("cloud", nargs="+",
                   help="point cloud .pcd or .ply; several for views of one wrap from different "
                        "cameras (required)")
    _add_cloud_options(p)
    return p


def _run_fit_cloud(args):
    from ..perception.comparison import fig8
    cloud, arm, seg, fit, base_from, prior = _cloud_arm_and_fit(args)
    out = {"cloud": cloud.source, "clouds": list(args.cloud), "units": cloud.units,
           "base_from": base_from, "prior": None if prior is None else prior.to_dict(),
           "n_points": seg.n_input, "arm_points": len(seg.points), "pieces": seg.n_pieces,
           **fit.to_dict()}
    if args.png:
        out["png"] = str(fig8(args.png, cloud, seg, fit, arm, title=cloud.source))
    if args.json:
        _print_json(out)
    else:
        _print_fit(fit, seg, cloud, base_from)
        if args.png:
            print(f"wrote {out['png']}")
    return 0


COMMANDS.append(("fit-cloud", _add_fit_cloud, _run_fit_cloud))


def _add_compare_real(subparsers):
    p = subparsers.add_parser(
        "compare-real", help="compare a real wrap (point cloud) with its simulated version",
        description="Fit the arm to the cloud, rebuild it in the Drake contact scene at that "
                    "configuration against the object, and report per-point deviation, the "
                    "chord-histogram distance between the two wraps and, with --model, the "
                    "category each yields (the paper's section V-D). Example: drake-continuum "
                    "compare-real real/data/cylinder_0.pcd --object real/data/cylinder.obj "
                    "--png out/fig8.png")
    p.add_argument("cloud", nargs="+",
                   help="point cloud .pcd or .ply; several for views of one wrap from different "
                        "cameras (required)")
    p.add_argument("--force", action="store_true",
                   help="call categories even from an ambiguous fit (default: refuse)")
    p.add_argument("--object", required=True,
                   help="object mesh in the world frame, e.g. real/data/cylinder.obj (required)")
    p.add_argument("--model", default=None,
                   help="trained model folder (drake-continuum train), e.g. out/model "
                        "(default: none, no categories)")
    _add_cloud_options(p)
    return p


def _run_compare_real(args):
    from ..perception.comparison import compare_real
    model = None
    if args.model is not None:
        from ..learning.model import load_model
        model = load_model(args.model)
    cloud, arm, seg, fit, base_from, prior = _cloud_arm_and_fit(args)
    c = fit.confidence
    if model is not None and c is not None and c.ambiguous and not args.force:
        raise UserError(f"{cloud.source}: the fit is ambiguous (tip uncertainty "
                        f"{1e3 * c.tip_uncertainty:.0f} mm, {c.n_solutions} distinct solutions "
                        f"explain the points; seen per section "
                        f"{', '.join(f'{100 * f:.0f} %' for f in c.seen_fraction)}), so no "
                        f"category is called from it: add a view from another side, give "
                        f"--prior, or pass --force")
    out = compare_real(cloud, seg, fit, arm, args.object, model, args.png,
                          simulated=None if prior is None else prior.config)
    out["base_from"] = base_from
    out["forced"] = bool(model is not None and c is not None and c.ambiguous)
    dev = out["deviation"]
    if args.json:
        _print_json(out)
        return 0
    _print_fit(fit, seg, cloud, base_from)
    print(f"real vs simulated: deviation mean {dev['mean_mm']:.2f} mm, Hausdorff "
          f"{dev['hausdorff_mm']:.2f} mm")
    ch = out["chords"]
    if ch.get("histogram_distance") is None:
        print(f"chord histograms: not compared ({ch.get('note')})")
    else:
        print(f"chord histograms: distance {ch['histogram_distance']:.3f} (total variation; "
              f"{ch['n_chords_real']} real, {ch['n_chords_simulated']} simulated chords)")
    if "category_real" in ch:
        forced = " (from an ambiguous fit: --force)" if out["forced"] else ""
        print(f"category: real {ch['category_real']}, simulated {ch['category_simulated']}"
              f"{forced}")
    if args.png:
        print(f"wrote {out['png']}")
    return 0


COMMANDS.append(("compare-real", _add_compare_real, _run_compare_real))


def _add_simulate_cloud(subparsers):
    p = subparsers.add_parser(
        "simulate-cloud", help="render a Kinect-like point cloud of the arm around an object",
        description="Render the arm (at a configuration, or at the end of a wrap on a plane) "
                    "against the object on the table with a Kinect v1 error model and write "
                    "the world-frame cloud plus a JSON sidecar with the true configuration. "
                    "Example: drake-continuum simulate-cloud models/mug.obj --plane 1 --out "
                    "out/mug.pcd")
    p.add_argument("object", help="object mesh in the world frame (required)")
    which = p.add_mutually_exclusive_group(required=True)
    which.add_argument("--plane", type=int, default=None,
                       help="wrap on this default plane and render its final configuration "
                            "(default: none)")
    which.add_argument("--arm-config", "--arm_config", dest="arm_config", default=None,
                       help='arm configuration to render, JSON file or text {"s":[..],'
                            '"kappa":[..],"phi":[..]} (default: none)')
    p.add_argument("--out", default="cloud.pcd",
                   help="output cloud .pcd or .ply; the sidecar is OUT with .json (default: "
                        "cloud.pcd)")
    p.add_argument("--deform", type=float, default=0.0,
                   help="how far the tube flattens against the object at contacts, mm "
                        "(default: 0)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default: 0)")
    p.add_argument("--voxel", type=float, default=0.0,
                   help="voxel downsampling of the written cloud, m, e.g. 0.004 (default: 0, "
                        "every pixel)")
    p.add_argument("--cameras", type=int, default=1,
                   help="views of the wrap: N cameras at the default camera's height and "
                        "distance, spread evenly round the object (2: the second opposite the "
                        "first); with N > 1 the clouds are OUT_view0 ... OUT_view<N-1> "
                        "(default: 1)")
    p.add_argument("--arm", default=None,
                   help="arm description YAML (default: the configuration's, models/arm.yaml)")
    _add_config_options(p)
    return p


def _run_simulate_cloud(args):
    from ..kinematics.arm import load_arm
    from ..objects.mesh import load_mesh
    from ..perception.depth_camera import simulate_clouds
    cfg = _config(args)
    arm = load_arm(args.arm) if args.arm is not None else cfg.arm()
    mesh = load_mesh(args.object)
    if args.deform < 0:
        raise UserError(f"--deform must be >= 0 mm, got {args.deform}")
    if args.cameras < 1:
        raise UserError(f"--cameras must be at least 1, got {args.cameras}")
    if not args.out.lower().endswith((".pcd", ".ply")):
        raise UserError(f"--out must end in .pcd or .ply, got {args.out}")
    meta = {"object": str(args.object)}
    if args.arm_config is not None:
        config = _read_arm_config(args.arm_config, "--arm-config")
        arm.check(config)
    else:
        from ..wrapping.scene import WrapScene
        from ..wrapping.wrap import wrap
        planes = _config_planes(cfg, arm)
        if not 0 <= args.plane < len(planes):
            raise UserError(f"--plane must lie in 0..{len(planes) - 1}, got {args.plane}")
        result = wrap(WrapScene(arm, args.object), planes[args.plane], cfg.wrap)
        config = result.final_config
        arm = arm.with_base(rotation=result.base_rotation)
        meta.update(plane=args.plane, wrap_status=result.status)
    for path, side, n in simulate_clouds(arm, config, mesh, args.out, cameras=args.cameras,
                                         deform_mm=args.deform, seed=args.seed,
                                         voxel=args.voxel, meta=meta):
        print(f"wrote {path} ({n} points) and {side}")
    return 0

COMMANDS.append(("simulate-cloud", _add_simulate_cloud, _run_simulate_cloud))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="drake-continuum",
        description="Object classification and recognition by continuum-arm wraps (Mao et al.), "
                    "on Drake.")
    parser.add_argument("-v", "--verbose", action="store_true", help="more logging")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, add, run in COMMANDS:
        p = add(sub)
        p.set_defaults(_run=run)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        return args._run(args) or 0
    except (DrakeContinuumError, OSError) as e:  # input, settings, files: the user's to fix
        print(f"drake-continuum {args.command}: error: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:  # Ctrl-C: what is written is whole (files.write_atomic)
        again = "; rerun the same command to resume" if args.command in RESUMABLE else ""
        print(f"drake-continuum {args.command}: interrupted{again}", file=sys.stderr)
        return 130  # 128 + SIGINT, as a shell reports it
    except Exception as e:  # anything else is a bug
        if args.verbose:
            traceback.print_exc()
        where = ("the traceback above" if args.verbose
                 else "its traceback (run again with -v to see it)")
        print(f"drake-continuum {args.command}: internal error: {type(e).__name__}: {e}\n"
              f"This is a bug; please report it with the command line and {where}.",
              file=sys.stderr)
        return INTERNAL_ERROR


if __name__ == "__main__":
    sys.exit(main())
